"""Constrained design optimisation of a rig with its hoses' dynamics in the loop (issue 28).

Which section II length, bore, accumulator capacity or pre-charge, which controller gain
minimise a metric of the port pressures (``supply.amplitude_mpa``, ...) subject to others
(``supply.frequency_hz>=30``)? Every evaluation is a variant of the sweep
(:class:`hydroline.studies.sweep.VariantRunner`: the rig with its numbers changed, run on the
model shared by every variant of its structure -- the numbers are runtime parameters, nothing
is recompiled), recorded in a results file as it finishes and read back on ``resume``.

Variables and problem
---------------------
* ``vary``: ``PATH=LOW..HIGH`` with units (``"supply.section2.length=0.5 m..4 m"``), values
  read as ``hydroline sweep`` reads them (:func:`hydroline.studies.design.parse_parameter`,
  ``PATH1+PATH2`` moves both); inside the optimiser scaled to [0, 1].
* ``choose``: ``PATH=V1,V2,...`` discrete values (``"supply.section2.diameter=12.7 mm,
  19.05 mm,25.4 mm"``, e.g. SAE 100R2 bores), an index inside the optimiser.
* ``minimize``: a metric name (:func:`metric_names`): the sweep's row columns with dots
  (``supply.amplitude_mpa``, ``return.first_excursion_mpa``, ``supply.frequency_hz``,
  ``tracking_error_rms_mm``; per axis ``axis2.supply.amplitude_mpa``,
  ``axis2.position_disturbance_mm``), the linearised model's closed position loop bandwidth
  (:data:`LINEAR_METRICS`: ``position_bandwidth_hz``, per axis ``axis2.position_bandwidth_hz``,
  :func:`hydroline.analysis.loop.position_bandwidth`, computed only where asked for) or a cost
  proxy (:data:`COST_METRICS`).
* ``subject_to``: ``"METRIC<=VALUE"`` / ``"METRIC>=VALUE"``, VALUE in the unit the metric's
  name ends with.

Methods
-------
Continuous variables only (``method="local"``, the default then): a few space-filling starting
points (Latin hypercube, :mod:`scipy.stats.qmc`, seeded) and the base rig's point, then
SLSQP (:func:`scipy.optimize.minimize`) from the best of them, the constraints as inequality
constraints, gradients by forward differences of ``step`` in the scaled variables, each
gradient's points evaluated as one batch (in parallel on ``workers`` processes or Dask).
With discrete choices, or ``method="global"`` (rough objectives): every combination where
the choices alone are varied and their grid fits the budget, else differential evolution
(:func:`scipy.optimize.differential_evolution`, integrality for the choices, each generation
one batch) on the objective plus a penalty on the constraints' violation; then SLSQP on the
continuous variables at the best choice. The optimum reported is the best feasible point
evaluated (the least violating where none is).

Results file and resume
-----------------------
With ``out=DIR`` every evaluation's row (the sweep's row: inputs in SI, every metric) is
appended to ``DIR/optimize.jsonl`` (:class:`hydroline.studies.journal.Journal`). ``resume=True``
reads it back (same rig, scenario, end time, solver and varied paths; another objective or
constraint may be asked of the same evaluations) and the optimiser, deterministic for its
seed, replays the recorded points without running them and goes on where it stopped.
"""
from __future__ import annotations

import math
import re
import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..rigs import Rig, RigError, load_rig
from ..scenarios.experiments import default_scenario, scenario_names
from ..units import UnitError, convert_quantity, exact_quantity, parse_quantity
from .design import parse_parameter, parse_parameters
from .executors import MAX_WORKERS, call_runner, dask_client, failure_reason, worker_pool
from .journal import FORMAT_VERSION, Journal, check_same_sweep, read_journal, rig_hash
from .sweep import SweepFileError, VariantRunner, check_levels, failed_row, metric_columns

__all__ = ["optimize", "OptimizeResult", "Variable", "Constraint", "parse_variables",
           "parse_constraint", "metric_names", "cost_metrics", "COST_METRICS",
           "OPTIMIZE_JOURNAL", "optimised_rig_text", "optimize_figure", "BudgetExhausted",
           "pareto_front", "objective_gradient", "LINEAR_METRICS", "LinearMetricsRunner"]

#: Cost proxies computed from the rig's numbers (no simulation): the sum of every hose
#: section's length [m] and of every accumulator's gas capacity [L].
COST_METRICS = ("total_hose_length_m", "accumulator_volume_l")
#: Metrics of the linearised model (per axis ``AXIS.<name>`` on a multi-axis rig), computed
#: for an evaluation only where the objective or a constraint names them:
#: ``position_bandwidth_hz``, the -3 dB bandwidth of the closed position loop at rest at
#: mid-stroke (:func:`hydroline.analysis.loop.position_bandwidth`), [Hz].
LINEAR_METRICS = ("position_bandwidth_hz",)
#: File name of the results file inside ``out``.
OPTIMIZE_JOURNAL = "optimize.jsonl"
#: Scaled objective given to the optimiser for a failed evaluation (the base rig's is 1).
FAILED_OBJECTIVE = 1e3
#: Weight of the constraints' scaled violation in the merit of the global method, [-].
PENALTY = 1e3
#: A constraint is met within this scaled tolerance and active within ACTIVE_TOLERANCE (of
#: its bound, or of the spread of its metric over the evaluations where that is smaller: a
#: metric that hardly moves is not "at its bound" for being near it everywhere), [-].
FEASIBILITY_TOLERANCE = 1e-6
ACTIVE_TOLERANCE = 1e-3
#: Derivative-free local method (COBYQA): its first and last trust-region radius in the
#: scaled variables (range = 1), [-].
DFO_RADIUS = 0.1
DFO_FINAL_RADIUS = 1e-3
#: SLSQP stalled when it improved the scaled objective by less than this (relative), [-].
STALL_TOLERANCE = 1e-6
#: Pareto front: the lowest epsilon level above a further objective's minimum, and the
#: domination tolerance, as a fraction of that objective's range over the front, [-].
FRONT_SLACK = 1e-3
_HOSE_LENGTH = re.compile(r"^(supply|return)\.section\d+\.length$")
#: The unit of a metric, by the end of its name (``supply.amplitude_mpa``: MPa).
METRIC_SUFFIX_UNITS = {"_mpa": "MPa", "_hz": "Hz", "_mm": "mm", "_s": "s", "_m": "m", "_l": "L"}

_CONSTRAINT = re.compile(r"^\s*([A-Za-z_][\w.]*)\s*(<=|>=|<|>)\s*(\S.*?)\s*$")


class BudgetExhausted(Exception):
    """The evaluations allowed (``max_evaluations``) are used up; the optimiser stops there.

    Parameters
    ----------
    *args : str
        The message
    **kwargs : dict
        None taken (as ``Exception``).
    """


# --------------------------------------------------------------------------- the problem

@dataclass(frozen=True)
class Variable:
    """One design variable: rig path(s) set together, a range or a list of choices (SI).

    Attributes
    ----------
    paths : tuple[str]
        Rig paths that take the same value
    unit : str
        Their SI unit
    low, high : float
        Bounds of a continuous variable, [unit] (None for choices)
    choices : tuple
        Values of a discrete variable, [unit] (None for a range)
    """

    paths: tuple
    unit: str
    low: float | None = None
    high: float | None = None
    choices: tuple | None = None

    @property
    def name(self) -> str:
        """The paths joined by ``+``."""
        return "+".join(self.paths)

    @property
    def discrete(self) -> bool:
        """True for a list of choices, False for a range."""
        return self.choices is not None

    def value(self, z: float):
        """The SI value at ``z``: a range's [0, 1] (clipped), a choice's index (rounded).

        Parameters
        ----------
        z : float
            Scaled coordinate, [-]

        Returns
        -------
        object
            The value, [unit] (a number, or a choice's value).
        """
        if self.discrete:
            return self.choices[int(np.clip(round(float(z)), 0, len(self.choices) - 1))]
        return self.low + float(np.clip(z, 0.0, 1.0)) * (self.high - self.low)

    def scaled(self, value) -> float | None:
        """The scaled coordinate of an SI value; None where it is out of range (not a choice).

        Parameters
        ----------
        value : float
            [unit]

        Returns
        -------
        float or None
            The scaled coordinate, [-]; None out of range.
        """
        if self.discrete:
            return float(self.choices.index(value)) if value in self.choices else None
        if value is None or not self.low <= value <= self.high:
            return None
        return (value - self.low) / (self.high - self.low)

    def describe(self) -> str:
        """The range or choices as text with the unit.

        Returns
        -------
        str
            E.g. ``"5 m .. 20 m"`` or ``"{0.01 m, 0.02 m}"``.
        """
        def text(v):
            number, unit = shown_value(v, self.unit)
            return f"{number:g} {unit}".strip() if isinstance(number, float) else str(number)

        if self.discrete:
            return "{" + ", ".join(text(v) for v in self.choices) + "}"
        return f"{text(self.low)} .. {text(self.high)}"


def parse_variables(vary=(), choose=(), rig: Rig | None = None) -> list[Variable]:
    """Design variables from ``--vary PATH=LOW..HIGH`` and ``--choose PATH=V1,V2,...``.

    Values are read as ``hydroline sweep --set`` reads them
    (:func:`hydroline.studies.design.parse_parameter`: units as in the rig file, circuit
    paths in the unit their component declares) and checked against the parameters' bounds
    and plausible ranges (:func:`hydroline.studies.sweep.check_levels`).

    Parameters
    ----------
    vary : sequence of str
        ``"PATH=LOW..HIGH"``
    choose : sequence of str
        ``"PATH=V1,V2,..."``
    rig : Rig
        The base rig

    Returns
    -------
    list[Variable]
        The ranges first, then the choices, in the order given

    Raises
    ------
    RigError
        One line naming the option and path.
    """
    params, out = [], []
    for text in vary:
        path, eq, spec = str(text).partition("=")
        low, sep, high = spec.partition("..")
        if not (eq and sep and path.strip() and low.strip() and high.strip()):
            raise RigError(f"--vary {text!r}: expected PATH=LOW..HIGH with units, e.g. "
                           f"'supply.section2.length=0.5 m..4 m'")
        p = parse_parameter(path, [low, high], rig)
        if p.unit == "str":
            raise RigError(f"--vary {p.name}: a text parameter has no range; give its values "
                           f"with --choose")
        lo, hi = p.levels
        if not lo < hi:
            raise RigError(f"--vary {p.name}: LOW must be below HIGH, got {low.strip()}.."
                           f"{high.strip()} ({lo:g}..{hi:g} {p.unit})")
        params.append(p)
        out.append(Variable(p.paths, p.unit, float(lo), float(hi)))
    for text in choose:
        path, eq, spec = str(text).partition("=")
        if not (eq and path.strip() and spec.strip()):
            raise RigError(f"--choose {text!r}: expected PATH=V1,V2,... with units, e.g. "
                           f"'supply.section2.diameter=12.7 mm,19.05 mm'")
        p = parse_parameter(path, spec, rig)
        if p.levels is None:
            raise RigError(f"--choose {p.name}: give the values (V1,V2,...), not a distribution")
        choices = tuple(dict.fromkeys(p.levels))
        if len(choices) < 2:
            raise RigError(f"--choose {p.name}: give at least two different values")
        params.append(p)
        out.append(Variable(p.paths, p.unit, choices=choices))
    if not out:
        raise RigError("nothing to optimise: give at least one --vary PATH=LOW..HIGH or "
                       "--choose PATH=V1,V2,...")
    parse_parameters(params, rig)       # a path given twice
    if rig is not None:
        check_levels(rig, params)       # bounds and choices the rig can take
    return out


@dataclass(frozen=True)
class Constraint:
    """``metric <= bound`` or ``metric >= bound``.

    Attributes
    ----------
    metric : str
        Metric name (:func:`metric_names`)
    sense : str
        "<=" or ">="
    bound : float
        [the metric's unit, the end of its name]
    """

    metric: str
    sense: str
    bound: float

    def describe(self) -> str:
        """The constraint as text, ``METRIC<=VALUE``.

        Returns
        -------
        str
            ``METRIC<=VALUE`` or ``METRIC>=VALUE``.
        """
        return f"{self.metric}{self.sense}{self.bound:g}"

    def margin(self, value: float) -> float:
        """How far ``value`` is inside the constraint, scaled by the bound (>= 0: met), [-].

        Parameters
        ----------
        value : float
            The metric, [its unit] (NaN: failed, -inf returned)

        Returns
        -------
        float
            The margin, [-].
        """
        if not math.isfinite(value):
            return -math.inf
        scale = abs(self.bound) if self.bound != 0 else 1.0
        d = self.bound - value if self.sense == "<=" else value - self.bound
        return d / scale


def parse_constraint(text) -> Constraint:
    """A :class:`Constraint` from ``"METRIC<=VALUE"`` or ``"METRIC>=VALUE"``.

    Parameters
    ----------
    text : str or Constraint
        VALUE a plain number in the unit the metric's name ends with,
        or a quantity with a unit of that dimension ("12 Hz", "2 bar")

    Raises
    ------
    RigError
        One line naming ``--subject-to`` and the text.

    Returns
    -------
    Constraint
        The constraint (``text`` itself when it is one).
    """
    if isinstance(text, Constraint):
        return text
    m = _CONSTRAINT.match(str(text))
    if not m:
        raise RigError(f"--subject-to {text!r}: expected 'METRIC<=VALUE' or 'METRIC>=VALUE', "
                       f"e.g. 'supply.frequency_hz>=30'")
    unit = next((u for suffix, u in METRIC_SUFFIX_UNITS.items()
                 if m.group(1).lower().endswith(suffix)), None)
    try:
        bound = float(m.group(3))
    except ValueError:
        bound = math.nan
        if unit is not None:            # "12 Hz", "2 bar", "30 ms": read in the metric's unit
            try:
                bound = parse_quantity(m.group(3), unit, f"--subject-to {m.group(1)}")
            except UnitError as e:
                raise RigError(f"--subject-to {text!r}: {e}") from None
    if not math.isfinite(bound):
        raise RigError(f"--subject-to {text!r}: VALUE must be a finite number, plain in the "
                       f"unit the metric's name ends with ({', '.join(METRIC_SUFFIX_UNITS)}) or "
                       f"with a unit of that dimension")
    sense = {"<": "<=", ">": ">="}.get(m.group(2), m.group(2))
    return Constraint(m.group(1), sense, bound)


def metric_names(axes=(), scenario: str = "open-loop-step") -> list[str]:
    """The metrics an optimisation can minimise or constrain.

    Parameters
    ----------
    axes : sequence of str
        The rig's servo axes
    scenario : str
        Scenario name (closed-loop-sine adds the tracking errors)

    Returns
    -------
    list[str]
        The sweep's metric columns (:func:`hydroline.studies.sweep.metric_columns`)
        with a dot after the side (``supply.amplitude_mpa``; per axis
        ``axis2.supply.amplitude_mpa`` as they are), :data:`LINEAR_METRICS`
        (per axis ``axis2.position_bandwidth_hz``), then :data:`COST_METRICS`
    """
    axes = list(axes)
    single = len(axes) <= 1
    names = []
    for c in metric_columns(axes, scenario):
        side, _, rest = c.partition("_")
        names.append(f"{side}.{rest}" if single and side in ("supply", "return") else c)
    linear = (list(LINEAR_METRICS) if single
              else [f"{a}.{m}" for a in axes for m in LINEAR_METRICS])
    return names + linear + list(COST_METRICS)


def _linear_axis(name: str):
    """(axis or None, metric) of a linear metric's name, or None for another metric."""
    axis, _, metric = name.rpartition(".")
    return (axis or None, metric) if metric in LINEAR_METRICS else None


class LinearMetricsRunner:
    """A runner that adds the linearised model's metrics (:data:`LINEAR_METRICS`) to the
    sweep's row of each evaluation.

    Called as ``runner(index, values) -> row``, like
    :class:`~hydroline.studies.sweep.VariantRunner`, and picklable like it. The simulation
    runs only where ``simulate`` (a metric of the response is asked for); a linear metric
    that cannot be computed (no operating point, no controller) is None, its reason in the
    row's ``linear_error``.

    Parameters
    ----------
    runner : callable
        The simulation's runner (``runner(index, values) -> row``)
    rig : Rig
        The base rig
    units : dict
        Rig path -> SI unit of the varied values
    metrics : list
        Linear metric names (:func:`metric_names`) to compute
    simulate : bool
        Run ``runner`` too (False: the row holds the inputs and these metrics)
    """

    def __init__(self, runner, rig: Rig, units: dict, metrics, simulate: bool = True):
        self.runner, self.rig, self.units = runner, rig, dict(units)
        self.metrics, self.simulate = list(metrics), simulate

    def __call__(self, index: int, values: dict) -> dict:
        """One evaluation's row: the simulation's (where ``simulate``) and the linear metrics."""
        from ..analysis.loop import position_bandwidth
        from .executors import failure_reason

        row = (self.runner(index, values) if self.simulate
               else {"variant": int(index), **values, "error": None})
        try:
            rig = _with_values(self.rig, values, self.units)
        except Exception as e:      # the simulation's row says why too
            rig, row["linear_error"] = None, failure_reason(e)
        for name in self.metrics:
            axis, metric = _linear_axis(name)
            row[name] = None
            if rig is None:
                continue
            try:
                if metric == "position_bandwidth_hz":
                    row[name] = position_bandwidth(rig, axis)
            except Exception as e:  # a failed linearisation: that metric is missing
                row["linear_error"] = f"{name}: {failure_reason(e)}"
        return row


def _column(name: str, axes) -> str:
    """The sweep row's column of a metric name."""
    side, dot, rest = name.partition(".")
    if len(list(axes)) <= 1 and dot and side in ("supply", "return"):
        return f"{side}_{rest}"
    return name


def cost_metrics(values: dict) -> dict:
    """The cost proxies of a rig's values: :data:`COST_METRICS`.

    Parameters
    ----------
    values : dict
        Rig path -> SI value (``Rig.values``, with the variant's values over it)

    Returns
    -------
    dict
        ``total_hose_length_m``: every hose section's length (template
        ``<side>.section<n>.length``, circuit components of type "hose"), [m];
        ``accumulator_volume_l``: every accumulator's gas capacity, [L]
    """
    types = {k[:-5]: v for k, v in values.items()
             if k.startswith("circuit.") and k.endswith(".type")}
    hose = capacity = 0.0
    for k, v in values.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            continue
        section, _, key = k.rpartition(".")
        if key == "length" and (_HOSE_LENGTH.match(k) or types.get(section) == "hose"):
            hose += float(v)
        elif key == "capacity" and (types.get(section) == "accumulator" or
                                    (not k.startswith("circuit.")
                                     and section.endswith(".accumulator"))):
            capacity += float(v)
    return {"total_hose_length_m": hose, "accumulator_volume_l": capacity * 1e3}


# --------------------------------------------------------------------------- evaluations

def _key(values: dict) -> tuple:
    return tuple(sorted((p, repr(float(v)) if isinstance(v, (int, float)) else str(v))
                        for p, v in values.items()))


class _Evaluations:
    """Every evaluation of one optimisation: rows by their inputs (from the results file
    too), run in batches, appended to the results file, counted against the budget."""

    def __init__(self, batch, paths, base_values, axes, journal, old_rows, budget):
        self.batch, self.paths, self.base_values, self.axes = batch, paths, base_values, axes
        self.journal, self.budget = journal, budget
        self.rows = {_key({p: r.get(p) for p in paths}): r for r in old_rows.values()}
        self.next_index = max(old_rows, default=-1) + 1
        self.used: dict = {}          # key -> row, in the order the optimiser asked
        self.computed = 0
        self.progress = None
        self.budget_restarts = False

    def __call__(self, points: list[dict]) -> list[dict]:
        keys = [_key(v) for v in points]
        new = [k for k in dict.fromkeys(keys) if k not in self.used]
        if len(self.used) + len(new) > self.budget:
            raise BudgetExhausted(f"{self.budget} evaluations used")
        todo = [(k, v) for k, v in dict(zip(keys, points)).items() if k not in self.rows]
        if todo:
            tasks = [(self.next_index + j, v) for j, (_, v) in enumerate(todo)]
            self.next_index += len(tasks)
            rows = self.batch(tasks)
            for (k, _), row in zip(todo, rows):
                self.rows[k] = row
                self.computed += 1
                if self.journal is not None:
                    self.journal.append(row)
        for k in new:
            self.used[k] = self.rows[k]
            if self.progress is not None:
                self.progress(len(self.used), self.budget)
        return [self.rows[k] for k in keys]

    def metric(self, row: dict, name: str) -> float:
        """A metric of a row (NaN where the variant failed or the metric does not exist)."""
        if name in COST_METRICS:
            return cost_metrics({**self.base_values,
                                 **{p: row[p] for p in self.paths if p in row}})[name]
        if row.get("error"):
            return math.nan
        v = row.get(_column(name, self.axes))
        return math.nan if v is None else float(v)


class _Problem:
    """The scaled problem the SciPy methods see: z -> rows -> objective, constraints."""

    def __init__(self, variables, objective, constraints, evaluations, scale):
        self.variables, self.objective_name = variables, objective
        self.constraints, self.ev, self.scale = constraints, evaluations, scale

    def point(self, z) -> dict:
        return {p: v.value(zi) for v, zi in zip(self.variables, z) for p in v.paths}

    def rows(self, zs) -> list[dict]:
        return self.ev([self.point(z) for z in zs])

    def objective(self, row) -> float:
        f = self.ev.metric(row, self.objective_name) / self.scale
        return f if math.isfinite(f) else FAILED_OBJECTIVE

    def margins(self, row) -> np.ndarray:
        m = np.array([c.margin(self.ev.metric(row, c.metric)) for c in self.constraints])
        return np.where(np.isfinite(m), m, -FAILED_OBJECTIVE)

    def merit(self, row) -> float:
        violation = float(np.sum(np.maximum(0.0, -self.margins(row))))
        return self.objective(row) + PENALTY * violation

    def rank(self, row) -> tuple:
        """Sort key of the best point: feasible first, then the objective (or violation)."""
        failed = not math.isfinite(self.ev.metric(row, self.objective_name))
        margins = self.margins(row)
        violation = float(np.sum(np.maximum(0.0, -margins)))
        feasible = bool(np.all(margins >= -FEASIBILITY_TOLERANCE))    # as the result's
        return (failed, not feasible, violation if not feasible else 0.0, self.objective(row))


def _forward_differences(problem: _Problem, zc, step: float, full) -> tuple:
    """The gradients SLSQP is given: forward differences of ``step`` in the scaled continuous
    coordinates ``zc`` (backward at the upper bound), the n + 1 points one batch; returns
    (d objective / dz, d margins / dz as rows per constraint), both scaled."""
    hs = np.array([step if zi + step <= 1.0 else -step for zi in zc])
    pts = [zc] + [zc + h * e for h, e in zip(hs, np.eye(len(zc)))]
    rows = problem.rows([full(p) for p in pts])
    f = np.array([problem.objective(r) for r in rows])
    c = np.array([problem.margins(r) for r in rows]).reshape(len(rows), -1)
    return (f[1:] - f[0]) / hs, ((c[1:] - c[0]) / hs[:, None]).T


def objective_gradient(vary, rig=None, *, minimize: str, at: dict | None = None,
                       step: float = 1e-3, scenario: str | None = None,
                       t_end: float | None = None, solver: str = "auto", runner=None) -> dict:
    """The gradient of a metric as the local method sees it: forward differences of ``step``
    of each range (the same code SLSQP's gradients come from), in SI units.

    Parameters
    ----------
    vary : sequence of str
        ``"PATH=LOW..HIGH"`` continuous variables with units
    rig : Rig, str or None
        The base rig (None: the embedded 2005 paper's rig)
    minimize : str
        The metric (:func:`metric_names`)
    at : dict
        Rig path -> SI value of the point (None: the base rig's values)
    step : float
        Forward-difference step in the scaled variables (range = 1), [-]
    scenario : str
        Scenario name (None: the rig's, else open-loop-step)
    t_end : float
        Simulated time per evaluation, [s]
    solver : str
        See :func:`hydroline.engine.integrate`
    runner : callable
        ``runner(index, values) -> row`` instead of the rig's simulation

    Returns
    -------
    dict
        Variable name -> d metric / d value, [the metric's unit per the variable's SI unit]
    """
    if not isinstance(rig, Rig):
        rig = load_rig(rig)
    scenario = scenario or default_scenario(rig)
    variables = parse_variables(vary, (), rig)
    axes = _axes(rig)
    units = {p: v.unit for v in variables for p in v.paths}
    if runner is None:
        runner = VariantRunner(rig, scenario, t_end, solver, units, axes)
    ev = _Evaluations(lambda tasks: [runner(i, v) for i, v in tasks], list(units),
                      dict(rig.values), axes, None, {}, math.inf)
    problem = _Problem(variables, minimize, [], ev, 1.0)
    at = {**rig.values, **(at or {})}
    z = np.array([v.scaled(at.get(v.paths[0])) for v in variables], dtype=float)
    if not np.all(np.isfinite(z)):
        raise RigError("objective_gradient: the point is outside the --vary ranges")
    g, _ = _forward_differences(problem, z, step, lambda zc: zc)
    return {v.name: float(gi) / (v.high - v.low) for v, gi in zip(variables, g)}


def _full(problem: _Problem, fixed: dict):
    """``full(zc) -> z``: the continuous coordinates ``zc`` with the fixed discrete ones."""
    cont = [i for i, v in enumerate(problem.variables) if not v.discrete]
    n = len(problem.variables)

    def full(zc):
        z = np.empty(n)
        for i, zi in fixed.items():
            z[i] = zi
        z[cont] = np.clip(zc, 0.0, 1.0)
        return z
    return cont, full


def _local(problem: _Problem, z0, fixed: dict, step: float, maxiter: int):
    """SLSQP over the continuous coordinates (``fixed``: index -> z of the discrete ones)."""
    from scipy.optimize import minimize

    cont, full = _full(problem, fixed)

    grads: dict = {}

    def gradients(zc):
        zc = np.clip(np.asarray(zc, dtype=float), 0.0, 1.0)
        key = zc.tobytes()
        if key not in grads:
            grads[key] = _forward_differences(problem, zc, step, full)
        return grads[key]

    def fun(zc):
        return problem.objective(problem.rows([full(zc)])[0])

    def cons(zc):
        return problem.margins(problem.rows([full(zc)])[0])

    constraints = ([{"type": "ineq", "fun": cons, "jac": lambda zc: gradients(zc)[1]}]
                   if problem.constraints else [])
    res = minimize(fun, np.asarray(z0, dtype=float), jac=lambda zc: gradients(zc)[0],
                   method="SLSQP", bounds=[(0.0, 1.0)] * len(cont), constraints=constraints,
                   options={"maxiter": maxiter, "ftol": 1e-6})
    return res


def _derivative_free(problem: _Problem, z0, fixed: dict, radius: float = DFO_RADIUS):
    """COBYQA (:func:`scipy.optimize.minimize`, derivative-free: a quadratic model fitted to
    the points evaluated, in a trust region from ``radius`` down to :data:`DFO_FINAL_RADIUS`
    of the scaled range) over the continuous coordinates, the constraints as nonlinear
    constraints; one evaluation at a time, until it converges or the budget is used up."""
    from scipy.optimize import Bounds, NonlinearConstraint, minimize

    cont, full = _full(problem, fixed)

    def fun(zc):
        return problem.objective(problem.rows([full(zc)])[0])

    def cons(zc):
        return problem.margins(problem.rows([full(zc)])[0])

    constraints = ([NonlinearConstraint(cons, 0.0, np.inf)] if problem.constraints else [])
    left = max(1, problem.ev.budget - len(problem.ev.used))
    z0 = np.clip(np.asarray(z0, dtype=float), 0.0, 1.0)
    return minimize(fun, z0, method="COBYQA", bounds=Bounds(0.0, 1.0),
                    constraints=constraints,
                    options={"maxfev": left + 1, "initial_tr_radius": radius,
                             "final_tr_radius": DFO_FINAL_RADIUS,
                             "feasibility_tol": FEASIBILITY_TOLERANCE})


def _best_z(problem: _Problem, cont) -> tuple:
    """(rank, scaled continuous coordinates) of the best point evaluated so far."""
    best = min(problem.ev.used.values(), key=problem.rank)
    z = [problem.variables[i].scaled(best[problem.variables[i].paths[0]]) for i in cont]
    return problem.rank(best), np.asarray(z, dtype=float)


def _stalled(res, start: tuple, after: tuple) -> bool:
    """SLSQP failed, or ended without improving on its starting point (rank ``start``; the
    best it evaluated ranks ``after``): a zero or noisy finite-difference gradient, as on a
    piecewise-constant or rough metric."""
    if not res.success:
        return True
    if after[:3] != start[:3]:          # became feasible (or less violating): progress
        return after[:3] > start[:3]
    return not after[3] < start[3] - STALL_TOLERANCE * max(1.0, abs(start[3]))


def _starts(problem: _Problem, count: int, seed: int, baseline_z) -> list:
    from scipy.stats import qmc

    cont = [i for i, v in enumerate(problem.variables) if not v.discrete]
    pts = qmc.LatinHypercube(d=len(cont), seed=seed).random(count) if count else []
    zs = [np.asarray(p, dtype=float) for p in pts]
    if baseline_z is not None:
        zs.insert(0, np.asarray([baseline_z[i] for i in cont], dtype=float))
    return zs


def _multistart(problem: _Problem, method: str, zs, rows, picked, step: float, maxiter: int,
                cont, results: list, notes: list) -> None:
    """The local runs from the starts ``picked`` (indices into ``zs``, their ``rows``):
    SLSQP, and COBYQA where it stalls, or COBYQA alone; each run's result appended to
    ``results`` and its message to ``notes`` as it goes (BudgetExhausted passes through)."""
    for k in picked:
        notes.append(f"start {k + 1}: ")
        if method == "derivative-free":
            res = _derivative_free(problem, zs[k], {})
            notes[-1] += f"COBYQA: {res.message}"
            results.append(res)
            continue
        seen = len(problem.ev.used)
        notes[-1] += "SLSQP: "
        res = _local(problem, zs[k], {}, step, maxiter)
        notes[-1] += f"{res.message}"
        after = min([problem.rank(r) for r in list(problem.ev.used.values())[seen:]]
                    + [problem.rank(rows[k])])
        if _stalled(res, problem.rank(rows[k]), after):
            zb = _best_z(problem, cont)[1]
            # a zero or noisy gradient: go on derivative-free from the best point
            notes[-1] += "; stalled, COBYQA from the best point: "
            res = _derivative_free(problem, zb, {})
            notes[-1] += f"{res.message}"
        results.append(res)


def _solve(problem: _Problem, method: str, starts: int, seed: int, step: float,
           maxiter: int, baseline_z, local_runs: int = 2) -> tuple:
    """Run the method; returns (converged, message)."""
    variables = problem.variables
    cont = [i for i, v in enumerate(variables) if not v.discrete]
    disc = [i for i, v in enumerate(variables) if v.discrete]
    try:
        if method in ("local", "derivative-free"):
            zs = _starts(problem, starts, seed, baseline_z)
            rows = problem.rows(zs)
            order = sorted(range(len(zs)), key=lambda k: problem.rank(rows[k]))
            results, notes = [], []
            try:
                _multistart(problem, method, zs, rows, order[:max(1, local_runs)], step,
                            maxiter, cont, results, notes)
            except BudgetExhausted as e:     # the runs before this one stay in the message
                notes[-1] += f"stopped: {e}"
                return False, "; ".join(notes)
            converged = all(r.success for r in results)
            return converged, "; ".join(notes)
        fixed = None
        grid = math.prod(len(variables[i].choices) for i in disc)
        if not cont and grid <= problem.ev.budget - len(problem.ev.used):
            import itertools

            zs = [np.asarray(z, dtype=float) for z in
                  itertools.product(*(range(len(v.choices)) for v in variables))]
            problem.rows(zs)
            return True, f"every one of the {grid} combinations of the choices evaluated"
        from scipy.optimize import differential_evolution

        bounds = [(0.0, 1.0) if not v.discrete else (0, len(v.choices) - 1) for v in variables]
        popsize = max(4, 8 // max(1, len(variables)) + 3)
        per_generation = popsize * len(variables)
        left = problem.ev.budget - len(problem.ev.used) - (8 * (len(cont) + 1) if cont else 0)
        generations = max(1, left // per_generation - 1)

        def merits(Z):
            Z = np.atleast_2d(Z.T if Z.ndim == 2 else Z[None, :])
            return np.array([problem.merit(r) for r in problem.rows(list(Z))])

        de = differential_evolution(
            merits, bounds, integrality=[v.discrete for v in variables], vectorized=True,
            updating="deferred", popsize=popsize, maxiter=generations, seed=seed, polish=False,
            tol=1e-3, init="latinhypercube")
        message = f"differential evolution: {de.message}"
        converged = bool(de.success)
        if cont:
            used = list(problem.ev.used.values())
            best = min(used, key=problem.rank)
            zb = [variables[i].scaled(best[variables[i].paths[0]]) for i in range(len(variables))]
            fixed = {i: zb[i] for i in disc}
            start, seen = problem.rank(best), len(problem.ev.used)
            res = _local(problem, [zb[i] for i in cont], fixed, step, maxiter)
            message += f"; SLSQP at the best choice: {res.message}"
            after = min([problem.rank(r) for r in list(problem.ev.used.values())[seen:]]
                        + [start])
            if _stalled(res, start, after):
                best = min(problem.ev.used.values(), key=problem.rank)
                zc = [variables[i].scaled(best[variables[i].paths[0]]) for i in cont]
                res = _derivative_free(problem, zc, fixed)
                message += f"; stalled, COBYQA from the best point: {res.message}"
            converged = converged and bool(res.success)
        return converged, message
    except BudgetExhausted as e:
        return False, f"stopped: {e}"


def pareto_front(solve, objectives, first, ev, points: int = 5) -> list[dict]:
    """A Pareto front by the epsilon-constraint method on the single-objective machinery.

    Each objective's minimum (subject to the user's constraints) gives the ends of the
    front; then the first objective is minimised subject to every further objective
    ``<= eps`` for ``points - 1`` levels of eps spread evenly between that objective's values
    at the ends, the lowest :data:`FRONT_SLACK` of the range above its minimum (so that end
    is the least first objective there, not a weakly dominated point; every combination of
    levels with three or more objectives), each level a problem of its own budget. Every
    problem
    reuses the evaluations of those before it (the same starts are not run again). The
    front is each problem's best feasible evaluated point, less those another dominates (by
    more than FRONT_SLACK of an objective's range over the front, no worse in the others).

    Parameters
    ----------
    solve : callable
        ``solve(metric, extra_constraints) -> (problem, converged,
        message)``: one single-objective problem (as :func:`optimize`)
    objectives : list[str]
        The metrics, at least two
    first : object
        The problem of the first objective, already solved
    ev : object
        The evaluations (rows of every point evaluated)
    points : int
        Levels of each further objective, its ends included, [-]

    Returns
    -------
    list[dict]
        ``{"variables": {PATH: SI value}, "objectives": {METRIC: value}}`` sorted by
        the first objective (its minimum first)
    """
    import itertools

    def best(problem):
        row = min(ev.used.values(), key=problem.rank)
        return row if problem.rank(row)[:2] == (False, False) else None

    anchors = [best(first)] + [best(solve(m)[0]) for m in objectives[1:]]
    ends = [r for r in anchors if r is not None]
    rows = list(ends)
    if ends:
        levels = []
        for m in objectives[1:]:
            vals = [ev.metric(r, m) for r in ends]
            lo, hi = min(vals), max(vals)
            levels.append([lo + (hi - lo) * max(k / (points - 1), FRONT_SLACK)
                           for k in range(points - 2, -1, -1)] if hi > lo else [lo])
        for eps in itertools.product(*levels):
            extra = [Constraint(m, "<=", e) for m, e in zip(objectives[1:], eps)]
            row = best(solve(objectives[0], extra)[0])
            if row is not None:
                rows.append(row)
    f = {id(r): [ev.metric(r, m) for m in objectives] for r in rows}
    tol = FRONT_SLACK * np.ptp(np.array(list(f.values())), axis=0)

    def dominated(r):       # by another point, within FRONT_SLACK of each objective's range
        a = np.array(f[id(r)])
        return any(np.all(np.array(f[id(o)]) <= a + tol) and np.any(np.array(f[id(o)]) < a - tol)
                   for o in rows)

    front, seen = [], set()
    for r in sorted(rows, key=lambda r: f[id(r)]):
        key = _key({p: r.get(p) for p in ev.paths})
        if key in seen or dominated(r):
            continue
        seen.add(key)
        front.append({"variables": {p: r.get(p) for p in ev.paths},
                      "objectives": dict(zip(objectives, f[id(r)]))})
    return front


# --------------------------------------------------------------------------- the result

@dataclass
class OptimizeResult:
    """The outcome of :func:`optimize`.

    Attributes
    ----------
    optimum : dict
        Rig path -> SI value of the best point
    objective : float
        The objective there, [its unit]
    objective_name : str
        The metric minimised
    metrics : dict
        Every metric there (:func:`metric_names`), [their units]
    evaluations : int
        Points this optimisation evaluated (from the results file too)
    n_computed : int
        Of those, run by this call
    feasible : bool
        The optimum meets every constraint
    active_constraints : list
        Constraints at their bound at the optimum (``METRIC<=VALUE``)
    at_bounds : list
        Variables at a bound of their range (``PATH=low``/``=high``)
    converged : bool
        The method ended by its convergence test (not by the budget)
    message : str
        What the method said
    method : str
        "local" or "global"
    baseline : dict
        Rig path -> SI value of the base rig
    baseline_objective : float
        The objective of the base rig, [its unit]
    baseline_metrics : dict
        Every metric of the base rig
    constraints : list[str]
        The constraints, as text
    variables : list[str]
        The variables with their ranges or choices, as text
    history : list[dict]
        Per evaluation in order: ``evaluation``, ``objective``,
        ``feasible``, ``error`` (and ``objectives`` with several)
    rig : Rig
        The base rig with the optimum set
    scenario : str
        The scenario every evaluation ran
    wall_time : float
        [s]
    files : dict
        "journal", "rig", "json", "figure" -> Path written
    objectives : list[str]
        The metrics minimised (several: a Pareto front)
    front : list[dict]
        With several objectives, the front from the first objective's
        minimum on: ``{"variables": {PATH: SI value}, "objectives":
        {METRIC: value}}`` and, once written to ``out``, ``"rig"``:
        the point's rig file name (None with one objective)
    units : dict
        Rig path -> SI unit of the varied values ("m", "m^3", "Pa")
    """

    optimum: dict
    objective: float
    objective_name: str
    metrics: dict
    evaluations: int
    n_computed: int
    feasible: bool
    active_constraints: list
    at_bounds: list
    converged: bool
    message: str
    method: str
    baseline: dict
    baseline_objective: float
    baseline_metrics: dict
    constraints: list
    variables: list
    history: list
    rig: Rig
    scenario: str
    wall_time: float = 0.0
    files: dict = field(default_factory=dict)
    objectives: list = field(default_factory=list)
    front: list | None = None
    units: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """The JSON document: ``optimum`` (PATH: SI value), ``objective``, ``metrics``,
        ``evaluations``, ``feasible``, ``active_constraints``, ``converged``, ``front`` (with
        several objectives) and the rest of the attributes but ``rig`` (files as text).

        Returns
        -------
        dict
            The document (plain numbers, texts, lists and dicts).
        """
        def plain(v):
            if isinstance(v, float) and not math.isfinite(v):
                return None
            if isinstance(v, dict):
                return {k: plain(x) for k, x in v.items()}
            if isinstance(v, list):
                return [plain(x) for x in v]
            return v.item() if isinstance(v, np.generic) else v

        d = {k: getattr(self, k) for k in (
            "optimum", "objective", "objective_name", "metrics", "evaluations", "n_computed",
            "feasible", "active_constraints", "at_bounds", "converged", "message", "method",
            "baseline", "baseline_objective", "baseline_metrics", "constraints", "variables",
            "scenario", "wall_time", "history", "objectives", "units")}
        if self.front is not None:
            d["front"] = self.front
        d["files"] = {k: str(p) for k, p in self.files.items()}
        return plain(d)


def optimised_rig_text(rig: Rig, optimum: dict, units: dict, why: str) -> str:
    """The rig file of the optimum: the base rig's TOML (:meth:`Rig.to_toml`) with each
    changed value set and commented ``# optimised for WHY (was OLD)``.

    Parameters
    ----------
    rig : Rig
        The base rig
    optimum : dict
        Rig path -> SI value
    units : dict
        Rig path -> SI unit
    why : str
        What it was optimised for (the objective and constraints)

    Returns
    -------
    str
        TOML text
    """
    opt = _with_values(rig, optimum, units)
    lines, section = [], ""
    for line in opt.to_toml().splitlines():
        if line.startswith("[") and line.endswith("]"):
            section = line[1:-1]
        key = line.partition(" = ")[0]
        path = f"{section}.{key}" if section else key
        if " = " in line and path in optimum:
            old = rig.raw.get(path)
            was = f" (was {old})" if old is not None else ""
            line = f"{line}   # optimised for {why}{was}"
        lines.append(line)
    return "\n".join(lines) + "\n"


def _with_values(rig: Rig, values: dict, units: dict) -> Rig:
    r = rig.copy()
    for path, v in values.items():
        unit = units[path]
        r.set(path, v if unit in ("-", "str") else exact_quantity(v, unit))
    return r


#: The unit a person reads a varied value in, by its SI unit.
SHOWN_UNITS = {"m^3": "L", "Pa": "MPa", "m^3/s": "L/min"}


def shown_value(value, unit):
    """A varied value in the unit a person reads it in: ``0.002951`` m^3 as ``(2.951, "L")``.

    Parameters
    ----------
    value : float or str
        The value, [unit] (SI); a discrete choice that is not a number is returned as is
    unit : str or None
        Its SI unit as in :attr:`Variable.unit` ("m", "m^3", "Pa", "-", "str")

    Returns
    -------
    tuple
        ``(value, unit)``: the value in the shown unit and that unit ("" for none)
    """
    if not isinstance(value, (int, float)) or isinstance(value, bool) or unit in (None, "-", "str"):
        return value, ""
    if unit in SHOWN_UNITS:
        return convert_quantity(value, unit, SHOWN_UNITS[unit]), SHOWN_UNITS[unit]
    return value, unit


def _title_value(value, unit) -> str:
    number, shown = shown_value(value, unit)
    text = f"{number:.4g}" if isinstance(number, (int, float)) else str(number)
    return f"{text} {shown}".strip()


def optimize_figure(result: OptimizeResult, traces=None, path=None):
    """The report figure: baseline and optimum port pressures (where ``traces`` are given),
    the objective per evaluation and the best feasible one so far, and a Pareto front
    (the first two objectives; a third as the points' colour).

    Parameters
    ----------
    result : OptimizeResult
        The optimisation's outcome
    traces : dict
        "baseline"/"optimum" -> (t [s], supply [Pa], return [Pa]), or None
    path : path
        PNG file to write (None: only return the figure)

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    from ..plotting import new_figure, save_png, tight_layout, wrap_title

    n = (3 if traces else 1) + (1 if result.front else 0)
    fig = new_figure((8, 2.5 * n + 1.0))
    axs = fig.subplots(n, 1, squeeze=False)[:, 0]
    if result.front:
        ax, axs = axs[-1], axs[:-1]
        m1, m2 = result.objectives[:2]
        pts = np.array([[np.nan if r.get(m) is None else r[m] for m in (m1, m2)]
                        for r in (h["objectives"] for h in result.history if h["feasible"])],
                       dtype=float).reshape(-1, 2)
        ax.plot(pts[:, 0], pts[:, 1], ".", ms=3, color="C7", label="evaluated")
        fr = np.array([[p["objectives"][m1], p["objectives"][m2]] for p in result.front])
        if len(result.objectives) > 2:      # a surface: the third objective as colour
            m3 = result.objectives[2]
            sc = ax.scatter(fr[:, 0], fr[:, 1], c=[p["objectives"][m3] for p in result.front],
                            s=30, cmap="viridis", label="Pareto front", zorder=3)
            fig.colorbar(sc, ax=ax, label=m3)
        else:
            ax.plot(fr[:, 0], fr[:, 1], "o-", ms=5, color="C3", label="Pareto front")
        ax.set_xlabel(m1)
        ax.set_ylabel(m2)
        ax.legend(loc="best", fontsize=8)
    if traces:
        for ax, k, side in ((axs[0], 1, "supply"), (axs[1], 2, "return")):
            for label, style in (("baseline", "C7"), ("optimum", "C0")):
                if label in traces:
                    t, *p = traces[label]
                    ax.plot(t, np.asarray(p[k - 1]) / 1e6, color=style, lw=1.0, label=label)
            ax.set_ylabel(f"{side} port [MPa]")
            ax.set_xlabel("time [s]")
            ax.legend(loc="best", fontsize=8)
    ax = axs[-1]
    k = [h["evaluation"] for h in result.history]
    f = np.array([np.nan if h["objective"] is None else h["objective"] for h in result.history])
    ok = np.array([h["feasible"] for h in result.history], dtype=bool)
    ax.plot(np.array(k)[ok], f[ok], "o", ms=3, color="C0", label="feasible")
    ax.plot(np.array(k)[~ok], f[~ok], "x", ms=4, color="C3", label="infeasible")
    best, run = [], math.inf
    for fi, oki in zip(f, ok):
        if oki and math.isfinite(fi):
            run = min(run, fi)
        best.append(run if math.isfinite(run) else np.nan)
    ax.step(k, best, where="post", color="k", lw=1.2, label="best feasible so far")
    ax.axhline(result.baseline_objective, color="C7", ls="--", lw=0.8, label="baseline")
    ax.set_xlabel("evaluation")
    ax.set_ylabel(result.objective_name)
    ax.legend(loc="best", fontsize=8)
    what = ", ".join(f"{p} = {_title_value(v, result.units.get(p))}"
                     for p, v in result.optimum.items())
    fig.suptitle(wrap_title(f"minimise {result.objective_name}: {what} "
                            f"({result.evaluations} evaluations)", 8, 10), fontsize=10)
    tight_layout(fig)
    if path is not None:
        save_png(fig, path)
    return fig


# --------------------------------------------------------------------------- the study

def optimize(vary=(), rig=None, *, choose=(), minimize: str, subject_to=(),
             scenario: str | None = None, t_end: float | None = None, solver: str = "auto",
             method: str = "auto", starts: int | None = None, local_runs: int = 2,
             max_evaluations: int | None = None, maxiter: int = 30, step: float = 1e-3,
             seed: int = 0, workers: int = 1, scheduler=None, out=None, resume: bool = False,
             figure: bool = True, runner=None, progress=None,
             front_points: int = 5) -> OptimizeResult:
    """Minimise a metric of a rig over its parameters, subject to constraints on others.

    Parameters
    ----------
    vary : sequence of str
        ``"PATH=LOW..HIGH"`` continuous variables with units
    rig : Rig, str or None
        The base rig (None: the embedded 2005 paper's rig)
    choose : sequence of str
        ``"PATH=V1,V2,..."`` discrete variables with units
    minimize : str or list
        The metric (:func:`metric_names`); several give a Pareto
        front (epsilon-constraint method, see :func:`pareto_front`):
        the optimum reported is then the first metric's minimum
    subject_to : sequence
        ``"METRIC<=VALUE"`` / ``"METRIC>=VALUE"``
    scenario : str
        Scenario name (None: the rig's, else open-loop-step)
    t_end : float
        Simulated time per evaluation, [s] (the scenario's when None)
    solver : str
        See :func:`hydroline.engine.integrate`
    method : str
        "auto" (local without choices, global with), "local", "global"
    starts : int
        Space-filling starting points of the local method (default
        3 + 2 per continuous variable), [-]
    local_runs : int
        SLSQP runs, from the best starting points (the base rig's
        among them), [-]
    max_evaluations : int
        Evaluations allowed (default 40 + 30 per variable), per
        single-objective problem of a front, [-]
    maxiter : int
        SLSQP iterations at most, [-]
    step : float
        Forward-difference step in the scaled variables (range = 1), [-]
    seed : int
        Seed of the starting points and of differential evolution
    workers : int
        Local worker processes (or workers of ``scheduler="local"``)
    scheduler : str or Client
        None, "local" or "tcp://host:port" (as :func:`sweep`)
    out : path
        Folder for optimize.jsonl, optimum.toml, optimize.json and
        optimize.png (and front_NN.toml, one rig per point of a
        Pareto front); None keeps everything in memory
    resume : bool
        Continue from the results file in ``out``
    figure : bool
        Write optimize.png (two more runs: baseline and optimum traces)
    runner : callable
        ``runner(index, values) -> row`` instead of the rig's
        simulation (:class:`~hydroline.studies.sweep.VariantRunner`);
        a surrogate or analytic model with the sweep's row columns
    progress : callable
        ``progress(evaluations, budget)`` after each new evaluation
    front_points : int
        Levels of each further objective across its range on the
        front (its two ends included), [-]

    Returns
    -------
    OptimizeResult
        The optimum, its metrics and the history of the evaluations.

    Raises
    ------
    ValueError
        (RigError, SweepFileError) on bad input, one line naming it.
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
    objectives = (list(dict.fromkeys(minimize)) if isinstance(minimize, (list, tuple))
                  else [minimize])
    if not objectives:
        raise RigError("--minimize METRIC is required, e.g. --minimize supply.amplitude_mpa")
    minimize = objectives[0]
    if len(objectives) > 1 and not 2 <= int(front_points) <= 20:
        raise RigError(f"--front-points must be within 2 ... 20 [-], got {front_points!r}")
    if method not in ("auto", "local", "derivative-free", "global"):
        raise RigError(f"--method must be auto, local, derivative-free or global, got "
                       f"{method!r}")
    variables = parse_variables(vary, choose, rig)
    constraints = [parse_constraint(c) for c in subject_to]
    axes = _axes(rig)
    known = metric_names(axes, scenario)
    for name, option in [(m, "--minimize") for m in objectives] + [(c.metric, "--subject-to")
                                                                    for c in constraints]:
        if name not in known:
            raise RigError(f"{option}: unknown metric {name!r} (known: {', '.join(known)})")
    if method == "auto":
        method = "global" if any(v.discrete for v in variables) else "local"
    if method in ("local", "derivative-free") and any(v.discrete for v in variables):
        raise RigError(f"--method {method}: the local methods take continuous variables "
                       f"only; --choose needs --method global (or auto)")
    n_cont = sum(not v.discrete for v in variables)
    starts = 3 + 2 * n_cont if starts is None else int(starts)
    budget = 40 + 30 * len(variables) if max_evaluations is None else int(max_evaluations)
    if budget < 2 or starts < 0:
        raise RigError(f"--max-evaluations must be >= 2 and --starts >= 0, got {budget}, "
                       f"{starts}")
    if not 0 < step < 0.5:
        raise RigError(f"step must be within 0 ... 0.5 (scaled variables), got {step!r}")
    workers = int(workers or 1)
    if not 1 <= workers <= MAX_WORKERS:
        raise RigError(f"--workers must be within 1 ... {MAX_WORKERS} [-], got {workers}")
    units = {p: v.unit for v in variables for p in v.paths}
    paths = list(units)
    asked = list(dict.fromkeys(objectives + [c.metric for c in constraints]))
    if runner is None:
        runner = VariantRunner(rig, scenario, t_end, solver, units, axes)
        linear = [m for m in asked if _linear_axis(m)]
        if linear:          # the linearised model's metrics: only where asked for
            runner = LinearMetricsRunner(
                runner, rig, units, linear,
                simulate=any(not _linear_axis(m) and m not in COST_METRICS for m in asked))

    header = {"hydroline_sweep": FORMAT_VERSION, "rig": rig.source, "rig_sha256": rig_hash(rig),
              "scenario": scenario, "t_end_s": t_end, "solver": solver,
              "design": {"kind": "optimize", "seed": None, "parameters": paths}}
    journal, old_rows, files = None, {}, {}
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        jpath = files["journal"] = out / OPTIMIZE_JOURNAL
        old_header, old_rows = read_journal(jpath)
        if old_header is not None and not resume:
            raise SweepFileError(f"{jpath} exists: pass --resume to continue (or reuse) that "
                                 f"optimisation's evaluations, or choose another --out")
        if old_header is not None:
            check_same_sweep(jpath, old_header, header)
            # a recorded evaluation without a metric now asked for (another objective, a
            # linear metric it did not compute) is run again
            need = [_column(m, axes) for m in asked if m not in COST_METRICS]
            old_rows = {i: r for i, r in old_rows.items() if all(c in r for c in need)}
        journal = Journal(jpath, None if old_header is not None else header)
    elif resume:
        raise RigError("--resume needs --out DIR (the folder of the optimisation to continue)")

    client = cluster = None
    owned = False
    if scheduler is not None:
        client, cluster, owned = dask_client(scheduler, workers)
    try:
        with _executor(runner, workers, client, scenario, axes) as batch:
            ev = _Evaluations(batch, paths, dict(rig.values), axes, journal, old_rows, budget)
            ev.progress = progress
            baseline = {p: rig.values.get(p) for p in paths}
            base_row = ev([baseline])[0]
            f0 = ev.metric(base_row, minimize)
            bz = [v.scaled(rig.values.get(v.paths[0])) for v in variables]
            baseline_z = None if any(z is None for z in bz) else bz

            def solve(objective, extra=()):
                """One single-objective problem on the shared evaluations, its own budget."""
                fb = ev.metric(base_row, objective)
                ev.budget = (len(ev.used) if ev.budget_restarts else 0) + budget
                ev.budget_restarts = True       # each further problem: its own budget
                p = _Problem(variables, objective, constraints + list(extra), ev,
                             abs(fb) if math.isfinite(fb) and fb != 0 else 1.0)
                return (p, *_solve(p, method, starts, seed, step, maxiter, baseline_z,
                                   local_runs))

            problem, converged, message = solve(minimize)
            front = (pareto_front(solve, objectives, problem, ev, int(front_points))
                     if len(objectives) > 1 else None)
    finally:
        if journal is not None:
            journal.close()
        if owned:
            client.close()
        if cluster is not None:
            cluster.close()

    used = list(ev.used.values())
    best = min(used, key=problem.rank)
    optimum = {p: best[p] for p in paths}
    history = []
    for k, row in enumerate(used):
        f = ev.metric(row, minimize)
        history.append({"evaluation": k + 1, "objective": f if math.isfinite(f) else None,
                        "feasible": bool(np.all(problem.margins(row) >= -FEASIBILITY_TOLERANCE)),
                        "error": row.get("error")})
        if len(objectives) > 1:
            history[-1]["objectives"] = {
                m: (lambda x: x if math.isfinite(x) else None)(ev.metric(row, m))
                for m in objectives}
    margins = problem.margins(best)
    every = np.array([problem.margins(r) for r in used]).reshape(len(used), len(constraints))
    every = np.where(every > -FAILED_OBJECTIVE, every, np.nan)    # failed evaluations out
    spreads = [float(np.nanmax(col) - np.nanmin(col)) if np.any(np.isfinite(col)) else 1.0
               for col in every.T]
    at_bounds = []
    for v in variables:
        if not v.discrete:
            z = v.scaled(best[v.paths[0]])
            if z is not None and z <= 1e-6:
                at_bounds.append(f"{v.name}=low")
            elif z is not None and z >= 1 - 1e-6:
                at_bounds.append(f"{v.name}=high")

    def all_metrics(row):
        return {m: (lambda x: x if math.isfinite(x) else None)(ev.metric(row, m)) for m in known}

    result = OptimizeResult(
        optimum=optimum, objective=ev.metric(best, minimize), objective_name=minimize,
        metrics=all_metrics(best), evaluations=len(used), n_computed=ev.computed,
        feasible=bool(np.all(margins >= -FEASIBILITY_TOLERANCE)) and not best.get("error"),
        active_constraints=[c.describe() for c, m, spread in zip(constraints, margins, spreads)
                            if abs(m) <= ACTIVE_TOLERANCE * min(1.0, spread)],
        at_bounds=at_bounds, converged=converged, message=message, method=method,
        baseline=baseline, baseline_objective=f0, baseline_metrics=all_metrics(base_row),
        constraints=[c.describe() for c in constraints],
        variables=[f"{v.name} = {v.describe()}" for v in variables], history=history,
        rig=_with_values(rig, optimum, units), scenario=scenario, files=files,
        objectives=objectives, front=front, units=units)
    if out is not None:
        _write_outputs(result, rig, units, out, figure, t_end, solver, axes)
    result.wall_time = _time.perf_counter() - tic
    return result


def _axes(rig: Rig) -> list[str]:
    from ..system import build_circuit

    try:
        return list(build_circuit(rig).axes)
    except Exception:       # the base rig does not build: its evaluation says why
        return []


class _executor:
    """``batch(tasks) -> rows`` in this process, on a worker pool or on Dask, for the
    optimisation's duration (the workers keep their shared models between batches)."""

    def __init__(self, runner, workers, client, scenario, axes):
        self.runner, self.workers, self.client = runner, workers, client
        self.scenario, self.axes = scenario, axes
        self._pool = None

    def __enter__(self):
        if self.client is not None:
            runner_f = self.client.scatter(self.runner, broadcast=True)
            return lambda tasks: self._gather([self.client.submit(
                call_runner, runner_f, i, v, pure=False) for i, v in tasks], tasks)
        if self.workers > 1:
            self._pool = worker_pool(self.workers, self.runner)
            submit = self._pool.__enter__()
            return lambda tasks: self._gather([submit(i, v) for i, v in tasks], tasks)
        return lambda tasks: [self.runner(i, v) for i, v in tasks]

    def _gather(self, futures, tasks):
        rows = []
        for fut, (i, v) in zip(futures, tasks):
            try:
                rows.append(fut.result())
            except Exception as e:      # a worker that died: that evaluation failed
                rows.append(failed_row(i, v, failure_reason(e), self.scenario, self.axes))
        return rows

    def __exit__(self, *exc):
        if self._pool is not None:
            return self._pool.__exit__(*exc)
        return False


def _write_outputs(result: OptimizeResult, rig: Rig, units: dict, out: Path, figure: bool,
                   t_end, solver, axes) -> None:
    """optimum.toml, front_NN.toml (a Pareto front's points), optimize.json and optimize.png
    in ``out``."""
    import json

    why = result.objective_name + "".join(f", {c}" for c in result.constraints)
    (out / "optimum.toml").write_text(optimised_rig_text(rig, result.optimum, units, why))
    result.files["rig"] = out / "optimum.toml"
    for old in out.glob("front_*.toml"):        # an earlier run's front (resume)
        if re.fullmatch(r"front_\d+\.toml", old.name):
            old.unlink()
    for k, point in enumerate(result.front or [], 1):
        name = f"front_{k:02d}.toml"
        at = ", ".join(f"{m} = {v:.6g}" for m, v in point["objectives"].items())
        text = optimised_rig_text(rig, point["variables"], units,
                                  f"Pareto front point {k} of {len(result.front)} ({at})"
                                  + "".join(f", {c}" for c in result.constraints))
        (out / name).write_text(text)
        point["rig"] = name
        result.files[f"front_{k:02d}"] = out / name
    if figure:
        traces = {}
        try:
            from ..scenarios.running import simulate

            for label, r in (("baseline", rig), ("optimum", result.rig)):
                res = simulate(r, result.scenario, t_end, solver=solver)
                sides = []
                for side in ("supply", "return"):
                    ax = (res.metadata.get("axes") or {})
                    name = (getattr(next(iter(ax.values())), f"{side}_pressure")
                            if len(ax) > 1 else f"{side}_port_pressure")
                    sides.append(np.asarray(res[name]))
                traces[label] = (np.asarray(res.t), *sides)
        except Exception:       # a surrogate runner, or a rig that does not build: no traces
            traces = None
        optimize_figure(result, traces, out / "optimize.png")
        result.files["figure"] = out / "optimize.png"
    result.files["json"] = out / "optimize.json"
    with open(out / "optimize.json", "w") as fh:
        json.dump(result.to_dict(), fh, indent=1)
