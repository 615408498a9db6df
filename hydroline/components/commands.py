"""Command signals (experiments): step, sine, ramp, table from CSV."""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..engine import ops
from ..engine.component import Component, Port, parameter

#: Unit of a command value: that of its ``quantity`` (see hydroline.circuit.types).
_VALUE = "-"

__all__ = ["StepCommand", "SineCommand", "RampCommand", "TableCommand", "read_table_csv"]


@dataclass(kw_only=True)
class _Command(Component):
    """Base of the command sources: one output ``command`` in the SI unit of ``quantity``.

    Parameters
    ----------
    quantity : str
        What the command drives: "current", "position", "pressure", "velocity",
        "force" or "flow" (its value then in [A], [m], [Pa], [m/s], [N], [m^3/s])
    """

    quantity: str = parameter("current", "str", "what the command drives",
                              choices=("current", "position", "pressure", "velocity", "force", "flow"))

    def __post_init__(self):
        self.check_parameters()
        self.outputs = {"command": Port(self.quantity, f"commanded {self.quantity}")}
        self.feedthrough = False


@dataclass(kw_only=True)
class StepCommand(_Command):
    """``initial`` before ``time``, ``final`` after, [SI unit of ``quantity``; s].

    Parameters
    ----------
    initial : float
        Value before the step, [SI unit of ``quantity``]
    final : float
        Value after the step, [SI unit of ``quantity``]
    time : float
        Time of the step, [s]

    Other Parameters
    ----------------
    name, connections, quantity
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.
    quantity
        What the command drives ("current", "position", ...), as for every command;
        its values are in that quantity's SI unit.
    """

    initial: float = parameter(0.0, _VALUE, "value before the step, [unit of quantity]")
    final: float = parameter(0.0, _VALUE, "value after the step, [unit of quantity]")
    time: float = parameter(0.0, "s", "time of the step", minimum=0.0,
                            plausible=(0.0, 1e4))

    def runtime_parameters(self):
        return {"initial": self.initial, "final": self.final}

    def outputs_of(self, t, x, u, p):
        return {"command": ops.if_else(t >= self.time, p["final"], p["initial"])}

    def breakpoints(self, t_end):
        return [self.time]


@dataclass(kw_only=True)
class SineCommand(_Command):
    """``offset + amplitude sin(2 pi frequency (t - start))`` for t >= start, offset before.

    Parameters
    ----------
    offset : float
        Mean value, [SI unit of ``quantity``]
    amplitude : float
        Amplitude, [SI unit of ``quantity``]
    frequency : float
        Frequency of the sine, [Hz]
    start : float
        Time the sine starts, [s]

    Other Parameters
    ----------------
    name, connections, quantity
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.
    quantity
        What the command drives ("current", "position", ...), as for every command;
        its values are in that quantity's SI unit.
    """

    offset: float = parameter(0.0, _VALUE, "mean value, [unit of quantity]")
    amplitude: float = parameter(0.0, _VALUE, "amplitude, [unit of quantity]")
    frequency: float = parameter(1.0, "Hz", "frequency of the sine", positive=True,
                                 plausible=(1e-4, 1e4))
    start: float = parameter(0.0, "s", "time the sine starts", minimum=0.0,
                             plausible=(0.0, 1e4))

    def runtime_parameters(self):
        return {"amplitude": self.amplitude}

    def outputs_of(self, t, x, u, p):
        phase = 2 * np.pi * self.frequency * (t - self.start)
        wave = p["amplitude"] * _sin(phase)
        return {"command": self.offset + ops.if_else(t >= self.start, wave, 0.0)}

    def breakpoints(self, t_end):
        return [self.start]


def _sin(x):
    if ops.is_symbolic(x):
        import casadi as ca

        return ca.sin(x)
    return np.sin(x)


@dataclass(kw_only=True)
class RampCommand(_Command):
    """``initial`` until ``start``, then rising at ``slope`` until ``end``, then held.

    Parameters
    ----------
    initial : float
        Value before the ramp, [SI unit of ``quantity``]
    slope : float
        Rate of the ramp, [SI unit of ``quantity``/s]
    start : float
        Time the ramp starts, [s]
    end : float
        Time the ramp ends (held after), [s]

    Other Parameters
    ----------------
    name, connections, quantity
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.
    quantity
        What the command drives ("current", "position", ...), as for every command;
        its values are in that quantity's SI unit.
    """

    initial: float = parameter(0.0, _VALUE, "value before the ramp, [unit of quantity]")
    slope: float = parameter(0.0, _VALUE, "rate of the ramp, [unit of quantity/s]")
    start: float = parameter(0.0, "s", "time the ramp starts", minimum=0.0,
                             plausible=(0.0, 1e4))
    end: float = parameter(1.0, "s", "time the ramp ends (held after)", minimum=0.0,
                           plausible=(0.0, 1e4))

    def outputs_of(self, t, x, u, p):
        tau = ops.fmin(ops.fmax(t - self.start, 0.0), self.end - self.start)
        return {"command": self.initial + self.slope * tau}

    def breakpoints(self, t_end):
        return [self.start, self.end]


@dataclass(kw_only=True)
class TableCommand(_Command):
    """Piecewise-linear command through (times [s], values [unit]); held beyond the ends.

    A time given twice is a jump (as in Modelica's ``CombiTimeTable``): the first of the two
    rows is the value reached just before it, the second the value from that time on (a step
    written by a data-acquisition card, or :class:`StepCommand`'s ``t >= time``).

    In the compiled model a table of up to ``RAMP_ROWS`` rows is the exact sum of clipped
    ramps ``v_0 + sum_k s_k min(max(t - t_k, 0), t_(k+1) - t_k)`` (slopes ``s_k``), which the
    C core compiles; a longer table is a CasADi interpolant (the integrator then uses CVODES).
    Jumps are added to either as steps ``J_j (t >= t_j)``.

    Parameters
    ----------
    times : array_like
        Times of the rows, increasing; a time twice is a jump, [s]
    values : array_like
        Values at those times, [SI unit of ``quantity``]

    Other Parameters
    ----------------
    name, connections, quantity
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.
    quantity
        What the command drives ("current", "position", ...), as for every command;
        its values are in that quantity's SI unit.
    """

    #: Longest table written as a sum of ramps, [rows].
    RAMP_ROWS = 256

    times: list = field(default_factory=list)
    values: list = field(default_factory=list)

    def __post_init__(self):
        super().__post_init__()
        self.times = np.asarray(self.times, dtype=float)
        self.values = np.asarray(self.values, dtype=float)
        if self.times.ndim != 1 or len(self.times) < 2 or len(self.times) != len(self.values):
            raise ValueError(f"{self.name}: table needs >= 2 (time, value) rows of equal length")
        if not (np.all(np.isfinite(self.times)) and np.all(np.isfinite(self.values))):
            raise ValueError(f"{self.name}: table has NaN or infinite entries")
        dt = np.diff(self.times)
        if np.any(dt < 0) or np.any((dt[1:] == 0) & (dt[:-1] == 0)):
            raise ValueError(f"{self.name}: table times must increase (a time at most twice: "
                             f"a jump) [s]")
        if np.all(dt == 0):
            raise ValueError(f"{self.name}: table needs two distinct times [s]")

    @cached_property
    def jumps(self) -> tuple:
        """(times [s], sizes [unit]) of the table's jumps (a time given twice)."""
        k = np.flatnonzero(np.diff(self.times) == 0)
        return self.times[k], self.values[k + 1] - self.values[k]

    @cached_property
    def continuous(self) -> tuple:
        """(times [s], values [unit]) of the table less its jumps: strictly increasing times,
        a continuous piecewise-linear function (the command is it plus the jumps' steps)."""
        k = np.flatnonzero(np.diff(self.times) == 0)
        shift = np.zeros(len(self.times))
        shift[k + 1] = self.values[k + 1] - self.values[k]
        keep = np.ones(len(self.times), dtype=bool)
        keep[k + 1] = False
        return self.times[keep], (self.values - np.cumsum(shift))[keep]

    @cached_property
    def interpolant(self):
        """The table (less its jumps) as a CasADi linear interpolant of time [s] (the compiled
        path of a table longer than ``RAMP_ROWS``; made on first use)."""
        import casadi as ca

        times, values = self.continuous
        return ca.interpolant(f"{self.name.replace('.', '_')}_table", "linear",
                              [times.tolist()], values.tolist())

    @classmethod
    def from_csv(cls, path, name="command", quantity="current", time_column=0, value_column=1,
                 value_scale=1.0, **kw):
        """Read a two-column CSV (header allowed); values multiplied by ``value_scale`` to SI.

        Parameters
        ----------
        path : str or Path
            CSV file with a header row, times in seconds
        name : str
            Component name
        quantity : str
            What the command is ("current", "position", "pressure", ...)
        time_column : int
            Column of the times [s] (index from 0)
        value_column : int
            Column of the values (index from 0)
        value_scale : float
            Factor from the file's values to SI, [SI unit/file unit]
        **kw : dict
            Further arguments of the component (``connections``, ...).

        Returns
        -------
        TableCommand
            The command through the file's rows.
        """
        import pandas as pd

        df = pd.read_csv(path)
        return cls(name=name, quantity=quantity, times=df.iloc[:, time_column].to_numpy(float),
                   values=df.iloc[:, value_column].to_numpy(float) * value_scale, **kw)

    @classmethod
    def from_csv_with_units(cls, path, unit, name="command", quantity="current", **kw):
        """Read a two-column CSV whose header carries units: ``time [ms]``, ``<name> [MPa]``.

        Parameters
        ----------
        path : str or Path
            CSV file, one header row, then (time, value) rows
        unit : str
            SI unit of the values, e.g. "Pa"; the header may give any unit of
            that dimension ("MPa", "bar", "psi"), [-]
        name, quantity : str
            As for the component: its name and what the command is.
        **kw : dict
            Further arguments of the component (``connections``, ...).

        Returns
        -------
        TableCommand
            The command through the file's rows, values in ``unit``.

        Raises
        ------
        ValueError
            One line naming the file and the column or row at fault.
        """
        return cls(name=name, quantity=quantity, **dict(zip(("times", "values"),
                                                              read_table_csv(path, unit))), **kw)

    def outputs_of(self, t, x, u, p):
        times, values = self.continuous
        if ops.is_symbolic(t):
            if len(times) <= self.RAMP_ROWS:
                dt = np.diff(times)
                slopes = np.diff(values) / dt
                out = float(values[0])
                for tk, dtk, sk in zip(times[:-1], dt, slopes):
                    if sk != 0.0:
                        out = out + float(sk) * ops.fmin(ops.fmax(t - float(tk), 0.0), float(dtk))
            else:
                out = self.interpolant(ops.fmin(ops.fmax(t, times[0]), times[-1]))
            for tj, size in zip(*self.jumps):
                out = out + ops.if_else(t >= float(tj), float(size), 0.0)
            return {"command": out}
        return {"command": float(self.at(t))}

    def at(self, t):
        """The command at times ``t`` (numbers), right-continuous at the jumps, [unit].

        Parameters
        ----------
        t : float or array_like
            Times, [s]

        Returns
        -------
        float or ndarray
            Values, [SI unit of ``quantity``]
        """
        times, values = self.continuous
        tj, size = self.jumps
        steps = np.r_[0.0, np.cumsum(size)]
        return np.interp(t, times, values) + steps[np.searchsorted(tj, t, side="right")]

    def breakpoints(self, t_end):
        """Times of the jumps, and where the table's slope changes for tables of up to
        ``RAMP_ROWS`` rows (integration restarts there, so a steep edge is not stepped
        over), [s].

        Parameters
        ----------
        t_end : float
            End of the run, [s]

        Returns
        -------
        list[float]
            The times, [s]
        """
        times, values = self.continuous
        out = [float(tj) for tj in self.jumps[0]]
        if len(times) <= self.RAMP_ROWS:
            slopes = np.diff(values) / np.diff(times)
            kinks = np.flatnonzero(np.diff(slopes) != 0.0) + 1
            out += [float(times[k]) for k in kinks]
        return sorted(set(out))

    def value_range(self):
        """Smallest and largest value of the table, [unit].

        Returns
        -------
        tuple of float
            ``(smallest, largest)``, [SI unit of ``quantity``]
        """
        return float(np.min(self.values)), float(np.max(self.values))


def read_table_csv(path, unit):
    """(times [s], values [unit]) from a two-column CSV with units in its header.

    Parameters
    ----------
    path : str or Path
        The file: header ``time [s], <name> [<unit>]``, then rows
    unit : str
        SI unit of the values, [-]

    Returns
    -------
    tuple(ndarray, ndarray)
        times [s], values [unit]

    Raises
    ------
    ValueError
        one line naming the file and what is wrong
    """
    import pandas as pd

    from ..units import csv_column

    src = str(path)
    try:
        raw = pd.read_csv(path, skipinitialspace=True)
    except FileNotFoundError:
        raise ValueError(f"{src}: table file not found") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise ValueError(f"{src}: not a readable CSV file ({str(e).strip().splitlines()[0]})") from None
    if raw.shape[1] != 2:
        raise ValueError(f"{src}: needs exactly two columns, 'time [s]' and a value with its unit "
                         f"[{unit}]; got {raw.shape[1]}")
    cols = [csv_column(raw, col, want, src) for col, want in zip(raw.columns, ("s", unit))]
    t, v = cols
    if len(t) < 2:
        raise ValueError(f"{src}: needs at least 2 rows of data, got {len(t)}")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise ValueError(f"{src}: time must increase strictly; data row {int(bad[0]) + 2} is not "
                         f"after row {int(bad[0]) + 1}")
    return t, v
