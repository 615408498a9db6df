"""The assembled test system: steady state, conservation, natural frequency, the paper's baseline."""
import json

import numpy as np
import pytest
from scipy.optimize import brentq

import hydroline
from hydroline import components as comp
from hydroline.cli import main
from hydroline.lines import Line, ModalLine
from hydroline.fluid import MINERAL_OIL
from hydroline.network import Network
from hydroline.rigs import load_rig
from hydroline.scenarios import build_scenario, simulate, summarize
from hydroline.simulation import integrate, solve_steady_state
from hydroline.system import build_network, hose_lines


@pytest.fixture(scope="module")
def default_run():
    return simulate()


def test_steady_state_pressure_drops_along_supply_and_return():
    # a wide underlap makes a large steady supply-to-return flow through the valve
    rig = load_rig()
    rig.set("servovalve.laps", ["0.1 mm"] * 4)
    sc = build_scenario(rig)
    net = build_network(rig, sc.commands)
    ss = solve_steady_state(net)
    assert ss.residual < 1e-8
    s = net.signals_at(0.0, ss.x, ss.p)
    q = s["supply_port_flow"]
    assert q > 1e-4                                          # a real flow, [m^3/s]
    lines = hose_lines(rig)
    # laminar hoses (M12) and the HSM resistance (M1) in series
    R_supply = lines["supply.section1"].resistance + rig["supply.manifold.resistance"] \
        + lines["supply.section2"].resistance
    assert s["pump_pressure"] - s["supply_port_pressure"] == pytest.approx(R_supply * q, rel=1e-6)
    qr = s["return_port_flow"]
    assert qr == pytest.approx(q, rel=1e-9)                  # blocked actuator: all flow returns
    R_return = lines["return.section1"].resistance + rig["return.manifold.resistance"] \
        + lines["return.section2"].resistance
    assert s["return_port_pressure"] - s["tank_pressure"] == pytest.approx(R_return * qr, rel=1e-6)
    # accumulators carry no steady flow
    assert abs(s["supply.accumulator_flow"]) < 1e-12 and abs(s["return.accumulator_flow"]) < 1e-12


def test_fluid_volume_conserved_in_closed_network():
    """QQ hose blocked at the valve end + accumulator: the oil the gas pushes out is stored in
    the hose's compliance. Final common pressure p_f solves, by hand,
    C (p_f - p_i) = V_g(p_f) - V_g0,  V_g(p) = V_g0 (p_g0/p)^(1/m)   (M16)."""
    line = Line(3.0, 0.0159, MINERAL_OIL, 2e8)
    hose = comp.HoseSection(name="hose", model=ModalLine(line, 4, "QQ"), nominal_pressure=10e6,
                            connections={"upstream_flow": "hose_inflow", "downstream_flow": "valve_flow",
                                         "upstream_pressure": "node_pressure",
                                         "downstream_pressure": "valve_port_pressure"})
    blocked = comp.StepCommand(name="valve", quantity="flow", initial=0.0, final=0.0, time=1.0,
                               connections={"command": "valve_flow"})
    acc = comp.PistonAccumulator(name="acc", capacity=1e-3, precharge_pressure=5e6, polytropic_exponent=1.4,
                                 resistance=2e9, inertance=3e5, nominal_pressure=15e6,
                                 connections={"pressure": "node_pressure", "flow": "acc_flow"})
    node = comp.FlowJunction(name="node", terms={"acc": -1},
                             connections={"acc": "acc_flow", "flow": "hose_inflow"})
    net = Network([hose, blocked, acc, node])
    # start: hose at rest at 10 MPa, gas charged to 15 MPa (out of equilibrium)
    p_i, p_g0 = 10e6, 15e6
    x0 = np.zeros(len(net.state_names))
    x0[net.state_names.index("hose.column.volume")] = line.capacitance * p_i
    Vg0 = 1e-3 * 5e6 / p_g0
    x0[net.state_names.index("acc.gas_volume")] = Vg0
    p = net.parameter_values.copy()
    p[net.parameter_names.index("acc.reference_pressure")] = p_g0
    res = integrate(net, x0, 3.0, dt_out=1e-3, p=p)
    C = line.capacitance
    p_f = brentq(lambda pf: C * (pf - p_i) - (Vg0 * (p_g0 / pf) ** (1 / 1.4) - Vg0), p_i, p_g0)
    assert res["node_pressure"][-1] == pytest.approx(p_f, rel=1e-5)
    assert res["valve_port_pressure"][-1] == pytest.approx(p_f, rel=1e-5)
    # and at every instant: hose storage + accumulator oil = const (to the integrator's tolerance)
    stored = res["hose.column.volume"] + (1e-3 - res["acc.gas_volume"])
    assert np.ptp(stored) < 1e-6 * stored[0]


def test_linearised_natural_frequency_with_ideal_supply():
    """w_h^2 = beta_c (A_b^2/V_b + A_t^2/V_t)/m (MODEL.md 4), from the Jacobian's eigenvalues."""
    rig = load_rig()
    rig.set("actuator.gravity", "0 m/s^2")
    for k in ("viscous_up", "viscous_down"):
        rig.set(f"friction.{k}", "0 N*s/m")
    act = hydroline.system.make_actuator(rig, position_guess=0.0)
    parts = [
        comp.PressureSource(name="supply", pressure=20.7e6, connections={"pressure": "supply_port_pressure"}),
        comp.PressureSource(name="tank", pressure=1e6, connections={"pressure": "return_port_pressure"}),
        comp.Servovalve(name="servovalve", rated_current=0.05, rated_flow=19e-3 / 60,
                        rated_pressure_drop=6.895e6, max_opening=4e-4, laps=(0.0,) * 4,
                        connections={"current": "valve_current", "supply_pressure": "supply_port_pressure",
                                     "return_pressure": "return_port_pressure",
                                     "bottom_pressure": "bottom_chamber_pressure",
                                     "top_pressure": "top_chamber_pressure",
                                     "supply_flow": "supply_port_flow", "return_flow": "return_port_flow",
                                     "bottom_flow": "bottom_chamber_flow", "top_flow": "top_chamber_flow"}),
        act,
        comp.StepCommand(name="command", initial=0.0, final=0.0, time=1.0,
                         connections={"command": "valve_current"}),
        comp.StepCommand(name="no_friction", quantity="force", connections={"command": "friction_force"}),
        comp.StepCommand(name="no_load", quantity="force", connections={"command": "load_force"}),
    ]
    net = Network(parts)
    x = net.guess()
    model = net.compile()
    J = model.jacobian(0.0, x, net.parameter_values)
    lam = np.linalg.eigvals(J)
    w_h = 2 * np.pi * act.hydraulic_natural_frequency(0.0)
    osc = lam[np.abs(lam.imag) > 1.0]
    w_model = np.abs(osc)[np.argmin(np.abs(np.abs(osc) - w_h))]
    A, V = act.bottom_area, act.bottom_volume
    w_hand = np.sqrt(act.bulk_modulus * 2 * A**2 / V / act.moving_mass)
    assert w_h == pytest.approx(w_hand, rel=1e-12)
    assert w_model == pytest.approx(w_hand, rel=0.02)
    assert act.hydraulic_natural_frequency(0.0) == pytest.approx(172.0, rel=0.01)   # [paper]


def test_default_scenario_reproduces_paper_baseline(default_run):
    """MODEL.md 7: supply ~40 Hz / 1.0 MPa, return ~31 Hz / 0.94 MPa after the 50 mA step."""
    s = summarize(default_run)
    assert s["supply"]["frequency_hz"] == pytest.approx(40.0, rel=0.10)
    assert s["return"]["frequency_hz"] == pytest.approx(31.0, rel=0.10)
    assert s["supply"]["amplitude_mpa"] == pytest.approx(1.0, rel=0.20)
    assert s["return"]["amplitude_mpa"] == pytest.approx(0.94, rel=0.20)
    assert default_run.steady_state.residual < 1e-8
    assert not s["warnings"]


def test_result_has_every_signal_and_state(default_run, tmp_path):
    d = default_run.data
    assert "supply.section2.mode3.flow" in d and "supply_port_pressure" in d
    assert np.all(np.isfinite(d.to_numpy()))
    default_run.to_csv(tmp_path / "r.csv")
    assert (tmp_path / "r.csv").read_text().startswith("time,")
    # starts at rest: the solved steady state has nothing moving before the step
    before = default_run.t < 0.01
    assert np.ptp(default_run["supply_port_pressure"][before]) < 1.0      # [Pa]


def test_closed_loop_sine_tracks():
    res = simulate(scenario="closed-loop-sine", t_end=0.6)
    s = summarize(res)
    assert 0 < s["tracking_error_rms_mm"] < 35.0 * 0.5
    assert np.max(np.abs(res["piston_position"])) < 0.051


def test_cli_json_summary(capsys, tmp_path):
    rc = main(["simulate", "--json", "--t-end", "0.12 s", "--out", str(tmp_path)])
    assert rc == 0
    s = json.loads(capsys.readouterr().out)
    # exactly the schema, nothing else
    assert set(s) == {"supply", "return", "actuator_natural_frequency_hz", "wall_time_s"}
    for side in ("supply", "return"):
        assert set(s[side]) == {"frequency_hz", "amplitude_mpa", "settling_time_s"}
        assert s[side]["frequency_hz"] is None or isinstance(s[side]["frequency_hz"], float)
        assert isinstance(s[side]["amplitude_mpa"], float)
        assert s[side]["settling_time_s"] is None or isinstance(s[side]["settling_time_s"], float)
    assert isinstance(s["actuator_natural_frequency_hz"], float)
    assert isinstance(s["wall_time_s"], float)
    # the metrics themselves: the paper's baseline (MODEL.md 7), 172 Hz from w_h (M22-M23)
    assert s["supply"]["frequency_hz"] == pytest.approx(40.0, rel=0.10)
    assert s["actuator_natural_frequency_hz"] == pytest.approx(172.0, rel=0.01)
    # summary.json may carry more (metrics window, warnings)
    assert "metrics_window_s" in json.loads((tmp_path / "summary.json").read_text())
    for f in ("results.csv", "summary.json", "pressures.png"):
        assert (tmp_path / f).stat().st_size > 0


@pytest.mark.parametrize("body, needle", [
    ('[rig]\nbase = "default"\n[supply.section2]\nlength = "-1 m"\n', "supply.section2.length"),
    ('[rig]\nbase = "default"\n[supply.section2]\nlength = 3.048\n', "bare number"),
    ('[rig]\nbase = "default"\n[turbocharger]\nboost = "1 bar"\n', "unknown component"),
    ('[rig]\nbase = "default"\n[connections]\n"servovalve.supply_pressure" = "nowhere"\n', "unconnected"),
    ('[rig]\nbase = "default"\n[connections]\n"pump.outlet" = "x"\n', "unknown component"),
    # values that used to reach the solver (SteadyStateError, ZeroDivisionError): refused by name
    ('[rig]\nbase = "default"\n[supply]\npressure = "-1 MPa"\n', "supply.pressure: must be above return.pressure"),
    ('[rig]\nbase = "default"\n[supply]\npressure = "0 MPa"\n', "supply.pressure: must be above return.pressure"),
    ('[rig]\nbase = "default"\n[supply]\npressure = "0.5 MPa"\n', "supply.pressure: must be above return.pressure"),
    ('[rig]\nbase = "default"\n[return]\npressure = "0 MPa"\n', "return.pressure: must be > 0 [Pa, absolute]"),
    ('[rig]\nbase = "default"\n[return]\npressure = "-0.1 MPa"\n', "return.pressure: must be > 0 [Pa, absolute]"),
    ('[rig]\nbase = "default"\n[actuator]\ninitial_position = "-80 mm"\n', "actuator.initial_position: must lie within +-stroke/2 = +-51 mm"),
    ('[rig]\nbase = "default"\n[actuator]\nmoving_mass = "-1 kg"\n', "actuator.moving_mass: must be > 0 [kg]"),
    ('[rig]\nbase = "default"\n[supply.accumulator]\nprecharge_pressure = "0 MPa"\n', "supply.accumulator.precharge_pressure"),
    ('[rig]\nbase = "default"\n[return.accumulator]\nprecharge_pressure = "1.5 MPa"\n', "return.accumulator.precharge_pressure: must be below return.pressure"),
    ('[rig]\nbase = "default"\n[supply.pressure_profile]\ntype = "sine"\namplitude = "20 MPa"\nfrequency = "5 Hz"\n', "supply.pressure_profile: the supply pressure must stay above"),
    ('[rig]\nbase = "default"\n[supply.pressure_profile]\ntype = "step"\nfinal = "18 MPa"\n', "supply.pressure_profile.time: required"),
    ('[rig]\nbase = "default"\n[supply.pressure_profile]\ntype = "table"\nfile = "nowhere.csv"\n', "supply.pressure_profile.file"),
    ('[rig]\nbase = "default"\n[servovalve]\nlaps = ["1 mm", "0 mm", "0 mm", "0 mm"]\n', "servovalve.laps"),
])
def test_bad_rig_files_exit_2_with_one_line(tmp_path, capsys, body, needle):
    f = tmp_path / "bad.toml"
    f.write_text(body)
    rc = main(["simulate", str(f), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1 and needle in err and "Traceback" not in err


def test_rig_connection_override_gives_ideal_supply():
    rig = load_rig()
    rig.set("connections.servovalve.supply_pressure", "pump_pressure")
    res = simulate(rig, t_end=0.05)
    assert np.allclose(res["pump_pressure"], rig["supply.pressure"])


def test_sampled_controller_matches_continuous_at_fast_sampling():
    # a 0.5 ms zero-order hold is far faster than the 2 Hz command: tracking nearly unchanged
    cont = summarize(simulate(scenario="closed-loop-sine", t_end=0.1))
    rig = load_rig()
    rig.set("controller.sample_time", "0.5 ms")
    samp = summarize(simulate(rig, "closed-loop-sine", t_end=0.1))
    assert samp["tracking_error_rms_mm"] == pytest.approx(cont["tracking_error_rms_mm"], rel=0.05)


def test_modal_accumulator_connection_option():
    rig = load_rig()
    rig.set("supply.accumulator.model", "modal")
    res = simulate(rig, t_end=0.03)
    assert any(n.startswith("supply.accumulator.line.mode") for n in res.data.columns)
    assert np.all(np.isfinite(res["supply_port_pressure"]))


def test_supply_pressure_table_from_rig_file(tmp_path):
    """[supply.pressure_profile] type = "table": the HPS pressure drops 2 MPa (207 -> 187 bar)
    between 20 and 30 ms with the valve at null. By hand: the pump pressure at 25 ms is
    19.7 MPa; the HSM node follows the 2.0 MPa drop (the null leakage, ~1e-5 m^3/s through
    ~1.3e9 Pa s/m^3, changes its loss by < 1 kPa); the supply accumulator's gas expands
    adiabatically, V_f/V_i = (p_i/p_f)^(1/1.4) (M16)."""
    (tmp_path / "p_hps.csv").write_text("time [ms],pressure [bar]\n0,207\n20,207\n30,187\n")
    f = tmp_path / "rig.toml"
    f.write_text('[rig]\nbase = "default"\n[supply.pressure_profile]\ntype = "table"\n'
                 'file = "p_hps.csv"\n[scenario.open-loop-step]\ncurrent = "0 mA"\n')
    res = simulate(load_rig(f), t_end=0.2)
    if hydroline.compiled.available():
        assert res.metadata["solver"] == "compiled"         # the table compiles (sum of ramps)
    t = res.t
    assert np.interp(0.025, t, res["pump_pressure"]) == pytest.approx(19.7e6, rel=1e-9)
    assert res["pump_pressure"][-1] == pytest.approx(18.7e6, rel=1e-12)
    p_i, p_f = res["supply.manifold_pressure"][[0, -1]]
    assert p_f - p_i == pytest.approx(-2.0e6, abs=5e3)
    V_i, V_f = res["supply.accumulator.gas_volume"][[0, -1]]
    assert V_f / V_i == pytest.approx((p_i / p_f) ** (1 / 1.4), rel=1e-4)
