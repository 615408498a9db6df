"""Command signals (experiments): step, sine, ramp, table from CSV."""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..network import ops
from ..network.component import Component, Port

__all__ = ["StepCommand", "SineCommand", "RampCommand", "TableCommand"]


@dataclass(kw_only=True)
class _Command(Component):
    quantity: str = "current"

    def __post_init__(self):
        self.outputs = {"command": Port(self.quantity, f"commanded {self.quantity}")}
        self.feedthrough = False


@dataclass(kw_only=True)
class StepCommand(_Command):
    """``initial`` before ``time``, ``final`` after, [SI unit of ``quantity``; s]."""

    initial: float = 0.0
    final: float = 0.0
    time: float = 0.0

    def runtime_parameters(self):
        return {"initial": self.initial, "final": self.final}

    def outputs_of(self, t, x, u, p):
        return {"command": ops.if_else(t >= self.time, p["final"], p["initial"])}

    def breakpoints(self, t_end):
        return [self.time]


@dataclass(kw_only=True)
class SineCommand(_Command):
    """``offset + amplitude sin(2 pi frequency (t - start))`` for t >= start, offset before.

    Parameters: offset, amplitude [SI unit of ``quantity``], frequency [Hz], start [s].
    """

    offset: float = 0.0
    amplitude: float = 0.0
    frequency: float = 1.0
    start: float = 0.0

    def runtime_parameters(self):
        return {"amplitude": self.amplitude}

    def outputs_of(self, t, x, u, p):
        phase = 2 * np.pi * self.frequency * (t - self.start)
        wave = p["amplitude"] * _sin(phase)
        return {"command": self.offset + ops.if_else(t >= self.start, wave, 0.0)}

    def breakpoints(self, t_end):
        return [self.start]


def _sin(x):
    return ca.sin(x) if ops.is_symbolic(x) else np.sin(x)


@dataclass(kw_only=True)
class RampCommand(_Command):
    """``initial`` until ``start``, then rising at ``slope`` until ``end``, then held.

    Parameters: initial [unit], slope [unit/s], start, end [s].
    """

    initial: float = 0.0
    slope: float = 0.0
    start: float = 0.0
    end: float = 1.0

    def outputs_of(self, t, x, u, p):
        tau = ops.fmin(ops.fmax(t - self.start, 0.0), self.end - self.start)
        return {"command": self.initial + self.slope * tau}

    def breakpoints(self, t_end):
        return [self.start, self.end]


@dataclass(kw_only=True)
class TableCommand(_Command):
    """Piecewise-linear command through (times [s], values [unit]); held beyond the ends."""

    times: list = field(default_factory=list)
    values: list = field(default_factory=list)

    def __post_init__(self):
        super().__post_init__()
        self.times = np.asarray(self.times, dtype=float)
        self.values = np.asarray(self.values, dtype=float)
        if self.times.ndim != 1 or len(self.times) < 2 or len(self.times) != len(self.values):
            raise ValueError(f"{self.name}: table needs >= 2 (time, value) rows of equal length")
        if np.any(np.diff(self.times) <= 0):
            raise ValueError(f"{self.name}: table times must increase strictly [s]")
        if not (np.all(np.isfinite(self.times)) and np.all(np.isfinite(self.values))):
            raise ValueError(f"{self.name}: table has NaN or infinite entries")
        self._interp = ca.interpolant(f"{self.name.replace('.', '_')}_table", "linear",
                                      [self.times.tolist()], self.values.tolist())

    @classmethod
    def from_csv(cls, path, name="command", quantity="current", time_column=0, value_column=1,
                 value_scale=1.0, **kw):
        """Read a two-column CSV (header allowed); values multiplied by ``value_scale`` to SI."""
        import pandas as pd

        df = pd.read_csv(path)
        return cls(name=name, quantity=quantity, times=df.iloc[:, time_column].to_numpy(float),
                   values=df.iloc[:, value_column].to_numpy(float) * value_scale, **kw)

    def outputs_of(self, t, x, u, p):
        if ops.is_symbolic(t):
            tc = ca.fmin(ca.fmax(t, self.times[0]), self.times[-1])
            return {"command": self._interp(tc)}
        return {"command": float(np.interp(t, self.times, self.values))}
