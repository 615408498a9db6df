"""The valve's bound on a hose's quarter-wave oscillation (M25-M26, hydroline.analysis.water_hammer)
against an ideal lossless line solved by the method of characteristics (exact for a lossless
line: one reach per time step along the characteristics), driven at its valve end by the flow
of a second-order valve and held at constant pressure at the manifold end."""
import math

import numpy as np
import pytest

from hydroline.analysis.water_hammer import (periodic_swing_fraction, quarter_wave_fraction,
                                             valve_bound, valve_gain)
from hydroline.fluid import Fluid
from hydroline.lines import Line
from hydroline.lines.characteristics import CharacteristicsLine

FLUID = Fluid(870.0, 3.2e-5, 1.5e9)


def valve_flow(dq, fv, zeta):
    """Unit-step response of w^2/(s^2 + 2 zeta w s + w^2) times dq, closed form, [m^3/s]."""
    w = 2 * np.pi * fv

    def q(t):
        t = np.clip(t, 0.0, None)
        if zeta == 1.0:
            return dq * (1 - (1 + w * t) * np.exp(-w * t))
        wd = w * np.sqrt(1 - zeta**2)
        return dq * (1 - np.exp(-zeta * w * t) * (np.cos(wd * t)
                                                  + zeta * w / wd * np.sin(wd * t)))
    return q


@pytest.mark.parametrize("length, fv, zeta", [(3.048, 140.0, 1.0), (0.7512, 140.0, 1.0),
                                              (1.524, 140.0, 1.0), (0.7512, 300.0, 0.7),
                                              (0.4, 140.0, 1.0)])
def test_bound_against_the_ideal_line(length, fv, zeta):
    """Fundamental (Fourier coefficient over whole periods, after the valve's transient) and
    half the peak-to-peak swing of the ideal line's valve-end pressure in its periodic state,
    against (M26) and the harmonic series, within 5 %."""
    line = Line(length, 13.43e-3, FLUID, 203.8e6)
    dq = 3.6e-4
    moc = CharacteristicsLine(line, n_reaches=200, friction="none")
    f = line.wave_speed / (4 * length)
    periods = 12
    t_settle = 12.0 / (zeta * 2 * np.pi * fv)          # the valve's transient gone (e^-12)
    n_skip = math.ceil(t_settle * f)
    res = moc.simulate((n_skip + periods) / f, upstream_pressure=0.0,
                       downstream_flow=valve_flow(dq, fv, zeta))
    w = res.t >= n_skip / f
    t, p = res.t[w], res.downstream_pressure[w]
    # fundamental by projection on whole periods (the samples are uniform)
    t, p = t[: int(periods / f / moc.dt)], p[: int(periods / f / moc.dt)]
    a1 = 2 * abs(np.mean(p * np.exp(-2j * np.pi * f * t)))
    b = valve_bound(length, line.wave_speed, line.impedance, dq, fv, zeta)
    assert b["quarter_wave_hz"] == pytest.approx(f)
    assert a1 == pytest.approx(b["mode_amplitude_pa"], rel=0.05)
    assert 0.5 * np.ptp(p) == pytest.approx(b["swing_amplitude_pa"], rel=0.05)


def test_limits_by_hand():
    """An instantaneous valve: the square wave of amplitude Z0 dQ, fundamental 4/pi; at the
    valve's natural frequency with zeta = 1 the gain is 1/2; far above it falls as 1/r^2."""
    assert quarter_wave_fraction(1e-6, 1.0) == pytest.approx(4 / np.pi)
    assert periodic_swing_fraction(1e-3, 1.0) == pytest.approx(1.0, rel=0.02)
    assert valve_gain(1.0, 1.0) == pytest.approx(0.5)
    assert quarter_wave_fraction(100.0, 1.0) == pytest.approx(4 / np.pi / 1e4, rel=1e-3)
    # the default rig's 0.7512 m and 3.048 m supply sections II (c = 484 m/s, 140 Hz spool)
    r_short, r_long = 484.0 / (4 * 0.7512) / 140.0, 484.0 / (4 * 3.048) / 140.0
    assert quarter_wave_fraction(r_short, 1.0) == pytest.approx(0.548, abs=0.005)
    assert quarter_wave_fraction(r_long, 1.0) == pytest.approx(1.178, abs=0.005)


def test_bad_input_names_the_parameter():
    with pytest.raises(ValueError, match=r"length .*\[m\]"):
        valve_bound(0.0, 484.0, 3e9, 3.6e-4, 140.0, 1.0)
    with pytest.raises(ValueError, match=r"damping_ratio"):
        quarter_wave_fraction(1.0, -1.0)
