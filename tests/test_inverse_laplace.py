"""Numerical inverse Laplace transforms and exact line step responses (docs/model.md section 2)."""

import numpy as np
import pytest
from scipy import special

from hydroline import Fluid
from hydroline.lines.inverse_laplace import dehoog, exact_step_response, talbot, wave_series
from hydroline.lines.line import Line

OIL = Fluid(870.0, 3.2e-5, 1.5e9)
RIG_HOSE = Line(3.048, 0.0127, OIL, 1.0e9)       # SAE 100R2 -8, default rig section
THIN = Line(10.0, 0.006, OIL, 1.0e9)             # a more dissipative line
ALL_ENTRIES = [(f, e) for f in ("PQ", "QP", "PP", "QQ")
               for e in ((0, 0), (0, 1), (1, 0), (1, 1))]


def near_lossless(length=3.048, diameter=0.0127):
    return Line(length, diameter, Fluid(870.0, 1e-12, 1.5e9), 1.0e9)


# ---- general-purpose inverters against known transforms ---------------------------------
def test_talbot_rational():
    t = np.linspace(0.05, 8.0, 60)
    f = talbot(lambda s: 1.0 / (s * (s + 1.0)), t)
    assert np.max(np.abs(f - (1.0 - np.exp(-t)))) < 1e-9


def test_talbot_branch_cut_erfc():
    # L^-1[exp(-a sqrt(s))/s] = erfc(a/(2 sqrt(t))): a branch point at s = 0
    a = 0.7
    t = np.logspace(-3, 2, 40)
    f = talbot(lambda s: np.exp(-a * np.sqrt(s)) / s, t)
    assert np.max(np.abs(f - special.erfc(a / (2.0 * np.sqrt(t))))) < 1e-9


def test_dehoog_rational_and_jump():
    t = np.linspace(0.05, 5.0, 50)
    f = dehoog(lambda s: 1.0 / (s * (s + 1.0)), t, n_terms=40)
    assert np.max(np.abs(f - (1.0 - np.exp(-t)))) < 1e-5
    # delayed unit step exp(-s)/s, away from the jump
    tj = np.array([0.3, 0.8, 1.2, 2.0, 3.5])
    fj = dehoog(lambda s: np.exp(-s) / s, tj, n_terms=80, period=4.0)
    assert np.allclose(fj, (tj > 1.0).astype(float), atol=1e-4)


def test_talbot_convergence_by_doubling():
    t = np.linspace(0.1, 40.0, 200) * THIN.wave_time
    y12 = exact_step_response(THIN, t, n_terms=12)
    y24 = exact_step_response(THIN, t, n_terms=24)
    y32 = exact_step_response(THIN, t, n_terms=32)
    assert np.max(np.abs(y24 - y32)) < 1e-8
    assert np.max(np.abs(y12 - y24)) < 1e-5


# ---- the wave-series decomposition reproduces Line.transfer --------------------------
@pytest.mark.parametrize("friction", ["dissipative", "linear"])
@pytest.mark.parametrize("form,entry", ALL_ENTRIES)
def test_wave_series_matches_transfer(form, entry, friction):
    s = np.array([5.0 + 100j, 50.0 + 3000j, 1.0 + 10j, 200.0, 20.0 - 700j])
    for line in (RIG_HOSE, THIN):
        h = line.transfer(s, form, friction, 1.1, 2.0)[..., entry[0], entry[1]]
        w = wave_series(line, s, form, entry, friction, 1.1, 2.0, n_waves=4000)
        assert np.max(np.abs(w - h) / np.abs(h)) < 1e-8


# ---- near-lossless line: the square waves of the lossless telegraph line ----------------
def _away_from_fronts(t, T, margin=0.05):
    phase = t / T
    return np.abs(phase - np.round(phase)) > margin


def test_near_lossless_blocked_line_square_wave():
    line = near_lossless()
    T = line.wave_time
    t = np.linspace(0.01, 20.0, 400) * T
    keep = _away_from_fronts(t, T)
    t = t[keep]
    y = exact_step_response(line, t, "PQ", (0, 0), friction="linear")
    # lossless 1/cosh(sT)/s: 0 until T, then 2 on (1,3)T, 0 on (3,5)T, 2 on (5,7)T, ...
    k = np.floor((t / T + 1.0) / 2.0)           # number of fronts arrived
    expected = np.where(k % 2 == 1, 2.0, 0.0)
    assert np.max(np.abs(y - expected)) < 1e-6
    # the de Hoog path through Line.transfer agrees away from the fronts (Gibbs ringing)
    t2 = (np.arange(12) + 0.5) * T
    yd = exact_step_response(line, t2, "PQ", (0, 0), friction="linear", method="dehoog")
    k2 = np.floor((t2 / T + 1.0) / 2.0)
    assert np.max(np.abs(yd - np.where(k2 % 2 == 1, 2.0, 0.0))) < 2e-3


def test_input_filter_near_lossless_lag():
    # the blocked near-lossless line driven through a first-order lag a/(s + a): each
    # arriving wave 2 (-1)^j of the square wave becomes 2 (-1)^j (1 - exp(-a (t - t_j)))
    line = near_lossless()
    T = line.wave_time
    a = 3.0 / T
    t = np.linspace(0.01, 12.0, 300) * T
    y = exact_step_response(line, t, "PQ", (0, 0), friction="linear",
                            input_filter=lambda s: a / (s + a))
    expected = np.zeros_like(t)
    for j in range(6):
        tj = (2 * j + 1) * T
        expected += np.where(t > tj, 2.0 * (-1) ** j * (1.0 - np.exp(-a * (t - tj))), 0.0)
    assert np.max(np.abs(y - expected)) < 1e-6


def test_near_lossless_other_entries():
    line = near_lossless()
    T, Z0 = line.wave_time, line.impedance
    t = (np.arange(16) + 0.5) * T
    n2 = np.floor(t / (2 * T))                   # round trips completed
    # PQ (0,1) = -Zc tanh: -Z0, +Z0, -Z0, ... per round trip
    y = exact_step_response(line, t, "PQ", (0, 1), friction="linear")
    assert np.allclose(y, -Z0 * (-1.0) ** n2, rtol=1e-6)
    # PP (0,0) = coth/Zc: staircase (2k+1)/Z0
    y = exact_step_response(line, t, "PP", (0, 0), friction="linear")
    assert np.allclose(y, (2 * n2 + 1) / Z0, rtol=1e-6)
    # QP (1,0) = 1/cosh: like PQ (0,0)
    y = exact_step_response(line, t, "QP", (1, 0), friction="linear")
    k = np.floor((t / T + 1.0) / 2.0)
    assert np.allclose(y, np.where(k % 2 == 1, 2.0, 0.0), atol=1e-6)


# ---- dissipative line: final values (M12) and cross-check of the two methods ----------
def test_final_value_equals_dc_gain():
    T = THIN.wave_time
    t = np.array([150.5, 200.5]) * T
    R = THIN.resistance
    assert np.allclose(exact_step_response(THIN, t, "PQ", (0, 0)), 1.0, atol=1e-6)
    assert np.allclose(exact_step_response(THIN, t, "PQ", (1, 1)), 1.0, atol=1e-6)
    assert np.allclose(exact_step_response(THIN, t, "PQ", (0, 1)), -R, rtol=1e-6)
    assert np.allclose(exact_step_response(THIN, t, "PQ", (1, 0)) * R, 0.0, atol=1e-6)
    assert np.allclose(exact_step_response(THIN, t, "PP", (0, 0)), 1.0 / R, rtol=1e-6)
    assert np.allclose(exact_step_response(THIN, t, "QP", (0, 0)), R, rtol=1e-6)


def test_initial_jump_is_wave_impedance():
    # just after t = 0 the flow answers a pressure step through Z0 (the front)
    t = np.array([1e-4, 1e-3]) * RIG_HOSE.wave_time
    y = exact_step_response(RIG_HOSE, t, "PQ", (1, 0)) * RIG_HOSE.impedance
    assert np.all(np.abs(y - 1.0) < 0.02)
    assert np.all(exact_step_response(RIG_HOSE, [-1.0, 0.0]) == 0.0)


@pytest.mark.parametrize("form,entry", [("PQ", (0, 0)), ("PQ", (0, 1)), ("PQ", (1, 0)),
                                        ("QP", (0, 0)), ("PP", (0, 1))])
def test_wavefront_agrees_with_dehoog(form, entry):
    T = THIN.wave_time
    t = (np.arange(12) + 0.5) * T
    yw = exact_step_response(THIN, t, form, entry)
    yd = exact_step_response(THIN, t, form, entry, method="dehoog", n_terms=256)
    scale = np.max(np.abs(yw))
    assert np.max(np.abs(yw - yd)) < 1e-5 * scale


def test_rig_hose_wavefront_agrees_with_dehoog_over_ten_periods():
    T = RIG_HOSE.wave_time
    t = (np.arange(40) + 0.5) * T
    yw = exact_step_response(RIG_HOSE, t)
    yd = exact_step_response(RIG_HOSE, t, method="dehoog")
    assert np.max(np.abs(yw - yd)) < 5e-4


@pytest.mark.parametrize("Dn", [0.01, 0.05])
def test_blocked_line_step_against_mpmath(Dn):
    """Spot check of the exact reference used by tests/test_residue.py (issue 7's case).

    Independent path: mpmath's de Hoog inversion (30 digits, degree 80) of the whole
    ``1/(s cosh Gamma(s))`` (M6) with mpmath's Bessel functions, no wave series; at 2.0
    and 5.5 L/c (away from the fronts at odd multiples), where it agrees with the
    wave-front Talbot result to ~1e-11 (measured).
    """
    mp = pytest.importorskip("mpmath")
    d, fluid, bulk = 0.006, OIL, 1.0e9
    c = np.sqrt(bulk / fluid.density)
    line = Line(Dn * c * d**2 / (4 * fluid.kinematic_viscosity), d, fluid, bulk)
    T = line.wave_time
    with mp.workdps(30):
        nu, r, tau = (mp.mpf(v) for v in (fluid.kinematic_viscosity, line.radius, T))

        def F(s):
            k = r * mp.sqrt(s / nu)
            G = s * tau * mp.sqrt(mp.besseli(0, k) / mp.besseli(2, k))
            return 1 / (s * mp.cosh(G))

        ref = [float(mp.invertlaplace(F, x * T, method="dehoog", degree=80))
               for x in (2.0, 5.5)]
    y = exact_step_response(line, np.array([2.0, 5.5]) * T, "PQ", (0, 0))
    assert np.max(np.abs(y - ref)) < 1e-9


@pytest.mark.parametrize("form, entry", [("PQ", (0, 0)), ("PQ", (0, 1)), ("QQ", (1, 0)),
                                          ("PP", (0, 0))])
def test_grid_shares_bessel_evaluations_to_round_off(form, entry):
    """On a uniform grid whose step divides L/c the shifted times t - m L/c recur from front
    to front and share one evaluation of the Bessel functions; one time alone shares
    nothing (each front evaluated on its own). Both agree to the documented round-off
    (1e-10 of the response scale; measured <= 2.3e-12 on 2000 points over 80 L/c), with and
    without an input filter, for the entries with the factors 1, Zc and 1/Zc."""
    T = THIN.wave_time
    t = np.arange(1, 401) * (T / 20.0)                     # 20 L/c, step L/(20 c)
    a = 40.0 / T

    def W(s):
        return a / (s + a)

    for filt in (None, W):
        y = exact_step_response(THIN, t, form, entry, input_filter=filt)
        pick = np.arange(3, 400, 23)
        alone = [exact_step_response(THIN, t[k:k + 1], form, entry, input_filter=filt)[0]
                 for k in pick]
        assert np.abs(y[pick] - alone).max() < 1e-10 * np.abs(y).max()


# ---- input validation --------------------------------------------------------------
def test_input_errors():
    t = np.linspace(0.1, 1.0, 5) * THIN.wave_time
    with pytest.raises(ValueError, match="form"):
        exact_step_response(THIN, t, form="XY")
    with pytest.raises(ValueError, match="entry"):
        exact_step_response(THIN, t, entry=(2, 0))
    with pytest.raises(ValueError, match="friction"):
        exact_step_response(THIN, t, friction="turbulent")
    with pytest.raises(ValueError, match="method"):
        exact_step_response(THIN, t, method="stehfest")
    with pytest.raises(ValueError, match="n_terms"):
        exact_step_response(THIN, t, n_terms=0)
    with pytest.raises(ValueError, match="line"):
        exact_step_response("hose", t)
    with pytest.raises(ValueError, match="t must"):
        talbot(lambda s: 1 / s, [0.0, 1.0])
    with pytest.raises(ValueError, match="tol"):
        dehoog(lambda s: 1 / s, [1.0], tol=2.0)
