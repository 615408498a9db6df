"""Analysis on a circuit rig's axes (two_axis): linearisation, Bode, against independent
numbers (the nonlinear model's small-step response, the hose's quarter-wave frequency)."""
import numpy as np
import pytest
from scipy.linalg import expm

from hydroline.analysis.frequency import bode_analysis, rated_velocity
from hydroline.analysis.linearize import linearize, select_axis
from hydroline.rigs import load_rig
from hydroline.engine import integrate
from hydroline.traces.metrics import oscillation_frequency


@pytest.fixture(scope="module")
def rig():
    return load_rig("two_axis")


@pytest.fixture(scope="module")
def axis2_model(rig):
    return linearize(rig, inputs=["valve_current"], outputs=["supply_port_pressure"], axis="axis2")


def quarter_wave_hz(rig, hose):
    """c / 4L of a hose, c = sqrt(B / rho) (lossless line, M5), [Hz]."""
    c = np.sqrt(rig[f"circuit.{hose}.bulk_modulus"] / rig["fluid.density"])
    return c / (4 * rig[f"circuit.{hose}.length"])


def test_axis_handles_pick_the_axis(rig, axis2_model):
    assert select_axis(rig).name == "axis1"
    solved = axis2_model.operating_point
    assert solved.axis.name == "axis2"
    # the generic output is axis 2's port; its valve current holds its piston against gravity
    assert solved.signals[solved.axis.current] == pytest.approx(solved.valve_current)
    assert abs(solved.signals["axis2.piston_velocity"]) < 1e-9
    assert rated_velocity(rig, "axis2") == pytest.approx(
        rig["circuit.axis2.servovalve.rated_flow"] / rig["circuit.axis2.actuator.bottom_area"])
    with pytest.raises(ValueError, match="no axis 'axis9'"):
        select_axis(rig, "axis9")


def test_linearised_axis2_matches_nonlinear_small_step(axis2_model):
    sys, solved = axis2_model, axis2_model.operating_point
    net = solved.network
    di = 0.5e-3                      # 1 % of rated: small enough to stay linear
    p = solved.p.copy()
    p[net.parameter_names.index("command.final")] += di
    p[net.parameter_names.index("command.initial")] += di
    dt, t_end = 2e-4, 0.12
    res = integrate(net, solved.x.copy(), t_end, dt_out=dt, p=p, rtol=1e-8)
    y_nl = res["axis2.supply_port_pressure"] - solved.signals["axis2.supply_port_pressure"]
    # the linear model's step response, exactly discretised (zero-order hold), scaled states
    S = sys.state_scales
    A = sys.A * S[None, :] / S[:, None]
    B = sys.B[:, :1] / S[:, None]
    C = sys.C[:1] * S[None, :]
    n = A.shape[0]
    M = expm(np.block([[A, B], [np.zeros((1, n + 1))]]) * dt)
    Ad, Bd = M[:n, :n], M[:n, n:]
    z, y_lin = np.zeros((n, 1)), []
    for _ in res.t:
        y_lin.append((C @ z).item() + sys.D[0, 0] * di)
        z = Ad @ z + Bd * di
    y_lin = np.array(y_lin)
    f_nl = oscillation_frequency(res.t, y_nl, 0.0)
    f_lin = oscillation_frequency(res.t, y_lin, 0.0)
    assert f_nl == pytest.approx(f_lin, rel=0.01)
    # the ringing is axis 2's supply hose at about its quarter wave, where the linearised axis
    # has its lightly damped eigenvalues (the hose's mode split by the manifold and valve)
    assert f_nl == pytest.approx(quarter_wave_hz(solved_rig(axis2_model), "axis2.supply_hose"),
                                 rel=0.03)
    ev = np.linalg.eigvals(sys.A)
    f_ev = np.abs(ev.imag) / (2 * np.pi)
    assert np.min(np.abs(f_ev - f_nl)) < 0.05 * f_nl


def solved_rig(model):
    return load_rig("two_axis")



def test_bode_axis1_shows_supply_hose_quarter_wave(rig):
    f = np.linspace(20.0, 60.0, 161)
    b = bode_analysis(rig, input_name="valve_current", outputs=["supply_port_pressure"], f=f,
                      compare=False, exact=False, axis="axis1")
    g = np.abs(b.curves["hoses, modal lines"][:, 0])
    f_peak = f[int(np.argmax(g))]
    assert f_peak == pytest.approx(quarter_wave_hz(rig, "axis1.supply_hose"), rel=0.05)
    assert b.operating_points["hoses, modal lines"].axis.name == "axis1"


def test_friction_identified_on_axis2(rig):
    """Axis 2's friction, set apart from axis 1's, comes back from virtual steady-velocity
    runs on axis 2 (Newton's law, M23, with axis 2's areas, mass and load; M24 fitted)."""
    from hydroline.analysis.friction_id import friction_table, identify_friction
    from hydroline.studies.friction_tests import virtual_friction_tests

    r = rig.copy()
    truth = {"viscous_up": 1200.0, "viscous_down": 1000.0, "coulomb_up": 70.0, "coulomb_down": 40.0}
    for k, v in truth.items():
        r.set(f"circuit.axis2.friction.{k}", f"{v} {'N*s/m' if k.startswith('viscous') else 'N'}")
    i_r = r["circuit.axis2.servovalve.rated_current"]
    steady, _ = virtual_friction_tests(r, currents=[s * f * i_r for f in (0.1, 0.25)
                                                    for s in (1, -1)],
                                       t_run=0.05, slow_currents=(), sine=False, axis="axis2")
    fit = identify_friction(r, steady, window=1e-3, axis="axis2").fit
    for k, v in truth.items():
        assert getattr(fit, k) == pytest.approx(v, rel=0.02), k
    assert friction_table(r, "axis2") == "circuit.axis2.friction"
    assert fit.apply(r, "circuit.axis2.friction")["circuit.axis2.friction.viscous_up"] == \
        pytest.approx(fit.viscous_up)


def test_fit_a_hose_of_axis2(rig):
    """A record of axis 2's supply port pressure after a valve step, made with a stiffer axis-2
    supply hose, gives that hose's bulk modulus back (the line's wave speed sets the ringing)."""
    import pandas as pd

    from hydroline.analysis.fit import Measurements, fit_parameters, parameter_unit, simulate_record

    path = "circuit.axis2.supply_hose.bulk_modulus"
    assert parameter_unit(rig, path) == "Pa"
    t = np.arange(0.0, 0.03, 2e-4)
    df = pd.DataFrame({"time": t, "valve_current": np.where(t >= 5e-3, 10e-3, 0.0),
                       "supply_port_pressure": np.zeros_like(t)})
    true = rig.copy()
    true.set(path, "215 MPa")
    df["supply_port_pressure"] = simulate_record(true, Measurements(df, "model"),
                                                 start="rest", axis="axis2")["supply_port_pressure"]
    res = fit_parameters(rig, Measurements(df, "model"), [path], start="rest", axis="axis2",
                         max_evaluations=6)
    assert res.estimate[0] == pytest.approx(215e6, rel=1e-3)


def test_bode_cli_on_axis2_constant_supply_is_the_hydraulic_resonance(rig, tmp_path, capsys):
    """With ideal constant port pressures axis 2 is valve + actuator alone: its one resonance
    is w_h^2 = beta (A_b^2 / V_b + A_t^2 / V_t) / m at mid-stroke (M22, M23)."""
    import json

    from hydroline.cli import main

    rc = main(["bode", "two_axis", "--axis", "axis2", "--velocity", "0 m/s", "--no-exact",
               "--f-min", "20 Hz", "--f-max", "250 Hz", "--points", "200", "--json",
               "--out", str(tmp_path)])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    a = "circuit.axis2.actuator."
    wh = np.sqrt(rig[a + "bulk_modulus"] * (rig[a + "bottom_area"] ** 2 / rig[a + "bottom_volume"]
                                            + rig[a + "top_area"] ** 2 / rig[a + "top_volume"])
                 / rig[a + "moving_mass"])
    ideal = d["resonances"]["constant supply and return"]
    assert len(ideal) == 1
    assert ideal[0]["frequency_hz"] == pytest.approx(wh / (2 * np.pi), rel=0.01)
    assert main(["bode", "two_axis", "--axis", "axis9", "--json", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "axis9" in err[0] and "axis1, axis2" in err[0]
