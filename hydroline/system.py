"""Build the electrohydraulic test system's network from a rig (docs/model.md sections 1, 6).

Signal names (the network's vocabulary; see ``docs`` of each component for its ports):

supply side   pump_pressure -> supply.section1 -> supply.manifold_inlet_pressure ->
              supply.manifold -> supply.manifold_pressure (HSM node, accumulator) ->
              supply.section2 -> supply_port_pressure (valve P port); flows back:
              supply_port_flow, supply.section2_inflow, supply.accumulator_flow,
              supply.manifold_flow, pump_flow.
return side   return_port_flow (valve T port, toward tank) -> return.section2 ->
              return.manifold_pressure (HSM return node, accumulator) -> manifold resistance,
              check valve -> return.section1 -> tank_pressure; pressures back:
              return_port_pressure, return.check_valve_pressure,
              return.section1_inlet_pressure; flows return.section2_outflow,
              return.accumulator_flow, return.manifold_flow, tank_flow.
valve/piston  valve_current, bottom_chamber_flow, top_chamber_flow, bottom_chamber_pressure,
              top_chamber_pressure, piston_position, piston_velocity, friction_force,
              load_force.

The supply hoses use the PQ form (M8). The return hoses are oriented from the valve toward
the tank and use the QP form (inputs: the flow entering at the valve end and the pressure at
the tank end), which is the paper's PQ return line seen from its other end: the same
dynamics with every flow positive toward the tank, so no sign flips at the valve or the HSM.
A section II of zero length is removed: the HSM node is joined to the valve port, and the
manifold block's oil volume (``<side>.manifold.volume``, default 50 cm^3) becomes the node
(without it the manifold resistance and the valve orifices would form an algebraic loop);
its pressure is then the port pressure signal (``supply_port_pressure``/``return_port_pressure``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import components as comp
from .fluid import Fluid
from .lines import DEFAULT_LINE_METHOD, Line, ModalLine
from .circuit import (Circuit, CircuitError, axes_of, check_circuit, circuit_components,
                      has_circuit, rewire)
from .engine import Network
from .rigs import SCHEMA, Rig, RigError, declarations
from .rigs.parameters import check_consistency, check_ranges

__all__ = ["build_network", "build_circuit", "make_fluid", "make_line", "hose_lines",
           "validate_rig", "pressure_profile"]


#: Oil volume of the HSM block's passages, used as the node when a section II is removed, [m^3]
#: ([assumed] 50 cm^3; a rig sets it as ``supply.manifold.volume``).
DEFAULT_NODE_VOLUME = 50e-6


def _section_present(rig: Rig, section: str) -> bool:
    """True for a positive length; False for 0 (section removed); RigError below 0."""
    length = rig.get(f"{section}.length", 0.0)
    if length < 0:
        raise RigError(f"{section}.length: must be >= 0 m (0 removes the section), got {length!r} m")
    return length > 0


def make_fluid(rig: Rig) -> Fluid:
    """The rig's fluid (``[fluid]``: density, kinematic viscosity, bulk modulus).

    Parameters
    ----------
    rig : Rig   Parameters (SI)

    Returns
    -------
    Fluid

    Raises
    ------
    RigError  One line naming the fluid parameter at fault
    """
    try:
        return Fluid(rig["fluid.density"], rig["fluid.kinematic_viscosity"], rig["fluid.bulk_modulus"])
    except ValueError as e:
        raise RigError(f"fluid: {e}") from None


def make_line(rig: Rig, section: str, fluid: Fluid) -> Line:
    """The Line of a hose section, e.g. ``section="supply.section2"``.

    Parameters
    ----------
    rig : Rig        Parameters (SI)
    section : str    Hose section, ``"<side>.section<n>"``
    fluid : Fluid    The fluid in it (the section's own bulk modulus, if set, overrides its
                     effective one)

    Returns
    -------
    Line  Length [m], diameter [m] and fluid of the section

    Raises
    ------
    RigError  One line naming the section's parameter at fault
    """
    length, diameter = rig[f"{section}.length"], rig[f"{section}.diameter"]   # (named in full)
    try:
        return Line(length, diameter, fluid, rig.get(f"{section}.bulk_modulus"))
    except ValueError as e:   # Line names the parameter: "diameter: must be > 0 ..."
        raise RigError(f"{section}.{e}") from None


def hose_lines(rig: Rig) -> dict:
    """All hose sections of the rig with a positive length, name -> Line.

    Parameters
    ----------
    rig : Rig   Parameters (SI)

    Returns
    -------
    dict  ``"supply.section1"``, ... -> :class:`Line`
    """
    fluid = make_fluid(rig)
    out = {}
    for side in ("supply", "return"):
        for sec in ("section1", "section2"):
            name = f"{side}.{sec}"
            if sec == "section2" and not _section_present(rig, name):
                continue
            out[name] = make_line(rig, name, fluid)
    return out


def _modes(rig, section):
    n = rig.get(f"{section}.modes", rig.get("rig.modes_per_section", 6))
    if int(n) != n or n < 1:
        raise RigError(f"{section}.modes: must be an integer >= 1, got {n!r}")
    return int(n)


def _hose(rig, name, line, form, nominal):
    model = ModalLine(line, _modes(rig, name), form,
                      method=rig.get("rig.line_method", DEFAULT_LINE_METHOD))
    return model


def _accumulator(rig, side, fluid, nominal, node_signal):
    key = f"{side}.accumulator"
    conn = Line(rig[f"{key}.connection_length"], rig[f"{key}.connection_diameter"], fluid)
    kind = rig.get(f"{key}.model", "version-II")
    kw = dict(capacity=rig[f"{key}.capacity"], precharge_pressure=rig[f"{key}.precharge_pressure"],
              polytropic_exponent=rig[f"{key}.polytropic_exponent"], nominal_pressure=nominal,
              connections={"pressure": node_signal, "flow": f"{side}.accumulator_flow"})
    if kind == "version-II":
        return comp.PistonAccumulator(name=key, resistance=conn.resistance,
                                      inertance=conn.inertance, **kw)
    if kind == "modal":
        return comp.PistonAccumulator(name=key, connection_model=ModalLine(
            conn, _modes(rig, key), "PP"), **kw)
    raise RigError(f"{key}.model: must be 'version-II' or 'modal', got {kind!r}")


#: Template-rig parameters checked before the network is built that no component declares
#: (the components' own are checked against their declarations, see
#: :func:`hydroline.rigs.declarations`). The value is echoed as written in the file.
_POSITIVE = ("return.pressure", "actuator.area", "actuator.dead_volume",
             "supply.manifold.volume", "return.manifold.volume")


_PROFILE_KEYS = {"step": ("time", "final"), "sine": ("amplitude", "frequency"),
                 "ramp": ("slope", "end"), "table": ("file",)}


def pressure_profile(rig: Rig, side: str):
    """The time-varying source pressure of a side from ``[<side>.pressure_profile]``.

    ``type = "step"``: ``<side>.pressure`` until ``time``, then ``final``;
    ``"sine"``: ``<side>.pressure + amplitude sin(2 pi frequency (t - start))`` from ``start``
    (default 0); ``"ramp"``: ``<side>.pressure + slope (t - start)`` between ``start`` (default
    0) and ``end``, held after; ``"table"``: the absolute pressure from the CSV ``file``
    (header ``time [s], pressure [MPa]``, any units; path relative to the rig file), held
    beyond its ends; its value at t = 0 replaces ``<side>.pressure``.

    Parameters
    ----------
    rig : Rig    Parameters (SI)
    side : str   "supply" or "return"

    Returns
    -------
    tuple  (waveform component or None, level at t = 0 [Pa], (lowest, highest) pressure over
           all time [Pa])
    """
    base = f"{side}.pressure_profile"
    level = rig.get(f"{side}.pressure")
    kind = rig.get(f"{base}.type")
    given = [k for k in rig.values if k.startswith(base + ".") and k != f"{base}.type"]
    if kind is None:
        if given:
            raise RigError(f"{base}.type: must be one of {', '.join(_PROFILE_KEYS)} when "
                           f"{given[0]} is given, got nothing")
        return None, level, (level, level)
    if kind not in _PROFILE_KEYS:
        raise RigError(f"{base}.type: must be one of {', '.join(_PROFILE_KEYS)}, got {kind!r}")
    for k in _PROFILE_KEYS[kind]:
        if f"{base}.{k}" not in rig:
            raise RigError(f"{base}.{k}: required for type = {kind!r} (not set in rig {rig.source})")
    allowed = set(_PROFILE_KEYS[kind]) | ({"start"} if kind in ("sine", "ramp") else set())
    for path in given:
        if path[len(base) + 1:] not in allowed:
            raise RigError(f"{path}: not a parameter of type = {kind!r} (give {', '.join(sorted(allowed))})")
    name = f"{side}.source.waveform"
    if kind != "table" and level is None:
        raise RigError(f"{side}.pressure: not set in rig {rig.source} (the {kind} profile is about it)")
    start = rig.get(f"{base}.start", 0.0)
    if not (np.isfinite(start) and start >= 0):
        raise _bad(rig, f"{base}.start", ">= 0")
    if kind == "step":
        t_step, final = rig[f"{base}.time"], rig[f"{base}.final"]
        if not t_step > 0:
            raise _bad(rig, f"{base}.time", "> 0 (the steady state is solved before the step)")
        w = comp.StepCommand(name=name, quantity="pressure", initial=level, final=final, time=t_step)
        return w, level, (min(level, final), max(level, final))
    if kind == "sine":
        amp, f = rig[f"{base}.amplitude"], rig[f"{base}.frequency"]
        if not f > 0:
            raise _bad(rig, f"{base}.frequency", "> 0")
        w = comp.SineCommand(name=name, quantity="pressure", offset=level, amplitude=amp,
                             frequency=f, start=start)
        return w, level, (level - abs(amp), level + abs(amp))
    if kind == "ramp":
        slope, end = rig[f"{base}.slope"], rig[f"{base}.end"]
        if not end > start:
            raise _bad(rig, f"{base}.end", f"> start ({start:g} s)")
        w = comp.RampCommand(name=name, quantity="pressure", initial=level, slope=slope,
                             start=start, end=end)
        last = level + slope * (end - start)
        return w, level, (min(level, last), max(level, last))
    path = Path(rig[f"{base}.file"])
    if not path.is_absolute() and not rig.source.startswith("embedded:"):
        path = Path(rig.source).parent / path
    try:
        w = comp.TableCommand.from_csv_with_units(path, "Pa", name=name, quantity="pressure")
    except ValueError as e:
        raise RigError(f"{base}.file: {e}") from None
    return w, float(np.interp(0.0, w.times, w.values)), w.value_range()


def _unit(path):
    sec, _, key = path.rpartition(".")
    u = SCHEMA.get(sec, {}).get(key, "")
    return {"-": "", "str": ""}.get(u, u.replace("list:", ""))


def _bad(rig, path, rule, value=None):
    shown = rig.raw.get(path, value if value is not None else rig.get(path))
    unit = _unit(path)
    if unit == "Pa" and path.endswith("pressure"):
        unit = "Pa, absolute"
    return RigError(f"{path}: must be {rule}{' [' + unit + ']' if unit else ''}, got {shown!r}")


def validate_rig(rig: Rig, position_guess: float | None = None) -> dict:
    """Refuse, with a RigError naming the parameter and its unit, values no physical rig has.

    Checked: signs (positive sizes, moduli, masses, pressures absolute > 0, non-negative
    resistances, gains and friction coefficients), ``supply.pressure > return.pressure > 0``
    (docs/model.md 1: the valve needs a supply above the tank), ``|initial_position| <= stroke/2``
    (the piston inside the cylinder, M23), accumulator pre-charges below the pressure of their
    side (an accumulator pre-charged above it holds no oil, M16), laps shorter than the spool stroke (M20) and the
    polytropic exponent within [1, 5/3] (isothermal ... monatomic adiabatic, M16).

    Parameters
    ----------
    rig : Rig               Parameters (SI)
    position_guess : float  Initial piston position given by the scenario, [m]; checked
                            like ``actuator.initial_position`` when not None

    Returns
    -------
    dict  side -> its :func:`pressure_profile` (read once, for the network builder)
    """
    declared = {}       # section -> its declarations, looked up once per section
    for path, v in rig.values.items():
        section, _, key = path.rpartition(".")
        if section not in declared:
            declared[section] = declarations(section)
        decl = declared[section].get(key)
        if decl is not None:
            rule = decl.violation(v)
            if rule is not None:
                raise _bad(rig, path, rule)
    if has_circuit(rig.values):
        check_ranges(rig)      # the rig-wide settings, the oil, the scenarios (the components':
        return {}              # hydroline.circuit.builder, against their declarations)
    for path in _POSITIVE:
        v = rig.get(path)
        if v is not None and not (np.isfinite(v) and v > 0):
            raise _bad(rig, path, "> 0")
    profiles = {side: pressure_profile(rig, side) for side in ("supply", "return")}
    _, p_s, (s_low, _) = profiles["supply"]
    _, p_t, (t_low, t_high) = profiles["return"]
    if p_s is None or p_t is None:
        raise RigError(f"{'supply' if p_s is None else 'return'}.pressure: not set in rig {rig.source}")
    if not (np.isfinite(p_s) and p_s > p_t):
        raise RigError(f"supply.pressure: must be above return.pressure ({rig.raw.get('return.pressure', p_t)!r}) "
                       f"[Pa absolute], got {rig.raw.get('supply.pressure', p_s)!r}")
    if not t_low > 0:
        raise RigError(f"return.pressure_profile: the tank pressure must stay > 0 [Pa, absolute]; "
                       f"it falls to {t_low / 1e6:.6g} MPa")
    if not s_low > t_high:
        raise RigError(f"supply.pressure_profile: the supply pressure must stay above the return "
                       f"pressure [Pa]; it falls to {s_low / 1e6:.6g} MPa "
                       f"(return up to {t_high / 1e6:.6g} MPa)")
    check_ranges(rig)          # plausible ranges, [rig] allow_implausible (rigs.parameters)
    half = rig["actuator.stroke"] / 2
    for path, x in (("actuator.initial_position", rig.get("actuator.initial_position")),
                    ("initial piston position", position_guess)):
        if x is not None and not (np.isfinite(x) and abs(x) <= half * (1 + 1e-12)):
            shown = rig.raw.get(path, f"{x:g} m")
            raise RigError(f"{path}: must lie within +-stroke/2 = +-{half * 1e3:g} mm [m] "
                           f"(piston inside the cylinder), got {shown!r}")
    x_max = rig.get("servovalve.max_opening")
    laps = rig.get("servovalve.laps")
    if laps is not None:
        if len(laps) != 4:
            raise RigError(f"servovalve.laps: must be four lengths u1..u4 [m], got {rig.raw.get('servovalve.laps')!r}")
        if x_max is not None and any(not abs(u) < x_max for u in laps):
            raise RigError(f"servovalve.laps: each lap must be shorter than max_opening "
                           f"({rig.raw.get('servovalve.max_opening', x_max)!r}) [m], got {rig.raw.get('servovalve.laps')!r}")
    for side, p_side in (("supply", p_s), ("return", p_t)):
        path = f"{side}.accumulator.precharge_pressure"
        p0 = rig.get(path)
        if p0 is not None and not p0 < p_side:
            raise RigError(f"{path}: must be below {side}.pressure ({rig.raw.get(f'{side}.pressure', p_side)!r}) "
                           f"[Pa, absolute]: pre-charged above it the accumulator holds no oil, "
                           f"got {rig.raw.get(path, p0)!r}")
    check_consistency(rig)     # weight vs force capacity, pre-charge vs the model's limit
    return profiles


def build_network(rig: Rig, commands: list, position_guess: float | None = None) -> Network:
    """The full test-system network of a rig, driven by the given command components.

    Parameters
    ----------
    rig : Rig             Parameters (SI)
    commands : list       Components that output each axis's valve current (open loop) or
                          position reference plus a controller (closed loop); see
                          :attr:`Circuit.axes` for the signal names
    position_guess : float  Initial piston position of the first axis for the steady-state
                          solver, [m]

    Returns
    -------
    Network
    """
    circuit = build_circuit(rig, position_guess)
    try:
        return circuit.network(commands)
    except CircuitError as e:
        raise RigError(str(e)) from None


def build_circuit(rig: Rig, position_guess: float | None = None) -> Circuit:
    """The components of a rig and their axis handles, before an experiment's commands.

    A rig with ``[circuit.<name>]`` tables is built from that description
    (:func:`hydroline.circuit.circuit_components`); the 2005 paper's flat rig (sections
    ``supply``, ``supply.section1``, ..., ``servovalve``, ``actuator``) is a compact template
    that expands into the same kind of component list here.

    Parameters
    ----------
    rig : Rig               Parameters (SI)
    position_guess : float  Initial piston position of the first axis, [m]; None: the rig's

    Returns
    -------
    Circuit  components, axes (handles), source
    """
    profiles = validate_rig(rig, position_guess if not has_circuit(rig.values) else None)
    if has_circuit(rig.values):
        try:
            circuit = circuit_components(rig, _overrides(rig))
            circuit.place(position_guess)
        except CircuitError as e:
            raise RigError(str(e)) from None
        _check_controller_table(rig, circuit)
        return circuit
    try:
        parts = _build(rig, position_guess, profiles)
    except (KeyError,) as e:
        raise RigError(f"rig is missing {e}") from None
    overrides = _overrides(rig)
    try:
        rewire(parts, overrides, allow_unknown=True)
        if overrides:   # the template itself is wired right (tests/test_wiring.py)
            check_circuit(parts, overrides)
    except CircuitError as e:
        raise RigError(str(e)) from None
    return Circuit(parts, axes_of(parts), rig.source, overrides)


def _check_controller_table(rig: Rig, circuit: Circuit):
    """A circuit rig's ``[controller]`` closes the loop of an axis whose circuit has no
    position controller: refused by name where every axis has its own (it would not be used)."""
    key = next((k for k in rig.values if k.startswith("controller.")), None)
    if key is not None and circuit.axes and all(ax.controller for ax in circuit.axes.values()):
        own = ", ".join(ax.controller for ax in circuit.axes.values())
        raise RigError(f"{key}: every axis of the circuit has its own position controller "
                       f"({own}); the [controller] table, which closes the loop of an axis "
                       f"without one, would not be used: remove it, or set the gains there")


def _overrides(rig):
    """The rig's ``[connections]`` overrides, "component.port" -> signal."""
    return {path[len("connections."):]: signal for path, signal in rig.values.items()
            if path.startswith("connections.")}


def _build(rig, position_guess, profiles):
    fluid = make_fluid(rig)
    w_s, p_s, _ = profiles["supply"]
    w_t, p_t, _ = profiles["return"]
    parts = []
    # ---- supply side (PQ lines) ----
    parts.append(comp.PressureSource(name="supply.pump", pressure=p_s, waveform=w_s,
                                     connections={"pressure": "pump_pressure"}))
    s1 = make_line(rig, "supply.section1", fluid)
    parts.append(comp.HoseSection(name="supply.section1", model=_hose(rig, "supply.section1", s1, "PQ", p_s),
                                  nominal_pressure=p_s, connections={
        "upstream_pressure": "pump_pressure", "downstream_flow": "supply.manifold_flow",
        "downstream_pressure": "supply.manifold_inlet_pressure", "upstream_flow": "pump_flow"}))
    supply_close_coupled = not _section_present(rig, "supply.section2")
    node = "supply_port_pressure" if supply_close_coupled else "supply.manifold_pressure"
    parts.append(_accumulator(rig, "supply", fluid, p_s, node))
    if not supply_close_coupled:
        parts.append(comp.LinearResistance(name="supply.manifold", compute="outlet",
                                           resistance=rig["supply.manifold.resistance"], connections={
            "inlet_pressure": "supply.manifold_inlet_pressure", "flow": "supply.manifold_flow",
            "outlet_pressure": "supply.manifold_pressure"}))
        s2 = make_line(rig, "supply.section2", fluid)
        parts.append(comp.HoseSection(name="supply.section2", model=_hose(rig, "supply.section2", s2, "PQ", p_s),
                                      nominal_pressure=p_s, connections={
            "upstream_pressure": "supply.manifold_pressure", "downstream_flow": "supply_port_flow",
            "downstream_pressure": "supply_port_pressure", "upstream_flow": "supply.section2_inflow"}))
        parts.append(comp.FlowJunction(name="supply.junction", terms={"section2": 1, "accumulator": 1},
                                       connections={"section2": "supply.section2_inflow",
                                                    "accumulator": "supply.accumulator_flow",
                                                    "flow": "supply.manifold_flow"}))
        supply_port = "supply_port_pressure"
    else:
        # HSM close-coupled to the valve: the manifold block's oil volume is the node
        parts.append(comp.LinearResistance(name="supply.manifold", compute="flow",
                                           resistance=rig["supply.manifold.resistance"], connections={
            "inlet_pressure": "supply.manifold_inlet_pressure",
            "outlet_pressure": node, "flow": "supply.manifold_flow"}))
        parts.append(comp.HydraulicVolume(
            name="supply.node", volume=rig.get("supply.manifold.volume", DEFAULT_NODE_VOLUME),
            bulk_modulus=fluid.bulk_modulus, nominal_pressure=p_s,
            terms={"inflow": 1, "valve": -1, "accumulator": -1},
            connections={"inflow": "supply.manifold_flow", "valve": "supply_port_flow",
                         "accumulator": "supply.accumulator_flow", "pressure": node}))
        supply_port = node
    # ---- return side (QP lines, flow toward the tank) ----
    parts.append(comp.PressureSource(name="return.tank", pressure=p_t, waveform=w_t,
                                     connections={"pressure": "tank_pressure"}))
    r1 = make_line(rig, "return.section1", fluid)
    parts.append(comp.HoseSection(name="return.section1", model=_hose(rig, "return.section1", r1, "QP", p_t),
                                  nominal_pressure=p_t, connections={
        "upstream_flow": "return.manifold_flow", "downstream_pressure": "tank_pressure",
        "upstream_pressure": "return.section1_inlet_pressure", "downstream_flow": "tank_flow"}))
    return_close_coupled = not _section_present(rig, "return.section2")
    node = "return_port_pressure" if return_close_coupled else "return.manifold_pressure"
    parts.append(_accumulator(rig, "return", fluid, p_t, node))
    cv_forward = rig.get("return.check_valve.forward_resistance", 0.0)
    cv_reverse = rig.get("return.check_valve.reverse_resistance", 1e13)
    if not return_close_coupled:
        parts.append(comp.CheckValve(name="return.check_valve", compute="inlet",
                                     forward_resistance=cv_forward, reverse_resistance=cv_reverse,
                                     connections={"outlet_pressure": "return.section1_inlet_pressure",
                                                  "flow": "return.manifold_flow",
                                                  "inlet_pressure": "return.check_valve_pressure"}))
        parts.append(comp.LinearResistance(name="return.manifold", compute="inlet",
                                           resistance=rig["return.manifold.resistance"], connections={
            "outlet_pressure": "return.check_valve_pressure", "flow": "return.manifold_flow",
            "inlet_pressure": "return.manifold_pressure"}))
        r2 = make_line(rig, "return.section2", fluid)
        parts.append(comp.HoseSection(name="return.section2", model=_hose(rig, "return.section2", r2, "QP", p_t),
                                      nominal_pressure=p_t, connections={
            "upstream_flow": "return_port_flow", "downstream_pressure": "return.manifold_pressure",
            "upstream_pressure": "return_port_pressure", "downstream_flow": "return.section2_outflow"}))
        parts.append(comp.FlowJunction(name="return.junction", terms={"section2": 1, "accumulator": -1},
                                       connections={"section2": "return.section2_outflow",
                                                    "accumulator": "return.accumulator_flow",
                                                    "flow": "return.manifold_flow"}))
        return_port = "return_port_pressure"
    else:
        # HSM close-coupled to the valve: node volume; manifold loss and check valve in series
        # become one check valve in flow causality with forward resistance R_hsm + R_cv
        parts.append(comp.CheckValve(name="return.manifold", compute="flow",
                                     forward_resistance=rig["return.manifold.resistance"] + cv_forward,
                                     reverse_resistance=cv_reverse, connections={
            "inlet_pressure": node,
            "outlet_pressure": "return.section1_inlet_pressure", "flow": "return.manifold_flow"}))
        parts.append(comp.HydraulicVolume(
            name="return.node", volume=rig.get("return.manifold.volume", DEFAULT_NODE_VOLUME),
            bulk_modulus=fluid.bulk_modulus, nominal_pressure=p_t,
            terms={"valve": 1, "accumulator": -1, "outflow": -1},
            connections={"valve": "return_port_flow", "accumulator": "return.accumulator_flow",
                         "outflow": "return.manifold_flow", "pressure": node}))
        return_port = node
    # ---- valve, actuator, friction, load ----
    sv = "servovalve"
    parts.append(comp.Servovalve(
        name="servovalve", rated_current=rig[f"{sv}.rated_current"], rated_flow=rig[f"{sv}.rated_flow"],
        rated_pressure_drop=rig[f"{sv}.rated_pressure_drop"], max_opening=rig[f"{sv}.max_opening"],
        natural_frequency=rig[f"{sv}.natural_frequency"], damping_ratio=rig[f"{sv}.damping_ratio"],
        laps=tuple(rig.get(f"{sv}.laps", [0.0] * 4)),
        laminar_pressure=rig.get(f"{sv}.laminar_pressure", 1e5),
        connections={"current": "valve_current", "supply_pressure": supply_port,
                     "return_pressure": return_port, "bottom_pressure": "bottom_chamber_pressure",
                     "top_pressure": "top_chamber_pressure", "supply_flow": "supply_port_flow",
                     "return_flow": "return_port_flow", "bottom_flow": "bottom_chamber_flow",
                     "top_flow": "top_chamber_flow"}))
    parts.append(make_actuator(rig, position_guess, nominal_pressure=0.5 * (p_s + p_t)))
    fr = {k: rig[f"friction.{k}"] for k in (
        "viscous_up", "viscous_down", "coulomb_up", "coulomb_down", "static_up", "static_down",
        "stribeck_velocity", "stribeck_exponent", "regularization_velocity",
        "bristle_stiffness", "bristle_damping", "model") if f"friction.{k}" in rig}
    parts.append(comp.StribeckFriction(name="friction", **fr,
                                       connections={"velocity": "piston_velocity"}))
    parts.append(comp.Load(name="load", stiffness=rig.get("load.stiffness", 0.0),
                           damping=rig.get("load.damping", 0.0),
                           applied_force=rig.get("load.applied_force", 0.0),
                           free_position=rig.get("load.free_position", 0.0),
                           connections={"position": "piston_position", "velocity": "piston_velocity"}))
    return parts


def make_actuator(rig: Rig, position_guess=None, nominal_pressure=None) -> comp.Actuator:
    """The actuator component of a rig (load mass added to the moving mass).

    ``nominal_pressure`` [Pa] scales the chamber-pressure states; the mean of the supply and
    return pressures at t = 0 when None.

    Parameters
    ----------
    rig : Rig                  Parameters (SI)
    position_guess : float     Piston position to start the steady-state solve from, [m];
                               ``actuator.initial_position`` when None
    nominal_pressure : float   Scale of the chamber-pressure states, [Pa]

    Returns
    -------
    Actuator

    Raises
    ------
    RigError  One line when neither ``actuator.area`` nor both side areas are given [m^2]
    """
    area = rig.get("actuator.area")
    Ab = rig.get("actuator.bottom_area", area)
    At = rig.get("actuator.top_area", area)
    if Ab is None or At is None:
        raise RigError("actuator.area: give area or bottom_area and top_area [m^2]")
    stroke = rig["actuator.stroke"]
    dead = rig["actuator.dead_volume"]
    x0 = rig.get("actuator.initial_position", 0.0) if position_guess is None else position_guess
    return comp.Actuator(
        name="actuator", bottom_area=Ab, top_area=At,
        bottom_volume=dead + Ab * stroke / 2, top_volume=dead + At * stroke / 2,
        bulk_modulus=rig["actuator.bulk_modulus"],
        moving_mass=rig["actuator.moving_mass"] + rig.get("load.mass", 0.0),
        stroke=stroke, gravity=rig.get("actuator.gravity", 9.81),
        internal_leakage=rig.get("actuator.internal_leakage", 0.0),
        external_leakage=rig.get("actuator.external_leakage", 0.0),
        initial_position=x0,
        nominal_pressure=nominal_pressure if nominal_pressure is not None else 0.5 * (
            pressure_profile(rig, "supply")[1] + pressure_profile(rig, "return")[1]),
        connections={"bottom_flow": "bottom_chamber_flow", "top_flow": "top_chamber_flow",
                     "bottom_pressure": "bottom_chamber_pressure",
                     "top_pressure": "top_chamber_pressure", "position": "piston_position",
                     "velocity": "piston_velocity"})
