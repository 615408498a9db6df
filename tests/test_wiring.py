"""Physical wiring checks (issue 24, hydroline/circuit/wiring.py): a circuit that causality
accepts but no real rig could be is refused before any run, in one line naming component and
port; an unusual but possible one gets a one-line warning; the shipped rigs and the
legitimate variants (ideal supply, close-coupled manifolds, a pump-fed supply) pass without a
word. The expectations come from how each circuit is built (which port was cut or crossed),
not from running the checks."""
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from hydroline import components as comp
from hydroline.circuit import CircuitError, check_circuit
from hydroline.circuit.wiring import WiringWarning
from hydroline.cli import main
from hydroline.engine import Network, NetworkError
from hydroline.engine.network import UnusedSignalWarning
from hydroline.rigs import RigError, load_rig
from hydroline.system import build_circuit

DATA = Path(__file__).parent / "data"
CIRCUIT = (DATA / "ayalew2005_circuit.toml").read_text()


def _one_line(capsys, argv):
    rc = main(argv)
    cap = capsys.readouterr()
    err = cap.err.strip()
    assert rc == 2, (rc, err)
    assert "\n" not in err and "Traceback" not in err and ": error: " in err, err
    assert cap.out == ""
    return err


# ---- the issue's reproducers (shared/repro, copied to tests/data) -------------------------
@pytest.mark.parametrize("name, needles", [
    # the valve's P port fed from its own return port
    ("p1_616_overlay.toml", ("connections.servovalve.supply_pressure", "return_port_pressure",
                             "short circuit")),
    # a hose reading its own downstream pressure as its upstream pressure
    ("p2_071_self_loop.toml", ("circuit.axis1.supply_hose.ports.upstream_pressure",
                               "downstream_pressure", "self-loop")),
    # supply and return manifolds cross-wired, the pump cut off: the supply manifold reads
    # the return side's pressure while its flow is drawn from the pump's hose
    ("p2_075_algebraic_loop.toml", ("circuit.supply.manifold.ports.inlet_pressure",
                                    "return.check_valve_pressure", "different nodes")),
    # a junction summing its own output (was: error: 'supply.manifold_flow')
    ("p2_065_self_loop.toml", ("circuit.supply.junction.ports.axis1", "self-loop")),
])
def test_issue_reproducers_exit_2_naming_the_port(tmp_path, capsys, name, needles):
    err = _one_line(capsys, ["simulate", str(DATA / name), "--json", "--out", str(tmp_path)])
    for n in needles:
        assert n in err, (n, err)
    assert "warning" not in err          # the error alone, not a lost-flow warning before it


def test_self_looped_junction_in_layout_is_one_line_not_a_key_error(tmp_path, capsys):
    err = _one_line(capsys, ["layout", str(DATA / "p2_065_self_loop.toml"), "--sections",
                             "axis1.supply_hose", "--lengths", "1,2", "--out", str(tmp_path)])
    assert "supply.junction" in err and "self-loop" in err
    assert not err.endswith("'supply.manifold_flow'")


def test_reproducer_in_a_real_process(tmp_path):
    done = subprocess.run([sys.executable, "-m", "hydroline", "simulate",
                           str(DATA / "p1_616_overlay.toml"), "--json", "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stdout == ""
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr
    assert "servovalve.supply_pressure" in done.stderr


def test_network_refuses_a_feedthrough_component_fed_its_own_output():
    """Every caller (layout, sweep, a script) gets the loop named, not a KeyError."""
    parts = [comp.PressureSource(name="tank", pressure=1e5, connections={"pressure": "p"}),
             comp.FlowJunction(name="j", terms={"a": 1, "b": 1},
                               connections={"a": "q", "b": "q_b", "flow": "q"}),
             comp.LinearResistance(name="r", compute="flow", resistance=1e9, connections={
                 "inlet_pressure": "p", "outlet_pressure": "p", "flow": "q_b"})]
    with pytest.raises(NetworkError, match=r"'j\.a' reads 'q', which its own port 'j\.flow'"):
        Network(parts)


# ---- legitimate circuits pass without a word ---------------------------------------------
def _rig(name, **settings):
    rig = load_rig(None if name == "default" else name)
    for k, v in settings.items():
        rig.set(k.replace("__", "."), v)
    return rig


IDEAL_TWO_AXIS = {f"connections.{n}.servovalve.{p}_pressure": s for n in ("axis1", "axis2")
                  for p, s in (("supply", "pump_pressure"), ("return", "tank_pressure"))}


@pytest.mark.parametrize("rig", [
    lambda: _rig("default"),
    lambda: _rig("default", supply__section2__length="0 m", return__section2__length="0 m"),
    lambda: _rig("default", supply__section2__length="0 m"),
    lambda: _rig("default", return__section2__length="0 m"),
    lambda: _rig("default", **{"connections.servovalve.supply_pressure": "pump_pressure"}),
    lambda: _rig("default", **{"connections.servovalve.supply_pressure": "pump_pressure",
                               "connections.servovalve.return_pressure": "tank_pressure"}),
    lambda: _rig("two_axis"),
    lambda: _rig("two_axis", **IDEAL_TWO_AXIS),
    lambda: _rig(DATA / "ayalew2005_circuit.toml"),
], ids=["default", "close-coupled", "supply-close-coupled", "return-close-coupled",
        "ideal-supply", "ideal-supply-and-tank", "two_axis", "two_axis-ideal", "paper-circuit"])
def test_shipped_and_legitimate_circuits_pass_without_a_word(rig):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        circuit = build_circuit(rig())
        # the template's own wiring too (its build checks only a rig's [connections])
        assert check_circuit(circuit.components, {}) == []


def _circuit(tmp_path, text):
    path = tmp_path / "c.toml"
    path.write_text(text)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        build_circuit(load_rig(path))
    return [str(w.message) for w in said if issubclass(w.category, (WiringWarning,
                                                                      UnusedSignalWarning))]


PUMP_FED = """
[circuit."supply.pump"]
type = "pump"
displacement = "10 cm^3"
shaft_speed = "1500 rpm"
ports = { outlet_pressure = "pump_pressure", inlet_pressure = "tank_pressure", flow = "q_pump" }
[circuit."supply.relief"]
type = "relief_valve"
cracking_pressure = "21 MPa"
flow_gradient = "1.2 L/min/bar"
ports = { inlet_pressure = "pump_pressure", outlet_pressure = "tank_pressure", flow = "q_relief" }
[circuit."supply.pump_node"]
type = "volume"
volume = "50 cm^3"
terms = { pump = 1, relief = -1, line = -1 }
ports = { pump = "q_pump", relief = "q_relief", line = "pump_flow", pressure = "pump_pressure" }
"""


def _without_table(text, name):
    """The circuit text without the table ``[circuit."name"]``."""
    return re.sub(rf'^\[circuit\."{re.escape(name)}"\].*\n(?:(?!\[).*\n)*', "", text, count=1,
                  flags=re.M)


def test_pump_fed_supply_passes_without_a_word(tmp_path):
    """The pressure source replaced by a fixed pump into a node with a relief valve to tank:
    P reaches a pump (``source_ends``), T the tank."""
    assert _circuit(tmp_path, _without_table(CIRCUIT, "supply.pump") + PUMP_FED) == []


def test_supply_without_any_source_is_warned(tmp_path):
    """The pump unit replaced by a closed 1 L volume: physically possible (the valve drains the
    stored oil), but P reaches neither a pressure source nor a pump."""
    text = _without_table(CIRCUIT, "supply.pump") + (
        '[circuit."supply.store"]\ntype = "volume"\nvolume = "1 L"\nnominal_pressure = "20 MPa"\n'
        'terms = { line = -1 }\nports = { line = "pump_flow", pressure = "pump_pressure" }\n')
    said = _circuit(tmp_path, text)
    assert len(said) == 1 and "servovalve.ports.supply_pressure" in said[0]
    assert "reaches no pressure source or pump" in said[0]


def test_leak_from_supply_to_tank_is_warned(tmp_path):
    """A bleed orifice from the P port into the return hose's node joins P and T through a
    resistance: a leak, possible but unusual (its flow, read by nobody, is warned of too)."""
    said = _circuit(tmp_path, CIRCUIT + (
        '[circuit.bleed]\ntype = "resistance"\ncompute = "flow"\nresistance = "1e12 Pa*s/m^3"\n'
        'ports = { inlet_pressure = "supply_port_pressure", outlet_pressure = '
        '"return_port_pressure", flow = "bleed_flow" }\n'))
    assert any("a leak from supply to return" in s and "servovalve" in s for s in said), said


def test_idle_pressure_source_is_warned(tmp_path):
    said = _circuit(tmp_path, CIRCUIT + (
        '[circuit.spare]\ntype = "pressure_source"\npressure = "5 MPa"\n'
        'ports = { pressure = "spare_pressure" }\n'))
    assert said == ["circuit.spare.ports.pressure: the pressure 'spare_pressure' is read by no "
                    "component: spare feeds nothing"]


def test_circuit_cut_off_from_every_source_is_refused(tmp_path):
    """Pump unit and tank both replaced by closed volumes: no oil path reaches a prescribed
    pressure or a pump, so no pressure of the circuit has a level to start from."""
    text = _without_table(_without_table(CIRCUIT, "supply.pump"), "return.tank") + (
        '[circuit."supply.store"]\ntype = "volume"\nvolume = "1 L"\nterms = { line = -1 }\n'
        'ports = { line = "pump_flow", pressure = "pump_pressure" }\n'
        '[circuit."return.store"]\ntype = "volume"\nvolume = "1 L"\nterms = { line = 1 }\n'
        'ports = { line = "tank_flow", pressure = "tank_pressure" }\n')
    with pytest.raises(RigError, match=r"cut off from every pressure source and pump"):
        _circuit(tmp_path, text)


# ---- one case per class, on the template rig's [connections] -----------------------------
@pytest.mark.parametrize("overrides, needles", [
    # a port reading its own component's output: a hose fed its own far end
    ({"supply.section2.upstream_pressure": "supply_port_pressure"},
     ("connections.supply.section2.upstream_pressure", "self-loop")),
    # two ports of one component on one node: the valve's chamber ports shorted
    ({"servovalve.top_pressure": "bottom_chamber_pressure"},
     ("connections.servovalve.top_pressure", "short circuit")),
    # P on the tank while its flow is drawn from the supply hose
    ({"servovalve.supply_pressure": "tank_pressure"},
     ("connections.servovalve.supply_pressure", "tank_pressure", "different nodes")),
    # chamber pressures crossed: the valve meters into one chamber and reads the other
    ({"servovalve.bottom_pressure": "top_chamber_pressure",
      "servovalve.top_pressure": "bottom_chamber_pressure"},
     ("connections.servovalve.bottom_pressure", "different nodes")),
    # P and T swapped, pressures and flows alike: every end consistent, but P faces the tank
    ({"servovalve.supply_pressure": "return_port_pressure", "servovalve.supply_flow": "return_port_flow",
      "servovalve.return_pressure": "supply_port_pressure", "servovalve.return_flow": "supply_port_flow"},
     ("connections.servovalve.supply_pressure", "must face the supply", "1.5 MPa against 20.7 MPa")),
    # the supply manifold fed from the return manifold, its flow still drawn from the pump hose
    ({"supply.manifold.inlet_pressure": "return.check_valve_pressure"},
     ("connections.supply.manifold.inlet_pressure", "different nodes")),
    # an actuator chamber fed from the accumulator's branch instead of the valve
    ({"actuator.bottom_flow": "supply.accumulator_flow"},
     ("actuator.bottom_pressure", "different nodes")),
    # a port on a signal nothing outputs
    ({"actuator.top_flow": "nowhere_flow"}, ("connections.actuator.top_flow", "unconnected")),
])
def test_miswired_template_refused_in_one_line(overrides, needles):
    rig = load_rig()
    for k, v in overrides.items():
        rig.set(f"connections.{k}", v)
    with pytest.raises(RigError) as err:
        build_circuit(rig)
    msg = str(err.value)
    assert "\n" not in msg
    for n in needles:
        assert n in msg, (n, msg)


def test_wiring_errors_are_circuit_errors():
    """The builder's own exception type (one line at the CLI, exit 2)."""
    parts = build_circuit(load_rig()).components
    valve = next(c for c in parts if isinstance(c, comp.Servovalve))
    valve.connections = dict(valve.connections, return_pressure="supply_port_pressure")
    with pytest.raises(CircuitError, match=r"^servovalve\.supply_pressure: .*short circuit"):
        check_circuit(parts, {})
