"""The performance envelope (issue 29): its search against known answers, the ideal-supply
envelope against the vendor's analytic one, the lines' cut, the command line."""
import json
import math

import numpy as np
import pytest

from hydroline.cli import main
from hydroline.rigs import load_rig
from hydroline.studies.envelope import (SineRig, analytic_envelope, clipped_sine_gain,
                                        envelope_points, fundamental, harmonic_distortion,
                                        largest_passing, periodic_change, vendor_parameters)

#: The default rig's rest pressures at the valve's ports (its lines' rest state: the pump's
#: 20.7 MPa less the null leakage's drop, the tank's 1.5 MPa plus it), [Pa]. Given here so a
#: constant-supply test builds no model of the lines.
PORTS = {"actuator": (20.6846e6, 1.5134e6)}


# ------------------------------------------------------------------ search, known answers

@pytest.mark.parametrize("start", [1e-4, 3e-3, 0.0123, 0.05])
def test_bisection_brackets_a_known_threshold(start):
    """passes(v) = v <= T: the answer lies within rtol below T, the failing bracket above."""
    T, rtol = 0.0123, 0.02
    calls = []

    def passes(v):
        calls.append(v)
        return v <= T, v

    v, info, v_fail, _ = largest_passing(passes, start, 1e-5, 0.05, rtol)
    assert v <= T < v_fail and v_fail / v <= 1 + rtol
    assert info == v
    # brackets of 1.5x then bisection of the log: log2(ln 1.5 / ln 1.02) + steps out
    assert len(calls) <= 6 + math.ceil(math.log(max(start, T) / min(start, T)) / math.log(1.5)) + 2


def test_bisection_ends_of_the_range():
    assert largest_passing(lambda v: (True, v), 0.01, 1e-3, 0.05)[:3:2] == (0.05, None)
    v, info, v_fail, _ = largest_passing(lambda v: (False, v), 0.01, 1e-3, 0.05)
    assert v == 1e-3 and info is None and v_fail == 1e-3


def test_fundamental_and_distortion_of_known_traces():
    n = 256
    ph = 2 * np.pi * np.arange(n) / n
    y = 0.3 + 2.0 * np.sin(ph) - 0.5 * np.cos(ph) + 0.1 * np.sin(3 * ph) + 0.2 * np.cos(2 * ph)
    assert fundamental(y, n) == pytest.approx(complex(2.0, -0.5), abs=1e-12)
    assert harmonic_distortion(y) == pytest.approx(math.hypot(0.1, 0.2) / math.hypot(2.0, 0.5),
                                                   rel=1e-12)


def test_periodic_change_of_a_decaying_transient():
    """A first-order transient exp(-t/tau) riding on a sine: the change between periods k and
    k+1 is (1 - exp(-T/tau)) exp(-k T/tau) of its size, the known answer."""
    n, tau, T = 256, 0.3, 0.1
    t = np.arange(3 * n) * T / n
    y = np.sin(2 * np.pi * t / T) + 0.5 * np.exp(-t / tau)
    expected = 0.5 * (1 - math.exp(-T / tau)) * math.exp(-T / tau)
    assert periodic_change(y[n:2 * n], y[2 * n:], 1.0) == pytest.approx(expected, rel=1e-9)


def test_clipped_sine_gain():
    """A clipped velocity's fundamental over its clip level: 1 for a pure sine, 4/pi for a
    square wave (the limit), in between rising with the distortion allowed."""
    g = [clipped_sine_gain(d) for d in (0.0, 0.01, 0.05, 0.1)]
    assert g[0] == 1.0 and all(1 < a < b < 4 / np.pi for a, b in zip(g[1:], g[2:]))


# ------------------------------------------------------------------ constant supply

@pytest.fixture(scope="module")
def constant():
    return SineRig(load_rig(), "constant", pressures=PORTS)


def test_amplitude_control_on_the_linear_loop(constant):
    """20 mm at 1 Hz, constant supply: the P loop is the first-order 1/(1 + i w/K_v) with
    K_v = K_p K_q / A, K_q = (Q_N/i_N) sqrt((p_s - p_t)/dp_N) (32.8 1/s). The reference the
    amplitude control settles on is the target over that gain: |C|/X within 1 % (friction's
    and gravity's load pressure, ~1 % of the drop), its lead within 15 % of atan(w/K_v)
    (the spool's 140 Hz lag, 0.8 deg, and the underlap's gain near null)."""
    rig = load_rig()
    p_s, p_t = PORTS["actuator"]
    k_q = rig["servovalve.rated_flow"] / rig["servovalve.rated_current"] * \
        math.sqrt((p_s - p_t) / rig["servovalve.rated_pressure_drop"])
    k_v = rig["controller.proportional_gain"] * k_q / rig["actuator.area"]
    w = 2 * np.pi * 1.0
    r, reached, gains = constant.reach(1.0, 0.02, {"actuator": 1.0 + 0j})
    assert reached and r.change <= constant.periodic_tolerance
    c = r.command["actuator"] / 0.02
    assert abs(c) == pytest.approx(math.hypot(1, w / k_v), rel=0.01)
    assert math.degrees(np.angle(c)) == pytest.approx(math.degrees(math.atan(w / k_v)), rel=0.15)
    assert abs(abs(r.position["actuator"]) - 0.02) <= 0.01 * 0.02


@pytest.mark.parametrize("stroke, frequencies, limits", [
    (None, [1.0, 8.0, 20.0], ["stroke", "valve", "valve"]),
    ("20 mm", [5.0], ["stroke"]),
])
def test_constant_supply_matches_the_analytic_envelope(stroke, frequencies, limits):
    """Where one limit acts alone, the simulated ideal-supply envelope lies within 5 % of the
    analytic one: the bisection's 2 % resolution, the 1 % amplitude tolerance, the 1 % stroke
    margin, the valve's 1 % underlap and the load pressure's fixed point at peak velocity
    (the clipped velocity's fundamental at 5 % distortion, 1.17 Q/A)."""
    rig = load_rig().copy()
    if stroke:
        rig.set("actuator.stroke", stroke)
        rig.set("actuator.initial_position", "0 mm")
    srig = SineRig(rig, "constant", pressures=PORTS)
    an = analytic_envelope(frequencies, **vendor_parameters(srig), distortion=0.05)
    assert an["limited_by"] == limits
    points = envelope_points(srig, frequencies, an["displacement_amplitude_m"])
    for point, x, limit in zip(points, an["displacement_amplitude_m"], limits):
        assert point["displacement_amplitude_m"] == pytest.approx(x, rel=0.05)
        assert point["limited_by"] == limit


# ------------------------------------------------------------------ with the lines

@pytest.mark.parametrize("f, limit, resonance", [
    (16.04818007, "return_rise", "the return line's 31 Hz"),
    (20.0, "supply_dip", "the supply line's 40 Hz"),
])
def test_lines_cut_the_envelope_at_the_line_resonances(f, limit, resonance):
    """The valve's flow pulsates at 2f: at 16 Hz that meets the return line's 31 Hz quarter
    wave (the return port's swing takes its troughs to the gas-release pressure), at 20 Hz
    the supply line's 40 Hz (the calibration's): the envelope with the lines lies below the
    constant supply's by more than the search's resolution, limited by the return rise or
    the supply dip."""
    rig = load_rig()
    hoses = SineRig(rig, "hoses")
    const = SineRig(rig, "constant", pressures=hoses.nominal)
    guess = [analytic_envelope([f], **vendor_parameters(const),
                               distortion=0.05)["displacement_amplitude_m"][0]]
    h = envelope_points(hoses, [f], guess)[0]
    c = envelope_points(const, [f], guess)[0]
    assert h["displacement_amplitude_m"] < 0.9 * c["displacement_amplitude_m"], resonance
    assert h["limited_by"] == limit and c["limited_by"] == "valve"
    if limit == "supply_dip":
        assert h["supply_min_pa"] < hoses.nominal["actuator"][0] - 2e6
    else:
        assert "return_port_pressure" in h["limit_note"]


# ------------------------------------------------------------------ command line

@pytest.mark.parametrize("args, needle", [
    (["--distortion", "5 parsecs"], "--distortion"),
    (["--distortion", "150 %"], "--distortion"),
    (["--frequencies", "10 Hz..1 Hz"], "--frequencies"),
    (["--frequencies", "3 m"], "--frequencies"),
    (["--workers", "0"], "--workers"),
])
def test_cli_refuses_bad_input_in_one_line(capsys, args, needle):
    rc = main(["envelope", *args])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and needle in err[0]


def test_cli_json_and_files(tmp_path, capsys):
    out = tmp_path / "env"
    assert main(["envelope", "--frequencies", "1 Hz", "--json", "--out", str(out)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["frequency_hz"] == [1.0]
    assert doc["limited_by"] == ["stroke"] and doc["constant_supply"]["limited_by"] == ["stroke"]
    assert doc["displacement_amplitude_m"][0] == pytest.approx(0.051, rel=0.02)
    assert doc["analytic"]["displacement_amplitude_m"] == [pytest.approx(0.051)]
    assert {p.name for p in out.iterdir()} == {"envelope.csv", "envelope.json", "envelope.png"}


@pytest.mark.parametrize("starts", [(1e-4, 0.05), (0.04, 2e-4), (0.0123, 0.0124)])
def test_bisection_grid_orders_two_searches(starts):
    """Both curves' searches try the same grid (1 + rtol)**k whatever their start: the lower
    threshold never gives the larger answer, and thresholds in one grid cell give one answer
    (so a curve above another by a grid step is the thresholds', not the searches')."""
    rtol = 0.02
    t_low, t_high = 0.0123, 0.0123 * 1.005          # one grid cell apart at most
    a = largest_passing(lambda v: (v <= t_low, None), starts[0], 1e-5, 0.05, rtol)[0]
    b = largest_passing(lambda v: (v <= t_high, None), starts[1], 1e-5, 0.05, rtol)[0]
    assert a <= b and b / a <= 1 + rtol + 1e-12
    c = largest_passing(lambda v: (v <= t_low, None), starts[1], 1e-5, 0.05, rtol)[0]
    assert c == a
    k = math.log(a) / math.log1p(rtol)
    assert abs(k - round(k)) < 1e-9                 # a grid value
