"""Analysis on a circuit rig's axes (two_axis): linearisation, Bode, against independent
numbers (the nonlinear model's small-step response, the hose's quarter-wave frequency)."""
import numpy as np
import pytest
from scipy.linalg import expm

from hydroline.analysis.frequency import bode_analysis, rated_velocity
from hydroline.analysis.linearize import linearize, select_axis
from hydroline.rigs import load_rig
from hydroline.simulation import integrate
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
