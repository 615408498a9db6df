"""Metrics of a step response: oscillation frequency, overshoot amplitude, settling time.

All three take a trace ``p(t)`` (any unit: pressure, position, flow) sampled at increasing,
possibly nonuniform times ``t`` [s], and the time ``t_step`` [s] at which the input stepped.

Levels
------
*Initial value* ``p0``: the trace at ``t_step`` (linear interpolation between samples).

*Final value* ``p_final``: the time average of the trace over the last 20 % of the interval
``[t_step, t[-1]]`` (trapezoidal rule on the piecewise-linear trace, so nonuniform samples
are weighted by the time they cover). The trace must be long enough for the response to have
settled there; a residual oscillation of amplitude ``a`` in that window moves ``p_final`` by
at most about ``a / (pi * cycles in the window)``.

*Net change*: the trace counts as returning to where it started when
``|p_final - p0| <= 3 * std(tail) + 1e-12 * max|p|``, where ``std(tail)`` is the time-weighted
standard deviation over the same last 20 % (a noise level: the direction of a change smaller
than the residual wiggle of the tail is not defined).

Oscillation frequency (docs/model.md section 8)
-----------------------------------------------
Picking the highest peak of a trace finds a harmonic when the trace has one, and counting
zero crossings about a constant finds extra crossings where a strong harmonic wiggles
through zero and skewed ones where the trace drifts. :func:`oscillation_frequency` therefore
proceeds as follows, all on ``[t_step, t[-1]]`` resampled onto uniform grids by linear
interpolation (so nonuniform solver output is fine):

1. *Coarse estimate.* Amplitude spectrum of the deviation ``p - p_final`` (zero-padded 8x,
   half-cosine taper over the last 20 % so that a trace ending off its final value does not
   ring across the spectrum). Its highest genuine local maximum (prominence >= 2 % of the
   highest value in range) between ``min_cycles / duration`` and a quarter of the sampling
   rate is the dominant peak, if it stands at least 10 times above the spectrum's median in
   that range (the largest of many bins of noise stands about 6 times above it). A
   monotone response has no such maximum: None. Where the candidates of steps 2-4 all
   fail, the dominant peak of the spectrum of the rate of change (sample differences, same
   taper and test) is tried last: a ringing short or small beside a large slow drift (a
   short hose's, after a valve step) stands out there. Where the deviation's spectrum has
   no genuine peak at all (a drift's spectrum falls from 0 Hz on), every further genuine
   peak of the rate's spectrum that stands 10 times above its median follows, highest
   first: a drift that bends has sidelobes there as high as a short ringing's peak, and
   which of near-equal peaks is the highest must not decide whether the ringing is seen.
   Such a further peak must keep its refinement in step 3 (no fallback to the peak as it
   is): it is weaker evidence than the dominant one.
2. *Harmonic check.* If the spectrum also has a genuine peak within 8 % of ``1/k`` of the
   dominant frequency (k = 2..5) at least 10 % as high, that lower peak is the first
   candidate for the fundamental (the largest such k first); the dominant peak is the last
   candidate. Steps 3 and 4 take the candidates in turn; the first that passes both wins.
3. *Complex demodulation.* Multiply the deviation by ``exp(-2 pi i f t)`` and average it
   twice over exactly one period. That filter has zeros at every multiple of ``f``: it
   removes the final value, every harmonic and nearly all of a slow drift, and it passes the
   damped fundamental ``exp((-sigma + i Delta) t)`` with its phase slope ``Delta`` unchanged
   (a linear filter multiplies an exponential by a constant). The amplitude-weighted slope
   of the unwrapped phase corrects ``f``; three passes, over the stretch around the
   envelope's peak where it stays above 5 % of it (a later, weaker component beyond a null
   of the envelope is another oscillation). The trace must span two periods, and the RMS of
   the phase about that line, weighted by the envelope squared (the oscillation's energy),
   must stay below 0.5 rad (a coherent oscillation, not noise; two modes beating near one
   frequency wander by about 0.3 rad). Where the refinement wanders off by more than 50 %
   (a burst of a few periods right after the step, which the demodulation sees only from
   one period on), the spectral peak's frequency is checked as it is.
4. *Oscillating or not.* The envelope of the fundamental (the demodulated amplitude divided
   by the filter's gain for the fitted decay rate) must lie above 1 % of the largest
   deviation ``max|p - p_final|`` for at least ``min_cycles`` periods after ``t_step``
   (the demodulation's first period counted, then the time it lies above, the threshold
   softened over one neper about it: an instant counts ``clip(ln(envelope / 1 %) + 1/2,
   0, 1)`` of itself, the envelope log-linear between its points. For an envelope that
   decays exponentially through 0.6-1.6 % this is the time to its crossing of 1 %
   exactly; where the envelope lingers near 1 % (a burst's later lobe whose top passes
   it), a change of the envelope by a factor ``1 + eps`` moves the count by at most
   ``eps`` times the periods it spends in that band, where a hard threshold's count
   jumps by all of them: :func:`_time_above`).
   For the step response of a second-order system this reports damping ratios up to
   about 0.46 with the default ``min_cycles = 1.5`` (ratio 0.45: 1.5 cycles of overshoot and
   undershoot above 1 %). No candidate passing: None. The verdict is a threshold: a ringing
   that dies within a few periods is near it, and :func:`pressure_metrics` fades its
   amplitude linearly to 0 there (from :data:`VERDICT_MARGIN` periods down to 1.5), so that
   the amplitude does not jump at the verdict.
5. *Zero crossings.* The mean interval between crossings in the same direction, over all
   crossings whose lobes reach 0.1 % of the largest, is the period; for a damped sinusoid
   about a constant it is exactly ``1 / f_d = 2 pi / omega_d``. Crossings of, in turn,
   (a) the deviation minus its centred one-period moving average (which keeps a damped
   fundamental exactly and removes the final value and drift), further averaged over 1/2,
   1/3, 1/4 and 1/5 of a period (nulling harmonics 2..6, 8, 9, 10; costs about one period
   at each end); (b) the same without the harmonic averaging (costs half a period at each
   end); (c) the raw deviation ``p - p_final``, for records too short for (a) and (b). The
   first whose crossings are regular (every same-direction interval within 15 % of the
   period of step 3) and agree with step 3 within 5 % gives the result; if none does, the
   demodulated frequency of step 3 stands.

On synthetic damped sinusoids with strong 2nd or 3rd harmonics, slow exponential drift or
1 % noise the result is within 0.1 % of the fundamental (``tests/test_metrics.py``).
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from .peaks import find_peaks, local_maxima, peak_prominence   # scipy.signal's, in NumPy

__all__ = ["oscillation_frequency", "oscillation_amplitude", "oscillation_baseline", "overshoot",
           "first_excursion", "peak_to_peak", "settling_time", "port_settling", "pressure_metrics",
           "SettlingBand", "SETTLING_BAND", "AMPLITUDE_MIN_PERIODS", "VERDICT_MARGIN",
           "VERDICT_PERIODS", "ringing_weight"]

#: Fraction of the post-step interval, at its end, that defines the final value.
TAIL_FRACTION = 0.2
#: Fraction of the post-step interval, at its end, in which a settled trace may not leave
#: its band (:func:`settling_time`).
SETTLED_FRACTION = 0.05
#: The fundamental counts as oscillating while its amplitude exceeds this fraction of the
#: largest deviation from the final value (:func:`oscillation_frequency`).
OSCILLATION_THRESHOLD = 0.01

_SAMPLES_PER_PERIOD = 64    # uniform grid used for the demodulation, per period of f
_MAX_GRID = 2 ** 21         # largest uniform grid, [samples]
_MIN_GRID = 4096            # smallest uniform grid for the spectrum, [samples]
_MAX_SPECTRUM_GRID = 2 ** 18  # largest uniform grid for the spectrum, [samples]
_PEAK_PROMINENCE = 0.02     # genuine spectral peak: prominence / highest peak in range
_SUBHARMONIC_HEIGHT = 0.10  # a peak at f/k this high (relative) makes f/k the fundamental
_SUBHARMONIC_TOL = 0.08     # relative distance of that peak from f/k
_MAX_SUBHARMONIC = 5
_MAX_INCOHERENCE = 0.5      # weighted RMS phase wander of a coherent fundamental, [rad]
_ABOVE_NOISE = 10.0         # a dominant spectral peak: this many times the median in range
_STRONG = 0.05              # the fundamental is fitted where its envelope is this much of its peak
_CROSSING_GRID = 120        # samples per period for the crossings (divisible by 2..5)
_DIRECT_AVERAGE = 16384     # moving averages costing more taps x samples: by running sums


# --------------------------------------------------------------------------- validation

def _validate(t, p, t_step):
    """Check a trace and return ``(t, p, t_step)`` as float arrays and a float."""
    try:
        t = np.asarray(t, dtype=float)
    except (TypeError, ValueError):
        raise ValueError("t must be a 1-D array of times [s]") from None
    try:
        p = np.asarray(p, dtype=float)
    except (TypeError, ValueError):
        raise ValueError("p must be a 1-D array of values") from None
    if t.ndim != 1:
        raise ValueError(f"t must be a 1-D array of times [s], got shape {t.shape}")
    if p.ndim != 1:
        raise ValueError(f"p must be a 1-D array of values, got shape {p.shape}")
    if t.size != p.size:
        raise ValueError(f"t and p must have the same length, got {t.size} and {p.size}")
    if not np.isfinite(t).all():
        raise ValueError("t must be finite (no NaN or inf) [s]")
    if not np.isfinite(p).all():
        raise ValueError("p must be finite (no NaN or inf)")
    if t.size >= 2 and not (t[1:] > t[:-1]).all():
        raise ValueError("t must be strictly increasing [s]")
    try:
        t_step = float(t_step)
    except (TypeError, ValueError):
        raise ValueError(f"t_step must be a number [s], got {t_step!r}") from None
    if not math.isfinite(t_step):
        raise ValueError(f"t_step must be finite [s], got {t_step!r}")
    if t.size == 0 or not t[0] <= t_step < t[-1]:
        span = f"[{t[0]:g}, {t[-1]:g})" if t.size else "(empty t)"
        raise ValueError(f"t_step = {t_step:g} s must lie in the time span of t {span} [s]")
    if np.count_nonzero(t > t_step) < 3:
        raise ValueError("t must hold at least 3 samples after t_step")
    return t, p, t_step


def _post_step(t, p, t_step):
    """Samples on ``[t_step, t[-1]]``, the first one interpolated at ``t_step``."""
    after = t > t_step
    ts = np.concatenate(([t_step], t[after]))
    ps = np.concatenate(([np.interp(t_step, t, p)], p[after]))
    return ts, ps


def _window_moments(ts, ps, t_from):
    """Time-weighted mean and standard deviation of the piecewise-linear trace on
    ``[t_from, ts[-1]]``."""
    i = int(np.searchsorted(ts, t_from, side="right"))     # ts > t_from from i on
    tw = np.concatenate(([t_from], ts[i:]))
    pw = np.concatenate(([np.interp(t_from, ts, ps)], ps[i:]))
    h = tw[1:] - tw[:-1]     # (np.diff's operation, without its overhead; so below)
    a, b = pw[:-1], pw[1:]
    span = tw[-1] - tw[0]
    mean = float((h * (a + b) / 2).sum() / span)
    # exact integral of the square of a linear segment: h (a^2 + a b + b^2) / 3
    a, b = a - mean, b - mean
    var = float((h * (a * a + a * b + b * b) / 3).sum() / span)
    return mean, math.sqrt(max(var, 0.0))


def _levels(t, p, t_step):
    """Post-step samples, initial and final value, and whether the net change is nonzero."""
    ts, ps = _post_step(t, p, t_step)
    p0 = float(ps[0])
    duration = ts[-1] - ts[0]
    p_final, tail_std = _window_moments(ts, ps, ts[-1] - TAIL_FRACTION * duration)
    scale = float(np.abs(ps).max())
    changed = abs(p_final - p0) > 3.0 * tail_std + 1e-12 * scale
    return ts, ps, p0, p_final, changed


def _line_fit(x, y, w=None):
    """Slope and offset of the least-squares line ``y ~ slope x + offset``, the residuals
    weighted by ``w`` (as ``np.polyfit(x, y, 1, w=w)``, in closed form about the weighted
    mean of x: a metric fits several lines per trace, and polyfit's general solver cost
    ~0.1 ms each)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    ww = np.ones_like(x) if w is None else np.asarray(w, dtype=float) ** 2
    total = float(ww.sum())
    xm = float(np.dot(ww, x)) / total
    ym = float(np.dot(ww, y)) / total
    dx = x - xm
    slope = float(np.dot(ww * dx, y - ym)) / float(np.dot(ww * dx, dx))
    return slope, ym - slope * xm


# --------------------------------------------------------------------------- amplitude

def _refined_max(ts, y):
    """Largest value of the samples ``y(ts)``, refined by the vertex of the parabola through
    the largest sample and its neighbours (so that a coarse grid does not clip the peak)."""
    k = int(np.argmax(y))
    best = float(y[k])
    if 0 < k < len(y) - 1:
        # the parabola c2 x^2 + c1 x + c0 through the three samples, x from ts[k]
        h0, h2 = float(ts[k] - ts[k - 1]), float(ts[k + 1] - ts[k])
        d0, d2 = float(y[k - 1]) - best, float(y[k + 1]) - best
        c2 = (d0 * h2 + d2 * h0) / (h0 * h2 * (h0 + h2))
        c1 = (d2 - c2 * h2 * h2) / h2
        if c2 < 0:
            xv = -c1 / (2 * c2)
            if -h0 <= xv <= h2:
                best = max(best, best - c1 * c1 / (4 * c2))
    return best


def overshoot(t, p, t_step):
    """Largest excursion of a step response beyond its final value (one-sided overshoot).

    The classical overshoot of a settled step response. It is *not* the amplitude of a pressure
    oscillation whose mean still drifts: which side counts flips when the final value moves
    across the oscillation (use :func:`oscillation_amplitude` for that).

    With ``p0`` the value at ``t_step`` and ``p_final`` the final value (module docstring):

    * rising response (``p0 < p_final``): ``max(p - p_final)`` over ``t >= t_step``;
    * falling response (``p0 > p_final``): ``max(p_final - p)`` over ``t >= t_step``;
    * no net change (``p_final == p0`` within the tail's noise): ``max|p - p_final|``.

    A response that never passes its final value has amplitude 0. The maximum is refined by
    a parabola through the largest sample and its neighbours.

    Parameters
    ----------
    t : array_like
        Sample times, strictly increasing, possibly nonuniform, [s]
    p : array_like
        Response at ``t``, [any unit]
    t_step : float
        Time of the input step, ``t[0] <= t_step < t[-1]``, [s]

    Returns
    -------
    float
        Overshoot beyond the final value, >= 0, [unit of p]. Divide by
        ``|p_final - p0|`` for the relative overshoot of a second-order system,
        ``exp(-zeta pi / sqrt(1 - zeta^2))``.

    Raises
    ------
    ValueError
        On arrays of different lengths, non-finite values, ``t`` not strictly
        increasing, or ``t_step`` outside ``t``.
    """
    t, p, t_step = _validate(t, p, t_step)
    ts, ps, p0, p_final, changed = _levels(t, p, t_step)
    if not changed:
        deviation = np.abs(ps - p_final)
    elif p0 < p_final:
        deviation = ps - p_final
    else:
        deviation = p_final - ps
    return max(0.0, _refined_max(ts, deviation))


# --------------------------------------------------------------------------- settling

def settling_time(t, p, t_step, band=0.02):
    """Time after the step from which the response stays within a band about its final value.

    The band is ``+-band * |p_final - p0|`` about the final value ``p_final`` (module
    docstring). A response with no net change (``p_final == p0`` within the tail's noise, e.g.
    a disturbance that dies away) uses ``+-band * max|p - p_final|`` instead, the largest
    deviation after ``t_step``; a trace that is constant after ``t_step`` has settled at once
    (0.0). The instant the trace last enters the band is interpolated linearly between
    samples.

    Parameters
    ----------
    t : array_like
        Sample times, strictly increasing, possibly nonuniform, [s]
    p : array_like
        Response at ``t``, [any unit]
    t_step : float
        Time of the input step, ``t[0] <= t_step < t[-1]``, [s]
    band : float
        Half-width of the band relative to the net change, [-]
        (0 < band < 1; 0.02 is the usual 2 % settling time)

    Returns
    -------
    float or None
        Settling time measured from ``t_step``, [s]; None when the trace has not
        been seen to settle: it is still outside the band during the last 5 % of
        the interval ``[t_step, t[-1]]``.

    Raises
    ------
    ValueError
        On invalid ``t``, ``p``, ``t_step`` (see :func:`overshoot`) or
        ``band`` outside (0, 1).

    Notes
    -----
    For a first-order response ``1 - exp(-t / tau)`` the 2 % settling time is
    ``tau ln(50) = 3.912 tau``.
    """
    t, p, t_step = _validate(t, p, t_step)
    try:
        band = float(band)
    except (TypeError, ValueError):
        raise ValueError(f"band must be a number in (0, 1) [-], got {band!r}") from None
    if not 0.0 < band < 1.0:
        raise ValueError(f"band must lie in (0, 1) [-], got {band!r}")
    return _settling_time(_levels(t, p, t_step), t_step, band)


def _settling_time(levels, t_step, band):
    """:func:`settling_time` from a checked trace's :func:`_levels`."""
    ts, ps, p0, p_final, changed = levels
    error = ps - p_final
    reference = abs(p_final - p0) if changed else float(np.max(np.abs(error)))
    if reference == 0.0:
        return 0.0
    entered = _band_exit(ts, error, band * reference)
    if entered is None or entered > ts[-1] - SETTLED_FRACTION * (ts[-1] - t_step):
        return None
    return float(entered - t_step)


# --------------------------------------------------------------------------- frequency

def _spectral_candidates(ts, ps, p_final, min_cycles):
    """Coarse fundamental frequencies from the spectrum of the deviation, best first, as
    ``(frequency [Hz], further)`` (a generator: the second spectrum is taken only when the
    first's candidates are used up); ``further`` marks the rate spectrum's peaks after its
    dominant one.

    The subharmonics of the dominant peak that pass the harmonic check (largest k first),
    then the dominant peak itself; then the dominant peak of the spectrum of the rate of
    change (the deviation's sample differences), where it is another frequency: a short
    ringing beside a large slow drift stands out there. Where the deviation's spectrum has
    no candidate at all (a drift whose spectrum falls from 0 Hz on and hides everything),
    every genuine peak of the rate's spectrum that stands 10 times above its median follows
    the dominant one, highest first: the sidelobes of the drift's bends stand there about as
    high as a short ringing's peak, and which of several near-equal peaks is the highest
    must not decide whether the ringing is tried. (Beside a deviation peak that fails, a slow
    waveform cut short by the window or dying fast, the rate's further peaks are that
    waveform's harmonics, which would pass for it.) A further peak must hold its own
    under the demodulation (:func:`_oscillating_fundamental` with ``refined``): a kink in
    a drift has such peaks too. Empty when neither spectrum has a genuine peak in range
    that stands 10 times above its median.

    The genuine peaks are the local maxima in range with a prominence of at least
    :data:`_PEAK_PROMINENCE` of the highest value in range (as
    ``scipy.signal.find_peaks(spectrum, prominence=...)`` restricted to the range). A
    prominence costs a pass over the spectrum, so it is taken only where it decides something:
    the highest maxima in turn until one is genuine (the dominant peak), and near each
    ``f / k`` the highest maxima down to 10 % of the dominant one.
    """
    duration = ts[-1] - ts[0]
    n = int(min(_MAX_SPECTRUM_GRID, max(_MIN_GRID, 2 * len(ts))))
    grid = _linspace(float(ts[0]), float(ts[-1]), n)
    dt = grid[1] - grid[0]
    deviation = np.interp(grid, ts, ps)
    deviation -= p_final
    # the rate of change, per sample (before the taper): a ringing that is short or small
    # beside a slow drift (a short hose's, after a valve step) stands out in its spectrum
    rate = deviation[1:] - deviation[:-1]
    # half-cosine taper over the tail (where the response has settled), so that a trace
    # ending off its final value does not ring across the spectrum; the start is kept
    # whole, since the step is where the oscillation is largest
    m = max(2, int(TAIL_FRACTION * n))
    deviation[n - m:] *= _taper(m)
    nfft = 1 << int(math.ceil(math.log2(8 * n)))
    spectrum = np.abs(_rfft(deviation, nfft))
    # the bins' frequencies (np.fft.rfftfreq(nfft, dt)) up to two bins above a quarter of the
    # sampling rate, the highest searched: the rest would never be looked at
    df = 1.0 / (nfft * dt)
    freq = np.arange(min(spectrum.size, int(0.25 / dt / df) + 3), dtype=float)
    freq *= df
    # the range is one run of bins: freq >= min_cycles / duration and freq <= 0.25 / dt
    lo = int(np.searchsorted(freq, min_cycles / duration, side="left"))
    hi = int(np.searchsorted(freq, 0.25 / dt, side="right")) - 1
    if hi < lo:
        return
    candidates = _peak_candidates(spectrum, freq, lo, hi)
    for f in candidates:
        yield f, False
    # (the rate's spectrum only where the caller asks for more: most traces do not)
    rate[rate.size - m:] *= _taper(m)
    rates = _peak_candidates(np.abs(_rfft(rate, nfft)), freq, lo, hi, subharmonics=False,
                             every=not candidates)
    for i, f in enumerate(rates):
        if all(abs(f / g - 1.0) > _SUBHARMONIC_TOL for g in candidates):
            yield f, i > 0


def _peak_candidates(spectrum, freq, lo, hi, subharmonics=True, every=False):
    """:func:`_spectral_candidates` of one amplitude spectrum ``spectrum`` at frequencies
    ``freq`` [Hz], searched within bins ``lo .. hi``: the subharmonics of its dominant peak
    that pass the harmonic check (largest k first; none where ``subharmonics`` is False),
    then the dominant peak, then (where ``every`` is True) every other genuine peak that
    stands 10 times above the median, highest first; empty when it has no genuine peak in
    range."""
    highest = float(spectrum[lo:hi + 1].max())
    if highest <= 0.0:
        return []
    peaks = _maxima_between(spectrum, lo, hi)
    if peaks.size == 0:
        return []
    threshold = _PEAK_PROMINENCE * highest
    floor = float(spectrum.min())     # no peak's prominence exceeds its height above this
    order = peaks[np.argsort(-spectrum[peaks], kind="stable")]   # highest first; ties: lowest f
    known = {}

    def genuine(k):
        if k not in known:
            known[k] = peak_prominence(spectrum, k) >= threshold
        return known[k]

    def best(among, least):
        """The highest genuine peak of ``among`` (highest first) at least ``least`` high."""
        for k in among:
            if spectrum[k] < least or spectrum[k] - floor < threshold:
                return None
            if genuine(int(k)):
                return int(k)
        return None

    main = best(order, -np.inf)
    # a peak of noise stands a few times above the spectrum's median (the largest of N
    # Rayleigh-distributed bins: about sqrt(2 ln N) / 0.83, ~6 for 1e5 bins); a ringing's
    # stands far above it (every 8th bin: the 8x zero padding makes neighbours alike)
    noise = _ABOVE_NOISE * _median(spectrum[lo:hi + 1:8])
    if main is None or spectrum[main] < noise:
        return []
    f_main, h_main = float(freq[main]), spectrum[main]
    candidates = [f_main]
    if every:
        # the genuine peaks below the dominant one, down to the noise criterion
        for k in order[int(np.flatnonzero(order == main)[0]) + 1:]:
            if spectrum[k] < noise or spectrum[k] - floor < threshold:
                break
            if genuine(int(k)):
                candidates.append(float(freq[k]))
    for k in range(2, _MAX_SUBHARMONIC + 1 if subharmonics else 2):
        near = order[np.abs(freq[order] - f_main / k) <= _SUBHARMONIC_TOL * f_main / k]
        sub = best(near, _SUBHARMONIC_HEIGHT * h_main)
        if sub is not None:
            candidates.insert(0, float(freq[sub]))
    return candidates


def _median(x):
    """``np.median(x)`` of a non-empty 1-D float array without NaN: the same number (the
    middle order statistic, or the mean of the two middle ones) without its generality's
    overhead (~30 us a spectrum)."""
    k = x.size // 2
    if x.size % 2:
        return float(np.partition(x, k)[k])
    part = np.partition(x, (k - 1, k))
    return float((part[k - 1] + part[k]) / 2)


def _linspace(start, stop, n):
    """``np.linspace(start, stop, n)`` for n >= 2 and start < stop: its operations without
    its generality's overhead (the same numbers)."""
    step = (stop - start) / (n - 1)
    if step == 0:
        return np.linspace(start, stop, n)
    y = np.arange(0, n, dtype=float)
    y *= step
    y += start
    y[-1] = stop
    return y


def _maxima_between(x, lo, hi):
    """Indices of the local maxima of ``x`` (:func:`local_maxima`) within ``[lo, hi]``, found
    on that stretch and its two neighbours (the whole of ``x`` where a flat top crosses its
    ends)."""
    n = x.size
    if (lo > 0 and x[lo - 1] == x[lo]) or (hi + 1 < n and x[hi] == x[hi + 1]):
        peaks = local_maxima(x)
        return peaks[(peaks >= lo) & (peaks <= hi)]
    a = max(lo - 1, 0)
    return local_maxima(x[a:hi + 2]) + a


_TAPERS: dict = {}


def _taper(m):
    """The half-cosine taper ``(1 + cos(pi k / (m - 1))) / 2``, k = 0 .. m - 1 (kept by m)."""
    w = _TAPERS.get(m)
    if w is None:
        if len(_TAPERS) > 64:
            _TAPERS.clear()
        w = _TAPERS[m] = 0.5 * (1.0 + np.cos(np.pi * np.arange(m) / (m - 1)))
    return w


def _rfft(x, n):
    """``numpy.fft.rfft(x, n)``, by ``scipy.fft`` where that is loaded already (2.7x faster
    on the 8x zero-padded spectra here, the same pocketfft algorithm; its import costs
    0.3 s, which a single run does not pay: a sweep's workers load it)."""
    fft = sys.modules.get("scipy.fft")
    return fft.rfft(x, n) if fft is not None else np.fft.rfft(x, n)


def _box_average(z, length):
    """Moving average of ``z`` over ``length`` samples (``np.convolve(z, box, "valid")``;
    by running sums where that convolution would cost more than :data:`_DIRECT_AVERAGE`
    taps x samples, equal to round-off)."""
    if length * z.size <= _DIRECT_AVERAGE:
        return np.convolve(z, np.full(length, 1.0 / length), mode="valid")
    out = _window_sums(z, length)
    out /= length
    return out


def _window_sums(z, length):
    """Sums of ``z`` over every run of ``length`` consecutive samples (``z.size - length + 1``
    of them), by differences of one cumulative sum."""
    c = np.empty(z.size + 1, dtype=z.dtype)
    c[0] = 0.0
    np.cumsum(z, out=c[1:])
    return c[length:] - c[:c.size - length]


def _demodulate(ts, ps, p_final, frequency):
    """Complex envelope of the component of the trace at ``frequency``.

    Returns centre times [s], the complex envelope, and the smoothing length [s]. The
    envelope is the deviation times ``exp(-2 pi i f t)``, averaged twice over one period.
    """
    period = 1.0 / frequency
    duration = ts[-1] - ts[0]
    per_period = min(_SAMPLES_PER_PERIOD, max(8, int(_MAX_GRID * period / duration)))
    dt = period / per_period
    n = int(duration / dt) + 1
    grid = ts[0] + dt * np.arange(n)
    deviation = np.interp(grid, ts, ps) - p_final
    z = deviation * np.exp(-2j * np.pi * frequency * (grid - ts[0]))
    z = _box_average(_box_average(z, per_period), per_period)
    centres = grid[0] + dt * (np.arange(z.size) + (per_period - 1))
    return centres, z, per_period * dt


def _unwrap(phase):
    """``np.unwrap(phase)`` of a 1-D array of angles [rad] (the same operations, without
    its generality's overhead)."""
    dd = phase[1:] - phase[:-1]
    if not (np.abs(dd) >= np.pi).any():     # nothing to correct: np.unwrap adds zeros
        return phase.copy()
    ddmod = np.mod(dd + np.pi, 2 * np.pi) - np.pi
    ddmod[(ddmod == -np.pi) & (dd > 0)] = np.pi
    correct = ddmod - dd
    correct[np.abs(dd) < np.pi] = 0.0
    out = phase.copy()
    out[1:] += np.cumsum(correct)
    return out


def _fit_fundamental(ts, ps, p_final, frequency, passes=3):
    """Refine ``frequency`` [Hz] from the phase slope of the demodulated fundamental.

    Returns ``(frequency [Hz], centre times [s], envelope of the fundamental [unit of p],
    weighted RMS phase residual [rad])`` of the last pass, or None where the trace is too
    short for the demodulation (under two periods) or holds nothing at ``frequency``.
    ``passes`` = 0: one pass at ``frequency``, which is returned unchanged.
    """
    for _ in range(max(passes, 1)):
        if frequency <= 0 or 2.0 / frequency >= ts[-1] - ts[0]:
            return None
        centres, z, width = _demodulate(ts, ps, p_final, frequency)
        if z.size < 4:
            return None
        magnitude = np.abs(z)
        peak = float(magnitude.max())
        if peak == 0.0:
            return None
        # the stretch around the strongest point where the component stays above 5 % of
        # it (a later, weaker component near this frequency, beyond a null of the
        # envelope, is not this oscillation)
        top = int(np.argmax(magnitude))
        weak = np.flatnonzero(magnitude < _STRONG * peak)
        # (weak ascends and never holds top: the weak points on either side by one search)
        i = int(np.searchsorted(weak, top))
        span = slice(int(weak[i - 1]) + 1 if i > 0 else 0,
                     int(weak[i]) if i < weak.size else magnitude.size)
        tc, zc, mc = centres[span], z[span], magnitude[span]
        if tc.size < 4:
            return None
        phase = _unwrap(np.angle(zc))
        weights = mc / peak
        x = tc - tc[0]
        slope, offset = _line_fit(x, phase, weights)
        if passes:
            frequency = frequency + slope / (2 * np.pi)
    # the last pass's phase residual (the earlier passes' are not used)
    # weighted as the fit itself (by the envelope squared: the oscillation's energy), so that
    # a weak later component near this frequency does not count as the oscillation wandering
    residual = phase - (offset + slope * x)
    energy = weights * weights
    incoherence = math.sqrt(float((energy * residual ** 2).sum() / energy.sum()))
    # decay rate from the log envelope, to undo the smoothing's gain on a decaying signal
    growth = _line_fit(x, np.log(mc), weights)[0]
    sigma = max(0.0, -growth)
    x = sigma * width / 2
    gain = (math.sinh(x) / x) ** 2 if x > 1e-8 else 1.0
    return frequency, centres, 2.0 * np.abs(z) / gain, incoherence


def _centred_average(y, length):
    """Centred moving average over ``length`` samples (trapezoidal rule, ``length + 1``
    taps); returns the average and the number of samples lost at each end."""
    if length * y.size <= _DIRECT_AVERAGE:
        kernel = np.full(length + 1, 1.0 / length)
        kernel[0] = kernel[-1] = 0.5 / length
        return np.convolve(y, kernel, mode="valid"), length // 2
    # longer: by running sums (a convolution with a period's taps cost ~0.05 ms per
    # trace), of the deviation from the first sample so that they stay small: equal to the
    # convolution to round-off (1e-13 of the swing on a 1000-sample trace)
    ref = y[0]
    d = y - ref
    total = _window_sums(d, length + 1)
    total -= 0.5 * (d[:d.size - length] + d[length:])
    total /= length
    total += ref
    return total, length // 2


def _crossing_lobes(y):
    """Sign changes of ``y`` and the peak |y| of each lobe (before the first crossing, between
    crossings, after the last); None when ``y`` is zero or crosses fewer than 3 times."""
    largest = float(np.abs(y).max())
    if largest == 0.0:
        return None
    sign = np.signbit(y)
    idx = np.flatnonzero(sign[1:] != sign[:-1])
    if idx.size < 3:
        return None
    bounds = np.concatenate(([0], idx + 1, [y.size]))
    return idx, np.maximum.reduceat(np.abs(y), bounds[:-1]), largest


def _crossing_frequency(ts, ps, p_final, frequency, filtering, memo=None):
    """Frequency [Hz] from the zero crossings of the (filtered) deviation, or None.

    ``filtering`` is one of

    ``"raw"``
        the deviation ``p - p_final`` itself (docs/model.md section 8);
    ``"highpass"``
        the deviation minus its centred moving average over one period ``1/frequency``:
        this keeps a damped fundamental ``exp(s t)`` exactly (a linear filter multiplies an
        exponential by a constant), removes the final value and nearly all of a slow drift,
        leaves the harmonics untouched, and costs half a period at each end;
    ``"harmonics"``
        that, further averaged over 1/2, 1/3, 1/4 and 1/5 of a period, which nulls
        harmonics 2 to 6, 8, 9, 10, still keeps the fundamental exact, and costs about one
        period at each end.

    Crossings count where the lobes on both sides reach 0.1 % of the largest value; the
    period is the mean interval between crossings in the same direction, which cancels the
    skew that harmonics and an offset give to alternate half periods. None when fewer than
    two crossings in one direction exist, or when any same-direction interval differs from
    ``1/frequency`` by more than 15 % (extra crossings from a strong harmonic).

    ``memo`` (a dict, or None) keeps the resampled and high-passed deviation between calls
    at the same ``frequency``.
    """
    period = 1.0 / frequency
    duration = ts[-1] - ts[0]
    per_period = _CROSSING_GRID
    dt = period / per_period
    n = int(duration / dt) + 1
    if n > _MAX_GRID or n < 2 * per_period:
        return None
    memo = {} if memo is None else memo
    if "raw" not in memo:
        grid = ts[0] + dt * np.arange(n)
        memo["raw"] = (np.interp(grid, ts, ps) - p_final, grid)
    y, ty = memo["raw"]
    if filtering in ("highpass", "harmonics"):
        if "highpass" not in memo:
            trend, lost = _centred_average(y, per_period)
            memo["highpass"] = (y[lost:n - lost] - trend, ty[lost:n - lost])
        y, ty = memo["highpass"]
    if filtering == "harmonics":
        for k in (2, 3, 4, 5):
            y, lost = _centred_average(y, per_period // k)
            ty = ty[lost:ty.size - lost]
    if y.size < per_period:
        return None
    found = _crossing_lobes(y)
    if found is None:
        return None
    idx, lobe, largest = found
    significant = (lobe[:-1] >= 1e-3 * largest) & (lobe[1:] >= 1e-3 * largest)
    # the crossings kept must be consecutive from the first one on
    stop = np.flatnonzero(~significant)
    idx = idx[:stop[0]] if stop.size else idx
    if idx.size < 3:
        return None
    crossing = ty[idx] - y[idx] * dt / (y[idx + 1] - y[idx])
    rising = y[idx + 1] > y[idx]
    estimates, weights = [], []
    for direction in (rising, ~rising):
        times = crossing[direction]
        if times.size < 2:
            continue
        gaps = times[1:] - times[:-1]
        if (np.abs(gaps / period - 1.0) > 0.15).any():
            return None
        estimates.append((times.size - 1) / (times[-1] - times[0]))
        weights.append(times.size - 1)
    if not estimates:
        return None
    # np.average(estimates, weights=weights), without its overhead (the same operations)
    return float(sum(e * w for e, w in zip(estimates, weights)) / sum(weights))


def _oscillating_fundamental(ts, ps, p_final, t_step, coarse, largest, min_cycles,
                             refined=False):
    """``(frequency [Hz], periods [-])``: the demodulated frequency near ``coarse`` and for
    how many periods after ``t_step`` its envelope lies above 1 % of ``largest`` (inf: still
    at the window's end; :func:`_time_above`, the threshold softened over a neper, the
    demodulation's first period counted), if
    that is at least ``min_cycles`` (a coherent oscillation), else None. Where the refined
    frequency wanders off (more than 50 %), the spectral peak's ``coarse`` itself is
    checked: a burst of a few periods right after the step, which the demodulation sees
    only from one period on, can pull the phase slope off to a later, slower component;
    with ``refined`` (a further spectral peak, weaker evidence) that candidate fails
    instead."""
    fitted = _fit_fundamental(ts, ps, p_final, coarse)
    if fitted is not None and not (math.isfinite(fitted[0]) and fitted[0] > 0
                                   and abs(fitted[0] / coarse - 1.0) <= 0.5):
        if refined:
            return None
        fitted = _fit_fundamental(ts, ps, p_final, coarse, passes=0)
    if fitted is None:
        return None
    frequency, centres, envelope, incoherence = fitted
    if not (incoherence <= _MAX_INCOHERENCE):
        return None
    floor = OSCILLATION_THRESHOLD * largest
    above = _time_above(centres, envelope, floor)
    if not above > 0.0:
        return None
    cycles = frequency * ((centres[0] - t_step) + above)
    if cycles < min_cycles:
        return None
    # (a ringing still above the threshold at the demodulation's last point lasts as long as
    # the window does: not close to the verdict's edge)
    return float(frequency), (math.inf if envelope[-1] >= floor else float(cycles))


def _time_above(times, values, level):
    """How long the envelope ``values(times)`` lies above ``level`` [s], the threshold
    softened over one neper (a factor e) about it: each instant counts
    ``clip(ln(values / level) + 1/2, 0, 1)`` of itself (all of it above ``level e^(1/2)``,
    none below ``level e^(-1/2)``), the envelope log-linear between its points.

    For an envelope that decays exponentially through the band, ``a exp(-sigma t)``, the
    ramp's two halves balance: the result is the time to the crossing of ``level`` itself,
    ``ln(a / level) / sigma``, as a hard threshold gives (the ring count's closed form holds).
    Where the envelope lingers near the level (a later lobe whose top passes it, a burst's
    tail that flattens there), a hard threshold's time jumps by the whole time the envelope
    spends at it when the envelope moves by a hair; here a change of the envelope by a
    factor ``(1 + eps)`` moves the result by at most ``eps`` times the time it spends within
    the band: the ring count is continuous, and its slope bounded, by construction."""
    if values.size < 2:
        return 0.0
    # x = ln(values / level) + 1/2: the band is 0 <= x <= 1 (a zero of the envelope is
    # taken as 1e-300 of the level: a segment from it spends no time in the band)
    x = np.log(np.maximum(values / level, 1e-300))
    x += 0.5
    h = times[1:] - times[:-1]
    a, b = x[:-1], x[1:]
    # the mean of clip(x, 0, 1) over a segment where x is linear: (G(b) - G(a)) / (b - a),
    # G the antiderivative (0 below 0, x^2 / 2 within the band, x - 1/2 above it)
    ga = np.where(a <= 0.0, 0.0, np.where(a >= 1.0, a - 0.5, 0.5 * a * a))
    gb = np.where(b <= 0.0, 0.0, np.where(b >= 1.0, b - 0.5, 0.5 * b * b))
    d = b - a
    flat = np.abs(d) < 1e-9
    share = np.empty_like(d)
    share[~flat] = (gb[~flat] - ga[~flat]) / d[~flat]
    share[flat] = np.clip(0.5 * (a[flat] + b[flat]), 0.0, 1.0)
    return float(np.dot(share, h))


def oscillation_frequency(t, p, t_step, min_cycles=1.5):
    """Dominant frequency of the oscillation of a step response after ``t_step``.

    The dominant peak of the spectrum of the deviation from the final value, checked for
    subharmonics so that a strong harmonic is not taken for the fundamental, refined from the
    phase of the complex-demodulated fundamental and finally from the zero crossings of the
    deviation, high-passed (against drift) and averaged over fractions of a period (against
    harmonics). The module docstring gives the method and its thresholds. Nonuniform samples
    are resampled linearly onto uniform grids. The trace after ``t_step`` must span at least
    two periods.

    Parameters
    ----------
    t : array_like
        Sample times, strictly increasing, possibly nonuniform, [s]
    p : array_like
        Response at ``t``, [any unit]
    t_step : float
        Time of the input step, ``t[0] <= t_step < t[-1]``, [s]
    min_cycles : float
        Fewest periods [-] (> 0), after ``t_step``, for which the
        fundamental must exceed 1 % of the largest deviation from the final
        value for the response to count as oscillating

    Returns
    -------
    float or None
        Frequency of the fundamental, [Hz] (cycles per second, not rad/s); None
        for a response that does not oscillate (monotone, overdamped, or dying
        away in fewer than ``min_cycles`` periods) or a constant trace.

    Raises
    ------
    ValueError
        On invalid ``t``, ``p``, ``t_step`` (see :func:`overshoot`) or
        ``min_cycles <= 0``.

    Notes
    -----
    For a damped sinusoid ``exp(-sigma t) cos(omega_d t + phi)`` about a constant the result
    is ``omega_d / (2 pi)``, the zero-crossing rate, not the resonance peak of the spectrum.
    """
    t, p, t_step = _validate(t, p, t_step)
    try:
        min_cycles = float(min_cycles)
    except (TypeError, ValueError):
        raise ValueError(f"min_cycles must be a positive number [-], got {min_cycles!r}") \
            from None
    if not (math.isfinite(min_cycles) and min_cycles > 0):
        raise ValueError(f"min_cycles must be a positive number [-], got {min_cycles!r}")
    return _frequency(_levels(t, p, t_step), t_step, min_cycles)


def _frequency(levels, t_step, min_cycles):
    """:func:`oscillation_frequency` from a checked trace's :func:`_levels`."""
    return _frequency_and_periods(levels, t_step, min_cycles)[0]


def _frequency_and_periods(levels, t_step, min_cycles):
    """``(frequency [Hz] or None, periods [-] or None)``: :func:`oscillation_frequency` and
    for how many periods after ``t_step`` the oscillation stays above 1 % of the largest
    deviation (what the verdict 'oscillating' needs ``min_cycles`` of)."""
    ts, ps, _, p_final, _ = levels
    largest = float(np.abs(ps - p_final).max())
    if largest == 0.0 or largest <= 1e-12 * float(np.abs(ps).max()):
        return None, None
    for coarse, further in _spectral_candidates(ts, ps, p_final, min_cycles):
        found = _oscillating_fundamental(ts, ps, p_final, t_step, coarse, largest, min_cycles,
                                         refined=further)
        if found is None:
            continue
        frequency, periods = found
        memo = {}
        for filtering in ("harmonics", "highpass", "raw"):
            crossing = _crossing_frequency(ts, ps, p_final, frequency, filtering, memo)
            if crossing is not None and abs(crossing / frequency - 1.0) < 0.05:
                return crossing, periods
        return frequency, periods
    return None, None



# --------------------------------------------------------------------------- pressure oscillation
#
# How a fluid-power engineer reads a port-pressure trace after a valve step (the definitions
# below are also written down in docs and in :func:`pressure_metrics`):
#
#   frequency     of the ringing (:func:`oscillation_frequency`);
#   amplitude     half the largest peak-to-peak swing of the ringing within one period, measured
#                 about a baseline that follows the slow drifts (:func:`oscillation_amplitude`);
#   first excursion  the largest |p - p0| (what a transducer's peak hold shows);
#   steady change    the level the pressure settles to minus the pre-step level;
#   peak-to-peak     max p - min p (what a scope's cursors show);
#   settling time    when the pressure stays within +-2 % of its final absolute pressure
#                    (:func:`port_settling`, :class:`SettlingBand`).

#: Fewest periods a ringing must stay above 1 % of its excursion to count as an oscillation
#: (the 'no oscillation' verdict of :func:`pressure_metrics`), [-].
VERDICT_PERIODS = 1.5
#: A ringing that stays above 1 % of its excursion for fewer periods than this is close to
#: the 'no oscillation' verdict: :func:`pressure_metrics` fades its amplitude linearly from
#: its whole swing here to 0 at :data:`VERDICT_PERIODS`, and its note says so, [-].
VERDICT_MARGIN = 3.0
#: Fewest periods of the oscillation the metrics window must hold for an amplitude, [-]: the
#: baseline is a centred mean over one period, so a swing is measured only where a period of
#: signal exists on both sides of the half period it belongs to.
AMPLITUDE_MIN_PERIODS = 2.0
_BASELINE_SAMPLES = 64      # uniform grid of the baseline and amplitude, per period
#: A window holding fewer periods than this of an oscillation whose every lobe reaches 30 % of
#: the largest (:func:`_rough_frequency`) is too short to read, not a 'no oscillation': the
#: frequency finder (:func:`oscillation_frequency`) may miss a ringing that fills only ~2.5
#: periods of the window (a supply section II of 5.05-5.1 m on the paper's rig, 25 Hz in
#: 103 ms, read 'no oscillation' between 0.94 MPa at 5.0 m and 'too short' at 5.15 m), [-].
SHORT_WINDOW_PERIODS = 4.0


def ringing_weight(periods):
    """The share of its swing that a ringing's reported amplitude keeps, by how long it rings.

    A ringing that stays above 1 % of its excursion for ``periods`` periods after the
    disturbance keeps its whole swing from :data:`VERDICT_MARGIN` (3) periods on; below
    that the share falls linearly to 0 at :data:`VERDICT_PERIODS` (1.5), the 'no
    oscillation' verdict, so that the amplitude fades continuously into the verdict instead
    of jumping to 0 there (:func:`pressure_metrics`).

    Parameters
    ----------
    periods : float or None
        Periods after the disturbance that the ringing stays above 1 % of its excursion,
        [-]; inf where it does so to the window's end, None where it does not ring

    Returns
    -------
    float
        The share, in [0, 1], [-]
    """
    if periods is None:
        return 0.0
    share = (float(periods) - VERDICT_PERIODS) / (VERDICT_MARGIN - VERDICT_PERIODS)
    return min(1.0, max(0.0, share))


@dataclass(frozen=True)
class SettlingBand:
    """The band a port pressure must stay within to count as settled (:func:`port_settling`).

    A fluid-power engineer reads a pressure trace against its operating pressure: the default
    band is +-2 % of the final absolute pressure (``reference="final"``). The control
    engineer's band of a step response, a fraction of the steady change, stays available
    (``reference="change"``; where the change is below 5 % of the largest deviation, e.g. a
    disturbance that dies away, that deviation stands in for it).

    Attributes
    ----------
    fraction : float
        Half-width of the band as a fraction of its reference, [-], in (0, 1)
    reference : str
        "final" (the final absolute pressure) or "change" (the steady change)
    """

    fraction: float = 0.02
    reference: str = "final"

    #: What each reference is, in words.
    REFERENCES: ClassVar[dict] = {"final": "the final absolute pressure",
                                  "change": "the steady pressure change"}

    def __post_init__(self):
        try:
            fraction = float(self.fraction)
        except (TypeError, ValueError):
            raise ValueError(f"--settling-band: the band must be a number in (0, 1) [-], got "
                             f"{self.fraction!r}") from None
        if not 0.0 < fraction < 1.0:
            raise ValueError(f"--settling-band: the band must lie between 0 and 100 % of its "
                             f"reference, got {fraction * 100:g} %")
        if self.reference not in self.REFERENCES:
            raise ValueError(f"--settling-band: the band is a fraction of 'final' (the final "
                             f"absolute pressure) or 'change' (the steady change), got "
                             f"{self.reference!r}")
        object.__setattr__(self, "fraction", fraction)

    @classmethod
    def parse(cls, spec) -> "SettlingBand":
        """The band from its text: ``"2%"`` or ``"2 % of final"`` (+-2 % of the final absolute
        pressure), ``"5% of change"`` (+-5 % of the steady change); a band passes through, a
        bare number is a fraction of the final pressure (0.02).

        Parameters
        ----------
        spec : str, float or SettlingBand
            The band (a number: the fraction of the final pressure, [-])

        Returns
        -------
        SettlingBand
            The band

        Raises
        ------
        ValueError
            One line naming ``--settling-band``.
        """
        if isinstance(spec, SettlingBand):
            return spec
        if not isinstance(spec, str):
            return cls(spec)
        text, of, reference = spec.strip().partition(" of ")
        text = text.strip()
        percent = text.endswith("%")
        try:
            value = float(text[:-1] if percent else text)
        except ValueError:
            raise ValueError(f"--settling-band: expected e.g. '2%' (of the final absolute "
                             f"pressure) or '5% of change', got {spec!r}") from None
        return cls(value / 100 if percent else value, reference.strip() if of else "final")

    def describe(self) -> str:
        """The band in words, e.g. "+-2 % of the final absolute pressure".

        Returns
        -------
        str
            ``+-<percent> % of <reference>``
        """
        return f"+-{self.fraction * 100:g} % of {self.REFERENCES[self.reference]}"

    def half_width(self, p_final: float, p0: float, largest: float) -> float:
        """The band's half-width, [unit of p].

        Parameters
        ----------
        p_final : float
            Final (absolute) pressure, [unit of p]
        p0 : float
            Pressure at the step, [unit of p]
        largest : float
            Largest deviation from the final pressure after the step, [unit of
            p]: the reference of a "change" band where the change is below 5 %
            of it

        Returns
        -------
        float
            >= 0, [unit of p]
        """
        if self.reference == "final":
            return self.fraction * abs(p_final)
        change = abs(p_final - p0)
        return self.fraction * (change if change > 0.05 * largest else largest)


#: The default settling band: +-2 % of the final absolute pressure.
SETTLING_BAND = SettlingBand(0.02, "final")
#: Fewest crests of the ringing, after its first period, that a decay is fitted to, [-].
MIN_CRESTS = 3
#: Largest RMS scatter of ln(crest) about the fitted exponential decay, [-].
MAX_FIT_SCATTER = 0.25
#: A crest within this fraction of the band's edge makes the settling time a near-discrete
#: event: a slightly smaller (larger) ringing moves it by half a period, [-].
EDGE_MARGIN = 0.1
#: An estimate whose uncertainty (one standard error of the fitted decay) exceeds this
#: fraction of itself is not given, [-].
MAX_ESTIMATE_SPREAD = 0.5


def _window(t, p, t_start, t_end):
    """Validated trace restricted to ``[t[0], t_end]`` and the checked ``t_end`` [s]."""
    t, p, t_start = _validate(t, p, t_start)
    if t_end is None:
        return t, p, t_start, float(t[-1])
    t_end = float(t_end)
    if not t_start < t_end:
        raise ValueError(f"t_end = {t_end:g} s must come after t_start = {t_start:g} s")
    keep = t <= t_end
    if np.count_nonzero(keep & (t > t_start)) < 3:
        raise ValueError("the window [t_start, t_end] must hold at least 3 samples")
    return t[keep], p[keep], t_start, float(min(t_end, t[keep][-1]))


def oscillation_baseline(t, p, t_start, frequency, t_end=None):
    """The slow part of a trace: its mean over one period of the oscillation, centred.

    A centred mean over exactly one period ``T = 1/frequency`` removes a sinusoid of that
    period and all its harmonics completely, and keeps a straight line unchanged, so it follows
    a drift (an accumulator charging, the steady pressure drop) while ignoring the ringing. A
    decaying sinusoid leaks into it by about ``sigma T / (2 pi)`` of its amplitude, 90 degrees out
    of phase, which changes the swing about the baseline by less than 1 % for damping ratios up
    to 0.2. Over the first and last half period of the window, where no centred period fits,
    the baseline is continued as a straight line fitted, together with a sinusoid of the
    oscillation's period that absorbs the leak, to its first (last) period of values.

    Parameters
    ----------
    t : array_like
        Sample times, strictly increasing, possibly nonuniform, [s]
    p : array_like
        Trace at ``t``, [any unit]
    t_start : float
        Start of the window (the disturbance), [s]
    frequency : float
        Oscillation frequency, > 0, [Hz]
    t_end : float
        End of the window, [s]; the end of ``t`` when None

    Returns
    -------
    grid : ndarray
        Uniform times on ``[t_start, t_end]``, 64 per period, [s]
    values : ndarray
        The trace on ``grid`` (linear interpolation), [unit of p]
    baseline : ndarray
        The baseline on ``grid``, [unit of p]

    Raises
    ------
    ValueError
        On an invalid trace or window, ``frequency <= 0``, or a window shorter than
        one period.
    """
    t, p, t_start, t_end = _window(t, p, t_start, t_end)
    frequency = float(frequency)
    if not (math.isfinite(frequency) and frequency > 0):
        raise ValueError(f"frequency must be a positive number [Hz], got {frequency!r}")
    return _baseline(t, p, t_start, frequency, t_end)


def _baseline(t, p, t_start, frequency, t_end):
    """:func:`oscillation_baseline` of a trace checked and cut by :func:`_window`."""
    period = 1.0 / frequency
    duration = t_end - t_start
    # at least 64 samples per period, more where the trace has them (up to 1024), so that a
    # noisy record keeps every sample for the smoothing of oscillation_amplitude
    inside = np.count_nonzero((t >= t_start) & (t <= t_end))
    density = inside * period / duration
    per_period = int(min(max(_BASELINE_SAMPLES, density), 1024, max(8, _MAX_GRID * period / duration))) // 2 * 2
    dt = period / per_period
    n = int(math.floor(duration / dt + 1e-9)) + 1
    if n < per_period + 1:
        raise ValueError(f"the window ({duration * 1e3:.3g} ms) is shorter than one period "
                         f"({period * 1e3:.3g} ms) of the oscillation")
    grid = t_start + dt * np.arange(n)
    values = np.interp(grid, t, p)
    centred, lost = _centred_average(values, per_period)
    baseline = np.empty(n)
    baseline[lost:n - lost] = centred
    if lost:
        # fit a line plus a sinusoid of the oscillation's period over a full period of
        # centred means (a decaying oscillation leaks into the mean as a sinusoid of its own
        # period, which a line alone would mistake for a slope) and continue the line only
        h = max(2, min(centred.size, per_period + 1))
        if h == per_period + 1:     # a full period (the usual case): the fit as two matrices
            fit = _edge_fit(per_period)
            offset, slope = fit @ centred[:h]       # the line from the first period's means
            baseline[:lost] = offset + slope * ((np.arange(lost) - lost) / per_period)
            offset, slope = fit @ centred[-h:]      # and from the last period's
            baseline[n - lost:] = offset + slope * ((np.arange(1, lost + 1) + per_period)
                                                    / per_period)
            return grid, values, baseline
        w = 2 * np.pi * frequency

        def line(tt, yy, at):
            basis = np.column_stack([np.ones_like(tt), tt - tt[0], np.cos(w * tt), np.sin(w * tt)])
            coef = np.linalg.lstsq(basis[:, :4 if tt.size >= 8 else 2], yy, rcond=None)[0]
            return coef[0] + coef[1] * (at - tt[0])

        baseline[:lost] = line(grid[lost:lost + h], centred[:h], grid[:lost])
        baseline[n - lost:] = line(grid[n - lost - h:n - lost], centred[-h:], grid[n - lost:])
    return grid, values, baseline


_EDGE_FITS: dict = {}


def _edge_fit(per_period: int) -> np.ndarray:
    """The least-squares fit of a line plus a sinusoid of one period (``per_period``
    samples) to ``per_period + 1`` uniform samples, as the matrix (2, per_period + 1) that
    gives the line's offset at the first sample and its slope per period (see
    :func:`oscillation_baseline`). A sinusoid of the grid's period spans the same functions
    whatever its phase, so the matrix depends on the sample count alone (kept by it); equal
    to the per-trace least-squares fit to round-off."""
    fit = _EDGE_FITS.get(per_period)
    if fit is None:
        h = per_period + 1
        k = np.arange(h, dtype=float)
        phase = 2 * np.pi * k / per_period
        basis = np.column_stack([np.ones(h), k / per_period, np.cos(phase), np.sin(phase)])
        # by the normal equations: the columns are near orthogonal (condition ~7), and most
        # runs of a sweep sample their oscillation with a new per_period, for which an SVD
        # cost ~0.3 ms
        fit = np.linalg.solve(basis.T @ basis, basis.T)[:2]
        if len(_EDGE_FITS) >= 256:
            _EDGE_FITS.clear()
        _EDGE_FITS[per_period] = fit
    return fit


def oscillation_amplitude(t, p, t_step, frequency=None, t_end=None):
    """Amplitude of the oscillation after ``t_step``, two-sided, about a drifting baseline.

    Half the largest peak-to-peak swing of ``p - baseline`` within any one period of the
    window ``[t_step, t_end]``, where the baseline is the trace's centred mean over one period
    (:func:`oscillation_baseline`), after a cubic Savitzky-Golay smoothing over 1/8 period
    against measurement noise. For ``p = b(t) + A cos(2 pi f t + phi)`` with a slowly varying
    ``b`` it is ``A``; for a decaying oscillation it is half the largest swing from a crest to
    the next trough (or trough to crest), the number an engineer reads off the trace as
    "+-A". Unlike an overshoot beyond a final value it does not depend on where the final
    value falls, and it changes by at most about twice as much as the trace itself changes
    (every step is a mean, a difference or a maximum of samples), so it is continuous in the
    rig's parameters.

    Parameters
    ----------
    t : array_like
        Sample times, strictly increasing, possibly nonuniform, [s]
    p : array_like
        Trace at ``t``, [any unit]
    t_step : float
        Time of the disturbance, ``t[0] <= t_step < t[-1]``, [s]
    frequency : float
        Oscillation frequency, [Hz]; found by :func:`oscillation_frequency`
        on the window when None
    t_end : float
        End of the window, [s]; the end of ``t`` when None

    Returns
    -------
    float or None
        Amplitude, >= 0, [unit of p]; 0.0 when no oscillation is detected (no
        frequency); None when the window holds fewer than
        :data:`AMPLITUDE_MIN_PERIODS` periods of it.

    Raises
    ------
    ValueError
        On an invalid trace or window.
    """
    t, p, t_step, t_end = _window(t, p, t_step, t_end)
    if frequency is None:
        frequency = oscillation_frequency(t, p, t_step)
        if frequency is None:
            return 0.0
    return _amplitude(t, p, t_step, frequency, t_end)


def _amplitude(t, p, t_step, frequency, t_end, base=None):
    """:func:`oscillation_amplitude` of a trace checked and cut by :func:`_window`, at a
    given frequency [Hz]; ``base``: its :func:`_baseline` where known."""
    if (t_end - t_step) * frequency < AMPLITUDE_MIN_PERIODS:
        return None
    frequency = float(frequency)
    if not (math.isfinite(frequency) and frequency > 0):
        raise ValueError(f"frequency must be a positive number [Hz], got {frequency!r}")
    grid, values, baseline = base or _baseline(t, p, t_step, frequency, t_end)
    swing = values - baseline
    per_period = int(round(1.0 / (frequency * (grid[1] - grid[0]))))
    from .filters import maximum_filter1d, minimum_filter1d, savgol_filter   # SciPy's, in NumPy

    # a cubic Savitzky-Golay fit over 1/8 period keeps the crests of the oscillation and its
    # first harmonics (attenuation at the fundamental ~1e-4) and averages measurement noise
    length = (per_period // 8) | 1
    if length >= 5:
        swing = savgol_filter(swing, length, 3, mode="interp")

    width = per_period + 1
    span = maximum_filter1d(swing, width, mode="nearest") - minimum_filter1d(swing, width,
                                                                              mode="nearest")
    half = width // 2
    valid = span[half:swing.size - (width - 1 - half)]
    return float(np.max(valid) / 2) if valid.size else float(np.ptp(swing) / 2)


def first_excursion(t, p, t_step, t_end=None):
    """Largest ``|p - p0|`` after ``t_step``, ``p0`` the value at ``t_step`` (a peak hold).

    Parameters
    ----------
    t : array_like
        Sample times, increasing, [s]
    p : array_like
        Signal at ``t``, [any unit]
    t_step : float
        Time of the disturbance, [s]
    t_end : float
        End of the window, [s] (None: the record's end)

    Returns
    -------
    float
        >= 0, [unit of p], refined by a parabola through the largest sample
    """
    t, p, t_step, t_end = _window(t, p, t_step, t_end)
    ts, ps = _post_step(t, p, t_step)
    return max(0.0, _refined_max(ts, np.abs(ps - ps[0])))


def peak_to_peak(t, p, t_step, t_end=None):
    """``max p - min p`` over ``[t_step, t_end]``, [unit of p] (what a scope's cursors show).

    Parameters
    ----------
    t : array_like
        Sample times, increasing, [s]
    p : array_like
        Signal at ``t``, [any unit]
    t_step : float
        Time of the disturbance, [s]
    t_end : float
        End of the window, [s] (None: the record's end)

    Returns
    -------
    float
        The peak-to-peak swing, >= 0, [unit of p]
    """
    t, p, t_step, t_end = _window(t, p, t_step, t_end)
    ts, ps = _post_step(t, p, t_step)
    return max(0.0, _refined_max(ts, ps) + _refined_max(ts, -ps))


def _rough_frequency(t, p, t_start, t_end):
    """Rough frequency [Hz] of an oscillation in a record too short for
    :func:`oscillation_frequency`, or None where the record shows no oscillation.

    The deviation from a fitted straight line must cross zero at least three times (a full
    period: down and up again; a single sag is not one), and every lobe between crossings
    must reach 30 % of the largest (a ramp with a small bump is not an oscillation); the mean
    interval between crossings is then taken as the half period."""
    grid = np.linspace(t_start, t_end, 2048)
    y = np.interp(grid, t, p)
    slope, offset = _line_fit(grid - t_start, y)
    y = y - (offset + slope * (grid - t_start))
    found = _crossing_lobes(y)
    if found is None:
        return None
    idx, lobes, largest = found
    if np.any(lobes[1:-1] < 0.3 * largest):     # inner lobes: whole half periods
        return None
    return float(0.5 / np.mean(np.diff(grid[idx])))


def _band_exit(times, error, tolerance):
    """The instant after which ``|error| <= tolerance`` for good: the last exit from the band,
    interpolated linearly between samples; ``times[0]`` when the error never leaves it; None
    when it is still outside at the last sample.

    Parameters
    ----------
    times : ndarray
        Sample times, increasing, [s]
    error : ndarray
        Deviation from the band's centre at ``times``, [unit of p]
    tolerance : float
        Half-width of the band, >= 0, [unit of p]

    Returns
    -------
    float or None
        [s]
    """
    outside = np.flatnonzero(np.abs(error) > tolerance)
    if outside.size == 0:
        return float(times[0])
    k = int(outside[-1])
    if k == len(times) - 1:
        return None
    side = math.copysign(tolerance, error[k])
    return float(times[k] + (times[k + 1] - times[k]) * (error[k] - side)
                 / (error[k] - error[k + 1]))


def port_settling(t, p, t_step, t_stop, frequency=None, band=SETTLING_BAND) -> dict:
    """Settling time of a port pressure after the step: when it stays within the band for good.

    The band (:class:`SettlingBand`) is by default +-2 % of the final absolute pressure; its
    half-width ``h`` is stated in the result.

    With an oscillation of frequency ``f`` (period ``T``) the band is centred on the
    pressure's slow level, its centred one-period mean (:func:`oscillation_baseline`, whose
    value at the window's end is the final pressure): the settling time is when the ringing
    about the operating pressure dies into the band, and a slow drift of that level (an
    accumulator charging) is the steady change's business, not the settling time's.

    ``"measured"``
        The ringing ``r = p - level`` leaves the band for the last time at least one period
        before ``t_stop``: that instant (interpolated linearly), from ``t_step``.
    ``"estimated"``
        It is still outside the band within the window's last period. The crests of ``|r|``
        after the first period (at least :data:`MIN_CRESTS`) are fitted with
        ``ln A = c - sigma t`` (RMS scatter at most :data:`MAX_FIT_SCATTER`, ``sigma > 0``);
        the ringing is continued as crests every ``T/2`` on that envelope, and the estimate
        is the last exit from the band of that continuation (after the last crest above the
        band ``A_k``: ``t_k + arccos(h / A_k) / (2 pi f)``). Its spread, one standard error
        of the fitted envelope's crossing of the band, is in the note; an estimate spread by
        more than :data:`MAX_ESTIMATE_SPREAD` of itself is not given.
    None
        Neither: the note says why.

    Without an oscillation (``frequency`` None) the band is centred on the final pressure
    (the mean of the window's last 20 %), and the trace must stay within it over the window's
    last 5 % to count as settled (as :func:`settling_time`).

    The last exit of a band is a discrete event: when the crest that last leaves it drops
    inside (or the next crest rises outside) the settling time jumps by half a period. Where
    a crest lies within :data:`EDGE_MARGIN` of the band's edge the result says so
    (``settling_jump_s``, and the note).

    Parameters
    ----------
    t : array
        Sample times, strictly increasing, [s]
    p : array
        Port pressure (absolute), [Pa]
    t_step : float
        Time of the step, [s]
    t_stop : float
        End of the metrics window, [s]
    frequency : float
        Oscillation frequency of the trace in the window, [Hz]; None: none
    band : SettlingBand, float or str
        The band (:meth:`SettlingBand.parse`: a number is a
        fraction of the final absolute pressure, [-])

    Returns
    -------
    dict
        ``settling_time_s`` (float from the step [s], or None), ``settling_method``
        ("measured", "estimated" or None), ``settling_note`` (how it was estimated, a
        crest at the band's edge, or why there is none; "" when there is nothing to add),
        ``settling_band`` (the band in words), ``settling_band_mpa`` (its half-width
        [MPa]) and ``settling_jump_s`` (the half period by which a crest at the band's edge
        may move the settling time [s], or None)
    """
    t, p, t_step, t_stop = _window(t, p, t_step, t_stop)
    return _port_settling(t, p, t_step, t_stop, frequency, SettlingBand.parse(band))


def _port_settling(t, p, t_step, t_stop, frequency, band, levels=None, base=None):
    """:func:`port_settling` of a trace checked and cut by :func:`_window`; ``levels``: its
    :func:`_levels`, ``base`` its :func:`_baseline` at ``frequency``, where known."""
    window = t_stop - t_step
    if frequency is not None and frequency > 0 and window * frequency >= AMPLITUDE_MIN_PERIODS:
        return _ringing_settling(t, p, t_step, t_stop, float(frequency), band, base)
    ts, ps, p0, p_final, _ = levels if levels is not None else _levels(t, p, t_step)
    error = ps - p_final
    h = band.half_width(p_final, p0, float(np.max(np.abs(error))))
    out = _settling_result(None, None, "", band, h, None)
    exit_ = _band_exit(ts, error, h)
    if exit_ is not None and exit_ <= ts[-1] - SETTLED_FRACTION * window:
        return {**out, "settling_time_s": exit_ - t_step, "settling_method": "measured"}
    last = ts >= t_stop - 0.1 * window
    slope = _line_fit(ts[last] - t_stop, ps[last])[0] if last.sum() >= 2 else 0.0
    out["settling_note"] = (f"not settled within the metrics window ({window * 1e3:.0f} ms "
                            f"after the step) in the +-{_mpa(h)} band about the final "
                            f"pressure: no oscillation; the pressure still moves "
                            f"{slope / 1e6:+.2g} MPa/s at the window's end")
    return out


def _mpa(v):
    return f"{v / 1e6:.3g} MPa"


def _settling_result(time, method, note, band, h, jump):
    return {"settling_time_s": None if time is None else float(time), "settling_method": method,
            "settling_note": note, "settling_band": band.describe(),
            "settling_band_mpa": None if h is None else float(h) / 1e6,
            "settling_jump_s": None if jump is None else float(jump)}


def _ringing_settling(t, p, t_step, t_stop, frequency, band, base=None):
    """:func:`port_settling` of a trace that rings at ``frequency`` [Hz]: the band about the
    pressure's one-period mean, which must itself have entered the band about the final
    pressure; ``base``: the trace's :func:`_baseline` where known."""
    period = 1.0 / frequency
    window = t_stop - t_step
    grid, values, level = base or _baseline(t, p, t_step, frequency, t_stop)
    p_final = float(level[-1])
    h = band.half_width(p_final, float(values[0]), float(np.abs(values - p_final).max()))
    settled, method, note, jump = _ringing_exit(grid, values - level, h, t_step, t_stop,
                                                frequency)
    if settled is None:
        return _settling_result(None, None, f"not settled within the metrics window "
                                f"({window * 1e3:.0f} ms after the step): {note}", band, h, None)
    # the slow level (a pressure drop settling, an accumulator charging) must have come
    # within the band of the final pressure too
    notes = [note]
    offset = np.abs(level - p_final)
    arrived = _band_exit(grid, level - p_final, h)
    if arrived > settled:
        # the mean's last excursion outside the band: a discrete event where it barely is
        last = np.flatnonzero(offset <= h)
        last = last[grid[last] < arrived]
        peak = float(np.max(offset[(last[-1] if last.size else 0):np.searchsorted(grid, arrived)]))
        jump = arrived - settled if peak < (1 + EDGE_MARGIN) * h else None
        settled = arrived
        notes = [f"the mean pressure enters the +-{_mpa(h)} band about the final pressure "
                 f"{(arrived - t_step) * 1e3:.0f} ms after the step, after its "
                 f"{frequency:.3g} Hz oscillation has" + (f" ({note})" if note else "")]
        if jump:
            notes.append(f"its last excursion exceeds the band by only {(peak / h - 1) * 100:.0f} "
                         f"%: a slightly smaller one settles {jump * 1e3:.3g} ms earlier (a "
                         f"discrete event)")
    else:
        later = offset[grid > settled]
        if jump is None and later.size and float(later.max()) > (1 - EDGE_MARGIN) * h:
            k = int(np.argmax(later))
            jump = float(grid[grid > settled][k]) - settled
            notes.append(f"the mean pressure comes within {(1 - later[k] / h) * 100:.0f} % of "
                         f"the band's edge {jump * 1e3:.3g} ms later: a slightly larger "
                         f"excursion settles that much later at least (a discrete event)")
    per_period = int(round(period / (grid[1] - grid[0])))
    drift = float(level[-1] - level[max(0, level.size - 1 - per_period)])
    if abs(drift) > h / 2:
        notes.append(f"the mean pressure still moves {drift / period / 1e6:+.2g} MPa/s at the "
                     f"window's end: the band is centred on its value there, which is not yet "
                     f"a final one")
    return _settling_result(settled - t_step, method, "; ".join(filter(None, notes)), band, h,
                            jump)


def _ringing_exit(grid, ringing, h, t_step, t_stop, frequency):
    """When the ringing ``ringing`` (on the uniform ``grid`` [s], about the pressure's
    one-period mean) leaves the band ``+-h`` for the last time: ``(time [s] or None, method,
    note, jump [s] or None)`` (:func:`port_settling`: measured, or estimated from the decay of
    its crests; None with the note saying why)."""
    period = 1.0 / frequency
    per_period = int(round(period / (grid[1] - grid[0])))
    # the crests of |ringing|: one per half period
    crests, _ = find_peaks(np.abs(ringing), distance=max(1, int(0.35 * per_period)))
    crest_t, crest_a = grid[crests], np.abs(ringing[crests])
    exit_ = _band_exit(grid, ringing, h)
    if exit_ is not None and exit_ <= t_stop - period:
        before = crest_a[crest_t < exit_]
        after = crest_a[crest_t > exit_]
        jump, note = _edge(before[-1] if before.size else None,
                           after[0] if after.size else None, h, period)
        return exit_, "measured", note, jump
    # still ringing outside the band in the window's last period: fit the decay
    fit = (crest_t >= t_step + period)
    n = int(np.count_nonzero(fit))
    if n < MIN_CRESTS:
        return None, None, (f"{n} crests of the {frequency:.3g} Hz oscillation after its first "
                            f"period, too few (< {MIN_CRESTS}) to fit its decay"), None
    x, y = crest_t[fit] - t_stop, np.log(crest_a[fit])
    slope, c = _line_fit(x, y)
    residual = y - (c + slope * x)
    scatter = float(np.sqrt(np.mean(residual ** 2)))
    sigma = -float(slope)
    if not sigma > 0:
        return None, None, f"the {frequency:.3g} Hz oscillation does not decay over the window", None
    if scatter > MAX_FIT_SCATTER:
        return None, None, (f"the envelope of the {frequency:.3g} Hz oscillation is not a clean "
                            f"exponential decay (scatter {scatter:.2f} in ln A)"), None
    # the fitted envelope A(t) = exp(c - sigma (t - t_stop)) crosses the band at t_stop + gap
    gap = (c - math.log(h)) / sigma
    # its standard error (inverse prediction from the line fit, n - 2 degrees of freedom)
    xm = float(np.mean(x))
    sxx = float(np.sum((x - xm) ** 2))
    s = math.sqrt(float(np.sum(residual ** 2)) / (n - 2))
    spread = s * math.sqrt(1.0 / n + (gap - xm) ** 2 / sxx) / sigma
    # continue the crests every half period on the envelope; the last one above the band
    last = float(crest_t[-1])
    half = period / 2
    j = math.floor((t_stop + gap - last) / half)      # crests last + k T/2, k <= j, above h
    while j >= 1 and c - sigma * (last + j * half - t_stop) <= math.log(h):
        j -= 1
    if j >= 1:
        t_k = last + j * half
        a_k = math.exp(c - sigma * (t_k - t_stop))
        settled = t_k + math.acos(min(1.0, h / a_k)) / (2 * math.pi * frequency)
        a_next = a_k * math.exp(-sigma * half)
    else:   # the next crest is predicted inside the band: the exit from the last one seen
        a_k = float(crest_a[-1])
        settled = exit_ if exit_ is not None else \
            max(t_stop, last + math.acos(min(1.0, h / a_k)) / (2 * math.pi * frequency))
        a_next = math.exp(c - sigma * (last + half - t_stop))
    decay = (f"the {frequency:.3g} Hz oscillation, +-{_mpa(math.exp(c))} about the mean "
             f"pressure at the window's end ({(t_stop - t_step) * 1e3:.0f} ms after the step), "
             f"decays as exp(-{sigma:.3g} t) (fit over {n} crests)")
    if spread > MAX_ESTIMATE_SPREAD * (settled - t_step):
        return None, None, (f"{decay} and would leave the +-{_mpa(h)} band about "
                            f"{(settled - t_step) * 1e3:.0f} +- {spread * 1e3:.0f} ms after the "
                            f"step: too uncertain to give"), None
    jump, edge_note = _edge(a_k, a_next, h, period)
    if settled <= t_stop:
        note = (f"estimated: the pressure left the +-{_mpa(h)} band for the last time "
                f"{(t_stop - settled) * 1e3:.0f} ms before the window's end; {decay}, and its "
                f"next crests are predicted inside the band")
    else:
        note = (f"estimated: {decay} and leaves the +-{_mpa(h)} band for the last time "
                f"{(settled - t_stop) * 1e3:.0f} ms after the window's end (+- "
                f"{spread * 1e3:.0f} ms, one standard error of the fit)")
    return settled, "estimated", "; ".join(filter(None, (note, edge_note))), jump


def _edge(a_out, a_in, h, period):
    """``(jump [s] or None, note)``: whether the crest that leaves the band last (``a_out``)
    or the first crest inside it (``a_in``) lies within :data:`EDGE_MARGIN` of the band's
    half-width ``h`` (amplitudes and ``h`` in one unit; None: no such crest)."""
    half = period / 2
    if a_out is not None and a_out < (1 + EDGE_MARGIN) * h:
        # (its fitted height may lie a little inside the band while the trace itself left it)
        return half, (f"the last crest outside the band lies within "
                      f"{abs(a_out / h - 1) * 100:.0f} % of its edge: a slightly smaller "
                      f"ringing settles half "
                      f"a period ({half * 1e3:.3g} ms) earlier (a discrete event)")
    if a_in is not None and a_in > (1 - EDGE_MARGIN) * h:
        return half, (f"the next crest reaches {a_in / h * 100:.0f} % of the band: a slightly "
                      f"larger ringing settles half a period ({half * 1e3:.3g} ms) later (a "
                      f"discrete event)")
    return None, ""


def pressure_metrics(t, p, t_step, t_end=None, settling_band=SETTLING_BAND) -> dict:
    """Every metric of one port pressure after a disturbance, over ``[t_step, t_end]``.

    Parameters
    ----------
    t : array_like
        Sample times, strictly increasing, [s]
    p : array_like
        Pressure, [Pa]
    t_step : float
        Time of the disturbance (start of the metrics window), [s]
    t_end : float
        End of the metrics window, [s]; the end of ``t`` when None
    settling_band : SettlingBand, float or str
        The settling band (:class:`SettlingBand`; a number is a fraction of the final
        absolute pressure, [-]; default +-2 % of the final absolute pressure)

    Returns
    -------
    dict
        ``frequency_hz``
            oscillation frequency, [Hz] (:func:`oscillation_frequency`);
            None: no oscillation, or too few periods to tell
        ``amplitude_mpa``
            oscillation amplitude, two-sided about the drifting baseline,
            [MPa] (:func:`oscillation_amplitude`), times
            :func:`ringing_weight` (below :data:`VERDICT_MARGIN` periods of
            ringing it fades to 0 at the verdict); 0.0 with a note when no
            oscillation is detected, None when the window is too short
        ``first_excursion_mpa``
            largest ``|p - p0|``, [MPa] (:func:`first_excursion`)
        ``steady_change_mpa``
            settled level minus the pre-step level ``p0``, [MPa]: the
            level is the mean over the window's last period of the
            oscillation, or over its last 20 % without one; None when
            the window is too short to tell
        ``peak_to_peak_mpa``
            ``max p - min p`` in the window, [MPa]
        ``settling_*``
            ``settling_time_s``, ``settling_method``, ``settling_note``, ``settling_band``,
            ``settling_band_mpa``, ``settling_jump_s`` (:func:`port_settling`)
        ``amplitude_note``
            "" when frequency and amplitude were measured, else why not
            (no oscillation; the window holds too few periods), or that
            the ringing lasts fewer than :data:`VERDICT_MARGIN` periods
            above 1 %: near the 'no oscillation' verdict, the amplitude
            faded (the share and the whole swing are given)
        ``ringing_periods``
            for how many periods after the step the oscillation's
            envelope lies above 1 % of the excursion (the threshold
            softened over a neper about it, so that the count moves
            continuously: :func:`oscillation_frequency`), [-]; None
            where it still does at the window's end, or does not ring
    """
    # the trace is checked once, and its post-step samples and levels (_levels) are shared
    # by every metric below (each public function would check and compute them again)
    t, p, t_step, t_end = _window(t, p, t_step, t_end)
    settling_band = SettlingBand.parse(settling_band)
    duration = t_end - t_step
    levels = _levels(t, p, t_step)
    frequency, periods = _frequency_and_periods(levels, t_step, VERDICT_PERIODS)
    note = ""
    amplitude = 0.0
    base = None
    if frequency is None:
        rough = _rough_frequency(t, p, t_step, t_end)
        if rough is not None and duration * rough < SHORT_WINDOW_PERIODS:
            amplitude = None
            note = (f"the window ({duration * 1e3:.0f} ms) holds {duration * rough:.1f} periods of "
                    f"an oscillation near {rough:.3g} Hz: too few to measure its frequency "
                    f"and amplitude (fewer than {SHORT_WINDOW_PERIODS:g})")
        else:
            note = ("no oscillation: the pressure does not ring (no coherent oscillation above "
                    f"{OSCILLATION_THRESHOLD:.0%} of its excursion for {VERDICT_PERIODS:g} "
                    "periods)")
    elif duration * frequency < AMPLITUDE_MIN_PERIODS:
        amplitude = None
        note = (f"the window ({duration * 1e3:.0f} ms) holds {duration * frequency:.1f} periods of "
                f"the {frequency:.3g} Hz oscillation; an amplitude needs {AMPLITUDE_MIN_PERIODS:g}")
    else:
        base = _baseline(t, p, t_step, frequency, t_end)
        swing = _amplitude(t, p, t_step, frequency, t_end, base)
        # near the verdict the amplitude fades into it (ringing_weight) instead of jumping
        amplitude = swing * ringing_weight(periods)
        if periods < VERDICT_MARGIN:
            note = (f"rings for only {periods:.2f} periods above {OSCILLATION_THRESHOLD:.0%} of "
                    f"its excursion, near the 'no oscillation' verdict ({VERDICT_PERIODS:g} "
                    f"periods): the amplitude is {ringing_weight(periods):.0%} of its "
                    f"{_mpa(swing)} swing, fading linearly from {VERDICT_MARGIN:g} periods to 0 "
                    f"at the verdict")
    ts, ps = levels[0], levels[1]       # _post_step(t, p, t_step)
    p0 = float(ps[0])
    if frequency is not None and duration * frequency >= 1.0:
        level, _ = _window_moments(ts, ps, t_end - 1.0 / frequency)
    else:
        level, _ = _window_moments(ts, ps, t_end - TAIL_FRACTION * duration)
    if amplitude is None:      # too short to know where the pressure settles, or when
        settling = _settling_result(None, None, f"not settled within the window: {note}",
                                    settling_band, None, None)
        change = None
    else:
        settling = _port_settling(t, p, t_step, t_end, frequency, settling_band, levels, base)
        change = (level - p0) / 1e6
    return {"frequency_hz": None if frequency is None else float(frequency),
            "amplitude_mpa": None if amplitude is None else float(amplitude) / 1e6,
            "first_excursion_mpa": max(0.0, _refined_max(ts, np.abs(ps - p0))) / 1e6,
            "steady_change_mpa": change,
            "peak_to_peak_mpa": max(0.0, _refined_max(ts, ps) + _refined_max(ts, -ps)) / 1e6,
            **settling, "amplitude_note": note,
            "ringing_periods": (float(periods) if periods is not None and math.isfinite(periods)
                                else None)}
