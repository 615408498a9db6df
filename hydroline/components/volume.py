"""A lumped hydraulic volume (a manifold node with compliance), (M33)."""
from __future__ import annotations

from dataclasses import dataclass, field

from ..engine.component import Component, HydraulicEnd, Port, State, parameter
from ..fluid import (Fluid, cavity_volume_fraction, chamber_pressure_scale, chamber_structure,
                     oil_compliance, oil_numbers)

__all__ = ["HydraulicVolume", "OilChamber"]


class OilChamber(Component):
    """A component whose states include pressures of oil held in chambers (M22, M33): its
    equations read the oil's entrained-air and cavity models (M40-M42), whose numbers it
    takes at run time and whose on/off it counts as structure. Subclasses hold ``fluid``.

    Parameters
    ----------
    name : str
        Unique name in the network (as :class:`~hydroline.engine.component.Component`)
    connections : dict
        Local port name -> network signal name (as
        :class:`~hydroline.engine.component.Component`)
    """

    def compiled_numbers(self) -> dict:
        """As :meth:`Component.compiled_numbers`, with the numbers of the oil's entrained air
        and cavity model that the chamber equations read (:func:`~hydroline.fluid.oil_numbers`).

        Returns
        -------
        dict
            Name -> float or tuple of floats, [SI].
        """
        return {**super().compiled_numbers(), **oil_numbers(self.fluid)}

    def structure_attributes(self, attributes: dict) -> dict:
        """As :meth:`Component.structure_attributes`; the oil stands as which of its models
        the chamber equations read (:meth:`~hydroline.fluid.Fluid.chamber_model`).

        Parameters
        ----------
        attributes : dict
            The component's attributes, name -> value.

        Returns
        -------
        dict
            Name -> value or mark.
        """
        return chamber_structure(super().structure_attributes(attributes))


@dataclass(kw_only=True)
class HydraulicVolume(OilChamber):
    """``dp/dt = beta/V * sum_i sign_i q_i``: the pressure of a volume of oil.

    Used for the HSM block when a hose section II is removed (the manifold joined to the
    valve): without a line there, the manifold resistance, the node and the valve orifices
    would form an algebraic loop; the block's own oil volume breaks it physically.

    Parameters
    ----------
    volume : float
        V, [m^3]
    bulk_modulus : float
        beta of the oil in it, [Pa]
    terms : dict
        Input port name -> sign (+1 into the volume, -1 out of it)
    nominal_pressure : float
        Guess for the steady-state solver, [Pa]
    fluid : Fluid or None
        The rig's oil: entrained air (M40) and a cavity (M42) make the compliance
        ``V/K_eff(p) + V dphi/dp`` (M41); None or air-free oil without a cavity model:
        ``V/beta``

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.

    Notes
    -----
    Ports: the flow terms [m^3/s]; output ``pressure`` [Pa]. State ``pressure``.
    """

    volume: float = parameter(1e-5, "m^3", "V, the oil volume", positive=True,
                              plausible=(1e-9, 1.0))
    bulk_modulus: float = parameter(1.5e9, "Pa", "beta of the oil in it", positive=True,
                                    plausible=(1e7, 5e9))
    terms: dict = field(default_factory=dict)
    nominal_pressure: float = parameter(1e7, "Pa", "guess for the steady state", positive=True,
                                        plausible=(1e3, 1e8))
    fluid: Fluid | None = None

    feedthrough = False
    conducts = True

    def __post_init__(self):
        self.check_parameters()
        self.inputs = {k: Port("flow", f"flow term, sign {s:+d}") for k, s in self.terms.items()}
        self.outputs = {"pressure": Port("pressure", "pressure in the volume")}

    @property
    def states(self):
        """The state: ``pressure`` [Pa] of the oil in the volume (its scale
        :func:`~hydroline.fluid.chamber_pressure_scale`)."""
        return [State("pressure", "Pa",
                      chamber_pressure_scale(max(self.nominal_pressure, 1e5), self.fluid))]

    def hydraulic_ends(self):
        """One node holding oil: its pressure and the flows into it.

        Returns
        -------
        dict
            End name -> :class:`~hydroline.engine.component.HydraulicEnd`.
        """
        return {"node": HydraulicEnd("pressure", tuple(self.terms), compliant=True)}

    def outputs_of(self, t, x, u, p):
        return {"pressure": x["pressure"]}

    def derivatives(self, t, x, u, p):
        net = 0.0
        for k, s in self.terms.items():
            net = net + s * u[k]
        if self.fluid is None or self.fluid.plain:
            return {"pressure": self.bulk_modulus / self.volume * net}
        return {"pressure": net / oil_compliance(self.volume, x["pressure"],      # (M41)
                                                 self.bulk_modulus, self.fluid)}

    def cavity_volumes(self, x, outputs=None):
        """Gas/vapour cavity volume in the node (M42), [m^3].

        Parameters
        ----------
        x : dict
            States (arrays of a run allowed), local name -> value [SI]
        outputs : dict, optional
            Its outputs there, local port name -> value [SI] (not needed: the pressures
            are states)

        Returns
        -------
        dict
            ``{"volume": V_cav}``, [m^3]; empty without a cavity model
        """
        if self.fluid is None or self.fluid.cavity_pressure is None:
            return {}
        return {"volume": self.volume * cavity_volume_fraction(
            x["pressure"], self.fluid.cavity_pressure, self.fluid.cavity_pressure_drop)}

    def initial_guess(self):
        return {"pressure": self.nominal_pressure}
