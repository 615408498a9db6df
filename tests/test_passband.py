"""The two -3 dB readings of a gain with notches (issue 23, item 5), on transfer functions whose
crossings are known in closed form or found here from the closed-form |H|^2 alone.

A first-order lag 1/(1 + s/w_c) has |H|^2 = 1/(1 + (f/f_c)^2) = 1/2 at f = f_c exactly. A lag
times a notch N(s) = (s^2 + 2 z_z w_n s + w_n^2)/(s^2 + 2 z_p w_n s + w_n^2) has

    |H|^2 = 1/(1 + (f/f_c)^2) * ((w_n^2 - w^2)^2 + (2 z_z w_n w)^2) / ((w_n^2 - w^2)^2 + (2 z_p w_n w)^2),

whose crossings of 1/2 are found by bracketing on a grid and Brent's method. The readings are
interpolated between samples linearly in (log f, dB); on a grid of step h in ln f that errs by
at most h^2/8 |d^2 dB/d(ln f)^2| / |d dB/d ln f| in ln f: for h = 2e-4 and the notch's
curvature (~1e4 dB, slope ~1e2 dB at its flanks) about 1e-6, so 1e-5 relative is a safe bound.
"""
import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar

from hydroline.analysis.frequency import LEVEL_DB, NOTCH_MARGIN_DB, bandwidth, passband

F = np.logspace(0, np.log10(500.0), 31_000)           # h = ln(500)/31000 = 2e-4
FC, FN, ZP = 100.0, 40.0, 0.05                          # lag corner, notch centre [Hz], damping
REL = 1e-5


def gain2(f, zz, fr=None, za=None):
    """|H|^2 of lag x notch (x a resonant peak at fr when given), closed form."""
    w, wn = 2 * np.pi * f, 2 * np.pi * FN
    out = 1 / (1 + (f / FC) ** 2) * ((wn**2 - w**2) ** 2 + (2 * zz * wn * w) ** 2) / \
        ((wn**2 - w**2) ** 2 + (2 * ZP * wn * w) ** 2)
    if fr is not None:       # peak: numerator damping za > denominator damping 0.05
        wr = 2 * np.pi * fr
        out = out * ((wr**2 - w**2) ** 2 + (2 * za * wr * w) ** 2) / ((wr**2 - w**2) ** 2 + (2 * 0.05 * wr * w) ** 2)
    return out


def response(zz, fr=None, za=None):
    """The complex response on F (what the code reads)."""
    s, wn = 2j * np.pi * F, 2 * np.pi * FN
    H = 1 / (1 + s / (2 * np.pi * FC)) * (s**2 + 2 * zz * wn * s + wn**2) / (s**2 + 2 * ZP * wn * s + wn**2)
    if fr is not None:
        wr = 2 * np.pi * fr
        H = H * (s**2 + 2 * za * wr * s + wr**2) / (s**2 + 2 * 0.05 * wr * s + wr**2)
    return H


def crossings(fun):
    """Frequencies where fun(f) = 1/2 (falls and rises), by Brent's method on grid brackets."""
    grid = np.logspace(0, np.log10(500.0), 4000)
    d = fun(grid) - 0.5
    ks = np.flatnonzero(np.sign(d[:-1]) != np.sign(d[1:]))
    return [brentq(lambda x: fun(x) - 0.5, grid[k], grid[k + 1], xtol=1e-12) for k in ks]


def test_first_order_lag_crosses_at_its_corner():
    H = 1 / (1 + 2j * np.pi * F / (2 * np.pi * FC))
    band = passband(F, H, reference=1.0)
    assert band.first_crossing_hz == pytest.approx(FC, rel=REL)
    assert band.within_3db_up_to_hz == pytest.approx(FC, rel=REL)
    assert not band.in_notch and band.note == ""
    assert bandwidth(F, H, reference=1.0) == pytest.approx(FC, rel=REL)
    assert LEVEL_DB == pytest.approx(10 * np.log10(0.5))


def test_lag_with_a_notch_below_the_level():
    """z_z = 0.02: the notch dips to 20 log10(0.02/0.05) - 0.7 = -8.7 dB: four crossings of
    1/2 (into the notch, out of it, the lag's corner and none after); the first reading is
    the first one and lies in the notch, the within-3-dB reading is the last."""
    roots = crossings(lambda f: gain2(f, 0.02))
    assert len(roots) == 3 and roots[0] < FN < roots[1] < roots[2]
    band = passband(F, response(0.02), reference=1.0)
    assert band.first_crossing_hz == pytest.approx(roots[0], rel=REL)
    assert band.within_3db_up_to_hz == pytest.approx(roots[2], rel=REL)
    assert band.in_notch and band.notch[0] == pytest.approx(FN, rel=0.01)
    depth = 10 * np.log10(minimize_scalar(lambda f: gain2(f, 0.02), bounds=(30, 50), method="bounded").fun)
    assert band.notch[1] == pytest.approx(depth, abs=0.01)
    assert "lies in a notch" in band.note
    assert "should it rise" not in band.note           # 5.7 dB below: far from the level


def test_notch_crossing_the_level_is_the_only_jump_and_is_stated():
    """Sweep z_z through the depth at which the notch's minimum touches -3 dB (found here from
    |H|^2): the within-3-dB reading moves continuously (by no more than the analytic last
    crossing does), the first crossing equals the last crossing above that depth and the
    notch's falling flank below it -- one jump, where the minimum crosses -3 dB -- and within
    NOTCH_MARGIN_DB of it the output names the notch and the jump."""
    def depth(zz):
        return 10 * np.log10(minimize_scalar(lambda f: gain2(f, zz), bounds=(30, 50), method="bounded").fun)

    z_star = brentq(lambda zz: depth(zz) - LEVEL_DB, 0.02, 0.06, xtol=1e-12)
    zs = np.linspace(0.03, 0.045, 31)
    bands = [passband(F, response(zz), reference=1.0) for zz in zs]
    for zz, b in zip(zs, bands):
        roots = crossings(lambda f: gain2(f, zz))
        assert b.within_3db_up_to_hz == pytest.approx(roots[-1], rel=REL)
        assert b.first_crossing_hz == pytest.approx(roots[0], rel=REL)
        assert b.in_notch == (zz < z_star)
        if abs(depth(zz) - LEVEL_DB) <= NOTCH_MARGIN_DB:
            assert "should it" in b.note or "should one" in b.note, (zz, b.note)
        else:
            assert "should" not in b.note, (zz, b.note)
    first = np.array([b.first_crossing_hz for b in bands])
    within = np.array([b.within_3db_up_to_hz for b in bands])
    jumps = np.flatnonzero(np.abs(np.diff(first)) > 1.0)        # [Hz]
    assert len(jumps) == 1 and zs[jumps[0]] < z_star < zs[jumps[0] + 1]
    assert np.max(np.abs(np.diff(within))) < 0.1                # [Hz]: continuous


def test_peak_beyond_the_band_crossing_the_level():
    """A resonant peak at 200 Hz beyond the lag's corner (no notch: z_z = z_p): while it stays below -3 dB the band
    ends at the corner and the note names the peak when it is within NOTCH_MARGIN_DB; once it
    rises above, the within-3-dB reading jumps past it and the first crossing -- the corner's
    -- becomes a crossing into a notch (the dip between corner and peak)."""
    def peak(za):
        return 10 * np.log10(-minimize_scalar(lambda f: -gain2(f, ZP, 200.0, za), bounds=(150, 250),
                                              method="bounded").fun)

    za_star = brentq(lambda za: peak(za) - LEVEL_DB, 0.06, 0.5, xtol=1e-12)
    below, above = 0.97 * za_star, 1.03 * za_star
    assert LEVEL_DB - NOTCH_MARGIN_DB < peak(below) < LEVEL_DB < peak(above)
    b = passband(F, response(ZP, 200.0, below), reference=1.0)
    roots = crossings(lambda f: gain2(f, ZP, 200.0, below))
    assert len(roots) == 1 and b.within_3db_up_to_hz == pytest.approx(roots[0], rel=REL)
    assert not b.in_notch and "peak" in b.note and "jumps up past it" in b.note
    b = passband(F, response(ZP, 200.0, above), reference=1.0)
    roots = crossings(lambda f: gain2(f, ZP, 200.0, above))
    assert len(roots) == 3 and roots[1] < 200.0 < roots[2]
    assert b.first_crossing_hz == pytest.approx(roots[0], rel=REL)
    assert b.within_3db_up_to_hz == pytest.approx(roots[2], rel=REL)
    assert b.in_notch


def test_readings_at_the_ends_of_the_range():
    """Below -3 dB from the first frequency: no reading (bandwidth() gives f[0]); within 3 dB
    to the end: no crossing."""
    H = 1 / (1 + 2j * np.pi * F / (2 * np.pi * 0.1))
    band = passband(F, H, reference=1.0)
    assert band.first_crossing_hz is None and band.within_3db_up_to_hz is None
    assert bandwidth(F, H, reference=1.0) == F[0]
    H = 1 / (1 + 2j * np.pi * F / (2 * np.pi * 1e4))
    band = passband(F, H, reference=1.0)
    assert band.first_crossing_hz is None and band.within_3db_up_to_hz is None and not band.in_notch
    assert bandwidth(F, H, reference=1.0) is None
