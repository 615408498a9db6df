"""The circuit as an ISO 1219-1 hydraulic schematic (issue 26 item 7): every component once
with its symbol, every node's line once and joining exactly the ports on that node (nodes
read from the components' pressure ports here, not from the layout), no symbol or label over
another, the lines from the pump to the valve left to right, and the command's files."""
import numpy as np
import pytest

from hydroline.circuit.drawing import type_name
from hydroline.circuit.iso1219 import SYMBOLS
from hydroline.circuit.schematic import SYMBOL_OF_TYPE, draw_schematic
from hydroline.circuit.types import COMPONENT_TYPES
from hydroline.cli import main
from hydroline.rigs import load_rig
from hydroline.system import build_circuit

PUMP_CIRCUIT = '''
[fluid]
density = "870 kg/m^3"
kinematic_viscosity = "32 cSt"
bulk_modulus = "1.5 GPa"
[circuit.tank]
type = "pressure_source"
pressure = "0.1 MPa"
ports = { pressure = "p_tank" }
[circuit.pump]
type = "pump"
displacement = "10 cm^3"
shaft_speed = "1500 rpm"
ports = { outlet_pressure = "p", inlet_pressure = "p_tank", flow = "q_pump" }
[circuit.relief]
type = "relief_valve"
cracking_pressure = "21 MPa"
flow_gradient = "1.2 L/min/bar"
ports = { inlet_pressure = "p", outlet_pressure = "p_tank", flow = "q_relief" }
[circuit.orifice]
type = "resistance"
compute = "flow"
resistance = "1e11 Pa*s/m^3"
ports = { inlet_pressure = "p", outlet_pressure = "p_tank", flow = "q_load" }
[circuit.node]
type = "volume"
volume = "50 cm^3"
terms = { pump = 1, relief = -1, load = -1 }
ports = { pump = "q_pump", relief = "q_relief", load = "q_load", pressure = "p" }
'''


@pytest.fixture(scope="module", params=["ayalew2005", "two_axis", "pump"])
def drawn(request, tmp_path_factory):
    if request.param == "pump":
        path = tmp_path_factory.mktemp("rig") / "pump.toml"
        path.write_text(PUMP_CIRCUIT)
        rig = load_rig(path)
    else:
        rig = load_rig(request.param)
    circuit = build_circuit(rig)
    return request.param, circuit, draw_schematic(circuit, title=request.param)


def test_every_component_type_has_a_symbol():
    assert set(COMPONENT_TYPES) <= set(SYMBOL_OF_TYPE)
    assert set(SYMBOL_OF_TYPE.values()) | {"tank"} <= set(SYMBOLS)


def test_every_component_once_with_its_symbol(drawn):
    _, circuit, s = drawn
    assert sorted(s.placed) == sorted(c.name for c in circuit.components)
    tanks = set()
    for c in circuit.components:
        p = s.placed[c.name]
        expected = SYMBOL_OF_TYPE[type_name(c)]
        if p.symbol == "tank":
            tanks.add(c.name)
            expected = "tank"
        assert p.symbol == expected, c.name
        assert p.box and p.box[2] > p.box[0], c.name          # drawn
    # the pressure sources that take the return flow or feed a pump's inlet are tanks
    assert tanks == {c.name for c in circuit.components if type_name(c) == "pressure_source"
                     and c.pressure < 5e6}


def _pressure_nodes(circuit):
    """Node -> the (component, port) reading or giving that pressure, from the ports."""
    nodes = {}
    for c in circuit.components:
        for port, spec in {**c.inputs, **c.outputs}.items():
            if spec.quantity == "pressure":
                nodes.setdefault(c.signal(port), set()).add(c.name)
    return nodes


def _connected(segments, points):
    """True when every point lies on the segments and they join into one piece."""
    def on(p, seg, tol=1e-6):
        (x0, y0), (x1, y1) = seg
        return (min(x0, x1) - tol <= p[0] <= max(x0, x1) + tol
                and min(y0, y1) - tol <= p[1] <= max(y0, y1) + tol
                and abs((x1 - x0) * (p[1] - y0) - (y1 - y0) * (p[0] - x0)) < tol)

    n = len(segments)
    parent = list(range(n))

    def root(i):
        while parent[i] != i:
            i = parent[i]
        return i

    for i in range(n):
        for j in range(i + 1, n):
            if any(on(e, segments[j]) for e in segments[i]) or \
                    any(on(e, segments[i]) for e in segments[j]):
                parent[root(i)] = root(j)
    pieces = set()
    for p in points:
        hits = [k for k in range(n) if on(p, segments[k])]
        if not hits:
            return False
        pieces.add(root(hits[0]))
    return len(pieces) <= 1


def test_every_node_once_joining_exactly_its_ports(drawn):
    _, circuit, s = drawn
    nodes = _pressure_nodes(circuit)
    kinds = {c.name: type_name(c) for c in circuit.components}
    # signal-only pressures (none here) aside, one line per node, with the components on it
    assert set(s.nets) == {n for n, names in nodes.items() if names}
    seen = []
    for node, net in s.nets.items():
        on_net = {name for name, _ in net.ends if kinds[name] != "junction"}
        assert on_net == nodes[node], node
        seen += net.ends
        ports = [s.placed[name].ends[end][:2] for name, end in net.ends
                 if kinds[name] != "junction"]
        if len(ports) > 1:
            assert _connected(net.segments, ports), node
    assert len(seen) == len(set(seen))                  # each end on one line only
    for name, kind in kinds.items():                     # a junction: a dot on its line
        if kind == "junction":
            net = next(n for n in s.nets.values() if (name, "node") in n.ends)
            p = s.placed[name]
            assert _connected(net.segments, [(p.x, p.y)] + [
                s.placed[m].ends[e][:2] for m, e in net.ends if kinds[m] != "junction"])


def test_no_symbol_or_label_over_another(drawn):
    _, _, s = drawn
    boxes = [(f"{n} symbol", p.box) for n, p in s.placed.items()] + \
            [(f"{n} label", p.label_box) for n, p in s.placed.items() if p.label_box]
    for i, (a, ba) in enumerate(boxes):
        for b, bb in boxes[i + 1:]:
            w = min(ba[2], bb[2]) - max(ba[0], bb[0])
            h = min(ba[3], bb[3]) - max(ba[1], bb[1])
            assert not (w > 1e-6 and h > 1e-6), f"{a} overlaps {b}"


def test_the_lines_run_from_the_supply_to_the_valve():
    s = draw_schematic(build_circuit(load_rig(None)))
    x = {n: p.x for n, p in s.placed.items()}
    assert x["supply.pump"] < x["supply.section1"] < x["supply.manifold"] \
        < x["supply.section2"] < x["servovalve"]
    assert x["return.tank"] < x["return.section1"] < x["return.check_valve"] \
        < x["return.manifold"] < x["return.section2"] < x["servovalve"]
    assert s.placed["actuator"].y > s.placed["servovalve"].y          # the cylinder above
    assert s.placed["supply.section2"].label.splitlines()[1] == "L = 3.05 m, d = 13.4 mm"


def test_circuit_command_writes_svg_and_png(tmp_path, capsys):
    svg, png = tmp_path / "c.svg", tmp_path / "c.png"
    assert main(["circuit", "two_axis", "--schematic", str(svg)]) == 0
    text = svg.read_text()
    assert text.lstrip().startswith("<?xml") and "<svg" in text
    assert "axis2.supply_hose" in text and "L = 3.05 m" in text   # labels as text
    assert main(["circuit", "--schematic", str(png), "--json"]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    capsys.readouterr()
    assert main(["circuit", "--schematic", str(tmp_path / "c.pdf")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--schematic" in err[0] and ".svg" in err[0]
    assert not (tmp_path / "c.pdf").exists()
