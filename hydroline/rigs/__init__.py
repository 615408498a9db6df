"""Rig descriptions: TOML files whose quantities carry units, parsed into SI (a parameter set).

``load_rig()`` gives the embedded default, the 2005 paper's rig (``ayalew2005.toml``);
``load_rig(path)`` reads a user's file, which may give only what differs from a base (``[rig]
base =`` a shipped rig's name, ``"default"`` for the embedded one, or a rig file's path relative
to the file; :func:`compose_rig`) or a complete description. Parameters are addressed by their
dotted path in the file, e.g. ``supply.section2.length``; :meth:`Rig.set` changes one with
units.

Optional ``[supply.pressure_profile]`` / ``[return.pressure_profile]`` tables make the pump or
tank pressure vary in time (step, sine, ramp about ``<side>.pressure``, or a CSV table of the
absolute pressure); see :func:`hydroline.rigs.template.pressure_profile`.

A rig is either the template (the tables above; it expands into a circuit,
:mod:`hydroline.rigs.template`) or a circuit (``[circuit.<name>]`` components, see
:mod:`hydroline.circuit`; a file extending a rig may remove, change and add components and
place sub-circuits, :mod:`hydroline.circuit.compose`); a table the rig's kind does not read (a
``[supply]`` table in a circuit rig) is refused by name.

An optional ``[connections]`` table rewires component ports to other signals, e.g.
``"servovalve.supply_pressure" = "pump_pressure"`` connects the valve straight to the pump
(an ideal supply). The result is checked before a run: a port wired to a signal nobody outputs
is reported as unconnected, and a physically wrong wiring (a self-loop, a short circuit, an end
cut off or crossed, a servovalve's P not above its T) is refused in one line
(:mod:`hydroline.circuit.wiring`).
"""
from __future__ import annotations

import copy
import sys
from pathlib import Path

from ..units import UnitError, exact_quantity, parse_quantity
from .parameters import DerivedTable

__all__ = ["Rig", "RigError", "load_rig", "SCHEMA", "DEFAULT_RIG"]

DEFAULT_RIG = "ayalew2005.toml"
#: Folder of the rigs shipped with the package (this package's own folder: read as files,
#: without importlib.resources, ~5 ms of every command's start-up)
SHIPPED_RIGS = Path(__file__).parent
#: Longest list a rig parameter may hold (the laps have four), [items].
MAX_LIST_LENGTH = 64
#: Largest rig file read, [bytes]: a rig is a page of parameters, not a data set.
MAX_RIG_BYTES = 1 << 20


class RigError(ValueError):
    """A rig file or parameter that cannot be used; the message is one line naming it.

    Parameters
    ----------
    *args : str
        The message: one line naming the file or the parameter (and its unit)
    **kwargs : dict
        None taken (as ``ValueError``)
    """


#: A time-varying source pressure (``[supply.pressure_profile]``, ``[return.pressure_profile]``):
#: ``type`` step (``time``, ``final``), sine (``amplitude``, ``frequency``, ``start``), ramp
#: (``slope``, ``start``, ``end``) about ``<side>.pressure``, or table (``file``: CSV with
#: ``time [unit]``, ``pressure [unit]`` columns, absolute, path relative to the rig file).
_PROFILE = {"type": "str", "time": "s", "final": "Pa", "amplitude": "Pa", "frequency": "Hz",
            "start": "s", "end": "s", "slope": "Pa/s", "file": "str"}
_LINE = {"length": "m", "diameter": "m", "bulk_modulus": "Pa", "modes": "-",
         "creep_compliances": "list:1/Pa", "retardation_times": "list:s"}

#: The sections of the template rig whose parameters a component declares (unit, bounds):
#: section -> (component type of :mod:`hydroline.circuit.types`, keys; None for all).
#: A bound belongs on the component's declaration (``parameter(..., minimum=...)``), not in a
#: table here: rig validation, circuit files and ``hydroline circuit --types`` all read it.
COMPONENT_SECTIONS = {
    "servovalve": ("servovalve", None),
    "friction": ("friction", None),
    "controller": ("position_controller", None),
    "load": ("load", ("mass", "stiffness", "damping", "applied_force", "free_position")),
    "return.check_valve": ("check_valve", ("reverse_resistance", "forward_resistance")),
    "supply.accumulator": ("accumulator", ("capacity", "precharge_pressure", "polytropic_exponent",
                                           "connection_length", "connection_diameter", "model", "modes")),
    "return.accumulator": ("accumulator", ("capacity", "precharge_pressure", "polytropic_exponent",
                                           "connection_length", "connection_diameter", "model", "modes")),
    "actuator": ("actuator", ("bottom_area", "top_area", "stroke", "bulk_modulus", "moving_mass",
                              "initial_position", "gravity", "internal_leakage", "external_leakage")),
    "supply.manifold": ("resistance", ("resistance",)),
    "return.manifold": ("resistance", ("resistance",)),
}


def declarations(section: str) -> dict:
    """The declared parameters (:class:`hydroline.engine.Parameter`) of a template-rig section
    that maps onto a component type, the fluid or the rig-wide settings components take,
    key -> Parameter; {} for other sections.

    Parameters
    ----------
    section : str
        Section of the template rig, e.g. ``"fluid"``, ``"actuator"``, ``"rig"``

    Returns
    -------
    dict
        Parameter key -> :class:`hydroline.engine.Parameter` (unit, range, description)
    """
    known = _DECLARATIONS.get(section)
    if known is None:     # the component classes' declarations do not change: made once
        from ..circuit.types import COMPONENT_TYPES, FLUID_PARAMETERS, RIG_SETTINGS
        if section == "fluid":
            known = dict(FLUID_PARAMETERS)
        elif section == "rig":
            known = dict(RIG_SETTINGS)
        elif section not in COMPONENT_SECTIONS:
            known = {}
        else:
            ctype, keys = COMPONENT_SECTIONS[section]
            decl = COMPONENT_TYPES[ctype].declarations()
            known = {k: v for k, v in decl.items() if keys is None or k in keys}
        if len(_DECLARATIONS) < 1024:     # (bounded: any section name may be asked for)
            _DECLARATIONS[section] = known
    return dict(known)


_DECLARATIONS: dict = {}


def _section_units(section: str, units: dict) -> dict:
    """A section's keys -> SI unit: the components' declarations, then the template's own."""
    return {**{k: d.unit for k, d in declarations(section).items()}, **units}


#: Every parameter a rig file may hold: section -> key -> SI unit ("-" dimensionless,
#: "str" text, "list:<unit>" list of quantities). Sections that are components (servovalve,
#: friction, controller, load, accumulators, check valve, actuator) take units from the
#: components' own declarations (:data:`COMPONENT_SECTIONS`); what is listed here is only
#: what the template rig adds (e.g. ``actuator.area``, ``actuator.dead_volume``). Circuit
#: files (``[circuit.<name>]``) are read with :mod:`hydroline.circuit`. Plausible ranges,
#: defaults and the ``allow_implausible`` override: :mod:`hydroline.rigs.parameters`.
SCHEMA = DerivedTable({
    "rig": {"name": "str", "modes_per_section": "-", "base": "str", "line_method": "str",
            "scenario": "str", "allow_implausible": "list:str"},
    "fluid": {"density": "kg/m^3", "kinematic_viscosity": "m^2/s", "bulk_modulus": "Pa",
              "gas_release_pressure": "Pa", "air_content": "-", "air_polytropic_exponent": "-",
              "cavity_pressure": "Pa", "cavity_pressure_drop": "Pa"},
    "supply": {"pressure": "Pa"},
    "supply.pressure_profile": _PROFILE,
    "supply.section1": _LINE, "supply.section2": _LINE,
    "supply.manifold": {"volume": "m^3"},
    "supply.accumulator": {},
    "return": {"pressure": "Pa"},
    "return.pressure_profile": _PROFILE,
    "return.section1": _LINE, "return.section2": _LINE,
    "return.manifold": {"volume": "m^3"},
    "return.check_valve": {},
    "return.accumulator": {},
    "servovalve": {},
    "actuator": {"area": "m^2", "dead_volume": "m^3"},
    "friction": {},
    "load": {},
    "controller": {},
    "scenario.open-loop-step": {"current": "A", "time": "s", "t_end": "s", "initial_current": "A"},
    "scenario.closed-loop-sine": {"amplitude": "m", "frequency": "Hz", "offset": "m",
                                  "t_end": "s", "initial_position": "m"},
    "scenario.position-step": {"axis": "str", "step": "m", "time": "s", "t_end": "s"},
}, _section_units)


def _flatten(tree, prefix="", depth=0):
    out = {}
    for k, v in tree.items():
        path = f"{prefix}{k}"
        if isinstance(v, dict):
            if depth >= 4:
                raise RigError(f"{path[:60]}...: tables nested too deeply; a rig parameter is "
                               f"section.key or section.subsection.key")
            out.update(_flatten(v, path + ".", depth + 1))
        else:
            out[path] = v
    return out


#: The tables a circuit rig (``[circuit.<name>]`` components) reads besides its components:
#: the rig's own settings, the oil, the experiments, rewired ports, and a ``[controller]``
#: that closes the loop of an axis whose circuit has no position controller. The template
#: rig's other tables (``[supply]``, ``[servovalve]``, ``[actuator]``, ...) describe
#: components a circuit gives as its own and are refused there by name.
CIRCUIT_RIG_TABLES = ("rig", "fluid", "scenario", "connections", "controller", "circuit")


def _unused_by_circuit(path: str, context: dict) -> str | None:
    """The message refusing ``path`` in a circuit rig that does not read it; None if read."""
    if path.split(".", 1)[0] in CIRCUIT_RIG_TABLES or \
            not any(k.startswith("circuit.") for k in context):
        return None
    table = path.rpartition(".")[0] or path
    return (f"{path}: a circuit rig does not use the [{table}] table (the template rig's); its "
            f"components and their values are its [circuit.<name>] tables: remove it, or give "
            f"the value on the component")


def _parse(path: str, raw, context: dict | None = None):
    unused = _unused_by_circuit(path, context or {})
    if unused:
        raise RigError(unused)
    if path.startswith("circuit."):
        # [circuit.<component>] tables: units from the component type's declarations
        from ..circuit import CircuitError, parse_circuit_value
        try:
            return parse_circuit_value(path, raw, context or {}, _parse_as)
        except CircuitError as e:
            raise RigError(str(e)) from None
    if path.startswith("connections."):
        # [connections] "component.port" = "signal": rewire one port (see build_network)
        if not isinstance(raw, str) or not raw:
            raise RigError(f"{path}: a connection names a signal, e.g. \"pump_pressure\"; got {raw!r}")
        return raw
    section, _, key = path.rpartition(".")
    if section not in SCHEMA and path.startswith("scenario."):
        # [scenario.<name>] type = "axis-commands": an experiment the rig defines itself
        from ..scenario_schema import is_own_scenario, parse_scenario_value
        if is_own_scenario(path, context or {}):
            try:
                return parse_scenario_value(path, raw, context or {}, _parse_as)
            except ValueError as e:
                raise RigError(str(e)) from None
    if section not in SCHEMA:
        known = ", ".join(sorted(SCHEMA))
        owners = [name for name in sorted(SCHEMA) if key in SCHEMA[name]] if not section else []
        hint = (f"; a top-level '{key}' belongs in a table: did you mean "
                + " or ".join(f"[{name}] {key}" for name in owners) + "?") if owners else ""
        raise RigError(f"{path}: unknown component/section '{section or key}'{hint} "
                       f"(known: {known})")
    unit = SCHEMA[section].get(key)
    if unit is None:
        raise RigError(f"{path}: unknown parameter '{key}' of '{section}' "
                       f"(known: {', '.join(sorted(SCHEMA[section]))})")
    if path in SWITCHED_OFF_BY_TEXT:
        if isinstance(raw, str) and raw.strip().lower() in ("off", "none"):
            return None
        try:
            return _parse_as(path, raw, unit)
        except RigError as e:
            raise RigError(f'{e}; or "off" (the feature switched off)') from None
    return _parse_as(path, raw, unit)


#: Parameters whose feature is on by default and which a rig switches off with the text
#: "off" (or "none"), held as None: the cavity model (M42, M45)
SWITCHED_OFF_BY_TEXT = frozenset({"fluid.cavity_pressure"})


def _parse_as(path: str, raw, unit: str):
    """One value in the SI ``unit`` ("str" text, "-" dimensionless, "list:<unit>")."""
    if unit == "str":
        if not isinstance(raw, str):
            raise RigError(f"{path}: expected text, got {raw!r}")
        return raw
    if unit.startswith("list:") and not (isinstance(raw, list) and len(raw) <= MAX_LIST_LENGTH):
        what = "text" if unit == "list:str" else f"quantities in [{unit[5:]}]"
        size = f" of {len(raw)} items" if isinstance(raw, list) else ""
        raise RigError(f"{path}: expected a list of at most {MAX_LIST_LENGTH} {what}, got a "
                       f"{type(raw).__name__}{size}")
    if unit == "list:str":
        if not all(isinstance(v, str) for v in raw):
            raise RigError(f"{path}: expected a list of text, e.g. [\"actuator.moving_mass\"]")
        return list(raw)
    try:
        if unit.startswith("list:"):
            return [parse_quantity(v, unit[5:], f"{path}[{i}]") for i, v in enumerate(raw)]
        return parse_quantity(raw, "dimensionless" if unit == "-" else unit, path)
    except UnitError as e:
        raise RigError(str(e)) from None


_IMMUTABLE = (float, int, str, bool, type(None))


def _copy_values(values: dict) -> dict:
    """A deep copy of a rig's value dict: numbers and text shared (immutable), anything else
    (lists, tables) deep-copied (a deepcopy of every value took ~0.25 ms per rig, paid per
    variant of a sweep)."""
    return {k: v if type(v) in _IMMUTABLE else copy.deepcopy(v) for k, v in values.items()}


class Rig:
    """A parsed rig: parameters in SI, addressed by dotted paths.

    Parameters
    ----------
    values : dict
        path -> SI value (float), text or list
    raw : dict
        path -> the value as written (with its unit)
    source : str
        Where it came from
    """

    def __init__(self, values: dict, raw: dict, source: str):
        self.values, self.raw, self.source = values, raw, source

    def __getitem__(self, path: str):
        try:
            return self.values[path]
        except KeyError:
            raise RigError(f"{path}: not set in rig {self.source}") from None

    def get(self, path: str, default=None):
        """The value at ``path`` (SI), or ``default`` when the rig does not set it.

        Parameters
        ----------
        path : str
            Dotted parameter path, e.g. ``"actuator.moving_mass"``
        default : object
            What to return when ``path`` is not set

        Returns
        -------
        object
            SI value (float), text or list; ``default`` when not set
        """
        return self.values.get(path, default)

    def __contains__(self, path):
        return path in self.values

    #: Parameters a rig's summary shows where the rig sets them (as written, with units).
    KEY_PARAMETERS = ("supply.pressure", "return.pressure", "fluid.density",
                      "fluid.bulk_modulus", "supply.section2.length", "return.section2.length",
                      "actuator.stroke", "actuator.moving_mass", "servovalve.rated_current",
                      "controller.proportional_gain", "rig.modes_per_section")

    def _summary_rows(self):
        """(label, value) rows of the rig's summary: name, source, experiments, components
        or key parameters as written."""
        scenarios = sorted({p.split(".")[1] for p in self.values if p.startswith("scenario.")})
        components = [p[len("circuit."):-len(".type")] for p in self.values
                      if p.startswith("circuit.") and p.endswith(".type")]
        rows = [("name", self.get("rig.name", "")), ("source", self.source),
                ("scenario", self.get("rig.scenario", "open-loop-step")),
                ("experiments in the rig", ", ".join(scenarios) or "-")]
        if components:
            rows.append(("circuit components", f"{len(components)}: {', '.join(components)}"))
        rows += [(p, self.raw[p]) for p in self.KEY_PARAMETERS if p in self.raw]
        rows.append(("parameters set", len(self.values)))
        return rows

    def __repr__(self) -> str:
        from ..engine.display import text_block

        return text_block("hydroline Rig", self._summary_rows())

    def _repr_html_(self) -> str:
        from ..engine.display import html_block

        return html_block("hydroline Rig", self._summary_rows(),
                          note="rig[path] gives a value in SI; rig.to_toml() every value")

    def set(self, path: str, value) -> "Rig":
        """Set one parameter from a quantity with units (``"1.5 m"``) or, for text and
        dimensionless ones, a plain value. Returns self.

        Parameters
        ----------
        path : str
            Dotted parameter path, e.g. ``"supply.section1.length"``
        value : object
            Quantity as text with its unit (``"1.5 m"``, ``"3000 psi"``), or text,
            number or list as the rig file would hold it

        Returns
        -------
        Rig
            self, for chaining

        Raises
        ------
        RigError
            One line naming the path and the unit expected
        """
        self.values[path] = _parse(path, value, {**self.raw, path: value})
        self.raw[path] = value
        return self

    def copy(self) -> "Rig":
        """An independent copy (values and raw values copied deeply).

        Returns
        -------
        Rig
            An independent copy (changing it leaves this rig as it is)
        """
        return Rig(_copy_values(self.values), _copy_values(self.raw), self.source)

    def to_toml(self) -> str:
        """The rig as TOML text with its units (the raw values).

        Returns
        -------
        str
            One ``[section]`` table per dotted prefix, each value as written
        """
        sections = {}
        for path, v in self.raw.items():
            sec, _, key = path.rpartition(".")
            sections.setdefault(sec, {})[key] = v
        lines = []
        for sec in sections:
            lines.append(f"[{sec}]")
            for k, v in sections[sec].items():
                lines.append(f"{k} = {_toml_value(v)}")
            lines.append("")
        return "\n".join(lines)


def _toml_value(v):
    if isinstance(v, str):
        return '"' + v.replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(v)


def shipped_rig(name: str) -> str | None:
    """The file of a rig shipped with the package named ``name`` ("two_axis" or
    "two_axis.toml"), or None.

    Parameters
    ----------
    name : str
        Rig name, with or without ``.toml``; a path (with a slash) is never a shipped rig

    Returns
    -------
    str or None
        File name inside :mod:`hydroline.rigs`, or None when no such rig is shipped
    """
    if "/" in name or "\\" in name:
        return None
    fname = name if name.endswith(".toml") else f"{name}.toml"
    return fname if SHIPPED_RIGS.joinpath(fname).is_file() else None


def shipped_rigs() -> list[str]:
    """The names of the rigs shipped with the package (``"two_axis"``, ...), sorted.

    Returns
    -------
    list of str
        Names without ``.toml``, as ``load_rig`` and ``[rig] base`` take them
    """
    return sorted(p.name[:-5] for p in SHIPPED_RIGS.iterdir()
                  if p.name.endswith(".toml"))


#: Table kind (:mod:`hydroline.cache`) of rig files' TOML tables as parsed, keyed by the
#: SHA-256 of the file's text (:func:`parse_toml`).
TOML_TABLES = "rig_toml"


def parse_toml(text: str, source: str) -> dict:
    """The TOML tables of a rig file's text: from the cache where the same text was parsed
    before (keyed by its SHA-256, the entry verified as every table is), else parsed by
    :mod:`tomllib` and stored where JSON holds them exactly (no dates): a command then
    neither imports nor runs the parser (~2.5 ms of a warm ``simulate``).

    Parameters
    ----------
    text : str
        The file's text
    source : str
        Where it came from, for the message

    Returns
    -------
    dict
        The tables, as :func:`tomllib.loads` gives them

    Raises
    ------
    RigError
        Not valid TOML
    """
    import hashlib
    import json

    from ..cache import load_table, store_table

    key = (f"toml py{sys.version_info[0]}.{sys.version_info[1]} "
           + hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest())
    tree = load_table(TOML_TABLES, key)
    if isinstance(tree, dict):
        return tree
    import tomllib

    try:
        tree = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise RigError(f"{source}: not valid TOML: {e}") from None
    try:
        exact = json.loads(json.dumps(tree)) == tree
    except (TypeError, ValueError, RecursionError):   # dates, or nested too deeply
        exact = False
    if exact:
        store_table(TOML_TABLES, key, tree)
    return tree


def _read_shipped(fname: str) -> tuple[dict, str]:
    text = SHIPPED_RIGS.joinpath(fname).read_text(encoding="utf-8")
    return parse_toml(text, f"embedded:{fname}"), f"embedded:{fname}"


def _read_toml(path) -> tuple[dict, str]:
    if path is None:
        return _read_shipped(DEFAULT_RIG)
    p = Path(path)
    shipped = None if p.is_file() else shipped_rig(str(path))
    if shipped is not None and p.suffix != ".toml":   # a shipped rig's name, e.g. "two_axis"
        return _read_shipped(shipped)
    if not p.is_file():   # a file name is a file: not silently the shipped rig of that name
        hint = (f" (the shipped rig of that name is '{Path(shipped).stem}', without .toml)"
                if shipped is not None else "")
        raise RigError(f"rig file not found: {path}{hint}")
    try:
        if p.stat().st_size > MAX_RIG_BYTES:
            raise RigError(f"{path}: {p.stat().st_size} bytes is too large for a rig file "
                           f"(at most {MAX_RIG_BYTES} bytes)")
        return parse_toml(p.read_text(encoding="utf-8"), str(path)), str(p)
    except UnicodeDecodeError as e:
        raise RigError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start})") from None
    except RecursionError:
        raise RigError(f"{path}: nested too deeply to be a rig file (arrays or tables "
                       f"inside each other hundreds of levels deep)") from None
    except OSError as e:
        raise RigError(f"{path}: cannot read the rig file ({e.strerror or e})") from None


def load_rig(path=None) -> Rig:
    """Load a rig file (the embedded default when ``path`` is None); a rig shipped with the
    package may be named instead of a path (``load_rig("two_axis")``).

    A file with ``[rig] base = "<shipped rig>"`` (``"default"``: the embedded rig) or ``base =
    "<path>.toml"`` (relative to the file) starts from that rig and changes only what it
    lists; a circuit file may also remove components and place sub-circuits
    (:mod:`hydroline.circuit.compose`).

    Parameters
    ----------
    path : str or Path
        Rig file, or the name of a shipped rig; None for the default
        (``ayalew2005.toml``)

    Returns
    -------
    Rig
        Parameters in SI, with the raw values as written (a base's, the sub-circuits'
        components written out)

    Raises
    ------
    RigError
        One line: file missing or unreadable, bad TOML, a parameter's bad value/unit,
        a base not found or naming itself, an edit of no component
    """
    tree, source = _read_toml(path)
    try:
        tree = compose_rig(tree, source)
    except RecursionError:
        raise RigError(f"{source}: nested too deeply to be a rig file") from None
    tree.pop("subcircuit", None)          # placed: its components are in [circuit]
    raw = _flatten(tree)
    values = {k: _parse(k, v, raw) for k, v in raw.items()}
    return Rig(values, raw, source)


#: Longest chain of bases (a base's base ...), [files].
MAX_BASE_DEPTH = 16


def compose_rig(tree: dict, source: str, chain: tuple = ()) -> dict:
    """A rig file's tables with its ``[rig] base`` resolved (recursively), its circuit edits
    applied and its sub-circuits placed (:func:`hydroline.circuit.compose.extend`).

    Parameters
    ----------
    tree : dict
        The file's TOML tables as read
    source : str
        Where they came from (a path, or ``embedded:<name>.toml``)
    chain : tuple
        The files extending this one (a base may not name one of them)

    Returns
    -------
    dict
        The composed tables, without ``[rig] base`` and ``[remove]``; sub-circuit
        definitions kept under ``subcircuit``

    Raises
    ------
    RigError
        One line naming the base or the edit at fault
    """
    from ..circuit.compose import extend, has_circuit_edits   # (the circuit layer is below)
    from ..circuit.types import CircuitError
    rig = tree.get("rig")
    base = rig.get("base") if isinstance(rig, dict) else None
    try:
        if base is None:
            return extend({}, tree)
        if len(chain) >= MAX_BASE_DEPTH:
            raise RigError(f"rig.base: more than {MAX_BASE_DEPTH} bases in a chain ({source})")
        base_tree, base_source = _read_base(base, source)
        seen = [_identity(s) for s in chain + (source,)]
        if _identity(base_source) in seen:
            loop = chain[seen.index(_identity(base_source)):] + (source, base_source)
            raise RigError(f"rig.base: a cycle of bases: {' -> '.join(map(_short, loop))}")
        base_tree = compose_rig(base_tree, base_source, chain + (source,))
        if has_circuit_edits(tree) and "circuit" not in base_tree:
            base_tree = template_circuit(base_tree, base_source)
        return extend(base_tree, tree)
    except CircuitError as e:
        raise RigError(str(e)) from None


#: The tables a template rig has and a circuit rig does not (they become ``[circuit.*]``).
TEMPLATE_TABLES = ("supply", "return", "servovalve", "actuator", "friction", "load")


def template_circuit(tree: dict, source: str) -> dict:
    """The tables of a template rig (``[supply]``, ``[servovalve]``, ...) as circuit tables
    (``[circuit.<name>]``): what a file with circuit edits extends when its base is a template.

    The template is expanded as it is built (:func:`hydroline.rigs.template.expand`): the same
    components, ports and values, each value written with its unit. Values the template
    derives (the chambers' volumes at mid-stroke, the hoses' nominal pressures) are written as
    the numbers they come to.

    Parameters
    ----------
    tree : dict
        The template rig's tables, composed
    source : str
        Where they came from

    Returns
    -------
    dict
        The same rig's tables as a circuit rig's: ``[circuit.*]`` and the template's
        ``[rig]``, ``[fluid]``, ``[controller]``, ``[scenario.*]``, ``[connections]``

    Raises
    ------
    RigError
        A template with a pressure profile (its waveform is not written out as a
        circuit's), or one line naming a bad value of the template
    """
    from ..circuit.types import COMPONENT_TYPES
    from .template import expand
    for side in ("supply", "return"):
        if isinstance(tree.get(side), dict) and "pressure_profile" in tree[side]:
            raise RigError(f"{side}.pressure_profile: a template rig with a pressure profile "
                           f"({_short(source)}) cannot take circuit edits; extend "
                           f"\"ayalew2005_circuit\" and give the pump a waveform instead")
    raw = _flatten(tree)
    rig = Rig({k: _parse(k, v, raw) for k, v in raw.items()}, raw, source)
    circuit = {}
    for spec in expand(rig):
        ctype = COMPONENT_TYPES[spec.type]
        table = {"type": spec.type}
        for key, v in spec.params.items():
            unit = ctype.unit_of(key, spec.params)
            if isinstance(v, (str, bool)) or unit in (None, "-", "str"):
                table[key] = v
            elif isinstance(v, (list, tuple)):
                table[key] = [exact_quantity(x, unit.removeprefix("list:")) for x in v]
            else:
                table[key] = exact_quantity(v, unit)
        if spec.ports:
            table["ports"] = dict(spec.ports)
        if spec.terms:
            table["terms"] = dict(spec.terms)
        circuit[spec.name] = table
    out = {k: v for k, v in tree.items() if k not in TEMPLATE_TABLES}
    out["circuit"] = circuit
    return out


def _identity(source: str) -> str:
    return source if source.startswith("embedded:") else str(Path(source).resolve())


def _short(source: str) -> str:
    """A rig's source as a message names it: a shipped rig by name, a file by its path."""
    return source[len("embedded:"):-len(".toml")] if source.startswith("embedded:") else source


def _read_base(base, source: str) -> tuple[dict, str]:
    """(tables, source) of the rig ``[rig] base`` names in the file at ``source``: a shipped
    rig's name (``"default"``: the embedded rig), or a path ending in ``.toml`` or holding a
    slash, relative to that file; its relative table files anchored to its folder."""
    names = shipped_rigs()
    if not isinstance(base, str) or not base.strip() or base != base.strip():
        raise RigError(f"rig.base: {repr(base)[:60]} names no rig: give a shipped rig's name "
                       f"({', '.join(names)}; \"default\" is {DEFAULT_RIG[:-5]}) or a rig "
                       f"file's path ending in .toml")
    if base in ("default", DEFAULT_RIG):
        return _read_shipped(DEFAULT_RIG)
    if not any(ch in base for ch in "/\\") and not base.endswith(".toml"):
        if base not in names:
            import difflib   # (only for the message)

            close = difflib.get_close_matches(base, names, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise RigError(f"rig.base: {base!r} is no shipped rig ({', '.join(names)}){hint}; "
                           f"a rig file's path ends in .toml (relative to the file naming it)")
        return _read_shipped(f"{base}.toml")
    here = Path(__file__).parent if source.startswith("embedded:") else Path(source).parent
    path = Path(base) if Path(base).is_absolute() else here / base
    if not path.is_file():
        hint = (f" (the shipped rig of that name is '{Path(base).stem}', without .toml)"
                if Path(base).stem in names and "/" not in base else "")
        raise RigError(f"rig.base: rig file not found: {path} (relative to {_short(source)}){hint}")
    tree, found = _read_toml(path)
    return _anchor_files(tree, path.parent), found


def _anchor_files(tree, folder: Path):
    """``tree`` with every relative ``file = "..."`` (a table command, a pressure profile)
    made absolute against ``folder``, the folder of the file that wrote it."""
    if not isinstance(tree, dict):
        return tree
    out = {k: _anchor_files(v, folder) for k, v in tree.items()}
    if isinstance(out.get("file"), str) and not Path(out["file"]).is_absolute():
        out["file"] = str(folder / out["file"])
    return out
