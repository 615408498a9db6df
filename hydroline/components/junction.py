"""Flow junction: the continuity equation at a node without volume (M34)."""
from __future__ import annotations

from dataclasses import dataclass, field

from ..engine.component import Component, HydraulicEnd, Port

__all__ = ["FlowJunction"]


@dataclass(kw_only=True)
class FlowJunction(Component):
    """``flow = sum_i sign_i * inflow_i`` (volume-free node; its compliance lives in the lines).

    Parameters
    ----------
    terms : dict
        Input port name -> sign (+1 or -1)

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.

    Notes
    -----
    Ports: inputs the terms [m^3/s]; output ``flow`` [m^3/s].
    """

    terms: dict = field(default_factory=dict)

    conducts = True

    def __post_init__(self):
        self.inputs = {k: Port("flow", f"flow term, sign {s:+d}") for k, s in self.terms.items()}
        self.outputs = {"flow": Port("flow", "sum of the signed flows")}

    def hydraulic_ends(self):
        """One node without its own pressure: the summed flows and the sum.

        Returns
        -------
        dict
            End name -> :class:`~hydroline.engine.component.HydraulicEnd`.
        """
        return {"node": HydraulicEnd(None, ("flow", *self.terms))}

    def outputs_of(self, t, x, u, p):
        total = 0.0
        for k, s in self.terms.items():
            total = total + s * u[k]
        return {"flow": total}
