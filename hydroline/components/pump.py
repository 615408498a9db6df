"""Hydraulic pumps as flow sources: fixed displacement, or pressure compensated (M31)."""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..engine import ops
from ..engine.component import Component, HydraulicEnd, Port, parameter

__all__ = ["Pump"]


@dataclass(kw_only=True)
class Pump(Component):
    """A positive-displacement pump delivering into a node (its outlet), static.

    ``control = "fixed"``: ``q = D n - C_l p`` with ``n = omega / 2 pi`` revolutions per second (geometric flow less leakage), to be protected
    by a :class:`~hydroline.components.ReliefValve` on its outlet node.
    ``control = "pressure-compensated"``: the swash plate destrokes between the compensator
    setting p_c (full flow below) and the dead-head pressure p_d (no flow):
    ``q = D n clip((p_d - p)/(p_d - p_c), 0, 1) - C_l p``.
    The outlet pressure is the gauge pressure above the inlet (``inlet_pressure``).

    Parameters
    ----------
    displacement : float
        D, volume per revolution, [m^3]
    shaft_speed : float
        omega, shaft speed (a file may give "1500 rpm"), [rad/s]
    leakage : float
        C_l, volumetric loss per pressure, [m^3/s/Pa]
    control : str
        "fixed" or "pressure-compensated"
    compensator_pressure : float
        p_c, where destroking starts, [Pa]
    deadhead_pressure : float
        p_d > p_c, where the flow reaches zero, [Pa]

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.

    Notes
    -----
    Ports: inputs ``outlet_pressure``, ``inlet_pressure`` [Pa]; output ``flow`` delivered into
    the outlet node [m^3/s].
    """

    displacement: float = parameter(10e-6, "m^3", "D, geometric volume per revolution", positive=True,
                                    plausible=(1e-7, 1e-2))
    shaft_speed: float = parameter(157.07963267948966, "rad/s", "omega, shaft speed (1500 rpm)",
                                   positive=True, plausible=(1.0, 2000.0))
    leakage: float = parameter(0.0, "m^3/s/Pa", "C_l, volumetric loss per pressure", minimum=0.0,
                               plausible=(0.0, 1e-9))
    control: str = parameter("fixed", "str", "fixed displacement or pressure compensated",
                             choices=("fixed", "pressure-compensated"))
    compensator_pressure: float = parameter(20e6, "Pa", "p_c, start of destroking", positive=True,
                                            plausible=(1e5, 1e8))
    deadhead_pressure: float = parameter(21e6, "Pa", "p_d, zero delivery", positive=True,
                                         plausible=(1e5, 1e8))

    inputs = {"outlet_pressure": Port("pressure", "pressure at the pump outlet"),
              "inlet_pressure": Port("pressure", "pressure at the pump inlet (tank)")}
    outputs = {"flow": Port("flow", "flow delivered into the outlet node")}
    source_ends = ("outlet",)

    def __post_init__(self):
        self.check_parameters()
        if self.control == "pressure-compensated" and not self.deadhead_pressure > self.compensator_pressure:
            raise ValueError(f"{self.name}: deadhead_pressure must be > compensator_pressure "
                             f"({self.compensator_pressure:g} Pa) [Pa], got {self.deadhead_pressure!r}")

    def hydraulic_ends(self):
        """Inlet and outlet, the delivered flow passing from one to the other.

        Returns
        -------
        dict
            End name -> :class:`~hydroline.engine.component.HydraulicEnd`.
        """
        return {"inlet": HydraulicEnd("inlet_pressure", ("flow",)),
                "outlet": HydraulicEnd("outlet_pressure", ("flow",))}

    @property
    def geometric_flow(self) -> float:
        """D omega / 2 pi, [m^3/s]."""
        return self.displacement * self.shaft_speed / (2.0 * math.pi)

    def flow(self, dp):
        """Delivered flow, [m^3/s].

        Parameters
        ----------
        dp : float
            Outlet minus inlet pressure, [Pa]

        Returns
        -------
        float
            Flow delivered into the outlet node (M31), [m^3/s]
        """
        q = self.geometric_flow
        if self.control == "pressure-compensated":
            span = self.deadhead_pressure - self.compensator_pressure
            q = q * ops.fmin(ops.fmax((self.deadhead_pressure - dp) / span, 0.0), 1.0)
        return q - self.leakage * dp

    def outputs_of(self, t, x, u, p):
        return {"flow": self.flow(u["outlet_pressure"] - u["inlet_pressure"])}
