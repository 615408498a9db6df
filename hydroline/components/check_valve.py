"""Check valve: no dynamics, small forward and large reverse resistance (MODEL.md 1)."""
from __future__ import annotations

from dataclasses import dataclass

from ..network import ops
from .resistance import OrientedResistance

__all__ = ["CheckValve"]


@dataclass(kw_only=True)
class CheckValve(OrientedResistance):
    """Ideal check valve, flow positive in its free direction (inlet -> outlet).

    ``dp = R_f q+ + R_r (q - q+)`` with the smooth positive part
    ``q+ = (q + sqrt(q^2 + q_t^2))/2``; ``dp`` rises monotonically with q, so negligible
    back-flow and no chatter.

    Parameters
    ----------
    forward_resistance : float   R_f in the free direction, [Pa s/m^3]
    reverse_resistance : float   R_r against it (large), [Pa s/m^3]
    transition_flow : float      q_t, width of the switch, [m^3/s]
    """

    forward_resistance: float = 0.0
    reverse_resistance: float = 1e13
    transition_flow: float = 1e-7

    def pressure_drop(self, q):
        q_pos = 0.5 * (q + ops.sqrt(q * q + self.transition_flow**2))
        return self.forward_resistance * q_pos + self.reverse_resistance * (q - q_pos)
