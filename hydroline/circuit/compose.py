"""Circuits made of circuits: a rig that extends another, and sub-circuits placed by name.

Works on the raw TOML tables of rig files (values as written, units and all), before the
builder (:mod:`hydroline.circuit.builder`) sees them; every message is one line
(:class:`~hydroline.circuit.types.CircuitError`) naming the table at fault. Where the base
comes from (a shipped rig or a file) is :func:`hydroline.rigs.load_rig`'s business; this
module gets the base's tables already composed.

**Extending a rig** (``[rig] base = ...``, :func:`extend`). The file's tables other than its
circuit are merged into the base's key by key (``[fluid]``, ``[scenario.*]``, ``[rig]``,
``[connections]``: the file wins). Its circuit edits, in this order:

1. ``[remove] components = ["name", ...]`` takes components out of the base (a sub-circuit
   instance's prefix, ``"axis2"``, takes all of its components); ``[remove] terms =
   ["supply.junction.axis2"]`` takes a flow term, and the port of that name, off a junction
   or volume;
2. a ``[circuit.<name>]`` table naming a component of the base changes only what it lists:
   a parameter's value, one port re-pointed (``ports = { supply_pressure = "filter_outlet" }``
   leaves the other ports as they were), a flow term added; its ``type``, if given, must be
   the base component's (remove it first to put another type in its place);
3. a table naming no component of the base, with a ``type``, adds a component; without a
   ``type`` it is refused (a misspelt name would otherwise change nothing).

After the edits, a port that a removed component left with nothing at its other end (a
signal it shared with that component alone, or read from it) is refused by name, unless an
experiment drives it (a valve current, a position reference); so is a ``[connections]``
entry of a removed component.

**Sub-circuits** (:func:`instantiate`). ``[subcircuit.<group>]`` defines a named group of
components with its own ports::

    [subcircuit.axis]
    ports = ["supply_pressure", "return_pressure"]     # the signals it joins outside

    [subcircuit.axis.servovalve]
    type = "servovalve"
    ...
    ports = { supply_pressure = "supply_pressure", current = "valve_current", ... }

and ``[circuit.<prefix>] subcircuit = "<group>"`` places one copy under ``<prefix>``::

    [circuit.axis2]
    subcircuit = "axis"
    ports = { supply_pressure = "supply.manifold_pressure", return_pressure = "return.manifold_pressure" }
    actuator = { initial_position = "0 mm" }     # the member's values changed, as in 2.

Member ``m`` becomes component ``<prefix>.m``; a signal inside the group is the group's own
(``valve_current`` becomes ``axis2.valve_current``) unless it is one of the group's ports,
which the instance joins to its outside signals (every port must be joined). A member may
itself be an instance of another group (``subcircuit = "..."`` in place of ``type``). The
group definitions of a base stay available to the file that extends it.
"""
from __future__ import annotations

import copy
import json

from .types import COMPONENT_TYPES, CircuitError
from .wiring import HYDRAULIC

__all__ = ["extend", "instantiate", "change_component", "components_by_name", "has_circuit_edits",
           "COMPOSE_TABLES"]

#: The tables of a rig file that compose a circuit; the builder never sees the last two.
COMPOSE_TABLES = ("circuit", "remove", "subcircuit")
#: What ``[remove]`` takes: key -> what its list names.
REMOVE_KEYS = {"components": "component names (a sub-circuit instance's prefix: all of its)",
               "terms": "flow terms, \"component.term\""}
#: Keys of an instance's table besides its members' changes.
INSTANCE_KEYS = ("subcircuit", "ports")
#: Deepest nesting of sub-circuits (a group placing a group placing ...).
MAX_NESTING = 8


def has_circuit_edits(tree: dict) -> bool:
    """True when a rig file's tables hold circuit components or edits (``[circuit.*]``,
    ``[remove]``, ``[subcircuit.*]``).

    Parameters
    ----------
    tree : dict
        The file's TOML tables as read

    Returns
    -------
    bool
        Whether the tables hold a circuit or edit one
    """
    return any(k in tree for k in COMPOSE_TABLES)


def _quoted(name: str) -> str:
    """``name`` as a TOML key in a table header (quoted, escaped, when not a bare key)."""
    bare = name.replace("_", "").replace("-", "")
    return name if bare.isascii() and bare.isalnum() else json.dumps(name, ensure_ascii=False)


def _shown(value) -> str:
    """A value as a one-line message shows it (its repr, cut at 60 characters)."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _hint(name: str, known) -> str:
    """`` (did you mean 'x'?)`` for a close name among ``known``, else the first few names."""
    import difflib   # (only for a message: not at every command's start)

    known = list(known)
    close = difflib.get_close_matches(name, known, n=1)
    if close:
        return f" (did you mean '{close[0]}'?)"
    more = f", ... {len(known) - 6} more" if len(known) > 6 else ""
    return f" (components: {', '.join(known[:6])}{more})" if known else ""


def _table(value, where: str, example: str) -> dict:
    if not isinstance(value, dict):
        raise CircuitError(f"{where}: expected a table, e.g. {example}; got {_shown(value)}")
    return value


def components_by_name(tables: dict, known=(), where: str = "circuit") -> dict:
    """Component name -> table of a ``[circuit]`` (or sub-circuit) tree, whether a dotted
    name is written quoted (``[circuit."axis1.valve"]``) or as nested tables
    (``[circuit.axis1.valve]``, as :meth:`hydroline.rigs.Rig.to_toml` writes it).

    A table is a component's when it has a ``type`` or ``subcircuit``, holds a value that is
    not a table, or is named in ``known``; a table holding only tables is a level of names.

    Parameters
    ----------
    tables : dict
        The tree as read
    known : iterable of str
        Component names already in the rig (an edit of one may hold only its ports)
    where : str
        The tree's path, for a message

    Returns
    -------
    dict
        Component name -> its table, in the order written

    Raises
    ------
    CircuitError
        One line: a value that is not a component's table, a component given twice
    """
    known, out = set(known), {}

    def walk(tree, prefix):
        for key, value in tree.items():
            name = f"{prefix}{key}"
            if not isinstance(value, dict):
                raise CircuitError(f"{where}.{_quoted(name)}: expected a component's table, "
                                   f"e.g. [{where}.{_quoted(name)}] type = \"...\"; got "
                                   f"{_shown(value)}")
            if (name in known or "type" in value or "subcircuit" in value
                    or any(not isinstance(v, dict) for v in value.values()) or not value):
                if name in out:
                    raise CircuitError(f"{where}.{_quoted(name)}: given twice (as a quoted "
                                       f"name and as nested tables); give it once")
                out[name] = value
            else:
                walk(value, name + ".")

    walk(tables, "")
    return out


def _merge(into: dict, new: dict) -> dict:
    """``new`` merged into a copy of ``into``, table by table (``new`` wins)."""
    out = dict(into)
    for k, v in new.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) \
            else copy.deepcopy(v)
    return out


def change_component(current: dict, change: dict, where: str) -> dict:
    """A component's table with ``change`` applied: values replaced, ports and terms one by
    one; a ``type`` in ``change`` must be the component's.

    Parameters
    ----------
    current : dict
        The component's table as written (type, values, ports, terms)
    change : dict
        What changes
    where : str
        The changing table, for a message (``circuit.servovalve``)

    Returns
    -------
    dict
        A new table

    Raises
    ------
    CircuitError
        One line, where ``change`` gives another type
    """
    if "type" in change and change["type"] != current.get("type"):
        raise CircuitError(f"{where}.type: {change['type']!r} would change the type of the "
                           f"component ({current.get('type')!r}); to put another type in its "
                           f"place remove it first ([remove] components = [...]) and give it whole")
    out = copy.deepcopy(current)
    for k, v in change.items():
        if k in ("ports", "terms") and isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = {**out[k], **copy.deepcopy(v)}
        else:
            out[k] = copy.deepcopy(v)
    return out


def _groups(base: dict, tree: dict) -> dict:
    """The sub-circuit definitions a file may place: the base's, then its own (by name)."""
    out = dict(base.get("subcircuit", {}))
    own = _table(tree.get("subcircuit", {}), "subcircuit",
                 "[subcircuit.axis] ports = [\"supply_pressure\"]")
    for name, group in own.items():
        _table(group, f"subcircuit.{name}", f"[subcircuit.{name}] ports = [...] and "
               f"[subcircuit.{name}.<component>] tables")
        out[name] = group
    return out


def _group_parts(gname: str, group: dict) -> tuple[list, dict]:
    """(ports, members) of a sub-circuit definition, checked."""
    where = f"subcircuit.{_quoted(gname)}"
    ports = group.get("ports", [])
    if not (isinstance(ports, list) and all(isinstance(p, str) and p for p in ports)):
        raise CircuitError(f"{where}.ports: the group's ports are a list of signal names, e.g. "
                           f"ports = [\"supply_pressure\", \"return_pressure\"]; got {_shown(ports)}")
    members = components_by_name({m: t for m, t in group.items() if m != "ports"}, (), where)
    if not members:
        raise CircuitError(f"{where}: a sub-circuit without components; give them as "
                           f"[{where}.<name>] tables with a type")
    used = {s for t in members.values() for s in (t.get("ports") or {}).values()
            if isinstance(t.get("ports"), dict)}
    for p in ports:
        if p not in used:
            raise CircuitError(f"{where}.ports: port '{p}' is joined to none of its components "
                               f"(name it as a signal in one of their ports)")
    return ports, members


def instantiate(prefix: str, table: dict, groups: dict, nesting: tuple = ()) -> dict:
    """The components of one sub-circuit instance, ``[circuit.<prefix>] subcircuit = ...``.

    Parameters
    ----------
    prefix : str
        The instance's name: its components are ``<prefix>.<member>``
    table : dict
        The instance's table: ``subcircuit``, ``ports`` (group port -> outside signal), and
        per member a table of changed values
    groups : dict
        Sub-circuit name -> definition (``[subcircuit.<name>]`` tables)
    nesting : tuple
        The groups being placed around this one (a group may not place itself)

    Returns
    -------
    dict
        Component name -> table (type, values, ports with the signals joined), in the
        group's order

    Raises
    ------
    CircuitError
        One line naming the instance's table: an unknown group or member, a port not joined
    """
    where = f"circuit.{_quoted(prefix)}"
    gname = table.get("subcircuit")
    if not isinstance(gname, str) or gname not in groups:
        known = ", ".join(groups) or "none defined: add [subcircuit.<name>] tables"
        raise CircuitError(f"{where}.subcircuit: no sub-circuit {_shown(gname)} (sub-circuits: "
                           f"{known})")
    if gname in nesting or len(nesting) >= MAX_NESTING:
        raise CircuitError(f"{where}.subcircuit: sub-circuit '{gname}' places itself "
                           f"({' -> '.join(nesting + (gname,))})")
    gports, members = _group_parts(gname, groups[gname])
    joined = _table(table.get("ports", {}), f"{where}.ports",
                    f"ports = {{ {gports[0] if gports else 'port'} = \"signal\" }}")
    for p in joined:
        if p not in gports:
            raise CircuitError(f"{where}.ports.{_quoted(p)}: sub-circuit '{gname}' has no port {p!r} "
                               f"(ports: {', '.join(gports) or 'none'})")
    for p in gports:
        if not isinstance(joined.get(p), str) or not joined.get(p):
            raise CircuitError(f"{where}.ports: port '{p}' of sub-circuit '{gname}' is not "
                               f"joined: give ports = {{ {p} = \"<signal>\", ... }}")
    changes = components_by_name({k: v for k, v in table.items() if k not in INSTANCE_KEYS},
                                 members, where)
    for m, change in changes.items():
        if m not in members:
            raise CircuitError(f"{where}.{_quoted(m)}: sub-circuit '{gname}' has no component {m!r}"
                               f"{_hint(m, members)}")
        _table(change, f"{where}.{m}", f"{m} = {{ <parameter> = \"<value with unit>\" }}")

    def signal(s):
        return joined[s] if s in joined else f"{prefix}.{s}"

    out = {}
    for m, member in members.items():
        if m in changes:
            member = change_component(member, changes[m], f"{where}.{m}")
        member = copy.deepcopy(member)
        ports = member.get("ports")
        if isinstance(ports, dict):
            member["ports"] = {p: signal(s) if isinstance(s, str) else s for p, s in ports.items()}
        if "subcircuit" in member:
            out.update(instantiate(f"{prefix}.{m}", member, groups, nesting + (gname,)))
        else:
            out[f"{prefix}.{m}"] = member
    return out


def _remove(components: dict, remove, connections: dict, own_connections) -> list:
    """Take out what ``[remove]`` lists (in place), with the base's ``[connections]`` entries
    of removed components; the ports taken away, as (what was removed, its type, port,
    signal)."""
    if remove is None:
        return []
    _table(remove, "remove", "[remove] components = [\"return.check_valve\"]")
    gone, taken = [], set()
    for key, names in remove.items():
        if key not in REMOVE_KEYS:
            raise CircuitError(f"remove.{_quoted(key)}: [remove] takes "
                               + " and ".join(f"{k} = [...], {v}" for k, v in REMOVE_KEYS.items()))
        if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
            raise CircuitError(f"remove.{key}: expected a list of {REMOVE_KEYS[key]}, got "
                               f"{_shown(names)}")
    for name in remove.get("components", []):
        hit = [name] if name in components else \
            [c for c in components if c.startswith(name + ".")]
        if not hit:
            raise CircuitError(f"remove.components: no component {name!r} in the base rig"
                               f"{_hint(name, components)}")
        for c in hit:
            table = components.pop(c)
            taken.add(c)
            gone += [(f"'{c}'", table.get("type"), p, s)
                     for p, s in (table.get("ports") or {}).items()]
    for ref in remove.get("terms", []):
        cname, _, term = ref.rpartition(".")
        table = components.get(cname)
        if table is None:
            raise CircuitError(f"remove.terms: no component {cname!r} in the base rig"
                               f"{_hint(cname, components)} (a term is \"component.term\")")
        terms = table.get("terms")
        if not isinstance(terms, dict) or term not in terms:
            have = ", ".join(terms) if isinstance(terms, dict) else "none"
            raise CircuitError(f"remove.terms: component {cname!r} has no flow term {term!r} "
                               f"(terms: {have})")
        table = components[cname] = copy.deepcopy(table)
        del table["terms"][term]
        if term in (table.get("ports") or {}):
            gone.append((f"the term '{term}' of '{cname}'", None, term, table["ports"].pop(term)))
    for target in list(connections):
        cname = target.rpartition(".")[0]
        if cname in taken and target in own_connections:
            raise CircuitError(f"connections.{target}: component {cname!r} is removed "
                               f"([remove] components); drop this connection")
        if cname in taken:
            del connections[target]
    return gone


def _static_port(ctype_name, port: str):
    """(direction, Port) of a port its type declares on the class ("in"/"out"), else None
    (ports that follow a form, a causality or terms are known only once built)."""
    ctype = COMPONENT_TYPES.get(ctype_name)
    if ctype is None:
        return None
    cls = ctype.component
    if port in cls.inputs:
        return "in", cls.inputs[port]
    if port in cls.outputs:
        return "out", cls.outputs[port]
    return None


def _experiment_driven(ctype_name, port: str) -> bool:
    """True for an input an experiment drives (a valve current, a position reference)."""
    found = _static_port(ctype_name, port)
    return found is not None and found[0] == "in" and (
        found[1].quantity == "current" or port == "reference")


def _unread_signal_output(ctype_name, port: str) -> bool:
    """True for an output of a signal (position, force, ...) that may go unread; an oil
    port left alone is a cut line."""
    found = _static_port(ctype_name, port)
    return found is not None and found[0] == "out" and found[1].quantity not in HYDRAULIC


def _check_dangling(components: dict, gone: list):
    """Refuse a port left with nothing at its other end by a removal (one line)."""
    named = {}
    for name, table in components.items():
        ports = table.get("ports")
        for port, sig in (ports.items() if isinstance(ports, dict) else ()):
            named.setdefault(sig, []).append((name, port))
    for what, ctype, rport, sig in gone:
        left = named.get(sig, [])
        if not left:
            continue
        produced = _static_port(ctype, rport)
        lost_source = produced is not None and produced[0] == "out" and all(
            (_static_port(components[n].get("type"), p) or ("?",))[0] == "in" for n, p in left)
        alone = len(left) == 1 and not _unread_signal_output(components[left[0][0]].get("type"),
                                                             left[0][1])
        if (alone or lost_source) and not all(
                _experiment_driven(components[n].get("type"), p) for n, p in left):
            n, p = left[0]
            terms = components[n].get("terms")
            drop = (f"drop the term ([remove] terms = [\"{n}.{p}\"])"
                    if isinstance(terms, dict) and p in terms else f"remove {n!r} too")
            raise CircuitError(
                f"remove: taking out {what} leaves port {p!r} of {n!r} (signal {sig!r}) with "
                f"nothing at its other end; re-point it ([circuit.{_quoted(n)}] ports = "
                f"{{ {_quoted(p)} = \"<signal>\" }}) or {drop}")


def extend(base: dict, tree: dict) -> dict:
    """The rig tables a file makes of its base's: settings merged, circuit edits applied,
    sub-circuit instances placed (see the module's description).

    Parameters
    ----------
    base : dict
        The base rig's tables, composed (``{}`` for a file without a base)
    tree : dict
        The file's tables as read (its ``[rig] base`` is ignored here)

    Returns
    -------
    dict
        Rig tables: ``[circuit.<name>]`` tables only of components (with a type), the
        sub-circuit definitions under ``subcircuit`` (for a file that extends this one),
        no ``[remove]``

    Raises
    ------
    CircuitError
        One line naming the table at fault
    """
    settings = {k: v for k, v in tree.items() if k not in COMPOSE_TABLES}
    if isinstance(settings.get("rig"), dict):
        settings["rig"] = {k: v for k, v in settings["rig"].items() if k != "base"}
    out = _merge({k: v for k, v in base.items() if k not in COMPOSE_TABLES}, settings)
    components = dict(base.get("circuit", {}))
    if "remove" in tree and not components:
        raise CircuitError("remove: there is nothing to remove from: [remove] takes components "
                           "out of the rig named by [rig] base, a circuit rig")
    connections = dict(out["connections"]) if isinstance(out.get("connections"), dict) else {}
    if connections:
        out["connections"] = connections
    own_connections = tree.get("connections") if isinstance(tree.get("connections"), dict) else {}
    gone = _remove(components, tree.get("remove"), connections, own_connections)
    groups = _groups(base, tree)
    own = components_by_name(_table(tree.get("circuit", {}), "circuit",
                                    "[circuit.pump] type = \"pressure_source\""), components)
    changes = []
    for name, table in own.items():
        if "subcircuit" in table:
            if "type" in table:
                raise CircuitError(f"circuit.{_quoted(name)}: either a component (type = ...) "
                                   f"or a sub-circuit's instance (subcircuit = ...), not both")
            for member, mt in instantiate(name, table, groups).items():
                if member in components:
                    raise CircuitError(f"circuit.{_quoted(name)}: its component {member!r} is "
                                       f"already in the rig (to place it anew, remove the base's "
                                       f"first: [remove] components = [\"{name}\"])")
                components[member] = mt
        elif name in components or "type" not in table:
            changes.append(name)
        else:
            components[name] = copy.deepcopy(table)
    for name in changes:
        if name not in components:
            stem, _, last = name.rpartition(".")
            shown = stem if last in ("ports", "terms") and stem else name
            raise CircuitError(
                f"circuit.{_quoted(name)}: no component {shown!r} to change"
                f"{_hint(shown, components)}; a new component needs type = \"...\" (one of "
                f"{', '.join(COMPONENT_TYPES)})")
        components[name] = change_component(components[name], own[name], f"circuit.{_quoted(name)}")
    _check_dangling(components, gone)
    if components:
        out["circuit"] = components
    if groups:
        out["subcircuit"] = groups
    return out
