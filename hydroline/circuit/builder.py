"""Circuits as data: a rig's ``[circuit.<name>]`` tables -> components, handles, network.

A circuit file lists components by type (:data:`hydroline.circuit.types.COMPONENT_TYPES`),
each with its parameters (quantities with units, provenance comments) and the signal each of
its ports is joined to::

    [circuit."supply.section1"]
    type = "hose"
    length = "3.048 m"           # [paper]
    diameter = "15.9 mm"
    form = "PQ"
    ports = { upstream_pressure = "pump_pressure", downstream_flow = "supply.manifold_flow",
              downstream_pressure = "supply.manifold_inlet_pressure", upstream_flow = "pump_flow" }

Two ports are connected when they name the same signal; exactly one of them outputs it
(causality). ``volume`` and ``junction`` components list their flow terms with signs
(``terms = { inflow = 1, valve = -1 }``). Every port must be listed: an unlisted port is
refused, as are a port the type does not have, an unknown type, two outputs on one signal,
a causality clash and an algebraic loop, each in one line naming the component and port;
then the physical wiring checks of :mod:`hydroline.circuit.wiring` (self-loops, short
circuits, ends cut off or crossed, a servovalve's P not above its T, parts cut off from every
source).

:func:`axes_of` finds the servo axes (actuator, its valve, its controller) in any component
list and returns their handles (:class:`Axis`): which signals are the axis's port pressures,
piston position, valve current, ... so experiments and analysis never hard-code names.
"""
from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import components as comp
from ..fluid import Fluid
from ..engine import Network, NetworkError
from ..engine.network import connection_table
from .types import COMPONENT_TYPES, CONTEXT, QUANTITY_UNIT, RIG_SETTINGS, CircuitError
from .wiring import check_self_loops, check_wiring

__all__ = ["Axis", "Circuit", "ComponentSpec", "axes_of", "build_components", "check_circuit",
           "check_circuit_value", "check_component_name", "circuit_components",
           "circuit_names", "circuit_specs", "has_circuit", "parse_circuit_value", "rewire",
           "rig_fluid", "MAX_NAME_LENGTH"]

PREFIX = "circuit."
#: Longest component name, [characters]: a name labels messages, result columns and figures.
MAX_NAME_LENGTH = 100


def has_circuit(values: dict) -> bool:
    """True when a rig's values describe a circuit (any ``circuit.*`` key).

    Parameters
    ----------
    values : dict
        A rig's values, path -> SI value

    Returns
    -------
    bool
        Whether any key starts with ``circuit.``
    """
    return any(k.startswith(PREFIX) for k in values)


def circuit_names(values: dict) -> list[str]:
    """Component names of the circuit, in file order.

    Parameters
    ----------
    values : dict
        A rig's values, path -> SI value

    Returns
    -------
    list of str
        The ``<name>`` of each ``[circuit.<name>]`` table with a type
    """
    return [k[len(PREFIX):-len(".type")] for k in values
            if k.startswith(PREFIX) and k.endswith(".type")]


def _split(path: str, raw: dict) -> tuple[str, str]:
    """(component name, key) of a ``circuit.<name>.<key>`` path."""
    parts = path[len(PREFIX):].split(".")
    for i in range(len(parts) - 1, 0, -1):
        name = ".".join(parts[:i])
        if f"{PREFIX}{name}.type" in raw:
            return name, ".".join(parts[i:])
    if parts[-1] == "type":
        return ".".join(parts[:-1]), "type"
    raise CircuitError(f"{path}: no component of the circuit holds it (give its table a "
                       f"type = \"...\", one of {', '.join(COMPONENT_TYPES)})")


def parse_circuit_value(path: str, raw_value, raw: dict, parse_quantity_as):
    """A ``circuit.*`` rig value in SI.

    Parameters
    ----------
    path : str
        ``circuit.<component>.<key>``
    raw_value : object
        The value as written (quantity with unit, text, number)
    raw : dict
        All raw values of the rig (to find the component's type)
    parse_quantity_as : callable
        ``(path, raw_value, unit) -> SI value`` (the rig's reader)

    Returns
    -------
    object
        float [SI unit of the parameter], text, list or a signal name
    """
    name, key = _split(path, raw)
    if key == "type":
        check_component_name(name)
        if raw_value not in COMPONENT_TYPES:
            raise CircuitError(f"{path}: unknown component type {raw_value!r} of component "
                               f"'{name}' (known: {', '.join(COMPONENT_TYPES)})")
        return raw_value
    ctype = COMPONENT_TYPES[raw[f"{PREFIX}{name}.type"]]
    if key.startswith("ports."):
        if not isinstance(raw_value, str) or not raw_value:
            raise CircuitError(f"{path}: port '{key[6:]}' of component '{name}' must name a "
                               f"signal, e.g. \"supply_port_pressure\"; got {raw_value!r}")
        return raw_value
    if key.startswith("terms."):
        if not ctype.takes_terms:
            raise CircuitError(f"{path}: component '{name}' ({ctype.name}) has no flow terms "
                               f"(only a volume or a junction sums signed flows)")
        if raw_value not in (1, -1):
            raise CircuitError(f"{path}: flow term '{key[6:]}' of component '{name}' must be "
                               f"+1 (in) or -1 (out), got {raw_value!r}")
        return int(raw_value)
    own = {k[len(PREFIX) + len(name) + 1:]: v for k, v in raw.items()
           if k.startswith(f"{PREFIX}{name}.")}
    unit = ctype.unit_of(key, own)
    if unit is None:
        raise CircuitError(f"{path}: component '{name}' ({ctype.name}) has no parameter '{key}' "
                           f"(parameters: {', '.join(ctype.declarations()) or 'none'}; ports, terms)")
    return parse_quantity_as(path, raw_value, unit)


def check_component_name(name: str):
    """Refuse a name no message, result column or figure can show: empty or blank, with a
    character that does not print (a control character, a line break), or longer than
    :data:`MAX_NAME_LENGTH`. Any script is welcome (``"Pumpe-Ölseite"``, ``"泵"``).

    Parameters
    ----------
    name : str
        Component name, the ``<name>`` of ``[circuit.<name>]``

    Raises
    ------
    CircuitError
        One line naming the component's table
    """
    table = f"[circuit.{json.dumps(name[:40], ensure_ascii=False)}]"
    if not name.strip():
        raise CircuitError(f"{table}: a component name must not be empty or blank; name the "
                           f"table, e.g. [circuit.pump]")
    if len(name) > MAX_NAME_LENGTH:
        raise CircuitError(f"{table[:-1]}...]: a component name of {len(name)} characters is "
                           f"too long (at most {MAX_NAME_LENGTH})")
    odd = next((i for i, ch in enumerate(name) if not ch.isprintable()), None)
    if odd is not None:
        raise CircuitError(f"{table}: the component name holds a character that does not "
                           f"print, {name[odd]!r} at position {odd + 1}; use letters, digits, "
                           f"'.', '_' or '-'")


@dataclass
class Axis:
    """Handles of one servo axis: the signal and component names experiments use.

    Attributes
    ----------
    name : str
        Axis name (the actuator's name without ``.actuator``)
    actuator : str
        Actuator component
    valve : str
        Servovalve component driving it
    current : str
        Valve current signal, [A]
    supply_pressure, return_pressure : str
        Valve P and T port pressure signals, [Pa]
    bottom_pressure, top_pressure : str
        Chamber pressure signals, [Pa]
    position, velocity : str
        Piston position [m] and velocity [m/s] signals
    controller : str
        Position controller in the circuit driving ``current`` (or None)
    reference : str
        Its reference signal, [m] (or None)
    friction : str
        Friction component on the piston (or None)
    stroke : float
        Full stroke, [m]
    """

    name: str
    actuator: str
    valve: str
    current: str
    supply_pressure: str
    return_pressure: str
    bottom_pressure: str
    top_pressure: str
    position: str
    velocity: str
    controller: str | None = None
    reference: str | None = None
    friction: str | None = None
    stroke: float = float("inf")

    @property
    def reference_signal(self) -> str:
        """The position reference signal [m]: the controller's, else one named for the axis."""
        if self.reference:
            return self.reference
        if self.position == "piston_position":
            return "position_reference"
        return f"{self.name}.position_reference"


def axes_of(components: list) -> dict:
    """The servo axes among components, axis name -> :class:`Axis` (in component order).

    An axis is an actuator whose chambers a servovalve feeds; its controller is the position
    controller whose current drives that valve, its friction the friction component on its
    friction-force signal.

    Parameters
    ----------
    components : list
        Components joined by signal names

    Returns
    -------
    dict
        Axis name -> :class:`Axis`, one per actuator
    """
    valves = [c for c in components if isinstance(c, comp.Servovalve)]
    ctls = [c for c in components if isinstance(c, comp.PositionController)]
    frs = [c for c in components if isinstance(c, comp.StribeckFriction)]
    out = {}
    for a in components:
        if not isinstance(a, comp.Actuator):
            continue
        pb = a.signal("bottom_pressure")
        v = next((v for v in valves if v.signal("bottom_pressure") == pb), None)
        if v is None:
            continue
        cur = v.signal("current")
        ctl = next((c for c in ctls if c.signal("current") == cur), None)
        fr = next((f for f in frs if f.signal("friction_force") == a.signal("friction_force")), None)
        name = a.name[:-len(".actuator")] if a.name.endswith(".actuator") else a.name
        out[name] = Axis(name, a.name, v.name, cur, v.signal("supply_pressure"),
                         v.signal("return_pressure"), pb, a.signal("top_pressure"),
                         a.signal("position"), a.signal("velocity"),
                         None if ctl is None else ctl.name,
                         None if ctl is None else ctl.signal("reference"),
                         None if fr is None else fr.name, a.stroke)
    return out


@dataclass
class Circuit:
    """Components of a rig with their handles; :meth:`network` adds an experiment's commands.

    Attributes
    ----------
    components : list
        The components (ports joined by signal names)
    axes : dict
        Axis name -> :class:`Axis`
    source : str
        Where the description came from
    overrides : dict
        The rig's ``[connections]``, "component.port" -> signal, applied to
        the components and again to an experiment's commands
    """

    components: list
    axes: dict = field(default_factory=dict)
    source: str = ""
    overrides: dict = field(default_factory=dict)

    def component(self, name: str):
        """The component called ``name``.

        Parameters
        ----------
        name : str
            Component name

        Returns
        -------
        Component
            The component of that name

        Raises
        ------
        KeyError
            When the circuit has no component of that name
        """
        for c in self.components:
            if c.name == name:
                return c
        raise KeyError(name)

    def place(self, position_guess: float | None, axis: str | None = None):
        """Start an axis from a piston position guess for the steady-state solver.

        Parameters
        ----------
        position_guess : float
            Piston position from mid-stroke, [m]; None: leave as is
        axis : str
            Axis name; None: the first
        """
        if position_guess is None or not self.axes:
            return
        ax = self.axes[axis or next(iter(self.axes))]
        act = self.component(ax.actuator)
        half = act.stroke / 2
        if not (np.isfinite(position_guess) and abs(position_guess) <= half * (1 + 1e-12)):
            raise CircuitError(f"initial piston position of '{ax.actuator}': must lie within "
                               f"+-stroke/2 = +-{half * 1e3:g} mm [m], got {position_guess:g} m")
        act.initial_position = float(position_guess)

    def network(self, commands=()) -> Network:
        """The network of the circuit driven by an experiment.

        Parameters
        ----------
        commands : list
            Experiment components (valve currents, position references, ...)

        Returns
        -------
        Network
            The circuit's components and the commands, joined by signal names
        """
        parts = list(self.components) + list(commands)
        rewire(parts, self.overrides)
        return Network(parts)

    def connection_table(self, commands=()) -> list[dict]:
        """One row per signal: its producer ``component.port`` and consumers, quantity, unit.

        Parameters
        ----------
        commands : list
            Experiment components to include

        Returns
        -------
        list of dict
            keys signal, producer (None: from the experiment), consumers, quantity, unit
        """
        return connection_table(list(self.components) + list(commands))


def rewire(parts: list, overrides: dict, allow_unknown: bool = False):
    """Join ports to other signals: ``overrides`` maps "component.port" -> signal.

    Parameters
    ----------
    parts : list
        Components (changed in place)
    overrides : dict
        "component.port" -> signal name
    allow_unknown : bool
        Skip components not among ``parts`` (an experiment adds them later)
    """
    by_name = {c.name: c for c in parts}
    for target, signal in overrides.items():
        cname, _, port = target.rpartition(".")
        c = by_name.get(cname)
        if c is None:
            if allow_unknown:
                continue
            raise CircuitError(f"connections.{target}: unknown component '{cname}' "
                               f"(components: {', '.join(sorted(by_name))})")
        if port not in c.inputs and port not in c.outputs:
            raise CircuitError(f"connections.{target}: component '{cname}' has no port '{port}' "
                               f"(ports: {', '.join(list(c.inputs) + list(c.outputs))})")
        c.connections = dict(c.connections, **{port: signal})


def rig_fluid(rig) -> Fluid:
    """The rig's oil (``[fluid]``: density, kinematic viscosity, bulk modulus; entrained air
    where given; the cavity model at ``cavity_pressure``, 5 kPa unless the rig gives another
    or ``"off"``).

    Parameters
    ----------
    rig : Rig
        Parameters (SI)

    Returns
    -------
    Fluid
        The oil of ``[fluid]`` (SI)

    Raises
    ------
    CircuitError
        One line naming the fluid parameter at fault
    """
    from .types import FLUID_PARAMETERS

    try:
        extra = {k: rig[f"fluid.{k}"] for k in ("air_content", "air_polytropic_exponent",
                                                  "cavity_pressure_drop")
                 if rig.get(f"fluid.{k}") is not None}
        # the cavity model: on by default (M42, M45); a rig's "off" is held as None
        extra["cavity_pressure"] = rig.get("fluid.cavity_pressure",
                                           FLUID_PARAMETERS["cavity_pressure"].default)
        return Fluid(rig["fluid.density"], rig["fluid.kinematic_viscosity"], rig["fluid.bulk_modulus"],
                     **extra)
    except ValueError as e:
        raise CircuitError(f"fluid: {e}") from None


@dataclass
class ComponentSpec:
    """One component of a circuit before it is made: what a ``[circuit.<name>]`` table says.

    Attributes
    ----------
    name : str
        Component name
    type : str
        Its type, a key of :data:`~hydroline.circuit.types.COMPONENT_TYPES`
    params : dict
        Parameter -> value as given, [SI]; the others take the type's defaults
    ports : dict
        Port -> the signal it is joined to
    terms : dict
        Flow term -> sign (+1 in, -1 out), for a volume or a junction
    table : str
        Where the component is written, for messages: ``circuit.<name>``
        (a circuit file), or a template rig's section (``supply.section1``)
    paths : dict
        Parameter -> the rig path its value was written at, where that is not
        ``<table>.<parameter>`` (a template value read from another section)
    derived : frozenset
        Parameters computed from other values (a hose's nominal pressure from
        the supply pressure): held to their bounds, not to their plausible
        range (the values they come from are)
    """

    name: str
    type: str
    params: dict = field(default_factory=dict)
    ports: dict = field(default_factory=dict)
    terms: dict = field(default_factory=dict)
    table: str = ""
    paths: dict = field(default_factory=dict)
    derived: frozenset = frozenset()

    def path(self, key: str) -> str:
        """The rig path of a parameter, as messages name it.

        Parameters
        ----------
        key : str
            Parameter name

        Returns
        -------
        str
            ``<table>.<key>``, or the path the value was read from
        """
        return self.paths.get(key) or f"{self.table or PREFIX + self.name}.{key}"


def _check_declared(rig, spec: ComponentSpec, ctype, decls: dict, key: str, v, allowed) -> None:
    """A component's parameter against its type's declaration (``decls``): bounds, then the
    plausible range (unless the path is in ``allowed`` or the value is derived); one line,
    CircuitError, naming the parameter's rig path."""
    decl = decls.get(key)
    if decl is None:
        return
    rule = decl.violation(v)
    implausible = None if rule is not None or key in spec.derived else decl.implausible(v)
    if rule is None and implausible is None:
        return
    path = spec.path(key)
    unit = f" [{decl.unit_text}]" if decl.unit_text else ""
    if rule is not None:
        raise CircuitError(f"{path}: must be {rule}{unit}, got {rig.raw.get(path, v)!r} "
                           f"(component '{spec.name}', {ctype.name})")
    if path not in allowed:
        raise CircuitError(f"{path}: {rig.raw.get(path, v)!r} is outside its plausible range, "
                           f"{implausible}{unit} ({decl.description}); if it is meant, "
                           f"add \"{path}\" to [rig] allow_implausible")


def _component_params(values: dict, name: str) -> dict:
    """A circuit component's own parameters (SI), by key: ``circuit.<name>.<key>`` without
    its type and its port and term tables."""
    head = f"{PREFIX}{name}."
    return {k[len(head):]: v for k, v in values.items()
            if k.startswith(head) and "." not in k[len(head):] and k[len(head):] != "type"}


def check_circuit_value(rig, path: str) -> None:
    """Refuse one circuit parameter's value (``circuit.<component>.<parameter>``) outside its
    type's declared bounds or plausible range, as :func:`circuit_components` does for all of
    them: what a sweep checks for each level before its first variant.

    Parameters
    ----------
    rig : Rig
        A rig holding the value (SI) and the component's type
    path : str
        ``circuit.<component>.<parameter>``

    Raises
    ------
    CircuitError
        One line naming the path, the bounds or range and the unit
    """
    name, key = _split(path, rig.raw)
    ctype = COMPONENT_TYPES[rig.values[f"{PREFIX}{name}.type"]]
    if path in rig.values and "." not in key:
        params = _component_params(rig.values, name)
        spec = ComponentSpec(name, ctype.name, params, table=PREFIX + name)
        _check_declared(rig, spec, ctype, ctype.declarations(params), key, rig.values[path],
                        set(rig.get("rig.allow_implausible") or []))


def circuit_specs(rig) -> list[ComponentSpec]:
    """The components of a rig's ``[circuit.*]`` tables, in file order, before they are made.

    Parameters
    ----------
    rig : Rig
        A rig whose values hold a circuit (SI)

    Returns
    -------
    list of ComponentSpec
        One per ``[circuit.<name>]`` table, in file order

    Raises
    ------
    CircuitError
        When the rig has no ``[circuit.<name>]`` table with a type
    """
    values = rig.values
    names = circuit_names(values)
    if not names:
        raise CircuitError(f"rig {rig.source}: no [circuit.<name>] table with a type")
    specs = {n: ComponentSpec(n, values[f"{PREFIX}{n}.type"], table=PREFIX + n) for n in names}
    for path, v in values.items():      # one pass: each value to the component holding it
        if not path.startswith(PREFIX):
            continue
        parts = path[len(PREFIX):].split(".")
        for i in range(len(parts) - 1, 0, -1):   # the longest component name it starts with
            spec = specs.get(".".join(parts[:i]))
            if spec is not None:
                break
        else:
            continue
        key = parts[i:]
        if len(key) == 1 and key[0] != "type":
            spec.params[key[0]] = v
        elif len(key) == 2 and key[0] == "ports":
            spec.ports[key[1]] = v
        elif len(key) == 2 and key[0] == "terms":
            spec.terms[key[1]] = v
    return list(specs.values())


def circuit_components(rig, overrides: dict | None = None) -> Circuit:
    """The components of a rig's ``[circuit.*]`` description, checked port by port.

    Parameters
    ----------
    rig : Rig
        A rig whose values hold a circuit (SI)
    overrides : dict
        "component.port" -> signal, applied after the ports (the rig's
        ``[connections]``)

    Returns
    -------
    Circuit
        The components, their axes and the rig's ``[connections]``
    """
    return build_components(rig, circuit_specs(rig), overrides)


#: How the builder reads each :data:`~hydroline.circuit.types.CONTEXT` entry from a rig.
_CONTEXT_READERS = {
    "fluid": rig_fluid,
    "modes_per_section": lambda rig: int(rig.get("rig.modes_per_section",
                                                 RIG_SETTINGS["modes_per_section"].default)),
    "line_method": lambda rig: rig.get("rig.line_method", RIG_SETTINGS["line_method"].default),
    "folder": lambda rig: None if rig.source.startswith("embedded:") else Path(rig.source).parent,
}
assert set(_CONTEXT_READERS) == set(CONTEXT)


class _Context:
    """What components take from the rig around them, each read once when first asked for."""

    def __init__(self, rig):
        self.rig, self.known = rig, {}

    def __getitem__(self, key):
        if key not in self.known:
            reader = _CONTEXT_READERS.get(key)
            if reader is None:
                raise CircuitError(f"context {key!r}: not something a circuit gives its "
                                   f"components (known: {', '.join(CONTEXT)})")
            self.known[key] = reader(self.rig)
        return self.known[key]


def _add_to_others(specs: list, types: list, params: dict):
    """Values components add to others' parameters before they are made (a component class's
    ``adds_to``: a load's mass to the moving mass of the actuator whose position it reads)."""
    for spec, ctype in zip(specs, types):
        for own, port, target in getattr(ctype.component, "adds_to", ()):
            value = params[spec.name].get(own)
            signal = spec.ports.get(port)
            if not value or signal is None:
                continue
            for other, otype in zip(specs, types):
                if other is spec or not any(sig == signal and p in otype.component.outputs
                                            for p, sig in other.ports.items()):
                    continue
                decl = otype.declarations().get(target)
                if decl is not None:
                    host = params[other.name]
                    host[target] = host.get(target, decl.default) + value
                    break


def _make(spec: ComponentSpec, ctype, params: dict, decls: dict, context: _Context):
    """The component of a spec: its type's factory given every declared parameter (the
    declared default where none is given), or its class given the parameters the spec gives
    (the class has the same defaults); then what it takes from the rig around it, and its
    flow terms."""
    kwargs = {}
    for key, v in params.items():       # (a list of quantities: a tuple, as declared)
        kwargs[key] = tuple(v) if isinstance(v, list) and key in decls else v
    if ctype.factory is not None:
        for key, decl in decls.items():
            if key in kwargs:
                continue
            if decl.default is not None:
                kwargs[key] = decl.default
            elif not decl.optional:
                raise CircuitError(f"{spec.path(key)}: not given; a {ctype.name} needs it "
                                   f"({decl.description})")
    for key in ctype.needs:
        kwargs[key] = context[key]
    if ctype.takes_terms:
        if not spec.terms:
            raise CircuitError(f"{spec.table}.terms: a {ctype.name} needs its flow terms, e.g. "
                               f"terms = {{ inflow = 1, outflow = -1 }}")
        kwargs["terms"] = dict(spec.terms)
    try:
        return ctype.make(spec.name, **kwargs)
    except CircuitError:
        raise
    except (ValueError, TypeError) as e:
        text = str(e)
        key = text.split(":", 1)[0]
        if key in decls:                 # "diameter: must be > 0": named by its rig path
            raise CircuitError(f"{spec.path(key)}{text[len(key):]}") from None
        raise CircuitError(f"{spec.table} ({ctype.name}): {text}") from None


def build_components(rig, specs: list, overrides: dict | None = None, *, wiring: bool = True,
                     port_path: str = "circuit.{component}.ports.{port}",
                     label: str = "circuit") -> Circuit:
    """The circuit of component specs: each value held to its declaration, each component
    made by its type with what it takes from the rig, each port checked, then the circuit's
    own checks (:func:`check_circuit`).

    Parameters
    ----------
    rig : Rig
        The rig the specs come from (values as written, ``[rig]`` settings,
        the oil, ``allow_implausible``)
    specs : list
        :class:`ComponentSpec`, in the order the network takes them (its
        state order)
    overrides : dict
        "component.port" -> signal, applied after the ports (the rig's
        ``[connections]``)
    wiring : bool
        Run :func:`check_circuit` (the network's and the wiring checks)
    port_path : str
        How its messages name a port (``{component}``, ``{port}``)
    label : str
        What a message of the network's checks starts with

    Returns
    -------
    Circuit
        The components, their axes and the rig's ``[connections]``

    Raises
    ------
    CircuitError
        One line naming the component, and its parameter or port, at fault
    """
    overrides = dict(overrides or {})
    allowed = set(rig.get("rig.allow_implausible") or [])
    types, decls = [], []
    for spec in specs:
        ctype = COMPONENT_TYPES[spec.type]
        d = ctype.declarations(spec.params)   # (a command's levels: its quantity's range)
        for key, v in spec.params.items():   # the declared bounds, with the value as written
            _check_declared(rig, spec, ctype, d, key, v, allowed)
        types.append(ctype)
        decls.append(d)
    params = {spec.name: dict(spec.params) for spec in specs}
    _add_to_others(specs, types, params)
    context = _Context(rig)
    parts = []
    for spec, ctype, d in zip(specs, types, decls):
        c = _make(spec, ctype, params[spec.name], d, context)
        have = list(c.inputs) + list(c.outputs)
        for port in spec.ports:
            if port not in have:
                raise CircuitError(f"{spec.table}.ports.{port}: component '{spec.name}' "
                                   f"({ctype.name}) has no port '{port}' (ports: {', '.join(have)})")
        for port in have:
            if port not in spec.ports:
                raise CircuitError(f"{spec.table}.ports.{port}: port '{port}' of component "
                                   f"'{spec.name}' is not connected (list it in ports = {{...}})")
        c.connections = dict(spec.ports)
        parts.append(c)
    rewire(parts, overrides, allow_unknown=True)
    circuit = Circuit(parts, axes_of(parts), rig.source, overrides)
    if wiring:
        check_circuit(parts, overrides, port_path, label)
    return circuit


def check_circuit(parts: list, overrides: dict, port_path: str = "{component}.{port}",
                  label: str = "connections") -> list:
    """The checks a circuit passes before any run: the network's (two outputs on a signal,
    causality, algebraic loops: on the circuit alone, with a stand-in for what an experiment
    feeds), then the physical wiring (:func:`hydroline.circuit.wiring.check_wiring`).

    Parameters
    ----------
    parts : list
        The components, rewired by ``overrides``
    overrides : dict
        The rig's ``[connections]``, "component.port" -> signal: a port named
        there is named ``connections.<component>.<port>`` in a message
    port_path : str
        How a message names any other port (``{component}``, ``{port}``)
    label : str
        What a message of the network's checks starts with ("circuit")

    Returns
    -------
    list of str
        The wiring warnings given

    Raises
    ------
    CircuitError
        One line naming the component and port at fault
    """
    def path_of(c, port):
        if f"{c.name}.{port}" in overrides:
            return f"connections.{c.name}.{port}"
        return port_path.format(component=c.name, port=port)

    check_self_loops(parts, path_of)   # named by its port before the network calls it a loop
    with warnings.catch_warnings(record=True) as said:   # given once the wiring is found sound
        warnings.simplefilter("always")
        try:
            Network(parts + experiment_placeholders(parts))
        except NetworkError as e:
            raise CircuitError(f"{label}: {e}") from None
    found = check_wiring(parts, path_of)
    for w in said:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return found


def experiment_placeholders(parts: list) -> list:
    """Constant commands on every input signal no component outputs (what an experiment will
    drive: valve currents, position references), so a circuit can be checked on its own.

    Parameters
    ----------
    parts : list
        Components

    Returns
    -------
    list
        One :class:`~hydroline.components.StepCommand` per such signal
    """
    produced = {c.signal(p) for c in parts for p in c.outputs}
    out, seen = [], set()
    for c in parts:
        for port, spec in c.inputs.items():
            sig = c.signal(port)
            if sig not in produced and sig not in seen and spec.quantity in QUANTITY_UNIT:
                seen.add(sig)
                out.append(comp.StepCommand(name=f"experiment:{sig}", quantity=spec.quantity,
                                            connections={"command": sig}))
    return out
