"""Calibrate rig parameters to measured time series by nonlinear least squares.

Measured data (CSV)
-------------------
One header row of ``name [unit]`` columns, one row per sample; any unit of the right
dimension is accepted (``time [ms]``, ``valve_current [mA]``, ``supply_port_pressure [MPa]``,
``piston_position [mm]``). Pressures are absolute (see :mod:`hydroline.units`).

============================  ============  =====================================================
column                        unit (SI)     meaning
============================  ============  =====================================================
``time``                      s             strictly increasing (required)
``valve_current``             A             servovalve coil current, drives the model (required)
``supply_port_pressure``      Pa            valve P port
``return_port_pressure``      Pa            valve T port
``bottom_chamber_pressure``   Pa            actuator bottom chamber
``top_chamber_pressure``      Pa            actuator top chamber
``piston_position``           m             from mid-stroke, up +
``piston_velocity``           m/s           up +
``external_force``            N             load force on the rod, positive down (friction ID)
============================  ============  =====================================================

At least one measured signal besides the current is needed; columns with other names are
ignored (and listed). Bad data -- a missing column, a column without a unit, time not
strictly increasing, NaN or non-numeric entries -- raise :class:`DataError` with one line
naming the file, column and row.

Model of the experiment
-----------------------
The measured valve current drives the open-loop network through a
:class:`~hydroline.components.TableCommand` (:func:`command_table`): piecewise linear between
samples, except where the current changes within one sample interval by more than ten
times the change in the intervals either side (a step written by a data-acquisition card or
by ``hydroline simulate``'s step command): that is a jump at the sample that first reads the
new value, as such a command makes it. Rows on a straight line through their neighbours are
dropped, so a stepped or ramped command is a short table the compiled core integrates with
restarts at its corners (a long, noisy current is a CasADi interpolant, CVODES). The record
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
``exp(theta +- t_{N-k} sqrt(cov_ii))`` (asymmetric in the value). The start is the rig's own
values (not ``exp(ln(value))``, an ulp off). Where a fitted parameter sets a hose's line
(:func:`changes_lines`), the runs' lines are interpolated over the dissipation number
(:mod:`hydroline.lines.residue_table`, as a sweep's) instead of realised anew in each run.
The intervals assume white noise and a right model; real residuals are correlated in time,
which makes them optimistic: a lag-1 autocorrelation of the residuals widens them (AR(1)
count of independent residuals). A record
made by a simulation is exact only to its integration tolerance: the shift of the estimate
that the integration error at ``RECORD_RTOL`` (``hydroline simulate``'s) causes is added to
each standard error, so a noise-free simulated record's truth lies inside its interval. That
error is one realisation (a ppm change of a parameter changes the integrator's step
decisions): the shift is the largest of the realisations at the optimum moved by each of
``INTEGRATION_NUDGES`` in every ln(value). One realisation alone, the
optimum's, gave half the default record's actual shift once the step decisions at its
breakpoint changed.

Samples the record's sampling does not resolve in the model's traces (:func:`unresolved_samples`:
a stop impact, whose contact lasts a fraction of a millisecond) are left out of the fit, and
the result says which (``unresolved="keep"`` fits them): there a residual measures when the
event happens to within a fraction of a sample, a matter of the stop's compliance, not of
the parameters. Each signal's rms residual at the start and at the optimum is reported; one
the fit made worse than the start is named with the reason (the fit traded it against the
other signals, or the optimiser stopped worse than it started).
"""
from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import components as comp
from ..components.hose import coefficients_as_parameters
from ..rigs import SCHEMA, Rig, RigError, load_rig
from ..engine import integrate, solve_steady_state
from ..units import csv_column, csv_unit_factor, exact_quantity, split_header
from .linearize import (VALVE_COMMAND, OperatingPoint, axis_network, axis_signal, select_axis,
                        solve_operating_point, transfer_state)

__all__ = ["DataError", "COLUMNS", "MEASURABLE", "read_measurements", "Measurements",
           "FitResult", "fit_parameters", "simulate_record", "parameter_unit", "noise_level",
           "STARTS", "residual_correlation", "command_table", "unresolved_samples",
           "sample_spans", "changes_lines", "LINE_KEYS"]

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
    """Measured data that cannot be used; the message is one line naming file, column, row.

    Parameters
    ----------
    *args : str
        The message: one line naming the file, column and row.
    **kwargs : dict
        None taken (as ``ValueError``).
    """


class Measurements:
    """A measured record in SI units.

    Parameters
    ----------
    data : pandas.DataFrame or dict
        Columns named as in :data:`COLUMNS` (no units), SI: a table, or name -> 1-D array
        (read from a CSV file: the table is made from them when :attr:`data` is first read,
        and pandas imported then)
    source : str
        Where it came from
    ignored : list[str]
        Columns that were not understood

    Attributes
    ----------
    source : str
        Where it came from
    ignored : list[str]
        Columns that were not understood
    """

    def __init__(self, data, source: str = "", ignored=None):
        self._table = data
        self.source = source
        self.ignored = [] if ignored is None else ignored

    @property
    def data(self) -> "pandas.DataFrame":
        """The record as a table, columns named as in :data:`COLUMNS` (no units), SI; a
        change made to it is the record's."""
        if isinstance(self._table, dict):
            import pandas as pd

            self._table = pd.DataFrame(self._table)
        return self._table

    @data.setter
    def data(self, table):
        self._table = table

    @property
    def names(self) -> list:
        """The record's columns, named as in :data:`COLUMNS`."""
        return list(self._table.keys()) if isinstance(self._table, dict) else \
            [str(c) for c in self._table.columns]

    def column(self, name: str) -> np.ndarray:
        """One column of the record (without making its table).

        Parameters
        ----------
        name : str
            The column's name (a key of :data:`COLUMNS`)

        Returns
        -------
        numpy.ndarray
            Its values, [SI]
        """
        if isinstance(self._table, dict):
            return self._table[name]
        return self._table[name].to_numpy()

    @property
    def t(self) -> np.ndarray:
        """Sample times, [s]"""
        return self.column("time")

    @property
    def signals(self) -> list:
        """Measured signals a fit can use."""
        names = self.names
        return [c for c in MEASURABLE if c in names]

    def to_csv(self, path):
        """Write with ``name [SI unit]`` headers.

        Parameters
        ----------
        path : str or Path
            CSV file to write
        """
        self.data.rename(columns={c: f"{c} [{COLUMNS[c]}]" for c in self.data}).to_csv(path, index=False)

    def __repr__(self) -> str:
        return f"Measurements({self.source!r}: {', '.join(self.names)}; {len(self.t)} samples)"


#: A number in a CSV cell as :func:`read_measurements` reads it without pandas: spaces, a
#: sign, digits with at most one decimal point, an optional exponent (anything else: pandas
#: reads the file).
_PLAIN_NUMBER = r" *[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"


def _read_plain_csv(path):
    """A CSV record's understood columns (:data:`COLUMNS`) read without pandas (whose import
    costs a fit's first run ~0.3 s): ``(header, {header: values [unit of its header]},
    rows)``; None where the file is not a plain table of numbers in those columns (a quote
    character, a cell that is not a plain number or is missing, a row of another length, a
    header twice or empty, text that is not UTF-8), which pandas then reads as before, with
    its messages. As ``pandas.read_csv(skipinitialspace=True)``: blank lines skipped, spaces
    before a cell dropped. The numbers are Python's (correctly rounded; pandas' parser reads
    the same from the 17 significant digits ``hydroline simulate`` writes)."""
    import re

    try:
        with open(path, encoding="utf-8-sig", newline="") as f:
            text = f.read()
    except UnicodeDecodeError:
        return None
    if '"' in text:
        return None
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    lines = [line for line in text.split("\n") if line]
    if len(lines) < 2:
        return None
    header = [h.lstrip(" ") for h in lines[0].split(",")]
    width = len(header)
    if len(set(header)) != width or not all(header) or \
            any(line.count(",") != width - 1 for line in lines):
        return None
    wanted = [j for j, col in enumerate(header) if split_header(col)[0] in COLUMNS]
    last = max(wanted, default=0) + 1   # (the cells after the last one read are not split)
    body = [line.split(",", last) for line in lines[1:]]
    number = re.compile(rf"(?:{_PLAIN_NUMBER}\n)*")
    columns = {}
    for j in wanted:
        cells = [r[j] for r in body]
        if not number.fullmatch("\n".join(cells) + "\n"):
            return None
        columns[header[j]] = np.array([float(c) for c in cells])
        if not np.all(np.isfinite(columns[header[j]])):   # (an overflow: pandas' message)
            return None
    return header, columns, len(body)


def _read_table(path, src) -> "pd.DataFrame":
    """A record as a table with ``name [unit]`` columns: a CSV as it is; a Parquet file with
    its units in the metadata (``attrs["units"]``, as ``hydroline simulate --format parquet``
    writes it); a MAT file of one variable per signal with the structs ``units`` and
    ``names`` (``--format mat``)."""
    import pandas as pd

    suffix = Path(path).suffix.lower()
    try:
        if suffix == ".parquet":
            table = pd.read_parquet(path)
            units = table.attrs.get("units", {})
            return table.rename(columns={c: f"{c} [{units[c]}]" for c in table.columns
                                         if c in units})
        if suffix == ".mat":
            from scipy.io import loadmat

            mat = loadmat(path, squeeze_me=True)
            fields = {k: mat[k] for k in ("units", "names") if k in mat}
            info = {k: {n: str(v[n]) for n in v.dtype.names} if getattr(v, "dtype", None) is not None
                    and v.dtype.names else {} for k, v in fields.items()}
            cols = {}
            for var, values in mat.items():
                if var.startswith("__") or var in ("units", "names"):
                    continue
                name = info.get("names", {}).get(var, var)
                unit = info.get("units", {}).get(var)
                cols[f"{name} [{unit}]" if unit else name] = np.ravel(values)
            return pd.DataFrame(cols)
        return pd.read_csv(path, skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise DataError(f"{src}: not a readable CSV file ({str(e).strip().splitlines()[0]})") from None
    except (OSError, ValueError, TypeError) as e:   # pyarrow's and SciPy's readers
        what = "Parquet" if suffix == ".parquet" else "MAT"
        raise DataError(f"{src}: not a readable {what} file "
                        f"({str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__})") from None


def read_measurements(path, required=("time", "valve_current"), need_signal: bool = True) -> Measurements:
    """Read and check a measured record (see the module docstring): a CSV, or a Parquet or
    MAT file as ``hydroline simulate --format parquet|mat`` writes them.

    Parameters
    ----------
    path : str or Path
        CSV, ``.parquet`` or ``.mat`` file
    required : tuple[str]
        Columns that must be present
    need_signal : bool
        Require at least one of :data:`MEASURABLE`

    Returns
    -------
    Measurements
        The record, in SI units.

    Raises
    ------
    DataError
        one line naming the file, column and row
    """
    src = str(path)
    if not Path(path).is_file():
        raise DataError(f"{src}: data file not found")
    plain = None if Path(path).suffix.lower() in (".parquet", ".mat") else _read_plain_csv(path)
    if plain is not None:
        header, values, n = plain
    else:
        raw = _read_table(path, src)
        header, n = list(raw.columns), len(raw)
    cols, ignored = {}, []
    for col in header:
        name, _ = split_header(col)
        if name not in COLUMNS:
            ignored.append(str(col))
            continue
        if name in cols:
            raise DataError(f"{src}: column '{name}' appears twice")
        try:
            cols[name] = (values[col] * csv_unit_factor(col, COLUMNS[name], src)
                          if plain is not None else csv_column(raw, col, COLUMNS[name], src))
        except ValueError as e:
            raise DataError(str(e)) from None
    for name in required:
        if name not in cols:
            raise DataError(f"{src}: missing column '{name} [{COLUMNS[name]}]' "
                            f"(columns: {', '.join(map(str, header))})")
    if need_signal and not any(c in cols for c in MEASURABLE):
        raise DataError(f"{src}: no measured signal; give at least one of "
                        + ", ".join(f"'{c} [{COLUMNS[c]}]'" for c in MEASURABLE))
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
    return Measurements(cols, src, ignored)


def noise_level(y) -> float:
    """Measurement noise sigma from the median absolute second difference, [unit of y].

    For white noise of sigma s, the second difference has sigma ``sqrt(6) s``; a smooth
    signal sampled densely adds little to it. Returns 0 for a noise-free trace.

    Parameters
    ----------
    y : array_like
        The measured trace, uniformly sampled, [unit of y]

    Returns
    -------
    float
        Noise standard deviation, [unit of y]
    """
    y = np.asarray(y, dtype=float)
    if len(y) < 5:
        return 0.0
    d2 = np.diff(y, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0))


#: A change of the current within one sample interval this many times larger than the changes
#: in the intervals either side is a jump (:func:`command_table`), [-].
JUMP_RATIO = 10.0


def command_table(t, values) -> tuple:
    """A sampled command as a :class:`~hydroline.components.TableCommand` table: jumps as a
    time given twice, rows on a straight line through their neighbours dropped.

    A change within one sample interval ``(t_k-1, t_k]`` larger than ``JUMP_RATIO`` times the
    changes in the intervals either side (and than ten noise levels and 0.1 % of the range)
    is a jump at ``t_k``, the sample that first reads the new value (a data-acquisition card's
    or a step command's ``t >= time``). Elsewhere the command is linear between samples.

    Parameters
    ----------
    t : array_like
        Sample times, strictly increasing, [s]
    values : array_like
        Sampled command, [SI unit of the command]

    Returns
    -------
    (times, values) : ndarray, ndarray
        The table, [s] and [SI unit of the command]
    """
    t = np.asarray(t, dtype=float)
    v = np.asarray(values, dtype=float)
    d = np.diff(v)
    neighbours = np.maximum(np.abs(np.r_[0.0, d[:-1]]), np.abs(np.r_[d[1:], 0.0]))
    floor = max(1e-3 * np.ptp(v), 10 * noise_level(v), 1e-300)
    jump = (np.abs(d) > floor) & (np.abs(d) > JUMP_RATIO * neighbours)
    # row k+1 after a jump interval k is preceded by (t_k+1, v_k): the value held up to it
    before = np.r_[False, jump]
    times = np.repeat(t, np.where(before, 2, 1))
    vals = np.repeat(v, np.where(before, 2, 1))
    first = np.cumsum(np.where(before, 2, 1)) - np.where(before, 2, 1)
    vals[first[before]] = v[np.flatnonzero(before) - 1]
    # drop rows on the straight line through their neighbours (exactly: checked afterwards)
    scale = max(np.ptp(vals), np.max(np.abs(vals)), 1e-300)
    keep = np.ones(len(times), dtype=bool)
    inner = np.arange(1, len(times) - 1)
    t0, t1, t2 = times[inner - 1], times[inner], times[inner + 1]
    distinct = (t0 < t1) & (t1 < t2)
    with np.errstate(invalid="ignore", divide="ignore"):
        line = vals[inner - 1] + (vals[inner + 1] - vals[inner - 1]) * (t1 - t0) / (t2 - t0)
    keep[inner] = ~(distinct & (np.abs(vals[inner] - line) <= 1e-12 * scale))
    short = comp.TableCommand(name="check", times=times[keep], values=vals[keep])
    if np.max(np.abs(short.at(t) - v)) > 1e-9 * scale:
        return times, vals
    return short.times, short.values


def parameter_unit(rig: Rig, path: str) -> str:
    """SI unit of a numeric rig parameter that can be fitted, or RigError naming it.

    Parameters
    ----------
    rig : Rig
        The rig
    path : str
        Rig path: a template parameter (``supply.section2.bulk_modulus``) or a circuit
        component's (``circuit.axis2.supply_hose.bulk_modulus``)

    Returns
    -------
    str
        The parameter's SI unit (e.g. ``Pa``).

    Raises
    ------
    RigError
        One line naming the path, when it is not a fittable number of the rig.
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


#: Keys of a template rig's hose section (``supply.section2``) or a circuit's hose that set
#: its line (:class:`hydroline.lines.Line`'s numbers).
LINE_KEYS = frozenset({"length", "diameter", "bulk_modulus", "creep_compliances",
                       "retardation_times"})


def changes_lines(rig: Rig, path: str) -> bool:
    """Whether a rig parameter enters a hose's transmission line (its length, bore, wall or
    the fluid), so that a fit of it realises lines anew in each run.

    Parameters
    ----------
    rig : Rig
        The rig
    path : str
        Rig path (as :func:`parameter_unit` takes it)

    Returns
    -------
    bool
        True for the fluid's density, viscosity and bulk modulus and a hose's
        :data:`LINE_KEYS`.
    """
    section, _, key = path.rpartition(".")
    if section == "fluid":
        return key in ("density", "kinematic_viscosity", "bulk_modulus")
    if path.startswith("circuit."):
        return rig.raw.get(f"{section}.type") == "hose" and key in LINE_KEYS
    return section.rpartition(".")[2].startswith("section") and key in LINE_KEYS


def _set(rig: Rig, path: str, value: float):
    unit = parameter_unit(rig, path)
    rig.set(path, float(value) if unit == "-" else exact_quantity(value, unit))


@dataclass
class _Start:
    network: object
    x: np.ndarray
    p: np.ndarray


def _initial_value(meas: Measurements, column: str) -> float:
    """Mean of a column over the record's quiet start: the samples before the valve current
    first moves from its initial value (at most 50 samples, at least 1), [SI]."""
    y = meas.column(column)
    i = meas.column("valve_current")
    tol = max(1e-3 * np.ptp(i), 10 * noise_level(i), 1e-12)
    moved = np.flatnonzero(np.abs(i - i[0]) > tol)
    n = int(min(moved[0] if moved.size else len(y), 50))
    return float(np.mean(y[:max(n, 1)]))


#: How a record's model starts: "auto", "rest" (steady state at the first current), "hold"
#: (the measured initial position held by the solved current).
STARTS = ("auto", "rest", "hold")


def start_mode(rig: Rig, meas: Measurements, start: str = "auto", axis: str | None = None) -> str:
    """How a record's model starts, "hold" or "rest" (module docstring).

    Parameters
    ----------
    rig : Rig
        The rig
    meas : Measurements
        The record
    start : str
        "auto", "rest" or "hold"
    axis : str
        The axis the record is of (None: the first)

    Returns
    -------
    str
        "hold" (the measured initial position held) or "rest" (the steady state at the
        first current).
    """
    return _start_mode(meas, start, lambda: select_axis(rig, axis))


def _start_mode(meas: Measurements, start: str, axis_of) -> str:
    """:func:`start_mode`, the axis (``axis_of()``, an ``Axis``) found only where needed."""
    if start not in STARTS:
        raise ValueError(f"start must be one of {', '.join(STARTS)}; got {start!r}")
    x0 = _initial_value(meas, "piston_position") if "piston_position" in meas.names else None
    if start == "hold" and x0 is None:
        raise DataError(f"{meas.source}: start 'hold' needs a 'piston_position [m]' column")
    if start == "auto":
        half = axis_of().stroke / 2
        return "hold" if x0 is not None and abs(x0) < half - 1e-3 else "rest"
    return start


def _start(rig: Rig, meas: Measurements, times, current, start: str, ax):
    """Network and initial state of the record's model (module docstring); ``ax``: the
    rig's axis the record is of (:func:`select_axis`: the rig's circuit built once a run)."""
    t0 = meas.t[0]
    half = ax.stroke / 2
    x0 = _initial_value(meas, "piston_position") if "piston_position" in meas.names else None
    times, current = command_table(times - t0, current)
    if _start_mode(meas, start, lambda: ax) == "hold":
        hold = solve_operating_point(rig, OperatingPoint(piston_position=float(x0)), axis=ax.name)
        values = current - current[0] + hold.valve_current
        cmd = comp.TableCommand(name=VALVE_COMMAND, quantity="current", times=times, values=values,
                                connections={"command": ax.current})
        net = axis_network(rig, [cmd], ax.name, float(x0))
        x, p = transfer_state(hold, net)
        return _Start(net, x, p)
    cmd = comp.TableCommand(name=VALVE_COMMAND, quantity="current", times=times, values=current,
                            connections={"command": ax.current})
    # on a stop: the measured position may lie a hair beyond it (the stop's compliance, M23)
    guess = float(np.clip(x0, -half, half)) if x0 is not None and abs(x0) >= half - 1e-3 else None
    net = axis_network(rig, [cmd], ax.name, guess)
    ss = solve_steady_state(net, t0=0.0)
    return _Start(net, ss.x, ss.p)


def simulate_record(rig: Rig, meas: Measurements, signals=None, rtol: float = 1e-8,
                    start: str = "auto", axis: str | None = None,
                    atol_scale: float | None = None) -> dict:
    """The model's response to a record's valve current, at the record's sample times.

    Parameters
    ----------
    rig : Rig
        The rig.
    meas : Measurements
        The record (its ``valve_current`` drives the model)
    signals : list[str]
        Signals to return (the record's measured ones when None)
    rtol : float
        Relative tolerance of the integrator, [-]
    start : str
        "auto" (module docstring), "rest" (steady state at the first
        current) or "hold" (the measured initial position held)
    axis : str
        The axis the record is of (None: the first): its valve current is
        driven, the record's columns are its signals, the others hold
    atol_scale : float
        Absolute tolerance as a fraction of each state's typical magnitude
        (None: ``rtol``), [-]

    Returns
    -------
    dict
        Signal -> array at ``meas.t``, [SI]
    """
    signals = meas.signals if signals is None else list(signals)
    t = meas.t
    ax = select_axis(rig, axis)
    # the hoses' matrix entries as runtime parameters: a fit's runs, which differ in a hose's
    # numbers, share one compiled model instead of compiling one each (the residue line's
    # entries depend on the bulk modulus, length and bore)
    with coefficients_as_parameters():
        st = _start(rig, meas, t, meas.column("valve_current"), start, ax)
    span = t[-1] - t[0]
    dt = float(np.median(np.diff(t)))
    n = int(np.ceil(span / dt - 1e-9))
    res = integrate(st.network, st.x, n * dt, dt_out=dt, p=st.p, rtol=rtol,
                    atol_scale=rtol if atol_scale is None else atol_scale)
    return {k: np.interp(t - t[0], res.t, res[axis_signal(ax, k)]) for k in signals}


#: A sample whose second difference in a model trace exceeds this fraction of the trace's
#: range is not resolved by the record's sampling: linear interpolation between samples
#: misses the motion there by up to about an eighth of it, over 1 % of the range (a
#: sensor's accuracy), [-].
UNRESOLVED_CURVATURE = 0.08
#: What the fit does with samples the sampling does not resolve: leave them out, or keep them.
UNRESOLVED = ("window", "keep")


def unresolved_samples(traces) -> np.ndarray:
    """Samples a record's sampling does not resolve in any of the model's traces (a stop
    impact, a valve slamming): second difference over one sample above
    ``UNRESOLVED_CURVATURE`` of the trace's range, with the samples either side.

    There the residual measures when an event happens to within a fraction of a sample, not
    the parameters; the compliance of the event (a stop's) rules it.

    Parameters
    ----------
    traces : dict
        Channel -> noise-free model trace at the record's sample times, [SI]

    Returns
    -------
    numpy.ndarray of bool
        True at the unresolved samples, [-]
    """
    traces = [np.asarray(y, dtype=float) for y in traces.values()]
    n = len(traces[0]) if traces else 0
    bad = np.zeros(n, dtype=bool)
    for y in traces:
        if n >= 3 and np.ptp(y) > 0:
            bad[1:-1] |= np.abs(np.diff(y, 2)) > UNRESOLVED_CURVATURE * np.ptp(y)
    return bad | np.r_[bad[1:], False] | np.r_[False, bad[:-1]]


def sample_spans(t, mask) -> list:
    """Contiguous runs of True in ``mask`` as (first, last) times.

    Parameters
    ----------
    t : array_like
        Sample times, [s]
    mask : array_like
        True for the samples to gather, one per sample, [-]

    Returns
    -------
    list of tuple
        ``(first, last)`` time of each run of gathered samples, [s]
    """
    m = np.r_[False, np.asarray(mask, dtype=bool), False]
    edges = np.flatnonzero(np.diff(m.astype(int)))
    return [(float(t[i]), float(t[j - 1])) for i, j in zip(edges[::2], edges[1::2])]


@dataclass
class FitResult:
    """Estimated parameters with confidence intervals.

    Attributes
    ----------
    names : list[str]
        Rig paths
    units : list[str]
        Their SI units
    start, estimate : ndarray
        Starting and fitted values, [SI]
    ci_low, ci_high : ndarray
        Confidence interval bounds, [SI]
    std_log : ndarray
        Standard errors of ln(value), [-] (~ relative standard errors),
        the integration term included
    correlation : ndarray
        Correlation matrix of the estimates, [-]
    confidence : float
        Confidence level of the intervals, [-]
    sigma : dict
        Channel -> noise level used as weight, [SI]
    rms : dict
        Channel -> rms residual at the optimum over the samples
        fitted, [SI]
    residual_variance : float
        s^2 = SSR/(N - k) of the weighted residuals, [-]
    n_data : int
        Residuals used
    n_evaluations : int
        Model runs
    success : bool
        Whether the optimiser converged.
    message : str
        The optimiser's message and the notes.
    fitted, initial : dict
        Channel -> model trace at the optimum / at the start, [SI]
        (channels with a free offset shown with it)
    rig : Rig
        The calibrated rig
    offsets : dict
        Channel -> fitted sensor offset, measured minus model, [SI]
    start_rms : dict
        Channel -> rms residual at the start over the same samples, [SI]
    windows : list
        (first, last) record times of the samples left out, [s]
    integration_std_log : ndarray
        Shift of ln(value) under the integration error of a
        simulated record (``record_rtol``), [-]
    notes : list[str]
        Why the result reads as it does: samples left out, a channel
        the fit made worse than the start, widened intervals
    worse : dict
        Channel -> why its fitted rms exceeds the start's (by more
        than ``WORSE`` of the start's rms or the noise level)
    status : str
        The optimiser's own message (``message`` adds the notes)
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
    start_rms: dict = field(default_factory=dict)
    windows: list = field(default_factory=list)
    integration_std_log: np.ndarray | None = None
    notes: list = field(default_factory=list)
    worse: dict = field(default_factory=dict)
    status: str = ""

    def table(self) -> list:
        """The fit as table rows, one per parameter.

        Returns
        -------
        list of list
            ``[name, unit, start, estimate, ci_low, ci_high, relative std error]``, the
            values in the parameter's SI unit.
        """
        return [[n, u, s, e, lo, hi, float(sd)] for n, u, s, e, lo, hi, sd in zip(
            self.names, self.units, self.start, self.estimate, self.ci_low, self.ci_high, self.std_log)]

    def to_dict(self) -> dict:
        """The fit as plain JSON-ready data: each parameter's unit, start, estimate, confidence
        interval and relative standard error, the correlation matrix, noise and residuals,
        the samples left out and the notes.

        Returns
        -------
        dict
            Numbers in the parameters' own (SI) units
        """
        shift = self.integration_std_log if self.integration_std_log is not None else \
            np.zeros(len(self.names))
        return {
            "parameters": {n: {"unit": u, "start": float(s), "estimate": float(e),
                               "ci_low": float(lo), "ci_high": float(hi),
                               "relative_std_error": float(sd),
                               "integration_relative_error": float(d)}
                           for (n, u, s, e, lo, hi, sd), d in zip(self.table(), shift)},
            "confidence": self.confidence, "correlation": np.asarray(self.correlation).tolist(),
            "noise_sigma": self.sigma, "rms_residual": self.rms,
            "rms_residual_start": self.start_rms,
            "residual_variance": self.residual_variance, "n_data": self.n_data,
            "n_evaluations": self.n_evaluations, "success": self.success, "message": self.message,
            "sensor_offsets": self.offsets,
            "left_out_s": [list(w) for w in self.windows], "notes": list(self.notes),
            "worse_than_start": dict(self.worse),
        }

    def calibrated_toml(self, data_source: str = "") -> str:
        """The calibrated rig as TOML, with the fit summarised in a header comment.

        Parameters
        ----------
        data_source : str
            Where the measured data came from, named in the header
            ("measured data" when empty)

        Returns
        -------
        str
            The rig file's text
        """
        head = [f"# Calibrated by 'hydroline fit' from {data_source or 'measured data'} "
                f"({self.n_data} residuals, {100 * self.confidence:g} % confidence intervals):"]
        for n, u, s, e, lo, hi, sd in self.table():
            head.append(f"#   {n} = {e:.6g} {u}  [{lo:.4g}, {hi:.4g}]  (start {s:.6g} {u})")
        return "\n".join(head) + "\n\n" + self.rig.to_toml()


#: A signal's fitted rms residual above the start's by more than this fraction of the larger
#: of the start's rms and the signal's noise level is reported as worse than the start, with
#: the reason (less is invisible beside the noise), [-].
WORSE = 0.01
#: Relative tolerance and absolute tolerance scale a simulated record is taken to be accurate
#: to: ``hydroline simulate``'s (:func:`hydroline.scenarios.simulate`'s defaults), [-].
RECORD_RTOL = 1e-6
RECORD_ATOL_SCALE = 1e-7
#: Moves of every ln(value) from the optimum at which a simulated record's integration error
#: is realised, the intervals carrying the largest shift of the estimate among them: far
#: below any interval, enough to change the integrator's step decisions, [-].
INTEGRATION_NUDGES = (0.0, -1e-5, 2e-5)


def fit_parameters(rig: Rig | str | None, meas: Measurements, params, signals=None,
                   confidence: float = 0.95, max_evaluations: int = 60, bound_factor: float = 10.0,
                   sigma: dict | None = None, start: str = "auto", offsets=None,
                   progress=None, axis: str | None = None, unresolved: str = "window",
                   record_rtol: float = RECORD_RTOL, on_fitted=None) -> FitResult:
    """Fit rig parameters to a measured record (see the module docstring).

    Parameters
    ----------
    rig : Rig, str or None
        Starting rig
    meas : Measurements
        The record
    params : list[str]
        Rig paths to fit (positive numbers)
    signals : list[str]
        Channels compared (all measured ones when None)
    confidence : float
        Level of the intervals, [-]
    max_evaluations : int
        Cap on least-squares function evaluations
    bound_factor : float
        Each parameter stays within start/factor ... start*factor, [-]
    sigma : dict
        Channel -> noise level [SI]; estimated from the data when None
    start : str
        How the model starts: "auto", "rest" or "hold" (see
        :func:`simulate_record`)
    offsets : list[str]
        Channels with a free constant sensor offset, profiled out
        of the residuals (one degree of freedom each). Default:
        ``piston_position`` when the model holds the measured initial
        position (its noisy initial value would otherwise bias the
        fit), none otherwise
    progress : callable
        Called with (evaluations, cost) after each model run
    axis : str
        The axis the record is of (None: the first); the record's
        columns (``piston_position``, ...) are its signals
    unresolved : str
        "window": leave out the samples the record's sampling does not
        resolve in the model's traces (:func:`unresolved_samples`, a
        stop impact), at the start and again at the optimum (the fit is
        redone once if they moved); "keep": fit every sample
    record_rtol : float
        Integration tolerance a simulated record is accurate to
        (``hydroline simulate``'s): the shift of the estimate under
        that integration error is added in quadrature to each
        standard error (negligible beside a sensor's noise), [-]
    on_fitted : callable
        Called once the traces the result shows are known, before the run that
        measures the integration error (the command line's figure is drawn meanwhile),
        with a dict of the result's ``sigma``, ``initial``, ``fitted``, ``rms``,
        ``start_rms``, ``windows`` and ``worse`` (as :class:`FitResult` holds them)

    Returns
    -------
    FitResult
        Estimates, intervals, residuals and the calibrated rig.
    """
    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    params = list(params)
    if not params:
        raise ValueError("--params: give at least one rig parameter to fit")
    if len(set(params)) != len(params):
        raise ValueError("--params: a parameter is listed twice")
    if unresolved not in UNRESOLVED:
        raise ValueError(f"unresolved must be one of {', '.join(UNRESOLVED)}; got {unresolved!r}")
    units = [parameter_unit(rig, k) for k in params]
    signals = meas.signals if signals is None else list(signals)
    for s in signals:
        if s not in meas.names:
            raise DataError(f"{meas.source}: no column '{s} [{COLUMNS.get(s, 'SI')}]' to fit")
    if not signals:
        raise DataError(f"{meas.source}: no measured signal to fit")
    y = {s: meas.column(s) for s in signals}
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
    # a fit of a line's numbers realises its lines anew in each run: there they are
    # interpolated over the dissipation number as a sweep's are (within 1e-5 of each state
    # equation's largest entry; the default record's estimates move by 5e-9-1e-8 of their
    # value, their intervals' half-widths are ~2.5e-6), from nodes kept on disk and shipped
    # for the default rig's hoses
    if any(changes_lines(rig, k) for k in params):
        from ..lines.residue_table import interpolated_lines as lines_realised
    else:
        lines_realised = nullcontext
    count = {"n": 0}
    cache = {}

    def values(theta):
        """The parameters' values at ``theta``: the rig's own where ``theta`` is the start's
        (``exp(log(v))`` may miss ``v`` by an ulp, and with it the line realisations the
        starting rig shares with a simulation of it, shipped or cached), [SI]."""
        return np.where(theta == theta0, start_values, np.exp(theta))

    def calibrated(theta):
        r = rig.copy()
        for k, v in zip(params, values(theta)):
            _set(r, k, v)
        return r

    def run(theta, **tolerances):
        """The record's traces at ``theta`` (simulate_record's tolerances by default)."""
        count["n"] += 1
        with lines_realised():
            return simulate_record(calibrated(theta), meas, signals, start=start, axis=axis,
                                   **tolerances)

    def model(theta):
        key = tuple(np.round(theta, 14))
        if key in cache:
            return cache[key]
        try:
            out = run(theta)
        except (RuntimeError, ArithmeticError):      # SteadyStateError, integration failure
            out = None
        cache[key] = out
        return out

    def weighted(out, use):
        """Weighted residuals of the used samples, channel by channel (offsets profiled)."""
        parts = []
        for s in signals:
            r = ((out[s] - y[s]) / sigma[s])[use]
            parts.append(r - np.mean(r) if s in offsets else r)
        return parts

    n_samples = len(meas.t)
    use = np.ones(n_samples, dtype=bool)

    def residuals(theta):
        out = model(theta)
        if out is None:
            return np.full(len(signals) * int(use.sum()), 1e3)
        r = np.concatenate(weighted(out, use))
        if progress:
            progress(count["n"], 0.5 * float(r @ r))
        return r

    lo, hi = theta0 - np.log(bound_factor), theta0 + np.log(bound_factor)
    initial = model(theta0)
    if initial is None:
        raise ValueError("the model does not run with the starting rig on this record")
    # (SciPy's optimiser, ~0.3 s to import, after the first run: the command line's fit
    # imports it while that run waits for its compiled library, compiled.many_runs)
    from scipy.optimize import least_squares
    # Student's t quantile: stdtrit is what scipy.stats.t.ppf computes, without the import of
    # scipy.stats (~0.3 s: its distributions' docstrings are assembled at import)
    from scipy.special import stdtrit
    left_out = unresolved_samples(initial) if unresolved == "window" else np.zeros(n_samples, bool)

    def solve(x0, nfev):
        return least_squares(residuals, x0, bounds=(lo, hi), method="trf", x_scale=1.0,
                             diff_step=1e-4, max_nfev=nfev, xtol=1e-6, ftol=1e-8)

    use = ~left_out
    sol = solve(theta0, max_evaluations)
    if unresolved == "window" and model(sol.x) is not None:
        moved = unresolved_samples(model(sol.x)) & ~left_out
        if moved.any() and count["n"] < max_evaluations:   # the events moved: fit once more
            left_out |= moved
            use = ~left_out
            sol = solve(sol.x, max(max_evaluations - count["n"], 2))
    if use.sum() < len(params) + 2:
        raise DataError(f"{meas.source}: too few samples the sampling resolves to fit "
                        f"({int(use.sum())}); try unresolved='keep' (--keep-unresolved)")
    N, k = len(sol.fun), len(params)
    dof = max(N - k - len(offsets), 1)
    s2 = float(sol.fun @ sol.fun) / dof
    J = sol.jac
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = np.full((k, k), np.inf)
    best = model(sol.x)
    notes = []
    rho, inflation = residual_correlation(weighted(best, use) if best else [])
    if inflation > 1.0:
        # misfit correlated in time is model error, not white noise: N residuals carry about
        # N (1 - rho)/(1 + rho) independent ones (AR(1)), which widens the interval
        cov = cov * inflation
        notes.append(f"residuals correlated in time (lag-1 autocorrelation {rho:.3f}): the "
                     f"misfit is model, integration or sampling error, not white noise, so the "
                     f"intervals are widened {np.sqrt(inflation):.3g}x for the "
                     f"~{N / inflation:.0f} independent residuals and still assume the model "
                     f"is right")
    fitted = dict(best or {})
    for s in offsets:
        if s in fitted:                 # shown with the fitted sensor offset
            fitted[s] = fitted[s] - np.mean((fitted[s] - y[s])[use])
            initial = dict(initial, **{s: initial[s] - np.mean((initial[s] - y[s])[use])})

    def rms_of(traces):
        return {s: float(np.sqrt(np.mean(((traces[s] - y[s])[use]) ** 2))) for s in signals}

    rms = rms_of(fitted) if fitted else {}
    start_rms = rms_of(initial)
    windows = sample_spans(meas.t, left_out)
    if windows:
        spans = ", ".join(f"{1e3 * (a - meas.t[0]):.1f}-{1e3 * (b - meas.t[0]):.1f} ms"
                          for a, b in windows[:4]) + (f" and {len(windows) - 4} more"
                                                      if len(windows) > 4 else "")
        notes.insert(0, f"left out {int(left_out.sum())} of {n_samples} samples ({spans} after "
                        f"the record's start) where the sampling does not resolve the model's "
                        f"motion (one-sample curvature over {100 * UNRESOLVED_CURVATURE:g} % of a "
                        f"signal's range, e.g. a stop impact): there the residual measures the "
                        f"event's timing to a fraction of a sample, not the parameters "
                        f"(--keep-unresolved fits them)")
    worse = {}
    if fitted:
        total0 = sum((start_rms[s] / sigma[s]) ** 2 for s in signals)
        total1 = sum((rms[s] / sigma[s]) ** 2 for s in signals)
        for s in signals:
            if rms[s] - start_rms[s] > WORSE * max(start_rms[s], sigma[s]):
                if total1 > total0:
                    why = (f"the optimiser stopped worse than it started ({sol.message}); the "
                           f"start is the better model")
                else:
                    why = (f"the fit trades {s} against the other signals (weighted sum of "
                           f"squares {total1:.4g} < {total0:.4g} at the start, each signal "
                           f"weighted by its noise level)")
                worse[s] = why
                notes.append(f"{s}: fitted rms {rms[s]:.4g} > start {start_rms[s]:.4g} [SI]: {why}")
    if on_fitted is not None:   # (e.g. the figure drawn while the run below goes on)
        on_fitted({"sigma": {s: float(v) for s, v in sigma.items()}, "initial": initial,
                   "fitted": fitted, "rms": rms, "start_rms": start_rms, "windows": windows,
                   "worse": worse})
    # a simulated record is exact only to its integration tolerance: the estimate's shift under
    # that error joins the standard error. The record's own error is one realisation; the
    # model's at the optimum is another (a ppm change of a parameter changes the integrator's
    # step decisions), so the shift is the largest of the realisations at the optimum moved
    # by each of INTEGRATION_NUDGES in every ln(value), each against its own tight run
    shift = np.zeros(k)
    if best is not None and record_rtol > 0:
        try:
            for nudge in INTEGRATION_NUDGES:
                theta = sol.x + nudge
                tight = best if nudge == 0 else model(theta)
                if tight is None:          # (the model does not run there: no more draws)
                    break
                loose = run(theta, rtol=record_rtol,
                            atol_scale=RECORD_ATOL_SCALE * record_rtol / RECORD_RTOL)
                dr = np.concatenate(weighted(loose, use)) - np.concatenate(weighted(tight, use))
                shift = np.maximum(shift, np.abs(np.linalg.lstsq(J, dr, rcond=None)[0]))
        except (RuntimeError, ArithmeticError, np.linalg.LinAlgError):
            pass
    cov = cov + np.diag(shift ** 2)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, np.inf))
    tq = float(stdtrit(dof, 0.5 + confidence / 2))
    est = values(sol.x)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    if shift.any():
        notes.append(f"intervals include the estimate's shift under the integration error of a "
                     f"simulated record (rtol {record_rtol:g}; the largest of {len(INTEGRATION_NUDGES)} "
                     f"realisations): up to {np.max(shift):.2g} in ln(value)")
    message = "; ".join([str(sol.message)] + notes)
    return FitResult(params, units, start_values, est, np.exp(sol.x - tq * sd), np.exp(sol.x + tq * sd), sd,
                     corr, confidence, {s: float(v) for s, v in sigma.items()}, rms, s2, N,
                     count["n"], bool(sol.success), message, fitted, initial,
                     calibrated(sol.x), {s: float(np.mean((y[s] - best[s])[use])) for s in offsets
                                         if best}, start_rms, windows, shift, notes, worse,
                     str(sol.message))


def residual_correlation(traces) -> tuple[float, float]:
    """Lag-1 autocorrelation of weighted residual traces and the variance inflation it implies.

    For AR(1) residuals of lag-1 correlation rho the variance of a mean (and of a
    least-squares estimate) is ``(1 + rho)/(1 - rho)`` times the white-noise value; a fit
    on a record whose misfit is a smooth model error (rho near 1) is otherwise as sure of
    itself as if every sample were independent.

    Parameters
    ----------
    traces : list of arrays
        Weighted residuals per channel, in time order, [-]

    Returns
    -------
    (rho, inflation)
        rho in [-1, 1] (0 for no data); inflation >= 1, [-]
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
