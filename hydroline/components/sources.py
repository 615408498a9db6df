"""Pressure sources: the pump unit (HPS) and the tank (docs/model.md section 1, 6)."""
from __future__ import annotations

from dataclasses import dataclass

from ..engine.component import Component, HydraulicEnd, Port, parameter
from .commands import StepCommand

__all__ = ["PressureSource"]

_PREFIX = "waveform."


@dataclass(kw_only=True)
class PressureSource(Component):
    """A known pressure ``p(t)``: constant or any command waveform (docs/model.md 1: ``p_hps(t)``,
    ``p_tank(t)`` are known inputs).

    Constant: ``p(t) = pressure``. With a ``waveform`` (a command of
    :mod:`hydroline.components.commands` with ``quantity="pressure"``: step, sine, ramp or
    CSV table, giving the absolute pressure):

        p(t) = waveform(t) + (p_run - pressure)

    where ``pressure`` is the level before the disturbance, ``waveform(0)`` (the steady
    state is solved there), and ``p_run`` the runtime parameter ``pressure``: changing it
    shifts the whole waveform (a sweep or a linearisation that varies the level). The old
    single-step form ``step_time``/``step_to`` is a :class:`StepCommand` waveform.

    Parameters
    ----------
    pressure : float
        Pressure (constant), or the waveform's value at t = 0 (may be
        omitted then), [Pa] (absolute)
    waveform : Component
        Command whose ``command`` output is the absolute pressure, [Pa];
        None for a constant
    step_time : float
        Time of an optional single step, [s]; None for none
    step_to : float
        Pressure after that step, [Pa]

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.

    Notes
    -----
    Ports: output ``pressure`` [Pa].
    """

    pressure: float | None = parameter(None, "Pa", "absolute pressure (or the waveform's at t = 0)",
                                       positive=True, optional=True, plausible=(1e3, 1e8))
    waveform: Component | None = None
    step_time: float | None = None
    step_to: float | None = None

    outputs = {"pressure": Port("pressure", "source pressure, absolute")}
    feedthrough = False
    conducts = True

    def __post_init__(self):
        self.check_parameters()
        if self.step_time is not None:
            if self.waveform is not None or self.step_to is None or self.pressure is None:
                raise ValueError(f"{self.name}: a step needs pressure and step_to [Pa] and no waveform")
            self.waveform = StepCommand(name=f"{self.name}.waveform", quantity="pressure",
                                        initial=self.pressure, final=self.step_to, time=self.step_time)
        if self.waveform is None:
            if self.pressure is None:
                raise ValueError(f"{self.name}: give pressure [Pa] or a waveform")
            return
        port = getattr(self.waveform, "outputs", {}).get("command")
        if port is None or port.quantity != "pressure":
            raise ValueError(f"{self.name}: waveform must be a command with quantity='pressure' "
                             f"(its output in [Pa])")
        if self.waveform.inputs or self.waveform.states:
            raise ValueError(f"{self.name}: waveform must be a command without inputs or states")
        start = self.waveform_value(0.0)
        if self.pressure is None:
            self.pressure = start
        elif abs(self.pressure - start) > 1e-9 * max(abs(start), 1.0):
            raise ValueError(f"{self.name}: pressure ({self.pressure:g} Pa) must equal the "
                             f"waveform's value at t = 0 ({start:g} Pa), or be omitted")

    def hydraulic_ends(self):
        """Its port: a prescribed pressure (it takes any flow).

        Returns
        -------
        dict
            End name -> :class:`~hydroline.engine.component.HydraulicEnd`.
        """
        return {"port": HydraulicEnd("pressure")}

    def waveform_value(self, t: float) -> float:
        """The waveform's pressure at time t (numbers; default parameters), [Pa].

        Parameters
        ----------
        t : float
            Time, [s]

        Returns
        -------
        float
            Source pressure, [Pa]
        """
        if self.waveform is None:
            return float(self.pressure)
        return float(self.waveform.outputs_of(t, {}, {}, self.waveform.runtime_parameters())["command"])

    def runtime_parameters(self):
        out = {"pressure": self.pressure}
        if self.waveform is not None:
            out.update({_PREFIX + k: v for k, v in self.waveform.runtime_parameters().items()})
        return out

    def outputs_of(self, t, x, u, p):
        if self.waveform is None:
            return {"pressure": p["pressure"]}
        wp = {k[len(_PREFIX):]: v for k, v in p.items() if k.startswith(_PREFIX)}
        w = self.waveform.outputs_of(t, {}, {}, wp)["command"]
        return {"pressure": w + (p["pressure"] - self.pressure)}

    def breakpoints(self, t_end):
        return [] if self.waveform is None else list(self.waveform.breakpoints(t_end))
