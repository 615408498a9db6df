"""The template rig: the 2005 paper's compact tables expanded into a circuit (docs/model.md 1, 6).

A template rig (``ayalew2005.toml``: ``[supply]``, ``[supply.section1]``, ...,
``[servovalve]``, ``[actuator]``, ``[friction]``, ``[load]``) describes one servo axis between
a supply side and a return side of the same shape. :func:`expand` turns its values into the
components a circuit file would list (:class:`hydroline.circuit.ComponentSpec`: type,
parameters, ports, flow terms), which the circuit builder makes and checks as it does every
circuit; :func:`check_template` holds the template's own values (pressures, stroke, laps,
pre-charges) to what a physical rig can be, naming the paths the file wrote.

Signal names (the network's vocabulary; see ``docs`` of each component for its ports):

supply side
    pump_pressure -> supply.section1 -> supply.manifold_inlet_pressure ->
    supply.manifold -> supply.manifold_pressure (HSM node, accumulator) ->
    supply.section2 -> supply_port_pressure (valve P port); flows back:
    supply_port_flow, supply.section2_inflow, supply.accumulator_flow,
    supply.manifold_flow, pump_flow.
return side
    return_port_flow (valve T port, toward tank) -> return.section2 ->
    return.manifold_pressure (HSM return node, accumulator) -> manifold resistance,
    check valve -> return.section1 -> tank_pressure; pressures back:
    return_port_pressure, return.check_valve_pressure,
    return.section1_inlet_pressure; flows return.section2_outflow,
    return.accumulator_flow, return.manifold_flow, tank_flow.
valve/piston
    valve_current, bottom_chamber_flow, top_chamber_flow, bottom_chamber_pressure,
    top_chamber_pressure, piston_position, piston_velocity, friction_force,
    load_force.

Both sides are one pattern (:data:`SIDES`): a source, section I to the HSM, the accumulator on
the HSM node, the manifold loss (on the return in series with its check valve), section II to
the valve. The supply hoses use the PQ form (M8). The return hoses are oriented from the valve
toward the tank and use the QP form (inputs: the flow entering at the valve end and the
pressure at the tank end), which is the paper's PQ return line seen from its other end: the
same dynamics with every flow positive toward the tank, so no sign flips at the valve or the
HSM. A section II of zero length is removed: the HSM node is joined to the valve port, and the
manifold block's oil volume (``<side>.manifold.volume``) becomes the node (without it the
manifold resistance and the valve orifices would form an algebraic loop); its pressure is
then the port pressure signal (``supply_port_pressure``/``return_port_pressure``).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import components as comp
from ..circuit import ComponentSpec
from ..circuit.types import COMPONENT_TYPES
from ..lines import Line
from . import COMPONENT_SECTIONS, SCHEMA, Rig, RigError
from .parameters import PARAMETERS, REQUIRED, check_consistency, check_ranges

__all__ = ["Side", "SIDES", "expand", "check_template", "pressure_profile", "section_present",
           "make_line", "bad_value"]


@dataclass(frozen=True)
class Side:
    """How one side of the template is wired: its components are named ``<name>.<part>``
    and its signals ``<name>.manifold_flow``, ``<name>_port_pressure``, ... where not given.

    Attributes
    ----------
    name : str
        "supply" or "return"
    source : str
        Its pressure source (the pump unit, the tank)
    source_pressure : str
        Signal of the source pressure, [Pa]
    source_flow : str
        Flow at the source end of section I, [m^3/s]
    inlet_pressure : str
        Pressure at section I's HSM end, [Pa]
    section2_flow : str
        Flow at section II's HSM end, [m^3/s]
    toward_valve : bool
        True where flows count positive from the source toward the valve
        (the supply: PQ hoses); False where they run from the valve toward
        the source (the return, toward the tank: QP hoses)
    check_valve : bool
        The manifold loss has a check valve in series, on the source side
    node_terms : tuple
        (term, flow: "manifold", "port" or "accumulator", sign) of the HSM
        block's oil volume that is the node when section II is removed
    """

    name: str
    source: str
    source_pressure: str
    source_flow: str
    inlet_pressure: str
    section2_flow: str
    toward_valve: bool
    check_valve: bool
    node_terms: tuple

    def flow(self, kind: str) -> str:
        """The signal of a flow of the side's HSM node: "manifold", "port" or "accumulator".

        Parameters
        ----------
        kind : str
            Which flow

        Returns
        -------
        str
            The flow's signal name, [m^3/s] signal
        """
        return f"{self.name}_port_flow" if kind == "port" else f"{self.name}.{kind}_flow"


#: The two sides of the template rig.
SIDES = {s.name: s for s in (
    Side("supply", "supply.pump", "pump_pressure", "pump_flow", "supply.manifold_inlet_pressure",
         "supply.section2_inflow", toward_valve=True, check_valve=False,
         node_terms=(("inflow", "manifold", 1), ("valve", "port", -1),
                     ("accumulator", "accumulator", -1))),
    Side("return", "return.tank", "tank_pressure", "tank_flow", "return.section1_inlet_pressure",
         "return.section2_outflow", toward_valve=False, check_valve=True,
         node_terms=(("valve", "port", 1), ("accumulator", "accumulator", -1),
                     ("outflow", "manifold", -1))),
)}

#: The valve and the piston: component -> ports (the template's one axis).
_AXIS_PORTS = {
    "servovalve": {"current": "valve_current", "supply_pressure": "supply_port_pressure",
                   "return_pressure": "return_port_pressure",
                   "bottom_pressure": "bottom_chamber_pressure",
                   "top_pressure": "top_chamber_pressure", "supply_flow": "supply_port_flow",
                   "return_flow": "return_port_flow", "bottom_flow": "bottom_chamber_flow",
                   "top_flow": "top_chamber_flow"},
    "actuator": {"bottom_flow": "bottom_chamber_flow", "top_flow": "top_chamber_flow",
                 "friction_force": "friction_force", "load_force": "load_force",
                 "bottom_pressure": "bottom_chamber_pressure",
                 "top_pressure": "top_chamber_pressure", "position": "piston_position",
                 "velocity": "piston_velocity"},
    "friction": {"velocity": "piston_velocity", "friction_force": "friction_force"},
    "load": {"position": "piston_position", "velocity": "piston_velocity",
             "load_force": "load_force"},
}


def section_present(rig: Rig, section: str) -> bool:
    """True for a hose section of positive length; False for 0 or none given (removed).

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    section : str
        Hose section, ``"<side>.section<n>"``

    Returns
    -------
    bool
        Whether the section is there (a length above 0)

    Raises
    ------
    RigError
        For a length below 0
    """
    length = rig.get(f"{section}.length", 0.0)
    if length < 0:
        raise RigError(f"{section}.length: must be >= 0 m (0 removes the section), "
                       f"got {length!r} m")
    return length > 0


def make_line(rig: Rig, section: str, fluid) -> Line:
    """The Line of a hose section, e.g. ``section="supply.section2"``.

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    section : str
        Hose section, ``"<side>.section<n>"``
    fluid : Fluid
        The fluid in it (the section's own bulk modulus, if set, overrides its
        effective one)

    Returns
    -------
    Line
        Length [m], diameter [m] and fluid of the section

    Raises
    ------
    RigError
        One line naming the section's parameter at fault
    """
    length, diameter = rig[f"{section}.length"], rig[f"{section}.diameter"]   # (named in full)
    try:
        creep = tuple(rig.get(f"{section}.creep_compliances", ()) or ())
        times = tuple(rig.get(f"{section}.retardation_times", ()) or ())
        if creep or times:        # a viscoelastic wall (M44)
            return Line(length, diameter, fluid, rig.get(f"{section}.bulk_modulus"), creep, times)
        return Line(length, diameter, fluid, rig.get(f"{section}.bulk_modulus"))
    except ValueError as e:   # Line names the parameter: "diameter: must be > 0 ..."
        raise RigError(f"{section}.{e}") from None


_REQUIRED: dict = {}


def _required(section: str) -> tuple:
    """Keys of a template section a rig must give (:data:`PARAMETERS` marks them)."""
    if not _REQUIRED:
        for path, p in PARAMETERS.items():
            if p.default == REQUIRED and p.scope == "always":
                sec, _, key = path.rpartition(".")
                _REQUIRED.setdefault(sec, []).append(key)
    return tuple(_REQUIRED.get(section, ()))


def _values(rig: Rig, given: dict, section: str) -> dict:
    """The values of a template section that are its component's parameters, as given;
    RigError naming one a rig must give and does not."""
    keys = COMPONENT_SECTIONS.get(section, (None, None))[1]
    out = {k: v for k, v in given.get(section, {}).items() if keys is None or k in keys}
    for key in _required(section):
        if key not in out and (keys is None or key in keys):
            raise RigError(f"{section}.{key}: not set in rig {rig.source}")
    return out


def _source(side: Side, profile) -> ComponentSpec:
    waveform, level, _ = profile
    params = {"pressure": level} if waveform is None else {"pressure": level, "waveform": waveform}
    return ComponentSpec(side.source, "pressure_source", params,
                         {"pressure": side.source_pressure}, table=side.name)


def _hose(rig, given, section, side, level, near: tuple, far: tuple) -> ComponentSpec:
    """A hose section from ``near`` (the source's end) to ``far`` (the valve's end), each a
    (pressure, flow) pair of signals."""
    ends = ("upstream", "downstream") if side.toward_valve else ("downstream", "upstream")
    ports = {}
    for end, (pressure, flow) in zip(ends, (near, far)):
        ports[f"{end}_pressure"], ports[f"{end}_flow"] = pressure, flow
    params = {**_values(rig, given, section), "form": "PQ" if side.toward_valve else "QP",
              "nominal_pressure": level}
    return ComponentSpec(section, "hose", params, ports, table=section,
                         paths={"nominal_pressure": f"{side.name}.pressure"},
                         derived=frozenset(("form", "nominal_pressure")))


def _side(rig: Rig, given: dict, side: Side, profile) -> list:
    """The components of one side, source to valve port, in the network's order."""
    n, level = side.name, profile[1]
    near, far = ("inlet", "outlet") if side.toward_valve else ("outlet", "inlet")   # resistances
    manifold_flow = side.flow("manifold")
    specs = [_source(side, profile),
             _hose(rig, given, f"{n}.section1", side, level,
                   (side.source_pressure, side.source_flow), (side.inlet_pressure, manifold_flow))]
    close_coupled = not section_present(rig, f"{n}.section2")
    node = f"{n}_port_pressure" if close_coupled else f"{n}.manifold_pressure"
    specs.append(ComponentSpec(
        f"{n}.accumulator", "accumulator",
        {**_values(rig, given, f"{n}.accumulator"), "nominal_pressure": level},
        {"pressure": node, "flow": side.flow("accumulator")}, table=f"{n}.accumulator",
        paths={"nominal_pressure": f"{n}.pressure"}, derived=frozenset(("nominal_pressure",))))
    loss = _values(rig, given, f"{n}.manifold")
    check = _values(rig, given, f"{n}.check_valve") if side.check_valve else None
    if close_coupled:
        # the manifold block's oil volume is the node; manifold loss and check valve in series
        # become one check valve in flow causality with forward resistance R_hsm + R_cv
        ports = {f"{near}_pressure": side.inlet_pressure, f"{far}_pressure": node,
                 "flow": manifold_flow}
        if check is None:
            specs.append(ComponentSpec(f"{n}.manifold", "resistance", {**loss, "compute": "flow"},
                                       ports, table=f"{n}.manifold",
                                       derived=frozenset(("compute",))))
        else:
            r_cv = check.get("forward_resistance", COMPONENT_TYPES["check_valve"].declarations()
                             ["forward_resistance"].default)
            params = {**check, "compute": "flow", "forward_resistance": loss["resistance"] + r_cv}
            specs.append(ComponentSpec(f"{n}.manifold", "check_valve", params, ports,
                                       table=f"{n}.check_valve",
                                       paths={"forward_resistance": f"{n}.manifold.resistance"},
                                       derived=frozenset(("compute", "forward_resistance"))))
        volume = f"{n}.manifold.volume"
        specs.append(ComponentSpec(
            f"{n}.node", "volume",
            {"volume": rig.get(volume, PARAMETERS[volume].default), "nominal_pressure": level},
            {**{term: side.flow(kind) for term, kind, _ in side.node_terms}, "pressure": node},
            {term: sign for term, _, sign in side.node_terms}, table=f"{n}.manifold",
            paths={"nominal_pressure": f"{n}.pressure"}, derived=frozenset(("nominal_pressure",))))
        return specs
    upstream = side.inlet_pressure
    if check is not None:
        specs.append(ComponentSpec(
            f"{n}.check_valve", "check_valve", {**check, "compute": far},
            {f"{near}_pressure": upstream, "flow": manifold_flow,
             f"{far}_pressure": f"{n}.check_valve_pressure"},
            table=f"{n}.check_valve", derived=frozenset(("compute",))))
        upstream = f"{n}.check_valve_pressure"
    specs.append(ComponentSpec(f"{n}.manifold", "resistance", {**loss, "compute": far},
                               {f"{near}_pressure": upstream, "flow": manifold_flow,
                                f"{far}_pressure": node},
                               table=f"{n}.manifold", derived=frozenset(("compute",))))
    specs.append(_hose(rig, given, f"{n}.section2", side, level,
                       (node, side.section2_flow), (f"{n}_port_pressure", side.flow("port"))))
    specs.append(ComponentSpec(f"{n}.junction", "junction", {},
                               {"section2": side.section2_flow,
                                "accumulator": side.flow("accumulator"), "flow": manifold_flow},
                               {"section2": 1, "accumulator": 1 if side.toward_valve else -1},
                               table=f"{n}.manifold"))
    return specs


def _actuator(rig: Rig, given: dict, nominal_pressure: float) -> ComponentSpec:
    """The actuator: side areas from ``area`` where not given, the chamber volumes at
    mid-stroke from the dead volume (``V = V_dead + A stroke / 2``)."""
    params = _values(rig, given, "actuator")
    paths = {}
    area = rig.get("actuator.area")
    for key in ("bottom_area", "top_area"):
        if key not in params:
            if area is None:
                raise RigError("actuator.area: give area or bottom_area and top_area [m^2]")
            params[key], paths[key] = area, "actuator.area"
    stroke, dead = rig["actuator.stroke"], rig["actuator.dead_volume"]
    params["bottom_volume"] = dead + params["bottom_area"] * stroke / 2
    params["top_volume"] = dead + params["top_area"] * stroke / 2
    params["nominal_pressure"] = nominal_pressure
    paths.update(bottom_volume="actuator.dead_volume", top_volume="actuator.dead_volume",
                 nominal_pressure="supply.pressure")
    return ComponentSpec("actuator", "actuator", params, dict(_AXIS_PORTS["actuator"]),
                         table="actuator", paths=paths,
                         derived=frozenset(("bottom_volume", "top_volume", "nominal_pressure")))


def expand(rig: Rig, profiles: dict | None = None) -> list:
    """The template rig as a circuit: its components with their parameters, ports and flow
    terms, in the network's order (supply side, return side, valve, actuator, friction, load).

    A pure function of the rig's values: the circuit builder
    (:func:`hydroline.circuit.build_components`) makes and checks the components. Every value
    the file does not give is left to the component's declared default.

    Parameters
    ----------
    rig : Rig
        A template rig (SI)
    profiles : dict
        side -> :func:`pressure_profile` (as :func:`check_template` returns them);
        None: read here

    Returns
    -------
    list of ComponentSpec
        The circuit the template stands for, in state order

    Raises
    ------
    RigError
        One line naming a value the template needs and the rig does not give
    """
    if profiles is None:
        profiles = {side: pressure_profile(rig, side) for side in SIDES}
    given = {}
    for path, v in rig.values.items():
        section, _, key = path.rpartition(".")
        given.setdefault(section, {})[key] = v
    specs = []
    for side in SIDES.values():
        specs += _side(rig, given, side, profiles[side.name])
    specs.append(ComponentSpec("servovalve", "servovalve", _values(rig, given, "servovalve"),
                               dict(_AXIS_PORTS["servovalve"]), table="servovalve"))
    specs.append(_actuator(rig, given, 0.5 * (profiles["supply"][1] + profiles["return"][1])))
    for name in ("friction", "load"):
        specs.append(ComponentSpec(name, name, _values(rig, given, name),
                                   dict(_AXIS_PORTS[name]), table=name))
    return specs


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
    rig : Rig
        Parameters (SI)
    side : str
        "supply" or "return"

    Returns
    -------
    tuple
        (waveform component or None, level at t = 0 [Pa], (lowest, highest) pressure over
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
        raise bad_value(rig, f"{base}.start", ">= 0")
    if kind == "step":
        t_step, final = rig[f"{base}.time"], rig[f"{base}.final"]
        if not t_step > 0:
            raise bad_value(rig, f"{base}.time", "> 0 (the steady state is solved before the step)")
        w = comp.StepCommand(name=name, quantity="pressure", initial=level, final=final, time=t_step)
        return w, level, (min(level, final), max(level, final))
    if kind == "sine":
        amp, f = rig[f"{base}.amplitude"], rig[f"{base}.frequency"]
        if not f > 0:
            raise bad_value(rig, f"{base}.frequency", "> 0")
        w = comp.SineCommand(name=name, quantity="pressure", offset=level, amplitude=amp,
                             frequency=f, start=start)
        return w, level, (level - abs(amp), level + abs(amp))
    if kind == "ramp":
        slope, end = rig[f"{base}.slope"], rig[f"{base}.end"]
        if not end > start:
            raise bad_value(rig, f"{base}.end", f"> start ({start:g} s)")
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


def bad_value(rig: Rig, path: str, rule: str, value=None) -> RigError:
    """The one-line error refusing a value: ``"<path>: must be <rule> [unit], got <value as
    written>"`` (a pressure's unit said "Pa, absolute").

    Parameters
    ----------
    rig : Rig
        The rig holding the value
    path : str
        Its dotted path
    rule : str
        What it must be, e.g. "> 0"
    value : object
        Shown where the rig holds no value as written at ``path``

    Returns
    -------
    RigError
        The error to raise (one line naming the path and its unit)
    """
    shown = rig.raw.get(path, value if value is not None else rig.get(path))
    unit = _unit(path)
    if unit == "Pa" and path.endswith("pressure"):
        unit = "Pa, absolute"
    return RigError(f"{path}: must be {rule}{' [' + unit + ']' if unit else ''}, got {shown!r}")


#: Template-rig parameters checked before the circuit is built that no component declares
#: (the components' own are checked against their declarations, see
#: :func:`hydroline.rigs.declarations`). The value is echoed as written in the file.
_POSITIVE = ("return.pressure", "actuator.area", "actuator.dead_volume",
             "supply.manifold.volume", "return.manifold.volume")


def check_template(rig: Rig, position_guess: float | None = None) -> dict:
    """The template's own checks (after each value's declared bounds): template-only sizes
    positive, ``supply.pressure > return.pressure > 0`` over every pressure profile, the
    plausible ranges (:func:`hydroline.rigs.parameters.check_ranges`), the piston inside the
    cylinder, laps shorter than the spool stroke, pre-charges below their side's pressure,
    and the consistency checks (:func:`hydroline.rigs.parameters.check_consistency`).

    Parameters
    ----------
    rig : Rig
        A template rig (SI)
    position_guess : float
        Initial piston position given by the scenario, [m]; checked
        like ``actuator.initial_position`` when not None

    Returns
    -------
    dict
        side -> its :func:`pressure_profile`

    Raises
    ------
    RigError
        One line naming the template path at fault, its unit and the value as written
    """
    for path in _POSITIVE:
        v = rig.get(path)
        if v is not None and not (np.isfinite(v) and v > 0):
            raise bad_value(rig, path, "> 0")
    profiles = {side: pressure_profile(rig, side) for side in SIDES}
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
