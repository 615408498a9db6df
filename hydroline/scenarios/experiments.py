"""Experiments on a rig: what drives which axis, for how long, and where the disturbance is.

The built-in experiments are the paper's open-loop step and closed-loop sine and the
multi-axis position step (:data:`EXPERIMENTS`); a rig may define its own, a command per axis
(:class:`AxisCommands`, :data:`OWN_EXPERIMENTS`). :func:`build_scenario` turns one into the
command components and times of a run (:class:`Scenario`); :mod:`hydroline.scenarios.running`
runs it and :mod:`hydroline.scenarios.summaries` summarizes the run.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

from .. import components as comp
from ..traces.metrics import SETTLING_BAND
from ..rigs import SCHEMA, Rig, RigError, load_rig
from ..components.commands import read_table_csv
from ..rigs.parameters import allowed_implausible, check_consistency
from ..engine import SimulationResult
from ..scenario_schema import QUANTITY_UNITS, WAVEFORM_KEYS
from ..system import build_circuit
from .summaries import COMMAND_START, run_summary

__all__ = ["SCENARIOS", "EXPERIMENTS", "OWN_EXPERIMENTS", "Experiment", "OpenLoopStep",
           "ClosedLoopSine", "PositionStep", "AxisCommand", "AxisCommands", "experiment",
           "scenario_names", "build_scenario", "Scenario", "default_scenario", "hold_other_axes",
           "template_controller"]

#: "position-step": the axis named by ``scenario.position-step.axis`` (the first by default)
#: steps its position reference by ``step`` at ``time`` while every other axis holds its
#: position under its controller (multi-axis rigs, e.g. ``two_axis``).
SCENARIOS = ("open-loop-step", "closed-loop-sine", "position-step")


def default_scenario(rig: Rig) -> str:
    """The rig's ``rig.scenario``, else "open-loop-step".

    Parameters
    ----------
    rig : Rig
        The parsed rig

    Returns
    -------
    str
        The scenario's name
    """
    return rig.get("rig.scenario", "open-loop-step")

@dataclass
class Scenario:
    """An experiment built for one rig: its command components and times.

    Attributes
    ----------
    name : str
        The experiment's name (its ``[scenario.NAME]`` table)
    commands : list
        Components that drive the network (``valve_current`` source or
        reference + controller)
    t_end : float
        Simulated time, [s]
    t_disturbance : float
        Time of the step (metrics start there), [s]
    position_guess : float
        Initial piston position, [m]
    experiment : Experiment
        The experiment it was built from
    """

    name: str
    commands: list
    t_end: float
    t_disturbance: float
    position_guess: float | None = None
    experiment: "Experiment | None" = None


def _scenario_value(rig, scenario, key, default=None):
    v = rig.get(f"scenario.{scenario}.{key}", default)
    if v is None:
        raise RigError(f"scenario.{scenario}.{key}: not set in rig {rig.source}; add to the rig "
                       f"file: [scenario.{scenario}] {key} = {_example_value(scenario, key)}")
    return v


def _example_value(scenario, key) -> str:
    """A TOML value for a missing ``scenario.<scenario>.<key>``: the embedded rig's (as written
    there, with its unit), else a placeholder in the key's SI unit."""
    from ..rigs.parameters import PARAMETERS

    raw = load_rig().raw.get(f"scenario.{scenario}.{key}")
    if raw is not None:
        return f'"{raw}"' if isinstance(raw, str) else repr(raw)
    units = [getattr(p, "unit", None) for path, p in PARAMETERS.items()
             if path.startswith("scenario.") and path.endswith(f".{key}")]
    unit = next((u for u in units if u and u not in ("-", "str")), None)
    return f'"<value> {unit}"' if unit else "<value>"


def _check_scenario(rig, scenario, t_end):
    """RigError naming the [scenario.*] key whose value no run can use."""
    def bad(key, rule):
        path = f"scenario.{scenario}.{key}"
        unit = SCHEMA.get(f"scenario.{scenario}", {}).get(key, "")
        raise RigError(f"{path}: must be {rule} [{unit}], got {rig.raw.get(path, rig.get(path))!r}")

    if t_end is None and rig.get(f"scenario.{scenario}.t_end") is not None \
            and not rig[f"scenario.{scenario}.t_end"] > 0:
        bad("t_end", "> 0")
    if scenario == "open-loop-step" and not rig.get(f"scenario.{scenario}.time", 0.0) >= 0:
        bad("time", ">= 0")
    if scenario == "closed-loop-sine":
        if rig.get(f"scenario.{scenario}.frequency") is not None \
                and not rig[f"scenario.{scenario}.frequency"] > 0:
            bad("frequency", "> 0")
        x0 = rig.get(f"scenario.{scenario}.initial_position")
        half = rig.get("actuator.stroke", np.inf) / 2
        if x0 is not None and not abs(x0) <= half:
            bad("initial_position", f"within +-stroke/2 = +-{half * 1e3:g} mm (piston inside the cylinder)")


def _initial_position(rig, axis) -> float:
    """Where the axis's piston starts (``circuit.<actuator>.initial_position``, else 0), [m]."""
    return 0.0 if rig is None else rig.get(f"circuit.{axis.actuator}.initial_position", 0.0)


def _pick_axis(axes: dict, name: str | None, key: str):
    """The axis called ``name`` (the first when None); RigError naming ``key`` if none."""
    if name is None:
        return next(iter(axes.values()))
    if name not in axes:
        raise RigError(f"{key}: no axis {name!r} in the rig (axes: {', '.join(axes)})")
    return axes[name]


def template_controller(rig: Rig, axis) -> comp.PositionController:
    """The template rig's position loop from its ``[controller]`` table, closed on ``axis``.

    Parameters
    ----------
    rig : Rig
        Parameters (SI): ``controller.proportional_gain`` [A/m] and optionally
        ``integral_gain`` [A/(m s)], ``derivative_gain`` [A s/m], ``current_limit`` [A],
        ``sample_time`` [s]
    axis : Axis
        The axis whose valve current the controller drives

    Returns
    -------
    PositionController
        The controller closing the axis's position loop
    """
    if rig is None or rig.get("controller.proportional_gain") is None:
        raise RigError(f"controller.proportional_gain: not set in rig "
                       f"{'' if rig is None else rig.source} [A/m] (axis '{axis.name}' has no "
                       f"position controller in the circuit; this closes its loop)")
    return comp.PositionController(
        name="controller", proportional_gain=rig["controller.proportional_gain"],
        integral_gain=rig.get("controller.integral_gain", 0.0),
        derivative_gain=rig.get("controller.derivative_gain", 0.0),
        current_limit=rig.get("controller.current_limit", rig.get("servovalve.rated_current", 0.05)),
        sample_time=rig.get("controller.sample_time"),
        connections={"reference": axis.reference_signal, "position": axis.position,
                     "velocity": axis.velocity, "current": axis.current})


def _within_stroke(rig, path: str, reach: float, what: str, axis):
    """Refuse a position reference that leaves the axis's stroke: ``reach`` [m] from mid-stroke
    beyond +-stroke/2 parks the piston on its stop for the run (a slip of unit, "1 km" for
    "1 mm"); ``[rig] allow_implausible`` naming ``path`` lets it run.

    Parameters
    ----------
    rig : Rig
        Parameters (SI); None: nothing is allowed
    path : str
        The scenario key that sets the command, for the message
    reach : float
        Farthest reference from mid-stroke, [m]
    what : str
        How the reference gets there, for the message
    axis : Axis
        The commanded axis (its stroke)
    """
    half = axis.stroke / 2
    if abs(reach) <= half * (1 + 1e-9) or (rig is not None and path in allowed_implausible(rig)):
        return
    raise RigError(f"{path}: {what} takes the position reference of axis '{axis.name}' to "
                   f"{reach * 1e3:g} mm, beyond its stroke (+-{half * 1e3:g} mm) [m]: the piston "
                   f"would sit on its stop; if it is meant, add \"{path}\" to [rig] "
                   f"allow_implausible")


def _drive(rig, axis, quantity: str, component, key: str) -> list:
    """``component`` (a command) connected to the axis's valve current or position reference;
    with the template's controller where a position reference has none in the circuit."""
    component.connections = {"command": axis.current if quantity == "current"
                             else axis.reference_signal}
    if quantity == "position" and not axis.controller:
        return [component, template_controller(rig, axis)]
    if quantity == "current" and axis.controller:
        raise RigError(f"{key}: the valve current of axis '{axis.name}' is driven by "
                       f"'{axis.controller}' in the circuit; command its position instead")
    return [component]


@dataclass(kw_only=True)
class Experiment:
    """An experiment: what drives which axis, for how long, where its disturbance is and what
    its summary holds. Subclasses register under a ``kind`` (:data:`EXPERIMENTS`); a rig
    selects one by name (``[scenario.NAME]``, ``--scenario NAME``).

    Attributes
    ----------
    name : str
        The experiment's name (its ``[scenario.NAME]`` table)
    t_end : float
        Simulated time, [s]
    """

    #: Registry name of the experiment type.
    kind: ClassVar[str] = ""
    #: How the metrics window's start is named in the summary note.
    window_start: ClassVar[str] = COMMAND_START

    name: str = ""
    t_end: float = 1.0

    def __post_init__(self):
        self.name = self.name or self.kind
        if not (np.isfinite(self.t_end) and self.t_end > 0):
            raise RigError(f"scenario.{self.name}.t_end: must be > 0 [s], got {self.t_end!r}")

    @property
    def t_disturbance(self) -> float:
        """Time of the disturbance (the metrics start there), [s]."""
        return 0.0

    @property
    def position_guess(self) -> float | None:
        """Initial piston position of a template rig's actuator, [m] (None: mid-stroke)."""
        return None

    def commands(self, axes: dict, rig: Rig | None = None) -> list:
        """The command components that drive (and hold) the rig's axes.

        Parameters
        ----------
        axes : dict
            Axis name -> :class:`hydroline.circuit.Axis` (signal handles)
        rig : Rig
            Parameters (SI): where pistons start, the template's ``[controller]``

        Returns
        -------
        list
            Components
        """
        raise NotImplementedError

    def driven_axes(self, axes: dict) -> list[str]:
        """Names of the axes the experiment moves on purpose (the others hold).

        Parameters
        ----------
        axes : dict
            Axis name -> Axis

        Returns
        -------
        list of str
            Axis names
        """
        return [next(iter(axes))]

    def metadata(self) -> dict:
        """What the experiment adds to a result's ``metadata``.

        Returns
        -------
        dict
            Key -> value (SI) added to the result's metadata; empty for most experiments
        """
        return {}

    def summary(self, result: SimulationResult, settling_band=SETTLING_BAND) -> dict:
        """The summary of a run of this experiment (see :func:`summarize`).

        Parameters
        ----------
        result : SimulationResult
            A run of this experiment (:func:`simulate`)
        settling_band : SettlingBand
            The port pressures' settling band
            (:class:`hydroline.traces.metrics.SettlingBand`; default
            +-2 % of the final absolute pressure)

        Returns
        -------
        dict
            The summary (:func:`hydroline.summarize`: per port metrics, notes, the window)
        """
        return run_summary(result, self.window_start, sine=False, settling_band=settling_band)


def _commands_with_holds(rig, axes, driven: str, commands: list) -> list:
    return commands + hold_other_axes(rig, axes, driven)


@dataclass(kw_only=True)
class OpenLoopStep(Experiment):
    """A step of valve current into one axis (the paper's open-loop test, Figs. 10-12).

    Attributes
    ----------
    current : float
        Current after the step, [A] (None: ``servovalve.rated_current``)
    initial_current : float
        Current before the step, [A]
    time : float
        Time of the step, [s]
    axis : str
        The stepped axis (None: the first)
    name : str
        The experiment's name (its ``[scenario.NAME]`` table)
    t_end : float
        Simulated time, [s] (default 0.25 s)
    """

    kind: ClassVar[str] = "open-loop-step"
    window_start: ClassVar[str] = "the valve step"

    current: float | None = None
    initial_current: float = 0.0
    time: float = 0.01
    axis: str | None = None
    t_end: float = 0.25

    @classmethod
    def from_rig(cls, rig: Rig, name: str = "open-loop-step", t_end: float | None = None):
        """The experiment from the rig's ``[scenario.open-loop-step]`` table (SI values).

        Parameters
        ----------
        rig : Rig
            Parameters (SI)
        name : str
            Its table's name
        t_end : float
            Simulated time, [s] (the table's, else 0.25 s, when None)

        Returns
        -------
        OpenLoopStep
            The experiment
        """
        return cls(name=name, current=_scenario_value(rig, name, "current",
                                                      rig.get("servovalve.rated_current", 0.05)),
                   initial_current=rig.get(f"scenario.{name}.initial_current", 0.0),
                   time=_scenario_value(rig, name, "time", 0.01),
                   t_end=t_end or _scenario_value(rig, name, "t_end", 0.25))

    @property
    def t_disturbance(self) -> float:
        return self.time

    def driven_axes(self, axes):
        return [_pick_axis(axes, self.axis, f"scenario.{self.name}.axis").name]

    def commands(self, axes, rig=None):
        axis = _pick_axis(axes, self.axis, f"scenario.{self.name}.axis")
        if axis.controller:
            raise RigError(f"scenario {self.name}: the valve current of axis '{axis.name}' is "
                           f"driven by '{axis.controller}' in the circuit; use position-step")
        final = self.current if self.current is not None else \
            (0.05 if rig is None else rig.get("servovalve.rated_current", 0.05))
        cmd = comp.StepCommand(name="command", quantity="current", initial=self.initial_current,
                               final=final, time=self.time, connections={"command": axis.current})
        return _commands_with_holds(rig, axes, axis.name, [cmd])


@dataclass(kw_only=True)
class ClosedLoopSine(Experiment):
    """A sine position reference tracked by one axis's position loop (the paper's 2 Hz test).

    Attributes
    ----------
    amplitude : float
        Reference amplitude, [m]
    frequency : float
        Reference frequency, [Hz]
    offset : float
        Reference mean, [m]
    initial_position : float
        Piston position at the start (template rigs), [m]
    axis : str
        The tracking axis (None: the first)
    name : str
        The experiment's name (its ``[scenario.NAME]`` table)
    t_end : float
        Simulated time, [s] (default 1 s)
    """

    kind: ClassVar[str] = "closed-loop-sine"

    amplitude: float = 0.0
    frequency: float = 1.0
    offset: float = 0.0
    initial_position: float = 0.0
    axis: str | None = None
    t_end: float = 1.0

    def __post_init__(self):
        super().__post_init__()
        if not (np.isfinite(self.frequency) and self.frequency > 0):
            raise RigError(f"scenario.{self.name}.frequency: must be > 0 [Hz], got "
                           f"{self.frequency!r}")

    @classmethod
    def from_rig(cls, rig: Rig, name: str = "closed-loop-sine", t_end: float | None = None):
        """The experiment from the rig's ``[scenario.closed-loop-sine]`` table (SI values).

        Parameters
        ----------
        rig : Rig
            Parameters (SI)
        name : str
            Its table's name
        t_end : float
            Simulated time, [s] (the table's, else 1 s, when None)

        Returns
        -------
        ClosedLoopSine
            The experiment
        """
        return cls(name=name, offset=_scenario_value(rig, name, "offset", 0.0),
                   amplitude=_scenario_value(rig, name, "amplitude"),
                   frequency=_scenario_value(rig, name, "frequency"),
                   initial_position=_scenario_value(rig, name, "initial_position", 0.0),
                   t_end=t_end or _scenario_value(rig, name, "t_end", 1.0))

    @property
    def position_guess(self):
        return self.initial_position

    def driven_axes(self, axes):
        return [_pick_axis(axes, self.axis, f"scenario.{self.name}.axis").name]

    def metadata(self):
        return {"command_frequency_hz": float(self.frequency)}

    def commands(self, axes, rig=None):
        axis = _pick_axis(axes, self.axis, f"scenario.{self.name}.axis")
        _within_stroke(rig, f"scenario.{self.name}.amplitude", abs(self.offset) + abs(self.amplitude),
                       f"an offset of {self.offset * 1e3:g} mm and an amplitude of "
                       f"{self.amplitude * 1e3:g} mm", axis)
        ref = comp.SineCommand(name="command", quantity="position", offset=self.offset,
                               amplitude=self.amplitude, frequency=self.frequency, start=0.0,
                               connections={"command": axis.reference_signal})
        cmds = [ref] if axis.controller else [ref, template_controller(rig, axis)]
        return _commands_with_holds(rig, axes, axis.name, cmds)

    def summary(self, result, settling_band=SETTLING_BAND):
        return run_summary(result, self.window_start, sine=True)


@dataclass(kw_only=True)
class PositionStep(Experiment):
    """A step of one axis's position reference; every other axis holds (multi-axis rigs).

    Attributes
    ----------
    step : float
        Reference step from where the piston starts, [m]
    time : float
        Time of the step, > 0 (the steady state is solved before it), [s]
    axis : str
        The stepped axis (None: the first)
    name : str
        The experiment's name (its ``[scenario.NAME]`` table)
    t_end : float
        Simulated time, [s] (default 0.15 s)
    """

    kind: ClassVar[str] = "position-step"

    step: float = 0.0
    time: float = 0.01
    axis: str | None = None
    t_end: float = 0.15

    def __post_init__(self):
        super().__post_init__()
        if not self.time > 0:
            raise RigError(f"scenario.{self.name}.time: must be > 0 [s] (the steady state is "
                           f"solved before the step), got {self.time!r}")

    @classmethod
    def from_rig(cls, rig: Rig, name: str = "position-step", t_end: float | None = None):
        """The experiment from the rig's ``[scenario.position-step]`` table (SI values).

        Parameters
        ----------
        rig : Rig
            Parameters (SI)
        name : str
            Its table's name
        t_end : float
            Simulated time, [s] (the table's, else 0.15 s, when None)

        Returns
        -------
        PositionStep
            The experiment
        """
        key = f"scenario.{name}"
        t_step = rig.get(f"{key}.time", 0.01)
        if not t_step > 0:
            raise RigError(f"{key}.time: must be > 0 [s] (the steady state is solved before the "
                           f"step), got {rig.raw.get(f'{key}.time', t_step)!r}")
        return cls(name=name, axis=rig.get(f"{key}.axis"), time=t_step,
                   step=_scenario_value(rig, name, "step"),
                   t_end=t_end or _scenario_value(rig, name, "t_end", 0.15))

    @property
    def t_disturbance(self):
        return self.time

    def driven_axes(self, axes):
        return [_pick_axis(axes, self.axis, f"scenario.{self.name}.axis").name]

    def commands(self, axes, rig=None):
        ax = _pick_axis(axes, self.axis, f"scenario.{self.name}.axis")
        x0 = _initial_position(rig, ax)
        _within_stroke(rig, f"scenario.{self.name}.step", x0 + self.step,
                       f"a step of {self.step * 1e3:g} mm from {x0 * 1e3:g} mm", ax)
        cmd = comp.StepCommand(name=f"{ax.name}.command", quantity="position", initial=x0,
                               final=x0 + self.step, time=self.time,
                               connections={"command": ax.reference_signal})
        # an axis without a position controller in the circuit (the template rig): the
        # rig's [controller] closes its loop, as for the closed-loop sine
        cmds = [cmd] if ax.controller else [cmd, template_controller(rig, ax)]
        return _commands_with_holds(rig, axes, ax.name, cmds)


@dataclass
class AxisCommand:
    """One axis's command in a user's own experiment: a waveform or a table.

    Attributes
    ----------
    quantity : str
        "current" (valve current, [A]) or "position" (position reference, [m])
    waveform : str
        "step", "ramp", "sine" or "table"
    values : dict
        The waveform's parameters (:data:`hydroline.scenario_schema.WAVEFORM_KEYS`),
        SI: [A] or [m] for levels, [A/s] or [m/s] for slopes, [s], [Hz]; a level
        left out (``initial``, ``offset``) is where the axis starts
    times : ndarray
        Table times, [s] (``waveform = "table"``)
    table : ndarray
        Table values, [A] or [m]
    """

    quantity: str
    waveform: str
    values: dict = field(default_factory=dict)
    times: np.ndarray | None = None
    table: np.ndarray | None = None

    def __post_init__(self):
        if self.quantity not in QUANTITY_UNITS:
            raise RigError(f"quantity: must be one of {', '.join(QUANTITY_UNITS)}, got "
                           f"{self.quantity!r}")
        if self.waveform == "table":
            probe = comp.TableCommand(name="probe", quantity=self.quantity, times=self.times,
                                      values=self.table)
            self.times, self.table = probe.times, probe.values
        elif self.waveform not in WAVEFORM_KEYS or self.waveform == "csv":
            raise RigError(f"waveform: must be step, ramp, sine or table, got {self.waveform!r}")

    @classmethod
    def from_csv(cls, quantity: str, path) -> "AxisCommand":
        """A table command from a two-column CSV whose header carries units
        (``time [ms], current [mA]``).

        Parameters
        ----------
        quantity : str
            "current" [A] or "position" [m]
        path : str or Path
            The file

        Returns
        -------
        AxisCommand
            A ``"table"`` command, times [s] and values [A] or [m]

        Raises
        ------
        ValueError
            one line naming the file and what is wrong
        """
        t, v = read_table_csv(path, QUANTITY_UNITS[quantity])
        return cls(quantity, "table", times=t, table=v)

    def change_time(self) -> float:
        """When the command first changes (its disturbance), [s].

        Returns
        -------
        float
            The time of the first change, [s] (0 for a table that never changes)
        """
        v = self.values
        if self.waveform == "step":
            return float(v["time"])
        if self.waveform in ("ramp", "sine"):
            return float(v.get("start", 0.0))
        moving = np.flatnonzero(np.diff(self.table) != 0.0)
        return float(self.times[moving[0]]) if moving.size else 0.0

    def component(self, name: str, start: float, key: str):
        """The command component (its output not yet connected).

        Parameters
        ----------
        name : str
            Component name
        start : float
            Where the axis starts (level default), [A] or [m]
        key : str
            Rig path of the axis's table, for messages

        Returns
        -------
        Component
            A step, ramp, sine or table command

        Raises
        ------
        RigError
            One line naming the waveform's value that is missing or out of range
        """
        v, unit = self.values, QUANTITY_UNITS[self.quantity]

        def need(k):
            if k not in v:
                raise RigError(f"{key}.{k}: required for waveform = {self.waveform!r} "
                               f"[{WAVEFORM_KEYS[self.waveform][k][0].replace('q', unit)}]")
            return float(v[k])

        q = self.quantity
        if self.waveform == "step":
            if not need("time") > 0:
                raise RigError(f"{key}.time: must be > 0 [s] (the steady state is solved before "
                               f"the step), got {v['time']!r}")
            return comp.StepCommand(name=name, quantity=q, initial=v.get("initial", start),
                                    final=need("final"), time=v["time"])
        if self.waveform == "ramp":
            if not need("end") > need("start") >= 0:
                raise RigError(f"{key}.end: must be > start >= 0 [s], got start {v['start']!r}, "
                               f"end {v['end']!r}")
            return comp.RampCommand(name=name, quantity=q, initial=v.get("initial", start),
                                    slope=need("slope"), start=v["start"], end=v["end"])
        if self.waveform == "sine":
            if not need("frequency") > 0:
                raise RigError(f"{key}.frequency: must be > 0 [Hz], got {v['frequency']!r}")
            if not v.get("start", 0.0) >= 0:
                raise RigError(f"{key}.start: must be >= 0 [s], got {v['start']!r}")
            return comp.SineCommand(name=name, quantity=q, offset=v.get("offset", start),
                                    amplitude=need("amplitude"), frequency=v["frequency"],
                                    start=v.get("start", 0.0))
        return comp.TableCommand(name=name, quantity=q, times=self.times, values=self.table)

    def position_range(self, start: float) -> tuple[float, float]:
        """Lowest and highest value the command reaches, [A] or [m].

        Parameters
        ----------
        start : float
            Where the axis starts (the level a waveform without its own initial
            value or offset holds), [A] or [m]

        Returns
        -------
        tuple of float
            (lowest, highest), [A] or [m]
        """
        v = self.values
        if self.waveform == "step":
            lo = [v.get("initial", start), v["final"]]
        elif self.waveform == "ramp":
            a = v.get("initial", start)
            lo = [a, a + v["slope"] * (v["end"] - v["start"])]
        elif self.waveform == "sine":
            o = v.get("offset", start)
            lo = [o - abs(v["amplitude"]), o + abs(v["amplitude"])]
        else:
            lo = [float(np.min(self.table)), float(np.max(self.table))]
        return min(lo), max(lo)


@dataclass(kw_only=True)
class AxisCommands(Experiment):
    """A user's own experiment: a command per axis (waveform or CSV table); axes not listed
    hold. From a rig: ``[scenario.NAME] type = "axis-commands"`` (schema:
    :mod:`hydroline.scenario_schema`).

    Attributes
    ----------
    axes : dict
        Axis name -> :class:`AxisCommand`
    disturbance_time : float
        Where the metrics start, [s] (None: the first time a command
        changes)
    name : str
        The experiment's name (its ``[scenario.NAME]`` table)
    t_end : float
        Simulated time, [s]
    """

    kind: ClassVar[str] = "axis-commands"

    axes: dict = field(default_factory=dict)
    disturbance_time: float | None = None

    def __post_init__(self):
        super().__post_init__()
        if not self.axes:
            raise RigError(f"scenario.{self.name}: no axis commanded (give a "
                           f"[scenario.{self.name}.<axis>] table with quantity and waveform)")
        if self.disturbance_time is not None and not 0 <= self.disturbance_time < self.t_end:
            raise RigError(f"scenario.{self.name}.disturbance_time: must be within 0 ... t_end "
                           f"[s], got {self.disturbance_time!r}")

    @classmethod
    def from_rig(cls, rig: Rig, name: str, t_end: float | None = None):
        """The experiment from the rig's ``[scenario.NAME]`` table and its axis tables.

        Parameters
        ----------
        rig : Rig
            Parameters (SI), read with :mod:`hydroline.scenario_schema`
        name : str
            The table's name
        t_end : float
            Simulated time, [s] (the table's when None)

        Returns
        -------
        AxisCommands
            The experiment
        """
        base = f"scenario.{name}"
        t_end = t_end or rig.get(f"{base}.t_end")
        if t_end is None:
            raise RigError(f"{base}.t_end: required [s] (simulated time), not set in rig {rig.source}")
        tables: dict = {}
        for path, value in rig.values.items():
            parts = path.split(".")
            if len(parts) == 4 and path.startswith(base + "."):
                tables.setdefault(parts[2], {})[parts[3]] = value
        axes = {}
        for axis, keys in tables.items():
            key = f"{base}.{axis}"
            for k in ("quantity", "waveform"):
                if k not in keys:
                    raise RigError(f"{key}.{k}: required ({' or '.join(QUANTITY_UNITS) if k == 'quantity' else ', '.join(WAVEFORM_KEYS)})")
            quantity, waveform = keys.pop("quantity"), keys.pop("waveform")
            if waveform == "csv":
                path = Path(keys["file"]) if "file" in keys else None
                if path is None:
                    raise RigError(f"{key}.file: required for waveform = 'csv' (a CSV with header "
                                   f"'time [s], {quantity} [{QUANTITY_UNITS[quantity]}]', any units)")
                if not path.is_absolute() and not rig.source.startswith("embedded:"):
                    path = Path(rig.source).parent / path
                try:
                    axes[axis] = AxisCommand.from_csv(quantity, path)
                except ValueError as e:
                    raise RigError(f"{key}.file: {e}") from None
            else:
                for k, (unit, required) in WAVEFORM_KEYS[waveform].items():
                    if required and k not in keys:
                        raise RigError(f"{key}.{k}: required for waveform = {waveform!r} "
                                       f"[{unit.replace('q', QUANTITY_UNITS[quantity])}]")
                axes[axis] = AxisCommand(quantity, waveform, dict(keys))
        return cls(name=name, axes=axes, t_end=t_end,
                   disturbance_time=rig.get(f"{base}.disturbance_time"))

    @property
    def t_disturbance(self):
        if self.disturbance_time is not None:
            return float(self.disturbance_time)
        return min(c.change_time() for c in self.axes.values())

    def driven_axes(self, axes):
        return [a for a in axes if a in self.axes]

    def commands(self, axes, rig=None):
        out = []
        for axis_name, command in self.axes.items():
            key = f"scenario.{self.name}.{axis_name}"
            ax = _pick_axis(axes, axis_name, key)
            start = _initial_position(rig, ax) if command.quantity == "position" else 0.0
            c = command.component(f"{ax.name}.command", start, key)
            if command.quantity == "position":
                lo, hi = command.position_range(start)
                if max(abs(lo), abs(hi)) > ax.stroke / 2:
                    raise RigError(f"{key}: the position command reaches {lo * 1e3:g} ... "
                                   f"{hi * 1e3:g} mm, beyond the stroke +-{ax.stroke / 2e-3:g} "
                                   f"mm [m]")
            out += _drive(rig, ax, command.quantity, c, key)
        for ax in axes.values():
            if ax.name not in self.axes:
                out += hold_other_axes(rig, {ax.name: ax}, None)
        return out


#: Built-in experiments by name (``--scenario NAME``, ``[scenario.NAME]``).
EXPERIMENTS = {cls.kind: cls for cls in (OpenLoopStep, ClosedLoopSine, PositionStep)}
#: Experiment types a rig may define itself (``[scenario.NAME] type = "..."``).
OWN_EXPERIMENTS = {cls.kind: cls for cls in (AxisCommands,)}


def scenario_names(rig: Rig) -> list[str]:
    """Every experiment a rig can run by name: the built-in ones and the rig's own.

    Parameters
    ----------
    rig : Rig
        Parameters (SI)

    Returns
    -------
    list of str
        The built-in experiments' names, then the rig's own
    """
    own = [k.split(".")[1] for k in rig.values
           if k.startswith("scenario.") and k.endswith(".type") and k.count(".") == 2]
    return list(EXPERIMENTS) + [n for n in own if n not in EXPERIMENTS]


def experiment(rig: Rig, scenario: "str | Experiment", t_end: float | None = None) -> Experiment:
    """The experiment called ``scenario`` on the rig (or ``scenario`` itself, an object).

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    scenario : str or Experiment
        A name (:func:`scenario_names`) or an experiment object
    t_end : float
        Simulated time, [s] (the experiment's own when None)

    Returns
    -------
    Experiment
        The experiment, with ``t_end`` applied
    """
    if isinstance(scenario, Experiment):
        exp = replace(scenario, t_end=t_end) if t_end is not None else scenario
    elif scenario in EXPERIMENTS:
        _check_scenario(rig, scenario, t_end)
        check_consistency(rig, scenario)
        exp = EXPERIMENTS[scenario].from_rig(rig, scenario, t_end)
    elif rig.get(f"scenario.{scenario}.type") in OWN_EXPERIMENTS:
        exp = OWN_EXPERIMENTS[rig.get(f"scenario.{scenario}.type")].from_rig(rig, scenario, t_end)
    else:
        raise RigError(f"unknown scenario {scenario!r} (known: {', '.join(scenario_names(rig))})")
    if exp.t_disturbance > 0 and not exp.t_end > exp.t_disturbance:
        key = "time" if exp.name in EXPERIMENTS else "disturbance_time"
        raise RigError(f"t_end: the run would end at {exp.t_end * 1e3:g} ms, before the disturbance "
                       f"of scenario {exp.name} at {exp.t_disturbance * 1e3:g} ms (scenario."
                       f"{exp.name}.{key}) [s]: nothing but the rest state to show; give a t_end "
                       f"beyond it (e.g. --t-end)")
    return exp


def build_scenario(rig: Rig, scenario: "str | Experiment" = "open-loop-step",
                   t_end: float | None = None, axes: dict | None = None) -> Scenario:
    """The command components and times of an experiment on a rig.

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    scenario : str or Experiment
        A name (built-in, :data:`SCENARIOS`, or the rig's own) or an
        experiment object
    t_end : float
        Simulated time, [s] (the experiment's default when None)
    axes : dict
        The rig's axis handles (:attr:`hydroline.circuit.Circuit.axes`);
        built from the rig when None

    Returns
    -------
    Scenario
        The experiment's commands and times for this rig
    """
    if axes is None:
        axes = build_circuit(rig).axes
    if not axes:
        raise RigError(f"rig {rig.source}: no servo axis (an actuator driven by a servovalve)")
    exp = experiment(rig, scenario, t_end)
    return Scenario(exp.name, exp.commands(axes, rig), exp.t_end, exp.t_disturbance,
                    exp.position_guess, exp)


def hold_other_axes(rig: Rig, axes: dict, driven: str | None) -> list:
    """Commands that hold every axis but ``driven``: a constant position reference where the
    circuit has the axis's controller (it holds where its actuator starts), else zero valve
    current.

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    axes : dict
        Axis handles, name -> :class:`hydroline.circuit.Axis`
    driven : str
        The axis the experiment drives (None: hold them all)

    Returns
    -------
    list
        Command components
    """
    out = []
    for ax in axes.values():
        if ax.name == driven:
            continue
        if ax.controller:
            x0 = _initial_position(rig, ax)
            out.append(comp.StepCommand(name=f"{ax.name}.command", quantity="position", initial=x0,
                                        final=x0, time=0.0,
                                        connections={"command": ax.reference_signal}))
        else:
            out.append(comp.StepCommand(name=f"{ax.name}.command", quantity="current",
                                        connections={"command": ax.current}))
    return out
