"""Piston friction: asymmetric Stribeck (M24), regularised, and a LuGre stick-slip option."""
from __future__ import annotations

from dataclasses import dataclass

from ..engine import ops
from ..engine.component import Component, Port, State, parameter

__all__ = ["StribeckFriction"]


@dataclass(kw_only=True)
class StribeckFriction(Component):
    """Memory-less asymmetric Stribeck friction (M24) with separate up (+) / down (-) values.

    ``F_f = F_v v + s(v) (F_c + (F_s - F_c) exp(-(|v|/C_s)^delta))`` where the coefficients
    are the "up" set for v > 0 and the "down" set for v < 0, and ``s(v) = tanh(v/v_reg)``
    regularises sgn(v) near zero velocity (M36) so the integrator does not chatter.

    ``model="lugre"`` is the stick-slip option: the LuGre bristle model (Canudas de Wit et al.,
    IEEE TAC 40 (1995) 419-425) with the same Stribeck curve as its steady state, bristle state
    ``bristle`` z: ``z' = v - sigma0 |v| z / g(v)``, ``F = sigma0 z + sigma1 z' + F_v v``, which
    sticks (F balances the applied force up to F_s) without a discontinuity.

    Parameters
    ----------
    viscous_up, viscous_down : float
        F_v+-, [N s/m]
    coulomb_up, coulomb_down : float
        F_c+-, [N]
    static_up, static_down : float
        F_s+-, [N]
    stribeck_velocity : float
        C_s, [m/s]
    stribeck_exponent : float
        delta, [-]
    regularization_velocity : float
        v_reg, [m/s]
    model : str
        "stribeck" or "lugre"
    bristle_stiffness : float
        sigma0 (LuGre), [N/m]
    bristle_damping : float
        sigma1 (LuGre), [N s/m]

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.

    Notes
    -----
    Ports: input ``velocity`` [m/s]; output ``friction_force`` [N], opposing +v when > 0.
    """

    viscous_up: float = parameter(0.0, "N*s/m", "F_v+ (M24)", minimum=0.0, plausible=(0.0, 1e6))
    viscous_down: float = parameter(0.0, "N*s/m", "F_v- (M24)", minimum=0.0, plausible=(0.0, 1e6))
    coulomb_up: float = parameter(0.0, "N", "F_c+ (M24)", minimum=0.0, plausible=(0.0, 1e6))
    coulomb_down: float = parameter(0.0, "N", "F_c- (M24)", minimum=0.0, plausible=(0.0, 1e6))
    static_up: float = parameter(0.0, "N", "F_s+ (M24)", minimum=0.0, plausible=(0.0, 1e6))
    static_down: float = parameter(0.0, "N", "F_s- (M24)", minimum=0.0, plausible=(0.0, 1e6))
    stribeck_velocity: float = parameter(0.01, "m/s", "C_s (M24)", positive=True,
                                         plausible=(1e-06, 1.0))
    stribeck_exponent: float = parameter(2.0, "-", "delta (M24)", minimum=0.0, plausible=(0.1, 5.0))
    regularization_velocity: float = parameter(1e-4, "m/s", "v_reg of tanh(v/v_reg)", positive=True,
                                               plausible=(1e-08, 0.1))
    model: str = parameter("stribeck", "str", "memory-less Stribeck or LuGre stick-slip",
                           choices=("stribeck", "lugre"))
    bristle_stiffness: float = parameter(1e7, "N/m", "sigma0 (LuGre)", positive=True,
                                         plausible=(100.0, 1e12))
    bristle_damping: float = parameter(1e3, "N*s/m", "sigma1 (LuGre)", minimum=0.0,
                                       plausible=(0.0, 1e8))

    inputs = {"velocity": Port("velocity", "piston velocity, up +")}
    outputs = {"friction_force": Port("force", "friction force opposing +v when > 0")}

    def __post_init__(self):
        self.check_parameters()
        self.feedthrough = True

    @property
    def states(self):
        """The states: the LuGre ``bristle`` deflection [m] with ``model = "lugre"``, else none."""
        return [State("bristle", "m", 1e-5)] if self.model == "lugre" else []

    #: The piston velocity's absolute tolerance never exceeds this fraction of ``v_reg``
    #: (:meth:`input_resolutions`), [-]: tanh(v / v_reg) changes by up to this fraction of
    #: the friction force per error of that size, well inside its linear range (slope 1 at
    #: v = 0); looser, a piston at rest jitters across the slope (Newton failures).
    VELOCITY_RESOLUTION = 0.1

    def input_resolutions(self):
        """The piston velocity to a tenth of ``v_reg`` (:data:`VELOCITY_RESOLUTION`): the
        regularised Stribeck curve's steep slope at rest (M36); none for LuGre.

        Returns
        -------
        dict
            ``{"velocity": ceiling}``, [m/s].
        """
        if self.model != "stribeck":
            return {}
        return {"velocity": self.VELOCITY_RESOLUTION * self.regularization_velocity}

    def _curve(self, v, up: bool):
        """Stribeck level F_c + (F_s - F_c) exp(-(|v|/C_s)^delta) of one direction, [N]."""
        fc = self.coulomb_up if up else self.coulomb_down
        fs = self.static_up if up else self.static_down
        av = ops.fabs(v) / self.stribeck_velocity
        return fc + (fs - fc) * ops.exp(-(av + 1e-30) ** self.stribeck_exponent)

    def _pick(self, v, up_value, down_value):
        return ops.if_else(v >= 0, up_value, down_value)

    def force(self, v, z=None):
        """Friction force at velocity v [m/s] (M24), [N].

        Parameters
        ----------
        v : float
            Piston velocity, positive up (number or CasADi symbol), [m/s]
        z : float
            Bristle deflection (LuGre only; unused by "stribeck"), [m]

        Returns
        -------
        float
            Friction force on the piston, opposing v, [N]
        """
        fv = self._pick(v, self.viscous_up, self.viscous_down)
        g = self._pick(v, self._curve(v, True), self._curve(v, False))
        if self.model == "stribeck":
            return fv * v + ops.tanh(v / self.regularization_velocity) * g
        dz = self._bristle_rate(v, z, g)
        return self.bristle_stiffness * z + self.bristle_damping * dz + fv * v

    def _bristle_rate(self, v, z, g):
        return v - self.bristle_stiffness * ops.fabs(v) * z / ops.fmax(g, 1e-9)

    def outputs_of(self, t, x, u, p):
        return {"friction_force": self.force(u["velocity"], x.get("bristle"))}

    def derivatives(self, t, x, u, p):
        if self.model == "stribeck":
            return {}
        v = u["velocity"]
        g = self._pick(v, self._curve(v, True), self._curve(v, False))
        return {"bristle": self._bristle_rate(v, x["bristle"], g)}
