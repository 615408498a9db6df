"""Pressure-relief valve: closed below its cracking pressure, then a linear override (M32)."""
from __future__ import annotations

from dataclasses import dataclass

from ..engine import ops
from ..engine.component import Component, HydraulicEnd, Port, parameter

__all__ = ["ReliefValve"]


@dataclass(kw_only=True)
class ReliefValve(Component):
    """Direct-acting relief valve from a node (inlet) to tank (outlet), static.

    ``q = G (dp - p_c)+`` with ``dp = p_in - p_out``, p_c the cracking pressure and G the
    flow-pressure slope of the override characteristic (a datasheet's ``rated flow /
    (full-flow pressure - cracking pressure)``); ``(y)+`` is the smooth positive part
    ``max(y, 0) + p_w ln(1 + exp(-|y|/p_w))``, exact to ``p_w exp(-|y|/p_w)`` a few
    ``p_w`` away from cracking, so the valve opens without a kink the integrator would
    have to find. Below cracking a leakage conductance ``G_l dp`` remains (default 0).

    Parameters
    ----------
    cracking_pressure : float
        p_c, drop across the valve at which it opens, [Pa]
    flow_gradient : float
        G = dq/dp above cracking, [m^3/s/Pa]
    transition_pressure : float
        p_w, width of the smooth opening, [Pa]
    leakage : float
        G_l, leakage conductance, [m^3/s/Pa]

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.

    Notes
    -----
    Ports: inputs ``inlet_pressure``, ``outlet_pressure`` [Pa]; output ``flow`` from inlet to
    outlet [m^3/s].
    """

    cracking_pressure: float = parameter(21e6, "Pa", "p_c, drop at which the valve cracks open",
                                         positive=True, plausible=(1e4, 1e8))
    flow_gradient: float = parameter(1e-10, "m^3/s/Pa", "G, flow-pressure slope above cracking",
                                     positive=True, plausible=(1e-14, 1e-6))
    transition_pressure: float = parameter(1e4, "Pa", "p_w, width of the smooth opening", positive=True,
                                           plausible=(1.0, 1e7))
    leakage: float = parameter(0.0, "m^3/s/Pa", "G_l, leakage conductance when closed", minimum=0.0,
                               plausible=(0.0, 1e-9))

    inputs = {"inlet_pressure": Port("pressure", "pressure at the protected node"),
              "outlet_pressure": Port("pressure", "pressure at the outlet (tank)")}
    outputs = {"flow": Port("flow", "flow relieved from inlet to outlet")}

    def __post_init__(self):
        self.check_parameters()

    def hydraulic_ends(self):
        """Inlet (the protected node) and outlet (tank), the relieved flow passing between.

        Returns
        -------
        dict
            End name -> :class:`~hydroline.engine.component.HydraulicEnd`.
        """
        return {"inlet": HydraulicEnd("inlet_pressure", ("flow",)),
                "outlet": HydraulicEnd("outlet_pressure", ("flow",))}

    def flow(self, dp):
        """Relieved flow, [m^3/s].

        Parameters
        ----------
        dp : float
            Inlet minus outlet pressure, [Pa]

        Returns
        -------
        float
            Flow from inlet to outlet (M32), [m^3/s]
        """
        y = dp - self.cracking_pressure
        pw = self.transition_pressure
        y_pos = ops.softplus(y, pw)
        return self.flow_gradient * y_pos + self.leakage * dp

    def outputs_of(self, t, x, u, p):
        return {"flow": self.flow(u["inlet_pressure"] - u["outlet_pressure"])}
