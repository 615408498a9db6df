"""Static flow resistances: the manifold (HSM) loss (M1) and the check valve."""
from __future__ import annotations

from dataclasses import dataclass

from ..engine.component import Component, HydraulicEnd, Port, parameter

__all__ = ["LinearResistance", "OrientedResistance"]


@dataclass(kw_only=True)
class OrientedResistance(Component):
    """Base of causal resistances: flow ``flow`` positive from inlet to outlet, drop ``dp(q)``.

    Parameters
    ----------
    compute : str
        What the component outputs (its causality): "outlet" (inputs
        ``inlet_pressure``, ``flow``; output ``outlet_pressure = p_in - dp(q)``),
        "inlet" (inputs ``outlet_pressure``, ``flow``; output
        ``inlet_pressure = p_out + dp(q)``) or "flow" (inputs both pressures;
        output ``flow = q(p_in - p_out)``, the inverse law)

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.
    """

    compute: str = parameter("outlet", "str", "causality: what the component outputs",
                             choices=("outlet", "inlet", "flow"))

    conducts = True

    def __post_init__(self):
        if self.compute not in ("outlet", "inlet", "flow"):
            raise ValueError(f"{self.name}: compute must be 'outlet', 'inlet' or 'flow', got {self.compute!r}")
        if self.compute == "flow":
            self.inputs = {"inlet_pressure": Port("pressure", "pressure at the inlet"),
                           "outlet_pressure": Port("pressure", "pressure at the outlet")}
            self.outputs = {"flow": Port("flow", "flow from inlet to outlet")}
            return
        known = "inlet" if self.compute == "outlet" else "outlet"
        self.inputs = {f"{known}_pressure": Port("pressure", f"pressure at the {known}"),
                       "flow": Port("flow", "flow from inlet to outlet")}
        self.outputs = {f"{self.compute}_pressure": Port("pressure", f"pressure at the {self.compute}")}

    def hydraulic_ends(self):
        """Inlet and outlet, the flow passing through from one to the other.

        Returns
        -------
        dict
            End name -> :class:`~hydroline.engine.component.HydraulicEnd`.
        """
        return {"inlet": HydraulicEnd("inlet_pressure", ("flow",)),
                "outlet": HydraulicEnd("outlet_pressure", ("flow",))}

    def pressure_drop(self, q):
        """Pressure drop [Pa] at flow q [m^3/s].

        Parameters
        ----------
        q : float
            Flow from inlet to outlet (number or CasADi symbol), [m^3/s]

        Returns
        -------
        float
            Pressure drop, inlet minus outlet, [Pa]
        """
        raise NotImplementedError

    def flow(self, dp):
        """Flow [m^3/s] at pressure drop dp [Pa] (inverse of :meth:`pressure_drop`).

        Parameters
        ----------
        dp : float
            Pressure drop, inlet minus outlet (number or CasADi symbol), [Pa]

        Returns
        -------
        float
            Flow from inlet to outlet, [m^3/s]
        """
        raise NotImplementedError

    def outputs_of(self, t, x, u, p):
        if self.compute == "flow":
            return {"flow": self.flow(u["inlet_pressure"] - u["outlet_pressure"])}
        dp = self.pressure_drop(u["flow"])
        if self.compute == "outlet":
            return {"outlet_pressure": u["inlet_pressure"] - dp}
        return {"inlet_pressure": u["outlet_pressure"] + dp}


@dataclass(kw_only=True)
class LinearResistance(OrientedResistance):
    """Linear resistance ``dp = R q`` (M1), the lumped HSM loss near rated flow.

    Parameters
    ----------
    resistance : float
        R, [Pa s/m^3]

    Other Parameters
    ----------------
    name, connections, compute
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.
    compute
        Causality, as for :class:`~hydroline.components.resistance.OrientedResistance`.
    """

    resistance: float = parameter(0.0, "Pa*s/m^3", "R of dp = R q (M1)", minimum=0.0,
                                  plausible=(0.0, 1e13))

    def __post_init__(self):
        super().__post_init__()
        self.check_parameters()
        if (self.compute == "flow" and not self.resistance > 0):
            raise ValueError(f"{self.name}: resistance must be > 0 [Pa s/m^3], got {self.resistance!r}")

    def pressure_drop(self, q):
        """Pressure drop ``dp = R q`` (M1), [Pa].

        Parameters
        ----------
        q : float
            Flow from inlet to outlet (number or CasADi symbol), [m^3/s]

        Returns
        -------
        float
            Pressure drop, inlet minus outlet, [Pa]
        """
        return self.resistance * q                      # (M1)

    def flow(self, dp):
        """Flow ``q = dp / R`` (M1), [m^3/s].

        Parameters
        ----------
        dp : float
            Pressure drop, inlet minus outlet (number or CasADi symbol), [Pa]

        Returns
        -------
        float
            Flow from inlet to outlet, [m^3/s]
        """
        return dp / self.resistance
