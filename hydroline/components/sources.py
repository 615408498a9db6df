"""Pressure sources: the pump unit (HPS) and the tank (MODEL.md section 1, 6)."""
from __future__ import annotations

from dataclasses import dataclass

from ..network import ops
from ..network.component import Component, Port

__all__ = ["PressureSource"]


@dataclass(kw_only=True)
class PressureSource(Component):
    """A known pressure ``p(t)``: constant, optionally with one step.

    ``p(t) = pressure`` before ``step_time`` and ``step_to`` after it.

    Parameters
    ----------
    pressure : float     Pressure, [Pa] (absolute)
    step_time : float    Time of an optional step, [s]; None for constant
    step_to : float      Pressure after the step, [Pa]

    Ports: output ``pressure`` [Pa].
    """

    pressure: float = 0.0
    step_time: float | None = None
    step_to: float | None = None

    outputs = {"pressure": Port("pressure", "source pressure, absolute")}
    feedthrough = False

    def runtime_parameters(self):
        return {"pressure": self.pressure}

    def outputs_of(self, t, x, u, p):
        if self.step_time is None:
            return {"pressure": p["pressure"]}
        return {"pressure": ops.if_else(t >= self.step_time, self.step_to, p["pressure"])}

    def breakpoints(self, t_end):
        return [] if self.step_time is None else [self.step_time]
