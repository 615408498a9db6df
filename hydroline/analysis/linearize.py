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
from ..engine import Network, SteadyStateError, solve_steady_state
from ..engine.steady_state import pseudo_transient, settle_components
from ..rigs import Rig, RigError, load_rig
from ..scenarios.experiments import hold_other_axes
from ..system import build_circuit

__all__ = ["balancing_scales", "OperatingPointError", "INPUTS", "DEFAULT_INPUTS", "DEFAULT_OUTPUTS", "OperatingPoint", "SolvedOperatingPoint",
           "solve_operating_point", "linearize", "linear_network", "jacobians", "SUPPLIES",
           "AXIS_SIGNALS", "VALVE_COMMAND", "select_axis", "axis_network", "axis_signal", "input_parameter", "check_names",
           "transfer_state", "friction_slope", "LinearModel", "linear_model"]

#: Name of the command component that drives the analysed axis's valve current (its runtime
#: parameters ``command.initial``/``command.final`` are the current, [A]).
VALVE_COMMAND = "command"

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

#: Generic channel names -> the :class:`hydroline.circuit.Axis` handle that names the signal on
#: any axis (``piston_velocity`` is ``axis2.piston_velocity`` on axis 2 of ``two_axis``).
AXIS_SIGNALS = {"supply_port_pressure": "supply_pressure", "return_port_pressure": "return_pressure",
                "bottom_chamber_pressure": "bottom_pressure", "top_chamber_pressure": "top_pressure",
                "piston_position": "position", "piston_velocity": "velocity",
                "valve_current": "current"}


def select_axis(rig: Rig, axis: str | None = None, circuit=None):
    """The handles of one servo axis of a rig (the first when ``axis`` is None).

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    axis : str
        Axis name (``hydroline circuit RIG`` lists them)
    circuit : hydroline.circuit.Circuit
        The rig's circuit where it is built already (None: built here,
        :func:`hydroline.system.build_circuit`)

    Returns
    -------
    hydroline.circuit.Axis
        The signal and component names of the axis.

    Raises
    ------
    ValueError
        one line naming the axis and the rig's axes
    """
    axes = (build_circuit(rig) if circuit is None else circuit).axes
    if not axes:
        raise ValueError(f"rig {rig.source}: no servo axis (an actuator driven by a servovalve)")
    if axis is None:
        return next(iter(axes.values()))
    if axis not in axes:
        raise ValueError(f"--axis: no axis {axis!r} in rig {rig.source} (axes: {', '.join(axes)})")
    return axes[axis]


def axis_signal(axis, name: str) -> str:
    """The network signal of a channel on an axis.

    Generic names (:data:`AXIS_SIGNALS`, e.g. ``piston_velocity``) go through the axis's
    handles, any other name is returned as given.

    Parameters
    ----------
    axis : hydroline.circuit.Axis
        The axis handles.
    name : str
        Channel name.

    Returns
    -------
    str
        The signal's name in the network.
    """
    return getattr(axis, AXIS_SIGNALS[name]) if name in AXIS_SIGNALS else name


def input_parameter(network: Network, axis, name: str) -> str:
    """The runtime parameter of ``network`` that is the input ``name`` (:data:`INPUTS`) of an
    axis: the valve current of its command, the applied force of the load on its piston, the
    pressure of the source of ``pump_pressure``/``tank_pressure``.

    Parameters
    ----------
    network : Network
        A network of :func:`linear_network`
    axis : hydroline.circuit.Axis
        The axis
    name : str
        Input name

    Returns
    -------
    str
        Runtime parameter name
    """
    if name == "valve_current":
        return f"{VALVE_COMMAND}.final"
    if name == "external_force":
        act = network.component(axis.actuator)
        for c in network.components:
            if isinstance(c, comp.Load) and c.signal("load_force") == act.signal("load_force"):
                return f"{c.name}.applied_force"
    if name in ("pump_pressure", "tank_pressure"):
        # the rig's source of that signal, or the ideal source that replaces the supply (or
        # return) at the valve port in the constant-supply variant (:func:`linear_network`)
        stand_in = {"pump_pressure": "supply.pump", "tank_pressure": "return.tank"}[name]
        for c in network.components:
            if isinstance(c, comp.PressureSource) and c.signal("pressure") == name:
                return f"{c.name}.pressure"
        for c in network.components:
            if isinstance(c, comp.PressureSource) and c.name == stand_in:
                return f"{c.name}.pressure"
    raise ValueError(f"input {name!r}: no such input on axis '{axis.name}' of this rig "
                     f"(inputs: {', '.join(INPUTS)})")



class OperatingPointError(ValueError):
    """An operating point that cannot be reached or held; one line naming the quantity.

    Parameters
    ----------
    *args : str
        The message: one line naming the quantity.
    **kwargs : dict
        None taken (as ``ValueError``).
    """


@dataclass
class OperatingPoint:
    """Where to linearise.

    Parameters
    ----------
    piston_position : float
        x_p from mid-stroke, up +, [m]; the holding current is solved
        for. None with ``valve_current`` given
    piston_velocity : float
        Steady piston velocity, [m/s] (0: at rest)
    external_force : float
        Load's applied force, positive down, [N]; the rig's
        ``load.applied_force`` when None
    valve_current : float
        Fixed valve current, [A]; then ``piston_position`` must be None
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
    network : Network
        The open-loop network (valve current from ``command``)
    x : ndarray
        States, [SI]
    p : ndarray
        Runtime parameters (``command.final`` = valve current), [SI]
    valve_current : float
        The valve current of the point, [A]
    signals : dict
        Every signal at the point, [SI]
    residual : float
        Largest scaled ``|dx/dt|`` over the states at rest, [1/s]
    supply : str
        "lines" or "constant"
    point : OperatingPoint
        What was asked for
    axis : hydroline.circuit.Axis
        The axis linearised (its handles name the signals)
    """

    network: Network
    x: np.ndarray
    p: np.ndarray
    valve_current: float
    signals: dict
    residual: float
    supply: str
    point: OperatingPoint = field(default_factory=OperatingPoint)
    axis: object = None


def axis_network(rig: Rig, commands: list, axis: str | None = None,
                 position_guess: float | None = None) -> Network:
    """The rig's network with one axis driven open loop by ``commands`` (its valve current):
    that axis's position controller, if the circuit has one, is left out; every other axis
    holds (:func:`hydroline.scenarios.hold_other_axes`).

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    commands : list
        Components driving the axis's valve current signal
        (``select_axis(rig, axis).current``)
    axis : str
        The axis (None: the first)
    position_guess : float
        Its piston position for the steady-state solver's guess, [m]

    Returns
    -------
    Network
        The axis's network with the given commands.
    """
    circuit = build_circuit(rig)
    ax = select_axis(rig, axis, circuit)
    if ax.name == next(iter(circuit.axes)):   # (the guess places the first axis)
        if position_guess is not None:
            circuit = build_circuit(rig, position_guess)
    else:
        try:
            circuit.place(position_guess, ax.name)
        except ValueError as e:
            raise RigError(str(e)) from None
    circuit.components = [c for c in circuit.components if c.name != ax.controller]
    return circuit.network(list(commands) + hold_other_axes(rig, circuit.axes, ax.name))


def linear_network(rig: Rig, supply: str = "lines", valve_current: float = 0.0,
                   position_guess: float | None = None, friction_force: float | None = None,
                   axis: str | None = None) -> Network:
    """The open-loop network used for operating points and linearisation.

    Parameters
    ----------
    rig : Rig
        Parameters (SI).
    supply : str
        "lines" (the rig's hoses, HSM, accumulators) or "constant" (the
        valve ports held at ``supply.pressure``/``return.pressure``)
    valve_current : float
        Constant valve current, runtime parameter ``command.final``, [A]
    position_guess : float
        Piston position for the solver's guess, [m]
    friction_force : float
        When given, the axis's friction component is replaced by this
        constant force (runtime parameter ``<friction>.final``), [N]
    axis : str
        The axis driven by the valve current (None: the first); its
        position controller is left out, every other axis holds
        (:func:`hydroline.scenarios.hold_other_axes`)

    Returns
    -------
    Network
        The open-loop network, valve current from the ``command`` component.
    """
    if supply not in SUPPLIES:
        raise ValueError(f"supply must be one of {', '.join(SUPPLIES)}; got {supply!r}")
    ax = select_axis(rig, axis)
    cmd = comp.StepCommand(name=VALVE_COMMAND, quantity="current", initial=valve_current,
                           final=valve_current, time=0.0, connections={"command": ax.current})
    net = axis_network(rig, [cmd], ax.name, position_guess)
    if supply == "lines" and friction_force is None:
        return net
    parts = list(net.components)
    if supply == "constant":
        valve, act = net.component(ax.valve), net.component(ax.actuator)
        if rig.get("supply.pressure") is not None and rig.get("return.pressure") is not None:
            p_supply, p_return = rig["supply.pressure"], rig["return.pressure"]
        else:   # a circuit: the valve's port pressures at rest with the valve closed
            ss = solve_steady_state(net)
            sig = net.signals_at(0.0, ss.x, ss.p)
            p_supply, p_return = sig[ax.supply_pressure], sig[ax.return_pressure]
        on_piston = {act.signal(k) for k in ("position", "velocity", "load_force", "friction_force")}
        keep = {ax.valve, ax.actuator, VALVE_COMMAND} | {
            c.name for c in parts if isinstance(c, (comp.Load, comp.StribeckFriction))
            and set(c.outputs) and any(c.signal(k) in on_piston for k in c.outputs)}
        parts = [c for c in parts if c.name in keep]
        parts += [comp.PressureSource(name="supply.pump", pressure=p_supply,
                                      connections={"pressure": valve.signal("supply_pressure")}),
                  comp.PressureSource(name="return.tank", pressure=p_return,
                                      connections={"pressure": valve.signal("return_pressure")})]
    if friction_force is not None:
        fr = net.component(ax.friction)
        parts = [c for c in parts if c.name != ax.friction]
        parts.append(comp.StepCommand(name=ax.friction, quantity="force", initial=friction_force,
                                      final=friction_force, time=0.0,
                                      connections={"command": fr.signal("friction_force")}))
    return Network(parts)


class _HoldingCurrentProblem:
    """The network's rest equations with the piston position fixed and the valve current
    unknown: z = x with the position entry replaced by the current; the position equation
    ``dx_p/dt = v_p`` is replaced by ``v_p = v_0`` (as a relaxation ``di/dt = k (v_0 - v_p)``,
    an integral velocity loop, so the pseudo-transient solver sees stable dynamics)."""

    def __init__(self, network, position, velocity, current_scale, velocity_gain, actuator):
        self.model = network.compile()
        names = network.state_names
        self.ip, self.iv = names.index(f"{actuator}.position"), names.index(f"{actuator}.velocity")
        self.jc = [network.parameter_names.index(f"{VALVE_COMMAND}.{k}") for k in ("initial", "final")]
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
                          supply: str = "lines", tol: float = 1e-9,
                          axis: str | None = None) -> SolvedOperatingPoint:
    """Solve the network's state at an operating point (see the module docstring).

    Parameters
    ----------
    rig : Rig, str or None
        The rig (None: the embedded default)
    operating_point : OperatingPoint
        Mid-stroke piston at rest under the rig's load when None
    supply : str
        "lines" or "constant"
    tol : float
        Required scaled residual, [1/s]
    axis : str
        The axis (None: the first); the others hold

    Returns
    -------
    SolvedOperatingPoint
        The steady state, valve current and signals at the point.
    """
    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    op = operating_point or OperatingPoint()
    ax = select_axis(rig, axis)
    if op.valve_current is None:
        half = ax.stroke / 2
        x0, v0 = float(op.piston_position), float(op.piston_velocity)
        if not abs(x0) < half:
            raise ValueError(f"operating point: piston_position must lie inside the stroke, |x_p| < "
                             f"{half * 1e3:g} mm, got {x0 * 1e3:g} mm (for a piston on its stop give "
                             f"valve_current instead)")
    net = linear_network(rig, supply, 0.0 if op.valve_current is None else op.valve_current,
                         position_guess=op.piston_position, axis=ax.name)
    if op.external_force is not None:   # the load's applied force, a runtime parameter
        name = input_parameter(net, ax, "external_force")
        net.component(name.rsplit(".", 1)[0]).applied_force = float(op.external_force)
        net.parameter_values[net.parameter_names.index(name)] = float(op.external_force)
    p = net.parameter_values.copy()
    if op.valve_current is not None:
        ss = solve_steady_state(net, tol=tol)
        return SolvedOperatingPoint(net, ss.x, ss.p, float(op.valve_current),
                                    net.signals_at(0.0, ss.x, ss.p), ss.residual, supply, op, ax)
    valve, act = net.component(ax.valve), net.component(ax.actuator)
    i_rated = valve.rated_current
    area = act.bottom_area
    # no-load velocity at rated current (M20, M21): scale of the velocity loop below (the
    # template's supply-to-return difference, else the valve's rated drop)
    dp = rig.get("supply.pressure", valve.rated_pressure_drop) - rig.get("return.pressure", 0.0)
    v_rated = valve.rated_flow / area * np.sqrt(max(dp, 1.0) / valve.rated_pressure_drop)
    # velocity loop of the relaxation: crossover about 10 rad/s (slow against the hydraulics)
    prob = _HoldingCurrentProblem(net, x0, 0.0, i_rated, 10.0 * i_rated / v_rated, ax.actuator)
    # 1. at rest: pseudo-transient continuation from the components' guesses
    z = pseudo_transient(prob, 0.0, net.guess(), p, prob.scales, tol)
    # 2. steady motion: Newton continuation in the velocity from rest to v0
    v, step = 0.0, v0
    ix = net.state_names.index(f"{ax.valve}.spool_position")
    while v != v0:
        prob.velocity = v + step
        # the velocity is known exactly (v_p = v0 is one of the equations); the current and
        # spool move along the no-load flow law, so Newton never crosses friction's kink at 0
        guess = z.copy()
        guess[prob.iv] = v + step
        guess[prob.ip] = z[prob.ip] + i_rated * step / v_rated
        guess[ix] = z[ix] + valve.max_opening * step / v_rated
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
                                supply, op, ax)


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
        The network to linearise.
    x : array
        States, [SI]
    p : array
        Runtime parameters, [SI]
    parameters : list[str]
        Runtime parameter names (inputs)
    signals : list[str]
        Signal or state names (outputs)
    t : float
        Time, [s]

    Returns
    -------
    A, B, C, D : ndarray
        The state-space matrices, [SI]
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


def friction_slope(friction, velocity: float) -> float:
    """Viscous slope of (M24) for the direction of motion (mean of up/down at rest), [N s/m].

    Parameters
    ----------
    friction : StribeckFriction or None
        The axis's friction component (None: no friction)
    velocity : float
        Piston velocity, [m/s]

    Returns
    -------
    float
        The viscous coefficient, [N s/m]
    """
    if friction is None:
        return 0.0
    up, down = friction.viscous_up, friction.viscous_down
    if velocity > 0:
        return up
    if velocity < 0:
        return down
    return 0.5 * (up + down)


def check_names(inputs, outputs):
    """Refuse an unknown input (:data:`INPUTS`) or an empty channel list (ValueError, one line).

    Parameters
    ----------
    inputs : sequence of str
        Input names
    outputs : sequence of str
        Output names
    """
    for u in inputs:
        if u not in INPUTS:
            raise ValueError(f"unknown input {u!r} (inputs: {', '.join(INPUTS)})")
    if not inputs or not outputs:
        raise ValueError("give at least one input and one output")


def _linear_parts(rig, solved: SolvedOperatingPoint, inputs, outputs, friction):
    """(network, x, p, A, B, C, D) of the linearisation, friction handled as documented."""
    if friction not in ("viscous", "model"):
        raise ValueError(f"friction must be 'viscous' or 'model'; got {friction!r}")
    ax = solved.axis
    signals = [axis_signal(ax, y) for y in outputs]
    if friction == "model" or ax.friction is None:
        net, x, p = solved.network, solved.x, solved.p
        params = [input_parameter(net, ax, u) for u in inputs]
        A, B, C, D = jacobians(net, x, p, params, signals)
        return net, x, p, A, B, C, D
    sig = solved.signals
    fr = solved.network.component(ax.friction)
    net = linear_network(rig, solved.supply, solved.valve_current,
                         friction_force=sig[fr.signal("friction_force")], axis=ax.name)
    x, p = transfer_state(solved, net)
    params = [input_parameter(net, ax, u) for u in inputs]
    A, B, C, D = jacobians(net, x, p, params + [f"{ax.friction}.final"], signals)
    # chain rule: the friction force follows the velocity with the viscous slope
    slope = friction_slope(fr, sig[ax.velocity])
    iv = net.state_names.index(f"{ax.actuator}.velocity")
    A[:, iv] += slope * B[:, -1]
    C[:, iv] += slope * D[:, -1]
    return net, x, p, A, B[:, :-1], C, D[:, :-1]


def transfer_state(solved: SolvedOperatingPoint, net: Network):
    """States and runtime parameters of a solved operating point carried over, by name, to
    another network of the same rig (one with a component replaced or cut out).

    Parameters
    ----------
    solved : SolvedOperatingPoint
        The solved point
    net : Network
        The other network; its states must all be in the
        solved network

    Returns
    -------
    (x, p) : ndarrays
        States and runtime parameters of ``net``, [SI]
    """
    src = solved.network
    x = np.array([solved.x[src.state_names.index(n)] for n in net.state_names])
    p = net.parameter_values.copy()
    for j, n in enumerate(net.parameter_names):
        if n in src.parameter_names:
            p[j] = solved.p[src.parameter_names.index(n)]
    return x, p


@dataclass
class LinearModel:
    """A linear state-space model with named states, inputs and outputs, as
    :func:`linear_model` gives it (:func:`linearize` makes a python-control ``StateSpace`` of
    it): ``dx' = A dx + B du``, ``dy = C dx + D du`` in SI units.

    Attributes
    ----------
    A, B, C, D : ndarray
        The matrices, [SI].
    state_labels, input_labels, output_labels : list
        Names of the states, inputs and outputs.
    operating_point : SolvedOperatingPoint
        Where it is linearised.
    state_scales : ndarray
        Typical state magnitudes, [SI].
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    state_labels: list
    input_labels: list
    output_labels: list
    operating_point: object
    state_scales: np.ndarray

    @property
    def nstates(self) -> int:
        """Number of states, [-]."""
        return self.A.shape[0]


def linear_model(rig: Rig | str | None = None, operating_point: OperatingPoint | None = None,
                 inputs=DEFAULT_INPUTS, outputs=DEFAULT_OUTPUTS, supply: str = "lines",
                 friction: str = "viscous", axis: str | None = None) -> LinearModel:
    """:func:`linearize`'s model as plain arrays (:class:`LinearModel`), without
    python-control (the Bode command's: ~1 s of imports less).

    Parameters
    ----------
    rig, operating_point, inputs, outputs, supply, friction, axis :
        As :func:`linearize`: the rig, where to linearise, the input and output names, the
        supply ("lines" or "constant"), the friction slope, the axis

    Returns
    -------
    LinearModel
    """
    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    inputs, outputs = list(inputs), list(outputs)
    check_names(inputs, outputs)
    solved = solve_operating_point(rig, operating_point, supply, axis=axis)
    net, x, p, A, B, C, D = _linear_parts(rig, solved, inputs, outputs, friction)
    return LinearModel(A, B, C, D, list(net.state_names), inputs, outputs, solved,
                       balancing_scales(net, x))


def balancing_scales(net: Network, x) -> np.ndarray:
    """Typical state magnitudes at an operating point, to balance A before numerical work:
    the network's state scales, or the state's own size where that is larger (a chamber
    pressure with a cavity model has its integrators' scale at 100 ``cavity_pressure_drop``,
    ``fluid.chamber_pressure_scale``, far below the ~10 MPa it holds: balanced on it, the
    eigenvectors of the default rig's A were numerically singular).

    Parameters
    ----------
    net : Network
        The linearised network
    x : ndarray
        Its states at the operating point, [SI]

    Returns
    -------
    ndarray
        Scales, [SI]
    """
    return np.maximum(np.asarray(net.state_scales, dtype=float), np.abs(np.asarray(x, dtype=float)))


def linearize(rig: Rig | str | None = None, operating_point: OperatingPoint | None = None,
              inputs=DEFAULT_INPUTS, outputs=DEFAULT_OUTPUTS, supply: str = "lines",
              friction: str = "viscous", axis: str | None = None):
    """Linear state-space model of the test system about an operating point.

    Parameters
    ----------
    rig : Rig, str or None
        The rig (None: the embedded default, the 2005 paper's)
    operating_point : OperatingPoint
        Default: piston at rest at mid-stroke, holding current
        solved for (see the module docstring)
    inputs : sequence of str
        Names from :data:`INPUTS` ([A], [N], [Pa])
    outputs : sequence of str
        Signal names (e.g. ``piston_velocity`` [m/s]; the generic
        names of :data:`AXIS_SIGNALS` are the axis's) or states
    supply : str
        "lines" (the rig's hoses) or "constant" (ideal supply
        and return pressures at the valve ports)
    friction : str
        "viscous" (default) or "model" (literal Jacobian of M24)
    axis : str
        The axis (None: the first); its valve current is the
        input, its position loop open, the other axes hold

    Returns
    -------
    control.StateSpace
        ``dx' = A dx + B du``, ``dy = C dx + D du`` in SI units, with named states, inputs
        and outputs. Attributes added: ``operating_point`` (the :class:`SolvedOperatingPoint`)
        and ``state_scales`` (typical state magnitudes [SI], to balance A before numerical
        work, e.g. :func:`hydroline.analysis.frequency.state_space_response`).
    """
    import control

    m = linear_model(rig, operating_point, inputs, outputs, supply, friction, axis)
    sys = control.ss(m.A, m.B, m.C, m.D, states=m.state_labels, inputs=m.input_labels,
                     outputs=m.output_labels, name=f"hydroline linearised ({supply} supply)")
    sys.operating_point = m.operating_point
    sys.state_scales = m.state_scales
    return sys
