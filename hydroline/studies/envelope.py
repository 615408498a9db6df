"""The performance envelope of a test rig: the largest sine amplitude the actuator holds at each
frequency, with the supply and return lines in the loop (issue 29).

At each frequency a fatigue-test controller's amplitude control is imitated: the position
reference's amplitude and phase are adjusted (:class:`HarmonicCommand`, amplitude and phase
runtime parameters) until the piston's fundamental reaches the target amplitude, so the closed
loop's linear roll-off is compensated, not a limit. The largest target that is reached at the
periodic state with the position's harmonic distortion within the tolerance is found by
bisection (:func:`largest_passing`) on the logarithm of the amplitude, each run warm-started
from the last run's periodic state and closed-loop gain (the neighbouring amplitude, then
frequency). What stops the next larger amplitude is diagnosed from its last period
(:func:`diagnose`, by the rules a laboratory reads a performance curve with): the stroke, the
valve at its limit (spool at its opening, or the current at the controller's limit) for want of
flow, the supply pressure dip or the return pressure rise at the valve (the lines' pulsation:
eating its pressure drop, or a port's troughs at the gas-release pressure), the actuator at its
stall force, gas release in a chamber, or distortion. Where the lines' pulsation at the ports
lifts the valve's flow instead (:func:`port_ripple_gain`), the envelope with the lines may lie
above the constant supply's by that much.

The same is done with an ideal constant supply and tank (:func:`constant_supply_circuit`: the
lines, manifolds and accumulators taken out, the valve's ports held at their rest pressures),
and the vendor's analytic envelope for that supply (:func:`analytic_envelope`) is given beside.
"""
from __future__ import annotations

import copy
import math
import time as _time
from dataclasses import dataclass, field

import numpy as np

from ..engine import integrate, ops
from ..engine.component import Component, HydraulicEnd, Port, parameter
from ..rigs import Rig, RigError, load_rig

__all__ = ["envelope", "EnvelopeResult", "envelope_points", "vendor_parameters", "CURVE_KEYS", "HarmonicCommand", "SineRig",
           "PeriodicResponse", "analytic_envelope", "constant_supply_circuit", "largest_passing",
           "harmonic_distortion", "clipped_sine_gain", "fundamental", "periodic_change", "diagnose", "LIMITS",
           "port_ripple_gain", "FLOW_LOSS", "STALL_SHARE",
           "EnvelopeRunner", "default_frequencies", "envelope_figure", "LIMIT_COLOURS"]

#: What limits the envelope at a frequency (``limited_by``, the rules in :func:`diagnose`): the
#: stroke (the amplitude reaches half the stroke), the valve's rated flow (spool at its opening
#: or current at the controller's limit), the supply pressure dip or return pressure rise at
#: the valve (the lines' pulsation: taking the valve's drop, or a port's troughs at the
#: gas-release pressure), the force (the actuator at its stall force), gas release in a
#: chamber, the position's harmonic distortion beyond the tolerance (nothing at its limit), or
#: "none" (the largest amplitude searched passes).
LIMITS = ("stroke", "valve", "supply_dip", "return_rise", "force", "gas_release", "distortion",
          "none")


@dataclass(kw_only=True)
class HarmonicCommand(Component):
    """``offset + a_s sin(2 pi f t) + a_c cos(2 pi f t)``, its amplitudes and frequency runtime
    parameters (one compiled model serves every amplitude, phase and frequency of an envelope).

    Parameters
    ----------
    quantity : str
        What the command drives ("position": [m])
    offset : float
        Mean value, [SI unit of ``quantity``]

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.

    Notes
    -----
    Runtime parameters: ``sine_amplitude`` and ``cosine_amplitude`` [SI unit of quantity],
    ``frequency`` [Hz].
    """

    quantity: str = parameter("position", "str", "what the command drives",
                              choices=("current", "position", "force"))
    offset: float = parameter(0.0, "-", "mean value, [unit of quantity]")

    def __post_init__(self):
        self.check_parameters()
        self.outputs = {"command": Port(self.quantity, f"commanded {self.quantity}")}
        self.feedthrough = False

    def runtime_parameters(self):
        return {"sine_amplitude": 0.0, "cosine_amplitude": 0.0, "frequency": 1.0}

    def outputs_of(self, t, x, u, p):
        phase = 2.0 * np.pi * p["frequency"] * t
        if ops.is_symbolic(phase):
            import casadi as ca

            s, c = ca.sin(phase), ca.cos(phase)
        else:
            s, c = np.sin(phase), np.cos(phase)
        return {"command": self.offset + p["sine_amplitude"] * s + p["cosine_amplitude"] * c}


# ----------------------------------------------------------------------------- signal tools

def fundamental(y, samples_per_period: int) -> complex:
    """The fundamental of a periodic trace as a phasor ``b_s + i b_c`` of
    ``b_s sin(w t) + b_c cos(w t)`` (the convention of :class:`HarmonicCommand`).

    Parameters
    ----------
    y : array_like
        One whole period (or whole periods), sampled evenly from phase 0,
        the end point left out, [any unit]
    samples_per_period : int
        Samples per period, [-]

    Returns
    -------
    complex
        [unit of y]
    """
    y = np.asarray(y, dtype=float)
    ph = 2.0 * np.pi * np.arange(len(y)) / samples_per_period
    return complex(2.0 * np.mean(y * np.sin(ph)), 2.0 * np.mean(y * np.cos(ph)))


def harmonic_distortion(y, harmonics: int = 10) -> float:
    """Total harmonic distortion of one period: rms of harmonics 2 ... ``harmonics`` over the
    fundamental's amplitude (the mean left out).

    Parameters
    ----------
    y : array_like
        One whole period, evenly sampled, the end point left out, [any unit]
    harmonics : int
        Highest harmonic counted, [-]

    Returns
    -------
    float
        [-] (inf for a trace without fundamental)
    """
    c = np.fft.rfft(np.asarray(y, dtype=float))
    a1 = abs(c[1])
    if a1 == 0.0:
        return math.inf
    return float(np.sqrt(np.sum(np.abs(c[2:harmonics + 1]) ** 2)) / a1)


def periodic_change(previous, last, scale: float) -> float:
    """How far a trace is from its periodic state: the largest difference between two
    consecutive periods over ``scale``.

    Parameters
    ----------
    previous, last : array_like
        Two consecutive periods sampled alike, [any unit]
    scale : float
        What the change is measured against (the amplitude), [unit]

    Returns
    -------
    float
        [-]
    """
    return float(np.max(np.abs(np.asarray(last) - np.asarray(previous))) / scale)


def largest_passing(passes, start: float, low: float, high: float, rtol: float = 0.02,
                    step: float = 1.5):
    """The largest value in ``[low, high]`` for which ``passes`` holds, by bracketing from
    ``start`` (steps of ``step``) and bisection on the logarithm, assuming it holds below some
    threshold and fails above.

    The values tried are those of one fixed grid, ``(1 + rtol)**k`` (``low`` and ``high`` at
    its ends), whatever ``start``: two searches (the lines' and the constant supply's) give
    the same answer where their thresholds lie between the same two grid values, and one
    threshold below the other never gives the larger answer.

    Parameters
    ----------
    passes : callable
        ``passes(value) -> (bool, info)``
    start : float
        First value tried (a neighbour's answer), [any unit]
    low, high : float
        Search range, > 0, [unit]
    rtol : float
        Ratio of neighbouring grid values less one: the final bracket's
        relative width, [-]
    step : float
        Bracketing step factor, > 1, [-]

    Returns
    -------
    (value, info_pass, value_fail, info_fail)
        The largest passing value (``low`` with
        ``info_pass`` None where even ``low`` fails), the smallest failing one (None where
        ``high`` passes) and what ``passes`` said of each
    """
    grid = math.log1p(rtol)
    k_low, k_high = math.floor(math.log(low) / grid), math.ceil(math.log(high) / grid)

    def value(k):
        return low if k <= k_low else high if k >= k_high else math.exp(k * grid)

    def index(v):
        return min(max(round(math.log(v) / grid), k_low), k_high)

    dk = max(1, round(math.log(step) / grid))
    k = index(min(max(start, low), high))
    ok, info = passes(value(k))
    lo = hi = None
    if ok:
        lo, lo_info = k, info
        while lo < k_high:
            k = min(lo + dk, k_high)
            ok, info = passes(value(k))
            if not ok:
                hi, hi_info = k, info
                break
            lo, lo_info = k, info
        if hi is None:
            return value(lo), lo_info, None, None
    else:
        hi, hi_info = k, info
        while hi > k_low:
            k = max(hi - dk, k_low)
            ok, info = passes(value(k))
            if ok:
                lo, lo_info = k, info
                break
            hi, hi_info = k, info
        if lo is None:
            return low, None, value(hi), hi_info
    while hi - lo > 1:
        k = (lo + hi) // 2
        ok, info = passes(value(k))
        if ok:
            lo, lo_info = k, info
        else:
            hi, hi_info = k, info
    return value(lo), lo_info, value(hi), hi_info


# ----------------------------------------------------------------------------- ideal supply

def constant_supply_circuit(circuit, pressures: dict):
    """The circuit with its supply and return lines, manifolds and accumulators taken out and
    every valve's P and T ports held by ideal pressure sources (a copy; ``circuit`` stays).

    Parameters
    ----------
    circuit : Circuit
        The rig's circuit (:func:`hydroline.system.build_circuit`)
    pressures : dict
        Axis name -> (supply, return) pressure at its valve's ports, absolute, [Pa]

    Returns
    -------
    Circuit
        Kept: each axis's valve, actuator, friction, load and controller (and any
        component that is not part of the hydraulic supply: no hydraulic ends)
    """
    from ..circuit.builder import Axis, Circuit
    from ..components import PressureSource

    axes = circuit.axes
    kept_names = set()
    for ax in axes.values():
        kept_names.update(n for n in (ax.valve, ax.actuator, ax.friction, ax.controller) if n)
    parts = []
    for c in circuit.components:
        ends = c.hydraulic_ends() if hasattr(c, "hydraulic_ends") else {}
        if c.name in kept_names or not ends:
            parts.append(copy.deepcopy(c))
    new_axes = {}
    for name, ax in axes.items():
        p_s, p_t = pressures[name]
        sup, ret = f"{name}.ideal_supply_pressure", f"{name}.ideal_return_pressure"
        parts.append(PressureSource(name=f"{name}.ideal_supply", pressure=p_s,
                                    connections={"pressure": sup}))
        parts.append(PressureSource(name=f"{name}.ideal_tank", pressure=p_t,
                                    connections={"pressure": ret}))
        valve = next(c for c in parts if c.name == ax.valve)
        valve.connections = {**valve.connections, "supply_pressure": sup, "return_pressure": ret}
        new_axes[name] = Axis(**{**ax.__dict__, "supply_pressure": sup, "return_pressure": ret})
    names = {c.name for c in parts}
    held = {f"{ax.valve}.{port}" for ax in axes.values()
            for port in ("supply_pressure", "return_pressure")}
    overrides = {k: v for k, v in (circuit.overrides or {}).items()
                 if k.rpartition(".")[0] in names and k not in held}
    return Circuit(parts, new_axes, f"{circuit.source} (constant supply)", overrides)


# ----------------------------------------------------------------------------- periodic runs

@dataclass
class PeriodicResponse:
    """One run of the rig at its periodic state under a sine position reference.

    Attributes
    ----------
    frequency : float
        Test frequency, [Hz]
    command : dict
        Axis -> reference phasor ``a_s + i a_c`` (:class:`HarmonicCommand`), [m]
    position : dict
        Axis -> the piston position's fundamental phasor, [m]
    distortion : dict
        Axis -> the position's total harmonic distortion, [-]
    force : dict
        Axis -> amplitude of the hydraulic force's fundamental, [N]
    excursion : dict
        Axis -> largest ``|position|`` over the period, [m]
    traces : dict
        Signal -> its last period (``SineRig.SAMPLES`` samples): the driven
        axes' ports, chambers, current and spool, every axis's position, [SI]
    periods : int
        Periods run until periodic, [-]
    change : float
        Largest period-to-period change at the end (position over its
        amplitude, port pressures over the supply's drop), [-]
    x_end : ndarray
        State at the end (phase 0), [SI]
    warnings : list
        Gas release: watched pressures below ``fluid.gas_release_pressure``
    gas_release_at : list
        The watched signals below it, [-]
    """

    frequency: float
    command: dict
    position: dict
    distortion: dict
    force: dict
    excursion: dict
    traces: dict
    periods: int
    change: float
    x_end: np.ndarray
    warnings: list = field(default_factory=list)
    gas_release_at: list = field(default_factory=list)


class SineRig:
    """A rig's closed loop driven by :class:`HarmonicCommand` position references: one
    compiled model for every frequency, amplitude and phase (runtime parameters).

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    supply : str
        "hoses" (the rig as it is) or "constant" (:func:`constant_supply_circuit`)
    axis : str
        The driven axis (None: the first; "all": every axis together, in phase);
        the others hold mid-stroke under their controllers (references of
        zero amplitude: one compiled model for every choice of axis)
    pressures : dict
        Axis -> (supply, return) port pressures of the constant supply, [Pa]
        (None: the rig's rest state with its lines)
    solver : str
        See :func:`hydroline.engine.integrate`
    periodic_tolerance : float
        Period-to-period change that counts as periodic, [-]
    max_periods : int
        Most periods run for one periodic state, [-]
    """

    #: Samples per period of the output, [-].
    SAMPLES = 256

    def __init__(self, rig: Rig, supply: str = "hoses", axis: str | None = None,
                 pressures: dict | None = None, solver: str = "auto",
                 periodic_tolerance: float = 2e-3, max_periods: int = 60):
        from ..scenarios.experiments import template_controller
        from ..scenarios.running import CAVITATION_PRESSURE, WATCHED_NODES, rest_state
        from ..system import build_circuit

        if supply not in ("hoses", "constant"):
            raise ValueError(f"supply must be 'hoses' or 'constant', got {supply!r}")
        self.rig, self.supply, self.solver = rig, supply, solver
        self.periodic_tolerance, self.max_periods = periodic_tolerance, max_periods
        circuit = build_circuit(rig, 0.0)
        if not circuit.axes:
            raise RigError(f"rig {rig.source}: no servo axis (an actuator driven by a servovalve)")
        for name in circuit.axes:
            circuit.place(0.0, name)            # every axis from mid-stroke
        if axis == "all":
            driven = list(circuit.axes)
        elif axis is None:
            driven = [next(iter(circuit.axes))]
        elif axis in circuit.axes:
            driven = [axis]
        else:
            raise RigError(f"axis: no axis {axis!r} in the rig (axes: {', '.join(circuit.axes)}, "
                           f"or 'all')")
        if supply == "constant":
            if pressures is None:
                pressures = SineRig(rig, "hoses", axis, solver=solver).port_pressures()
            circuit = constant_supply_circuit(circuit, pressures)
        self.circuit, self.driven = circuit, driven
        # every axis gets a sine reference about mid-stroke, those not driven with zero
        # amplitude: they hold where they start under their controllers, and one compiled model
        # serves each axis alone and all together
        commands = []
        for name, ax in circuit.axes.items():
            commands.append(HarmonicCommand(name=f"{name}.envelope_command", quantity="position",
                                            connections={"command": ax.reference_signal}))
            if not ax.controller:
                commands.append(template_controller(rig, ax))
        self.network = net = circuit.network(commands)
        self.rest = rest_state(net)
        self.p = self.rest.p.copy()
        names = list(net.parameter_names)
        self.index = {(n, k): names.index(f"{n}.envelope_command.{k}") for n in circuit.axes
                      for k in ("sine_amplitude", "cosine_amplitude", "frequency")}
        self.axes = circuit.axes
        self.threshold = rig.get("fluid.gas_release_pressure", CAVITATION_PRESSURE)
        self.watched = []
        for ax in circuit.axes.values():
            self.watched += [s for s in (ax.supply_pressure, ax.return_pressure,
                                         ax.bottom_pressure, ax.top_pressure) if s not in self.watched]
        self.watched += [s for s in WATCHED_NODES if s in net.signal_names]
        self.limits = {}
        for name in driven:
            ax = circuit.axes[name]
            valve, act = net.component(ax.valve), net.component(ax.actuator)
            ctrl = net.component(ax.controller or "controller")
            self.limits[name] = dict(current=min(ctrl.current_limit, valve.rated_current),
                                     opening=valve.max_opening, stroke=act.stroke,
                                     bottom_area=act.bottom_area, top_area=act.top_area)
        self.nominal = pressures if pressures is not None else self.port_pressures()

    def port_pressures(self) -> dict:
        """Axis -> (supply, return) pressure at its valve's ports in the rest state, [Pa].

        Returns
        -------
        dict
            Axis name -> ``(supply, return)`` pressures, [Pa].
        """
        sig = self.network.signals_at(0.0, self.rest.x, self.rest.p)
        return {name: (sig[ax.supply_pressure], sig[ax.return_pressure])
                for name, ax in self.axes.items()}

    def run(self, frequency: float, command: dict, x0=None) -> PeriodicResponse:
        """Run at ``frequency`` with the reference phasors ``command`` until the periodic state.

        Parameters
        ----------
        frequency : float
            [Hz]
        command : dict
            Axis -> reference phasor ``a_s + i a_c``, [m] (driven axes)
        x0 : array
            Start state at phase 0, [SI] (None: the rest state)

        Returns
        -------
        PeriodicResponse
        """
        n = self.SAMPLES
        p = self.p

        def set_command(phasors):
            for name in self.driven:
                c = complex(phasors[name])
                p[self.index[name, "sine_amplitude"]] = c.real
                p[self.index[name, "cosine_amplitude"]] = c.imag
                p[self.index[name, "frequency"]] = frequency

        x = (self.rest.x if x0 is None else x0).copy()
        if x0 is None and any(complex(command[name]).real != 0.0 for name in self.driven):
            # From the rest state a sine reference leaves every derivative zero at t = 0 and at
            # every whole and half period: the variable-step solver may step over the whole
            # run and see nothing. A quarter period of the reference shifted a quarter
            # period back (a_s sin + a_c cos -> a_c sin - a_s cos: nonzero at t = 0) ends
            # at the reference's phase 0, where the run proper starts.
            set_command({name: complex(complex(command[name]).imag, -complex(command[name]).real)
                         for name in self.driven})
            res = integrate(self.network, x, 0.25 / frequency, dt_out=0.25 / frequency, p=p,
                            solver=self.solver, rtol=1e-6, atol_scale=1e-7)
            x = np.array([res[s][-1] for s in self.network.state_names])
        set_command(command)
        total, chunk = 0, 3 if x0 is None else 2
        drop = max(abs(ps - pt) for ps, pt in self.nominal.values())
        while True:
            res = integrate(self.network, x, chunk / frequency, dt_out=1.0 / (frequency * n),
                            p=p, solver=self.solver, rtol=1e-6, atol_scale=1e-7)
            total += chunk
            rows = len(res.t) - 1                   # = chunk * n (+ the start row)
            last, prev = slice(rows - n, rows), slice(rows - 2 * n, rows - n)
            change = 0.0
            for name in self.driven:
                xp = res[self.axes[name].position]
                scale = max(abs(command[name]), 0.5 * (xp[last].max() - xp[last].min()), 1e-6)
                change = max(change, periodic_change(xp[prev], xp[last], scale))
                for s in (self.axes[name].supply_pressure, self.axes[name].return_pressure):
                    change = max(change, periodic_change(res[s][prev], res[s][last], drop))
            x = np.array([res[s][-1] for s in self.network.state_names])
            if change <= self.periodic_tolerance or total >= self.max_periods:
                break
            chunk = max(2, min(total, self.max_periods - total))
        # every axis's position: the held axes' too (what the driven one's flow does to them)
        traces = {ax.position: res[ax.position][last] for ax in self.axes.values()}
        position, distortion, force, excursion = {}, {}, {}, {}
        for name in self.driven:
            ax = self.axes[name]
            lim = self.limits[name]
            for s in (ax.position, ax.current, ax.supply_pressure, ax.return_pressure,
                      ax.bottom_pressure, ax.top_pressure, ax.velocity):
                traces[s] = res[s][last]
            traces[f"{ax.valve}.spool_position"] = res[f"{ax.valve}.spool_position"][last]
            xp = traces[ax.position]
            position[name] = fundamental(xp, n)
            distortion[name] = harmonic_distortion(xp)
            f_h = lim["bottom_area"] * traces[ax.bottom_pressure] \
                - lim["top_area"] * traces[ax.top_pressure]
            force[name] = abs(fundamental(f_h, n))
            excursion[name] = float(np.max(np.abs(xp)))
        warnings, released = [], []
        for s in self.watched:
            if s in res:
                low = float(np.min(res[s][last]))
                if low < self.threshold:
                    released.append(s)
                    warnings.append(f"{s} falls below the gas-release pressure "
                                    f"{self.threshold / 1e6:.3g} MPa absolute "
                                    f"(fluid.gas_release_pressure; lowest {low / 1e6:.3g} MPa)")
        return PeriodicResponse(frequency, dict(command), position, distortion, force, excursion,
                                traces, total, change, x, warnings, released)

    def reach(self, frequency: float, target: float, gains: dict, x0=None, tolerance: float = 0.01,
              iterations: int = 12):
        """Amplitude control: the reference's amplitude and phase adjusted, run after run,
        until each driven piston's fundamental is ``target`` in phase with the wanted sine.

        Each run's reference is the target over the closed-loop gain last measured (its phase
        and, on a linear loop, its amplitude). Where the response grows less than in
        proportion (the current or spool saturating), the amplitude is corrected on the
        measured slope of log amplitude against log reference instead (a secant,
        ``|C| (X/|x|)**(1/slope)``, slope at least 0.1), so a target just below the saturated
        amplitude is reached in a few runs rather than approached by ever smaller steps.

        Parameters
        ----------
        frequency : float
            [Hz]
        target : float
            Wanted displacement amplitude, [m]
        gains : dict
            Axis -> closed-loop gain estimate (position over reference
            phasor, [-]); a neighbour's
        x0 : array
            Start state at phase 0, [SI] (None: the rest state)
        tolerance : float
            Relative amplitude error accepted, [-]
        iterations : int
            Most runs, [-]

        Returns
        -------
        (PeriodicResponse, bool, dict)
            The last run, whether every amplitude was reached,
            the gains measured
        """
        gains = dict(gains)
        x = x0
        history = {n: [] for n in self.driven}      # (|reference|, |fundamental|) per run
        for _ in range(iterations):
            command = {}
            for n in self.driven:
                c = target / gains[n]
                if len(history[n]) >= 2:
                    (c0, a0), (c1, a1) = history[n][-2:]
                    if c1 != c0 and a0 > 0 and a1 > 0:
                        slope = math.log(a1 / a0) / math.log(c1 / c0)
                        if 0 < slope < 1:           # saturating: secant on the log-log curve
                            c = c / abs(c) * c1 * (target / a1) ** (1 / max(slope, 0.1))
                command[n] = c
            r = self.run(frequency, command, x)
            x = r.x_end
            errors = [abs(abs(r.position[n]) - target) / target for n in self.driven]
            if max(errors) <= tolerance:
                return r, True, gains
            for n in self.driven:
                history[n].append((abs(command[n]), abs(r.position[n])))
                g = r.position[n] / command[n]
                if abs(g) > 1e-9:
                    gains[n] = g
            if any(abs(target / gains[n]) > 1e3 * target for n in self.driven):
                break
        return r, False, gains


#: The share of the valve's flow a loss of its pressure drop may cost before the loss is named
#: the limit: the 5 % within which an envelope counts as matching the vendor's. At a given
#: opening the flow goes as the root of the drop, so a loss ``L`` of the rest drop ``D`` costs
#: ``1 - sqrt(1 - L/D)`` of it: the supply dip or return rise counts from
#: ``L = (1 - 0.95**2) D = 9.75 %`` of the drop, [-].
FLOW_LOSS = 0.05
#: The hydraulic force's peak, over the actuator's stall force (supply pressure on the pushing
#: area less tank pressure on the other: ``(p_s - p_t) A`` for equal areas), from which the
#: force limits: one chamber at the supply pressure, the other at the tank's, [-].
STALL_SHARE = 0.95


def diagnose(response: PeriodicResponse, rig: SineRig, reached: bool, distortion: float) -> str:
    """What keeps a run from passing (one of :data:`LIMITS`), from its last period, by the
    rules a test laboratory reads a performance curve with, in this order:

    1. ``supply_dip`` / ``return_rise``: a pressure at the valve's supply (return) port, or
       in the supply (return) manifold, fell below the gas-release pressure: the line's
       pressure pulsation at the valve, not the valve or the actuator, ends the test (the
       return port's swing about its rest pressure both rises, taking the valve's drop, and
       falls, its troughs to the gas-release pressure).
    2. ``force``: the hydraulic force reached :data:`STALL_SHARE` of the actuator's stall
       force (one chamber at supply, the other at tank pressure): the load, not the flow,
       limits; beyond it the low chamber cavitates.
    3. ``gas_release``: an actuator chamber fell below the gas-release pressure with the
       force short of the stall force (an overrunning mass braked through a throttling valve).
    4. Where a driven valve is at its limit (spool within 1 % of its opening, or the current
       within 1 % of the controller's limit), the mean loss of its drop over those instants:
       the supply port's dip below its rest pressure (``supply_dip``) or the return port's
       rise above it (``return_rise``) where it costs more than :data:`FLOW_LOSS` of the
       flow (9.75 % of the rest drop), else the valve's rated flow (``valve``).
    5. ``distortion``: nothing at a limit, the position's distortion over the tolerance.

    Parameters
    ----------
    response : PeriodicResponse
        The failing run
    rig : SineRig
        Its rig (limits, rest pressures, axis handles)
    reached : bool
        The amplitude control reached the target
    distortion : float
        Harmonic distortion allowed, [-]

    Returns
    -------
    str
    """
    from ..scenarios.running import WATCHED_NODES

    side = dict(zip(WATCHED_NODES, ("supply_dip", "return_rise")))
    for ax in rig.axes.values():
        side.update({ax.supply_pressure: "supply_dip", ax.return_pressure: "return_rise"})
    ports = [side[s] for s in response.gas_release_at if s in side]
    if ports:
        return ports[0]
    tr = response.traces
    for name in rig.driven:
        ax, lim = rig.axes[name], rig.limits[name]
        p_s, p_t = rig.nominal[name]
        a_b, a_t = lim["bottom_area"], lim["top_area"]
        force = a_b * tr[ax.bottom_pressure] - a_t * tr[ax.top_pressure]
        if force.max() >= STALL_SHARE * (a_b * p_s - a_t * p_t) or \
                -force.min() >= STALL_SHARE * (a_t * p_s - a_b * p_t):
            return "force"
    if response.gas_release_at:
        return "gas_release"
    loss = 1.0 - (1.0 - FLOW_LOSS) ** 2
    for name in rig.driven:
        ax, lim = rig.axes[name], rig.limits[name]
        spool = tr[f"{ax.valve}.spool_position"]
        at_limit = (np.abs(spool) >= 0.99 * lim["opening"]) | \
            (np.abs(tr[ax.current]) >= 0.99 * lim["current"])
        if not at_limit.any():
            continue
        p_s, p_t = rig.nominal[name]
        dip = float(np.mean((p_s - tr[ax.supply_pressure])[at_limit]))
        rise = float(np.mean((tr[ax.return_pressure] - p_t)[at_limit]))
        if max(dip, rise) > loss * (p_s - p_t):
            return "supply_dip" if dip >= rise else "return_rise"
        return "valve"
    return "distortion"


def port_ripple_gain(response: PeriodicResponse, rig: SineRig, axis: str | None = None) -> float:
    """How much the pressure pulsation at the valve's supply and return ports raises the
    valve's fundamental load flow: the fundamental of the load flow ``(q_b + q_t)/2`` of the
    valve's own metering law (M20) over the run's last period, with the port pressures as they
    were, over the same with the ports held at their period means (spool and chamber
    pressures as they were).

    A flow ``x_v sqrt(dp)`` whose drop pulsates at twice the test frequency, ``dp (1 + e
    cos(2 w t + phi))``, has its fundamental changed by up to ``e/4`` of it, up or down with
    the phase ``phi`` of the pulsation against the spool's: where the lines' standing wave
    at ``2 f`` peaks the drop while the spool is open widest, the lines lift the valve's flow
    above what the same mean pressures give, and the envelope may lie above the constant
    supply's by that much (1.0 from a constant supply).

    Parameters
    ----------
    response : PeriodicResponse
        A run (its traces)
    rig : SineRig
        Its rig
    axis : str
        The axis (None: the first driven one)

    Returns
    -------
    float
        [-]
    """
    name = axis or rig.driven[0]
    ax = rig.axes[name]
    tr = response.traces
    valve = rig.network.component(ax.valve)
    spool = {"spool_position": tr[f"{ax.valve}.spool_position"]}
    chambers = {"bottom_pressure": tr[ax.bottom_pressure], "top_pressure": tr[ax.top_pressure]}

    def load_flow(p_s, p_t):
        q = valve.outputs_of(0.0, spool, {**chambers, "supply_pressure": p_s,
                                          "return_pressure": p_t}, {})
        return abs(fundamental(0.5 * (q["bottom_flow"] + q["top_flow"]), len(p_s)))

    p_s, p_t = tr[ax.supply_pressure], tr[ax.return_pressure]
    steady = load_flow(np.full_like(p_s, p_s.mean()), np.full_like(p_t, p_t.mean()))
    return float(load_flow(p_s, p_t) / steady) if steady > 0 else 1.0


# ----------------------------------------------------------------------------- analytic

def vendor_parameters(rig: SineRig, axis: str | None = None) -> dict:
    """What the vendor's analytic envelope reads from a rig (:func:`analytic_envelope`).

    Parameters
    ----------
    rig : SineRig
        The rig (its constant supply's pressures: the rest pressures at the ports)
    axis : str
        The axis (None: the first driven one)

    Returns
    -------
    dict
        stroke [m], area [m^2], mass [kg], supply_pressure, return_pressure [Pa],
        rated_flow [m^3/s], rated_pressure_drop [Pa], load_force (friction's Coulomb and
        gravity, the worse direction) [N], viscous (friction) [N s/m], coulomb [N]
    """
    from ..components import Load

    name = axis or rig.driven[0]
    ax, net = rig.axes[name], rig.network
    act, valve = net.component(ax.actuator), net.component(ax.valve)
    mass = act.moving_mass + sum(c.mass for c in net.components if isinstance(c, Load)
                                 and c.connections.get("position") == ax.position)
    fr = net.component(ax.friction) if ax.friction else None
    coulomb = max(fr.coulomb_up, fr.coulomb_down) if fr is not None else 0.0
    viscous = max(fr.viscous_up, fr.viscous_down) if fr is not None else 0.0
    p_s, p_t = rig.nominal[name]
    return dict(stroke=act.stroke, area=min(act.bottom_area, act.top_area), mass=mass,
                supply_pressure=p_s, return_pressure=p_t, rated_flow=valve.rated_flow,
                rated_pressure_drop=valve.rated_pressure_drop,
                load_force=coulomb + abs(mass * act.gravity), viscous=viscous, coulomb=coulomb)


def clipped_sine_gain(distortion: float, samples: int = 2048) -> float:
    """How far above the flow limit a sine's fundamental velocity may go when the position may
    have ``distortion``: a velocity ``clip(V sin(w t), +-v_max)`` whose displacement (its
    integral) has that total harmonic distortion (harmonics 2-10, as
    :func:`harmonic_distortion`) has the fundamental ``gain * v_max``.

    Parameters
    ----------
    distortion : float
        Displacement THD allowed, [-] (0: a pure sine, gain 1)
    samples : int
        Samples of the period, [-]

    Returns
    -------
    float
        Fundamental over the clip level, >= 1, [-]
    """
    if distortion <= 0:
        return 1.0
    ph = 2.0 * np.pi * np.arange(samples) / samples

    def thd_and_gain(c):
        v = np.clip(np.sin(ph), -c, c)
        x = np.cumsum(v)
        return harmonic_distortion(x - x.mean()), abs(np.fft.rfft(v)[1]) * 2 / samples / c

    lo, hi = 1e-3, 1.0           # clip levels: distortion falls as the level rises
    if thd_and_gain(lo)[0] <= distortion:
        return thd_and_gain(lo)[1]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if thd_and_gain(mid)[0] > distortion:
            lo = mid
        else:
            hi = mid
    return thd_and_gain(hi)[1]


def analytic_envelope(frequencies, stroke: float, area: float, mass: float,
                      supply_pressure: float, return_pressure: float, rated_flow: float,
                      rated_pressure_drop: float, load_force: float = 0.0,
                      viscous: float = 0.0, distortion: float = 0.0, coulomb: float = 0.0) -> dict:
    """The vendor's performance curve from a constant supply: the least of the stroke limit
    ``x = stroke/2``, the flow limit ``v = Q(p_L)/A`` with ``Q(p_L) = Q_N sqrt((p_s - p_t -
    p_L)/dp_N)`` at the load pressure at peak velocity ``p_L = (F + c v)/A`` and the force
    limit ``a = (p_s - p_t) A / m``. With a ``distortion`` allowed, the flow limit's
    fundamental is ``clipped_sine_gain(distortion)`` times ``Q/A`` (the velocity clipped at
    ``Q/A``: 1.16 at 5 %); the vendor's curve is ``distortion = 0``.

    Parameters
    ----------
    frequencies : array_like
        [Hz]
    stroke : float
        Full stroke, [m]
    area : float
        Piston area, [m^2]
    mass : float
        Moving mass, [kg]
    supply_pressure, return_pressure : float
        At the valve's ports, [Pa]
    rated_flow : float
        Q_N, [m^3/s]
    rated_pressure_drop : float
        dp_N over the valve (two edges), [Pa]
    load_force : float
        Force at peak velocity besides viscous friction (Coulomb
        friction, weight), [N]
    viscous : float
        Viscous friction coefficient, [N s/m]
    distortion : float
        Displacement THD allowed, [-] (0: the vendor's pure sine)
    coulomb : float
        Coulomb friction, [N] (the force's fundamental: mass times
        acceleration in quadrature with the friction's fundamental,
        ``c v + 4 F_c / pi``)

    Returns
    -------
    dict
        ``frequency_hz``, ``displacement_amplitude_m``, ``velocity_amplitude_m_s``,
        ``acceleration_amplitude_m_s2``, ``force_amplitude_n`` (mass and friction), ``limited_by``
        ("stroke", "valve", "force") per frequency; ``flow_limited_velocity_m_s`` [m/s]
    """
    f = np.asarray(frequencies, dtype=float)
    w = 2.0 * np.pi * f
    drop = supply_pressure - return_pressure
    v = rated_flow * math.sqrt(drop / rated_pressure_drop) / area
    for _ in range(50):         # the load pressure at that velocity (fixed point)
        p_load = min((load_force + viscous * v) / area, drop)
        v = rated_flow * math.sqrt((drop - p_load) / rated_pressure_drop) / area
    v_clip = v
    v = v * clipped_sine_gain(distortion)
    a = drop * area / mass
    limits = np.vstack([np.full_like(f, stroke / 2), v / w, a / w**2])
    k = np.argmin(limits, axis=0)
    x = limits[k, np.arange(len(f))]
    return {"frequency_hz": f.tolist(), "displacement_amplitude_m": x.tolist(),
            "velocity_amplitude_m_s": (w * x).tolist(),
            "acceleration_amplitude_m_s2": (w**2 * x).tolist(),
            "force_amplitude_n": np.hypot(mass * w**2 * x,
                                          viscous * w * x + 4 / np.pi * coulomb).tolist(),
            "limited_by": [("stroke", "valve", "force")[i] for i in k],
            "flow_limited_velocity_m_s": v_clip, "distortion": distortion}


# ----------------------------------------------------------------------------- the search

def default_frequencies(points: int = 20, low: float = 0.5, high: float = 200.0) -> np.ndarray:
    """``points`` frequencies spaced evenly on a log scale from ``low`` to ``high``, [Hz].

    Parameters
    ----------
    points : int
        How many, >= 1, [-]
    low : float
        Lowest, [Hz]
    high : float
        Highest, [Hz]

    Returns
    -------
    ndarray
        The frequencies, [Hz].
    """
    if points == 1:
        return np.array([float(low)])
    return np.geomspace(low, high, int(points))


def envelope_points(srig: SineRig, frequencies, guesses, distortion: float = 0.05,
                    rtol: float = 0.02, amplitude_tolerance: float = 0.01,
                    stroke_margin: float = 0.01, progress=None) -> list[dict]:
    """The envelope of one :class:`SineRig` at ascending frequencies (one after the other,
    each warm-started from the last one's periodic state, gain and answer).

    Parameters
    ----------
    srig : SineRig
        The rig
    frequencies : array_like
        Ascending, [Hz]
    guesses : array_like
        First amplitude tried at each, [m] (the analytic envelope)
    distortion : float
        Harmonic distortion of the position allowed, [-]
    rtol : float
        Relative width of the bisection's last bracket, [-]
    amplitude_tolerance : float
        Relative error of the reached amplitude accepted, [-]
    stroke_margin : float
        The amplitude searched up to ``(1 - margin) stroke/2``, [-]
    progress : callable
        Called with the number of frequencies done

    Returns
    -------
    list of dict
        Per frequency: ``frequency_hz``, ``displacement_amplitude_m``,
        ``velocity_amplitude_m_s``, ``acceleration_amplitude_m_s2``, ``force_amplitude_n``,
        ``limited_by``, ``distortion``, ``command_gain`` (reference over displacement amplitude)
        and ``command_phase_deg``, ``supply_min_pa``, ``return_max_pa`` (at the valve's ports),
        ``port_ripple_gain`` (:func:`port_ripple_gain` of the passing run),
        ``held_motion_m`` (the largest half peak-to-peak motion of an axis held, [m]),
        ``runs``, ``periods``, ``failing_amplitude_m`` (the bracket's smallest failing one) and
        ``limit_note`` (its port pressures' range and distortion, or the gas-release warning)
    """
    top = min(srig.limits[n]["stroke"] for n in srig.driven) / 2 * (1 - stroke_margin)
    warm = {"x": None, "gains": {n: 1.0 + 0j for n in srig.driven}}
    out, previous = [], None
    for k, (f, guess) in enumerate(zip(frequencies, guesses)):
        f = float(f)
        counts = {"runs": 0, "periods": 0}

        def passes(target, f=f, counts=counts):
            r, reached, gains = srig.reach(f, target, warm["gains"], warm["x"],
                                           amplitude_tolerance)
            counts["runs"] += 1
            counts["periods"] += r.periods
            ok = (reached and not r.warnings
                  and max(r.distortion.values()) <= distortion
                  and max(r.excursion[n] / (srig.limits[n]["stroke"] / 2)
                          for n in srig.driven) <= 1.0)
            if ok:
                warm["x"], warm["gains"] = r.x_end, gains
            return ok, (r, reached)

        start = guess if previous is None else previous[1] * guess / previous[0]
        x, good, x_fail, bad = largest_passing(passes, start, top * 1e-4, top, rtol)
        if bad is None:
            limited = "stroke" if x >= top * (1 - 1e-9) else "none"
        else:
            limited = diagnose(bad[0], srig, bad[1], distortion)
        note = ""
        if bad is not None:
            tr, ax0 = bad[0].traces, srig.axes[srig.driven[0]]
            note = ((bad[0].warnings[0] + "; ") if bad[0].warnings else "") + (
                    f"at {x_fail * 1e3:.3g} mm: supply port {tr[ax0.supply_pressure].min() / 1e6:.3g}"
                    f"-{tr[ax0.supply_pressure].max() / 1e6:.3g} MPa, return port "
                    f"{tr[ax0.return_pressure].min() / 1e6:.3g}-"
                    f"{tr[ax0.return_pressure].max() / 1e6:.3g} MPa, distortion "
                    f"{max(bad[0].distortion.values()) * 100:.2g} %")
        w = 2 * np.pi * f
        name = srig.driven[0]
        ax = srig.axes[name]
        point = {"frequency_hz": f, "displacement_amplitude_m": x if good else 0.0,
                 "velocity_amplitude_m_s": w * x if good else 0.0,
                 "acceleration_amplitude_m_s2": w * w * x if good else 0.0,
                 "force_amplitude_n": good[0].force[name] if good else 0.0,
                 "limited_by": limited, "limit_note": note, "failing_amplitude_m": x_fail,
                 "distortion": good[0].distortion[name] if good else None,
                 "command_gain": abs(good[0].command[name]) / x if good else None,
                 "command_phase_deg": math.degrees(np.angle(good[0].command[name])) if good
                 else None,
                 "supply_min_pa": float(good[0].traces[ax.supply_pressure].min()) if good else None,
                 "return_max_pa": float(good[0].traces[ax.return_pressure].max()) if good else None,
                 "port_ripple_gain": port_ripple_gain(good[0], srig, name) if good else None,
                 "held_motion_m": max((float(np.ptp(good[0].traces[a.position])) / 2
                                       for n, a in srig.axes.items() if n not in srig.driven),
                                      default=0.0) if good else None,
                 **counts}
        out.append(point)
        if good:
            previous = (guess, x)
        if progress is not None:
            progress(k + 1)
    return out


class EnvelopeRunner:
    """Runs one share of an envelope (a supply, a run of ascending frequencies) where it is
    sent: ``runner(index, values) -> row``, picklable (:mod:`hydroline.studies.executors`).

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    axis : str
        Driven axis (None: the first; "all": all together)
    pressures : dict
        Axis -> the constant supply's (supply, return) pressures, [Pa]
    options : dict
        Keywords of :func:`envelope_points` (distortion, rtol, ...)
    solver : str
        See :func:`hydroline.engine.integrate`
    """

    def __init__(self, rig: Rig, axis, pressures: dict, options: dict, solver: str = "auto"):
        self.rig, self.axis, self.pressures = rig, axis, pressures
        self.options, self.solver = dict(options), solver
        self.progress = None
        self._rigs = {}

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_rigs"], state["progress"] = {}, None
        return state

    def sine_rig(self, supply: str) -> SineRig:
        """The :class:`SineRig` of ``supply`` ("hoses" or "constant"), built once here.

        Parameters
        ----------
        supply : str
            "hoses" or "constant"

        Returns
        -------
        SineRig
            The rig of that supply.
        """
        if supply not in self._rigs:
            self._rigs[supply] = SineRig(self.rig, supply, self.axis, self.pressures, self.solver)
        return self._rigs[supply]

    def __call__(self, index: int, values: dict) -> dict:
        """One share's row: ``index``, ``supply``, ``points`` (:func:`envelope_points`),
        ``error`` (None, or "Type: reason")."""
        from .executors import failure_reason

        row = {"index": index, "supply": values["supply"], "points": [], "error": None}
        try:
            srig = self.sine_rig(values["supply"])
            row["points"] = envelope_points(srig, values["frequencies"], values["guesses"],
                                            progress=self.progress, **self.options)
        except Exception as e:      # a share that fails is said, the others go on
            row["error"] = failure_reason(e)
        return row


# ----------------------------------------------------------------------------- the study

#: Per-frequency quantities of each curve in the JSON and CSV, with their units.
CURVE_KEYS = ("displacement_amplitude_m", "velocity_amplitude_m_s", "acceleration_amplitude_m_s2",
              "force_amplitude_n", "limited_by")


@dataclass
class EnvelopeResult:
    """The envelope of a rig with its lines (``hoses``), from a constant supply
    (``constant_supply``) and the vendor's analytic one for that supply (``analytic``).

    Attributes
    ----------
    frequency_hz : list
        Test frequencies, [Hz]
    hoses : list
        Per frequency the point of :func:`envelope_points` (lines in the loop)
    constant_supply : list
        The same from an ideal constant supply and tank (empty: not run)
    analytic : dict
        :func:`analytic_envelope` for that supply
    rig : str
        The rig's source
    axis : str
        The driven axis ("all": every axis together)
    distortion : float
        Harmonic distortion allowed, [-]
    wall_time : float
        [s]
    errors : list
        Shares that failed ("supply: Type: reason")
    """

    frequency_hz: list
    hoses: list
    constant_supply: list
    analytic: dict
    rig: str = ""
    axis: str = ""
    distortion: float = 0.05
    wall_time: float = 0.0
    errors: list = field(default_factory=list)

    @staticmethod
    def curve(points: list) -> dict:
        """A curve's per-frequency lists (:data:`CURVE_KEYS` and the diagnostics) from its points.

        Parameters
        ----------
        points : list of dict
            From :func:`envelope_points`

        Returns
        -------
        dict
            Key -> list with one value per frequency, [the key's unit].
        """
        keys = [k for k in (points[0] if points else {}) if k != "frequency_hz"]
        return {k: [p[k] for p in points] for k in keys}

    def to_dict(self) -> dict:
        """The JSON form: ``frequency_hz``, the hose curve's lists (``displacement_amplitude_m``,
        ``velocity_amplitude_m_s``, ``acceleration_amplitude_m_s2``, ``force_amplitude_n``,
        ``limited_by``, ...), ``constant_supply`` and ``analytic`` with the same keys, and the
        study's settings.

        Returns
        -------
        dict
            The JSON document (plain numbers and texts).
        """
        out = {"frequency_hz": list(self.frequency_hz), **self.curve(self.hoses)}
        if self.constant_supply:
            out["constant_supply"] = self.curve(self.constant_supply)
        out["analytic"] = {k: v for k, v in self.analytic.items() if k != "frequency_hz"}
        out.update(rig=self.rig, axis=self.axis, distortion=self.distortion,
                   wall_time_s=self.wall_time, errors=list(self.errors))
        return out

    def rows(self) -> list[dict]:
        """One CSV row per frequency: the hose curve, the constant supply's and the analytic
        one side by side (``constant_supply.<key>``, ``analytic.<key>``).

        Returns
        -------
        list of dict
            Column name -> value, one dict per frequency.
        """
        rows = []
        for k, f in enumerate(self.frequency_hz):
            row = {"frequency_hz": f}
            for prefix, pts in (("", self.hoses), ("constant_supply.", self.constant_supply)):
                if k < len(pts):
                    row.update({prefix + key: v for key, v in pts[k].items() if key != "frequency_hz"})
            row.update({f"analytic.{key}": self.analytic[key][k] for key in CURVE_KEYS})
            rows.append(row)
        return rows


#: Shading of each limiting mechanism in the figure.
LIMIT_COLOURS = {"stroke": "#c6dbef", "valve": "#d9f0d3", "supply_dip": "#fdd0a2",
                 "return_rise": "#fcbba1", "force": "#dadaeb", "gas_release": "#fa9fb5",
                 "distortion": "#fee391", "none": "#f0f0f0"}


def _minor_log_label(axis):
    """A tick label function for a log axis's minor ticks, the plain number where the axis
    has too few major ticks to be read by them: at 2, 4, 6 and 8 times a power of ten on an
    axis spanning less than a decade, at 2 and 5 times one on an axis spanning less than 2.5,
    nothing on a wider one."""
    def label(value, _position):
        low, high = sorted(axis.get_view_interval())
        decades = np.log10(high / low) if low > 0 else np.inf
        digit = round(value / 10.0 ** np.floor(np.log10(value) + 1e-9), 6)
        shown = (2, 4, 6, 8) if decades < 1 else (2, 5) if decades < 2.5 else ()
        return f"{value:g}" if digit in shown else ""
    return label


def envelope_figure(result: EnvelopeResult, path=None):
    """Displacement, velocity, acceleration and force amplitude against frequency on log-log
    axes: the envelope with the lines (solid), from the constant supply (dashed), the
    analytic one (dotted); the band of each test frequency shaded by what limits the
    envelope with the lines there.

    Parameters
    ----------
    result : EnvelopeResult
        From :func:`envelope`
    path : str or Path
        PNG to write (None: not written)

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.patches import Patch
    from matplotlib.ticker import FuncFormatter

    from ..plotting import new_figure, save_png, wrap_title

    f = np.asarray(result.frequency_hz, dtype=float)
    fig = new_figure((11, 8))
    axes = fig.subplots(2, 2, sharex=True).ravel()
    quantities = (("displacement_amplitude_m", "displacement amplitude [mm]", 1e3),
                  ("velocity_amplitude_m_s", "velocity amplitude [m/s]", 1.0),
                  ("acceleration_amplitude_m_s2", "acceleration amplitude [m/s²]", 1.0),
                  ("force_amplitude_n", "force amplitude [kN]", 1e-3))
    edges = np.sqrt(f[1:] * f[:-1]) if len(f) > 1 else np.array([])
    lo = np.r_[f[0] / (edges[0] / f[0]) if len(edges) else f[0] / 1.2, edges]
    hi = np.r_[edges, f[-1] * (f[-1] / edges[-1]) if len(edges) else f[-1] * 1.2]
    used = []
    for ax, (key, label, scale) in zip(axes, quantities):
        for k, point in enumerate(result.hoses):
            ax.axvspan(lo[k], hi[k], color=LIMIT_COLOURS.get(point["limited_by"], "#ffffff"),
                       lw=0, zorder=0)
            used.append(point["limited_by"])
        curves = [(result.hoses, "-", "C0", "with the lines")]
        if result.constant_supply:
            curves.append((result.constant_supply, "--", "C1", "constant supply"))
        for pts, style, colour, name in curves:
            y = np.array([p[key] for p in pts], dtype=float) * scale
            ax.loglog(f[:len(y)], np.where(y > 0, y, np.nan), style, color=colour, marker="o",
                      ms=3, label=name)
        y = np.array(result.analytic[key], dtype=float) * scale
        ax.loglog(f, y, ":", color="k", label="analytic (constant supply)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
        for axis in (ax.xaxis, ax.yaxis):    # plain numbers (60, 2, 0.8), not 6 x 10^1
            axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
            axis.set_minor_formatter(FuncFormatter(_minor_log_label(axis)))
    for ax in axes[2:]:
        ax.set_xlabel("frequency [Hz]")
    handles, labels = axes[0].get_legend_handles_labels()
    handles += [Patch(color=LIMIT_COLOURS[m], label=f"limited by {m.replace('_', ' ')}")
                for m in LIMITS if m in used]
    fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.suptitle(wrap_title(f"Performance envelope, {result.rig}, axis {result.axis}: position "
                            f"THD ≤ {result.distortion * 100:g} % (shading: what limits the "
                            f"envelope with the lines)", 11, 11), fontsize=11)
    fig.subplots_adjust(bottom=0.14, top=0.9, hspace=0.08, wspace=0.22)
    if path is not None:
        save_png(fig, path, dpi=110)
    return fig


def envelope(rig: "Rig | str | None" = None, frequencies=None, *, points: int = 20,
             axis: str | None = None, distortion: float = 0.05, constant_supply: bool = True,
             rtol: float = 0.02, workers: int = 1, scheduler=None, solver: str = "auto",
             progress=None) -> EnvelopeResult:
    """The performance envelope of a rig with its lines in the loop, beside the same from an
    ideal constant supply and the vendor's analytic one (module docstring).

    Parameters
    ----------
    rig : Rig, str or None
        The rig (a path or shipped name; None: the paper's)
    frequencies : array_like
        Test frequencies, [Hz] (None: ``points`` from 0.5 to 200 Hz,
        log-spaced)
    points : int
        Frequencies when ``frequencies`` is None, [-]
    axis : str
        Driven axis (None: the first; "all": every axis together, in
        phase); the others hold
    distortion : float
        Total harmonic distortion of the position allowed, [-]
    constant_supply : bool
        Also run the ideal constant supply
    rtol : float
        Relative resolution of the amplitude, [-]
    workers : int
        Local worker processes (the lines' frequencies split in
        ``workers`` runs of neighbours, each warm-started in itself), [-]
    scheduler : str or Client
        A Dask scheduler ("tcp://host:port", "local", a Client)
    solver : str
        See :func:`hydroline.engine.integrate`
    progress : callable
        ``progress(done, total)``: frequencies done over all curves

    Returns
    -------
    EnvelopeResult
    """
    from .executors import dask_client, run_dask, run_processes, run_serial

    tic = _time.perf_counter()
    if not isinstance(rig, Rig):
        rig = load_rig(rig)
    freqs = default_frequencies(points) if frequencies is None else \
        np.sort(np.asarray(frequencies, dtype=float).ravel())
    if freqs.size == 0 or not np.all(np.isfinite(freqs) & (freqs > 0)):
        raise RigError(f"frequencies: must be > 0 [Hz], got {freqs.tolist()!r}")
    if not 0 < distortion < 1:
        raise RigError(f"distortion: must lie between 0 and 100 % [-], got {distortion!r}")
    hoses = SineRig(rig, "hoses", axis, solver=solver)
    pressures = hoses.port_pressures()
    analytic = analytic_envelope(freqs, **vendor_parameters(hoses), distortion=distortion)
    guesses = analytic["displacement_amplitude_m"]
    options = {"distortion": distortion, "rtol": rtol}
    runner = EnvelopeRunner(rig, axis, pressures, options, solver)
    runner._rigs["hoses"] = hoses
    supplies = ["hoses"] + (["constant"] if constant_supply else [])
    # the lines' runs cost ~20x the constant supply's: they are split among the workers,
    # the constant supply's frequencies run as one share
    shares = max(1, workers) if scheduler is None else max(2, workers)
    tasks = []
    for s in supplies:
        n = min(shares if s == "hoses" else 1, len(freqs))
        for c in np.array_split(np.arange(len(freqs)), n):
            tasks.append((len(tasks), {"supply": s, "frequencies": freqs[c].tolist(),
                                       "guesses": [guesses[j] for j in c]}))
    rows, total = {}, len(freqs) * len(supplies)
    done = {"finished": 0, "share": 0}

    def record(row):
        rows[row["index"]] = row
        done["finished"] += len(tasks[row["index"]][1]["frequencies"])
        done["share"] = 0
        if progress is not None:
            progress(done["finished"], total)

    def failed(index, values, reason):
        return {"index": index, "supply": values["supply"], "points": [], "error": reason}

    if scheduler is not None:
        client, cluster, owned = dask_client(scheduler, max(workers, 1))
        try:
            run_dask(tasks, client, runner, record, failed)
        finally:
            if owned:
                client.close()
                if cluster is not None:
                    cluster.close()
    elif workers > 1 and len(tasks) > 1:
        run_processes(tasks, min(workers, len(tasks)), runner, record, failed)
    else:
        if progress is not None:
            def step(k):
                progress(done["finished"] + k, total)
            runner.progress = step
        run_serial(tasks, runner, record)
    curves = {s: [] for s in supplies}
    errors = []
    for i in sorted(rows):
        curves[rows[i]["supply"]] += rows[i]["points"]
        if rows[i]["error"]:
            errors.append(f"{rows[i]['supply']}: {rows[i]['error']}")
    return EnvelopeResult(freqs.tolist(), curves["hoses"], curves.get("constant", []), analytic,
                          rig.source, axis or hoses.driven[0], distortion,
                          _time.perf_counter() - tic, errors)
