"""Calibrate rig parameters to measured time series by nonlinear least squares.

Measured data (CSV)
-------------------
One header row of ``name [unit]`` columns, one row per sample; any unit of the right
dimension is accepted (``time [ms]``, ``valve_current [mA]``, ``supply_port_pressure [MPa]``,
``piston_position [mm]``). Pressures are absolute (see :mod:`hydroline.units`).

==========================  ============  ==========================================
column                      unit (SI)     meaning
==========================  ============  ==========================================
``time``                    s             strictly increasing (required)
``valve_current``           A             servovalve coil current, drives the model (required)
``supply_port_pressure``    Pa            valve P port
``return_port_pressure``    Pa            valve T port
``bottom_chamber_pressure`` Pa            actuator bottom chamber
``top_chamber_pressure``    Pa            actuator top chamber
``piston_position``         m             from mid-stroke, up +
``piston_velocity``         m/s           up +
``external_force``          N             load force on the rod, positive down (friction ID)
==========================  ============  ==========================================

At least one measured signal besides the current is needed; columns with other names are
ignored (and listed). Bad data -- a missing column, a column without a unit, time not
strictly increasing, NaN or non-numeric entries -- raise :class:`DataError` with one line
naming the file, column and row.

Model of the experiment
-----------------------
The measured valve current drives the open-loop network through a
:class:`~hydroline.components.TableCommand` (piecewise linear between samples). The record
must start at rest. If the piston position is measured and clear of the stops at the first
sample, the model starts from the operating point that holds it there (the current that
holds it is solved for, and the model's current is the measured one shifted by the
difference: a null offset of the real valve is absorbed). Otherwise it starts from the
network's steady state at the first sample's current (piston on a stop, or against a
spring).

Estimation
----------
Parameters are fitted as ``theta = ln(value)`` (positive, scale-free) by
``scipy.optimize.least_squares`` (trust-region reflective, finite-difference Jacobian) on the
residuals ``(y_model - y_measured)/sigma_c``, with ``sigma_c`` each channel's noise level
estimated from the data (median absolute second difference, which a smooth signal sampled
densely does not reach). With ``J`` the Jacobian at the optimum and ``s^2 = SSR/(N - k)``,
``cov(theta) = s^2 (J^T J)^-1`` and the confidence interval of a parameter is
``exp(theta +- t_{N-k} sqrt(cov_ii))`` (asymmetric in the value). They assume white noise and
a right model; real residuals are correlated in time, which makes them optimistic.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .. import components as comp
from ..rigs import SCHEMA, Rig, RigError, load_rig
from ..engine import integrate, solve_steady_state
from ..units import csv_column, split_header
from .linearize import (VALVE_COMMAND, OperatingPoint, axis_network, axis_signal, select_axis,
                        solve_operating_point, transfer_state)

__all__ = ["DataError", "COLUMNS", "MEASURABLE", "read_measurements", "Measurements",
           "FitResult", "fit_parameters", "simulate_record", "parameter_unit", "noise_level",
           "STARTS", "residual_correlation"]

#: Columns understood in a measurement file: name -> SI unit.
COLUMNS = {
    "time": "s",
    "valve_current": "A",
    "supply_port_pressure": "Pa",
    "return_port_pressure": "Pa",
    "bottom_chamber_pressure": "Pa",
    "top_chamber_pressure": "Pa",
    "piston_position": "m",
    "piston_velocity": "m/s",
    "external_force": "N",
}
#: Columns a fit compares with the model.
MEASURABLE = ("supply_port_pressure", "return_port_pressure", "bottom_chamber_pressure",
              "top_chamber_pressure", "piston_position", "piston_velocity")


class DataError(ValueError):
    """Measured data that cannot be used; the message is one line naming file, column, row."""


@dataclass
class Measurements:
    """A measured record in SI units.

    Attributes
    ----------
    data : pandas.DataFrame   Columns named as in :data:`COLUMNS` (no units), SI
    source : str              Where it came from
    ignored : list[str]       Columns that were not understood
    """

    data: pd.DataFrame
    source: str = ""
    ignored: list = field(default_factory=list)

    @property
    def t(self) -> np.ndarray:
        return self.data["time"].to_numpy()

    @property
    def signals(self) -> list:
        """Measured signals a fit can use."""
        return [c for c in MEASURABLE if c in self.data]

    def to_csv(self, path):
        """Write with ``name [SI unit]`` headers."""
        self.data.rename(columns={c: f"{c} [{COLUMNS[c]}]" for c in self.data}).to_csv(path, index=False)


def read_measurements(path, required=("time", "valve_current"), need_signal: bool = True) -> Measurements:
    """Read and check a measurement CSV (see the module docstring).

    Parameters
    ----------
    path : str or Path      CSV file
    required : tuple[str]   Columns that must be present
    need_signal : bool      Require at least one of :data:`MEASURABLE`

    Returns
    -------
    Measurements  (SI units)

    Raises
    ------
    DataError  one line naming the file, column and row
    """
    src = str(path)
    if not Path(path).is_file():
        raise DataError(f"{src}: data file not found")
    try:
        raw = pd.read_csv(path, skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise DataError(f"{src}: not a readable CSV file ({str(e).strip().splitlines()[0]})") from None
    cols, ignored = {}, []
    for col in raw.columns:
        name, _ = split_header(col)
        if name not in COLUMNS:
            ignored.append(str(col))
            continue
        if name in cols:
            raise DataError(f"{src}: column '{name}' appears twice")
        try:
            values = csv_column(raw, col, COLUMNS[name], src)
        except ValueError as e:
            raise DataError(str(e)) from None
        cols[name] = values
    for name in required:
        if name not in cols:
            raise DataError(f"{src}: missing column '{name} [{COLUMNS[name]}]' "
                            f"(columns: {', '.join(map(str, raw.columns))})")
    if need_signal and not any(c in cols for c in MEASURABLE):
        raise DataError(f"{src}: no measured signal; give at least one of "
                        + ", ".join(f"'{c} [{COLUMNS[c]}]'" for c in MEASURABLE))
    n = len(raw)
    if n < 3:
        raise DataError(f"{src}: needs at least 3 rows of data, got {n}")
    if "time" in cols:
        dt = np.diff(cols["time"])
        bad = np.flatnonzero(dt <= 0)
        if bad.size:
            k = int(bad[0]) + 1
            raise DataError(f"{src}: column 'time' must increase strictly; data row {k + 1} "
                            f"(t = {cols['time'][k]:.6g} s) is not after row {k} "
                            f"(t = {cols['time'][k - 1]:.6g} s)")
    return Measurements(pd.DataFrame(cols), src, ignored)


def noise_level(y) -> float:
    """Measurement noise sigma from the median absolute second difference, [unit of y].

    For white noise of sigma s, the second difference has sigma ``sqrt(6) s``; a smooth
    signal sampled densely adds little to it. Returns 0 for a noise-free trace.
    """
    y = np.asarray(y, dtype=float)
    if len(y) < 5:
        return 0.0
    d2 = np.diff(y, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0))


def parameter_unit(rig: Rig, path: str) -> str:
    """SI unit of a numeric rig parameter that can be fitted, or RigError naming it.

    Parameters
    ----------
    rig : Rig    The rig
    path : str   Rig path: a template parameter (``supply.section2.bulk_modulus``) or a circuit
                 component's (``circuit.axis2.supply_hose.bulk_modulus``)
    """
    section, _, key = path.rpartition(".")
    unit = SCHEMA.get(section, {}).get(key)
    if path.startswith("circuit.") and f"{section}.type" in rig.raw:
        from ..circuit.types import COMPONENT_TYPES

        own = {k[len(section) + 1:]: v for k, v in rig.raw.items() if k.startswith(section + ".")}
        unit = COMPONENT_TYPES[rig.raw[f"{section}.type"]].unit_of(key, own)
    if unit is None:
        raise RigError(f"--params: unknown rig parameter '{path}' (e.g. supply.section2.bulk_modulus, "
                       f"supply.manifold.resistance, friction.viscous_up)")
    if unit == "str" or unit.startswith("list:"):
        raise RigError(f"--params: '{path}' is not a number and cannot be fitted")
    if path not in rig:
        raise RigError(f"--params: '{path}' is not set in rig {rig.source}; give it a starting "
                       f"value [{unit}] there")
    if not rig[path] > 0:
        raise RigError(f"--params: '{path}' must start > 0 [{unit}] to be fitted (on a log scale), "
                       f"got {rig[path]!r}")
    return unit


def _set(rig: Rig, path: str, value: float):
    unit = parameter_unit(rig, path)
    rig.set(path, float(value) if unit == "-" else f"{float(value)!r} {unit}")


@dataclass
class _Start:
    network: object
    x: np.ndarray
    p: np.ndarray


def _initial_value(meas: Measurements, column: str) -> float:
    """Mean of a column over the record's quiet start: the samples before the valve current
    first moves from its initial value (at most 50 samples, at least 1), [SI]."""
    y = meas.data[column].to_numpy()
    i = meas.data["valve_current"].to_numpy()
    tol = max(1e-3 * np.ptp(i), 10 * noise_level(i), 1e-12)
    moved = np.flatnonzero(np.abs(i - i[0]) > tol)
    n = int(min(moved[0] if moved.size else len(y), 50))
    return float(np.mean(y[:max(n, 1)]))


#: How a record's model starts: "auto", "rest" (steady state at the first current), "hold"
#: (the measured initial position held by the solved current).
STARTS = ("auto", "rest", "hold")


def start_mode(rig: Rig, meas: Measurements, start: str = "auto", axis: str | None = None) -> str:
    """"hold" or "rest": how a record's model starts (module docstring).

    Parameters
    ----------
    rig : Rig              The rig
    meas : Measurements    The record
    start : str            "auto", "rest" or "hold"
    axis : str             The axis the record is of (None: the first)
    """
    if start not in STARTS:
        raise ValueError(f"start must be one of {', '.join(STARTS)}; got {start!r}")
    x0 = _initial_value(meas, "piston_position") if "piston_position" in meas.data else None
    if start == "hold" and x0 is None:
        raise DataError(f"{meas.source}: start 'hold' needs a 'piston_position [m]' column")
    if start == "auto":
        half = select_axis(rig, axis).stroke / 2
        return "hold" if x0 is not None and abs(x0) < half - 1e-3 else "rest"
    return start


def _start(rig: Rig, meas: Measurements, times, current, start: str = "auto", axis=None):
    """Network and initial state of the record's model (module docstring)."""
    t0 = meas.t[0]
    ax = select_axis(rig, axis)
    half = ax.stroke / 2
    x0 = _initial_value(meas, "piston_position") if "piston_position" in meas.data else None
    if start_mode(rig, meas, start, ax.name) == "hold":
        hold = solve_operating_point(rig, OperatingPoint(piston_position=float(x0)), axis=ax.name)
        values = current - current[0] + hold.valve_current
        cmd = comp.TableCommand(name=VALVE_COMMAND, quantity="current", times=times - t0, values=values,
                                connections={"command": ax.current})
        net = axis_network(rig, [cmd], ax.name, float(x0))
        x, p = transfer_state(hold, net)
        return _Start(net, x, p)
    cmd = comp.TableCommand(name=VALVE_COMMAND, quantity="current", times=times - t0, values=current,
                            connections={"command": ax.current})
    # on a stop: the measured position may lie a hair beyond it (the stop's compliance, M23)
    guess = float(np.clip(x0, -half, half)) if x0 is not None and abs(x0) >= half - 1e-3 else None
    net = axis_network(rig, [cmd], ax.name, guess)
    ss = solve_steady_state(net, t0=0.0)
    return _Start(net, ss.x, ss.p)


def simulate_record(rig: Rig, meas: Measurements, signals=None, rtol: float = 1e-8,
                    start: str = "auto", axis: str | None = None) -> dict:
    """The model's response to a record's valve current, at the record's sample times.

    Parameters
    ----------
    rig : Rig
    meas : Measurements   The record (its ``valve_current`` drives the model)
    signals : list[str]   Signals to return (the record's measured ones when None)
    rtol : float          Integrator tolerance
    start : str           "auto" (module docstring), "rest" (steady state at the first
                          current) or "hold" (the measured initial position held)
    axis : str            The axis the record is of (None: the first): its valve current is
                          driven, the record's columns are its signals, the others hold

    Returns
    -------
    dict  signal -> array at ``meas.t``, [SI]
    """
    signals = meas.signals if signals is None else list(signals)
    t = meas.t
    ax = select_axis(rig, axis)
    st = _start(rig, meas, t, meas.data["valve_current"].to_numpy(), start, ax.name)
    span = t[-1] - t[0]
    dt = float(np.median(np.diff(t)))
    n = int(np.ceil(span / dt - 1e-9))
    res = integrate(st.network, st.x, n * dt, dt_out=dt, p=st.p, rtol=rtol)
    return {k: np.interp(t - t[0], res.t, res[axis_signal(ax, k)]) for k in signals}


@dataclass
class FitResult:
    """Estimated parameters with confidence intervals.

    Attributes
    ----------
    names : list[str]          Rig paths
    units : list[str]          Their SI units
    start, estimate : ndarray  Starting and fitted values, [SI]
    ci_low, ci_high : ndarray  Confidence interval bounds, [SI]
    std_log : ndarray          Standard errors of ln(value), [-] (~ relative standard errors)
    correlation : ndarray      Correlation matrix of the estimates, [-]
    confidence : float         Confidence level of the intervals, [-]
    sigma : dict               Channel -> noise level used as weight, [SI]
    rms : dict                 Channel -> rms residual at the optimum, [SI]
    residual_variance : float  s^2 = SSR/(N - k) of the weighted residuals, [-]
    n_data : int               Residuals used
    n_evaluations : int        Model runs
    success : bool
    message : str
    fitted, initial : dict     Channel -> model trace at the optimum / at the start, [SI]
                               (channels with a free offset shown with it)
    rig : Rig                  The calibrated rig
    offsets : dict             Channel -> fitted sensor offset, measured minus model, [SI]
    """

    names: list
    units: list
    start: np.ndarray
    estimate: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    std_log: np.ndarray
    correlation: np.ndarray
    confidence: float
    sigma: dict
    rms: dict
    residual_variance: float
    n_data: int
    n_evaluations: int
    success: bool
    message: str
    fitted: dict
    initial: dict
    rig: Rig
    offsets: dict = field(default_factory=dict)

    def table(self) -> list:
        """Rows (name, unit, start, estimate, ci_low, ci_high, relative std error)."""
        return [[n, u, s, e, lo, hi, float(sd)] for n, u, s, e, lo, hi, sd in zip(
            self.names, self.units, self.start, self.estimate, self.ci_low, self.ci_high, self.std_log)]

    def to_dict(self) -> dict:
        return {
            "parameters": {n: {"unit": u, "start": float(s), "estimate": float(e),
                               "ci_low": float(lo), "ci_high": float(hi),
                               "relative_std_error": float(sd)}
                           for n, u, s, e, lo, hi, sd in self.table()},
            "confidence": self.confidence, "correlation": np.asarray(self.correlation).tolist(),
            "noise_sigma": self.sigma, "rms_residual": self.rms,
            "residual_variance": self.residual_variance, "n_data": self.n_data,
            "n_evaluations": self.n_evaluations, "success": self.success, "message": self.message,
            "sensor_offsets": self.offsets,
        }

    def calibrated_toml(self, data_source: str = "") -> str:
        """The calibrated rig as TOML, with the fit summarised in a header comment."""
        head = [f"# Calibrated by 'hydroline fit' from {data_source or 'measured data'} "
                f"({self.n_data} residuals, {100 * self.confidence:g} % confidence intervals):"]
        for n, u, s, e, lo, hi, sd in self.table():
            head.append(f"#   {n} = {e:.6g} {u}  [{lo:.4g}, {hi:.4g}]  (start {s:.6g} {u})")
        return "\n".join(head) + "\n\n" + self.rig.to_toml()


def fit_parameters(rig: Rig | str | None, meas: Measurements, params, signals=None,
                   confidence: float = 0.95, max_evaluations: int = 60, bound_factor: float = 10.0,
                   sigma: dict | None = None, start: str = "auto", offsets=None,
                   progress=None, axis: str | None = None) -> FitResult:
    """Fit rig parameters to a measured record (see the module docstring).

    Parameters
    ----------
    rig : Rig, str or None       Starting rig
    meas : Measurements          The record
    params : list[str]           Rig paths to fit (positive numbers)
    signals : list[str]          Channels compared (all measured ones when None)
    confidence : float           Level of the intervals, [-]
    max_evaluations : int        Cap on least-squares function evaluations
    bound_factor : float         Each parameter stays within start/factor ... start*factor, [-]
    sigma : dict                 Channel -> noise level [SI]; estimated from the data when None
    start : str                  How the model starts: "auto", "rest" or "hold" (see
                                 :func:`simulate_record`)
    offsets : list[str]          Channels with a free constant sensor offset, profiled out
                                 of the residuals (one degree of freedom each). Default:
                                 ``piston_position`` when the model holds the measured initial
                                 position (its noisy initial value would otherwise bias the
                                 fit), none otherwise
    progress : callable          Called with (evaluations, cost) after each model run
    axis : str                   The axis the record is of (None: the first); the record's
                                 columns (``piston_position``, ...) are its signals

    Returns
    -------
    FitResult
    """
    from scipy.optimize import least_squares
    from scipy.stats import t as student_t

    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    params = list(params)
    if not params:
        raise ValueError("--params: give at least one rig parameter to fit")
    if len(set(params)) != len(params):
        raise ValueError("--params: a parameter is listed twice")
    units = [parameter_unit(rig, k) for k in params]
    signals = meas.signals if signals is None else list(signals)
    for s in signals:
        if s not in meas.data:
            raise DataError(f"{meas.source}: no column '{s} [{COLUMNS.get(s, 'SI')}]' to fit")
    if not signals:
        raise DataError(f"{meas.source}: no measured signal to fit")
    y = {s: meas.data[s].to_numpy() for s in signals}
    if offsets is None:
        hold = start_mode(rig, meas, start, axis) == "hold"
        offsets = ["piston_position"] if hold and "piston_position" in signals else []
    offsets = [s for s in offsets if s in signals]
    if sigma is None:
        sigma = {}
        for s in signals:
            noise = noise_level(y[s])
            floor = 1e-6 * max(np.ptp(y[s]), np.max(np.abs(y[s])), 1e-12)
            sigma[s] = max(noise, floor)
    start_values = np.array([rig[k] for k in params], dtype=float)
    theta0 = np.log(start_values)
    count = {"n": 0}
    cache = {}

    def model(theta):
        key = tuple(np.round(theta, 14))
        if key in cache:
            return cache[key]
        r = rig.copy()
        for k, v in zip(params, np.exp(theta)):
            _set(r, k, v)
        try:
            out = simulate_record(r, meas, signals, start=start, axis=axis)
        except (RuntimeError, ArithmeticError):      # SteadyStateError, integration failure
            out = None
        count["n"] += 1
        cache[key] = out
        return out

    def residuals(theta):
        out = model(theta)
        if out is None:
            return np.full(sum(len(v) for v in y.values()), 1e3)
        parts = []
        for s in signals:
            r = (out[s] - y[s]) / sigma[s]
            parts.append(r - np.mean(r) if s in offsets else r)
        r = np.concatenate(parts)
        if progress:
            progress(count["n"], 0.5 * float(r @ r))
        return r

    lo, hi = theta0 - np.log(bound_factor), theta0 + np.log(bound_factor)
    initial = model(theta0)
    if initial is None:
        raise ValueError("the model does not run with the starting rig on this record")
    sol = least_squares(residuals, theta0, bounds=(lo, hi), method="trf", x_scale=1.0,
                        diff_step=1e-4, max_nfev=max_evaluations, xtol=1e-6, ftol=1e-8)
    N, k = len(sol.fun), len(params)
    dof = max(N - k - len(offsets), 1)
    s2 = float(sol.fun @ sol.fun) / dof
    J = sol.jac
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = np.full((k, k), np.inf)
    rho, inflation = residual_correlation([
        (model(sol.x)[s] - y[s]) / sigma[s] for s in signals] if model(sol.x) else [])
    note = ""
    if inflation > 1.0:
        # misfit correlated in time is model error, not white noise: N residuals carry about
        # N (1 - rho)/(1 + rho) independent ones (AR(1)), which widens the interval
        cov = cov * inflation
        note = (f"; residuals correlated in time (lag-1 autocorrelation {rho:.3f}): the misfit "
                f"is model or sampling error, not white noise, so the intervals are widened "
                f"{np.sqrt(inflation):.3g}x for the ~{N / inflation:.0f} independent residuals "
                f"and still assume the model is right (a step in the current between samples, "
                f"a stop impact in the record bias the estimate; fit the part of the record "
                f"before the piston reaches a stop)")
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, np.inf))
    tq = float(student_t.ppf(0.5 + confidence / 2, dof))
    est = np.exp(sol.x)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    fitted = dict(model(sol.x) or {})
    for s in offsets:
        if s in fitted:                 # shown with the fitted sensor offset
            fitted[s] = fitted[s] - np.mean(fitted[s] - y[s])
            if initial is not None and s in initial:
                initial = dict(initial, **{s: initial[s] - np.mean(initial[s] - y[s])})
    calibrated = rig.copy()
    for name, v in zip(params, est):
        _set(calibrated, name, v)
    rms = {s: float(np.sqrt(np.mean((fitted[s] - y[s]) ** 2))) for s in signals} if fitted else {}
    offset_values = {s: float(np.mean(y[s] - model(sol.x)[s])) for s in offsets if model(sol.x)}
    return FitResult(params, units, start_values, est, np.exp(sol.x - tq * sd), np.exp(sol.x + tq * sd), sd,
                     corr, confidence, {s: float(v) for s, v in sigma.items()}, rms, s2, N,
                     count["n"], bool(sol.success), str(sol.message) + note, fitted, initial,
                     calibrated, offset_values)


def residual_correlation(traces) -> tuple[float, float]:
    """Lag-1 autocorrelation of weighted residual traces and the variance inflation it implies.

    For AR(1) residuals of lag-1 correlation rho the variance of a mean (and of a
    least-squares estimate) is ``(1 + rho)/(1 - rho)`` times the white-noise value; a fit
    on a record whose misfit is a smooth model error (rho near 1) is otherwise as sure of
    itself as if every sample were independent.

    Parameters
    ----------
    traces : list of arrays   Weighted residuals per channel, in time order, [-]

    Returns
    -------
    (rho, inflation)  rho in [-1, 1] (0 for no data); inflation >= 1, [-]
    """
    num = den = 0.0
    for r in traces:
        r = np.asarray(r, dtype=float)
        if len(r) < 3:
            continue
        r = r - np.mean(r)
        num += float(r[1:] @ r[:-1])
        den += float(r @ r)
    if den <= 0:
        return 0.0, 1.0
    rho = float(np.clip(num / den, -1.0, 0.999))
    return rho, max((1 + rho) / (1 - rho), 1.0)
