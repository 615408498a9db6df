"""Components against hand-derived numbers (MODEL.md sections 3-5)."""
import numpy as np
import pytest

from hydroline import components as comp
from hydroline.components.servovalve import valve_coefficient
from hydroline.lines import Line, ModalLine
from hydroline.fluid import MINERAL_OIL
from hydroline.network import Network, NetworkError
from hydroline.simulation import integrate, solve_steady_state

# A 5 gpm valve rated at 1000 psi (MODEL.md 7)
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
        comp.TableCommand(name="t", times=[0, 0, 2], values=[0, 1, 2])


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


# ---- time-varying pressure source (MODEL.md 1: p_hps(t), p_tank(t) known inputs) -----------
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


def test_table_csv_errors_name_file_and_column(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("time [ms], pressure\n0, 1\n1, 2\n")
    with pytest.raises(ValueError, match=r"p\.csv: column 'pressure' has no unit"):
        comp.TableCommand.from_csv_with_units(f, "Pa")
    f.write_text("time [ms], pressure [MPa]\n0, 1\n0, 2\n")
    with pytest.raises(ValueError, match="increase strictly"):
        comp.TableCommand.from_csv_with_units(f, "Pa")
