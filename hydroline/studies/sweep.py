"""Parameter sweeps: many variants of a rig through one scenario, in parallel, resumable.

Each variant is ``rig.copy()``, ``rig.set(path, value)`` for every varied path, then
:func:`hydroline.scenarios.simulate` and :func:`hydroline.scenarios.summarize`; its row holds
the inputs (SI units, one column per rig path), the port metrics and an ``error`` column. A
variant that fails (a negative bore, a steady state that does not converge, a worker process
that dies twice on it) gets its reason in ``error`` and the sweep goes on.

Where it runs
-------------
* ``workers=1``: in this process, one variant after the other;
* ``workers=W``: W local worker processes (``concurrent.futures``);
* ``scheduler="tcp://host:port"``: an existing Dask cluster (``dask.distributed``); hydroline
  must be installed on its workers. ``scheduler="local"`` starts a local Dask cluster of W
  single-threaded worker processes on 127.0.0.1, and a ``distributed.Client`` may be passed
  as is. Only a bounded window of variants is in flight at any time (four per worker
  thread), so 10^5 variants need no more memory than 100.

Results file and resume
-----------------------
With ``out=DIR`` every finished row is appended to ``DIR/sweep.jsonl`` the moment it
arrives (one JSON object per line, after a header line that identifies the sweep: rig hash,
scenario, end time, solver and the design). ``resume=True`` reads that file, checks that it
belongs to the same sweep, keeps every row already there (failed ones included: a failure is
a result) and runs only the missing variants; a line cut short by a kill is dropped and its
variant run again. On an interruption (Ctrl-C, SIGTERM to the CLI, an exception from the
callback) the variants already running are waited for and recorded too. At the end (or on
interruption) the table of every finished variant of the design, in variant order, is
written to ``DIR/sweep.csv`` and, where pyarrow is installed, to ``DIR/sweep.parquet``
(otherwise :attr:`SweepResult.notes` says so). Rows of a random design resumed with a smaller
``samples`` stay in the results file, out of the table (a note says so).

Worker processes end with the process that started the sweep, even when it is killed with
SIGKILL (a thread in each worker watches it: a pidfd on Linux, else a poll every 0.5 s).

Circuit rigs
------------
On a rig that describes its circuit (``[circuit.<name>]`` tables, e.g. the shipped
``two_axis``) a parameter is ``circuit.<component>.<parameter>`` and its values are read in
the unit the component type declares (:mod:`hydroline.circuit.types`). Where the rig has
several servo axes, each row holds the metrics per axis, ``<axis>.<side>.<metric>``
(:func:`metric_columns`), and each axis's position disturbance.

Modules: this one is the study (design -> variants -> rows -> :class:`SweepResult`);
:mod:`hydroline.studies.journal` the results file, :mod:`hydroline.studies.executors` where
the variants run.

Per-variant time limits are not offered: the compiled integrator runs a whole variant in one
C call, which a Python-level timer cannot interrupt, and ending a worker process from the
parent breaks the pool for the other variants in flight.
"""
from __future__ import annotations

import functools
import math
import os
import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..blas import one_blas_thread
from ..rigs import Rig, RigError, load_rig
from ..scenarios.experiments import default_scenario, scenario_names
from ..scenarios.running import simulate
from ..units import exact_quantity
from .design import Design, parameter_unit, parse_parameters
from .executors import (MAX_ATTEMPTS, MAX_WORKERS, dask_client, failure_reason, run_dask,
                        run_processes, run_serial)
from .journal import (FORMAT_VERSION, JOURNAL_NAME, Journal, SweepFileError, check_same_inputs,
                      check_same_sweep, journal_header, read_journal)
from .settling import port_summary

__all__ = ["sweep", "check_levels", "run_variant", "VariantRunner", "SweepResult", "SweepFileError",
           "METRIC_COLUMNS", "TRACKING_COLUMNS", "SETTLING_COLUMNS", "PORT_METRICS",
           "JOURNAL_NAME", "FORMAT_VERSION", "MAX_ATTEMPTS", "MAX_WORKERS", "read_journal",
           "metric_columns", "settling_columns", "failed_row", "row_columns", "graph_signature",
           "simulate_shared", "base_rest_state", "SharedModel", "HOSE_KEYS"]

#: Metric columns of every row of a single-axis rig (then ``warnings`` and ``error``); the
#: closed-loop scenario adds ``tracking_error_rms_mm`` and ``tracking_error_max_mm``.
METRIC_COLUMNS = ["supply_frequency_hz", "supply_amplitude_mpa", "supply_settling_time_s",
                  "return_frequency_hz", "return_amplitude_mpa", "return_settling_time_s",
                  "supply_first_excursion_mpa", "supply_steady_change_mpa",
                  "supply_peak_to_peak_mpa", "return_first_excursion_mpa",
                  "return_steady_change_mpa", "return_peak_to_peak_mpa", "wall_time_s"]
#: Port metrics taken from :func:`hydroline.scenarios.summarize` into each row (one definition
#: for simulate, layout and sweep, :func:`hydroline.traces.metrics.pressure_metrics`).
PORT_METRICS = ("frequency_hz", "amplitude_mpa", "settling_time_s", "first_excursion_mpa",
                "steady_change_mpa", "peak_to_peak_mpa")
TRACKING_COLUMNS = ["tracking_error_rms_mm", "tracking_error_max_mm"]
#: How each settling time was obtained: "measured", "estimated" or "" (none), see
#: :func:`hydroline.studies.settling.port_settling`.
SETTLING_COLUMNS = ["supply_settling_method", "return_settling_method"]
#: Per-axis columns of a multi-axis rig besides the port metrics: the piston's largest
#: excursion from where it stood at the disturbance (axes held still; None for the stepped
#: axis), and the stepped axis's travel, [mm].
AXIS_COLUMNS = ("position_disturbance_mm", "position_change_mm")
SIDES = ("supply", "return")


def metric_columns(axes=(), scenario: str = "open-loop-step") -> list[str]:
    """The numeric metric columns of a sweep's rows.

    Parameters
    ----------
    axes : sequence of str
        The rig's servo axes (:attr:`hydroline.circuit.Circuit.axes`);
        with one axis or none, the single-axis columns
        :data:`METRIC_COLUMNS`
    scenario : str
        Scenario name (closed-loop-sine adds :data:`TRACKING_COLUMNS`)

    Returns
    -------
    list[str]
        Single axis: :data:`METRIC_COLUMNS`; several: ``<axis>.<side>.<metric>`` for
        each axis, side and :data:`PORT_METRICS` (frequencies [Hz], amplitudes,
        excursions, changes, peak-to-peak [MPa], settling times [s]),
        ``<axis>.position_disturbance_mm`` and ``<axis>.position_change_mm`` [mm],
        then ``wall_time_s`` [s]
    """
    axes = list(axes)
    if len(axes) <= 1:
        cols = list(METRIC_COLUMNS)
        return cols + TRACKING_COLUMNS if scenario == "closed-loop-sine" else cols
    cols = [f"{a}.{side}.{k}" for a in axes for side in SIDES for k in PORT_METRICS]
    cols += [f"{a}.{k}" for a in axes for k in AXIS_COLUMNS]
    return cols + ["wall_time_s"]


def settling_columns(axes=()) -> list[str]:
    """The text columns that say how each settling time was obtained.

    Parameters
    ----------
    axes : sequence of str
        The rig's servo axes

    Returns
    -------
    list[str]
        :data:`SETTLING_COLUMNS`, or ``<axis>.<side>.settling_method`` per axis of a
        multi-axis rig; their values are "measured", "estimated" or "".
    """
    axes = list(axes)
    if len(axes) <= 1:
        return list(SETTLING_COLUMNS)
    return [f"{a}.{side}.settling_method" for a in axes for side in SIDES]


def row_columns(design: Design, axes=(), scenario: str = "open-loop-step") -> list[str]:
    """Every column of a sweep's table, in order.

    Parameters
    ----------
    design : Design
        The variants
    axes : sequence of str
        The rig's servo axes
    scenario : str
        Scenario name

    Returns
    -------
    list[str]
        ``variant``, the inputs, the metrics, the settling methods, ``warnings``, ``error``.
    """
    return ["variant", *design.columns, *metric_columns(axes, scenario), *settling_columns(axes),
            "warnings", "error"]


def _set_si(rig: Rig, path: str, value, unit: str):
    """Set a rig parameter from an SI value through :meth:`Rig.set` (so it is validated)."""
    if unit in ("-", "str"):
        rig.set(path, value)
    else:
        rig.set(path, exact_quantity(value, unit))


def _values_checked(p) -> tuple:
    """The values of a parameter that :func:`check_levels` checks: every level; the ends of a
    distribution that has them (uniform, loguniform, triangular), every value of a choice, the
    centre of one that has none (normal: its mean, lognormal: its median)."""
    if p.levels is not None:
        return p.levels
    d = p.distribution
    if d.kind == "triangular":
        return (d.args[0], d.args[2])
    if d.kind in ("normal", "lognormal"):
        return d.args[:1]
    return d.args


def check_levels(rig: Rig, params) -> None:
    """Refuse a sweep, before its first variant, whose parameter takes a value no variant
    could run: each level (:func:`_values_checked` for a distribution), set alone on the base
    rig, is checked against its bounds and plausible range (``[rig] allow_implausible``
    honoured) -- :func:`hydroline.rigs.parameters.check_ranges`, and for a circuit path its
    component type's declaration. Combinations (a pre-charge level above a supply pressure
    level) are the variants' own: such a variant fails with its reason, the others run.

    Parameters
    ----------
    rig : Rig
        The base rig
    params : list[Parameter]
        The parsed parameters (:func:`~hydroline.studies.design.parse_parameters`)

    Raises
    ------
    RigError
        One line: ``PATH: <value> is outside its plausible range, ...``
    """
    from ..circuit import CircuitError, check_circuit_value
    from ..rigs.parameters import check_ranges

    for p in params:
        if p.unit == "str":
            continue
        probe = rig.copy()
        for value in _values_checked(p):
            try:
                for path in p.paths:
                    _set_si(probe, path, value, p.unit)
                    if path.startswith("circuit."):
                        check_circuit_value(probe, path)
                check_ranges(probe)
            except CircuitError as e:
                raise RigError(str(e)) from None


def _empty_row(index, values, axes, scenario) -> dict:
    row = {"variant": int(index), **values}
    row.update({k: None for k in metric_columns(axes, scenario)})
    row.update({k: "" for k in settling_columns(axes)})
    row["warnings"], row["error"] = "", None
    return row


def failed_row(index: int, values: dict, reason: str, scenario: str = "open-loop-step",
               axes=()) -> dict:
    """The row of a variant that failed: inputs, no metrics, its reason in ``error``.

    Parameters
    ----------
    index : int
        Variant number, [-]
    values : dict
        Rig path -> SI value
    reason : str
        Why it failed ("Type: message")
    scenario : str
        Scenario name
    axes : sequence of str
        The rig's servo axes (for the per-axis columns)

    Returns
    -------
    dict
        Column -> value: the inputs, None for every metric, ``error`` the reason.
    """
    row = _empty_row(index, values, axes, scenario)
    row["error"] = reason
    return row


def _fill_metrics(row: dict, summary: dict) -> None:
    """Copy a run's summary (:func:`hydroline.scenarios.summarize`) into a row."""
    if "axes" in summary and len(summary["axes"]) > 1:
        for name, entry in summary["axes"].items():
            for side in SIDES:
                for k in PORT_METRICS:
                    row[f"{name}.{side}.{k}"] = _finite_or_none(entry[side].get(k))
                row[f"{name}.{side}.settling_method"] = entry[side].get("settling_method") or ""
            for k in AXIS_COLUMNS:
                row[f"{name}.{k}"] = _finite_or_none(entry.get(k))
    else:
        if "axes" in summary:       # a multi-axis summary of one axis: its entry
            entry = next(iter(summary["axes"].values()))
            summary = {**summary, **entry}
        for side in SIDES:
            for k in PORT_METRICS:
                row[f"{side}_{k}"] = _finite_or_none(summary[side].get(k))
            row[f"{side}_settling_method"] = summary[side].get("settling_method") or ""
        for k in TRACKING_COLUMNS:
            if k in summary:
                row[k] = _finite_or_none(summary[k])
    row["warnings"] = "; ".join(summary["warnings"])


class VariantRunner:
    """Runs the variants of one sweep: the base rig, scenario and solver, kept where it runs.

    Called as ``runner(index, values) -> row``; picklable, so the process pool sends it once
    per worker and Dask scatters it once (:mod:`hydroline.studies.executors`).

    Variants of one structure share one model (:class:`SharedModel`), built with its
    hoses' matrix entries as runtime parameters
    (:func:`hydroline.components.hose.coefficients_as_parameters`). A variant that differs
    from a kept model's rig only in hose lengths, bores or bulk moduli gets that model's p
    with those hoses' entries (M8-M14) made anew: no network is built. Any other variant's
    network is built (the components and their wiring) and, where everything but its p
    equals a kept model's (:func:`graph_signature`), runs on that model's CasADi functions
    and compiled library with its own p -- no graph, code generation or library lookup per
    variant. The steady state starts from the previous variant's rest state on that model
    (the components' guess where that fails); it, the integration and the summary are those
    of :func:`hydroline.scenarios.simulate` with ``metrics_only`` (a test checks the rows
    equal its rows within the solver tolerance): a run ends with its metrics window, so a
    row's warnings (gas release) are those of the window. The hoses' correction factors are
    kept in memory, not written to the disk cache
    (:class:`hydroline.lines.corrections.kept_in_memory`).

    Parameters
    ----------
    rig : Rig
        The base rig (not modified)
    scenario : str
        Scenario name (:func:`hydroline.scenarios.scenario_names`)
    t_end : float
        Simulated time, [s]; the scenario's default when None
    solver : str
        See :func:`hydroline.engine.integrate`
    units : dict
        Rig path -> SI unit (looked up in the rig when None)
    axes : sequence
        The rig's servo axes (names), for the row's columns
    share_models : bool
        Share one model among variants of one structure (False: every
        variant through :func:`hydroline.scenarios.simulate`)

    Attributes
    ----------
    shared_runs : int
        Variants run here on a model shared with an earlier variant, [-]
    hose_runs : int
        Of those, variants that differed only in hoses (no network built,
        :meth:`SharedModel.hose_parameters`), [-]
    """

    #: Structures kept per runner (their networks and compiled libraries), [-].
    MODELS_KEPT = 4

    def __init__(self, rig: Rig, scenario: str = "open-loop-step", t_end: float | None = None,
                 solver: str = "auto", units: dict | None = None, axes=(),
                 share_models: bool = True):
        self.rig, self.scenario, self.t_end, self.solver = rig, scenario, t_end, solver
        self.units = dict(units or {})
        self.axes = tuple(axes)
        self.share_models = share_models
        self._models: dict = {}
        self.shared_runs = self.hose_runs = 0

    @property
    def models(self) -> tuple:
        """The structures kept (:class:`SharedModel`), least recently used first."""
        return tuple(self._models.values())

    def __getstate__(self):     # the models stay where they were built
        state = dict(self.__dict__)
        state["_models"], state["shared_runs"], state["hose_runs"] = {}, 0, 0
        return state

    def __call__(self, index: int, values: dict) -> dict:
        """One variant's row; never raises for a bad variant (see :func:`run_variant`)."""
        # the metrics' spectra use scipy.fft where it is loaded: the same numbers 2.7x
        # faster; ~30 ms to import, once per process
        import scipy.fft  # noqa: F401

        from ..lines.corrections import kept_in_memory
        from ..lines.residue_table import interpolated_lines

        tic = _time.perf_counter()
        row = _empty_row(index, values, self.axes, self.scenario)
        try:
            r = self.rig.copy()
            for path, v in values.items():
                _set_si(r, path, v, self.units.get(path) or parameter_unit(path, self.rig))
            # (no cache file per variant's hose, its exact-pole lines interpolated over Dn;
            # the lines' and the model's small dense matrices on one BLAS thread)
            with kept_in_memory(), interpolated_lines(), one_blas_thread():
                res = self.simulate(r)
            _fill_metrics(row, port_summary(res))
        except Exception as e:   # a failed variant is recorded, never sinks the sweep
            row["error"] = failure_reason(e)
        row["wall_time_s"] = _time.perf_counter() - tic
        return row

    def simulate(self, rig: Rig):
        """:func:`hydroline.scenarios.simulate` of one variant, on a shared model where one of
        its structure was run before (see the class).

        Parameters
        ----------
        rig : Rig
            The variant

        Returns
        -------
        SimulationResult
            The run, with the metadata and warnings ``simulate`` gives.
        """
        if not self.share_models or self.solver not in ("auto", "compiled") or \
                any(k.endswith(".file") for k in rig.values):     # a table file may change
            return simulate(rig, self.scenario, self.t_end, solver=self.solver,
                            metrics_only=True)
        return simulate_shared(rig, self.scenario, self.t_end, self.solver, self._models, self,
                               base=self.rig)


def graph_signature(network):
    """What a network's CasADi graph is made from, but its runtime parameters p: per
    component its type and every attribute by value (a hose whose matrix entries are runtime
    parameters: their pattern, not their values;
    :func:`hydroline.engine.fingerprint.components_signature`). Two networks of equal
    signature have the same graph as a function of (t, x, p), so one's compiled model serves
    the other with its own p. A part that cannot be described by value (a function, a class
    of another package) makes the signature unique to this network.

    Parameters
    ----------
    network : Network
        The assembled model

    Returns
    -------
    str or tuple
        A hashable signature.
    """
    from ..engine.fingerprint import components_signature

    key = components_signature(network.components, _hose_pattern_only)
    return key if key is not None else ("unique", id(network))


def _hose_pattern_only(component, attributes: dict) -> dict:
    """A hose section whose matrix entries are runtime parameters, described by its line
    model's kind, form and port/state names instead of the matrices' values."""
    from ..components.hose import HoseSection

    if isinstance(component, HoseSection) and component.coefficient_pattern is not None:
        m = attributes["model"]
        attributes = {**attributes, "model": (type(m).__qualname__, m.form,
                                              tuple(m.input_names), tuple(m.output_names),
                                              tuple(m.state_names))}
    return attributes


#: Rig keys of a hose section (``<side>.section<n>.<key>`` of the template rig) that change
#: only its line's matrix entries (M8-M14), i.e. only p on a shared model.
HOSE_KEYS = ("length", "diameter", "bulk_modulus")
_MISSING = object()


class SharedModel:
    """One structure's model, shared by the variants of a :class:`VariantRunner`.

    Parameters
    ----------
    network : Network
        Built with the hoses' matrix entries in p (its p is swapped per
        variant)
    circuit : Circuit
        The rig's circuit (axis handles)
    scenario : Scenario
        The experiment's commands and times
    values : dict
        Rig values (SI) of the variant it was built for

    Attributes
    ----------
    p : ndarray
        Runtime parameters of that variant, [SI]
    hoses : dict
        Hose section name -> its component (matrix entries in p)
    hose_entries : dict
        Hose section name -> indices of its entries in p, in the order of its
        :meth:`~hydroline.components.HoseSection.runtime_parameters`
    rest : ndarray
        The last variant's solved rest state, [SI] (None before the first)
    """

    def __init__(self, network, circuit, scenario, values: dict):
        from ..components.hose import HoseSection

        self.network, self.circuit, self.scenario = network, circuit, scenario
        self.values = dict(values)
        self.p = network.parameter_values.copy()
        self.hoses, self.hose_entries = {}, {}
        for c in network.components:
            if isinstance(c, HoseSection) and c.coefficient_pattern is not None:
                self.hoses[c.name] = c
                self.hose_entries[c.name] = np.array(
                    [network.parameter_names.index(f"{c.name}.{k}")
                     for k in c.runtime_parameters()], dtype=np.intp)
        self.rest = None

    def changed_hoses(self, rig: Rig):
        """The hose sections whose length, bore or bulk modulus (:data:`HOSE_KEYS`) differ.

        Parameters
        ----------
        rig : Rig
            A variant

        Returns
        -------
        list[str] or None
            The sections; None when anything else differs (or the rig describes its circuit,
            whose hoses are read otherwise).
        """
        from ..circuit import has_circuit

        if has_circuit(rig.values):
            return None
        changed = set()
        for k in self.values.keys() | rig.values.keys():
            if _same_value(self.values.get(k, _MISSING), rig.values.get(k, _MISSING)):
                continue
            section, _, key = k.rpartition(".")
            if key not in HOSE_KEYS or section not in self.hoses:
                return None
            changed.add(section)
        return changed

    def hose_parameters(self, rig: Rig):
        """p of a variant that differs from this model's rig only in its hoses' length, bore
        or bulk modulus: the model's p with those hoses' matrix entries (M8-M14) made anew;
        None for any other variant (a structure change, e.g. a section removed). The rig is
        checked as a full build checks it (:func:`hydroline.system.validate_rig`).

        Parameters
        ----------
        rig : Rig
            A variant

        Returns
        -------
        ndarray or None
            Runtime parameters, [SI]
        """
        from ..lines import ModalLine
        from ..system import hose_lines, validate_rig

        changed = self.changed_hoses(rig)
        if changed is None:
            return None
        validate_rig(rig)            # raises what a full build raises, before any line
        lines = hose_lines(rig)      # sections of positive length
        p = self.p.copy()
        for name in sorted(changed):
            old = self.hoses[name]
            if name not in lines or type(old.model) is not ModalLine:
                return None
            m = old.model
            new = ModalLine(lines[name], m.n_modes, m.form, method=m.method)
            # its runtime parameters (the matrices' nonzero entries, and an end cavity's
            # gains) where the pattern is the kept hose's; a hose section is not built
            values = old.parameters_for(new)
            if values is None or len(values) != len(self.hose_entries[name]):
                return None
            p[self.hose_entries[name]] = values
        return p


def _same_value(a, b) -> bool:
    if a is b:
        return True
    try:
        return type(a) is type(b) and bool(a == b)
    except (TypeError, ValueError):     # e.g. arrays: compared as different
        return False


def _run_shared(model: SharedModel, rig: Rig, p, guess, solver: str, tic: float):
    """Steady state, integration and metadata of a variant on a shared model with its p.

    The steady state starts from the last variant's rest state (a neighbour in a sweep:
    Newton converges in a few steps), else from ``guess``; a start that fails is followed by
    the next. Returns None where every start failed and ``guess`` is None (the caller builds
    the variant anew).
    """
    from ..engine import integrate
    from ..engine.steady_state import SteadyStateError
    from ..scenarios.running import describe_run, rest_state, window_end

    net, sc = model.network, model.scenario
    net.parameter_values = np.asarray(p, dtype=float).copy()       # this variant's p
    starts = [x for x in (model.rest, guess) if x is not None]
    for k, x0 in enumerate(starts):
        try:
            ss = rest_state(net, x_guess=x0)     # a failure said as simulate() says it
            break
        except SteadyStateError:
            if k == len(starts) - 1:
                if guess is None:
                    return None
                raise
    model.rest = ss.x.copy()
    # (a row is metrics only: the run ends with the metrics window, as simulate(metrics_only))
    res = integrate(net, ss.x, sc.t_end, p=ss.p, solver=solver, **simulate_defaults(),
                    until=window_end(model.circuit, sc))
    describe_run(res, rig, model.circuit, net, sc, ss, tic)     # as simulate()
    return res


@functools.lru_cache(maxsize=1)
def _simulate_parameters() -> tuple:
    import inspect

    params = inspect.signature(simulate).parameters
    return tuple((k, params[k].default) for k in ("dt_out", "rtol", "atol_scale"))


def simulate_defaults() -> dict:
    """:func:`hydroline.scenarios.simulate`'s default output step and tolerances.

    A shared model's run integrates as ``simulate()`` does: the defaults are read from its
    signature, so that the two cannot drift apart.

    Returns
    -------
    dict
        ``dt_out`` [s], ``rtol`` [-] and ``atol_scale`` [-].
    """
    return dict(_simulate_parameters())


def simulate_shared(rig: Rig, scenario: str, t_end, solver: str, models: dict, counter=None,
                    base: Rig | None = None):
    """:func:`hydroline.scenarios.simulate` (default output step and tolerances, and
    ``metrics_only``: the run ends with its metrics window, where a row's metrics end), the
    model shared with earlier runs of the same structure in ``models``.

    A variant that differs from a kept model's rig only in hose lengths, bores or bulk
    moduli (:data:`HOSE_KEYS`, template rigs) gets that model's p with only those hoses'
    matrix entries made anew (:meth:`SharedModel.hose_parameters`): no network is built.
    Any other variant is built (components, wiring) and compared by :func:`graph_signature`
    with the kept ones; a new structure becomes a new shared model. Its first rest state
    starts from ``base``'s where that differs from the variant only in hoses
    (:func:`base_rest_state`), else from the components' guess.

    Parameters
    ----------
    rig : Rig
        The variant
    scenario : str
        Scenario name
    t_end : float
        Simulated time, [s] (the scenario's when None)
    solver : str
        "auto" or "compiled"
    models : dict
        signature -> :class:`SharedModel`, kept between calls (bounded by
        the caller, most recently used last)
    counter : object
        Its ``shared_runs`` (and ``hose_runs``, variants that needed no
        network build) are counted up where a model is shared
    base : Rig or None
        The sweep's base rig (a new model's first rest state starts from
        its rest state where it differs from the variant only in hoses)

    Returns
    -------
    SimulationResult
        The run, with the metadata and warnings ``simulate`` gives.
    """
    from ..components.hose import coefficients_as_parameters
    from ..limits import check_output_size
    from ..scenarios.experiments import build_scenario
    from ..system import build_circuit

    tic = _time.perf_counter()
    for key in reversed(list(models)):          # most recently used first
        model = models[key]
        if model.rest is None:
            continue
        p = model.hose_parameters(rig)
        if p is None:
            continue
        res = _run_shared(model, rig, p, None, solver, tic)
        if res is not None:
            models[key] = models.pop(key)       # most recently used last
            if counter is not None:
                counter.shared_runs += 1
                counter.hose_runs = getattr(counter, "hose_runs", 0) + 1
            return res
        break
    dt_out = simulate_defaults()["dt_out"]
    with coefficients_as_parameters():
        circuit = build_circuit(rig)
        sc = build_scenario(rig, scenario, t_end, axes=circuit.axes)
        if sc.position_guess is not None:
            circuit = build_circuit(rig, sc.position_guess)
        net = circuit.network(sc.commands)
    check_output_size(sc.t_end, dt_out, len(net.signal_names) + len(net.state_names),
                      name="t_end" if t_end is not None else f"scenario.{sc.name}.t_end")
    key = graph_signature(net)
    model = models.pop(key, None)
    if model is None:
        if len(models) >= VariantRunner.MODELS_KEPT:
            models.pop(next(iter(models)))          # the least recently used
        model = SharedModel(net, circuit, sc, rig.values)
    elif counter is not None:
        counter.shared_runs += 1
    models[key] = model
    model.values, model.p = dict(rig.values), net.parameter_values.copy()
    if model.rest is None and base is not None:
        model.rest = base_rest_state(model, base)
    return _run_shared(model, rig, net.parameter_values, net.guess(), solver, tic)


def base_rest_state(model: SharedModel, base: Rig):
    """The rest state of ``base`` on a shared model whose variant differs from it only in
    hoses (:meth:`SharedModel.hose_parameters`): a start for the variant's first rest state.

    From the components' guess (every flow zero, the check valve in the middle of its switch)
    Newton takes its shifted steps first (engine/steady_state.py, ~7 ms); from a neighbour's
    rest state it converges in a few plain steps, and the variants of a hose sweep are such
    neighbours of their base rig's. (Before the shifted steps the guess needed the
    pseudo-transient continuation, 0.1-0.7 s: this start was then the larger saving.)

    Parameters
    ----------
    model : SharedModel
        The model, built for a variant
    base : Rig
        The sweep's base rig

    Returns
    -------
    ndarray or None
        The base rig's rest state, [SI]; None where it differs from the variant in more than
        its hoses, equals it, or has no rest state
    """
    from ..scenarios.running import rest_state

    # (only a start: whatever goes wrong with the base leaves the variant to the guess)
    try:
        p = model.hose_parameters(base)
    except Exception:
        return None
    if p is None or np.array_equal(p, model.p):
        return None
    net = model.network
    kept = net.parameter_values
    net.parameter_values = p
    try:
        return rest_state(net).x.copy()
    except Exception:
        return None
    finally:
        net.parameter_values = kept


def run_variant(rig: Rig, index: int, values: dict, scenario: str = "open-loop-step",
                t_end: float | None = None, solver: str = "auto", units: dict | None = None,
                axes=(), share_models: bool = False) -> dict:
    """Run one variant and return its row; never raises for a bad variant.

    Parameters
    ----------
    rig : Rig
        The base rig (not modified)
    index : int
        Variant number, [-]
    values : dict
        Rig path -> value in SI units (text for text parameters)
    scenario : str
        Scenario name, e.g. "open-loop-step", "closed-loop-sine", "position-step"
    t_end : float
        Simulated time, [s]; the scenario's default when None
    solver : str
        See :func:`hydroline.engine.integrate`
    units : dict
        Rig path -> SI unit (looked up in the rig when None)
    axes : sequence
        The rig's servo axes (names); several give per-axis columns
    share_models : bool
        Run on a model shared with earlier variants of this process's
        :class:`VariantRunner` (False: :func:`hydroline.scenarios.simulate`)

    Returns
    -------
    dict
        ``variant``, the inputs, :func:`metric_columns` (frequencies [Hz], amplitudes,
        first excursions, steady changes and peak-to-peak [MPa], settling times [s], wall
        time [s]; None where a metric does not exist),
        :func:`settling_columns` (how each settling time was obtained, as in the layout
        study: :func:`hydroline.studies.settling.port_settling`), ``warnings`` (text, ""
        when none) and ``error`` (None, or "Type: reason").
    """
    return VariantRunner(rig, scenario, t_end, solver, units, axes, share_models)(index, values)


def _finite_or_none(v):
    """None for a metric that does not exist (None or NaN/inf): rows are strict JSON."""
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


@dataclass
class SweepResult:
    """The outcome of :func:`sweep`.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per finished variant, in variant order: ``variant``,
        the inputs (one column per rig path, SI units), the metrics
        (:attr:`metrics`), the settling methods, ``warnings`` and
        ``error``
    design : Design
        The variants
    n_computed : int
        Variants run by this call (the rest came from the results file)
    wall_time : float
        Wall time of this call, [s]
    files : dict
        "journal", "csv", "parquet" -> Path of the files written
    complete : bool
        Every variant of the design is in the table
    notes : list[str]
        What the user should know about the files: sweep.parquet not
        written (pyarrow missing), rows of the results file beyond
        this design left out of the table (a larger --samples earlier)
    metrics : list[str]
        The numeric metric columns (:func:`metric_columns`: per axis
        ``<axis>.<side>.<metric>`` on a multi-axis rig)
    axes : list[str]
        The rig's servo axes
    scenario : str
        The scenario every variant ran
    """

    table: "pandas.DataFrame"
    design: Design
    n_computed: int = 0
    wall_time: float = 0.0
    files: dict = field(default_factory=dict)
    complete: bool = True
    notes: list = field(default_factory=list)
    metrics: list = field(default_factory=lambda: list(METRIC_COLUMNS))
    axes: list = field(default_factory=list)
    scenario: str = "open-loop-step"

    def _summary_rows(self):
        return [("scenario", self.scenario),
                ("variants", f"{len(self.table)} of {len(self.design)} in the table, "
                             f"{self.n_computed} run by this call, {self.n_failed} failed"),
                ("parameters", ", ".join(f"{'='.join(p.paths)} [{p.unit}]"
                                         for p in self.design.parameters)),
                ("wall time [s]", self.wall_time),
                ("complete", self.complete)] + \
            [(role, str(path)) for role, path in self.files.items()] + \
            [("note", n) for n in self.notes]

    def __repr__(self) -> str:
        from ..engine.display import text_block

        return text_block("hydroline SweepResult", self._summary_rows()) + \
            "\n  (.table: one row per variant, pandas)"

    def _repr_html_(self) -> str:
        from ..engine.display import html_block

        head = self.table.head(10)
        return (html_block("hydroline SweepResult", self._summary_rows())
                + f"<div>first {len(head)} of {len(self.table)} rows of .table</div>"
                + head._repr_html_())

    @property
    def failed(self) -> "pandas.DataFrame":
        """The rows of failed variants (``error`` set)."""
        return self.table[self.table["error"].notna()]

    @property
    def n_failed(self) -> int:
        """Number of failed variants, [-]"""
        return int(self.table["error"].notna().sum())


def _table(rows: dict, design: Design, scenario: str, axes=()):
    import pandas as pd

    cols = row_columns(design, axes, scenario)
    data = [rows[i] for i in sorted(rows) if i < len(design)]
    df = pd.DataFrame(data, columns=cols)
    for c in metric_columns(axes, scenario):
        df[c] = pd.to_numeric(df[c], errors="coerce").astype(float)
    df["variant"] = df["variant"].astype(int)
    for c in settling_columns(axes):    # rows of an older results file lack them
        df[c] = df[c].fillna("").astype(str)
    df["error"] = df["error"].astype(object).where(df["error"].notna(), None)
    return df.reset_index(drop=True)


def _write_tables(df, out: Path, files: dict, notes: list):
    """sweep.csv, and sweep.parquet where pyarrow is installed (a note says why not)."""
    df.to_csv(out / "sweep.csv", index=False)
    files["csv"] = out / "sweep.csv"
    try:
        import pyarrow  # noqa: F401  (optional)
    except ImportError:
        notes.append("sweep.parquet not written: pip install pyarrow (sweep.csv holds the "
                     "same table)")
        return
    try:
        df.to_parquet(out / "sweep.parquet", index=False)
    except Exception as e:      # e.g. a column pyarrow cannot type; the CSV stands
        notes.append(f"sweep.parquet not written: {failure_reason(e)} (sweep.csv holds the "
                     f"table)")
        return
    files["parquet"] = out / "sweep.parquet"


# --------------------------------------------------------------------------- the sweep

def sweep(parameters, rig=None, *, samples: int | None = None, seed: int = 0,
          scenario: str | None = None, t_end: float | None = None, solver: str = "auto",
          workers: int | None = None, scheduler=None, out=None, resume: bool = False,
          progress=None, callback=None) -> SweepResult:
    """Run a parameter study of a rig: a full factorial or random samples, in parallel.

    Parameters
    ----------
    parameters : list or dict
        What varies: ``["PATH=VALUES", ...]`` as on the command line
        (``"supply.section2.bulk_modulus=150 MPa,220 MPa"``; on a
        circuit rig ``"circuit.<component>.<parameter>=..."``, the
        unit the component declares), or ``{PATH: VALUES}`` with
        VALUES text, a list of quantities or a
        :class:`~hydroline.studies.Distribution`; the syntax (levels,
        ``linspace``, ``uniform``, ``normal``, ...) is in
        :mod:`hydroline.studies.design`
    rig : Rig, str or None
        The base rig (None: the embedded 2005 paper's rig; a shipped
        rig may be named, "two_axis")
    samples : int
        Random design of this many variants; None: full factorial
    seed : int
        Seed of the random design, [-]
    scenario : str
        One of :func:`hydroline.scenarios.scenario_names`; None: the
        rig's ``rig.scenario``, else "open-loop-step"
    t_end : float
        Simulated time per variant, [s]; the scenario's when None
    solver : str
        See :func:`hydroline.engine.integrate`
    workers : int
        Local worker processes (default: the CPU count), or the
        number of workers of a ``scheduler="local"`` Dask cluster
    scheduler : str or Client
        None: local processes; "local": a local Dask cluster;
        "tcp://host:port": an existing Dask scheduler
    out : path
        Folder for ``sweep.jsonl`` (every row as it finishes),
        ``sweep.csv`` and ``sweep.parquet``; None keeps it in memory
    resume : bool
        Continue the sweep in ``out``: keep its rows, run the rest
    progress : callable
        ``progress(done, total, failed)`` after each variant
    callback : callable
        ``callback(row)`` after each variant is recorded (an
        exception raised there stops the sweep; what is recorded
        stays recorded)

    Returns
    -------
    SweepResult
        The table of rows (a multi-axis rig's rows have per-axis columns,
        :func:`metric_columns`), the design and the files written.

    Raises
    ------
    ValueError
        (RigError, UnitError, SweepFileError) On bad input, one line naming it.
    """
    tic = _time.perf_counter()
    if not isinstance(rig, Rig):
        rig = load_rig(rig)
    scenario = scenario or default_scenario(rig)
    if scenario not in scenario_names(rig):
        raise RigError(f"--scenario: unknown scenario {scenario!r} (known: "
                       f"{', '.join(scenario_names(rig))})")
    if t_end is not None and not t_end > 0:
        raise RigError(f"--t-end must be > 0 s, got {t_end!r}")
    params = parse_parameters(parameters, rig)
    design = Design(params, samples, seed)
    check_levels(rig, params)      # before the first variant: a level no variant could run
    workers = (os.cpu_count() or 1) if workers is None else int(workers)
    if not 1 <= workers <= MAX_WORKERS:
        raise RigError(f"--workers must be within 1 ... {MAX_WORKERS} [-] (processes on this "
                       f"machine or Dask workers), got {workers}")
    units = {path: p.unit for p in params for path in p.paths}
    axes = _axis_names(rig)
    header = journal_header(rig, design, scenario, t_end, solver)
    runner = VariantRunner(rig, scenario, t_end, solver, units, axes)

    client = cluster = None
    owned = False
    if scheduler is not None:      # connect first: an unreachable cluster leaves no files
        client, cluster, owned = dask_client(scheduler, workers)
    try:
        return _sweep(runner, design, header, workers, client, out, resume, progress, callback,
                      tic)
    finally:
        if owned:
            client.close()
        if cluster is not None:
            cluster.close()


def _axis_names(rig: Rig) -> list[str]:
    """The rig's servo axes (names); [] where the rig cannot be built (every variant then
    fails with its own reason, in the single-axis columns)."""
    from ..system import build_circuit

    try:
        return list(build_circuit(rig).axes)
    except Exception:
        return []


def _sweep(runner, design, header, workers, client, out, resume, progress, callback,
           tic) -> SweepResult:
    scenario, axes = runner.scenario, runner.axes
    rows: dict = {}
    files: dict = {}
    journal = None
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        jpath = out / JOURNAL_NAME
        files["journal"] = jpath
        old_header, old_rows = read_journal(jpath)
        if old_header is not None and not resume:
            raise SweepFileError(f"{jpath} exists: pass --resume to continue that sweep, or "
                                 f"choose another --out")
        if old_header is not None:
            check_same_sweep(jpath, old_header, header)
            check_same_inputs(jpath, old_rows, design)
            rows.update(old_rows)
            journal = Journal(jpath)
        else:
            journal = Journal(jpath, header)
    elif resume:
        raise RigError("--resume needs --out DIR (the folder of the sweep to continue)")

    total = len(design)
    tasks = [(i, design.variant(i)) for i in range(total) if i not in rows]
    done = [sum(1 for i in rows if i < total)]
    failed = [sum(1 for i, r in rows.items() if i < total and r.get("error"))]
    computed = [0]

    def record(row):
        i = row["variant"]
        rows[i] = row
        if journal is not None:
            journal.append(row)
        computed[0] += 1
        done[0] += 1
        failed[0] += bool(row.get("error"))
        if progress is not None:
            progress(done[0], total, failed[0])
        if callback is not None:
            callback(row)

    def failed_variant(index, values, reason):
        return failed_row(index, values, reason, scenario, axes)

    if progress is not None:
        progress(done[0], total, failed[0])
    try:
        if not tasks:
            pass
        elif client is not None:
            run_dask(tasks, client, runner, record, failed_variant)
        elif workers == 1 or len(tasks) == 1:
            run_serial(tasks, runner, record)
        else:
            run_processes(tasks, min(workers, len(tasks)), runner, record, failed_variant)
    finally:
        if journal is not None:
            journal.close()
        table = _table(rows, design, scenario, axes)
        notes = []
        extra = sorted(i for i in rows if i >= total)
        if extra:           # a random design resumed with a smaller --samples: kept in the file
            notes.append(f"{len(extra)} variants of an earlier, larger run ({total}..{extra[-1]}) "
                         f"stay in {JOURNAL_NAME} but not in the table, which holds the "
                         f"{total} of this design; resume with --samples {extra[-1] + 1} to "
                         f"include them")
        if out is not None:
            _write_tables(table, out, files, notes)
    return SweepResult(table, design, computed[0], _time.perf_counter() - tic, files,
                       complete=len(table) == total, notes=notes,
                       metrics=metric_columns(axes, scenario), axes=list(axes), scenario=scenario)
