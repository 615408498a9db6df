"""Components against hand-derived numbers (docs/model.md sections 3-5)."""
import numpy as np
import pytest

from hydroline import components as comp
from hydroline.components.servovalve import valve_coefficient
from hydroline.lines import Line, ModalLine
from hydroline.fluid import MINERAL_OIL
from hydroline.engine import Network, NetworkError
from hydroline.engine import integrate, solve_steady_state

# A 5 gpm valve rated at 1000 psi (docs/model.md 7)
Q_N = 19e-3 / 60          # 19 L/min, [m^3/s]
DP_N = 1000 * 6894.757    # 1000 psi, [Pa]
X_MAX = 4e-4              # [m]


def valve(**kw):
    args = dict(name="servovalve", rated_current=0.05, rated_flow=Q_N, rated_pressure_drop=DP_N,
                max_opening=X_MAX, natural_frequency=140.0, damping_ratio=1.0,
                laminar_pressure=1e4)
    args.update(kw)
    return comp.Servovalve(**args)


def test_valve_coefficient_by_hand():
    # (M21): K_v = Q_N / (x_max sqrt(dp_N / 2))
    assert valve_coefficient(Q_N, DP_N, X_MAX) == pytest.approx(Q_N / (X_MAX * np.sqrt(DP_N / 2)))


def test_orifice_flow_at_rated_conditions_equals_rated_flow():
    v = valve()
    pS, pR = 21e6, 21e6 - DP_N
    # rated drop split evenly over the two metering edges: P->B and A(top)->T
    pb, pt = pS - DP_N / 2, pR + DP_N / 2
    y = v.outputs_of(0.0, {"spool_position": X_MAX, "spool_velocity": 0.0},
                     {"current": 0.05, "supply_pressure": pS, "return_pressure": pR,
                      "bottom_pressure": pb, "top_pressure": pt}, {})
    # laminar smoothing changes sqrt by (1 + (p_lam/dp)^2)^(-1/4) = 1 - 4e-6 here
    assert y["bottom_flow"] == pytest.approx(Q_N, rel=1e-5)
    assert y["top_flow"] == pytest.approx(Q_N, rel=1e-5)
    assert y["supply_flow"] == pytest.approx(Q_N, rel=1e-5)
    assert y["return_flow"] == pytest.approx(Q_N, rel=1e-5)


def test_valve_flow_reverses_and_saturates():
    v = valve()
    u = {"current": 0.0, "supply_pressure": 20e6, "return_pressure": 0.0,
         "bottom_pressure": 10e6, "top_pressure": 10e6}
    up = v.outputs_of(0, {"spool_position": 2e-4, "spool_velocity": 0}, u, {})
    down = v.outputs_of(0, {"spool_position": -2e-4, "spool_velocity": 0}, u, {})
    assert up["bottom_flow"] > 0 and down["bottom_flow"] < 0
    assert up["bottom_flow"] == pytest.approx(-down["bottom_flow"], rel=1e-12)
    beyond = v.outputs_of(0, {"spool_position": 3 * X_MAX, "spool_velocity": 0}, u, {})
    full = v.outputs_of(0, {"spool_position": X_MAX, "spool_velocity": 0}, u, {})
    assert beyond["bottom_flow"] == pytest.approx(full["bottom_flow"])
    # spool: current saturates at rated; steady spool position = x_max
    d = v.derivatives(0, {"spool_position": X_MAX, "spool_velocity": 0.0}, {"current": 0.2}, {})
    assert d["spool_velocity"] == pytest.approx(0.0, abs=1e-9)


def _accumulator_network(m, p1, p2, t_step=0.01):
    src = comp.PressureSource(name="source", pressure=p1, step_time=t_step, step_to=p2,
                              connections={"pressure": "node_pressure"})
    acc = comp.PistonAccumulator(name="acc", capacity=1e-3, precharge_pressure=5e6,
                                 polytropic_exponent=m, resistance=1e9, inertance=3e5,
                                 nominal_pressure=p1, connections={"pressure": "node_pressure",
                                                                  "flow": "acc_flow"})
    return Network([src, acc])


@pytest.mark.parametrize("m", [1.0, 1.4])
def test_accumulator_compression_isothermal_and_adiabatic(m):
    # charged isothermally from p0 = 5 MPa at V0 = 1 L to p1 = 10 MPa: V_g0 = V0 p0/p1 = 0.5 L;
    # then a step to p2 = 15 MPa compresses polytropically (M16): V = V_g0 (p1/p2)^(1/m)
    p1, p2 = 10e6, 15e6
    net = _accumulator_network(m, p1, p2)
    ss = solve_steady_state(net)
    Vg0 = ss.x[net.state_names.index("acc.gas_volume")]
    assert Vg0 == pytest.approx(1e-3 * 5e6 / p1, rel=1e-9)
    res = integrate(net, ss.x, 1.0, dt_out=1e-4, p=ss.p)
    V_end = res["acc.gas_volume"][-1]
    assert V_end == pytest.approx(Vg0 * (p1 / p2) ** (1 / m), rel=1e-6)
    # oil that entered = gas volume lost; flow integrates to it
    assert np.trapezoid(res["acc_flow"], res.t) == pytest.approx(Vg0 - V_end, rel=1e-3)


def test_accumulator_stops_delivering_when_empty():
    # node pressure falls below the pre-charge: the piston rests on its stop, V_g <= ~V0
    net = _accumulator_network(1.4, 10e6, 2e6)
    ss = solve_steady_state(net)
    res = integrate(net, ss.x, 1.0, dt_out=1e-3, p=ss.p)
    assert res["acc.gas_volume"][-1] == pytest.approx(1e-3, rel=1e-3)
    assert abs(res["acc_flow"][-1]) < 1e-8


def friction(**kw):
    args = dict(name="friction", viscous_up=800, viscous_down=600, coulomb_up=60, coulomb_down=50,
                static_up=90, static_down=80, stribeck_velocity=5e-3, stribeck_exponent=2.0,
                regularization_velocity=1e-5)
    args.update(kw)
    return comp.StribeckFriction(**args)


@pytest.mark.parametrize("v", [0.002, 0.01, 0.1, -0.002, -0.05])
def test_friction_at_chosen_velocities(v):
    f = friction()
    up = v > 0
    Fv, Fc, Fs = (800, 60, 90) if up else (600, 50, 80)
    expected = Fv * v + np.sign(v) * (Fc + (Fs - Fc) * np.exp(-(abs(v) / 5e-3) ** 2))   # (M24)
    assert f.force(v) == pytest.approx(expected, rel=1e-9)


def test_friction_regularised_through_zero():
    f = friction()
    assert f.force(0.0) == pytest.approx(0.0, abs=1e-9)
    v = np.linspace(-1e-4, 1e-4, 101)
    F = np.array([f.force(x) for x in v])
    assert np.all(np.diff(F) > 0)       # continuous and monotone across zero: no chatter


def test_lugre_sticks_below_breakaway():
    # LuGre option: under a steady applied force below F_s the bristle deflects and holds
    f = friction(model="lugre", bristle_stiffness=1e6, bristle_damping=300)
    z_ss = 70.0 / 1e6   # force 70 N < F_s = 90 N
    assert f.force(0.0, z_ss) == pytest.approx(70.0)
    assert f.derivatives(0, {"bristle": z_ss}, {"velocity": 0.0}, {})["bristle"] == 0.0


def test_check_valve_blocks_reverse_flow():
    cv = comp.CheckValve(name="cv", compute="inlet", forward_resistance=1e8, reverse_resistance=1e13)
    fwd = cv.pressure_drop(1e-4)
    rev = cv.pressure_drop(-1e-4)
    assert fwd == pytest.approx(1e8 * 1e-4, rel=1e-4)
    assert rev == pytest.approx(-1e13 * 1e-4, rel=1e-4)


def test_linear_resistance_both_causalities():
    r = comp.LinearResistance(name="r", compute="outlet", resistance=2e9)
    assert r.outputs_of(0, {}, {"inlet_pressure": 10e6, "flow": 1e-4}, {})["outlet_pressure"] == pytest.approx(9.8e6)
    r = comp.LinearResistance(name="r", compute="inlet", resistance=2e9)
    assert r.outputs_of(0, {}, {"outlet_pressure": 1e6, "flow": 1e-4}, {})["inlet_pressure"] == pytest.approx(1.2e6)


def test_commands():
    step = comp.StepCommand(name="c", initial=0.0, final=0.05, time=0.01)
    p = step.runtime_parameters()
    assert step.outputs_of(0.005, {}, {}, p)["command"] == 0.0
    assert step.outputs_of(0.02, {}, {}, p)["command"] == 0.05
    sine = comp.SineCommand(name="s", quantity="position", amplitude=0.035, frequency=2.0)
    assert sine.outputs_of(0.125, {}, {}, sine.runtime_parameters())["command"] == pytest.approx(0.035)
    ramp = comp.RampCommand(name="r", initial=1.0, slope=2.0, start=1.0, end=2.0)
    assert ramp.outputs_of(1.5, {}, {}, {})["command"] == pytest.approx(2.0)
    assert ramp.outputs_of(5.0, {}, {}, {})["command"] == pytest.approx(3.0)
    table = comp.TableCommand(name="t", times=[0, 1, 2], values=[0, 10, 0])
    assert table.outputs_of(0.5, {}, {}, {})["command"] == pytest.approx(5.0)
    with pytest.raises(ValueError, match="increase"):
        comp.TableCommand(name="t", times=[0, 0, 0, 2], values=[0, 1, 2, 3])
    with pytest.raises(ValueError, match="increase"):
        comp.TableCommand(name="t", times=[0, 1, 0.5], values=[0, 1, 2])
    # a time given twice is a jump: the second value from that time on (StepCommand's t >= time)
    jump = comp.TableCommand(name="t", times=[0, 1, 1, 2], values=[0, 1, 5, 7])
    assert [jump.outputs_of(t, {}, {}, {})["command"] for t in (0.5, 1 - 1e-12, 1.0, 1.5, 3.0)] == \
        pytest.approx([0.5, 1.0, 5.0, 6.0, 7.0])
    assert jump.breakpoints(3.0) == [1.0]


def test_table_command_from_csv(tmp_path):
    f = tmp_path / "cmd.csv"
    f.write_text("time [s],current [mA]\n0,0\n0.01,50\n")
    table = comp.TableCommand.from_csv(f, value_scale=1e-3)
    assert table.outputs_of(0.005, {}, {}, {})["command"] == pytest.approx(0.025)


def test_controller_limits_current():
    c = comp.PositionController(name="ctl", proportional_gain=10.0, current_limit=0.05)
    u = {"reference": 0.1, "position": 0.0, "velocity": 0.0}
    assert c.outputs_of(0, {}, u, {})["current"] == pytest.approx(0.05)
    u = {"reference": 0.001, "position": 0.0, "velocity": 0.0}
    assert c.outputs_of(0, {}, u, {})["current"] == pytest.approx(0.01)


def test_network_refuses_bad_wiring():
    src = comp.PressureSource(name="pump", pressure=1e7, connections={"pressure": "p1"})
    line = comp.HoseSection(name="hose", model=ModalLine(Line(1.0, 0.01, MINERAL_OIL, 1e9), 2),
                            connections={"upstream_pressure": "p1", "downstream_flow": "q_valve"})
    with pytest.raises(NetworkError, match=r"hose\.downstream_flow.*unconnected.*q_valve"):
        Network([src, line])
    src2 = comp.PressureSource(name="pump2", pressure=1e7, connections={"pressure": "p1"})
    with pytest.raises(NetworkError, match="two outputs"):
        Network([src, src2])
    # a pressure fed into a flow input
    bad = comp.PressureSource(name="wrong", pressure=1.0, connections={"pressure": "q_valve"})
    with pytest.raises(NetworkError, match="causality mismatch.*q_valve"):
        Network([src, line, bad])


# ---- time-varying pressure source (docs/model.md 1: p_hps(t), p_tank(t) known inputs) -----------
def test_pressure_source_waveforms_by_hand(tmp_path):
    sine = comp.PressureSource(name="pump", waveform=comp.SineCommand(
        name="w", quantity="pressure", offset=20e6, amplitude=1e6, frequency=50.0, start=0.01))
    p = sine.runtime_parameters()
    assert sine.pressure == 20e6                                  # level before the disturbance
    # 50 Hz: a quarter period after the start (5 ms) is the crest, three quarters the trough
    assert sine.outputs_of(0.005, {}, {}, p)["pressure"] == pytest.approx(20e6)
    assert sine.outputs_of(0.015, {}, {}, p)["pressure"] == pytest.approx(21e6)
    assert sine.outputs_of(0.025, {}, {}, p)["pressure"] == pytest.approx(19e6)
    ramp = comp.PressureSource(name="pump", waveform=comp.RampCommand(
        name="w", quantity="pressure", initial=20.7e6, slope=-20e6, start=0.01, end=0.11))
    # -20 MPa/s for 40 ms: 0.8 MPa down; held at 20.7 - 2.0 = 18.7 MPa after 110 ms
    assert ramp.outputs_of(0.05, {}, {}, ramp.runtime_parameters())["pressure"] == pytest.approx(19.9e6)
    assert ramp.outputs_of(0.5, {}, {}, ramp.runtime_parameters())["pressure"] == pytest.approx(18.7e6)
    assert ramp.breakpoints(1.0) == [0.01, 0.11]
    f = tmp_path / "p_hps.csv"
    f.write_text("time [ms], pressure [bar]\n0, 207\n20, 207\n30, 187\n")
    table = comp.PressureSource(name="pump", waveform=comp.TableCommand.from_csv_with_units(
        f, "Pa", name="w", quantity="pressure"))
    pt = table.runtime_parameters()
    assert table.pressure == pytest.approx(20.7e6)                # 207 bar
    assert table.outputs_of(0.025, {}, {}, pt)["pressure"] == pytest.approx(19.7e6)   # halfway
    assert table.outputs_of(1.0, {}, {}, pt)["pressure"] == pytest.approx(18.7e6)     # held
    # the runtime level shifts the whole waveform (sweeps, linearisation)
    pt["pressure"] += 1e5
    assert table.outputs_of(0.025, {}, {}, pt)["pressure"] == pytest.approx(19.8e6)
    # the legacy single step is a StepCommand waveform
    step = comp.PressureSource(name="pump", pressure=1e6, step_time=0.01, step_to=2e6)
    assert [step.outputs_of(t, {}, {}, step.runtime_parameters())["pressure"] for t in (0.0, 0.02)] == [1e6, 2e6]
    with pytest.raises(ValueError, match="quantity='pressure'"):
        comp.PressureSource(name="pump", waveform=comp.StepCommand(name="w", quantity="current"))
    with pytest.raises(ValueError, match="value at t = 0"):
        comp.PressureSource(name="pump", pressure=1e6, waveform=comp.StepCommand(
            name="w", quantity="pressure", initial=2e6, final=2e6, time=1.0))


def test_table_command_compiles_to_exact_ramps():
    """The symbolic table (a sum of clipped ramps) equals np.interp, also outside the ends."""
    import casadi as ca

    table = comp.TableCommand(name="t", quantity="pressure", times=[0.0, 0.01, 0.03, 0.04],
                              values=[1.0, 3.0, 3.0, -1.0])
    t = ca.SX.sym("t")
    f = ca.Function("f", [t], [table.outputs_of(t, {}, {}, {})["command"]])
    for tk in (-1.0, 0.0, 0.005, 0.02, 0.035, 0.04, 1.0):
        assert float(f(tk)) == pytest.approx(np.interp(tk, table.times, table.values), abs=1e-12)
    # jumps (a time twice): steps on top of the ramps, right-continuous like StepCommand
    jump = comp.TableCommand(name="j", quantity="current", times=[0.0, 0.01, 0.01, 0.02, 0.03, 0.03],
                             values=[0.0, 0.0, 0.05, 0.04, 0.04, 0.0])
    g = ca.Function("g", [t], [jump.outputs_of(t, {}, {}, {})["command"]])
    for tk, want in ((0.005, 0.0), (0.01 - 1e-9, 0.0), (0.01, 0.05), (0.015, 0.045), (0.025, 0.04),
                     (0.03, 0.0), (1.0, 0.0)):
        assert float(g(tk)) == pytest.approx(want, abs=1e-12)
        assert jump.outputs_of(tk, {}, {}, {})["command"] == pytest.approx(want, abs=1e-12)


def test_table_csv_errors_name_file_and_column(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("time [ms], pressure\n0, 1\n1, 2\n")
    with pytest.raises(ValueError, match=r"p\.csv: column 'pressure' has no unit"):
        comp.TableCommand.from_csv_with_units(f, "Pa")
    f.write_text("time [ms], pressure [MPa]\n0, 1\n0, 2\n")
    with pytest.raises(ValueError, match="increase strictly"):
        comp.TableCommand.from_csv_with_units(f, "Pa")


# ---- servovalve: spool dynamics (M19), laps and the laminar region (M20) --------------------
def test_spool_step_is_the_critically_damped_140_hz_curve():
    """(M19) with zeta = 1: a current step i0 below saturation moves the spool as
    x_v(t) = G_v i0 (1 - (1 + w tau) exp(-w tau)), tau = t - t_step, w = 2 pi 140 Hz,
    G_v = x_max / i_rated (0.4 mm / 50 mA): 25 mA gives 0.2 mm."""
    ports = {"current": "i", "supply_pressure": "pS", "return_pressure": "pR",
             "bottom_pressure": "pb", "top_pressure": "pt"}
    parts = [valve(connections=ports),
             comp.StepCommand(name="cmd", initial=0.0, final=0.025, time=1e-3,
                              connections={"command": "i"})]
    parts += [comp.PressureSource(name=f"src_{k}", pressure=v, connections={"pressure": k})
              for k, v in (("pS", 21e6), ("pR", 1e6), ("pb", 11e6), ("pt", 11e6))]
    net = Network(parts)
    res = integrate(net, np.zeros(len(net.state_names)), 0.03, dt_out=1e-4)
    w = 2 * np.pi * 140.0
    tau = np.maximum(res.t - 1e-3, 0.0)
    x_hand = 0.2e-3 * (1 - (1 + w * tau) * np.exp(-w * tau))
    assert np.max(np.abs(res["servovalve.spool_position"] - x_hand)) < 1e-4 * 0.2e-3
    # no overshoot (critical damping); 10-90 % rise by hand: 1 - (1 + y) e^-y = 0.1, 0.9 at
    # y = w tau = 0.5318, 3.8897, so t_r = 3.3579 / w = 3.817 ms
    x = res["servovalve.spool_position"]
    assert x.max() <= 0.2e-3 * (1 + 1e-6)
    t10, t90 = (np.interp(f * 0.2e-3, x[res.t < 0.02], res.t[res.t < 0.02]) for f in (0.1, 0.9))
    assert t90 - t10 == pytest.approx(3.3579 / w, rel=0.01)


def test_null_leakage_through_underlap_by_hand():
    """Spool at null, laps u = 4 um (1 % of x_max), ports at p_b = p_t = (p_S + p_R)/2: the
    four edges are open by u, so (M20, M21)
    q_S = 2 K_v u sqrt((p_S - p_R)/2) = 2 Q_N (u/x_max) sqrt((p_S - p_R)/dp_N)
        = 2 * 3.1667e-4 * 0.01 * sqrt(19.7 MPa / 6.895 MPa) = 1.0705e-5 m^3/s (0.64 L/min),
    all of it returning (q_R = q_S) and none into the chambers (q_b = q_t = 0)."""
    u = 4e-6
    v = valve(laps=(u,) * 4)
    pS, pR = 20.7e6, 1.0e6
    y = v.outputs_of(0.0, {"spool_position": 0.0, "spool_velocity": 0.0},
                     {"current": 0.0, "supply_pressure": pS, "return_pressure": pR,
                      "bottom_pressure": (pS + pR) / 2, "top_pressure": (pS + pR) / 2}, {})
    q_hand = 2 * Q_N * (u / X_MAX) * np.sqrt((pS - pR) / DP_N)
    assert q_hand == pytest.approx(1.0705e-5, rel=1e-4)
    # laminar smoothing: (1 + (p_lam/dp)^2)^(-1/4) = 1 - 3e-7 at dp = 9.85 MPa, p_lam = 10 kPa
    assert y["supply_flow"] == pytest.approx(q_hand, rel=1e-6)
    assert y["return_flow"] == pytest.approx(q_hand, rel=1e-6)
    assert abs(y["bottom_flow"]) < 1e-15 and abs(y["top_flow"]) < 1e-15
    # zero laps: a critically lapped valve at null passes nothing; an overlap (negative lap)
    # keeps every edge shut while |x_v| < the overlap
    for laps, xv in (((0.0,) * 4, 0.0), ((-1e-5,) * 4, 5e-6)):
        y = valve(laps=laps).outputs_of(0.0, {"spool_position": xv, "spool_velocity": 0.0},
                                        {"current": 0.0, "supply_pressure": pS, "return_pressure": pR,
                                         "bottom_pressure": 5e6, "top_pressure": 15e6}, {})
        assert all(q == 0.0 for q in y.values())


def test_laminar_region_slope_at_zero_drop():
    """phi(dp) = dp/(dp^2 + p_lam^2)^(1/4) has slope 1/sqrt(p_lam) at dp = 0, so an edge
    opened by x passes q = K_v x dp / sqrt(p_lam) near zero drop (finite conductance), and
    the square-root law K_v x sqrt(dp) well above p_lam."""
    v = valve(laminar_pressure=1e5)
    K, x = v.coefficient, 2e-4
    slope_hand = K * x / np.sqrt(1e5)
    for dp in (1.0, -1.0, 10.0):
        assert v.orifice(x, dp) / dp == pytest.approx(slope_hand, rel=1e-8)
    # odd, smooth, and turbulent far away: 1 % of the square root at 7 p_lam
    assert v.orifice(x, -5e4) == pytest.approx(-v.orifice(x, 5e4))
    assert v.orifice(x, 7e5) == pytest.approx(K * x * np.sqrt(7e5), rel=0.011)
    assert v.orifice(x, 1e7) == pytest.approx(K * x * np.sqrt(1e7), rel=1e-4)


# ---- actuator (M22-M23), load, controller --------------------------------------------------
def actuator(**kw):
    args = dict(name="actuator", bottom_area=1e-3, top_area=1e-3, bottom_volume=1e-4,
                top_volume=1e-4, bulk_modulus=1.4e9, moving_mass=20.0, stroke=0.1,
                gravity=0.0, stop_stiffness=1e9)
    args.update(kw)
    return comp.Actuator(**args)


def test_actuator_leakage_flows_by_hand():
    """(M22) at x_p = 10 mm, v_p = 0.05 m/s, p_b = 10 MPa, p_t = 5 MPa, q_b = q_t = 0.1 L/s,
    C_i = 1e-12, C_e = 2e-13 m^3/s/Pa:
    q_i = C_i (p_t - p_b) = -5e-6, q_eb = 2e-6, q_et = 1e-6, A v = 5e-5 [m^3/s];
    V_b = 1e-4 + 1e-5 = 1.1e-4, V_t = 0.9e-4 [m^3];
    dp_b/dt = 1.4e9/1.1e-4 (1e-4 - 5e-5 - 5e-6 - 2e-6) = 5.4727e8 Pa/s,
    dp_t/dt = 1.4e9/0.9e-4 (-1e-4 + 5e-5 + 5e-6 - 1e-6) = -7.1556e8 Pa/s."""
    a = actuator(internal_leakage=1e-12, external_leakage=2e-13)
    x = {"bottom_pressure": 10e6, "top_pressure": 5e6, "position": 0.01, "velocity": 0.05}
    u = {"bottom_flow": 1e-4, "top_flow": 1e-4, "friction_force": 0.0, "load_force": 0.0}
    d = a.derivatives(0.0, x, u, {})
    assert d["bottom_pressure"] == pytest.approx(5.4727e8, rel=1e-4)
    assert d["top_pressure"] == pytest.approx(-7.1556e8, rel=1e-4)
    # (M23): A_b p_b - A_t p_t = 1e4 - 5e3 = 5 kN on 20 kg
    assert d["velocity"] == pytest.approx(250.0)
    # no leakage: the same chamber with the leak terms removed
    d0 = actuator().derivatives(0.0, x, u, {})
    assert d0["bottom_pressure"] - d["bottom_pressure"] == pytest.approx(1.4e9 / 1.1e-4 * 7e-6, rel=1e-9)


def test_actuator_end_stop_force_by_hand():
    """Stops at +-stroke/2 = +-50 mm: spring k = 1e9 N/m on the penetration, damper
    c = 2 sqrt(k m) = 2 sqrt(1e9 * 20) = 2.828e5 N s/m engaged over the first 10 um."""
    a = actuator()
    pb = pt = 5e6
    u = {"bottom_flow": 0.0, "top_flow": 0.0, "friction_force": 0.0, "load_force": 0.0}

    def accel(xp, vp):
        return a.derivatives(0.0, {"bottom_pressure": pb, "top_pressure": pt, "position": xp,
                                   "velocity": vp}, u, {})["velocity"]

    assert accel(0.0499, 0.1) == 0.0                                     # clear of the stop
    assert accel(0.0501, 0.0) == pytest.approx(-1e9 * 1e-4 / 20.0)       # -100 kN
    c = 2 * np.sqrt(1e9 * 20.0)
    assert accel(0.050005, 0.1) == pytest.approx((-1e9 * 5e-6 - c * 0.1 * 0.5) / 20.0)
    assert accel(-0.0502, 0.0) == pytest.approx(+1e9 * 2e-4 / 20.0)      # bottom stop pushes up
    assert accel(-0.0502, -0.1) == pytest.approx((1e9 * 2e-4 + c * 0.1) / 20.0)


def test_load_force_by_hand():
    """F = k (x - x0) + b v + F_applied (+ F_step after its time), positive down:
    1e5 (0.03 - 0.01) + 2e3 * 0.1 + 500 = 2000 + 200 + 500 = 2700 N."""
    load = comp.Load(name="load", stiffness=1e5, damping=2e3, free_position=0.01, applied_force=500.0,
                     step_time=0.5, step_force=100.0)
    u = {"position": 0.03, "velocity": 0.1}
    p = load.runtime_parameters()
    assert load.outputs_of(0.0, {}, u, p)["load_force"] == pytest.approx(2700.0)
    assert load.outputs_of(1.0, {}, u, p)["load_force"] == pytest.approx(2800.0)
    assert load.breakpoints(1.0) == [0.5]


def test_pid_output_by_hand():
    """i = Kp e + Ki int(e) - Kd v_p (derivative on the measurement), clipped at +-limit:
    Kp = 1.5 A/m, Ki = 10 A/(m s), Kd = 0.02 A s/m, e = 0.02 - 0.01 = 0.01 m,
    int(e) = 0.002 m s, v_p = 0.05 m/s: i = 0.015 + 0.020 - 0.001 = 0.034 A."""
    c = comp.PositionController(name="ctl", proportional_gain=1.5, integral_gain=10.0,
                                derivative_gain=0.02, current_limit=0.05)
    x = {"error_integral": 0.002}
    u = {"reference": 0.02, "position": 0.01, "velocity": 0.05}
    assert c.outputs_of(0.0, x, u, {})["current"] == pytest.approx(0.034)
    assert c.derivatives(0.0, x, u, {})["error_integral"] == pytest.approx(0.01)   # d/dt int(e) = e
    # the integral term alone saturates: 10 * 0.01 = 0.1 A > 50 mA
    assert c.outputs_of(0.0, {"error_integral": 0.01}, u, {})["current"] == pytest.approx(0.05)
    assert c.outputs_of(0.0, {"error_integral": -0.01}, u, {})["current"] == pytest.approx(-0.05)


def test_pid_integral_accumulates_in_time():
    """A constant error e = 5 mm for 0.2 s (reference held, position held): the integrator
    state reaches e t = 1e-3 m s and the current Kp e + Ki e t = 7.5 mA + 10 mA = 17.5 mA."""
    parts = [comp.PositionController(name="ctl", proportional_gain=1.5, integral_gain=10.0,
                                     current_limit=0.05,
                                     connections={"current": "i"}),
             comp.StepCommand(name="ref", quantity="position", initial=0.005, final=0.005, time=1.0,
                              connections={"command": "reference"}),
             comp.StepCommand(name="pos", quantity="position", connections={"command": "position"}),
             comp.StepCommand(name="vel", quantity="velocity", connections={"command": "velocity"})]
    net = Network(parts)
    res = integrate(net, np.zeros(len(net.state_names)), 0.2, dt_out=1e-3)
    assert res["ctl.error_integral"][-1] == pytest.approx(1e-3, rel=1e-6)
    assert res["i"][-1] == pytest.approx(0.0175, rel=1e-6)


def test_modal_and_version_ii_accumulator_connections_agree():
    """docs/model.md 3: the accumulator connection as a rigid column (R, I; version II, M18) or as a
    full modal PP line; the 0.1 m passage is short (first mode c/2L ~ 6.6 kHz, far above the 40 Hz
    and 31 Hz port oscillations), so both give the same port oscillation within a few %."""
    from hydroline.rigs import load_rig
    from hydroline.scenarios import simulate, summarize

    out = {}
    for model in ("version-II", "modal"):
        rig = load_rig()
        for side in ("supply", "return"):
            rig.set(f"{side}.accumulator.model", model)
        out[model] = summarize(simulate(rig, t_end=0.12))
    for side in ("supply", "return"):
        a, b = out["version-II"][side], out["modal"][side]
        assert b["frequency_hz"] == pytest.approx(a["frequency_hz"], rel=0.03)
        assert b["amplitude_mpa"] == pytest.approx(a["amplitude_mpa"], rel=0.05)
