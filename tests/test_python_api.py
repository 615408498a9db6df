"""The Python entry points of issue 26: top-level names, margins read from the linearised model
through its frequency response, and readable reprs (text and HTML) of rigs and results."""
import math

import numpy as np
import pytest
from scipy import optimize

import hydroline
from hydroline.analysis.loop import bode_data, frequency_response_data, stability_margins


def test_top_level_names_are_the_analysis_functions():
    from hydroline import analysis, studies
    assert hydroline.linearize is analysis.linearize
    assert hydroline.bode_analysis is analysis.bode_analysis
    assert hydroline.stability_margins is stability_margins
    assert hydroline.bode_data is bode_data
    assert hydroline.layout is studies.layout and hydroline.sweep is studies.sweep
    assert {"linearize", "bode_data", "stability_margins"} <= set(dir(hydroline))


def _third_order(K):
    """L(s) = K / (s (s+1) (s+2)) as a state-space model (python-control)."""
    import control
    return control.ss(control.tf([K], [1, 3, 2, 0]), inputs=["u"], outputs=["y"])


def test_margins_of_a_known_loop():
    """K/(s(s+1)(s+2)): the phase is -180 deg at w = sqrt(2) rad/s where |L| = K/6, so the gain
    margin is 6/K; the phase margin is 90 - atan(w_c) - atan(w_c/2) deg at |L(j w_c)| = 1."""
    K = 2.0
    f = np.logspace(-3, 2, 4000)
    m = stability_margins(_third_order(K), f=f)
    assert m["gain_margin"] == pytest.approx(6 / K, rel=1e-4)
    assert m["gain_margin_db"] == pytest.approx(20 * math.log10(6 / K), rel=1e-4)
    assert m["phase_crossover_hz"] == pytest.approx(math.sqrt(2) / (2 * math.pi), rel=1e-4)
    wc = optimize.brentq(lambda w: K - w * math.hypot(w, 1) * math.hypot(w, 2), 1e-3, 10)
    assert m["gain_crossover_hz"] == pytest.approx(wc / (2 * math.pi), rel=1e-4)
    pm = 90 - math.degrees(math.atan(wc) + math.atan(wc / 2))
    assert m["phase_margin_deg"] == pytest.approx(pm, abs=0.01)
    # a loop gain with the controller's gain given apart: the same margins
    assert stability_margins(_third_order(1.0), gain=K, f=f)["gain_margin"] == pytest.approx(
        6 / K, rel=1e-4)


def test_frequency_response_data_and_bode_data_against_the_transfer_function():
    f = np.array([0.05, 0.2, 1.0])
    frd = frequency_response_data(_third_order(2.0), f)
    s = 2j * np.pi * f
    H = 2.0 / (s * (s + 1) * (s + 2))
    assert np.allclose(frd.frdata[0, 0], H, rtol=1e-10)
    assert list(frd.input_labels) == ["u"] and list(frd.output_labels) == ["y"]
    tab = bode_data(_third_order(2.0), f)
    assert list(tab.columns) == ["frequency_hz", "gain", "gain_db", "phase_deg"]
    assert np.allclose(tab["gain"], np.abs(H), rtol=1e-10)
    # the phase of 1/(s(s+1)(s+2)): -90 - atan(w) - atan(w/2), continuous (unwrapped)
    w = 2 * np.pi * f
    assert np.allclose(tab["phase_deg"], -90 - np.degrees(np.arctan(w) + np.arctan(w / 2)))
    with pytest.raises(ValueError, match="output: 'x' is not one of"):
        bode_data(_third_order(2.0), f, output="x")


def test_margins_of_the_default_rigs_position_loop():
    """P control around valve current -> piston position (~60 states): read through the
    frequency response. The loop is an integrator below the hose modes: the phase at the gain
    crossover is near -90 deg (margin between 45 and 90 deg) and |K_p H| there is 1."""
    rig = hydroline.load_rig()
    plant = hydroline.linearize(rig, inputs=["valve_current"], outputs=["piston_position"])
    kp = rig["controller.proportional_gain"]
    m = stability_margins(plant, gain=kp)
    assert 45 < m["phase_margin_deg"] <= 90
    assert m["gain_margin"] > 1 and m["phase_crossover_hz"] > m["gain_crossover_hz"]
    at = bode_data(plant, f=[m["gain_crossover_hz"], m["phase_crossover_hz"]])
    assert at["gain"][0] * kp == pytest.approx(1.0, rel=1e-3)
    assert at["gain"][1] * kp * m["gain_margin"] == pytest.approx(1.0, rel=1e-3)


def test_rig_repr_text_and_html():
    rig = hydroline.load_rig()
    text = repr(rig)
    assert text.startswith("hydroline Rig") and rig["rig.name"] in text
    assert "supply.pressure" in text and rig.raw["supply.pressure"] in text
    page = rig._repr_html_()
    assert "<table>" in page and "&amp;" in page          # "Ayalew & Kulakowski", escaped
    two = repr(hydroline.load_rig("two_axis"))
    assert "axis1.supply_hose" in two and "circuit components" in two


def test_simulation_result_repr_shows_its_summary():
    res = hydroline.simulate(None, t_end=0.06)
    summary = hydroline.summarize(res)
    text = repr(res)
    assert "open-loop-step" in text and f"{len(res.t)} rows" in text
    assert f"{summary['supply']['first_excursion_mpa']:.4g}" in text
    assert "<table>" in res._repr_html_()
    from hydroline.engine import SimulationResult   # built by hand: no summary, still readable
    assert "2 rows" in repr(SimulationResult(times=[0.0, 1.0], table=[[1.0], [2.0]], columns=["x"]))


def test_layout_and_sweep_reprs():
    from hydroline.studies import LayoutStudy
    port = {"frequency_hz": 40.0, "amplitude_mpa": 1.0, "settling_time_s": 0.0123}
    study = LayoutStudy([3.048], [{"supply": port, "return": port}], [], rig_name="r")
    text = repr(study)
    assert "3.048" in text and "40" in text and "12.3" in text     # settling in ms
    assert "<table>" in study._repr_html_()
    sw = hydroline.sweep(["supply.pressure=20 MPa"], t_end=0.03)
    assert "1 of 1 in the table" in repr(sw) and "supply.pressure [Pa]" in repr(sw)
    assert "<table" in sw._repr_html_()
