"""Position controller of the servo loop: P or PID, current limited to +-rated (M30)."""
from __future__ import annotations

from dataclasses import dataclass

from ..engine import ops
from ..engine.component import Component, Port, State, parameter

__all__ = ["PositionController"]


@dataclass(kw_only=True)
class PositionController(Component):
    """``i = Kp e + Ki int(e) + Kd de/dt``, ``e = x_ref - x_p``, clipped to +-current_limit.

    The derivative acts on the measured velocity (``-Kd v_p``, no derivative kick).
    With ``sample_time`` set, the controller is sampled: the current is computed at multiples
    of the sample time and held in between (zero-order hold); the simulation steps the
    integrator from sample to sample.

    Parameters
    ----------
    proportional_gain : float
        Kp, [A/m]
    integral_gain : float
        Ki, [A/(m s)]
    derivative_gain : float
        Kd, [A s/m]
    current_limit : float
        [A] (the valve's rated current)
    sample_time : float
        [s]; None for a continuous controller

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.

    Notes
    -----
    Ports: inputs ``reference`` and ``position`` [m], ``velocity`` [m/s]; output ``current`` [A].
    States: ``error_integral`` [m s] when Ki != 0.
    """

    proportional_gain: float = parameter(0.0, "A/m", "Kp", minimum=0.0, plausible=(0.0, 1000.0))
    integral_gain: float = parameter(0.0, "A/m/s", "Ki", minimum=0.0, plausible=(0.0, 1e5))
    derivative_gain: float = parameter(0.0, "A*s/m", "Kd, on the measured velocity", minimum=0.0,
                                       plausible=(0.0, 10.0))
    current_limit: float = parameter(0.05, "A", "+- limit of the current (the valve's rated)", positive=True,
                                     plausible=(0.0001, 5.0))
    sample_time: float | None = parameter(None, "s", "zero-order-hold period (None: continuous)",
                                          positive=True, optional=True, plausible=(1e-06, 1.0))

    inputs = {"reference": Port("position", "position command"),
              "position": Port("position", "measured piston position"),
              "velocity": Port("velocity", "measured piston velocity")}
    outputs = {"current": Port("current", "valve coil current")}

    def __post_init__(self):
        self.check_parameters()

    @property
    def states(self):
        """The states: ``error_integral`` [m s] when ``integral_gain`` is not 0, else none."""
        return [State("error_integral", "m s", 1e-3)] if self.integral_gain else []

    def runtime_parameters(self):
        # "sampled" is 0 while the steady state is solved (the continuous law holds the piston)
        # and 1 once settle() has stored the held current
        return {"held_current": 0.0, "sampled": 0.0} if self.sample_time else {}

    def law(self, x, u):
        """Unclipped control law, [A].

        Parameters
        ----------
        x : dict
            States, local name -> value [SI] (``error_integral`` [m s] when Ki != 0)
        u : dict
            Inputs ``reference``, ``position`` [m] and ``velocity`` [m/s]

        Returns
        -------
        float
            Coil current before the limit, [A]
        """
        e = u["reference"] - u["position"]
        i = self.proportional_gain * e - self.derivative_gain * u["velocity"]
        if "error_integral" in x:   # (Ki != 0: the state exists; Ki may be a symbol here)
            i = i + self.integral_gain * x["error_integral"]
        return i

    def clip(self, i):
        """The current limited to +-``current_limit``, [A].

        Parameters
        ----------
        i : float
            Coil current (number or CasADi symbol), [A]

        Returns
        -------
        float
            The current within +-``current_limit``, [A]
        """
        return ops.fmin(ops.fmax(i, -self.current_limit), self.current_limit)

    def outputs_of(self, t, x, u, p):
        continuous = self.clip(self.law(x, u))
        if "sampled" in p:          # (a sample time: its hold parameters exist)
            return {"current": p["sampled"] * p["held_current"] + (1.0 - p["sampled"]) * continuous}
        return {"current": continuous}

    def derivatives(self, t, x, u, p):
        if "error_integral" not in x:
            return {}
        return {"error_integral": u["reference"] - u["position"]}

    def settle(self, x, u, p):
        """At the steady state the held current is the law's output there.

        Parameters
        ----------
        x : dict
            States at the steady state, local name -> value [SI]
        u : dict
            Inputs there, local port name -> value [SI]
        p : dict
            Runtime parameters, name -> value [SI]

        Returns
        -------
        tuple or None
            ``({}, {"held_current": [A], "sampled": 1.0})``; None when continuous
        """
        if not self.sample_time:
            return None
        return {}, {"held_current": float(self.clip(self.law(x, u))), "sampled": 1.0}

    def sample(self, x, u):
        """New held current at a sampling instant (numbers), [A].

        Parameters
        ----------
        x : dict
            States at the instant, local name -> value [SI]
        u : dict
            Inputs there, local port name -> value [SI]

        Returns
        -------
        dict
            ``{"held_current": current}``, [A]
        """
        return {"held_current": float(self.clip(self.law(x, u)))}
