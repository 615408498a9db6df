"""A rig's circuit as a hydraulic schematic with ISO 1219-1 symbols (``hydroline circuit
--schematic FILE.svg|.png``).

The hydraulic connections come from the components' declared ends (the nodes the wiring
checks find, :func:`hydroline.circuit.wiring.hydraulic_nodes`): one line per node, a dot
where three lines or more meet. The schematic reads from supply to actuator: each servo axis
is a unit at the right -- the cylinder above its servovalve, the load and friction on the
rod, the controller and commands beside the valve's torque motor (signal lines dashed) --
and the supply lines run from the valve's P port to the left, to the pump, on the unit's
supply lane, the return lines from T to the tank on its return lane below. Components are
placed column by column along the lines (tree layout from the valves); an accumulator or a
volume stands on its line; a second branch from a node takes a lane of its own; a connection
that cannot run along its lane is routed around below. Without a servovalve the lines run
from the pump (or the highest pressure source) to the right. Hoses are labelled with length
and bore, every component with its name and main parameters.

:func:`schematic` lays the circuit out (:class:`Schematic`: every component once, with its
symbol and box, and every node's line once); :func:`draw_schematic` draws and writes it.
"""
from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field

from .drawing import type_name
from .iso1219 import SYMBOLS, LINE_WIDTH, Pen
from .wiring import hydraulic_nodes

__all__ = ["schematic", "draw_schematic", "Schematic", "Placed", "Net", "SYMBOL_OF_TYPE"]

#: Circuit component type -> ISO 1219 symbol (:data:`hydroline.circuit.iso1219.SYMBOLS`);
#: a pressure source is drawn as a tank where it takes the return flow.
SYMBOL_OF_TYPE = {"pressure_source": "pressure_source", "pump": "pump",
                  "relief_valve": "relief_valve", "hose": "hose", "resistance": "restriction",
                  "check_valve": "check_valve", "volume": "volume", "junction": "junction",
                  "accumulator": "accumulator", "servovalve": "servovalve",
                  "actuator": "cylinder", "friction": "friction", "load": "load",
                  "position_controller": "controller", "step_command": "command",
                  "sine_command": "command", "ramp_command": "command",
                  "table_command": "command"}

#: Symbols that stand on a line (one port, drawn upright above it).
BRANCH_SYMBOLS = ("accumulator", "volume")
#: Symbols that end a line (one port, drawn at the end of their lane).
END_SYMBOLS = ("pressure_source", "tank")

#: Layout, [drawing units]: columns along the lines, the return lanes' offset from the supply
#: lanes' columns (so that no line runs through a symbol of the other), the supply lane below
#: the valve, the return lane below the supply lane, one unit's height, an extra lane's pitch.
COLUMN, RETURN_SHIFT = 5.6, 0.8
SUPPLY_DROP, RETURN_GAP, UNIT_PITCH, LANE_PITCH = 1.0, 3.2, 9.0, 3.0
#: Drawing units per inch of the figure, and the labels' size, [points].
UNITS_PER_INCH, LABEL_SIZE = 2.5, 6.5


@dataclass
class Placed:
    """One component in the schematic.

    Attributes
    ----------
    name : str
        The component
    type : str
        Its circuit type (:func:`hydroline.circuit.drawing.type_name`)
    symbol : str
        Its symbol (a key of :data:`hydroline.circuit.iso1219.SYMBOLS`)
    x, y : float
        Where the symbol's origin lies, [drawing units]
    mirror : bool
        Mirrored (a flow from right to left)
    turns : int
        Quarter turns counter-clockwise, [-]
    ends : dict
        Hydraulic end -> (x, y, exit direction) of its port, [drawing units]
    box : tuple
        The symbol's extent (x0, y0, x1, y1), [drawing units] (set when drawn)
    label : str
        Name and main parameters
    label_box : tuple
        The label's extent, [drawing units] (set when drawn)
    role : str
        "supply", "return", "branch", "end", "unit", "signal", "junction",
        "other"
    inscription : str
        Text inside the symbol (a controller's "PID", a command's waveform)
    """

    name: str
    type: str
    symbol: str
    x: float = 0.0
    y: float = 0.0
    mirror: bool = False
    turns: int = 0
    ends: dict = field(default_factory=dict)
    box: tuple = ()
    label: str = ""
    label_box: tuple = ()
    role: str = "other"
    inscription: str = ""


@dataclass
class Net:
    """The line of one hydraulic node: the component ends on it and the segments drawn.

    Attributes
    ----------
    node : str
        The node (its pressure signal)
    ends : list
        (component, end) on it
    segments : list
        ((x0, y0), (x1, y1)) of each straight piece, [drawing units]
    dots : list
        (x, y) where three lines or more meet, [drawing units]
    anchor : tuple
        Where a junction on the node is drawn, (x, y), [drawing units]
    """

    node: str
    ends: list = field(default_factory=list)
    segments: list = field(default_factory=list)
    dots: list = field(default_factory=list)
    anchor: tuple = None


@dataclass
class Schematic:
    """A circuit laid out as a schematic (:func:`schematic`).

    Attributes
    ----------
    placed : dict
        Component name -> :class:`Placed`
    nets : dict
        Node -> :class:`Net`
    signals : list
        (from, to, signal, segments) of each signal line (dashed), from a
        component or "experiment"
    title : str
        Figure title
    """

    placed: dict
    nets: dict
    signals: list
    title: str = ""


# ---- labels -------------------------------------------------------------------------------

def _q(v, unit, scale=1.0, fmt="{:.3g}"):
    return f"{fmt.format(v * scale)} {unit}"


def component_label(c, kind: str) -> str:
    """A component's name and main parameters, for its label.

    Parameters
    ----------
    c : Component
        The component.
    kind : str
        Its circuit type.

    Returns
    -------
    str
        Lines of text.
    """
    def get(name):
        return getattr(c, name, None)

    extra = ""
    if kind == "hose":
        line = getattr(c.model, "line", None)
        if line is not None:
            extra = f"L = {_q(line.length, 'm')}, d = {_q(line.diameter, 'mm', 1e3)}"
    elif kind == "resistance":
        extra = f"R = {_q(get('resistance'), 'Pa s/m^3')}"
    elif kind == "check_valve":
        extra = f"reverse R = {_q(get('reverse_resistance'), 'Pa s/m^3')}"
    elif kind == "relief_valve":
        extra = f"cracks at {_q(get('cracking_pressure'), 'MPa', 1e-6)}"
    elif kind == "pump":
        extra = (f"{_q(get('displacement'), 'cm^3', 1e6)}/rev, "
                 f"{_q(get('shaft_speed'), 'rpm', 60 / (2 * math.pi), '{:.4g}')}")
    elif kind == "pressure_source":
        p = get("pressure")
        extra = f"p = {_q(p, 'MPa', 1e-6)}" if isinstance(p, (int, float)) else ""
    elif kind == "accumulator":
        extra = (f"V0 = {_q(get('capacity'), 'L', 1e3)}, "
                 f"p0 = {_q(get('precharge_pressure'), 'MPa', 1e-6)}")
    elif kind == "volume":
        extra = f"V = {_q(get('volume'), 'cm^3', 1e6)}"
    elif kind == "servovalve":
        extra = (f"{_q(get('rated_flow'), 'L/min', 6e4)} at "
                 f"{_q(get('rated_pressure_drop'), 'MPa', 1e-6)}, "
                 f"{_q(get('natural_frequency'), 'Hz')}")
    elif kind == "actuator":
        extra = (f"A = {_q(get('bottom_area'), 'cm^2', 1e4)}, "
                 f"stroke {_q(get('stroke'), 'mm', 1e3)}, m = {_q(get('moving_mass'), 'kg')}")
    elif kind == "load":
        k, m = get("stiffness") or 0.0, get("mass") or 0.0
        extra = f"m = {_q(m, 'kg')}, k = {_q(k, 'N/m')}"
    elif kind == "position_controller":
        extra = f"Kp = {_q(get('proportional_gain'), 'A/m')}"
    elif kind.endswith("_command"):
        extra = f"{kind.replace('_command', '')} ({get('quantity')})"
    return c.name + (f"\n{extra}" if extra else "")


def _inscription(c, kind: str) -> str:
    """The text inside a signal symbol: a controller's terms, a command's waveform."""
    if kind == "position_controller":
        terms = "".join(t for t, g in (("P", "proportional_gain"), ("I", "integral_gain"),
                                       ("D", "derivative_gain")) if getattr(c, g, 0.0))
        return terms or "controller"
    if kind.endswith("_command"):
        return kind.replace("_command", "")
    return ""


# ---- layout -------------------------------------------------------------------------------

class _Lanes:
    """Extra lanes: above the top one for the supply side, below the bottom one for the
    return side and the routed connections."""

    def __init__(self, top, bottom):
        self.top, self.bottom = top, bottom

    def above(self):
        self.top += LANE_PITCH
        return self.top

    def below(self):
        self.bottom -= LANE_PITCH
        return self.bottom


def schematic(circuit, title: str = "") -> Schematic:
    """Lay a circuit out as a hydraulic schematic (see the module): where each symbol goes
    and how each node's line runs; :func:`draw_schematic` draws it.

    Parameters
    ----------
    circuit : Circuit
        The circuit (:func:`hydroline.system.build_circuit`).
    title : str
        Figure title.

    Returns
    -------
    Schematic
        The placed symbols and nets, ready to draw
    """
    comps = {c.name: c for c in circuit.components}
    kinds = {n: type_name(c) for n, c in comps.items()}
    ends_of = hydraulic_nodes(circuit.components)
    at_node = defaultdict(list)
    for name, ends in ends_of.items():
        for end, node in ends.items():
            if node is not None:
                at_node[node].append((name, end))
    placed: dict[str, Placed] = {}
    # a pressure source where a pump draws or a relief valve spills is a tank
    tank_nodes = {ends_of[n].get(e) for n, k in kinds.items() if n in ends_of
                  for kk, e in (("pump", "inlet"), ("relief_valve", "outlet")) if k == kk}

    def place(name, symbol, role, **kw):
        p = Placed(name, kinds[name], symbol, role=role,
                   label=component_label(comps[name], kinds[name]),
                   inscription=_inscription(comps[name], kinds[name]), **kw)
        placed[name] = p
        return p

    # -- servo units: valve, cylinder, load, friction, controller --------------------------
    axes = list(circuit.axes.values())
    valves = [a.valve for a in axes if a.valve in comps]
    valves += [n for n, k in kinds.items() if k == "servovalve" and n not in valves]
    units = []
    for k, valve in enumerate(valves):
        yv = -k * UNIT_PITCH
        axis = next((a for a in axes if a.valve == valve), None)
        units.append((valve, axis, yv))
        place(valve, "servovalve", "unit", x=0.0, y=yv)
        actuator = axis.actuator if axis is not None and axis.actuator in comps else None
        if actuator is None:   # a cylinder on the valve's A or B node
            vends = ends_of.get(valve, {})
            actuator = next((n for e in ("bottom", "top") for n, _ in at_node.get(vends.get(e), ())
                             if kinds[n] == "actuator" and n not in placed), None)
        if actuator is not None and actuator not in placed:
            place(actuator, "cylinder", "unit", x=0.0, y=yv + 1.95)
    sign = -1 if valves else 1
    lanes = _Lanes(SUPPLY_DROP * -1 + 1.9, -SUPPLY_DROP - RETURN_GAP
                   - (len(units) - 1) * UNIT_PITCH - 1.0)

    # -- the lines: a tree from each valve's P and T ports (or from the pump) ----------------
    node_at = {}        # node -> (x of its line, band)
    queue = []          # (node, band, lane y, column, direction)
    if valves:
        for valve, _, yv in units:
            vends = ends_of.get(valve, {})
            if vends.get("supply"):
                queue.append((vends["supply"], "supply", yv - SUPPLY_DROP, 0.5, 1))
            if vends.get("return"):
                queue.append((vends["return"], "return", yv - SUPPLY_DROP - RETURN_GAP, 0.5, 1))
    else:
        root = _root_component(comps, kinds, ends_of)
        if root is not None:
            p = place(root, _symbol(kinds[root], "supply"), "supply", x=0.0, y=0.0)
            _orient_inline(p, ends_of[root], ends_of[root].get(
                "outlet", next(iter(ends_of[root].values()))), +1)
            for end, node in ends_of[root].items():
                if end != "inlet":   # (the inlet's tank is reached along the lines)
                    queue.append((node, "supply", 0.0, 0.5, 1))
            lanes = _Lanes(1.9, -1.0)
    shift = {"supply": 0.0, "return": RETURN_SHIFT}

    def xpos(col, band):
        return sign * (col * COLUMN + shift[band])

    branches = defaultdict(list)     # node -> [component]
    while queue:
        node, band, lane, col, direction = queue.pop(0)
        if node in node_at:
            continue
        node_at[node] = (xpos(col, band), band)
        first = True
        for name, end in at_node[node]:
            if name in placed or kinds[name] == "junction":
                continue
            symbol = _symbol(kinds[name], "return" if node in tank_nodes else band)
            if symbol in BRANCH_SYMBOLS or (len(ends_of[name]) == 1 and symbol not in END_SYMBOLS):
                branches[node].append(name)
                placed[name] = None           # (placed when the node's line is known)
                continue
            if not first:
                lane = lanes.above() if band == "supply" else lanes.below()
            first = False
            c = col + 0.5 * direction
            p = place(name, symbol, band, x=xpos(c, band), y=lane)
            _orient_inline(p, ends_of[name], node, -sign * direction)   # back to the node
            for other_end, other in ends_of[name].items():
                if other_end != end and other not in node_at:
                    queue.append((other, band, lane, c + 0.5 * direction, direction))
    # the branches stand on their node's line, above its top
    tops = _line_tops(placed, ends_of, node_at, units)
    for node, names in branches.items():
        x0, band = node_at[node]
        for k, name in enumerate(names):
            del placed[name]
            x = x0 + (1.3 * ((k + 1) // 2) * (1 if k % 2 else -1) if k else 0.0)
            p = place(name, _symbol(kinds[name], band), "branch", x=x, y=tops[node] + 0.45)
            p.ends = {end: (x, p.y, "down") for end in ends_of[name]}
    # -- the cylinder's load and friction, the controllers and commands --------------------
    signals = []
    _place_attachments(circuit, comps, kinds, placed, units, place, signals)
    # -- anything else: a row at the bottom ------------------------------------------------
    left = [n for n in comps if n not in placed and kinds[n] != "junction"]
    y_other = lanes.below()
    for k, name in enumerate(left):
        symbol = SYMBOL_OF_TYPE.get(kinds[name], "box")
        p = place(name, symbol, "other", x=sign * k * COLUMN * 0.6, y=y_other)
        names = list(ends_of.get(name, {}))
        p.ends = {e: (p.x + (0.6 if i else -0.6), p.y, "right" if i else "left")
                  for i, e in enumerate(names)}
    # -- the lines ---------------------------------------------------------------------------
    nets = {}
    for node, ends in at_node.items():
        nets[node] = _route(node, ends, placed, node_at, lanes)
    # a junction is the dot where its node's lines meet
    for name, kind in kinds.items():
        if kind != "junction" or name in placed:
            continue
        node = next(iter(ends_of.get(name, {}).values()), None)
        net = nets.get(node)
        if net is not None and getattr(net, "anchor", None) is not None:
            x, y = net.anchor
        else:
            x, y = 0.0, lanes.below()
        place(name, "junction", "junction", x=x, y=y)
    return Schematic(placed, nets, signals, title)


def _symbol(kind: str, band: str) -> str:
    symbol = SYMBOL_OF_TYPE.get(kind, "box")
    if symbol == "pressure_source" and band == "return":
        return "tank"
    return symbol


def _root_component(comps, kinds, ends_of):
    """Where a circuit without a servovalve starts: a pump, else the highest pressure source."""
    pumps = [n for n, k in kinds.items() if k == "pump" and n in ends_of]
    if pumps:
        return pumps[0]
    sources = [(getattr(comps[n], "pressure", None), n) for n, k in kinds.items()
               if k == "pressure_source" and n in ends_of]
    sources = [(p if isinstance(p, (int, float)) else -math.inf, n) for p, n in sources]
    if sources:
        return max(sources)[1]
    return next(iter(ends_of), None)


#: The symbol's own connection points (u along the line), by symbol: (near, far) ends.
_INLINE_PORTS = {"hose": 1.3, "restriction": 0.6, "check_valve": 0.6, "relief_valve": 0.75,
                 "pump": 0.7, "pressure_source": 0.7, "tank": 0.6, "box": 0.6}


def _orient_inline(p, ends, near_node, toward):
    """Place an in-line symbol's ends: the one on ``near_node`` faces ``toward`` (+1 right,
    -1 left), the other the opposite way; an oriented symbol (inlet ``a``) mirrored so that
    its inlet is on its inlet's side."""
    half = _INLINE_PORTS.get(p.symbol, 0.6)
    names = list(ends)
    near = next((e for e in names if ends[e] == near_node), names[0])
    p.ends = {}
    for e in names:
        side = toward if e == near else -toward
        p.ends[e] = (p.x + side * half, p.y, "right" if side > 0 else "left")
    first = names[0]                       # inlet / upstream: the symbol's end "a"
    if p.symbol in END_SYMBOLS:            # its port "b" on the right
        p.mirror = p.ends[first][0] < p.x
    else:
        p.mirror = p.ends[first][0] > p.x


def _line_tops(placed, ends_of, node_at, units):
    """The highest point of each node's line before its branches stand on it, [units]."""
    tops = {}
    for name, p in placed.items():
        if p is None:
            continue
        for end, node in ends_of.get(name, {}).items():
            if node in node_at and end in p.ends:
                tops[node] = max(tops.get(node, -math.inf), p.ends[end][1])
    for valve, _, yv in units:
        for end, drop in (("supply", SUPPLY_DROP), ("return", SUPPLY_DROP + RETURN_GAP)):
            node = ends_of.get(valve, {}).get(end)
            if node is not None:
                tops[node] = max(tops.get(node, -math.inf), yv - drop)
    return tops


def _unit_ends(p, yv):
    """The servovalve's and the cylinder's ports, (x, y, exit)."""
    if p.symbol == "servovalve":
        return {"supply": (-0.25, yv - 0.4, "down"), "return": (0.25, yv - 0.4, "down"),
                "bottom": (-0.25, yv + 0.4, "up"), "top": (0.25, yv + 0.4, "up")}
    return {"bottom": (-0.9, p.y - 0.35, "down"), "top": (0.9, p.y - 0.35, "down")}


def _place_attachments(circuit, comps, kinds, placed, units, place, signals):
    """Load and friction on each cylinder's rod, the controller and the commands beside the
    valve's torque motor, and the signal lines between them (dashed)."""
    producer, readers = {}, defaultdict(list)
    for c in circuit.components:
        for port in c.outputs:
            producer[c.signal(port)] = c.name
        for port in c.inputs:
            readers[c.signal(port)].append(c.name)
    for valve, axis, yv in units:
        p = placed[valve]
        p.ends = _unit_ends(p, yv)
        cyl = next((q for q in placed.values() if q is not None and q.symbol == "cylinder"
                    and abs(q.y - (yv + 1.95)) < 1e-9), None)
        if cyl is not None:
            cyl.ends = _unit_ends(cyl, yv)
            signals_of = {comps[cyl.name].signal(port) for port in comps[cyl.name].outputs}
            rod = [n for n in comps if n not in placed and kinds[n] in ("load", "friction")
                   and any(comps[n].signal(port) in signals_of for port in comps[n].inputs)]
            for n in rod:
                if kinds[n] == "friction":
                    place(n, "friction", "unit", x=-1.9, y=cyl.y)
                elif not any(q is not None and q.symbol == "load" and q.y == cyl.y
                             for q in placed.values()):
                    place(n, "load", "unit", x=1.9, y=cyl.y)
                else:   # a second load: below the first
                    place(n, "load", "unit", x=1.9, y=cyl.y - 0.9)
        # what drives the valve's current: a controller, a command, or the experiment
        current = comps[valve].signal("current") if "current" in comps[valve].inputs else None
        driver = producer.get(current)
        x_side = 3.6
        if driver is not None and driver not in placed:
            kind = kinds[driver]
            symbol = "controller" if kind == "position_controller" else SYMBOL_OF_TYPE.get(kind, "box")
            place(driver, symbol, "signal", x=x_side, y=yv)
            signals.append((driver, valve, current, [((x_side - 0.7, yv), (2.05, yv))]))
            if symbol == "controller":
                _controller_inputs(comps, kinds, placed, place, producer, driver, cyl, yv,
                                   signals)
        elif driver is None and current is not None:
            signals.append(("experiment", valve, current, [((3.4, yv), (2.05, yv))]))


def _controller_inputs(comps, kinds, placed, place, producer, ctrl, cyl, yv, signals):
    """A controller's feedback from the cylinder's rod and its reference."""
    c = comps[ctrl]
    x = placed[ctrl].x
    for port in c.inputs:
        sig = c.signal(port)
        src = producer.get(sig)
        if port == "reference":
            if src is None:
                signals.append(("experiment", ctrl, sig, [((x + 1.6, yv), (x + 0.7, yv))]))
            elif src not in placed:
                place(src, SYMBOL_OF_TYPE.get(kinds[src], "command"), "signal", x=x + 2.1, y=yv)
                signals.append((src, ctrl, sig, [((x + 1.6, yv), (x + 0.7, yv))]))
        elif src is not None and cyl is not None and src == cyl.name and port == "position":
            y_top = yv + 0.75
            signals.append((src, ctrl, sig, [((2.25, cyl.y - 0.35), (2.25, y_top)),
                                             ((2.25, y_top), (x, y_top)),
                                             ((x, y_top), (x, yv + 0.3))]))


def _route(node, ends, placed, node_at, lanes) -> Net:
    """The line of one node: each port to the node's vertical line (its x), straight along
    its lane where nothing is in the way, else around below; dots where three lines meet."""
    net = Net(node, list(ends))
    points = []
    for name, end in ends:
        p = placed.get(name)
        if p is None or end not in p.ends:
            continue
        x, y, exit_ = p.ends[end]
        points.append((name, end, x, y, exit_))
    if not points:
        return net
    units_only = all(placed[name].role == "unit" for name, *_ in points)
    if node in node_at:
        xn = node_at[node][0]
    elif units_only:   # valve to cylinder
        xn = None
    else:
        xn = sum(q[2] for q in points) / len(points)
    if xn is None:   # A or B line of a unit: up from the valve, across, up to the cylinder
        (_, _, x0, y0, _), *rest = sorted(points, key=lambda q: q[3])
        for _, _, x1, y1, _ in rest:
            ym = y0 + (0.45 if x0 < 0 else 0.65)
            net.segments += [((x0, y0), (x0, ym)), ((x0, ym), (x1, ym)), ((x1, ym), (x1, y1))]
        return net
    on_line = []                 # (y on the node's line, came from the left/right/above/below)
    boxes = [(q.name, _estimated_box(q)) for q in placed.values() if q is not None]
    for name, end, x, y, exit_ in points:
        p = placed[name]
        if p.symbol == "servovalve" and end in ("supply", "return"):   # down to its lane
            lane = p.y - SUPPLY_DROP - (RETURN_GAP if end == "return" else 0.0)
            net.segments.append(((x, y), (x, lane)))
            y = lane
            exit_ = "left" if xn < x else "right"
        if exit_ == "down" and p.role == "branch":        # standing on the line
            if abs(x - xn) > 1e-9:
                yb = y - 0.2
                net.segments += [((x, y), (x, yb)), ((x, yb), (xn, yb))]
                on_line.append((yb, "right" if x > xn else "left"))
            else:
                on_line.append((y, "up"))
            continue
        toward = (exit_ == "left" and xn <= x) or (exit_ == "right" and xn >= x)
        blocked = any(n != name and _crosses(b, min(x, xn), max(x, xn), y) for n, b in boxes)
        if toward and not blocked:
            if abs(x - xn) > 1e-9:
                net.segments.append(((x, y), (xn, y)))
            on_line.append((y, "right" if x > xn else "left"))
        else:    # out of its port, down to a lane of its own, across to the node's line
            step = 0.35 if exit_ == "right" else -0.35
            yc = lanes.below()
            net.segments += [((x, y), (x + step, y)), ((x + step, y), (x + step, yc)),
                             ((x + step, yc), (xn, yc))]
            on_line.append((yc, "right" if x + step > xn else "left"))
    ys = [y for y, _ in on_line]
    lo, hi = min(ys), max(ys)
    if hi > lo:
        net.segments.append(((xn, lo), (xn, hi)))
    for y in sorted(set(round(v, 9) for v in ys)):
        sides = {s for v, s in on_line if abs(v - y) < 1e-9}
        if y > lo + 1e-9:
            sides.add("below")
        if y < hi - 1e-9:
            sides.add("above")
        if len(sides) >= 3:
            net.dots.append((xn, y))
    net.anchor = net.dots[0] if net.dots else (xn, hi)
    return net


#: Half-extents of each symbol (u along its line, v across), for routing before it is drawn.
_EXTENT = {"hose": (1.3, 0.3), "restriction": (0.6, 0.25), "check_valve": (0.6, 0.26),
           "relief_valve": (0.75, 0.8), "pump": (0.7, 0.66), "pressure_source": (0.7, 0.38),
           "tank": (0.6, 0.62), "box": (0.6, 0.3), "servovalve": (2.1, 0.5),
           "cylinder": (1.9, 0.35), "controller": (0.7, 0.3), "command": (0.5, 0.22),
           "load": (1.35, 0.35), "friction": (0.55, 0.2), "accumulator": (0.3, 1.35),
           "volume": (0.4, 0.85), "junction": (0.09, 0.09)}


def _estimated_box(p):
    hu, hv = _EXTENT.get(p.symbol, (0.6, 0.3))
    if p.role == "branch":
        return (p.x - hu, p.y, p.x + hu, p.y + hv)
    return (p.x - hu, p.y - hv, p.x + hu, p.y + hv)


def _crosses(box, x0, x1, y) -> bool:
    """True when the horizontal segment ``[x0, x1]`` at ``y`` runs through ``box``."""
    bx0, by0, bx1, by1 = box
    return by0 < y < by1 and bx0 < x1 - 1e-6 and x0 + 1e-6 < bx1


# ---- drawing ------------------------------------------------------------------------------

def draw_schematic(circuit, path=None, title: str = "") -> Schematic:
    """Draw a circuit as a hydraulic schematic with ISO 1219-1 symbols (see the module) and
    write it to ``path``: SVG or PNG by its extension.

    Parameters
    ----------
    circuit : Circuit
        The circuit (:func:`hydroline.system.build_circuit`).
    path : str or Path
        The file to write (``.svg`` or ``.png``); None: not written.
    title : str
        Figure title.

    Returns
    -------
    Schematic
        The layout, with each symbol's and label's drawn extent, [drawing units]; its
        figure as ``figure``.
    """
    from ..plotting import new_figure, save_png, wrap_title

    s = schematic(circuit, title)
    boxes = [_estimated_box(p) for p in s.placed.values()]
    for net in s.nets.values():
        for (x0, y0), (x1, y1) in net.segments:
            boxes.append((min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1)))
    margin = 0.8
    x0 = min(b[0] for b in boxes) - margin
    x1 = max(b[2] for b in boxes) + margin
    y0 = min(b[1] for b in boxes) - margin
    y1 = max(b[3] for b in boxes) + margin
    width, height = (x1 - x0) / UNITS_PER_INCH, (y1 - y0) / UNITS_PER_INCH
    fig = new_figure((width, height + TITLE_BAND + NOTE_BAND))
    ax = fig.add_axes(_drawing_area(height))
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.axis("off")
    # symbols
    for p in s.placed.values():
        turns = p.turns
        pen = Pen(ax, p.x, p.y, mirror=p.mirror, quarter_turns=turns)
        SYMBOLS[p.symbol](pen)
        if p.inscription:
            pen.text(0.0, 0.0, p.inscription, fontsize=LABEL_SIZE)
        p.box = pen.box
    # working lines (solid), junction dots, signal lines (dashed)
    for net in s.nets.values():
        for (xa, ya), (xb, yb) in net.segments:
            ax.plot([xa, xb], [ya, yb], color="k", lw=LINE_WIDTH, solid_capstyle="projecting")
        for x, y in net.dots:
            ax.add_patch(_dot(x, y))
    for src, dst, sig, segments in s.signals:
        for (xa, ya), (xb, yb) in segments:
            ax.plot([xa, xb], [ya, yb], color="k", lw=0.8, ls=(0, (4, 2)))
        (xa, ya), (xb, yb) = segments[-1]
        ax.annotate("", (xb, yb), (xa, ya), arrowprops=dict(arrowstyle="-|>", lw=0.8,
                                                            color="k", shrinkA=0, shrinkB=0))
        if src == "experiment":
            xs, ys = segments[0][0]
            ax.text(xs + 0.15, ys, f"{sig}\n(from the experiment)", fontsize=LABEL_SIZE - 0.5,
                    ha="left", va="center", color="0.25")
    _place_labels(fig, ax, s)
    # the drawing grows to hold the texts that reach past it (at the same scale)
    renderer, inverse = fig.canvas.get_renderer(), ax.transData.inverted()
    for t in ax.texts:
        e = t.get_window_extent(renderer)
        (a0, b0), (a1, b1) = inverse.transform([(e.x0, e.y0), (e.x1, e.y1)])
        x0, y0, x1, y1 = min(x0, a0 - 0.3), min(y0, b0 - 0.3), max(x1, a1 + 0.3), max(y1, b1 + 0.3)
    width, height = (x1 - x0) / UNITS_PER_INCH, (y1 - y0) / UNITS_PER_INCH
    fig.set_size_inches(width, height + TITLE_BAND + NOTE_BAND)
    ax.set_position(_drawing_area(height))
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    fig.suptitle(wrap_title(title or "hydraulic circuit (ISO 1219-1 symbols)", width, 10),
                 fontsize=10, y=1 - 0.08 / (height + TITLE_BAND + NOTE_BAND), va="top")
    fig.text(0.01, 0.005, "solid: working lines; dashed: signal lines; dot: connection; "
             "lines crossing without a dot are not connected", fontsize=6, color="0.3",
             ha="left", va="bottom")
    s.figure = fig
    if path is not None:
        if str(path).lower().endswith(".svg"):
            import matplotlib

            with matplotlib.rc_context({"svg.fonttype": "none"}):   # text stays text
                fig.savefig(path, format="svg", metadata={"Date": None})
        else:
            save_png(fig, path, dpi=130)
    return s


#: Bands above the drawing for the title and below it for the note on the lines, [inch].
TITLE_BAND, NOTE_BAND = 0.5, 0.25


def _drawing_area(height):
    """The axes' place in the figure, [fractions], for a drawing ``height`` inches high."""
    total = height + TITLE_BAND + NOTE_BAND
    return (0, NOTE_BAND / total, 1, height / total)


def _dot(x, y):
    from matplotlib.patches import Circle

    return Circle((x, y), 0.1, color="k", zorder=4)


#: Where a label is tried, in order, by the symbol's role: (side, alignment).
_LABEL_SPOTS = {"supply": ("above", "below", "above-left", "above-right"),
                "return": ("below", "above", "below-left", "below-right"),
                "branch": ("above", "right", "left"),
                "unit": ("above", "left", "right", "below"),
                "signal": ("below", "above", "right"),
                "junction": ("above-right", "below-right", "above-left", "below-left"),
                "other": ("below", "above", "right", "left")}


def _place_labels(fig, ax, s):
    """Each symbol's label beside it, where it overlaps no symbol, label or line (or the
    least), measured as drawn."""
    renderer = fig.canvas.get_renderer()
    inverse = ax.transData.inverted()
    obstacles = [p.box for p in s.placed.values() if p.box]
    lines = []
    for net in s.nets.values():
        lines += net.segments
    for *_, segments in s.signals:
        lines += segments
    done = []

    def overlap(a, b):
        w = min(a[2], b[2]) - max(a[0], b[0])
        h = min(a[3], b[3]) - max(a[1], b[1])
        return w * h if w > 0 and h > 0 else 0.0

    def line_cost(box):
        cost = 0.0
        for (xa, ya), (xb, yb) in lines:
            seg = (min(xa, xb) - 0.05, min(ya, yb) - 0.05, max(xa, xb) + 0.05, max(ya, yb) + 0.05)
            cost += overlap(box, seg)
        return cost

    roles = ("unit", "signal", "branch", "supply", "return", "junction", "other")
    order = sorted(s.placed.values(), key=lambda p: roles.index(p.role) if p.role in roles else 9)
    for p in order:
        if not p.label or not p.box:
            continue
        bx0, by0, bx1, by1 = p.box
        xc, yc = 0.5 * (bx0 + bx1), 0.5 * (by0 + by1)
        gap = 0.12
        spots = {"above": (xc, by1 + gap, "center", "bottom"),
                 "below": (xc, by0 - gap, "center", "top"),
                 "right": (bx1 + gap, yc, "left", "center"),
                 "left": (bx0 - gap, yc, "right", "center"),
                 "above-left": (bx1, by1 + gap, "right", "bottom"),
                 "above-right": (bx0, by1 + gap, "left", "bottom"),
                 "below-left": (bx1, by0 - gap, "right", "top"),
                 "below-right": (bx0, by0 - gap, "left", "top")}
        tried = list(_LABEL_SPOTS.get(p.role, ())) + [k for k in spots
                                                       if k not in _LABEL_SPOTS.get(p.role, ())]
        best = None
        for key in tried:
            x, y, ha, va = spots[key]
            t = ax.text(x, y, p.label, fontsize=LABEL_SIZE, ha=ha, va=va, linespacing=1.1)
            ext = t.get_window_extent(renderer)
            (a0, b0), (a1, b1) = inverse.transform([(ext.x0, ext.y0), (ext.x1, ext.y1)])
            box = (a0, b0, a1, b1)
            # (over a line it stays readable; over a symbol or a label it does not)
            cost = (3 * sum(overlap(box, o) for o in obstacles)
                    + 3 * sum(overlap(box, o) for o in done) + 0.3 * line_cost(box))
            if best is None or cost < best[0]:
                if best is not None:
                    best[1].remove()
                best = (cost, t, box)
            else:
                t.remove()
            if cost == 0:
                break
        p.label_box = best[2]
        done.append(best[2])
