"""Experiments on a rig: the open-loop step and the closed-loop sine (the paper's tests).

``simulate(rig, scenario, t_end)`` builds the network of the rig with the scenario's command
components, solves its steady state before the disturbance, integrates, checks validity
(pressures below zero absolute) and returns a :class:`~hydroline.engine.SimulationResult`
whose ``metadata`` holds what the summary needs.
"""
from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

from . import components as comp
from .traces.metrics import SETTLING_BAND, SettlingBand, pressure_metrics
from .limits import check_output_size
from .rigs import SCHEMA, Rig, RigError, load_rig
from .components.commands import read_table_csv
from .rigs.parameters import (ATMOSPHERIC_PRESSURE, allowed_implausible, check_consistency,
                              steady_state_hint)
from .engine import SimulationResult, SteadyStateError, integrate, solve_steady_state
from .scenario_schema import QUANTITY_UNITS, WAVEFORM_KEYS
from .system import build_circuit

__all__ = ["SCENARIOS", "EXPERIMENTS", "OWN_EXPERIMENTS", "Experiment", "OpenLoopStep",
           "ClosedLoopSine", "PositionStep", "AxisCommand", "AxisCommands", "experiment",
           "scenario_names", "simulate", "summarize", "SineSummaryStream", "build_scenario",
           "Scenario", "default_scenario", "hold_other_axes", "template_controller", "rest_state",
           "ripple_metrics"]

#: "position-step": the axis named by ``scenario.position-step.axis`` (the first by default)
#: steps its position reference by ``step`` at ``time`` while every other axis holds its
#: position under its controller (multi-axis rigs, e.g. ``two_axis``).
SCENARIOS = ("open-loop-step", "closed-loop-sine", "position-step")


def default_scenario(rig: Rig) -> str:
    """The rig's ``rig.scenario``, else "open-loop-step".

    Parameters
    ----------
    rig : Rig  The parsed rig

    Returns
    -------
    str  The scenario's name
    """
    return rig.get("rig.scenario", "open-loop-step")

#: Pressures watched for gas release and cavitation (docs/model.md 8): below the rig's
#: ``fluid.gas_release_pressure`` (absolute; default one atmosphere, the pressure at which oil
#: from a vented tank holds its dissolved air) the oil releases gas and the linear line model
#: no longer holds, [Pa].
CAVITATION_PRESSURE = ATMOSPHERIC_PRESSURE
#: Shared nodes watched besides every axis's ports and chambers (from its handles), where the
#: circuit has them: the HSM nodes of the template rig and of ``two_axis``.
WATCHED_NODES = ("supply.manifold_pressure", "return.manifold_pressure")
#: What is watched in a result without axis handles (the template rig's signals).
WATCHED_PRESSURES = ("supply_port_pressure", "return_port_pressure", "bottom_chamber_pressure",
                     "top_chamber_pressure") + WATCHED_NODES


@dataclass
class Scenario:
    """An experiment built for one rig: its command components and times.

    Attributes
    ----------
    name : str
    commands : list          Components that drive the network (``valve_current`` source or
                             reference + controller)
    t_end : float            Simulated time, [s]
    t_disturbance : float    Time of the step (metrics start there), [s]
    position_guess : float   Initial piston position, [m]
    experiment : Experiment  The experiment it was built from
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
    from .rigs.parameters import PARAMETERS

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
    rig : Rig    Parameters (SI): ``controller.proportional_gain`` [A/m] and optionally
                 ``integral_gain`` [A/(m s)], ``derivative_gain`` [A s/m], ``current_limit`` [A],
                 ``sample_time`` [s]
    axis : Axis  The axis whose valve current the controller drives

    Returns
    -------
    PositionController
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
    rig : Rig        Parameters (SI); None: nothing is allowed
    path : str       The scenario key that sets the command, for the message
    reach : float    Farthest reference from mid-stroke, [m]
    what : str       How the reference gets there, for the message
    axis : Axis      The commanded axis (its stroke)
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
    name : str          The experiment's name (its ``[scenario.NAME]`` table)
    t_end : float       Simulated time, [s]
    """

    #: Registry name of the experiment type.
    kind: ClassVar[str] = ""
    #: How the metrics window's start is named in the summary note.
    window_start: ClassVar[str] = "the start of the command"

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
        axes : dict   Axis name -> :class:`hydroline.circuit.Axis` (signal handles)
        rig : Rig     Parameters (SI): where pistons start, the template's ``[controller]``

        Returns
        -------
        list  Components
        """
        raise NotImplementedError

    def driven_axes(self, axes: dict) -> list[str]:
        """Names of the axes the experiment moves on purpose (the others hold).

        Parameters
        ----------
        axes : dict   Axis name -> Axis
        """
        return [next(iter(axes))]

    def metadata(self) -> dict:
        """What the experiment adds to a result's ``metadata``."""
        return {}

    def summary(self, result: SimulationResult, settling_band=SETTLING_BAND) -> dict:
        """The summary of a run of this experiment (see :func:`summarize`).

        Parameters
        ----------
        result : SimulationResult  A run of this experiment (:func:`simulate`)
        settling_band : SettlingBand  The port pressures' settling band
                                   (:class:`hydroline.traces.metrics.SettlingBand`; default
                                   +-2 % of the final absolute pressure)

        Returns
        -------
        dict
        """
        return _summary(result, self.window_start, sine=False, settling_band=settling_band)


def _commands_with_holds(rig, axes, driven: str, commands: list) -> list:
    return commands + hold_other_axes(rig, axes, driven)


@dataclass(kw_only=True)
class OpenLoopStep(Experiment):
    """A step of valve current into one axis (the paper's open-loop test, Figs. 10-12).

    Attributes
    ----------
    current : float           Current after the step, [A] (None: ``servovalve.rated_current``)
    initial_current : float   Current before the step, [A]
    time : float              Time of the step, [s]
    axis : str                The stepped axis (None: the first)
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
        rig : Rig       Parameters (SI)
        name : str      Its table's name
        t_end : float   Simulated time, [s] (the table's, else 0.25 s, when None)
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
    amplitude : float          Reference amplitude, [m]
    frequency : float          Reference frequency, [Hz]
    offset : float             Reference mean, [m]
    initial_position : float   Piston position at the start (template rigs), [m]
    axis : str                 The tracking axis (None: the first)
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
        rig : Rig       Parameters (SI)
        name : str      Its table's name
        t_end : float   Simulated time, [s] (the table's, else 1 s, when None)
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
        return _summary(result, self.window_start, sine=True)


@dataclass(kw_only=True)
class PositionStep(Experiment):
    """A step of one axis's position reference; every other axis holds (multi-axis rigs).

    Attributes
    ----------
    step : float   Reference step from where the piston starts, [m]
    time : float   Time of the step, > 0 (the steady state is solved before it), [s]
    axis : str     The stepped axis (None: the first)
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
        rig : Rig       Parameters (SI)
        name : str      Its table's name
        t_end : float   Simulated time, [s] (the table's, else 0.15 s, when None)
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
    quantity : str     "current" (valve current, [A]) or "position" (position reference, [m])
    waveform : str     "step", "ramp", "sine" or "table"
    values : dict      The waveform's parameters (:data:`hydroline.scenario_schema.WAVEFORM_KEYS`),
                       SI: [A] or [m] for levels, [A/s] or [m/s] for slopes, [s], [Hz]; a level
                       left out (``initial``, ``offset``) is where the axis starts
    times : ndarray    Table times, [s] (``waveform = "table"``)
    table : ndarray    Table values, [A] or [m]
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
        quantity : str      "current" [A] or "position" [m]
        path : str or Path  The file

        Raises
        ------
        ValueError  one line naming the file and what is wrong
        """
        t, v = read_table_csv(path, QUANTITY_UNITS[quantity])
        return cls(quantity, "table", times=t, table=v)

    def change_time(self) -> float:
        """When the command first changes (its disturbance), [s]."""
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
        name : str     Component name
        start : float  Where the axis starts (level default), [A] or [m]
        key : str      Rig path of the axis's table, for messages
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
        start : float  Where the axis starts (the level a waveform without its own initial
                       value or offset holds), [A] or [m]

        Returns
        -------
        tuple of float  (lowest, highest), [A] or [m]
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
    axes : dict                 Axis name -> :class:`AxisCommand`
    disturbance_time : float    Where the metrics start, [s] (None: the first time a command
                                changes)
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
        rig : Rig       Parameters (SI), read with :mod:`hydroline.scenario_schema`
        name : str      The table's name
        t_end : float   Simulated time, [s] (the table's when None)
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


def describe_run(res: SimulationResult, rig: Rig, circuit, net, sc: "Scenario", ss, tic: float,
                 window: bool = True) -> None:
    """Fill a finished run's metadata and warnings as :func:`simulate` gives them (the
    experiment, its axes, natural frequencies, gas-release warnings, metrics window); also
    used by :func:`hydroline.studies.sweep.simulate_shared`, whose variants run on a model
    shared among them.

    Parameters
    ----------
    res : SimulationResult   The run (modified)
    rig : Rig                Parameters (SI)
    circuit : Circuit        The rig's circuit (axis handles)
    net : Network            The run's network (its components give stroke and w_h)
    sc : Scenario            The experiment's commands and times
    ss : SteadyState         The rest state the run started from
    tic : float              ``time.perf_counter()`` at the run's start, [s]
    window : bool            Take the metrics window (False for a streamed run)
    """
    res.steady_state = ss
    first = next(iter(circuit.axes.values()))
    act = net.component(first.actuator)
    exp = sc.experiment
    driven = exp.driven_axes(circuit.axes)
    res.metadata.update(exp.metadata())
    res.metadata.update(scenario=sc.name, t_disturbance=sc.t_disturbance, rig=rig.source,
                        stroke=act.stroke, axes=circuit.axes, experiment=exp,
                        driven_axes=driven, stepped_axis=driven[0] if driven else first.name,
                        actuator_natural_frequency_hz=act.hydraulic_natural_frequency(0.0),
                        axis_natural_frequency_hz={
                            n: net.component(a.actuator).hydraulic_natural_frequency(0.0)
                            for n, a in circuit.axes.items()},
                        total_wall_time=_time.perf_counter() - tic,
                        steady_state_residual=ss.residual, n_states=len(net.state_names))
    threshold = rig.get("fluid.gas_release_pressure", CAVITATION_PRESSURE)
    if "stream_stats" not in res.metadata:
        res.warnings.extend(check_cavitation(res, threshold))
    else:   # streamed or kept in part: the column statistics have every column
        lows = res.metadata["stream_stats"]["min"]
        res.warnings.extend(f"{k} falls below the gas-release pressure {threshold / 1e6:.3g} MPa "
                            f"absolute (fluid.gas_release_pressure; lowest {lows[k] / 1e6:.3g} "
                            f"MPa): the line model is not valid there"
                            for k in watched_pressures(res)
                            if k in lows.index and lows[k] < threshold)
    if window:
        res.metadata["metrics_window"] = metrics_window(res)
    res.metadata["total_wall_time"] = _time.perf_counter() - tic


def scenario_names(rig: Rig) -> list[str]:
    """Every experiment a rig can run by name: the built-in ones and the rig's own.

    Parameters
    ----------
    rig : Rig
    """
    own = [k.split(".")[1] for k in rig.values
           if k.startswith("scenario.") and k.endswith(".type") and k.count(".") == 2]
    return list(EXPERIMENTS) + [n for n in own if n not in EXPERIMENTS]


def experiment(rig: Rig, scenario: "str | Experiment", t_end: float | None = None) -> Experiment:
    """The experiment called ``scenario`` on the rig (or ``scenario`` itself, an object).

    Parameters
    ----------
    rig : Rig                   Parameters (SI)
    scenario : str or Experiment  A name (:func:`scenario_names`) or an experiment object
    t_end : float               Simulated time, [s] (the experiment's own when None)

    Returns
    -------
    Experiment
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
    rig : Rig                     Parameters (SI)
    scenario : str or Experiment  A name (built-in, :data:`SCENARIOS`, or the rig's own) or an
                                  experiment object
    t_end : float                 Simulated time, [s] (the experiment's default when None)
    axes : dict                   The rig's axis handles (:attr:`hydroline.circuit.Circuit.axes`);
                                  built from the rig when None

    Returns
    -------
    Scenario
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
    rig : Rig      Parameters (SI)
    axes : dict    Axis handles, name -> :class:`hydroline.circuit.Axis`
    driven : str   The axis the experiment drives (None: hold them all)

    Returns
    -------
    list  Command components
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


def simulate(rig: Rig | str | None = None, scenario: "str | Experiment | None" = None,
             t_end: float | None = None, dt_out: float = 1e-4, solver: str = "auto",
             progress=None, rtol: float = 1e-6, atol_scale: float = 1e-7, stream_to=None,
             stream_columns=None, **options) -> SimulationResult:
    """Run a scenario on a rig, from its solved steady state.

    Parameters
    ----------
    rig : Rig, str or None   A parsed rig, a path to a rig TOML file, or None for the
                             embedded default (the 2005 paper's rig)
    scenario : str or Experiment  A name (one of :data:`SCENARIOS` or the rig's own
                             ``[scenario.NAME]``) or an experiment object (:class:`Experiment`);
                             None: the rig's ``rig.scenario``, else "open-loop-step"
    t_end : float            Simulated time, [s] (the scenario's default when None)
    dt_out : float           Output sampling interval, [s]
    solver : str             "auto" (the compiled C core where a C compiler exists, else
                             "cvodes"), "compiled", "cvodes" (CasADi + CVODES) or "scipy"
                             (reference Python path); see :func:`hydroline.engine.integrate`
    progress : callable      Called with the fraction done
    rtol : float             Relative tolerance of the integrator (default 1e-6: the default
                             scenario's port pressures and piston velocity then lie within
                             6e-3 % of their excursion from a 1e-10 reference, benchmarks/), [-]
    atol_scale : float       Absolute tolerance as a fraction of each state's typical
                             magnitude, [-]
    stream_to : path         Stream the time series to this CSV file in constant memory (long
                             runs); ``data`` then holds the last row only and
                             ``metadata["stream_stats"]`` per-column min/max/mean/rms
    stream_columns : list    Columns to stream (all when None)
    options                  Further keywords of :func:`hydroline.engine.integrate`
                             (``stream_every``, ``keep_columns``, ``preview_columns``, ...)

    Returns
    -------
    SimulationResult  (``.data`` has every signal and state; ``.metadata`` the scenario,
    the disturbance time, the actuator's hydraulic natural frequency)
    """
    tic = _time.perf_counter()
    if not isinstance(rig, Rig):
        rig = load_rig(rig)
    scenario = scenario or default_scenario(rig)
    key = _model_key(rig, scenario, t_end)
    if key in _MODELS:
        circuit, sc, net, ss = _MODELS[key]
    else:
        circuit = build_circuit(rig)
        sc = build_scenario(rig, scenario, t_end, axes=circuit.axes)
        if sc.position_guess is not None:
            circuit = build_circuit(rig, sc.position_guess)
        net = circuit.network(sc.commands)
    kept = options.get("keep_columns")   # bounded memory: only these columns stay in memory
    # (a streamed file holds every stream_every-th row: its size on the disk is that of those)
    written = dt_out * max(int(options.get("stream_every", 1)), 1) if stream_to is not None \
        else dt_out
    check_output_size(sc.t_end, written, len(kept) if kept is not None and stream_to is None
                      else len(net.signal_names) + len(net.state_names),
                      stream_to=stream_to if kept is None or stream_to is not None else None,
                      name="t_end" if t_end is not None else f"scenario.{sc.name}.t_end")
    if key not in _MODELS:
        ss = rest_state(net)
        _remember_model(key, (circuit, sc, net, ss))
    ss = replace(ss, x=ss.x.copy(), p=ss.p.copy())
    res = integrate(net, ss.x, sc.t_end, dt_out=dt_out, p=ss.p, solver=solver, progress=progress,
                    rtol=rtol, atol_scale=atol_scale, stream_to=stream_to,
                    stream_columns=stream_columns, **options)
    describe_run(res, rig, circuit, net, sc, ss, tic,
                 window=stream_to is None or options.get("keep_columns") is not None)
    return res


def rest_state(net, x_guess=None):
    """The network's steady state before the run; a failure is said in terms of the rig's
    parameters (:func:`hydroline.rigs.parameters.steady_state_hint`).

    Parameters
    ----------
    net : Network     The rig's network with the experiment's commands
    x_guess : array   Start for the solver, [SI]; the components' guesses when None

    Returns
    -------
    SteadyState

    Raises
    ------
    SteadyStateError  Naming the balance that does not close and the parameters to look at
    """
    try:
        return solve_steady_state(net, t0=0.0, x_guess=x_guess)
    except SteadyStateError as e:   # say it in terms of the rig's parameters
        if getattr(e, "state", None) is None:
            raise
        raise SteadyStateError(f"steady state not found before the run: "
                               f"{steady_state_hint(e.state)}; the solver stopped with a scaled "
                               f"residual of {e.residual:.3g} 1/s at '{e.state}'",
                               e.state, e.residual) from None


def watched_pressures(res: SimulationResult) -> list[str]:
    """Pressure signals watched for cavitation: every axis's ports and chambers (from the
    handles in ``res.metadata["axes"]``) and the shared nodes (:data:`WATCHED_NODES`); the
    template's signals (:data:`WATCHED_PRESSURES`) for a result without handles.

    Parameters
    ----------
    res : SimulationResult  A run
    """
    axes = res.metadata.get("axes") or {}
    if not axes:
        return list(WATCHED_PRESSURES)
    out = []
    for ax in axes.values():
        out += [s for s in (ax.supply_pressure, ax.return_pressure, ax.bottom_pressure,
                            ax.top_pressure) if s not in out]
    return out + [s for s in WATCHED_NODES if s not in out]


#: Recent (scenario, t_end, rig values) -> (circuit, scenario, network, steady state): a
#: repeated run of the same rig in one process reuses its model, compiled library and rest
#: state (built anew otherwise).
_MODELS: dict = {}
_MODELS_KEPT = 8


def _model_key(rig: Rig, scenario, t_end):
    """Key of a run's model in :data:`_MODELS` (None: not cached: a table file may change, or
    an experiment object)."""
    if not isinstance(scenario, str) or any(k.endswith(".file") for k in rig.values):
        return None
    return (scenario, t_end, repr(sorted(rig.values.items())))


def _remember_model(key, model) -> None:
    if key is None:
        return
    if len(_MODELS) >= _MODELS_KEPT:
        _MODELS.pop(next(iter(_MODELS)))
    _MODELS[key] = model


def check_cavitation(res: SimulationResult, threshold: float = CAVITATION_PRESSURE) -> list[str]:
    """One warning per watched pressure that falls below ``threshold`` absolute (docs/model.md
    8), giving the time of the first crossing.

    Parameters
    ----------
    res : SimulationResult
    threshold : float      Gas-release pressure, absolute, [Pa] (``fluid.gas_release_pressure``)
    """
    out = []
    for k in watched_pressures(res):
        if k not in res:
            continue
        p = res[k]
        i = int(np.argmin(p))
        if p[i] < threshold:
            below = res.t[p < threshold]
            what = ("cavitate (below 0 Pa absolute)" if threshold <= 0 else
                    f"release gas (below the gas-release pressure {threshold / 1e6:.3g} MPa "
                    f"absolute, fluid.gas_release_pressure)")
            out.append(f"{k} falls below {threshold / 1e6:.3g} MPa absolute from t = "
                       f"{below[0] * 1e3:.1f} ms (lowest {p[i] / 1e6:.3g} MPa at "
                       f"{res.t[i] * 1e3:.1f} ms): the oil would {what} there and the line model "
                       f"is not valid; raise the return/back pressure or shorten the hose")
    return out


def metrics_window(res: SimulationResult, margin: float = 1e-3) -> tuple[float, float, str]:
    """The part of a run the metrics are taken over: ``(t_start, t_end, why_it_ends)``.

    It starts at the disturbance (the valve step; 0 for the closed-loop sine) and ends when the
    piston arrives at the stop it moves *toward* -- the end stop on the side of its first
    clear displacement (more than ``margin``) after the disturbance -- or at the end of the run
    if it never gets there. What follows an arrival is a second transient (the flow stops),
    not the response to the step. A piston that starts resting on one stop and moves away from
    it does not end the window there.

    Parameters
    ----------
    res : SimulationResult  With ``piston_position`` [m] and metadata ``t_disturbance`` [s],
                            ``stroke`` [m]
    margin : float          Distance from a stop that counts as arrived, [m]

    Returns
    -------
    tuple  ``(t_start [s], t_end [s], reason)``; ``reason`` is "stop" (the piston reached the
           stop it moves toward) or "end" (the run ended first)
    """
    t0 = float(res.metadata.get("t_disturbance", 0.0))
    t = res.t
    axes = res.metadata.get("axes") or {}
    pairs = [(ax.position, ax.stroke) for ax in axes.values()] or \
        [("piston_position", res.metadata.get("stroke", np.inf))]
    end, reason = float(t[-1]), "end"
    for signal, stroke in pairs:     # the first axis to arrive at the stop it moves toward
        if signal not in res:
            continue
        x = res[signal]
        half = stroke / 2
        after = t >= t0
        x0 = float(np.interp(t0, t, x))
        moved = np.flatnonzero(after & (np.abs(x - x0) > margin))
        if moved.size == 0 or not np.isfinite(half):
            continue
        direction = math.copysign(1.0, x[moved[0]] - x0)
        arrived = np.flatnonzero(after & (direction * x >= half - margin) & (t > t[moved[0]] - 1e-12))
        if arrived.size and float(t[arrived[0]]) < end:
            end, reason = float(t[arrived[0]]), "stop"
    return t0, end, reason


def _window_note(t0, t1, reason, start):
    if reason == "stop":
        return (f"metrics from {start} at {t0 * 1e3:.0f} ms to {t1 * 1e3:.0f} ms, when the piston "
                f"reaches the stop it moves toward")
    return (f"metrics from {start} at {t0 * 1e3:.0f} ms to the end of the run at {t1 * 1e3:.0f} ms "
            f"(the piston has not reached a stop)")


def _cycle_ripple(t, p, t0, t1, frequency):
    """Peak-to-peak [Pa] of ``p`` in each full command cycle within ``[t0, t1]``."""
    period = 1.0 / frequency
    out = []
    k = 0
    # t ascends: each cycle's samples t0 + k T <= t <= t0 + (k + 1) T are one slice (a mask
    # over the whole trace per cycle made a 600 s run's summary take ~40 s)
    while t0 + (k + 1) * period <= t1 + 1e-9:
        i = int(np.searchsorted(t, t0 + k * period, side="left"))
        j = int(np.searchsorted(t, t0 + (k + 1) * period, side="right"))
        if j - i >= 2:
            out.append(float(np.ptp(p[i:j])))
        k += 1
    return out


def ripple_metrics(ripple) -> dict:
    """A port's summary entries under a sine command from its peak-to-peak pressure ripple
    per full command cycle (the largest one as the amplitude; no oscillation frequency or
    settling time).

    Parameters
    ----------
    ripple : list of float   Peak-to-peak pressure of each full cycle in the window, [Pa]

    Returns
    -------
    dict  ``frequency_hz``, ``amplitude_mpa``, ``ripple_pp_mpa``, ``ripple_pp_mpa_per_cycle``,
          ``settling_time_s`` and ``amplitude_note`` (why there is no amplitude)
    """
    top = max(ripple) if ripple else None
    return {"frequency_hz": None,
            "amplitude_mpa": None if top is None else top / 2e6,
            "ripple_pp_mpa": None if top is None else top / 1e6,
            "ripple_pp_mpa_per_cycle": [r / 1e6 for r in ripple],
            "settling_time_s": None,
            "amplitude_note": "" if ripple else "the window holds no full command cycle"}


def summarize(res: SimulationResult, settling_band=SETTLING_BAND) -> dict:
    """The summary of a run (what ``hydroline simulate`` prints and ``summary.json`` holds):
    its experiment's :meth:`Experiment.summary`.

    Open-loop step (and a user's own experiment): per port (``"supply"``, ``"return"``) the
    metrics of :func:`hydroline.traces.metrics.pressure_metrics` over :func:`metrics_window`:
    frequency [Hz], two-sided oscillation amplitude [MPa], first excursion [MPa], steady
    change [MPa], peak-to-peak [MPa], settling time [s] in ``settling_band`` (by default
    +-2 % of the final absolute pressure; measured or estimated, with its method, note, band
    and half-width ``settling_band_mpa``), and a note where an amplitude cannot be given.

    Closed-loop sine (no step, a forced response): per port the peak-to-peak ripple in each
    full command cycle (``ripple_pp_mpa_per_cycle``, its maximum ``ripple_pp_mpa``);
    ``amplitude_mpa`` is half that maximum, ``frequency_hz`` and ``settling_time_s`` are None;
    the tracking error (reference minus position) as rms and max [mm].

    Also: ``actuator_natural_frequency_hz``, ``wall_time_s``, ``metrics_window_s``,
    ``metrics_window_note``, ``warnings``. A multi-axis rig gives these per axis under
    ``"axes"``. The result is not modified.

    Parameters
    ----------
    res : SimulationResult  A run of :func:`simulate`
    settling_band : SettlingBand or str  The port pressures' settling band
                            (:meth:`hydroline.traces.metrics.SettlingBand.parse`: "2%" of the
                            final absolute pressure, the default, or e.g. "5% of change")

    Returns
    -------
    dict
    """
    settling_band = SettlingBand.parse(settling_band)
    exp = res.metadata.get("experiment")
    if exp is not None:
        # (an experiment of a user's own that overrides summary(result) keeps the default band)
        return exp.summary(res) if settling_band == SETTLING_BAND else \
            exp.summary(res, settling_band=settling_band)
    scenario = res.metadata.get("scenario")
    return _summary(res, "the valve step" if scenario == "open-loop-step"
                    else "the start of the command", sine=scenario == "closed-loop-sine",
                    settling_band=settling_band)


def _summary(res: SimulationResult, window_start: str, sine: bool,
             settling_band=SETTLING_BAND) -> dict:
    """Summary of a run (:func:`summarize`); ``sine``: ripple per command cycle and tracking
    error instead of step metrics (single-axis rigs)."""
    t0, t1, reason = metrics_window(res)
    m = res.t <= t1
    t = res.t[m]
    axes = res.metadata.get("axes") or {}
    if len(axes) > 1:
        return _summarize_axes(res, axes, t0, t1, m, reason, window_start, sine,
                               settling_band)
    ax = next(iter(axes.values()), None)
    out = {}
    for side, key in (("supply", ax.supply_pressure if ax else "supply_port_pressure"),
                      ("return", ax.return_pressure if ax else "return_port_pressure")):
        p = res[key][m]
        if sine:
            out[side] = ripple_metrics(_cycle_ripple(t, p, t0, t1,
                                                     res.metadata["command_frequency_hz"]))
        else:
            out[side] = pressure_metrics(t, p, t0, t1, settling_band)
    out["actuator_natural_frequency_hz"] = float(res.metadata["actuator_natural_frequency_hz"])
    out["wall_time_s"] = float(res.metadata.get("total_wall_time", res.wall_time))
    if sine:
        err = (res[ax.reference_signal if ax else "position_reference"]
               - res[ax.position if ax else "piston_position"])[m]
        out["tracking_error_rms_mm"] = float(np.sqrt(np.mean(err**2)) * 1e3)
        out["tracking_error_max_mm"] = float(np.max(np.abs(err)) * 1e3)
    out["metrics_window_s"] = [t0, t1]
    out["metrics_window_note"] = _window_note(t0, t1, reason, window_start)
    if not sine:
        out["settling_band"] = settling_band.describe()
    out["warnings"] = list(res.warnings)
    return out


class SineSummaryStream:
    """The closed-loop sine's summary (:func:`summarize`) computed chunk by chunk as a long run
    goes, in constant memory: pass :meth:`update` as ``observe`` to
    :func:`hydroline.simulation.integrate` (through :func:`simulate`), then call :meth:`summary`.

    Same numbers as :func:`summarize` on the whole trace: the metrics window of
    :func:`metrics_window` (its end found as the rows arrive), per port the peak-to-peak in each
    full command cycle, the tracking error's rms and max up to the window's end.

    Parameters
    ----------
    t_disturbance : float   Start of the metrics window, [s]
    stroke : float          Full stroke, [m]
    frequency : float       Command frequency, [Hz]
    supply, ret, position, reference : str   Signal names: port pressures [Pa], piston
                            position and its reference [m]
    margin : float          Distance from a stop that counts as arrived, [m]
    window_start : str      What the metrics window starts at (its note)
    """

    def __init__(self, t_disturbance, stroke, frequency, supply="supply_port_pressure",
                 ret="return_port_pressure", position="piston_position",
                 reference="position_reference", margin=1e-3,
                 window_start=ClosedLoopSine.window_start):
        self.t0, self.half, self.margin = float(t_disturbance), stroke / 2, margin
        self.window_start = window_start
        self.period = 1.0 / frequency
        self.names = (supply, ret, position, reference)
        self.index = None
        self.prev = None          # last row before this chunk (t, x): x0 by interpolation
        self.x0 = self.direction = self.t_moved = None
        self.t_end, self.arrived = None, False
        self.cycles = {}          # k -> [min supply, max supply, min return, max return, rows]
        self.n = 0
        self.sumsq = 0.0
        self.err_max = 0.0

    def update(self, t, table, columns):
        """Take in one block of output rows (pass as ``observe`` to :func:`simulate`).

        Parameters
        ----------
        t : ndarray         Ascending output times, [s]
        table : ndarray     One row per time: signals and states side by side, [SI]
        columns : list[str] Names of the table's columns
        """
        if self.arrived or len(t) == 0:
            return
        if self.index is None:
            self.index = [list(columns).index(k) for k in self.names]
        # one pass over the rows gathers the four columns (contiguous: each later pass is cheap)
        ps, pr, x, ref = np.ascontiguousarray(table[:, self.index].T)
        end = len(t)
        if self.x0 is None and t[-1] >= self.t0:   # the piston's position at the disturbance
            tt, xx = (t, x) if self.prev is None else (np.r_[self.prev[0], t], np.r_[self.prev[1], x])
            self.x0 = float(np.interp(self.t0, tt, xx))
        if self.x0 is not None and math.isfinite(self.half):
            after = t >= self.t0
            if self.direction is None:
                moved = np.flatnonzero(after & (np.abs(x - self.x0) > self.margin))
                if moved.size:
                    self.direction = math.copysign(1.0, x[moved[0]] - self.x0)
                    self.t_moved = float(t[moved[0]])
            if self.direction is not None:
                hit = np.flatnonzero(after & (self.direction * x >= self.half - self.margin)
                                     & (t > self.t_moved - 1e-12))
                if hit.size:   # the window ends here: rows after it are not the sine's response
                    end = int(hit[0]) + 1
                    self.arrived = True
        t, ps, pr = t[:end], ps[:end], pr[:end]
        err = ref[:end] - x[:end]
        self.n += end
        # (not np.dot: BLAS's threads on a busy machine took ~8 ms per 20 000 rows)
        self.sumsq += float(np.sum(err * err))
        self.err_max = max(self.err_max, float(np.max(np.abs(err))))
        k = max(int(np.floor((t[0] - self.t0) / self.period)) - 1, 0)
        while self.t0 + k * self.period <= t[-1]:   # (same bounds as _cycle_ripple)
            i = int(np.searchsorted(t, self.t0 + k * self.period, side="left"))
            j = int(np.searchsorted(t, self.t0 + (k + 1) * self.period, side="right"))
            if j > i:
                c = self.cycles.setdefault(k, [np.inf, -np.inf, np.inf, -np.inf, 0])
                c[0], c[1] = min(c[0], ps[i:j].min()), max(c[1], ps[i:j].max())
                c[2], c[3] = min(c[2], pr[i:j].min()), max(c[3], pr[i:j].max())
                c[4] += j - i
            k += 1
        self.prev = (t[-1], x[end - 1])
        self.t_end = float(t[-1])

    def summary(self, res: SimulationResult) -> dict:
        """The summary dict of :func:`summarize` (closed-loop sine), from the rows seen and the
        run's metadata and warnings.

        Parameters
        ----------
        res : SimulationResult  The run (need not hold the trace: its metadata and warnings)

        Returns
        -------
        dict
        """
        t0, t1 = self.t0, self.t_end
        reason = "stop" if self.arrived else "end"
        out = {}
        for side, lo in (("supply", 0), ("return", 2)):
            ripple = []
            k = 0
            while t0 + (k + 1) * self.period <= t1 + 1e-9:
                c = self.cycles.get(k)
                if c is not None and c[4] >= 2:
                    ripple.append(float(c[lo + 1] - c[lo]))
                k += 1
            out[side] = ripple_metrics(ripple)
        out["actuator_natural_frequency_hz"] = float(res.metadata["actuator_natural_frequency_hz"])
        out["wall_time_s"] = float(res.metadata.get("total_wall_time", res.wall_time))
        out["tracking_error_rms_mm"] = float(np.sqrt(self.sumsq / max(self.n, 1)) * 1e3)
        out["tracking_error_max_mm"] = float(self.err_max * 1e3)
        out["metrics_window_s"] = [t0, t1]
        out["metrics_window_note"] = _window_note(t0, t1, reason, self.window_start)
        out["warnings"] = list(res.warnings)
        return out


def _summarize_axes(res, axes, t0, t1, m, reason, window_start, sine=False,
                    settling_band=SETTLING_BAND):
    """Per-axis summary of a multi-axis run: port metrics, position disturbance, w_h.

    ``position_disturbance_mm`` is the largest excursion of the piston from where it stood at
    the disturbance, over the metrics window, for every axis but the stepped one (null there:
    it moves on purpose; ``position_change_mm`` gives its travel), [mm]. ``sine``: per axis
    the ripple per command cycle instead of the step metrics, and the tracking error
    (reference minus position, rms and max [mm]), as :func:`_summary` gives a single axis.
    """
    t = res.t[m]
    i0 = int(np.searchsorted(res.t, t0))
    driven = res.metadata.get("driven_axes", [res.metadata.get("stepped_axis")])
    out = {"axes": {}}
    for name, ax in axes.items():
        x = res[ax.position][m]
        dev = float(np.max(np.abs(x[i0:] - x[i0])) * 1e3) if len(x) > i0 else 0.0
        ports = (("supply", ax.supply_pressure), ("return", ax.return_pressure))
        if sine:
            f = res.metadata["command_frequency_hz"]
            entry = {side: ripple_metrics(_cycle_ripple(t, res[key][m], t0, t1, f))
                     for side, key in ports}
            err = (res[ax.reference_signal] - res[ax.position])[m]
            entry["tracking_error_rms_mm"] = float(np.sqrt(np.mean(err**2)) * 1e3)
            entry["tracking_error_max_mm"] = float(np.max(np.abs(err)) * 1e3)
        else:
            entry = {side: pressure_metrics(t, res[key][m], t0, t1, settling_band)
                     for side, key in ports}
        entry["position_disturbance_mm"] = None if name in driven else dev
        if name in driven:
            entry["position_change_mm"] = float((x[-1] - x[i0]) * 1e3)
        entry["actuator_natural_frequency_hz"] = float(
            res.metadata["axis_natural_frequency_hz"][name])
        out["axes"][name] = entry
    out["wall_time_s"] = float(res.metadata.get("total_wall_time", res.wall_time))
    out["metrics_window_s"] = [t0, t1]
    out["metrics_window_note"] = _window_note(t0, t1, reason, window_start)
    out["settling_band"] = settling_band.describe()
    out["warnings"] = list(res.warnings)
    return out


SimulationResult.summarizer = staticmethod(summarize)   # what a result's repr shows
