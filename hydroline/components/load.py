"""The load on the rod: specimen spring and damper, applied force (M29, docs/model.md 4)."""
from __future__ import annotations

from dataclasses import dataclass

from ..engine import ops
from ..engine.component import Component, Port, parameter

__all__ = ["Load"]


@dataclass(kw_only=True)
class Load(Component):
    """Force of the load on the piston, positive down (opposing +x).

    ``F = k (x - x_free) + b v + F_applied`` (and ``F_step`` after ``step_time``). The load
    mass is rigidly attached and is part of the moving mass of the actuator whose position
    it reads (``adds_to``: the circuit builder adds it), so its weight is in (M23)'s ``m g``.

    Parameters
    ----------
    mass : float
        Load mass, [kg] (added to the actuator's moving mass)
    stiffness : float
        Specimen stiffness k, [N/m]
    damping : float
        Specimen damping b, [N s/m]
    free_position : float
        x at which the specimen is unloaded, [m]
    applied_force : float
        Constant external force, positive down, [N]
    step_time : float
        Time of an optional step of the external force (None: none), [s]
    step_force : float
        The force step, positive down, [N]

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.

    Notes
    -----
    Ports: inputs ``position`` [m], ``velocity`` [m/s]; output ``load_force`` [N].
    """

    mass: float = parameter(0.0, "kg", "load mass, added to the actuator's moving mass", minimum=0.0,
                            plausible=(0.0, 1e5))
    stiffness: float = parameter(0.0, "N/m", "specimen stiffness k", minimum=0.0,
                                 plausible=(0.0, 1e10))
    damping: float = parameter(0.0, "N*s/m", "specimen damping b", minimum=0.0,
                               plausible=(0.0, 1e8))
    free_position: float = parameter(0.0, "m", "x at which the specimen is unloaded",
                                     plausible=(-10.0, 10.0))
    applied_force: float = parameter(0.0, "N", "constant external force, positive down",
                                     plausible=(-1e7, 1e7))
    step_time: float | None = parameter(None, "s", "time of a step of the external force",
                                        minimum=0.0, optional=True, plausible=(0.0, 1e4))
    step_force: float = parameter(0.0, "N", "the force step, positive down",
                                  plausible=(-1e7, 1e7))

    inputs = {"position": Port("position", "piston position"),
              "velocity": Port("velocity", "piston velocity")}
    outputs = {"load_force": Port("force", "force of the load, positive down")}
    adds_to = (("mass", "position", "moving_mass"),)

    def __post_init__(self):
        self.check_parameters()

    def runtime_parameters(self):
        return {"applied_force": self.applied_force}

    def outputs_of(self, t, x, u, p):
        f = self.stiffness * (u["position"] - self.free_position) + self.damping * u["velocity"] \
            + p["applied_force"]
        if self.step_time is not None:
            f = f + ops.if_else(t >= self.step_time, self.step_force, 0.0)
        return {"load_force": f}

    def breakpoints(self, t_end):
        return [] if self.step_time is None else [self.step_time]
