"""The rig's plant as an FMU sees it: inputs, outputs, tunable parameters, the rest state.

The plant is the open-loop test-system network (:func:`hydroline.analysis.linearize.linear_network`:
hoses, HSM, accumulators, check valve, servovalve, actuator, friction, load) with the valve
current, the external force and the pump and tank pressures as runtime parameters, so an
importer can change them between steps without recompiling. Its start state is the rest
state of a scenario (:func:`rest_state`), solved in Python at export.

Tunable parameters: values that do not change the network's structure are bound to CasADi
symbols before the graph is written as C (:func:`symbolic_model`), so they become entries of
the runtime parameter vector ``p`` of the generated code -- exactly, not by interpolation. The
hose bulk moduli are *not* among them: they enter the modal line matrices through the
root-matched frequency and damping corrections (M13-M15), computed numerically at build time.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import casadi as ca
import numpy as np

from ..analysis.linearize import INPUTS as LINEAR_INPUTS
from ..analysis.linearize import linear_network
from ..components import CheckValve, LinearResistance
from ..rigs import Rig, RigError
from ..rigs.parameters import PARAMETERS
from ..scenarios.experiments import SCENARIOS, build_scenario
from ..engine import SteadyStateError, solve_steady_state
from ..system import build_circuit, build_network

__all__ = ["Tunable", "TUNABLES", "INPUTS", "OUTPUTS", "Plant", "rest_state", "symbolic_model"]

#: FMU inputs: name -> (runtime parameter of the plant network, SI unit, description).
#: ``pump_pressure``/``tank_pressure`` only where that side has no pressure profile.
INPUTS = {name: LINEAR_INPUTS[name] for name in
          ("valve_current", "external_force", "pump_pressure", "tank_pressure")}

#: FMU outputs: network signal -> description (units from the signal's port).
OUTPUTS = {
    "supply_port_pressure": "pressure at the servovalve's supply (P) port",
    "return_port_pressure": "pressure at the servovalve's return (T) port",
    "bottom_chamber_pressure": "actuator bottom chamber pressure p_b (M22)",
    "top_chamber_pressure": "actuator top chamber pressure p_t (M22)",
    "piston_position": "piston position from mid-stroke, up + (M23)",
    "piston_velocity": "piston velocity, up + (M23)",
}


@dataclass(frozen=True)
class Tunable:
    """A rig parameter exposed as a tunable FMU parameter.

    Attributes
    ----------
    name : str
        Rig path, also the FMU variable name
    unit : str
        SI unit
    description : str
        What it is (the rig parameter's description).
    """

    name: str
    unit: str
    description: str


TUNABLES = (
    Tunable("actuator.bulk_modulus", "Pa", "bulk modulus of the oil in the actuator chambers (M22)"),
    Tunable("load.mass", "kg", "load mass rigidly on the rod, added to actuator.moving_mass (M23)"),
    Tunable("load.stiffness", "N/m", "specimen stiffness (load force k (x - x_free))"),
    Tunable("load.damping", "N.s/m", "specimen damping (load force b v)"),
    Tunable("friction.viscous_up", "N.s/m", "viscous friction F_v, moving up (M24)"),
    Tunable("friction.viscous_down", "N.s/m", "viscous friction F_v, moving down (M24)"),
    Tunable("friction.coulomb_up", "N", "Coulomb friction F_c, moving up (M24)"),
    Tunable("friction.coulomb_down", "N", "Coulomb friction F_c, moving down (M24)"),
    Tunable("friction.static_up", "N", "static friction F_s, moving up (M24)"),
    Tunable("friction.static_down", "N", "static friction F_s, moving down (M24)"),
    Tunable("supply.manifold.resistance", "Pa.s/m3", "HSM supply manifold loss R (M1)"),
    Tunable("return.manifold.resistance", "Pa.s/m3", "HSM return manifold loss R (M1)"),
    Tunable("return.check_valve.forward_resistance", "Pa.s/m3",
            "check valve resistance in its free direction"),
)


@dataclass
class Plant:
    """The plant network at its rest state.

    Attributes
    ----------
    network : Network
        Open-loop network; inputs are its runtime parameters
    x : ndarray
        Rest state, [SI]
    p : ndarray
        Runtime parameters at rest (inputs included), [SI]
    inputs : dict
        FMU input name -> index in p
    tunables : list
        The :class:`Tunable` entries, with their values in ``tunable_values``
    tunable_values : ndarray
        Values of the tunables, [SI]
    start : str
        Scenario whose rest state this is
    residual : float
        Scaled residual ``max |dz/dt|`` at the rest state, [1/s]
    rig : Rig
        The rig the plant was built from.
    """

    network: object
    x: np.ndarray
    p: np.ndarray
    inputs: dict
    tunables: list
    tunable_values: np.ndarray
    start: str
    residual: float
    rig: Rig


#: Why a rig is refused for export: what an FMU's interface holds.
SINGLE_AXIS_ONLY = ("only a single-axis plant (one servovalve driven by 'valve_current', one "
                    "'actuator') can be exported as an FMU")


def rest_state(rig: Rig, start: str = "open-loop-step") -> Plant:
    """The plant of a rig at the rest state of a scenario, before its disturbance.

    ``"open-loop-step"``: the valve current before the step (the scenario's
    ``initial_current``, 0 by default), the piston where the load puts it (on its bottom stop
    for the default rig). ``"closed-loop-sine"``: the piston held by the rig's position
    controller at the scenario's start; the controller's current there becomes the valve
    current input's start value, so a controller built around the FMU starts at rest.

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    start : str
        A scenario name (:data:`hydroline.scenarios.SCENARIOS`)

    Returns
    -------
    Plant
        The open-loop network at its rest state, with its inputs and tunables.
    """
    if start not in SCENARIOS:
        raise ValueError(f"start: unknown scenario {start!r} (known: {', '.join(SCENARIOS)})")
    axes = build_circuit(rig).axes   # said first: no scenario of a multi-axis rig would do
    if len(axes) > 1:
        raise RigError(f"rig {rig.source}: {len(axes)} servo axes ({', '.join(axes)}): "
                       f"{SINGLE_AXIS_ONLY}")
    sc = build_scenario(rig, start)
    full = build_network(rig, sc.commands, sc.position_guess)
    if "valve_current" not in full.signal_names or "actuator" not in {c.name for c in full.components}:
        raise RigError(f"rig {rig.source}: {SINGLE_AXIS_ONLY}")
    ss = solve_steady_state(full, t0=0.0)
    current = full.signals_at(0.0, ss.x, ss.p)["valve_current"]
    net = linear_network(rig, "lines", valve_current=current, position_guess=sc.position_guess)
    x = np.array([ss.x[full.state_names.index(s)] for s in net.state_names])
    p = net.parameter_values.copy()
    for k, name in enumerate(net.parameter_names):
        if name in full.parameter_names and not name.startswith("command."):
            p[k] = ss.p[full.parameter_names.index(name)]
    r = net.compile().rhs(0.0, x, p) / net.state_scales
    k = int(np.argmax(np.abs(r)))
    if not abs(r[k]) < 1e-6:
        raise SteadyStateError(f"the plant is not at rest at the {start} start: scaled residual "
                               f"{abs(r[k]):.3g} 1/s at '{net.state_names[k]}'")
    inputs = {}
    for name, (param, _, _) in INPUTS.items():
        if param in net.parameter_names and not _has_profile(rig, name):
            inputs[name] = net.parameter_names.index(param)
    tun = [t for t in TUNABLES if _tunable_present(net, t.name)]
    values = np.array([rig.get(t.name, 0.0) for t in tun], dtype=float)
    return Plant(net, x, p, inputs, tun, values, start, float(abs(r[k])), rig)


def _has_profile(rig, input_name):
    side = {"pump_pressure": "supply", "tank_pressure": "return"}.get(input_name)
    return side is not None and rig.get(f"{side}.pressure_profile.type") is not None


def _tunable_present(net, name):
    names = {c.name for c in net.components}
    if name == "return.check_valve.forward_resistance":
        return "return.check_valve" in names or isinstance(_component(net, "return.manifold"), CheckValve)
    return name.rpartition(".")[0] in names or name.startswith("load.")


def _component(net, name):
    try:
        return net.component(name)
    except KeyError:
        return None


def _bind(plant: Plant, sym, component, number) -> None:
    """Set the components' attributes to expressions of the tunable symbols.

    ``component(name)`` gives the object whose attributes are set (a copy of the component
    holding symbols for its numbers, :meth:`~hydroline.engine.Component.with_numbers`);
    ``number(name, value)`` stands for a rig value that enters the equations without being
    tunable (a symbol of the compiled model's numbers, or the value itself)."""
    rig = plant.rig
    s = {t.name: sym[k] for k, t in enumerate(plant.tunables)}
    act = component("actuator")
    if "actuator.bulk_modulus" in s:
        act.bulk_modulus = s["actuator.bulk_modulus"]
    if "load.mass" in s:
        rig_mass = number("load.mass", rig.get("load.mass", PARAMETERS["load.mass"].default))
        mass = act.moving_mass - rig_mass + s["load.mass"]
        act.moving_mass = mass
        act.stop_damping = 2.0 * ca.sqrt(act.stop_stiffness * mass)   # as Actuator derives it
    load = component("load")
    for k in ("stiffness", "damping"):
        if f"load.{k}" in s:
            setattr(load, k, s[f"load.{k}"])
    fr = component("friction")
    for k in ("viscous_up", "viscous_down", "coulomb_up", "coulomb_down", "static_up", "static_down"):
        if f"friction.{k}" in s:
            setattr(fr, k, s[f"friction.{k}"])
    if "supply.manifold.resistance" in s:
        component("supply.manifold").resistance = s["supply.manifold.resistance"]
    path_hsm, path_cv = "return.manifold.resistance", "return.check_valve.forward_resistance"
    r_hsm = s[path_hsm] if path_hsm in s else number(path_hsm, rig.get(path_hsm))
    r_cv = (s[path_cv] if path_cv in s
            else number(path_cv, rig.get(path_cv, PARAMETERS[path_cv].default)))
    manifold = component("return.manifold")
    if isinstance(manifold, LinearResistance):
        manifold.resistance = r_hsm
        component("return.check_valve").forward_resistance = r_cv
    else:   # section II removed: manifold loss and check valve are one check valve (rigs/template.py)
        manifold.forward_resistance = r_hsm + r_cv


def symbolic_model(plant: Plant):
    """The plant's CasADi graph with the tunable parameters appended to ``p``.

    Returns an object with the attributes :func:`hydroline.compiled.codegen.generate` reads
    (``network`` with ``state_names``, ``state_scales``, ``parameter_names`` and
    ``compiled_numbers``; ``t``, ``x``, ``p``, ``dx``, ``y``; ``k``, ``dx_general``,
    ``y_general``). The runtime parameter vector is then ``[network parameters...,
    tunable values...]``.

    Numbers are parameters: where the plant network's graph takes the components' numbers as
    symbols (:class:`~hydroline.engine.CompiledModel`), so does this one (``k``: those
    numbers, then the rig values the tunables' binding reads), and its C code depends on the
    plant's structure only -- a rig that differs only in numbers exports the same binary,
    with other numbers in its resources. Otherwise ``k`` is None and the numbers are the
    graph's constants.

    Parameters
    ----------
    plant : Plant
        The plant to export (network, inputs, outputs, tunable parameters)

    Returns
    -------
    object
        The symbolic model (CasADi SX expressions and the network's names and scales)
    """
    net = plant.network
    n, m, k = len(net.state_names), len(net.parameter_names), len(plant.tunables)
    t = ca.SX.sym("t")
    x = ca.SX.sym("x", n)
    p = ca.SX.sym("p", m + k)
    names, values = net.compiled_numbers()
    general = net.compile().k is not None
    extra_names, extra_values = [], []
    if general:
        numbers = ca.SX.sym("k", len(values))
        views, pos = {}, 0
        for c in net.components:
            symbols = {}
            for name, v in c.compiled_numbers().items():
                if isinstance(v, (tuple, list)):
                    symbols[name] = type(v)(numbers[pos + i] for i in range(len(v)))
                    pos += len(v)
                else:
                    symbols[name] = numbers[pos]
                    pos += 1
            views[c.name] = c.with_numbers(symbols)
        extra = []

        def number(name, value):
            extra.append(ca.SX.sym(name))
            extra_names.append(f"fmu.{name}")
            extra_values.append(float(value))
            return extra[-1]
    else:
        views = {c.name: c.with_numbers({}) for c in net.components}

        def number(name, value):
            return value
    _bind(plant, [p[m + j] for j in range(k)], views.__getitem__, number)
    dx, sig = net.evaluate(t, [x[i] for i in range(n)], [p[i] for i in range(m)], views)
    dx = ca.vertcat(*[v if isinstance(v, ca.SX) else ca.SX(v) for v in dx])
    y = ca.vertcat(*[sig[s] if isinstance(sig[s], ca.SX) else ca.SX(sig[s]) for s in net.signal_names])
    both = ca.vertcat(dx, y)
    for j, tun in enumerate(plant.tunables):
        if not ca.depends_on(both, p[m + j]):
            raise RigError(f"{tun.name}: does not enter the plant's equations (cannot be tuned)")
    all_names = list(names) + extra_names
    all_values = np.concatenate([values, np.array(extra_values, dtype=float)])
    shim = SimpleNamespace(state_names=list(net.state_names), state_scales=net.state_scales,
                           parameter_names=(list(net.parameter_names)
                                            + [t.name for t in plant.tunables]),
                           compiled_numbers=lambda: (all_names, all_values))
    if not general:
        return SimpleNamespace(network=shim, t=t, x=x, p=p, dx=dx, y=y, k=None,
                               dx_general=None, y_general=None)
    kk = ca.vertcat(numbers, *extra)
    dx_n, y_n = ca.substitute([dx, y], [kk], [ca.DM(all_values)])
    return SimpleNamespace(network=shim, t=t, x=x, p=p, dx=dx_n, y=y_n, k=kk, dx_general=dx,
                           y_general=y, number_equations=None)   # not cut open: no copies
