"""Circuits as data: the paper's rig written as a circuit, the two-axis rig, relief valve and
pump against hand-derived values, bad circuits refused in one line."""
from pathlib import Path

import numpy as np
import pytest

import hydroline
from hydroline import components as comp
from hydroline.analysis import oscillation_frequency
from hydroline.engine import Network
from hydroline.rigs import RigError, load_rig
from hydroline.engine import solve_steady_state
from hydroline.system import build_circuit

DATA = Path(__file__).parent / "data"


def test_paper_rig_written_as_circuit_equals_the_template():
    """The default rig (compact template, rigs.template.expand) and the same rig written component by
    component in tests/data/ayalew2005_circuit.toml give the same run: port pressures and
    piston velocity of the 50 mA step within the solver tolerance (rtol 1e-6: 6e-3 % of the
    excursion, README), here 1e-4 of each trace's excursion."""
    # (rtol throughout: after the stop simulate() goes on 30x looser by default)
    a = hydroline.simulate(None, "open-loop-step", after_stop_rtol=None)
    default, circuit = load_rig(), load_rig(DATA / "ayalew2005_circuit.toml")
    # the calibrated values follow the default rig's (recalibrated now and then)
    for sec in ("supply.section1", "supply.section2", "return.section1", "return.section2"):
        for k in ("length", "diameter", "bulk_modulus"):
            circuit.set(f"circuit.{sec}.{k}", default.raw[f"{sec}.{k}"])
    for side in ("supply", "return"):
        circuit.set(f"circuit.{side}.manifold.resistance", default.raw[f"{side}.manifold.resistance"])
    circuit.set("circuit.supply.pump.pressure", default.raw["supply.pressure"])
    circuit.set("circuit.return.tank.pressure", default.raw["return.pressure"])
    circuit.set("circuit.actuator.moving_mass", default.raw["actuator.moving_mass"])
    circuit.set("circuit.actuator.bulk_modulus", default.raw["actuator.bulk_modulus"])
    b = hydroline.simulate(circuit, "open-loop-step", after_stop_rtol=None)
    assert sorted(a.metadata["axes"]) == sorted(b.metadata["axes"]) == ["actuator"]
    for k in ("supply_port_pressure", "return_port_pressure", "piston_velocity"):
        span = np.ptp(a[k])
        assert np.max(np.abs(a[k] - b[k])) < 1e-4 * span, k
    assert hydroline.summarize(b)["supply"]["frequency_hz"] == pytest.approx(
        hydroline.summarize(a)["supply"]["frequency_hz"], rel=1e-4)


@pytest.fixture(scope="module")
def two_axis_runs():
    shared = hydroline.simulate("two_axis")
    rig = load_rig("two_axis")
    for n in ("axis1", "axis2"):   # ideal supply: each valve straight on the pump and tank
        rig.set(f"connections.{n}.servovalve.supply_pressure", "pump_pressure")
        rig.set(f"connections.{n}.servovalve.return_pressure", "tank_pressure")
    return shared, hydroline.simulate(rig)


def test_two_axis_disturbance_at_supply_line_frequency(two_axis_runs):
    """Axis 1 steps 40 mm; axis 2, held by its P loop, is shaken through the shared manifold
    at the frequency its supply port rings with: the supply hose's quarter wave c/(4L)
    between the accumulator-held manifold (pressure node) and the valve (closed end), with
    c = sqrt(194.5 MPa/870 kg/m^3) = 473 m/s and L = 3.048 m -> 38.8 Hz;
    and with an ideal pressure source at each valve the disturbance all but vanishes."""
    res, ideal = two_axis_runs
    s = hydroline.summarize(res)
    ax2 = s["axes"]["axis2"]
    assert s["axes"]["axis1"]["position_change_mm"] == pytest.approx(40, abs=1)
    t0, t1 = s["metrics_window_s"]
    m = res.t <= t1
    f_x = oscillation_frequency(res.t[m], res["axis2.piston_velocity"][m], t0)
    f_p = ax2["supply"]["frequency_hz"]
    c = np.sqrt(194.5e6 / 870)
    assert f_p == pytest.approx(c / (4 * 3.048), rel=0.1)
    assert f_x == pytest.approx(f_p, rel=0.1)
    d_ideal = hydroline.summarize(ideal)["axes"]["axis2"]["position_disturbance_mm"]
    assert ax2["position_disturbance_mm"] > 0
    assert d_ideal < 0.1 * ax2["position_disturbance_mm"]


def test_two_axis_cli_json_schema(capsys, tmp_path):
    from hydroline.cli import main
    import json
    assert main(["simulate", "two_axis", "--json", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert {"schema_version", "axes", "wall_time_s", "metrics_window_s", "warnings",
            "settling_band"} <= set(doc)
    assert set(doc["axes"]) == {"axis1", "axis2"}
    for a in doc["axes"].values():
        assert {"frequency_hz", "amplitude_mpa", "settling_time_s", "first_excursion_mpa",
                "settling_note", "settling_band_mpa"} <= set(a["supply"])
        assert "position_disturbance_mm" in a
    from test_json_summary import validate_summary   # the documented schema (docs/)
    validate_summary(doc)
    assert isinstance(doc["axes"]["axis2"]["position_disturbance_mm"], float)


def _pump_node(pump, relief, load_resistance):
    """Pump -> 50 cm^3 node (relief valve to tank, a load orifice to tank) -> tank at 0.1 MPa."""
    tank = comp.PressureSource(name="tank", pressure=1e5, connections={"pressure": "p_tank"})
    parts = [tank, pump, relief,
             comp.LinearResistance(name="orifice", compute="flow", resistance=load_resistance,
                                   connections={"inlet_pressure": "p", "outlet_pressure": "p_tank",
                                                "flow": "q_load"}),
             comp.HydraulicVolume(name="node", volume=50e-6, bulk_modulus=1.5e9, nominal_pressure=1e7,
                                  terms={"pump": 1, "relief": -1, "load": -1},
                                  connections={"pump": "q_pump", "relief": "q_relief",
                                               "load": "q_load", "pressure": "p"})]
    pump.connections = {"outlet_pressure": "p", "inlet_pressure": "p_tank", "flow": "q_pump"}
    relief.connections = {"inlet_pressure": "p", "outlet_pressure": "p_tank", "flow": "q_relief"}
    net = Network(parts)
    return net, net.signals_at(0.0, solve_steady_state(net).x)


def test_relief_valve_cracking_and_slope():
    """q = G (dp - p_c)+: nothing a few p_w below cracking, G p_w ln 2 at cracking, exactly
    G (dp - p_c) a few p_w above (slope G)."""
    rv = comp.ReliefValve(name="rv", cracking_pressure=21e6, flow_gradient=2e-11,
                          transition_pressure=1e4)
    assert rv.flow(21e6 - 2e5) == pytest.approx(0.0, abs=2e-11 * 1e4 * 1e-8)
    assert rv.flow(21e6) == pytest.approx(2e-11 * 1e4 * np.log(2), rel=1e-12)
    assert rv.flow(22e6) == pytest.approx(2e-11 * 1e6, rel=1e-12)
    assert (rv.flow(22.5e6) - rv.flow(22e6)) / 0.5e6 == pytest.approx(2e-11, rel=1e-12)


def test_fixed_pump_with_relief_settles_on_the_override_line():
    """Fixed pump D n = 10 cm^3 x 1500 rpm = 250 cm^3/s into a node with a 1e11 Pa s/m^3 load
    orifice (10 cm^3/s per MPa: 210 cm^3/s at 21 MPa) and a relief valve cracking at
    21 MPa with G = 2e-11 m^3/s/Pa: the balance D n = p/R + G (p - p_c) (gauge, tank 0.1 MPa)
    gives p - p_t = (D n + G p_c) / (1/R + G)."""
    Dn, R, G, pc = 10e-6 * 25, 1e11, 2e-11, 21e6
    net, sig = _pump_node(comp.Pump(name="pump", displacement=10e-6, shaft_speed=2 * np.pi * 25.0),
                          comp.ReliefValve(name="rv", cracking_pressure=pc, flow_gradient=G), R)
    p_hand = (Dn + G * pc) / (1 / R + G) + 1e5
    assert sig["p"] == pytest.approx(p_hand, rel=1e-6)
    assert sig["q_pump"] == pytest.approx(Dn, rel=1e-9)
    assert sig["q_relief"] + sig["q_load"] == pytest.approx(Dn, rel=1e-6)


def test_pressure_compensated_pump_destrokes_between_settings():
    """Compensator 20 MPa, dead head 21 MPa, no relief flow (cracks at 30 MPa): on a load
    orifice R the node settles where q_max (p_d - p)/(p_d - p_c) = p/R (gauge), i.e.
    p = p_d / (1 + (p_d - p_c)/(R q_max)); and q = q_max below p_c."""
    qmax, pc, pd, R = 250e-6, 20e6, 21e6, 1e11
    pump = comp.Pump(name="pump", displacement=10e-6, shaft_speed=2 * np.pi * 25.0,
                     control="pressure-compensated", compensator_pressure=pc, deadhead_pressure=pd)
    net, sig = _pump_node(pump, comp.ReliefValve(name="rv", cracking_pressure=30e6), R)
    p_hand = pd / (1 + (pd - pc) / (R * qmax))
    assert sig["p"] - 1e5 == pytest.approx(p_hand, rel=1e-6)
    assert pump.flow(10e6) == pytest.approx(qmax, rel=1e-12)
    assert pump.flow(20.5e6) == pytest.approx(qmax / 2, rel=1e-12)


def _circuit_file(tmp_path, body):
    text = (DATA / "ayalew2005_circuit.toml").read_text() + "\n" + body
    path = tmp_path / "bad.toml"
    path.write_text(text)
    return path


def _one_line_error(tmp_path, capsys, text, replace=None):
    from hydroline.cli import main
    base = (DATA / "ayalew2005_circuit.toml").read_text()
    if replace:
        assert replace[0] in base
        base = base.replace(*replace)
    path = tmp_path / "bad.toml"
    path.write_text(base + "\n" + text)
    assert main(["simulate", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    return err


@pytest.mark.parametrize("extra, replace, needles", [
    # an unconnected port: the valve's current left out of its ports
    ("", ('ports = { current = "valve_current", ', 'ports = { '), ("servovalve", "current", "not connected")),
    # two outputs on one signal: a second pump onto pump_pressure
    ('[circuit.pump2]\ntype = "pressure_source"\npressure = "20 MPa"\nports = { pressure = "pump_pressure" }\n',
     None, ("pump_pressure", "two outputs", "pump2.pressure")),
    # causality clash: a flow port on a pressure signal
    ("", ('downstream_flow = "supply.manifold_flow"', 'downstream_flow = "pump_pressure"'),
     ("causality", "supply.section1.downstream_flow")),
    # algebraic loop: r1 needs r2's flow, r2 needs r1's outlet pressure (both feed through)
    ('[circuit.r1]\ntype = "resistance"\nresistance = "1e9 Pa*s/m^3"\ncompute = "outlet"\n'
     'ports = { inlet_pressure = "x_b", flow = "x_q", outlet_pressure = "x_a" }\n'
     '[circuit.r2]\ntype = "resistance"\nresistance = "1e9 Pa*s/m^3"\ncompute = "flow"\n'
     'ports = { inlet_pressure = "x_a", outlet_pressure = "tank_pressure", flow = "x_q" }\n'
     '[circuit.r3]\ntype = "resistance"\nresistance = "1e9 Pa*s/m^3"\ncompute = "inlet"\n'
     'ports = { outlet_pressure = "x_a", flow = "x_q", inlet_pressure = "x_b" }\n',
     None, ("algebraic loop", "r1.flow reads 'x_q' from r2.flow")),
    # unknown component type
    ('[circuit.gizmo]\ntype = "flux_capacitor"\n', None, ("gizmo", "unknown component type")),
    # a parameter without its unit
    ("", ('rated_current = "50 mA"', "rated_current = 0.05"), ("servovalve.rated_current",)),
    # a value outside its declared bounds, echoed as written
    ("", ('rated_current = "50 mA"', 'rated_current = "-50 mA"'),
     ("circuit.servovalve.rated_current", "must be > 0 [A]", "-50 mA")),
    # a port the type does not have
    ("", ('ports = { current = "valve_current", ', 'ports = { current = "valve_current", coil = "x", '),
     ("servovalve", "no port 'coil'")),
])
def test_bad_circuit_refused_in_one_line(tmp_path, capsys, extra, replace, needles):
    err = _one_line_error(tmp_path, capsys, extra, replace)
    for n in needles:
        assert n in err, (n, err)


def test_circuit_handles_of_the_template_and_two_axis():
    """The template's axis handles are today's signal names; the two-axis rig has two axes,
    each with its own controller."""
    ax = build_circuit(load_rig()).axes["actuator"]
    assert (ax.current, ax.supply_pressure, ax.return_pressure, ax.position) == (
        "valve_current", "supply_port_pressure", "return_port_pressure", "piston_position")
    axes = build_circuit(load_rig("two_axis")).axes
    assert list(axes) == ["axis1", "axis2"]
    assert axes["axis2"].controller == "axis2.controller"
    assert axes["axis2"].supply_pressure == "axis2.supply_port_pressure"


def test_component_parameters_declared_once():
    """Units and bounds come from the declaration: the rig schema and the message agree."""
    from hydroline.rigs import SCHEMA
    decl = comp.Servovalve.parameters()["rated_current"]
    assert decl.unit == SCHEMA["servovalve"]["rated_current"] == "A" and decl.default == 0.05
    with pytest.raises(ValueError, match=r"v: rated_current must be > 0 \[A\]"):
        comp.Servovalve(name="v", rated_current=-1.0)
    rig = load_rig()
    rig.set("servovalve.rated_current", "-5 mA")
    with pytest.raises(RigError, match=r"servovalve.rated_current: must be > 0 \[A\]"):
        hydroline.simulate(rig)


def test_circuit_command_prints_and_draws(tmp_path, capsys):
    """`hydroline circuit two_axis` lists every component with its causality, every signal with
    the port that outputs it and those reading it, the axes; --png writes the graph."""
    from hydroline.cli import main
    png = tmp_path / "c.png"
    assert main(["circuit", "two_axis", "--png", str(png)]) == 0
    out = capsys.readouterr().out
    assert "axis2.servovalve  (servovalve" in out
    assert "current <- axis2.valve_current" in out
    assert ("supply.manifold_pressure [Pa]: supply.manifold.outlet_pressure -> "
            "supply.accumulator.pressure, axis1.supply_hose.upstream_pressure, "
            "axis2.supply_hose.upstream_pressure") in out
    assert png.stat().st_size > 10_000


def test_two_axis_fluid_volume_conserved_with_blocked_valves():
    """Mass (docs/model.md 2-3) through a transient of the shared supply: both valves blocked
    (zero laps, zero current: every opening sg(0) = 0, M20), the circuit starts at 20.7 MPa
    and the pump drops to 15 MPa. The oil the pump line delivers, int q_pump dt, equals what
    the supply hoses and the accumulator give up:
        sum_h C_h (p_f - p_0) - (V_g(end) - V_g(0))      (M16: oil side = V_0 - V_g)
    with C_h each hose's compliance in the model, -C A^-2 B of its (upstream pressure ->
    upstream flow) channel, the blocked line's low-frequency admittance s C_h; it lies within
    3 % of the distributed A L / beta_e (the modal truncation and corrections, M13-M15)."""
    from hydroline.engine import integrate
    rig = load_rig("two_axis")
    # the Yang-Tobler line, whose steady state is exact by construction (M13): the balance
    # below holds to 1e-4 with it; the exact-pole line's stored oil differs from its
    # -C A^-2 B by 6e-4 here (not understood yet; its dynamics are checked against the
    # characteristics line in tests/test_default_line.py)
    rig.set("rig.line_method", "yang-tobler")
    for n in ("axis1", "axis2"):
        rig.set(f"circuit.{n}.servovalve.laps", ["0 um"] * 4)
        rig.set(f"circuit.{n}.controller.proportional_gain", "0 A/m")
    circ = build_circuit(rig)
    refs = [comp.StepCommand(name=f"{n}.reference", quantity="position",
                             connections={"command": f"{n}.position_reference"}) for n in circ.axes]
    net = circ.network(refs)
    p = net.parameter_values.copy()
    p[net.parameter_names.index("pump.pressure")] = 15e6
    res = integrate(net, net.guess(), 2.0, dt_out=1e-4, p=p)
    delivered = np.trapezoid(res["pump_flow"], res.t)

    def compliance(m):
        i, j = m.input_names.index("upstream_pressure"), m.output_names.index("upstream_flow")
        Ai = np.linalg.inv(m.A)
        return float(-(m.C @ Ai @ Ai @ m.B)[j, i])

    hoses = [circ.component(n).model for n in ("supply.section1", "axis1.supply_hose", "axis2.supply_hose")]
    for m in hoses:
        assert compliance(m) == pytest.approx(m.line.capacitance, rel=0.03)
    gas = res["supply.accumulator.gas_volume"]
    stored = sum(compliance(m) for m in hoses) * (15e6 - 20.7e6) - (gas[-1] - gas[0])
    assert abs(stored) > 1e-4                                   # > 100 cm^3 moved
    assert delivered == pytest.approx(stored, rel=1e-4)
    assert res["axis2.supply_port_pressure"][-1] == pytest.approx(15e6, rel=1e-6)
    for n in ("axis1", "axis2"):                                # blocked: nothing reaches the pistons
        for q in ("supply_port_flow", "return_port_flow", "bottom_chamber_flow", "top_chamber_flow"):
            assert np.all(res[f"{n}.{q}"] == 0.0)


def test_pump_and_relief_valve_from_a_circuit_file(tmp_path):
    """The same fixed pump / relief / orifice node as above, written as a circuit file (types
    pump, relief_valve, volume, resistance, pressure_source; units as a user writes them):
    the node settles at (D n + G p_c)/(1/R + G) above the tank."""
    path = tmp_path / "pump.toml"
    path.write_text('''
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
''')
    circ = build_circuit(load_rig(path))
    assert circ.axes == {}
    net = circ.network()
    sig = net.signals_at(0.0, solve_steady_state(net).x)
    Dn, G, pc, R = 10e-6 * 25, 1.2e-3 / 60 / 1e5, 21e6, 1e11
    assert sig["p"] - 1e5 == pytest.approx((Dn + G * pc) / (1 / R + G), rel=1e-6)


def test_experiments_on_two_axes_drive_one_and_hold_the_others():
    """Scenarios take the axes from the handles: on the two-axis rig the closed-loop sine
    drives axis 1's reference and holds axis 2's where it starts (its own P loop, no second
    controller added); an open-loop current step onto a controlled axis is refused."""
    from hydroline.scenarios import build_scenario
    rig = load_rig("two_axis")
    sc = build_scenario(rig, "closed-loop-sine")
    wired = {c.signal("command"): c for c in sc.commands}
    assert set(wired) == {"axis1.position_reference", "axis2.position_reference"}
    assert isinstance(wired["axis1.position_reference"], comp.SineCommand)
    hold = wired["axis2.position_reference"]
    assert hold.initial == hold.final == 0.0          # axis 2 starts at 0 mm (two_axis.toml)
    step = build_scenario(rig, "position-step")
    assert {c.signal("command"): c.final - c.initial for c in step.commands} == pytest.approx(
        {"axis1.position_reference": 0.040, "axis2.position_reference": 0.0})
    with pytest.raises(RigError, match="axis1.controller.*position-step"):
        build_scenario(rig, "open-loop-step")


def test_parameter_reference_derives_from_declarations(capsys):
    """`hydroline circuit --types` (the docs' reference) lists every type and every declared
    parameter with the declaration's unit and bounds."""
    from hydroline.circuit import COMPONENT_TYPES
    from hydroline.cli import main
    assert main(["circuit", "--types"]) == 0
    out = capsys.readouterr().out
    for name, t in COMPONENT_TYPES.items():
        assert f"### `{name}`" in out
        for key in t.declarations():
            assert f"| `{key}` |" in out
    assert "| `rated_current` | A | > 0 | 0.0001 ... 5 | 0.05 |" in out
    assert "| `polytropic_exponent` | - | within [1, 1.66667] | 1 ... 1.66667 | 1.4 |" in out
