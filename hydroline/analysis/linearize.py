"""Linear models of the test system about an operating point (for control design).

:func:`linearize` returns the Jacobian linearisation of the compiled network (docs/model.md 6)
as a python-control ``StateSpace`` with named states (``supply.section2.mode3.flow``),
inputs and outputs.

Operating point
---------------
The open-loop system has no isolated rest state at mid-stroke: the piston position is a pure
integrator, and with the valve at its null the load (gravity, ``m_p g`` in (M23)) makes the
piston sag until it rests on its bottom stop -- which is where the default open-loop steady
state puts it. A mid-stroke linearisation therefore fixes the piston position and solves for
the **holding current**: the valve current at which the piston is at rest at that position
under the given load (the chamber pressures then carry the load, ``A_b p_b - A_t p_t = m_p g
+ F_ext``). That is exactly the state a position controller holds the piston in (its output
is the holding current), so the linear model is the plant a controller designer needs, and it
is an equilibrium of the open-loop network with the current held constant.

An operating point may also be a piston in steady motion (``piston_velocity`` != 0): all
states at rest except the position, which moves at the given velocity; the valve current
is solved for so that the piston moves at that speed. The linearisation there is the
local plant along that motion (the position changes the chamber volumes only slowly).
This is the operating point that shows the hoses: with the spool at null an underlapped
valve draws the same supply flow whichever way the spool moves (to first order), so the
supply and return lines hardly couple to the piston; with the piston moving, the valve's
supply and return flows follow the spool and the line dynamics enter the plant.

With ``valve_current`` given instead of a position, the network's own steady state at that
current is used (the piston rests where the load puts it: on a stop, or against a spring).

Friction
--------
The memory-less friction (M24) is regularised near zero velocity (``tanh(v/v_reg)``), so its
slope there is ``F_v + F_s/v_reg`` -- a numerical artefact of the regularisation that would
weld the piston to the frame in a linear model (about 9e5 N s/m on the default rig). With
``friction="viscous"`` (default) the linear model keeps the friction force of the operating
point and uses the viscous coefficient as its slope (F_v+ moving up, F_v- down, their mean
at rest); Coulomb and static friction act as a dead band that no linear model holds.
``friction="model"`` keeps the literal Jacobian of the friction model.

Inputs
------
``valve_current`` [A], ``external_force`` [N] (the load's applied force, positive down, i.e.
opposing +x, as ``load.applied_force``), ``pump_pressure`` [Pa] (the HPS pressure; with the
ideal supply, the supply-port pressure itself) and ``tank_pressure`` [Pa].

Ideal supply
------------
``supply="constant"`` builds the valve, actuator, friction and load alone, with the supply
and return ports held at the rig's ``supply.pressure`` and ``return.pressure`` by pressure
sources: the "constant supply and return pressure" assumption the 2005 paper warns about.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from .. import components as comp
from ..engine import Network
from ..rigs import Rig, load_rig
from ..engine import SteadyStateError, solve_steady_state
from ..engine.steady_state import pseudo_transient, settle_components
from ..system import build_network

__all__ = ["OperatingPointError", "INPUTS", "DEFAULT_INPUTS", "DEFAULT_OUTPUTS", "OperatingPoint", "SolvedOperatingPoint",
           "solve_operating_point", "linearize", "linear_network", "jacobians", "SUPPLIES"]

#: Inputs of the linear model: name -> (runtime parameter of the network, SI unit, meaning).
INPUTS = {
    "valve_current": ("command.final", "A", "servovalve coil current"),
    "external_force": ("load.applied_force", "N", "external force on the rod, positive down"),
    "pump_pressure": ("supply.pump.pressure", "Pa", "HPS (pump) pressure"),
    "tank_pressure": ("return.tank.pressure", "Pa", "tank pressure"),
}
DEFAULT_INPUTS = ("valve_current", "external_force", "pump_pressure")
DEFAULT_OUTPUTS = ("supply_port_pressure", "return_port_pressure", "bottom_chamber_pressure",
                   "top_chamber_pressure", "piston_position", "piston_velocity")
#: Supply variants: the rig's hoses, HSM and accumulators, or ideal constant port pressures.
SUPPLIES = ("lines", "constant")

_POSITION, _VELOCITY = "actuator.position", "actuator.velocity"


class OperatingPointError(ValueError):
    """An operating point that cannot be reached or held; one line naming the quantity."""


@dataclass
class OperatingPoint:
    """Where to linearise.

    Parameters
    ----------
    piston_position : float   x_p from mid-stroke, up +, [m]; the holding current is solved
                              for. None with ``valve_current`` given
    piston_velocity : float   Steady piston velocity, [m/s] (0: at rest)
    external_force : float    Load's applied force, positive down, [N]; the rig's
                              ``load.applied_force`` when None
    valve_current : float     Fixed valve current, [A]; then ``piston_position`` must be None
                              and the piston rests where the load puts it
    """

    piston_position: float | None = 0.0
    piston_velocity: float = 0.0
    external_force: float | None = None
    valve_current: float | None = None

    def __post_init__(self):
        if self.valve_current is not None and self.piston_position is not None:
            raise ValueError("operating point: give piston_position [m] (the holding current is "
                             "solved for) or valve_current [A] (the piston rests where the load "
                             "puts it), not both")
        if self.valve_current is None and self.piston_position is None:
            raise ValueError("operating point: give piston_position [m] or valve_current [A]")
        if self.valve_current is not None and self.piston_velocity != 0.0:
            raise ValueError("operating point: piston_velocity [m/s] needs piston_position, "
                             "not valve_current")
        for k in ("piston_position", "piston_velocity", "external_force", "valve_current"):
            v = getattr(self, k)
            if v is not None and not np.isfinite(v):
                raise ValueError(f"operating point: {k} must be finite, got {v!r}")


@dataclass
class SolvedOperatingPoint:
    """A solved operating point of a network.

    Attributes
    ----------
    network : Network         The open-loop network (valve current from ``command``)
    x : ndarray               States, [SI]
    p : ndarray               Runtime parameters (``command.final`` = valve current), [SI]
    valve_current : float     [A]
    signals : dict            Every signal at the point, [SI]
    residual : float          max scaled |dx/dt| over the states at rest, [1/s]
    supply : str              "lines" or "constant"
    point : OperatingPoint    What was asked for
    """

    network: Network
    x: np.ndarray
    p: np.ndarray
    valve_current: float
    signals: dict
    residual: float
    supply: str
    point: OperatingPoint = field(default_factory=OperatingPoint)


def linear_network(rig: Rig, supply: str = "lines", valve_current: float = 0.0,
                   position_guess: float | None = None, friction_force: float | None = None) -> Network:
    """The open-loop network used for operating points and linearisation.

    Parameters
    ----------
    rig : Rig
    supply : str              "lines" (the rig's hoses, HSM, accumulators) or "constant" (the
                              valve ports held at ``supply.pressure``/``return.pressure``)
    valve_current : float     Constant valve current, runtime parameter ``command.final``, [A]
    position_guess : float    Piston position for the solver's guess, [m]
    friction_force : float    When given, the friction component is replaced by this constant
                              force (runtime parameter ``friction.final``), [N]

    Returns
    -------
    Network
    """
    if supply not in SUPPLIES:
        raise ValueError(f"supply must be one of {', '.join(SUPPLIES)}; got {supply!r}")
    cmd = comp.StepCommand(name="command", quantity="current", initial=valve_current,
                           final=valve_current, time=0.0, connections={"command": "valve_current"})
    net = build_network(rig, [cmd], position_guess)
    if supply == "lines" and friction_force is None:
        return net
    parts = list(net.components)
    if supply == "constant":
        valve = net.component("servovalve")
        keep = {"servovalve", "actuator", "friction", "load", "command"}
        parts = [c for c in parts if c.name in keep]
        parts += [comp.PressureSource(name="supply.pump", pressure=rig["supply.pressure"],
                                      connections={"pressure": valve.signal("supply_pressure")}),
                  comp.PressureSource(name="return.tank", pressure=rig["return.pressure"],
                                      connections={"pressure": valve.signal("return_pressure")})]
    if friction_force is not None:
        fr = net.component("friction")
        parts = [c for c in parts if c.name != "friction"]
        parts.append(comp.StepCommand(name="friction", quantity="force", initial=friction_force,
                                      final=friction_force, time=0.0,
                                      connections={"command": fr.signal("friction_force")}))
    return Network(parts)


class _HoldingCurrentProblem:
    """The network's rest equations with the piston position fixed and the valve current
    unknown: z = x with the position entry replaced by the current; the position equation
    ``dx_p/dt = v_p`` is replaced by ``v_p = v_0`` (as a relaxation ``di/dt = k (v_0 - v_p)``,
    an integral velocity loop, so the pseudo-transient solver sees stable dynamics)."""

    def __init__(self, network, position, velocity, current_scale, velocity_gain):
        self.model = network.compile()
        names = network.state_names
        self.ip, self.iv = names.index(_POSITION), names.index(_VELOCITY)
        self.jc = [network.parameter_names.index(k) for k in ("command.initial", "command.final")]
        self.position, self.velocity, self.k = position, velocity, velocity_gain
        self.jac_p = ca.Function("jac_p", [self.model.t, self.model.x, self.model.p],
                                 [ca.jacobian(self.model.dx, self.model.p)])
        self.scales = network.state_scales.copy()
        self.scales[self.ip] = current_scale

    def full(self, z, p):
        x = np.array(z, dtype=float)
        x[self.ip] = self.position
        q = np.array(p, dtype=float)
        q[self.jc] = z[self.ip]
        return x, q

    def rhs(self, t, z, p):
        x, q = self.full(z, p)
        f = self.model.rhs(t, x, q)
        f[self.ip] = self.k * (self.velocity - x[self.iv])
        return f

    def jacobian(self, t, z, p):
        x, q = self.full(z, p)
        J = self.model.jacobian(t, x, q)
        Jp = np.asarray(ca.densify(self.jac_p(t, x, q)))
        J[:, self.ip] = Jp[:, self.jc].sum(axis=1)
        J[self.ip, :] = 0.0
        J[self.ip, self.iv] = -self.k
        return J


def _settle(network, x, p, t0=0.0):
    """Let components adopt the solved state (accumulator charge); True if anything changed."""
    return settle_components(network, network.components, x, p, network.signals_at(t0, x, p))


def solve_operating_point(rig: Rig | str | None = None, operating_point: OperatingPoint | None = None,
                          supply: str = "lines", tol: float = 1e-9) -> SolvedOperatingPoint:
    """Solve the network's state at an operating point (see the module docstring).

    Parameters
    ----------
    rig : Rig, str or None          The rig (None: the embedded default)
    operating_point : OperatingPoint  Mid-stroke piston at rest under the rig's load when None
    supply : str                    "lines" or "constant"
    tol : float                     Required scaled residual, [1/s]

    Returns
    -------
    SolvedOperatingPoint
    """
    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    op = operating_point or OperatingPoint()
    if op.external_force is not None:
        rig = rig.copy()
        rig.values["load.applied_force"] = float(op.external_force)
        rig.raw["load.applied_force"] = f"{float(op.external_force)!r} N"
    if op.valve_current is not None:
        net = linear_network(rig, supply, op.valve_current)
        ss = solve_steady_state(net, tol=tol)
        return SolvedOperatingPoint(net, ss.x, ss.p, float(op.valve_current),
                                    net.signals_at(0.0, ss.x, ss.p), ss.residual, supply, op)
    half = rig["actuator.stroke"] / 2
    x0, v0 = float(op.piston_position), float(op.piston_velocity)
    if not abs(x0) < half:
        raise ValueError(f"operating point: piston_position must lie inside the stroke, |x_p| < "
                         f"{half * 1e3:g} mm, got {x0 * 1e3:g} mm (for a piston on its stop give "
                         f"valve_current instead)")
    i_rated = rig["servovalve.rated_current"]
    area = rig.get("actuator.bottom_area", rig.get("actuator.area"))
    # no-load velocity at rated current (M20, M21): scale of the velocity loop below
    v_rated = rig["servovalve.rated_flow"] / area * np.sqrt(
        max(rig["supply.pressure"] - rig["return.pressure"], 1.0) / rig["servovalve.rated_pressure_drop"])
    net = linear_network(rig, supply, 0.0, position_guess=x0)
    # velocity loop of the relaxation: crossover about 10 rad/s (slow against the hydraulics)
    prob = _HoldingCurrentProblem(net, x0, 0.0, i_rated, 10.0 * i_rated / v_rated)
    p = net.parameter_values.copy()
    # 1. at rest: pseudo-transient continuation from the components' guesses
    z = pseudo_transient(prob, 0.0, net.guess(), p, prob.scales, tol)
    # 2. steady motion: Newton continuation in the velocity from rest to v0
    v, step = 0.0, v0
    ix = net.state_names.index("servovalve.spool_position")
    while v != v0:
        prob.velocity = v + step
        # the velocity is known exactly (v_p = v0 is one of the equations); the current and
        # spool move along the no-load flow law, so Newton never crosses friction's kink at 0
        guess = z.copy()
        guess[prob.iv] = v + step
        guess[prob.ip] = z[prob.ip] + i_rated * step / v_rated
        guess[ix] = z[ix] + rig["servovalve.max_opening"] * step / v_rated
        z_new = _newton(prob, guess, p, tol)
        if z_new is not None:
            z, v = z_new, v + step
            step = float(np.clip(2 * step, -abs(v0 - v), abs(v0 - v)))
        elif abs(step) > 1e-4 * abs(v0):
            step /= 2
        else:
            break
    prob.velocity = v
    # 3. components settle (accumulator charge), then solve again
    for _ in range(4):
        x, p = prob.full(z, p)
        changed = _settle(net, x, p)
        z = x.copy()
        z[prob.ip] = p[prob.jc[1]]
        z_new = _newton(prob, z, p, tol)
        z = z if z_new is None else z_new
        if not changed:
            break
    if v == v0:
        z[prob.iv] = v0          # exact (the equation v_p = v0 holds to the solver's tolerance)
    x, p = prob.full(z, p)
    r = prob.rhs(0.0, z, p) / prob.scales
    k = int(np.argmax(np.abs(r)))
    current = float(z[prob.ip])
    if v != v0 and np.all(np.isfinite(z)):
        raise OperatingPointError(
            f"operating point: piston_velocity {v0:g} m/s is out of reach; the steady motion was "
            f"followed up to {v:.4g} m/s (valve current {z[prob.ip] * 1e3:.4g} mA, rated "
            f"+-{i_rated * 1e3:g} mA)")
    if not np.all(np.isfinite(z)) or abs(r[k]) > 1e-6:
        raise SteadyStateError(f"operating point not found: scaled residual {abs(r[k]):.3g} 1/s at "
                               f"'{net.state_names[k]}' (x_p = {x0 * 1e3:g} mm, v_p = {v:g} of {v0:g} m/s)")
    if abs(current) > i_rated:
        raise OperatingPointError(f"operating point: holding the piston at {x0 * 1e3:g} mm, {v0:g} m/s needs "
                         f"{current * 1e3:.3g} mA, beyond the rated +-{i_rated * 1e3:g} mA")
    return SolvedOperatingPoint(net, x, p, current, net.signals_at(0.0, x, p), float(abs(r[k])),
                                supply, op)


def _newton(prob, z, p, tol, max_iter=50):
    """Newton's method with backtracking on the scaled residual; None if it fails."""
    sc = prob.scales
    w = np.asarray(z, dtype=float) / sc
    r = prob.rhs(0.0, w * sc, p) / sc
    norm = np.linalg.norm(r)
    for _ in range(max_iter):
        if np.max(np.abs(r)) < tol:
            return w * sc
        J = prob.jacobian(0.0, w * sc, p) * sc[None, :] / sc[:, None]
        try:
            dw = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError:
            return None
        lam = 1.0
        while lam > 1e-4:
            w_new = w + lam * dw
            r_new = prob.rhs(0.0, w_new * sc, p) / sc
            n_new = np.linalg.norm(r_new)
            if np.isfinite(n_new) and n_new <= (1 - 1e-4 * lam) * norm:
                break
            lam /= 2
        else:
            return None
        w, r, norm = w_new, r_new, n_new
    return w * sc if np.max(np.abs(r)) < tol else None


def jacobians(network: Network, x, p, parameters, signals, t: float = 0.0):
    """Jacobian linearisation of a network at (t, x, p).

    ``dx' = A dx + B dp``, ``dy = C dx + D dp`` for the chosen runtime parameters (inputs) and
    signals or states (outputs).

    Parameters
    ----------
    network : Network
    x : array                States, [SI]
    p : array                Runtime parameters, [SI]
    parameters : list[str]   Runtime parameter names (inputs)
    signals : list[str]      Signal or state names (outputs)
    t : float                Time, [s]

    Returns
    -------
    (A, B, C, D) : ndarrays, SI units
    """
    model = network.compile()
    jp = [network.parameter_names.index(k) for k in parameters]
    rows = []
    for s in signals:
        if s in network.signal_names:
            rows.append(model.y[network.signal_names.index(s)])
        elif s in network.state_names:
            rows.append(model.x[network.state_names.index(s)])
        else:
            raise ValueError(f"unknown output {s!r}: not a signal or state of the network "
                             f"(signals: {', '.join(network.signal_names)})")
    y = ca.vertcat(*rows) if rows else ca.SX(0, 1)
    F = ca.Function("lin", [model.t, model.x, model.p],
                    [ca.jacobian(model.dx, model.x), ca.jacobian(model.dx, model.p),
                     ca.jacobian(y, model.x), ca.jacobian(y, model.p)])
    A, Bp, C, Dp = (np.asarray(ca.densify(m)) for m in F(t, x, p))
    return A, Bp[:, jp], C, Dp[:, jp]


def _friction_slope(rig: Rig, velocity: float) -> float:
    """Viscous slope of (M24) for the direction of motion (mean of up/down at rest), [N s/m]."""
    up, down = rig.get("friction.viscous_up", 0.0), rig.get("friction.viscous_down", 0.0)
    if velocity > 0:
        return up
    if velocity < 0:
        return down
    return 0.5 * (up + down)


def _check_names(inputs, outputs):
    for u in inputs:
        if u not in INPUTS:
            raise ValueError(f"unknown input {u!r} (inputs: {', '.join(INPUTS)})")
    if not inputs or not outputs:
        raise ValueError("give at least one input and one output")


def _linear_parts(rig, solved: SolvedOperatingPoint, inputs, outputs, friction):
    """(network, x, p, A, B, C, D) of the linearisation, friction handled as documented."""
    if friction not in ("viscous", "model"):
        raise ValueError(f"friction must be 'viscous' or 'model'; got {friction!r}")
    params = [INPUTS[u][0] for u in inputs]
    if friction == "model":
        net, x, p = solved.network, solved.x, solved.p
        A, B, C, D = jacobians(net, x, p, params, outputs)
        return net, x, p, A, B, C, D
    sig = solved.signals
    f0 = sig[solved.network.component("friction").signal("friction_force")]
    net = linear_network(rig, solved.supply, solved.valve_current, friction_force=f0)
    x, p = _transfer_state(solved, net)
    A, B, C, D = jacobians(net, x, p, params + ["friction.final"], outputs)
    # chain rule: the friction force follows the velocity with the viscous slope
    slope = _friction_slope(rig, sig["piston_velocity"])
    iv = net.state_names.index(_VELOCITY)
    A[:, iv] += slope * B[:, -1]
    C[:, iv] += slope * D[:, -1]
    return net, x, p, A, B[:, :-1], C, D[:, :-1]


def _transfer_state(solved: SolvedOperatingPoint, net: Network):
    """States and parameters of ``solved`` carried over to ``net`` by name."""
    src = solved.network
    x = np.array([solved.x[src.state_names.index(n)] for n in net.state_names])
    p = net.parameter_values.copy()
    for j, n in enumerate(net.parameter_names):
        if n in src.parameter_names:
            p[j] = solved.p[src.parameter_names.index(n)]
    return x, p


def linearize(rig: Rig | str | None = None, operating_point: OperatingPoint | None = None,
              inputs=DEFAULT_INPUTS, outputs=DEFAULT_OUTPUTS, supply: str = "lines",
              friction: str = "viscous"):
    """Linear state-space model of the test system about an operating point.

    Parameters
    ----------
    rig : Rig, str or None            The rig (None: the embedded default, the 2005 paper's)
    operating_point : OperatingPoint  Default: piston at rest at mid-stroke, holding current
                                      solved for (see the module docstring)
    inputs : sequence of str          Names from :data:`INPUTS` ([A], [N], [Pa])
    outputs : sequence of str         Signal names (e.g. ``piston_velocity`` [m/s]) or states
    supply : str                      "lines" (the rig's hoses) or "constant" (ideal supply
                                      and return pressures at the valve ports)
    friction : str                    "viscous" (default) or "model" (literal Jacobian of M24)

    Returns
    -------
    control.StateSpace
        ``dx' = A dx + B du``, ``dy = C dx + D du`` in SI units, with named states, inputs
        and outputs. Attributes added: ``operating_point`` (the :class:`SolvedOperatingPoint`)
        and ``state_scales`` (typical state magnitudes [SI], to balance A before numerical
        work, e.g. :func:`hydroline.analysis.frequency.state_space_response`).
    """
    import control

    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    inputs, outputs = list(inputs), list(outputs)
    _check_names(inputs, outputs)
    solved = solve_operating_point(rig, operating_point, supply)
    net, x, p, A, B, C, D = _linear_parts(rig, solved, inputs, outputs, friction)
    sys = control.ss(A, B, C, D, states=list(net.state_names), inputs=inputs, outputs=outputs,
                     name=f"hydroline linearised ({supply} supply)")
    sys.operating_point = solved
    sys.state_scales = net.state_scales.copy()
    return sys
