"""Check valve: no dynamics, small forward and large reverse resistance (M28, docs/model.md 1)."""
from __future__ import annotations

from dataclasses import dataclass

from ..engine import ops
from ..engine.component import parameter
from .resistance import OrientedResistance

__all__ = ["CheckValve"]


@dataclass(kw_only=True)
class CheckValve(OrientedResistance):
    """Ideal check valve, flow positive in its free direction (inlet -> outlet).

    ``dp = R_f q+ + R_r (q - q+)`` with the smooth positive part (softplus)
    ``q+ = q_t ln(1 + exp(q/q_t))``, which equals max(q, 0) up to ``q_t exp(-|q|/q_t)``:
    ``dp`` rises monotonically with q (dq+/dq lies in (0, 1)), is exact a few q_t away from
    zero flow, gives negligible back-flow and no chatter.

    Parameters
    ----------
    forward_resistance : float
        R_f in the free direction, [Pa s/m^3]
    reverse_resistance : float
        R_r against it (large), [Pa s/m^3]
    transition_flow : float
        q_t, width of the switch, [m^3/s]

    Other Parameters
    ----------------
    name, connections, compute
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.
    compute
        Causality, as for :class:`~hydroline.components.resistance.OrientedResistance`.
    """

    forward_resistance: float = parameter(0.0, "Pa*s/m^3", "R_f in the free direction", minimum=0.0,
                                          plausible=(0.0, 1e13))
    reverse_resistance: float = parameter(1e13, "Pa*s/m^3", "R_r against it (large)", positive=True,
                                          plausible=(1e6, 1e16))
    transition_flow: float = parameter(1e-7, "m^3/s", "q_t, width of the switch", positive=True,
                                       plausible=(1e-12, 1e-3))

    def __post_init__(self):
        super().__post_init__()
        self.check_parameters()
        if self.compute == "flow" and not self.forward_resistance > 0:
            raise ValueError(f"{self.name}: forward_resistance must be > 0 [Pa s/m^3] for compute='flow'")

    def flow(self, dp):
        """Inverse law, ``q = dp+/R_f + (dp - dp+)/R_r`` with dp+ the softplus of dp over
        ``p_t = R_f q_t``; monotone, exact a few p_t away from zero drop, [m^3/s].

        Parameters
        ----------
        dp : float
            Pressure drop, inlet minus outlet (number or CasADi symbol), [Pa]

        Returns
        -------
        float
            Flow from inlet to outlet, [m^3/s]
        """
        pt = self.forward_resistance * self.transition_flow
        dp_pos = ops.softplus(dp, pt)
        return dp_pos / self.forward_resistance + (dp - dp_pos) / self.reverse_resistance

    def pressure_drop(self, q):
        """Pressure drop ``dp = R_f q+ + R_r (q - q+)``, q+ the softplus of q over the
        transition flow ``q_t``, [Pa].

        Parameters
        ----------
        q : float
            Flow from inlet to outlet (number or CasADi symbol), [m^3/s]

        Returns
        -------
        float
            Pressure drop, inlet minus outlet, [Pa]
        """
        qt = self.transition_flow
        q_pos = ops.softplus(q, qt)
        return self.forward_resistance * q_pos + self.reverse_resistance * (q - q_pos)
