"""Experiments on a rig: the open-loop step and the closed-loop sine (the paper's tests).

``simulate(rig, scenario, t_end)`` builds the network of the rig with the scenario's command
components, solves its steady state before the disturbance, integrates, checks validity
(pressures below zero absolute) and returns a :class:`~hydroline.engine.SimulationResult`
whose ``metadata`` holds what the summary needs.
"""
from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, replace

import numpy as np

from . import components as comp
from .traces.metrics import pressure_metrics
from .limits import check_output_size
from .rigs import SCHEMA, Rig, RigError, load_rig
from .rigs.parameters import ATMOSPHERIC_PRESSURE, check_consistency, steady_state_hint
from .engine import SimulationResult, SteadyStateError, integrate, solve_steady_state
from .system import build_circuit

__all__ = ["SCENARIOS", "simulate", "summarize", "build_scenario", "Scenario", "default_scenario"]

#: "position-step": the axis named by ``scenario.position-step.axis`` (the first by default)
#: steps its position reference by ``step`` at ``time`` while every other axis holds its
#: position under its controller (multi-axis rigs, e.g. ``two_axis``).
SCENARIOS = ("open-loop-step", "closed-loop-sine", "position-step")


def default_scenario(rig: Rig) -> str:
    """The rig's ``rig.scenario``, else "open-loop-step"."""
    return rig.get("rig.scenario", "open-loop-step")

#: Pressures watched for gas release and cavitation (docs/model.md 8): below the rig's
#: ``fluid.gas_release_pressure`` (absolute; default one atmosphere, the pressure at which oil
#: from a vented tank holds its dissolved air) the oil releases gas and the linear line model
#: no longer holds, [Pa].
CAVITATION_PRESSURE = ATMOSPHERIC_PRESSURE
WATCHED_PRESSURES = ("supply_port_pressure", "return_port_pressure", "bottom_chamber_pressure",
                     "top_chamber_pressure", "supply.manifold_pressure", "return.manifold_pressure")


@dataclass
class Scenario:
    """An experiment: command components, its duration and the disturbance time.

    Attributes
    ----------
    name : str
    commands : list          Components that drive the network (``valve_current`` source or
                             reference + controller)
    t_end : float            Simulated time, [s]
    t_disturbance : float    Time of the step (metrics start there), [s]
    position_guess : float   Initial piston position, [m]
    """

    name: str
    commands: list
    t_end: float
    t_disturbance: float
    position_guess: float | None = None


def _scenario_value(rig, scenario, key, default=None):
    v = rig.get(f"scenario.{scenario}.{key}", default)
    if v is None:
        raise RigError(f"scenario.{scenario}.{key}: not set in rig {rig.source}")
    return v


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


def build_scenario(rig: Rig, scenario: str = "open-loop-step", t_end: float | None = None,
                   axes: dict | None = None) -> Scenario:
    """The command components and times of a named scenario, from the rig's [scenario.*].

    Parameters
    ----------
    rig : Rig         Parameters (SI)
    scenario : str    One of :data:`SCENARIOS`
    t_end : float     Simulated time, [s] (the scenario's default when None)
    axes : dict       The rig's axis handles (:attr:`hydroline.circuit.Circuit.axes`); built
                      from the rig when None

    Returns
    -------
    Scenario
    """
    if axes is None:
        axes = build_circuit(rig).axes
    if not axes:
        raise RigError(f"rig {rig.source}: no servo axis (an actuator driven by a servovalve)")
    if scenario in SCENARIOS:
        _check_scenario(rig, scenario, t_end)
        check_consistency(rig, scenario)
    if scenario == "position-step":
        return _position_step(rig, axes, t_end)
    axis = next(iter(axes.values()))
    rated = rig.get("servovalve.rated_current", 0.05)
    others = hold_other_axes(rig, axes, axis.name)
    if scenario == "open-loop-step":
        if axis.controller:
            raise RigError(f"scenario open-loop-step: the valve current of axis '{axis.name}' is "
                           f"driven by '{axis.controller}' in the circuit; use position-step")
        t_step = _scenario_value(rig, scenario, "time", 0.01)
        cmd = comp.StepCommand(name="command", quantity="current",
                               initial=rig.get(f"scenario.{scenario}.initial_current", 0.0),
                               final=_scenario_value(rig, scenario, "current", rated),
                               time=t_step, connections={"command": axis.current})
        return Scenario(scenario, [cmd] + others,
                        t_end or _scenario_value(rig, scenario, "t_end", 0.25), t_step)
    if scenario == "closed-loop-sine":
        ref = comp.SineCommand(name="command", quantity="position",
                               offset=_scenario_value(rig, scenario, "offset", 0.0),
                               amplitude=_scenario_value(rig, scenario, "amplitude"),
                               frequency=_scenario_value(rig, scenario, "frequency"),
                               start=0.0, connections={"command": axis.reference_signal})
        cmds = [ref]
        if not axis.controller:   # the template's P loop, from [controller]
            cmds.append(comp.PositionController(
                name="controller", proportional_gain=rig["controller.proportional_gain"],
                integral_gain=rig.get("controller.integral_gain", 0.0),
                derivative_gain=rig.get("controller.derivative_gain", 0.0),
                current_limit=rig.get("controller.current_limit", rated),
                sample_time=rig.get("controller.sample_time"),
                connections={"reference": axis.reference_signal, "position": axis.position,
                             "velocity": axis.velocity, "current": axis.current}))
        return Scenario(scenario, cmds + others, t_end or _scenario_value(rig, scenario, "t_end", 1.0), 0.0,
                        position_guess=_scenario_value(rig, scenario, "initial_position", 0.0))
    raise RigError(f"unknown scenario {scenario!r} (known: {', '.join(SCENARIOS)})")


def hold_other_axes(rig: Rig, axes: dict, driven: str) -> list:
    """Commands that hold every axis but ``driven``: a constant position reference where the
    circuit has the axis's controller (it holds where its actuator starts), else zero valve
    current.

    Parameters
    ----------
    rig : Rig      Parameters (SI)
    axes : dict    Axis handles, name -> :class:`hydroline.circuit.Axis`
    driven : str   The axis the experiment drives

    Returns
    -------
    list  Command components
    """
    out = []
    for ax in axes.values():
        if ax.name == driven:
            continue
        if ax.controller:
            x0 = rig.get(f"circuit.{ax.actuator}.initial_position", 0.0)
            out.append(comp.StepCommand(name=f"{ax.name}.command", quantity="position", initial=x0,
                                        final=x0, time=0.0,
                                        connections={"command": ax.reference_signal}))
        else:
            out.append(comp.StepCommand(name=f"{ax.name}.command", quantity="current",
                                        connections={"command": ax.current}))
    return out


def _position_step(rig, axes, t_end):
    """Step one axis's position reference; hold every other axis where it starts."""
    key = "scenario.position-step"
    name = rig.get(f"{key}.axis", next(iter(axes)))
    if name not in axes:
        raise RigError(f"{key}.axis: no axis {name!r} in the rig (axes: {', '.join(axes)})")
    t_step = rig.get(f"{key}.time", 0.01)
    if not t_step > 0:
        raise RigError(f"{key}.time: must be > 0 [s] (the steady state is solved before the "
                       f"step), got {rig.raw.get(f'{key}.time', t_step)!r}")
    step = _scenario_value(rig, "position-step", "step")
    ax = axes[name]
    if ax.controller is None:
        raise RigError(f"{key}: axis '{ax.name}' has no position controller in the circuit "
                       f"(a position_controller whose current drives '{ax.valve}')")
    x0 = rig.get(f"circuit.{ax.actuator}.initial_position", 0.0)
    cmds = [comp.StepCommand(name=f"{ax.name}.command", quantity="position", initial=x0,
                             final=x0 + step, time=t_step,
                             connections={"command": ax.reference_signal})]
    cmds += hold_other_axes(rig, axes, name)
    return Scenario("position-step", cmds, t_end or _scenario_value(rig, "position-step", "t_end", 0.15),
                    t_step)


def simulate(rig: Rig | str | None = None, scenario: str | None = None,
             t_end: float | None = None, dt_out: float = 1e-4, solver: str = "auto",
             progress=None, rtol: float = 1e-6, atol_scale: float = 1e-7, stream_to=None,
             stream_columns=None, **options) -> SimulationResult:
    """Run a scenario on a rig, from its solved steady state.

    Parameters
    ----------
    rig : Rig, str or None   A parsed rig, a path to a rig TOML file, or None for the
                             embedded default (the 2005 paper's rig)
    scenario : str           One of :data:`SCENARIOS`; None: the rig's ``rig.scenario``, else
                             "open-loop-step"
    t_end : float            Simulated time, [s] (the scenario's default when None)
    dt_out : float           Output sampling interval, [s]
    solver : str             "auto" (the compiled C core where a C compiler exists, else
                             "cvodes"), "compiled", "cvodes" (CasADi + CVODES) or "scipy"
                             (reference Python path); see :func:`hydroline.engine.integrate`
    progress : callable      Called with the fraction done
    rtol : float             Relative tolerance of the integrator (default 1e-6: the default
                             scenario's port pressures and piston velocity then lie within
                             6e-3 % of their excursion from a 1e-10 reference, benchmarks/)
    atol_scale : float       Absolute tolerance as a fraction of each state's typical magnitude
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
    check_output_size(sc.t_end, dt_out, len(kept) if kept is not None and stream_to is None
                      else len(net.signal_names) + len(net.state_names),
                      stream_to=stream_to if kept is None or stream_to is not None else None,
                      name="t_end" if t_end is not None else f"scenario.{scenario}.t_end")
    if key not in _MODELS:
        try:
            ss = solve_steady_state(net, t0=0.0)
        except SteadyStateError as e:   # say it in terms of the rig's parameters
            if getattr(e, "state", None) is None:
                raise
            raise SteadyStateError(f"steady state not found before the run: "
                                   f"{steady_state_hint(e.state)}; the solver stopped with a scaled "
                                   f"residual of {e.residual:.3g} 1/s at '{e.state}'",
                                   e.state, e.residual) from None
        _remember_model(key, (circuit, sc, net, ss))
    ss = replace(ss, x=ss.x.copy(), p=ss.p.copy())
    res = integrate(net, ss.x, sc.t_end, dt_out=dt_out, p=ss.p, solver=solver, progress=progress,
                    rtol=rtol, atol_scale=atol_scale, stream_to=stream_to,
                    stream_columns=stream_columns, **options)
    res.steady_state = ss
    first = next(iter(circuit.axes.values()))
    act = net.component(first.actuator)
    if sc.name == "closed-loop-sine":
        res.metadata["command_frequency_hz"] = float(sc.commands[0].frequency)
    res.metadata.update(scenario=sc.name, t_disturbance=sc.t_disturbance, rig=rig.source,
                        stroke=act.stroke, axes=circuit.axes,
                        stepped_axis=rig.get("scenario.position-step.axis", first.name),
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
    if stream_to is None or options.get("keep_columns") is not None:
        res.metadata["metrics_window"] = metrics_window(res)
    res.metadata["total_wall_time"] = _time.perf_counter() - tic
    return res


def watched_pressures(res: SimulationResult) -> list[str]:
    """Pressure signals watched for cavitation: the paper rig's and every axis's ports and
    chambers (from the handles in ``res.metadata["axes"]``)."""
    out = list(WATCHED_PRESSURES)
    for ax in res.metadata.get("axes", {}).values():
        out += [s for s in (ax.supply_pressure, ax.return_pressure, ax.bottom_pressure,
                            ax.top_pressure) if s not in out]
    return out


#: Recent (scenario, t_end, rig values) -> (circuit, scenario, network, steady state): a
#: repeated run of the same rig in one process reuses its model, compiled library and rest
#: state (built anew otherwise).
_MODELS: dict = {}
_MODELS_KEPT = 8


def _model_key(rig: Rig, scenario: str, t_end):
    """Key of a run's model in :data:`_MODELS` (None: not cached, a table file may change)."""
    if any(k.endswith(".file") for k in rig.values):
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


def _window_note(t0, t1, reason, scenario):
    start = "the valve step" if scenario == "open-loop-step" else "the start of the command"
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
    while t0 + (k + 1) * period <= t1 + 1e-9:
        m = (t >= t0 + k * period) & (t <= t0 + (k + 1) * period)
        if np.count_nonzero(m) >= 2:
            out.append(float(np.ptp(p[m])))
        k += 1
    return out


def summarize(res: SimulationResult) -> dict:
    """The summary of a run (what ``hydroline simulate`` prints and ``summary.json`` holds).

    Open-loop step: per port (``"supply"``, ``"return"``) the metrics of
    :func:`hydroline.analysis.pressure_metrics` over :func:`metrics_window`: frequency [Hz],
    two-sided oscillation amplitude [MPa], first excursion [MPa], steady change [MPa],
    peak-to-peak [MPa], 2 % settling time [s] (measured or estimated, with its method and
    note), and a note where an amplitude cannot be given.

    Closed-loop sine (no step, a forced response): per port the peak-to-peak ripple in each
    full command cycle (``ripple_pp_mpa_per_cycle``, its maximum ``ripple_pp_mpa``);
    ``amplitude_mpa`` is half that maximum, ``frequency_hz`` and ``settling_time_s`` are None;
    the tracking error (reference minus position) as rms and max [mm].

    Also: ``actuator_natural_frequency_hz``, ``wall_time_s``, ``metrics_window_s``,
    ``metrics_window_note``, ``warnings``. The result is not modified.
    """
    t0, t1, reason = metrics_window(res)
    scenario = res.metadata.get("scenario")
    m = res.t <= t1
    t = res.t[m]
    axes = res.metadata.get("axes") or {}
    if len(axes) > 1:
        return _summarize_axes(res, axes, t0, t1, m, reason)
    ax = next(iter(axes.values()), None)
    out = {}
    for side, key in (("supply", ax.supply_pressure if ax else "supply_port_pressure"),
                      ("return", ax.return_pressure if ax else "return_port_pressure")):
        p = res[key][m]
        if scenario == "closed-loop-sine":
            ripple = _cycle_ripple(t, p, t0, t1, res.metadata["command_frequency_hz"])
            top = max(ripple) if ripple else None
            out[side] = {"frequency_hz": None,
                         "amplitude_mpa": None if top is None else top / 2e6,
                         "ripple_pp_mpa": None if top is None else top / 1e6,
                         "ripple_pp_mpa_per_cycle": [r / 1e6 for r in ripple],
                         "settling_time_s": None,
                         "amplitude_note": "" if ripple else
                         "the window holds no full command cycle"}
        else:
            out[side] = pressure_metrics(t, p, t0, t1)
    out["actuator_natural_frequency_hz"] = float(res.metadata["actuator_natural_frequency_hz"])
    out["wall_time_s"] = float(res.metadata.get("total_wall_time", res.wall_time))
    if scenario == "closed-loop-sine":
        err = (res[ax.reference_signal if ax else "position_reference"]
               - res[ax.position if ax else "piston_position"])[m]
        out["tracking_error_rms_mm"] = float(np.sqrt(np.mean(err**2)) * 1e3)
        out["tracking_error_max_mm"] = float(np.max(np.abs(err)) * 1e3)
    out["metrics_window_s"] = [t0, t1]
    out["metrics_window_note"] = _window_note(t0, t1, reason, scenario)
    out["warnings"] = list(res.warnings)
    return out


def _summarize_axes(res, axes, t0, t1, m, reason):
    """Per-axis summary of a multi-axis run: port metrics, position disturbance, w_h.

    ``position_disturbance_mm`` is the largest excursion of the piston from where it stood at
    the disturbance, over the metrics window, for every axis but the stepped one (null there:
    it moves on purpose; ``position_change_mm`` gives its travel), [mm].
    """
    t = res.t[m]
    i0 = int(np.searchsorted(res.t, t0))
    stepped = res.metadata.get("stepped_axis")
    out = {"axes": {}}
    for name, ax in axes.items():
        x = res[ax.position][m]
        dev = float(np.max(np.abs(x[i0:] - x[i0])) * 1e3) if len(x) > i0 else 0.0
        entry = {side: pressure_metrics(t, res[key][m], t0, t1)
                 for side, key in (("supply", ax.supply_pressure), ("return", ax.return_pressure))}
        entry["position_disturbance_mm"] = None if name == stepped else dev
        if name == stepped:
            entry["position_change_mm"] = float((x[-1] - x[i0]) * 1e3)
        entry["actuator_natural_frequency_hz"] = float(
            res.metadata["axis_natural_frequency_hz"][name])
        out["axes"][name] = entry
    out["wall_time_s"] = float(res.metadata.get("total_wall_time", res.wall_time))
    out["metrics_window_s"] = [t0, t1]
    out["metrics_window_note"] = _window_note(t0, t1, reason, res.metadata.get("scenario"))
    out["warnings"] = list(res.warnings)
    return out
