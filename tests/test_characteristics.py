"""Method-of-characteristics reference line with unsteady laminar friction."""
import time

import numpy as np
import pytest
from scipy import special

from hydroline import Fluid
from hydroline.lines.characteristics import (TRIKHA_WEIGHTS, CharacteristicsLine,
                                             zielke_weighting, weighting_terms)
from hydroline.lines.inverse_laplace import exact_step_response, talbot
from hydroline.lines.line import Line

OIL = Fluid(870.0, 3.2e-5, 1.5e9)
RIG_HOSE = Line(3.048, 0.0127, OIL, 1.0e9)       # SAE 100R2 -8, default rig section
THIN = Line(10.0, 0.006, OIL, 1.0e9)             # a more dissipative line


def away_from_fronts(t, T, margin=0.1):
    phase = t / T
    return np.abs(phase - np.round(phase)) >= margin


def moc_errors(line, grids=(16, 32, 64), n_waves=40):
    """Max and rms |p_d(MOC) - p_d(exact)| for a unit upstream step, blocked end, per grid.

    Compared at the times t = k T/16 common to all grids, away from the wave fronts.
    """
    T = line.wave_time
    t_cmp = np.arange(16 * n_waves + 1) * T / 16
    keep = away_from_fronts(t_cmp, T)
    exact = exact_step_response(line, t_cmp[keep], "PQ", (0, 0))
    out = []
    for n in grids:
        res = CharacteristicsLine(line, n).step_response(n_waves * T)
        e = np.abs(res.downstream_pressure[::n // 16][keep] - exact)
        out.append((e.max(), np.sqrt(np.mean(e**2))))
    return out


# ---- Zielke's weighting function --------------------------------------------------------
def test_zielke_weighting_is_inverse_of_dissipative_friction():
    # Laplace transform of W (dimensionless s = kappa^2): (kappa I1/(2 I2) - 2)/s, from (M6)
    def w_transform(s):
        k = np.sqrt(s)
        return (k * special.ive(1, k) / (2.0 * special.ive(2, k)) - 2.0) / s

    tau = np.logspace(-8, np.log10(0.3), 30)
    assert np.allclose(zielke_weighting(tau), talbot(w_transform, tau), rtol=1e-8)


def test_zielke_weighting_matches_zielke_1968_series():
    tau = np.array([1e-5, 1e-4, 1e-3, 0.01])
    w = (0.282095 / np.sqrt(tau) - 1.25 + 1.057855 * np.sqrt(tau) + 0.9375 * tau
         + 0.396696 * tau**1.5 - 0.351563 * tau**2)
    assert np.allclose(zielke_weighting(tau), w, rtol=2e-5)
    tau = np.array([0.05, 0.2])
    assert np.allclose(zielke_weighting(tau),
                       np.exp(-np.outer(tau, [26.3744, 70.8493, 135.0198, 218.9216,
                                              322.5544])).sum(axis=1), rtol=1e-4)


def test_exponential_approximations():
    tau = np.logspace(-13, np.log10(0.5), 2000)
    w = zielke_weighting(tau)
    m, n = weighting_terms("zielke")
    assert np.all(m > 0) and np.all(n > 0)
    assert np.max(np.abs(np.exp(-np.outer(tau, n)) @ m / w - 1.0)) < 5e-5
    m, n = weighting_terms("trikha")
    assert np.array_equal(m, [40.0, 8.1, 1.0]) and np.array_equal(n, [8000.0, 200.0, 26.4])
    assert m is not TRIKHA_WEIGHTS[0]
    # Trikha's three terms are a rough fit (within ~40 %) for 1e-4 <= tau <= 0.1
    tau = np.logspace(-4, -1, 30)
    assert np.allclose(np.exp(-np.outer(tau, n)) @ m, zielke_weighting(tau), rtol=0.4)


# ---- lossless line ----------------------------------------------------------------------
def test_lossless_square_wave_exact():
    T = RIG_HOSE.wave_time
    res = CharacteristicsLine(RIG_HOSE, 16, friction="none").step_response(20 * T)
    k = np.round(res.t / T)
    at_front = np.isclose(res.t / T, k) & (k % 2 == 1)
    n_fronts = np.floor((res.t / T + 1.0) / 2.0 + 1e-9)
    expected = np.where(n_fronts % 2 == 1, 2.0, 0.0)
    assert np.allclose(res.downstream_pressure[~at_front], expected[~at_front], atol=1e-12)
    # upstream flow of the lossless line: 1/Z0 during the first round trip, then +-2/Z0
    Z0 = RIG_HOSE.impedance
    n2 = np.floor(res.t / (2 * T) + 1e-9)
    q_expected = np.where(n2 == 0, 1.0, 2.0 * (-1.0) ** n2 + (-1.0) ** (n2 + 1)) / Z0
    keep = ~np.isclose(res.t / (2 * T), np.round(res.t / (2 * T)))
    assert np.allclose(res.upstream_flow[keep], q_expected[keep], rtol=1e-12)


def test_lossless_matches_near_lossless_exact():
    line = Line(3.048, 0.0127, Fluid(870.0, 1e-12, 1.5e9), 1.0e9)
    T = line.wave_time
    res = CharacteristicsLine(line, 32, friction="none").step_response(10 * T)
    keep = away_from_fronts(res.t, T, 0.02)
    exact = exact_step_response(line, res.t[keep], friction="linear")
    assert np.max(np.abs(res.downstream_pressure[keep] - exact)) < 1e-6


# ---- dissipative lines against the exact dissipative model (M6) ------------------------
def test_rig_hose_against_exact_and_convergence():
    errs = moc_errors(RIG_HOSE)
    max64, rms64 = errs[-1]
    assert max64 < 0.03 and rms64 < 0.006          # of a unit step, ten wave periods
    for (m1, r1), (m2, r2) in zip(errs, errs[1:]):
        assert m2 < 0.8 * m1 and r2 < 0.7 * r1        # converges with the grid


def test_thin_line_against_exact_and_convergence():
    errs = moc_errors(THIN)
    max64, rms64 = errs[-1]
    assert max64 < 0.03 and rms64 < 0.003
    for (m1, r1), (m2, r2) in zip(errs, errs[1:]):
        assert m2 < 0.8 * m1 and r2 < 0.7 * r1


def test_unsteady_friction_matters():
    # steady (Hagen-Poiseuille) friction alone badly under-damps a hose: the unsteady part
    # is what makes the MOC agree with (M6)
    T = RIG_HOSE.wave_time
    res = CharacteristicsLine(RIG_HOSE, 16, friction="steady").step_response(40 * T)
    keep = away_from_fronts(res.t, T)
    exact = exact_step_response(RIG_HOSE, res.t[keep])
    assert np.max(np.abs(res.downstream_pressure[keep] - exact)) > 0.5


def test_flow_driven_end_against_exact():
    # upstream pressure held at 0, downstream flow stepped (a callable input)
    q0 = 1e-4
    T, Z0 = THIN.wave_time, THIN.impedance
    res = CharacteristicsLine(THIN, 64).simulate(
        40 * T, upstream_pressure=0.0, downstream_flow=lambda t: np.where(t >= 0, q0, 0.0))
    sub = slice(None, None, 4)                     # every 4th step, T/16 apart
    t = res.t[sub]
    keep = away_from_fronts(t, T)
    pd = q0 * exact_step_response(THIN, t[keep], "PQ", (0, 1))
    qu = q0 * exact_step_response(THIN, t[keep], "PQ", (1, 1))
    assert np.max(np.abs(res.downstream_pressure[sub][keep] - pd)) < 0.04 * Z0 * q0
    assert np.max(np.abs(res.upstream_flow[sub][keep] - qu)) < 0.04 * q0
    assert np.all(res.downstream_flow == q0)


def test_steady_state_and_initial_flow():
    R = THIN.resistance
    p0, q0 = 2.0e5, 1e-5
    moc = CharacteristicsLine(THIN, 16)
    # initial steady laminar flow is kept exactly (M12)
    res = moc.simulate(10 * THIN.wave_time, p0, q0, initial_pressure=p0, initial_flow=q0)
    assert np.allclose(res.downstream_pressure, p0 - R * q0, rtol=1e-12)
    assert np.allclose(res.upstream_flow, q0, rtol=1e-10)
    # from rest, the line settles to (M12)
    res = moc.simulate(200 * THIN.wave_time, p0, q0)
    assert res.downstream_pressure[-1] == pytest.approx(p0 - R * q0, rel=1e-6)
    assert res.upstream_flow[-1] == pytest.approx(q0, rel=1e-6)


def test_result_layout_and_speed():
    moc = CharacteristicsLine(RIG_HOSE, 64)
    T = RIG_HOSE.wave_time
    assert moc.dt == pytest.approx(T / 64)
    t0 = time.perf_counter()
    res = moc.step_response(40 * T, upstream_pressure=3.0, initial_pressure=1.0)
    elapsed = time.perf_counter() - t0
    assert elapsed < 2.0
    assert res.t.shape == res.downstream_pressure.shape == res.upstream_flow.shape
    assert res.t[0] == 0.0 and res.t[-1] >= 40 * T * (1 - 1e-12)
    assert res.upstream_pressure[0] == 3.0 and res.downstream_pressure[0] == 1.0
    assert np.all(res.downstream_flow == 0.0)


# ---- input validation --------------------------------------------------------------
@pytest.mark.parametrize("bad", [0, -3, 2.5, True, "8"])
def test_bad_n_reaches(bad):
    with pytest.raises(ValueError, match="n_reaches"):
        CharacteristicsLine(RIG_HOSE, bad)


def test_input_errors():
    with pytest.raises(ValueError, match="line"):
        CharacteristicsLine("hose")
    with pytest.raises(ValueError, match="friction"):
        CharacteristicsLine(RIG_HOSE, 8, friction="turbulent")
    with pytest.raises(ValueError, match="weighting"):
        CharacteristicsLine(RIG_HOSE, 8, weighting="vardy")
    moc = CharacteristicsLine(RIG_HOSE, 8)
    with pytest.raises(ValueError, match="t_end"):
        moc.step_response(0.0)
    with pytest.raises(ValueError, match="t_end"):
        moc.step_response(np.inf)
    with pytest.raises(ValueError, match="downstream"):
        moc.step_response(0.01, downstream="open")
    with pytest.raises(ValueError, match="upstream_pressure"):
        moc.step_response(0.01, upstream_pressure="high")
    with pytest.raises(ValueError, match="downstream_flow"):
        moc.simulate(0.01, downstream_flow=lambda t: np.nan * t)
    with pytest.raises(ValueError, match="theta"):
        moc.simulate(0.01, theta=2.0)
    with pytest.raises(ValueError, match="tau"):
        zielke_weighting([0.0])
