"""Design studies: the section II layout study and parameter sweeps (local or on Dask).

* :func:`layout` -- the 2005 paper's hose-layout question (Figs. 13-14): supply and return
  port oscillations against the length of the sections II, 0 included (close-coupled
  manifold). CLI: ``hydroline layout``.
* :func:`sweep` -- any rig parameters by their path in the rig file, a full factorial or
  random samples from distributions, in parallel over local processes or a Dask cluster,
  every row appended to a results file as it finishes so that an interrupted sweep resumes.
  CLI: ``hydroline sweep``. Value and distribution syntax: :mod:`hydroline.studies.design`;
  the results file: :mod:`.journal`; where variants run: :mod:`.executors`.
* :func:`optimize` -- constrained design optimisation: a metric of the rig's response
  minimised over rig parameters (ranges and discrete choices) subject to constraints on
  others, SLSQP from space-filling starts or differential evolution on the sweep's
  shared-model runner, every evaluation journaled and resumable. CLI: ``hydroline optimize``.
* :func:`port_settling` -- the studies' settling time of a port pressure (+-2 % of its final
  absolute pressure by default): measured on the metrics window, or estimated from the decay
  of its oscillation (:mod:`.settling`).
"""
from .design import DISTRIBUTIONS, Design, Distribution, Parameter, parse_parameter, parse_parameters
from .layout import DEFAULT_LENGTHS, LayoutStudy, layout, parse_lengths
from .optimize import OptimizeResult, optimize
from .settling import port_settling, port_summary
from .sweep import (METRIC_COLUMNS, SweepFileError, SweepResult, VariantRunner, metric_columns,
                    read_journal, run_variant, sweep)

__all__ = ["layout", "LayoutStudy", "DEFAULT_LENGTHS", "parse_lengths",
           "sweep", "SweepResult", "SweepFileError", "run_variant", "VariantRunner", "read_journal",
           "METRIC_COLUMNS", "metric_columns",
           "Design", "Parameter", "Distribution", "DISTRIBUTIONS", "parse_parameter",
           "parse_parameters", "port_settling", "port_summary", "optimize", "OptimizeResult"]
