"""Nothing in a rig is ignored or absurd without a word (issue 24, item 4), and a rig without a
rest state is refused.

* every numeric parameter of every component type declares a plausible range (a 1e30 cm^3
  chamber is refused by name, with its unit; ``[rig] allow_implausible`` still lets it run);
* a table the rig's kind does not read (a template ``[supply]`` table in a circuit rig) is
  refused by name, in a file and through :meth:`Rig.set`; ``[rig] base`` names a shipped rig,
  a rig file or nothing (tests/test_compose.py: what an extending file may change);
* scenario steps and amplitudes are checked against the commanded axis's stroke;
* component names are non-empty, printable and bounded in length (any script);
* a network whose rest state does not exist (a pump filling a closed block) is refused in one
  line naming the state, with the residual derived by hand; loosening the steady-state
  residual guard (engine/steady_state.py) makes these tests fail.
"""
import math
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from hydroline import components as comp
from hydroline.circuit.builder import MAX_NAME_LENGTH
from hydroline.circuit.types import (COMPONENT_TYPES, FLUID_PARAMETERS, QUANTITY_PLAUSIBLE,
                                     QUANTITY_UNIT)
from hydroline.cli import main
from hydroline.engine import Network, SteadyStateError, solve_steady_state
from hydroline.rigs import RigError, load_rig
from hydroline.scenarios import build_scenario
from hydroline.system import build_circuit

TWO_AXIS = resources.files("hydroline.rigs").joinpath("two_axis.toml").read_text()
CIRCUIT = Path(__file__).parent / "data" / "ayalew2005_circuit.toml"   # one axis, no controller


def _rig_file(tmp_path, text, name="rig.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _refused(capsys, path, *culprits):
    """`hydroline simulate PATH --json`: exit 2, one line on stderr naming every culprit."""
    assert main(["simulate", str(path), "--json"]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert "Traceback" not in captured.err and captured.out == ""
    for c in culprits:
        assert c in lines[0], lines[0]
    return lines[0]


# ---------------------------------------------------------------- plausible ranges

def _declarations():
    """(type, key, declaration) of every parameter a circuit file may give, a command's
    levels once per quantity (their unit and range are the quantity's)."""
    for tname, t in COMPONENT_TYPES.items():
        variants = [{"quantity": q} for q in QUANTITY_UNIT] if "quantity" in t.declarations() \
            else [None]
        for values in variants:
            for key, decl in t.declarations(values).items():
                yield f"{tname}.{key}" + (f" ({values['quantity']})" if values else ""), decl
    for key, decl in FLUID_PARAMETERS.items():
        yield f"fluid.{key}", decl


@pytest.mark.parametrize("where, decl", list(_declarations()), ids=lambda v: v if
                         isinstance(v, str) else "")
def test_every_numeric_parameter_of_every_component_type_declares_a_plausible_range(where, decl):
    """A range on every numeric parameter (text parameters have choices instead), lying
    inside the physical bounds, with the default inside it: a slip of unit or exponent in any
    parameter of any component is caught (issue 24: a 1e30 cm^3 chamber volume had none)."""
    if decl.unit == "str":
        return
    assert decl.plausible is not None, f"{where}: numeric parameter without a plausible range"
    low, high = decl.plausible
    assert low is not None or high is not None, where
    if low is not None and high is not None:
        assert low < high, where
    if decl.minimum is not None and low is not None:
        assert low >= decl.minimum, f"{where}: plausible {low} below the physical bound"
    if decl.maximum is not None and high is not None:
        assert high <= decl.maximum, f"{where}: plausible {high} above the physical bound"
    default = decl.default
    if isinstance(default, (int, float, tuple, list)) and not isinstance(default, bool):
        assert decl.implausible(default) is None, f"{where}: default {default!r} implausible"


def test_a_command_level_takes_the_plausible_range_of_its_quantity():
    """A step command's levels are a pressure's range when it commands a pressure (20 MPa
    plausible) and a current's when a current (20 MPa would not even be a current); the slope
    of a ramp is its quantity per second."""
    step = COMPONENT_TYPES["step_command"]
    assert step.declarations({"quantity": "pressure"})["final"].unit == "Pa"
    assert step.declarations({"quantity": "pressure"})["final"].implausible(20e6) is None
    assert step.declarations({"quantity": "current"})["final"].implausible(20e6) is not None
    assert step.declarations()["final"].plausible == (-QUANTITY_PLAUSIBLE["current"],
                                                      QUANTITY_PLAUSIBLE["current"])
    assert COMPONENT_TYPES["ramp_command"].declarations({"quantity": "position"})["slope"].unit \
        == "m/s"


_NODE = '''
[fluid]
density = "870 kg/m^3"
kinematic_viscosity = "32 cSt"
bulk_modulus = "1.5 GPa"
[circuit.tank]
type = "pressure_source"
pressure = "0.5 MPa"
ports = { pressure = "p_tank" }
[circuit.command]
type = "step_command"
quantity = "pressure"
initial = "5 MPa"
final = "FINAL"
time = "1 ms"
ports = { command = "p_in" }
[circuit.inlet]
type = "resistance"
compute = "flow"
resistance = "1e11 Pa*s/m^3"
ports = { inlet_pressure = "p_in", outlet_pressure = "p", flow = "q_in" }
[circuit.outlet]
type = "resistance"
compute = "flow"
resistance = "1e11 Pa*s/m^3"
ports = { inlet_pressure = "p", outlet_pressure = "p_tank", flow = "q_out" }
[circuit.node]
type = "volume"
volume = "50 cm^3"
terms = { inflow = 1, outflow = -1 }
ports = { inflow = "q_in", outflow = "q_out", pressure = "p" }
'''


def test_a_commanded_level_out_of_its_quantitys_range_is_refused_with_its_unit(tmp_path):
    build_circuit(load_rig(_rig_file(tmp_path, _NODE.replace("FINAL", "6 MPa"))))
    with pytest.raises(RigError, match=r"circuit\.command\.final: '6e30 MPa' is outside its "
                       r"plausible range, within -1e\+08 \.\.\. 1e\+08 \[Pa\]"):
        build_circuit(load_rig(_rig_file(tmp_path, _NODE.replace("FINAL", "6e30 MPa"))))


def test_a_huge_chamber_volume_is_refused_by_name_unless_allowed(tmp_path, capsys):
    """The reproducer of issue 24: top_volume = "1e30 cm^3" on axis 2 of two_axis ran."""
    text = TWO_AXIS + '\n[circuit."axis2.actuator"]\ntop_volume = "1e30 cm^3"\n'   # axis 2's only
    line = _refused(capsys, _rig_file(tmp_path, text), "circuit.axis2.actuator.top_volume",
                    "'1e30 cm^3'", "[m^3]", "allow_implausible")
    assert "hydroline simulate: error:" in line
    allowed = text.replace('scenario = "position-step"', 'scenario = "position-step"\n'
                           'allow_implausible = ["circuit.axis2.actuator.top_volume"]', 1)
    circuit = build_circuit(load_rig(_rig_file(tmp_path, allowed)))   # the override still works
    assert circuit.component("axis2.actuator").top_volume == pytest.approx(1e24)


def test_allow_implausible_names_a_real_circuit_parameter(tmp_path):
    """A misspelt override would silently allow nothing: refused by name."""
    text = TWO_AXIS.replace('scenario = "position-step"', 'scenario = "position-step"\n'
                            'allow_implausible = ["circuit.axis2.actuator.top_volum"]', 1)
    with pytest.raises(RigError, match=r"rig\.allow_implausible: 'circuit\.axis2\.actuator\."
                       r"top_volum' is not a parameter of a circuit component"):
        build_circuit(load_rig(_rig_file(tmp_path, text)))


# ---------------------------------------------------------------- what a rig's kind reads

@pytest.mark.parametrize("table, key, value", [
    ("supply", "pressure", '"5 MPa"'),                   # the reproducer of issue 24
    ("servovalve", "rated_current", '"50 mA"'),
    ("actuator", "stroke", '"102 mm"'),
    ("return.section1", "length", '"3 m"'),
    ("supply.pressure_profile", "type", '"step"'),
])
def test_a_template_table_in_a_circuit_rig_is_refused_by_name(tmp_path, capsys, table, key, value):
    path = _rig_file(tmp_path, TWO_AXIS + f"\n[{table}]\n{key} = {value}\n")
    _refused(capsys, path, f"{table}.{key}", f"[{table}]", "circuit rig")


def test_a_circuit_rig_keeps_the_tables_it_reads(tmp_path):
    """[rig], [fluid], [scenario.*], [connections] and [controller] (which closes the loop of
    an axis without a controller in its circuit) are read by a circuit rig: accepted; a
    [controller] beside axes that all have their own is refused by name."""
    extra = '\n[controller]\nproportional_gain = "1.5 A/m"\n'
    sine = '\n[scenario.closed-loop-sine]\namplitude = "20 mm"\nfrequency = "2 Hz"\n'
    rig = load_rig(_rig_file(tmp_path, CIRCUIT.read_text() + extra + sine))
    sc = build_scenario(rig, "closed-loop-sine")         # the axis's loop: [controller]'s
    assert [c.proportional_gain for c in sc.commands if isinstance(c, comp.PositionController)] \
        == [1.5]
    with pytest.raises(RigError, match=r"controller\.proportional_gain: every axis of the "
                       r"circuit has its own position controller \(axis1\.controller, "
                       r"axis2\.controller\)"):
        build_circuit(load_rig(_rig_file(tmp_path, TWO_AXIS + extra)))
    text = TWO_AXIS + '\n[connections]\n"axis2.servovalve.supply_pressure" = ' \
                      '"axis2.supply_port_pressure"\n'
    build_circuit(load_rig(_rig_file(tmp_path, text)))


def test_setting_a_template_parameter_on_a_circuit_rig_is_refused():
    """What a sweep's --set does: the value would change nothing in the circuit."""
    rig = load_rig("two_axis")
    with pytest.raises(RigError, match=r"supply\.pressure: a circuit rig does not use the "
                       r"\[supply\] table"):
        rig.set("supply.pressure", "5 MPa")
    rig.set("circuit.pump.pressure", "20 MPa")          # the circuit's own value: fine
    assert rig["circuit.pump.pressure"] == 20e6


@pytest.mark.parametrize("base, says", [
    ('""', "names no rig"), ('" default"', "names no rig"), ("1", "names no rig"),
    ('"two_axes"', "is no shipped rig .* \\(did you mean 'two_axis'\\?\\)"),
    ('"no_such.toml"', "rig file not found: .*no_such.toml \\(relative to ")])
def test_a_base_that_names_no_rig_is_refused(tmp_path, base, says):
    """`[rig] base = ""` was taken as no base (the file read as a complete rig)."""
    path = _rig_file(tmp_path, f'[rig]\nbase = {base}\n[supply]\npressure = "20 MPa"\n')
    with pytest.raises(RigError, match=r"^rig\.base: .*" + says):
        load_rig(path)


def test_a_template_table_on_a_circuit_base_is_refused(tmp_path):
    path = _rig_file(tmp_path, '[rig]\nbase = "two_axis"\n[supply]\npressure = "20 MPa"\n')
    with pytest.raises(RigError, match=r"^supply\.pressure: a circuit rig does not use the "
                       r"\[supply\] table"):
        load_rig(path)


def test_circuit_edits_on_the_template_base(tmp_path):
    """Circuit tables on the template base edit the template's expansion (its components
    under their template names): a hose's length changed as a circuit edit is the same rig as
    the template value changed, and as the paper's circuit with that edit."""
    from hydroline.scenarios.experiments import build_scenario
    from hydroline.scenarios.running import rest_state
    from hydroline.system import build_circuit

    def rest(text):
        rig = load_rig(_rig_file(tmp_path, text))
        circuit = build_circuit(rig)
        net = circuit.network(build_scenario(rig, "open-loop-step", None,
                                             axes=circuit.axes).commands)
        return net.state_names, rest_state(net).x

    names, x = rest('[rig]\nbase = "default"\n[circuit."supply.section2"]\nlength = "1 m"\n')
    for text in ('[rig]\nbase = "default"\n[supply.section2]\nlength = "1 m"\n',
                 '[rig]\nbase = "ayalew2005_circuit"\n[circuit."supply.section2"]\n'
                 'length = "1 m"\n'):
        other_names, other_x = rest(text)
        assert other_names == names
        np.testing.assert_allclose(other_x, x, rtol=1e-9, atol=1e-6)
    path = _rig_file(tmp_path, '[rig]\nbase = "default"\n[supply]\npressure = "20 MPa"\n')
    assert load_rig(path)["supply.pressure"] == 20e6     # the template's own base still works


def test_a_template_with_a_pressure_profile_takes_no_circuit_edits(tmp_path):
    _rig_file(tmp_path, '[rig]\nbase = "default"\n[supply.pressure_profile]\n'
              'type = "step"\ntime = "20 ms"\nfinal = "19 MPa"\n', name="base.toml")
    path = _rig_file(tmp_path, '[rig]\nbase = "base.toml"\n[circuit."supply.section2"]\n'
                     'length = "1 m"\n')
    with pytest.raises(RigError, match=r"^supply\.pressure_profile: a template rig with a "
                       r"pressure profile .* cannot take circuit edits"):
        load_rig(path)


def test_flow_terms_on_a_component_without_them_are_refused(tmp_path):
    text = TWO_AXIS + '\n[circuit."supply.section1".terms]\na = 1\n'
    with pytest.raises(RigError, match=r"circuit\.supply\.section1\.terms\.a: component "
                       r"'supply\.section1' \(hose\) has no flow terms"):
        load_rig(_rig_file(tmp_path, text))


# ---------------------------------------------------------------- scenarios and the stroke

def test_a_kilometre_step_on_a_102_mm_stroke_is_refused_with_its_unit(tmp_path, capsys):
    """The reproducer of issue 24 (a 1 km position step ran, the piston on its stop)."""
    path = _rig_file(tmp_path, TWO_AXIS.replace('step = "40 mm"', 'step = "1 km"', 1))
    _refused(capsys, path, "scenario.position-step.step", "'1 km'", "[m]")


def test_a_step_beyond_the_stroke_is_refused_unless_allowed(tmp_path):
    """Axis 1 starts at -20 mm on a 102 mm stroke: a 40 mm step reaches +20 mm (fine), an
    80 mm step +60 mm, past the stop at +51 mm."""
    text = TWO_AXIS.replace('step = "40 mm"', 'step = "80 mm"', 1)
    with pytest.raises(RigError, match=r"scenario\.position-step\.step: a step of 80 mm from "
                       r"-20 mm takes the position reference of axis 'axis1' to 60 mm, beyond "
                       r"its stroke \(\+-51 mm\) \[m\]"):
        build_scenario(load_rig(_rig_file(tmp_path, text)), "position-step")
    allowed = text.replace('scenario = "position-step"', 'scenario = "position-step"\n'
                           'allow_implausible = ["scenario.position-step.step"]', 1)
    sc = build_scenario(load_rig(_rig_file(tmp_path, allowed)), "position-step")
    step = {c.signal("command"): c.final for c in sc.commands}
    assert step["axis1.position_reference"] == pytest.approx(0.060)


def test_a_sine_beyond_the_stroke_of_a_circuit_axis_is_refused(tmp_path):
    text = TWO_AXIS.replace('amplitude = "20 mm"', 'amplitude = "60 mm"', 1)
    with pytest.raises(RigError, match=r"scenario\.closed-loop-sine\.amplitude: .* to 60 mm, "
                       r"beyond its stroke \(\+-51 mm\)"):
        build_scenario(load_rig(_rig_file(tmp_path, text)), "closed-loop-sine")
    build_scenario(load_rig("two_axis"), "closed-loop-sine")     # 20 mm: fine


# ---------------------------------------------------------------- component names

def _renamed(name: str) -> str:
    """two_axis with its pump named ``name`` (a TOML basic string)."""
    return TWO_AXIS.replace("[circuit.pump]", f"[circuit.{name}]", 1)


@pytest.mark.parametrize("name, says", [
    ('""', "must not be empty or blank"),                # the reproducer of issue 24
    ('"   "', "must not be empty or blank"),
    ('"pump\\n2"', "does not print, '\\n' at position 5"),
    ('"pump\\u0007"', "does not print"),
    ('"' + "p" * (MAX_NAME_LENGTH + 1) + '"', f"of {MAX_NAME_LENGTH + 1} characters is too long"),
])
def test_a_component_name_that_cannot_be_shown_is_refused(tmp_path, capsys, name, says):
    _refused(capsys, _rig_file(tmp_path, _renamed(name)), "[circuit.", says)


@pytest.mark.parametrize("name", ['"泵"', '"Pumpe-Ölseite"', '"насос"'])
def test_a_printable_name_in_any_script_is_welcome(tmp_path, name):
    circuit = build_circuit(load_rig(_rig_file(tmp_path, _renamed(name))))
    assert name.strip('"') in [c.name for c in circuit.components]


# ---------------------------------------------------------------- no rest state

D, OMEGA, V, BETA, P_SCALE = 1e-6, 2 * math.pi * 25, 1e-3, 1.5e9, 1e7


def _pump_into_a_closed_block():
    """A fixed pump (1 cm^3/rev at 1500 rpm, no leakage) filling a closed 1 L block from the
    tank: the block's pressure rises at beta q / V for ever, at any pressure."""
    tank = comp.PressureSource(name="tank", pressure=5e5, connections={"pressure": "p_tank"})
    pump = comp.Pump(name="pump", displacement=D, shaft_speed=OMEGA,
                     connections={"outlet_pressure": "p_block", "inlet_pressure": "p_tank",
                                  "flow": "q_pump"})
    block = comp.HydraulicVolume(name="block", volume=V, bulk_modulus=BETA, terms={"inflow": 1},
                                 nominal_pressure=P_SCALE,
                                 connections={"inflow": "q_pump", "pressure": "p_block"})
    return Network([tank, pump, block])


def test_a_network_without_a_rest_state_is_refused_in_one_line():
    """dp/dt = beta D omega / (2 pi V) = 3.75e7 Pa/s whatever the pressure: no rest state.
    The solver must say so (one line naming the block's pressure) with the scaled residual
    derived here, 3.75 1/s on the state's scale of 10 MPa -- between the guard (1e-4 1/s) and
    a guard loosened a hundred-million-fold (1e4 1/s), which would pass it as a rest state."""
    with pytest.raises(SteadyStateError) as err:
        solve_steady_state(_pump_into_a_closed_block())
    message = str(err.value)
    assert "\n" not in message and message.startswith("steady state not found")
    assert err.value.state == "block.pressure" and "'block.pressure'" in message
    expected = BETA * D * OMEGA / (2 * math.pi) / V / P_SCALE
    assert expected == pytest.approx(3.75)
    assert err.value.residual == pytest.approx(expected, rel=1e-9)


_NO_REST = '''
[rig]
name = "a servo axis beside a pump that fills a closed block"
modes_per_section = 2
[scenario.open-loop-step]
current = "10 mA"
time = "1 ms"
t_end = "2 ms"
[fluid]
density = "870 kg/m^3"
kinematic_viscosity = "32 cSt"
bulk_modulus = "1.5 GPa"
[circuit.supply]
type = "pressure_source"
pressure = "20.7 MPa"
ports = { pressure = "supply_pressure" }
[circuit.tank]
type = "pressure_source"
pressure = "0.5 MPa"
ports = { pressure = "tank_pressure" }
[circuit.servovalve]
type = "servovalve"
rated_current = "50 mA"
rated_flow = "19 L/min"
rated_pressure_drop = "1000 psi"
max_opening = "0.4 mm"
natural_frequency = "140 Hz"
damping_ratio = 1.0
laps = ["4 um", "4 um", "4 um", "4 um"]
ports = { current = "valve_current", supply_pressure = "supply_pressure", return_pressure = "tank_pressure", bottom_pressure = "bottom_pressure", top_pressure = "top_pressure", supply_flow = "supply_flow", return_flow = "return_flow", bottom_flow = "bottom_flow", top_flow = "top_flow" }
[circuit.actuator]
type = "actuator"
bottom_area = "4.83 cm^2"
top_area = "4.83 cm^2"
bottom_volume = "34.6 cm^3"
top_volume = "34.6 cm^3"
bulk_modulus = "1.4 GPa"
moving_mass = "16 kg"
stroke = "102 mm"
gravity = "0 m/s^2"
ports = { bottom_flow = "bottom_flow", top_flow = "top_flow", friction_force = "friction_force", load_force = "load_force", bottom_pressure = "bottom_pressure", top_pressure = "top_pressure", position = "position", velocity = "velocity" }
[circuit.friction]
type = "friction"
viscous_up = "800 N*s/m"
viscous_down = "800 N*s/m"
ports = { velocity = "velocity", friction_force = "friction_force" }
[circuit.load]
type = "load"
ports = { position = "position", velocity = "velocity", load_force = "load_force" }
[circuit.pump]
type = "pump"
displacement = "1 cm^3"
shaft_speed = "1500 rpm"
ports = { outlet_pressure = "block_pressure", inlet_pressure = "tank_pressure", flow = "pump_flow" }
[circuit.block]
type = "volume"
volume = "1 L"
terms = { pump = 1 }
ports = { pump = "pump_flow", pressure = "block_pressure" }
'''


def test_a_rig_without_a_rest_state_is_refused_in_one_line(tmp_path, capsys):
    """The same pump and block beside a servo axis, run as a user runs a rig: one line, exit
    2, naming the block, no run from a state that is not at rest. The rig's cavity model (on
    by default, M42) puts the block's pressure scale at 100 cavity_pressure_drop = 0.1 MPa:
    the residual is 3.75e7 Pa/s over it, 375 1/s."""
    line = _refused(capsys, _rig_file(tmp_path, _NO_REST), "steady state not found",
                    "'block'", "'block.pressure'", "375 1/s")
    assert "relief valve" in line


@pytest.mark.parametrize("line, suggestion", [
    ('base = "default"', "[rig] base"),
    ('pressure = "3000 psi"', "[return] pressure or [supply] pressure"),
])
def test_a_top_level_key_is_pointed_to_the_tables_that_hold_it(tmp_path, line, suggestion):
    path = _rig_file(tmp_path, line + "\n")
    with pytest.raises(RigError, match=r"did you mean " + suggestion.replace("[", r"\[")
                       .replace("]", r"\]") + r"\?"):
        load_rig(path)
