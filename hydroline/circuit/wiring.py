"""Physical wiring checks: a circuit that causality accepts but no real rig could be.

The network's own checks (:class:`hydroline.engine.Network`) make sure every input is fed by
exactly one output of its kind and that no algebraic loop forms. A circuit can pass them and
still be physically wrong: a hose that reads its own downstream pressure as its upstream
one, a servovalve fed from its own return port, a manifold cut off from the pump. Such a
circuit runs and gives a wrong answer without a word, so these checks run before every run
of a circuit rig and of a template rig with ``[connections]``.

Everything is derived from the components' declarations (:meth:`Component.hydraulic_ends`,
``conducts``, ``pressure_order``, ``source_ends``), never from their type names; a component
that declares no ends (a user's own type) only joins its oil ports for rule 8 below:

* a **node** is a pressure signal; an end sits at the node its pressure port is joined to;
  a flow junction (an end without a pressure) sits where all its flows meet;
* a **side** joins the nodes linked by conducting components (hoses, resistances, check
  valves): a servovalve, a piston or a pump stands between sides;
* a **prescribed pressure** is a pressure output of a component without inputs (a
  ``pressure_source``, a pressure command): it takes any flow.

Errors (one line, :class:`CircuitError`, naming component and port):

1. a port reads a signal its own component outputs (a self-loop);
2. two hydraulic input ports of one component read one signal (a short circuit);
3. a hydraulic input that no component of the circuit outputs (experiments drive only valve
   currents and position references);
4. the flows of a junction do not meet at one node;
5. an end whose pressure and flow belong to different nodes (a cut or crossed connection),
   in particular a pressure that no component reads while its flow goes elsewhere; reading a
   prescribed pressure of the same side in place of the node's own (an ideal supply:
   ``"servovalve.supply_pressure" = "pump_pressure"``) is allowed;
6. ``pressure_order`` broken: a servovalve whose P does not reach a higher prescribed
   pressure than its T (P and T on the tank's side, or swapped);
7. a side with neither a prescribed pressure nor oil held by a compliance;
8. components cut off from every prescribed pressure and pump.

Warnings (one line, :class:`WiringWarning`; the circuit is possible but unusual): a pressure
source that feeds nothing; a servovalve whose P and T are joined through conducting
components (a leak from supply to tank), or whose P reaches neither a prescribed pressure
nor a pump.
"""
from __future__ import annotations

import warnings
from collections import Counter

from .types import CircuitError

__all__ = ["check_wiring", "check_self_loops", "WiringWarning", "HYDRAULIC", "hydraulic_nodes"]

#: Signal quantities of the oil (the other quantities are signals only).
HYDRAULIC = ("pressure", "flow")


class WiringWarning(UserWarning):
    """A circuit that is physically possible but unusual (one line naming the component).

    Parameters
    ----------
    *args : str
        The message: one line naming the component
    **kwargs : dict
        None taken (as ``UserWarning``)
    """


def _port_path(c, port: str) -> str:
    return f"{c.name}.{port}"


def _root(parent: dict, a):
    """The representative of ``a`` in a union-find forest (``parent``: item -> parent)."""
    parent.setdefault(a, a)
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


class _Circuit:
    """The hydraulic graph of a component list: producers, readers, ends, nodes and sides."""

    def __init__(self, parts):
        self.parts = list(parts)
        self.producer, self.readers = {}, {}
        for c in self.parts:
            for port in c.outputs:
                self.producer.setdefault(c.signal(port), (c, port))
            for port in c.inputs:
                self.readers.setdefault(c.signal(port), []).append((c, port))
        self.ends = {c.name: c.hydraulic_ends() for c in self.parts}
        self.flow_ends = {}        # flow signal -> [(component, end)]
        for c in self.parts:
            for end in self.ends[c.name].values():
                for f in end.flows:
                    self.flow_ends.setdefault(c.signal(f), []).append((c, end))
        # prescribed pressures (and flows): outputs of components without inputs
        self.prescribed = {}       # signal -> level at t = 0 [Pa] (None where unknown)
        for c in self.parts:
            if c.inputs:
                continue
            for port, spec in c.outputs.items():
                if spec.quantity in HYDRAULIC:
                    self.prescribed[c.signal(port)] = self._level(c, port)
        self._junction_nodes, self._visiting = {}, set()
        self.side = self._sides()

    @staticmethod
    def _level(c, port):
        """A prescribed signal's value at t = 0 [SI], None where it cannot be evaluated."""
        try:
            x = c.initial_guess()
            return float(c.outputs_of(0.0, x, {}, c.runtime_parameters())[port])
        except Exception:          # a level is only used to order P and T; unknown is fine
            return None

    def _sides(self) -> dict:
        """Node -> side label: nodes joined by conducting components (union-find)."""
        parent = {}
        for c in self.parts:
            nodes = [c.signal(e.pressure) for e in self.ends[c.name].values() if e.pressure]
            for n in nodes:
                _root(parent, n)
            if c.conducts:
                for n in nodes[1:]:
                    parent[_root(parent, n)] = _root(parent, nodes[0])
        return {n: _root(parent, n) for n in list(parent)}

    def side_of(self, node):
        return self.side.get(node, node)

    # ---- nodes -----------------------------------------------------------------------
    def touched(self, flow: str, exclude: str) -> set:
        """The nodes where a flow signal is exchanged, by components other than ``exclude``."""
        nodes = set()
        for c, end in self.flow_ends.get(flow, ()):
            if c.name == exclude:
                continue
            if end.pressure is not None:
                nodes.add(c.signal(end.pressure))
            else:
                nodes |= self.junction_node(c, end)
        return nodes

    def junction_flow_nodes(self, c, end) -> list:
        """(port, nodes where its flow is exchanged elsewhere) for each flow of a junction."""
        return [(f, self.touched(c.signal(f), c.name)) for f in end.flows]

    def junction_node(self, c, end) -> set:
        """The node a junction sits at: where all its flows meet (empty where they do not)."""
        key = (c.name, id(end))
        if key in self._junction_nodes:
            return self._junction_nodes[key]
        if key in self._visiting:           # junctions feeding each other in a ring
            return set()
        self._visiting.add(key)
        sets = [s for _, s in self.junction_flow_nodes(c, end) if s]
        self._visiting.discard(key)
        node = set.intersection(*sets) if sets else set()
        self._junction_nodes[key] = node
        return node

    def supplies(self, side) -> list:
        """The prescribed pressures [Pa] on a side; +inf for a pump outlet there."""
        out = [lv for s, lv in self.prescribed.items() if lv is not None
               and self.producer[s][0].outputs[self.producer[s][1]].quantity == "pressure"
               and self.side_of(s) == side]
        for c in self.parts:
            for e in c.source_ends:
                end = self.ends[c.name].get(e)
                if end is not None and end.pressure and self.side_of(c.signal(end.pressure)) == side:
                    out.append(float("inf"))
        return out


def hydraulic_nodes(parts) -> dict:
    """Where each component meets the oil: the node (a pressure signal) of each of its ends,
    as the wiring checks find them (a flow junction at the node where its flows meet).

    Parameters
    ----------
    parts : list
        The circuit's components.

    Returns
    -------
    dict
        Component name -> {end name: node}, in the order of ``parts`` and of each component's
        :meth:`~hydroline.engine.Component.hydraulic_ends`; the node None for a junction whose
        flows meet at no one node. A component that declares no ends is not in it.
    """
    g = _Circuit(parts)
    out = {}
    for c in g.parts:
        ends = {}
        for name, end in g.ends[c.name].items():
            if end.pressure is not None:
                ends[name] = c.signal(end.pressure)
            else:
                nodes = g.junction_node(c, end)
                ends[name] = min(nodes) if nodes else None
        if ends:
            out[c.name] = ends
    return out


def _fmt_levels(levels) -> str:
    if not levels:
        return "none"
    return ", ".join("a pump" if lv == float("inf") else f"{lv / 1e6:.4g} MPa"
                     for lv in sorted(set(levels), reverse=True))


def check_wiring(parts, path_of=_port_path) -> list[str]:
    """Refuse a physically impossible wiring; warn of an unusual one (see the module).

    Parameters
    ----------
    parts : list
        The circuit's components (an experiment's commands not included)
    path_of : callable
        ``(component, port) -> str``: how a message names a port, e.g.
        ``"circuit.pump.ports.pressure"`` or ``"connections.servovalve.supply_pressure"``

    Returns
    -------
    list of str
        The warnings given (each also issued as a :class:`WiringWarning`)

    Raises
    ------
    CircuitError
        One line naming the component and port at fault
    """
    g = _Circuit(parts)
    check_self_loops(parts, path_of)
    _short_circuits(g, path_of)
    _unfed_inputs(g, path_of)
    _junctions(g, path_of)
    _ends(g, path_of)
    found = _pressure_order(g, path_of)
    _compliance(g, path_of)
    _islands(g, path_of)
    found += _idle_sources(g, path_of)
    for text in found:
        warnings.warn(text, WiringWarning, stacklevel=3)
    return found


def check_self_loops(parts, path_of=_port_path):
    """Refuse a port that reads a signal its own component outputs (rule 1 of the module).

    Parameters
    ----------
    parts : list
        The circuit's components
    path_of : callable
        ``(component, port) -> str``: how the message names the port

    Raises
    ------
    CircuitError
        One line naming the component and port
    """
    for c in parts:
        own = {c.signal(p): p for p in c.outputs}
        for port in c.inputs:
            sig = c.signal(port)
            if sig in own:
                raise CircuitError(f"{path_of(c, port)}: reads '{sig}', which its own port "
                                   f"'{own[sig]}' outputs: a self-loop ({c.name} fed its own "
                                   f"output; join the port to the node it belongs to)")


def _short_circuits(g, path_of):
    for c in g.parts:
        seen = {}
        for port, spec in c.inputs.items():
            if spec.quantity not in HYDRAULIC:
                continue
            sig = c.signal(port)
            if sig in seen:
                a, b = sorted((seen[sig], port), key=lambda q: not path_of(c, q).startswith(
                    "connections."))              # a port rewired by [connections] first
                raise CircuitError(f"{path_of(c, a)}: reads '{sig}' like its port '{b}': two "
                                   f"ports of {c.name} on one signal (a short circuit; each "
                                   f"port needs its own node)")
            seen[sig] = port


def _unfed_inputs(g, path_of):
    for c in g.parts:
        for port, spec in c.inputs.items():
            sig = c.signal(port)
            if spec.quantity in HYDRAULIC and sig not in g.producer:
                raise CircuitError(f"{path_of(c, port)}: unconnected: no component of the "
                                   f"circuit outputs the {spec.quantity} '{sig}' it reads (an "
                                   f"experiment drives only valve currents and position "
                                   f"references)")


def _junctions(g, path_of):
    for c in g.parts:
        for end in g.ends[c.name].values():
            if end.pressure is not None or g.junction_node(c, end):
                continue
            flows = [(f, s) for f, s in g.junction_flow_nodes(c, end) if s]
            if len(flows) < 2:
                continue
            common, _ = Counter(n for _, s in flows for n in s).most_common(1)[0]
            port, nodes = next((f, s) for f, s in flows if common not in s)
            raise CircuitError(f"{path_of(c, port)}: the flow '{c.signal(port)}' is exchanged at "
                               f"{_names(nodes)}, the other flows of {c.name} at '{common}': a "
                               f"junction's flows must meet at one node")


def _names(nodes) -> str:
    return ", ".join(f"'{n}'" for n in sorted(nodes))


def _ends(g, path_of):
    """Pressure and flow of every end on one node (rule 5 of the module). Of several ends
    found wrong, one on a port rewired by ``[connections]`` is named (that is what changed),
    else one that reads a pressure of another node before one left cut off by it."""
    found = []
    for c in g.parts:
        ends = g.ends[c.name]
        for name, end in ends.items():
            if end.pressure is None:
                continue
            node = c.signal(end.pressure)
            for f in end.flows:
                nodes = g.touched(c.signal(f), c.name)
                if not nodes or node in nodes:
                    continue          # exchanged nowhere else (a lost flow), or at its node
                through = any(f in e.flows for n, e in ends.items() if n != name)
                if through and node in g.prescribed:
                    continue          # drawn from / spilled into a prescribed pressure
                side = g.side_of(node)
                if any(g.side_of(n) == side and (n in g.prescribed or node in g.prescribed)
                       for n in nodes):
                    continue          # reads a prescribed pressure of its side (ideal source)
                flow = c.signal(f)
                path = path_of(c, end.pressure)
                rewired = any(p.startswith("connections.") for p in (path, path_of(c, f)))
                if end.pressure in c.outputs and node not in g.readers:
                    found.append((not rewired, True, path,
                        f"outputs the pressure '{node}', which no component reads: this end of "
                        f"{c.name} is cut off (its flow '{flow}' is exchanged at {_names(nodes)})"))
                else:
                    found.append((not rewired, False, path,
                        f"is on '{node}' but its flow '{flow}' ({c.name}.{f}) is exchanged at "
                        f"{_names(nodes)}: the pressure and flow of one end on different nodes "
                        f"(a cut or crossed connection)"))
    if found:
        _, _, path, text = min(found, key=lambda x: x[:2])   # stable: the first of the best
        raise CircuitError(f"{path}: {text}")


def _pressure_order(g, path_of) -> list:
    found = []
    for c in g.parts:
        ends = g.ends[c.name]
        for high, low in c.pressure_order:
            ph, pl = ends[high].pressure, ends[low].pressure
            nh, nl = c.signal(ph), c.signal(pl)
            sh, sl = g.side_of(nh), g.side_of(nl)
            up, down = g.supplies(sh), g.supplies(sl)
            if up and down and max(up) <= min(down):
                raise CircuitError(
                    f"{path_of(c, ph)}: on '{nh}', which reaches no higher pressure than "
                    f"'{nl}' of {c.name}.{pl} ({_fmt_levels(up)} against {_fmt_levels(down)}): "
                    f"the {high} port must face the supply and the {low} port the tank "
                    f"(swapped, or both on one side)")
            if sh == sl:
                found.append(f"{path_of(c, ph)}: '{nh}' and {c.name}.{pl} ('{nl}') are joined "
                             f"through hoses or resistances: a leak from {high} to {low}")
            elif not up:
                found.append(f"{path_of(c, ph)}: '{nh}' reaches no pressure source or pump "
                             f"through the lines: {c.name} can only draw on stored oil")
    return found


def _compliance(g, path_of):
    held = {g.side_of(n) for n in g.prescribed}
    for c in g.parts:
        for end in g.ends[c.name].values():
            if end.compliant and end.pressure:
                held.add(g.side_of(c.signal(end.pressure)))
    for c in g.parts:
        for end in g.ends[c.name].values():
            if end.pressure and g.side_of(c.signal(end.pressure)) not in held:
                raise CircuitError(
                    f"{path_of(c, end.pressure)}: the node '{c.signal(end.pressure)}' reaches "
                    f"neither a prescribed pressure nor a compliance (hose, chamber, "
                    f"accumulator, volume): its pressure has no oil to follow")


def _islands(g, path_of):
    """Components joined by any oil path (valves and pistons included) that reach no
    prescribed pressure and no pump."""
    parent = {}
    hydraulic = []
    for c in g.parts:
        ports = [p for e in g.ends[c.name].values() for p in (e.pressure, *e.flows) if p]
        if not ports:   # a component that declares no ends: all its oil ports are one place
            ports = [p for p, s in {**c.inputs, **c.outputs}.items() if s.quantity in HYDRAULIC]
        if not ports:
            continue
        hydraulic.append((c, ports))
        for p in ports:      # (kind, name): a component and a signal may share a name
            parent[_root(parent, ("signal", c.signal(p)))] = _root(parent, ("component", c.name))
    fed = {_root(parent, ("signal", s)) for s in g.prescribed if ("signal", s) in parent}
    fed |= {_root(parent, ("component", c.name)) for c, _ in hydraulic if c.source_ends}
    for c, ports in hydraulic:
        if _root(parent, ("component", c.name)) not in fed:
            raise CircuitError(f"{path_of(c, ports[0])}: {c.name} is cut off from every "
                               f"pressure source and pump (no oil path reaches one): its "
                               f"pressures have no level to start from")


def _idle_sources(g, path_of) -> list:
    found = []
    for sig, level in g.prescribed.items():
        c, port = g.producer[sig]
        if c.hydraulic_ends() and sig not in g.readers:
            found.append(f"{path_of(c, port)}: the pressure '{sig}' is read by no component: "
                         f"{c.name} feeds nothing")
    return found
