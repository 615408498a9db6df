"""The assembled test system: steady state, conservation, natural frequency, the paper's baseline."""
import json

import numpy as np
import pytest
from scipy.optimize import brentq

import hydroline
from hydroline import components as comp
from hydroline.cli import main
from hydroline.lines import Line
from hydroline.fluid import MINERAL_OIL
from hydroline.engine import Network
from hydroline.rigs import load_rig
from hydroline.scenarios import build_scenario, simulate, summarize
from hydroline.engine import integrate, solve_steady_state
from hydroline.system import build_circuit, build_network, hose_lines
from pathlib import Path


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


def _closed_network(laps):
    """Two hoses, an accumulator, two manifold nodes and a real servovalve at null, sealed.

    V1 (accumulator) -> supply hose (PQ) -> valve P port;  valve T port -> return hose (PQ,
    oriented from V2 toward the valve, so its downstream flow is minus the valve's return
    flow) -> V2 -> resistance -> V1. Valve control ports end in closed chamber volumes.
    Lumped R-I-C hoses: their stored volume is a function of their states, (C/N) sum p_k."""
    from hydroline.lines.lumped import LumpedLine

    beta = MINERAL_OIL.bulk_modulus
    l1 = Line(3.0, 0.0159, MINERAL_OIL, 2e8)
    l2 = Line(2.0, 0.0159, MINERAL_OIL, 1.5e8)
    vol = lambda name, V, terms, p, conn: comp.HydraulicVolume(  # noqa: E731
        name=name, volume=V, bulk_modulus=beta, terms=terms, nominal_pressure=p, connections=conn)
    parts = [
        comp.StepCommand(name="command", connections={"command": "valve_current"}),   # null
        comp.Servovalve(name="valve", rated_current=0.05, rated_flow=19e-3 / 60,
                        rated_pressure_drop=6.895e6, max_opening=4e-4, laps=laps,
                        connections={"current": "valve_current", "supply_pressure": "pS",
                                     "return_pressure": "pR", "bottom_pressure": "pb",
                                     "top_pressure": "pt", "supply_flow": "qS",
                                     "return_flow": "qR", "bottom_flow": "qb", "top_flow": "qt"}),
        comp.HoseSection(name="supply", model=LumpedLine(l1, 8), nominal_pressure=10e6, connections={
            "upstream_pressure": "p1", "downstream_flow": "qS", "downstream_pressure": "pS",
            "upstream_flow": "q1"}),
        comp.FlowJunction(name="flip", terms={"r": -1}, connections={"r": "qR", "flow": "q_to_T"}),
        comp.HoseSection(name="return", model=LumpedLine(l2, 8), nominal_pressure=5e6, connections={
            "upstream_pressure": "p2", "downstream_flow": "q_to_T", "downstream_pressure": "pR",
            "upstream_flow": "q2"}),
        comp.LinearResistance(name="R", compute="flow", resistance=2e9,
                              connections={"inlet_pressure": "p2", "outlet_pressure": "p1",
                                           "flow": "q21"}),
        comp.PistonAccumulator(name="acc", capacity=1e-3, precharge_pressure=5e6,
                               polytropic_exponent=1.4, resistance=2e9, inertance=3e5,
                               nominal_pressure=15e6, connections={"pressure": "p1", "flow": "qa"}),
        vol("V1", 50e-6, {"r": 1, "line": -1, "acc": -1}, 12e6,
            {"r": "q21", "line": "q1", "acc": "qa", "pressure": "p1"}),
        vol("V2", 30e-6, {"line": -1, "r": -1}, 5e6, {"line": "q2", "r": "q21", "pressure": "p2"}),
        vol("Vb", 20e-6, {"valve": 1}, 8e6, {"valve": "qb", "pressure": "pb"}),
        vol("Vt", 25e-6, {"valve": -1}, 11e6, {"valve": "qt", "pressure": "pt"}),
    ]
    return Network(parts), l1, l2, beta


@pytest.mark.parametrize("lap", [0.0, 4e-6])
def test_fluid_volume_conserved_in_closed_network(lap):
    """Mass (docs/model.md 2-4): in a sealed network of hoses, accumulator, nodes and a servovalve
    at null the oil volume at zero gauge pressure is constant:
        S = C1/N sum p_k + C2/N sum p_k + (V_0 - V_g) + sum_nodes V p / beta
    (hose storage, accumulator oil (M16), node compressibility). Started far from
    equilibrium: hoses at 10 and 5 MPa, nodes at 12, 5, 8 and 11 MPa, gas at 15 MPa.
    Zero laps: the valve is blocked (M20: every opening sg(0) = 0), the chambers keep their
    pressures and the rest reaches one pressure p_f; by hand (adiabatic gas, M16)
        sum_j C_j (p_f - p_j0) = V_g0 ((p_g0/p_f)^(1/1.4) - 1),  j: hoses, V1, V2
    (C_j = A L/beta_e for a hose, V/beta for a node).
    4 um underlap: the valve's null leakage joins the chambers to the hoses, so every
    volume ends at one p_f that solves the same balance over all volumes."""
    net, l1, l2, beta = _closed_network((lap,) * 4)
    names = net.state_names
    x0 = np.zeros(len(names))
    init = {"supply": 10e6, "return": 5e6}
    for n in names:
        if n.endswith(".pressure"):
            x0[names.index(n)] = init.get(n.split(".")[0], 0.0)
    node_p0 = {"V1": 12e6, "V2": 5e6, "Vb": 8e6, "Vt": 11e6}
    node_V = {"V1": 50e-6, "V2": 30e-6, "Vb": 20e-6, "Vt": 25e-6}
    for k, v in node_p0.items():
        x0[names.index(f"{k}.pressure")] = v
    p_g0, V0, p0 = 15e6, 1e-3, 5e6
    Vg0 = V0 * p0 / p_g0
    x0[names.index("acc.gas_volume")] = Vg0
    p = net.parameter_values.copy()
    p[net.parameter_names.index("acc.reference_pressure")] = p_g0
    res = integrate(net, x0, 4.0, dt_out=2e-3, p=p)

    def hose(name, line):
        cols = [c for c in res.data.columns if c.startswith(f"{name}.segment") and c.endswith(".pressure")]
        return line.capacitance / len(cols) * res.data[cols].to_numpy().sum(axis=1)

    S = hose("supply", l1) + hose("return", l2) + (V0 - res["acc.gas_volume"]) \
        + sum(node_V[k] * res[f"{k}.pressure"] / beta for k in node_V)
    moved = res["acc.gas_volume"].max() - Vg0        # oil the gas pushed out, [m^3]
    assert moved > 1e-5                               # a real transient: > 10 cm^3
    assert np.max(np.abs(S - S[0])) < 1e-8 * moved    # conserved (linear invariant of BDF)
    # final state by hand
    C = {"supply": l1.capacitance, "return": l2.capacitance,
         **{k: node_V[k] / beta for k in node_V}}
    start = {"supply": 10e6, "return": 5e6, **node_p0}
    joined = list(C) if lap > 0 else ["supply", "return", "V1", "V2"]
    p_f = brentq(lambda pf: sum(C[j] * (pf - start[j]) for j in joined)
                 - Vg0 * ((p_g0 / pf) ** (1 / 1.4) - 1), p0, p_g0)
    for sig in ("p1", "p2", "pS", "pR") + (("pb", "pt") if lap > 0 else ()):
        assert res[sig][-1] == pytest.approx(p_f, rel=1e-5)
    if lap == 0:   # blocked: no flow at any port, the chambers untouched
        for q in ("qS", "qR", "qb", "qt"):
            assert np.all(res[q] == 0.0)
        assert np.ptp(res["pb"]) == 0.0 and np.ptp(res["pt"]) == 0.0


def test_linearised_natural_frequency_with_ideal_supply():
    """w_h^2 = beta_c (A_b^2/V_b + A_t^2/V_t)/m (docs/model.md 4), from the Jacobian's eigenvalues."""
    rig = load_rig()
    rig.set("actuator.gravity", "0 m/s^2")
    for k in ("viscous_up", "viscous_down"):
        rig.set(f"friction.{k}", "0 N*s/m")
    act = build_circuit(rig, position_guess=0.0).component("actuator")   # the rig's, at mid-stroke
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
    """docs/model.md 7: supply ~40 Hz / 1.0 MPa, return ~31 Hz / 0.94 MPa after the 50 mA step."""
    s = summarize(default_run)
    assert s["supply"]["frequency_hz"] == pytest.approx(40.0, rel=0.05)
    assert s["return"]["frequency_hz"] == pytest.approx(31.0, rel=0.05)
    assert s["supply"]["amplitude_mpa"] == pytest.approx(1.0, rel=0.10)
    assert s["return"]["amplitude_mpa"] == pytest.approx(0.94, rel=0.10)
    assert s["actuator_natural_frequency_hz"] == pytest.approx(172.0, rel=0.02)
    assert default_run.steady_state.residual < 1e-8
    # no validity warning inside the metrics window; after the piston's stop the return port
    # and top chamber dip to ~75 kPa, below the default gas-release pressure (1 atm)
    for w in s["warnings"]:
        assert "gas-release pressure" in w
        first = float(w.split("from t = ")[1].split(" ms")[0]) * 1e-3
        assert first > s["metrics_window_s"][1]


def test_result_has_every_signal_and_state(default_run, tmp_path):
    d = default_run.data
    assert "supply.section2.mode3.flow" in d and "supply_port_pressure" in d
    assert np.all(np.isfinite(d.to_numpy()))
    default_run.to_csv(tmp_path / "r.csv")
    assert (tmp_path / "r.csv").read_text().startswith("time [s],pump_pressure [Pa],")   # units in the header
    # starts at rest: the solved steady state has nothing moving before the step
    before = default_run.t < 0.01
    assert np.ptp(default_run["supply_port_pressure"][before]) < 1.0      # [Pa]


def test_closed_loop_sine_tracks():
    """The paper's 2 Hz, 35 mm sine under P control (docs/model.md 5, 7): tracking-error amplitude.

    The valve (140 Hz) and the hydraulics (172 Hz) are far faster than 2 Hz, and the load
    (m g = 158 N, friction < 100 N, i.e. < 0.35 MPa of the 19.7 MPa supply-to-return drop)
    hardly changes the valve's pressure drop, so the valve-actuator is a velocity source
    proportional to the current: v = (v_N/i_N) i, with the no-load velocity at rated current
    (M20, M21: two orifices in series, each at (p_S - p_R)/2)
        v_N = Q_N sqrt((p_S - p_R)/dp_N) / A = 3.1667e-4 sqrt(19.7/6.895) / 4.83e-4
            = 1.108 m/s   (i_N = 50 mA).
    With i = K_p e the loop is x' = K (r - x), K = K_p v_N/i_N = 1.5 * 1.108/0.05 = 33.2 1/s, so
    E(s)/R(s) = s/(s + K) and for r = X sin(w t) the steady error amplitude is
        |e| = w X / sqrt(K^2 + w^2) = 12.57 * 35 mm / sqrt(33.2^2 + 12.57^2) = 12.4 mm.
    The start transient decays as exp(-K t) (30 ms): measure over 0.25-0.75 s (one period)."""
    res = simulate(scenario="closed-loop-sine", t_end=0.75)
    s = summarize(res)
    e = res["position_reference"] - res["piston_position"]
    m = res.t >= 0.25
    amplitude = (e[m].max() - e[m].min()) / 2
    Q_N, dp_N, A, i_N, K_p = 19e-3 / 60, 6.894757e6, 4.83e-4, 0.05, 1.5
    v_N = Q_N * np.sqrt((20.7e6 - 1.0e6) / dp_N) / A
    K, w, X = K_p * v_N / i_N, 2 * np.pi * 2.0, 0.035
    hand = w * X / np.sqrt(K**2 + w**2)
    assert hand == pytest.approx(12.4e-3, rel=0.01)
    assert amplitude == pytest.approx(hand, rel=0.10)
    assert 0 < s["tracking_error_rms_mm"] < 35.0 * 0.5
    assert np.max(np.abs(res["piston_position"])) < 0.051


def test_cli_json_summary(capsys, tmp_path):
    rc = main(["simulate", "--json", "--t-end", "0.12 s", "--out", str(tmp_path)])
    assert rc == 0
    s = json.loads(capsys.readouterr().out)
    # the summary (issue 26): issue 3's keys among the rest, and the settling band (issue 23)
    assert {"supply", "return", "actuator_natural_frequency_hz", "wall_time_s",
            "settling_band"} <= set(s)
    assert s["settling_band"] == "+-2 % of the final absolute pressure"
    for side in ("supply", "return"):
        assert {"frequency_hz", "amplitude_mpa", "settling_time_s", "settling_band_mpa"} \
            <= set(s[side])
        assert s[side]["frequency_hz"] is None or isinstance(s[side]["frequency_hz"], float)
        assert isinstance(s[side]["amplitude_mpa"], float)
        assert s[side]["settling_time_s"] is None or isinstance(s[side]["settling_time_s"], float)
    assert isinstance(s["actuator_natural_frequency_hz"], float)
    assert isinstance(s["wall_time_s"], float)
    # the metrics themselves: the paper's baseline (docs/model.md 7), 172 Hz from w_h (M22-M23)
    assert s["supply"]["frequency_hz"] == pytest.approx(40.0, rel=0.10)
    assert s["actuator_natural_frequency_hz"] == pytest.approx(172.0, rel=0.01)
    # summary.json holds the same document
    assert json.loads((tmp_path / "summary.json").read_text()).keys() == s.keys()
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


def test_sampled_controller_holds_the_law_of_the_sampling_instant():
    # zero-order hold by hand: over (t_k, t_k + 1 ms] the current is the P law applied to the
    # reference and position at t_k, limited to +-current_limit (the sampled signals are the
    # compiled core's output row at t_k, not a Python evaluation: same numbers)
    rig = load_rig()
    rig.set("controller.sample_time", "1 ms")
    res = simulate(rig, "closed-loop-sine", t_end=0.03, dt_out=1e-4)
    kp, limit = rig["controller.proportional_gain"], rig["controller.current_limit"]
    t = res.t
    for k in range(1, 30):
        i_k = int(round(k * 10))                      # the row at t_k = k ms
        law = kp * (res["position_reference"][i_k] - res["piston_position"][i_k])
        held = min(max(law, -limit), limit)
        rows = slice(i_k + 1, i_k + 11)               # (t_k, t_k + 1 ms]
        assert t[i_k] == pytest.approx(k * 1e-3, abs=1e-12)
        assert res["valve_current"][rows] == pytest.approx(held, rel=1e-9, abs=1e-15)


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
    # 0.5 s: the exact-pole line keeps the hoses' slow viscous (real-axis) poles, through
    # which the manifold is still 18 kPa short of its final drop at 0.2 s
    res = simulate(load_rig(f), t_end=0.5)
    if hydroline.compiled.available():
        assert res.metadata["solver"] == "compiled"         # the table compiles (sum of ramps)
    t = res.t
    assert np.interp(0.025, t, res["pump_pressure"]) == pytest.approx(19.7e6, rel=1e-9)
    assert res["pump_pressure"][-1] == pytest.approx(18.7e6, rel=1e-12)
    p_i, p_f = res["supply.manifold_pressure"][[0, -1]]
    assert p_f - p_i == pytest.approx(-2.0e6, abs=5e3)
    V_i, V_f = res["supply.accumulator.gas_volume"][[0, -1]]
    assert V_f / V_i == pytest.approx((p_i / p_f) ** (1 / 1.4), rel=1e-4)


def test_pressure_figure_scaled_to_the_metrics_window(default_run):
    """pressures.png: after the piston reaches its stop (end of the metrics window) the traces
    are greyed on a shaded span and do not set the y-range; the oscillation after the step
    fills the panels (the paper's Figs. 10-12)."""
    import matplotlib.pyplot as plt
    from hydroline.scenarios import metrics_window

    t0, t1, reason = metrics_window(default_run)
    assert reason == "stop"
    assert t0 < t1 < default_run.t[-1]                       # the piston does reach its stop
    fig = default_run.plot()
    ax = fig.axes[0]                                          # supply port [MPa]
    p = default_run["supply_port_pressure"] / 1e6
    inside, after = p[default_run.t <= t1], p[default_run.t > t1]
    lo, hi = ax.get_ylim()
    assert lo <= inside.min() and inside.max() <= hi          # the window fits
    assert hi < after.max()                                   # the stop transient is clipped
    assert hi - lo < 1.2 * np.ptp(inside)
    spans = [a for a in ax.patches   # axvspan: x in data units, whatever the patch class
             if a.get_path().get_extents(a.get_patch_transform()).x0 == pytest.approx(t1 * 1e3)]
    assert spans, "no shaded span after the stop"
    plt.close(fig)


def test_the_papers_line_model_rig_reproduces_the_baseline_too():
    """The shipped rig with the paper's Yang-Tobler lines (calibrated through them) gives the
    paper's baseline as the default rig does (docs/model.md 7)."""
    rig = load_rig("ayalew2005_yang_tobler")
    assert rig["rig.line_method"] == "yang-tobler"
    s = summarize(simulate(rig, "open-loop-step"))
    assert s["supply"]["frequency_hz"] == pytest.approx(40.0, rel=0.05)
    assert s["return"]["frequency_hz"] == pytest.approx(31.0, rel=0.05)
    assert s["supply"]["amplitude_mpa"] == pytest.approx(1.0, rel=0.10)
    assert s["return"]["amplitude_mpa"] == pytest.approx(0.94, rel=0.10)


def test_every_calibrated_value_states_its_target_and_elasticity():
    """A [calibrated] value in the default rig file says what it was calibrated against
    (a target in Hz or MPa, or "as" another value that does) and how firmly (its elasticity
    or its closed form), as the developers' guide asks of calibrated numbers."""
    import re

    path = Path(hydroline.rigs.__file__).with_name("ayalew2005.toml")
    entries, current = [], None
    for line in path.read_text().splitlines():
        if re.match(r"^[a-z_]+\s*=", line):
            current = [line]
            entries.append(current)
        elif current is not None and re.match(r"^\s+#", line):
            current.append(line)
        else:
            current = None
    calibrated = [" ".join(e) for e in entries if "[calibrated]" in e[0]]
    assert len(calibrated) >= 5
    for text in calibrated:
        assert re.search(r"\d+(\.\d+)? (Hz|MPa)|see there", text), text
        assert re.search(r"elasticit|closed form|see there", text), text
