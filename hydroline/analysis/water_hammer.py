"""How much of the water hammer a servovalve can put into a hose's quarter-wave mode
(docs/model.md, M25-M26).

A hose section between a manifold held at constant pressure by its accumulator (an open end)
and a valve port whose flow changes by ``dQ`` (a flow-driven end) is a quarter-wave
resonator: its input impedance at the valve is ``Z0 tanh(s T)``, ``T = L / c`` (lossless line,
M3). A flow step that rises instantly gives the Joukowsky water hammer, a square wave of
amplitude ``Z0 dQ`` about the initial pressure, period ``4 T``, i.e. frequency
``f = c / (4 L)``::

    p(t) - p(0) = -Z0 dQ [1 - 2 H(t - 2T) + 2 H(t - 4T) - ...]                        (M25)

Its Fourier series holds the odd harmonics k f with amplitudes ``4 Z0 dQ / (pi k)``. A valve
flow that rises like a second-order system, ``Q(s) = dQ / s * w_v^2 / (s^2 + 2 zeta_v w_v s +
w_v^2)``, passes each harmonic through the valve's gain ``|G_v(j k w)|``, so the quarter-wave
mode (the fundamental) of the lossless line settles to the amplitude::

    A_1 = (4 / pi) Z0 dQ / sqrt((1 - r^2)^2 + (2 zeta_v r)^2),   r = f / f_v           (M26)

and the whole periodic trace swings by half the peak-to-peak of the series of all odd
harmonics (:func:`periodic_swing_fraction`). Friction and a manifold that is not quite an
open end (its resistance, the accumulator's connection) only lower both: for a lossless line
the mode is undamped, so (M26) is the largest share of ``Z0 dQ`` such a valve can put into
the mode. Short hoses (``r`` near or above 1) are bounded by the valve, not by the hose: at
the default rig's 0.7512 m section II (c = 484 m/s, f = 161 Hz, r = 1.15 with a 140 Hz,
zeta = 1 spool) ``A_1 = 0.55 Z0 dQ``, against ``1.18 Z0 dQ`` at 3.048 m (f = 39.7 Hz,
r = 0.28): the short hose's oscillation can reach at most ~47 % of the long one's.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["valve_gain", "quarter_wave_fraction", "periodic_swing_fraction", "valve_bound"]

#: Samples of one period of the periodic swing (harmonics up to half of it: beyond the
#: valve's corner, k r > 1, each falls as 1/(k r)^2, so for r >= 1e-3 the cut leaves < 1e-3
#: of Z0 dQ), [-]
_SAMPLES = 2**16


def _check(name, value, low=0.0, unit="-"):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number [{unit}], got {value!r}") from None
    if not (math.isfinite(v) and v > low):
        raise ValueError(f"{name} must be finite and > {low:g} [{unit}], got {value!r}")
    return v


def valve_gain(frequency_ratio, damping_ratio):
    """``|G_v(j w)|`` of a second-order valve with unit static gain at ``w / w_v``, [-].

    Parameters
    ----------
    frequency_ratio : float or ndarray
        Frequency over the valve's natural frequency, f / f_v, >= 0, [-].
    damping_ratio : float
        The valve's damping ratio zeta_v, > 0, [-].

    Returns
    -------
    float or ndarray
        1 / sqrt((1 - r^2)^2 + (2 zeta r)^2), [-].
    """
    r = np.asarray(frequency_ratio, dtype=float)
    z = _check("damping_ratio", damping_ratio)
    g = 1.0 / np.sqrt((1.0 - r**2) ** 2 + (2.0 * z * r) ** 2)
    return float(g) if g.ndim == 0 else g


def quarter_wave_fraction(frequency_ratio, damping_ratio) -> float:
    """Amplitude of a lossless quarter-wave hose's fundamental mode driven by the valve's flow
    step, as a fraction of the water hammer Z0 dQ (M26), [-].

    Parameters
    ----------
    frequency_ratio : float
        The hose's quarter-wave frequency c/(4L) over the valve's natural frequency, > 0, [-].
    damping_ratio : float
        The valve's damping ratio zeta_v, > 0, [-].

    Returns
    -------
    float
        ``(4/pi) |G_v(j r)|``: 4/pi for an instantaneous valve (r -> 0), falling as
        (4/pi)/r^2 far above the valve's corner, [-].
    """
    r = _check("frequency_ratio", frequency_ratio)
    return 4.0 / math.pi * valve_gain(r, damping_ratio)


def periodic_swing_fraction(frequency_ratio, damping_ratio) -> float:
    """Half the peak-to-peak swing of the lossless hose's periodic pressure at the valve (the
    square wave (M25) with each harmonic through the valve's gain and phase), as a fraction
    of Z0 dQ, [-]. 1 for an instantaneous valve (the square wave), ~ :func:`quarter_wave_fraction`
    when the valve filters the third harmonic out (r above ~0.5).

    Parameters
    ----------
    frequency_ratio : float
        The hose's quarter-wave frequency over the valve's natural frequency, >= 1e-3, [-].
    damping_ratio : float
        The valve's damping ratio zeta_v, > 0, [-].

    Returns
    -------
    float
        Half the peak-to-peak of the periodic trace over Z0 dQ, [-].
    """
    r = _check("frequency_ratio", frequency_ratio)
    if r < 1e-3:
        raise ValueError(f"frequency_ratio must be >= 0.001 [-] (a valve {1 / r:.3g} times "
                         f"faster than the hose is instantaneous: the swing is 1), got {r!r}")
    z = _check("damping_ratio", damping_ratio)
    theta = (np.arange(_SAMPLES) + 0.5) * (2 * np.pi / _SAMPLES)   # no sample on a jump
    square = np.sign(np.sin(theta))
    k = np.arange(_SAMPLES // 2 + 1, dtype=float)
    g = 1.0 / (1.0 - (k * r) ** 2 + 2j * z * k * r)                 # G_v(j k w), 1 at k = 0
    wave = np.fft.irfft(np.fft.rfft(square) * g, n=_SAMPLES)
    return float(0.5 * (wave.max() - wave.min()))


def valve_bound(length, wave_speed, impedance, flow_change, valve_frequency,
                valve_damping) -> dict:
    """The valve's bound on a section's quarter-wave oscillation (M26), with its terms.

    Parameters
    ----------
    length : float
        Section length L, > 0, [m].
    wave_speed : float
        Wave speed c of the section (M2), [m/s].
    impedance : float
        Characteristic impedance Z0 = rho c / A of the section (M3), [Pa*s/m^3].
    flow_change : float
        Change of the valve port's flow dQ (its sign ignored), [m^3/s].
    valve_frequency : float
        The valve's natural frequency f_v, [Hz].
    valve_damping : float
        The valve's damping ratio zeta_v, [-].

    Returns
    -------
    dict
        ``quarter_wave_hz`` c/(4L) [Hz], ``frequency_ratio`` f/f_v [-], ``water_hammer_pa``
        ``Z0 |dQ|`` [Pa], ``mode_fraction`` (M26) [-], ``mode_amplitude_pa`` [Pa],
        ``swing_fraction`` and ``swing_amplitude_pa`` (:func:`periodic_swing_fraction`) [-],
        [Pa].
    """
    L = _check("length", length, unit="m")
    c = _check("wave_speed", wave_speed, unit="m/s")
    z0 = _check("impedance", impedance, unit="Pa*s/m^3")
    fv = _check("valve_frequency", valve_frequency, unit="Hz")
    f = c / (4.0 * L)
    r = f / fv
    hammer = z0 * abs(float(flow_change))
    mode = quarter_wave_fraction(r, valve_damping)
    swing = periodic_swing_fraction(r, valve_damping)
    return {"quarter_wave_hz": f, "frequency_ratio": r, "water_hammer_pa": hammer,
            "mode_fraction": mode, "mode_amplitude_pa": mode * hammer,
            "swing_fraction": swing, "swing_amplitude_pa": swing * hammer}
