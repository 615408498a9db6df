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
------------------------------------------
Picking the highest peak of a trace finds a harmonic when the trace has one, and counting
zero crossings about a constant finds extra crossings where a strong harmonic wiggles
through zero and skewed ones where the trace drifts. :func:`oscillation_frequency` therefore
proceeds as follows, all on ``[t_step, t[-1]]`` resampled onto uniform grids by linear
interpolation (so nonuniform solver output is fine):

1. *Coarse estimate.* Amplitude spectrum of the deviation ``p - p_final`` (zero-padded 8x,
   half-cosine taper over the last 20 % so that a trace ending off its final value does not
   ring across the spectrum). Its highest genuine local maximum (prominence >= 2 % of the
   highest value in range) between ``min_cycles / duration`` and a quarter of the sampling
   rate is the dominant peak. A monotone response has no such maximum: None.
2. *Harmonic check.* If the spectrum also has a genuine peak within 8 % of ``1/k`` of the
   dominant frequency (k = 2..5) at least 10 % as high, that lower peak is the first
   candidate for the fundamental (the largest such k first); the dominant peak is the last
   candidate. Steps 3 and 4 take the candidates in turn; the first that passes both wins.
3. *Complex demodulation.* Multiply the deviation by ``exp(-2 pi i f t)`` and average it
   twice over exactly one period. That filter has zeros at every multiple of ``f``: it
   removes the final value, every harmonic and nearly all of a slow drift, and it passes the
   damped fundamental ``exp((-sigma + i Delta) t)`` with its phase slope ``Delta`` unchanged
   (a linear filter multiplies an exponential by a constant). The amplitude-weighted slope
   of the unwrapped phase corrects ``f``; three passes. The trace must span two periods, and
   the weighted RMS of the phase about that line must stay below 0.3 rad (a coherent
   oscillation, not noise).
4. *Oscillating or not.* The envelope of the fundamental (the demodulated amplitude divided
   by the filter's gain for the fitted decay rate) must stay above 1 % of the largest
   deviation ``max|p - p_final|`` for at least ``min_cycles`` periods after ``t_step``.
   For the step response of a second-order system this reports damping ratios up to
   about 0.46 with the default ``min_cycles = 1.5`` (ratio 0.45: 1.5 cycles of overshoot and
   undershoot above 1 %). No candidate passing: None.
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

import numpy as np
from .peaks import find_peaks, local_maxima, peak_prominence   # scipy.signal's, in NumPy

__all__ = ["oscillation_frequency", "oscillation_amplitude", "oscillation_baseline", "overshoot",
           "first_excursion", "peak_to_peak", "settling_time", "port_settling", "pressure_metrics",
           "AMPLITUDE_MIN_PERIODS"]

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
_MAX_INCOHERENCE = 0.3      # weighted RMS phase wander of a coherent fundamental, [rad]
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
    if not np.all(np.isfinite(t)):
        raise ValueError("t must be finite (no NaN or inf) [s]")
    if not np.all(np.isfinite(p)):
        raise ValueError("p must be finite (no NaN or inf)")
    if t.size >= 2 and not np.all(np.diff(t) > 0):
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
    h = np.diff(tw)
    a, b = pw[:-1], pw[1:]
    span = tw[-1] - tw[0]
    mean = float(np.sum(h * (a + b) / 2) / span)
    # exact integral of the square of a linear segment: h (a^2 + a b + b^2) / 3
    a, b = a - mean, b - mean
    var = float(np.sum(h * (a * a + a * b + b * b) / 3) / span)
    return mean, math.sqrt(max(var, 0.0))


def _levels(t, p, t_step):
    """Post-step samples, initial and final value, and whether the net change is nonzero."""
    ts, ps = _post_step(t, p, t_step)
    p0 = float(ps[0])
    duration = ts[-1] - ts[0]
    p_final, tail_std = _window_moments(ts, ps, ts[-1] - TAIL_FRACTION * duration)
    scale = float(np.max(np.abs(ps)))
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
    total = float(np.sum(ww))
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
    t : array_like       Sample times, strictly increasing, possibly nonuniform, [s]
    p : array_like       Response at ``t``, [any unit]
    t_step : float       Time of the input step, ``t[0] <= t_step < t[-1]``, [s]

    Returns
    -------
    float  Overshoot beyond the final value, >= 0, [unit of p]. Divide by
           ``|p_final - p0|`` for the relative overshoot of a second-order system,
           ``exp(-zeta pi / sqrt(1 - zeta^2))``.

    Raises
    ------
    ValueError  On arrays of different lengths, non-finite values, ``t`` not strictly
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
    t : array_like       Sample times, strictly increasing, possibly nonuniform, [s]
    p : array_like       Response at ``t``, [any unit]
    t_step : float       Time of the input step, ``t[0] <= t_step < t[-1]``, [s]
    band : float         Half-width of the band relative to the net change, [-]
                         (0 < band < 1; 0.02 is the usual 2 % settling time)

    Returns
    -------
    float or None  Settling time measured from ``t_step``, [s]; None when the trace has not
                   been seen to settle: it is still outside the band during the last 5 % of
                   the interval ``[t_step, t[-1]]``.

    Raises
    ------
    ValueError  On invalid ``t``, ``p``, ``t_step`` (see :func:`overshoot`) or
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
    tolerance = band * reference
    outside = np.flatnonzero(np.abs(error) > tolerance)
    if outside.size == 0:
        return 0.0
    k = int(outside[-1])
    if k == len(ts) - 1:
        return None
    side = math.copysign(tolerance, error[k])
    entered = ts[k] + (ts[k + 1] - ts[k]) * (error[k] - side) / (error[k] - error[k + 1])
    if entered > ts[-1] - SETTLED_FRACTION * (ts[-1] - t_step):
        return None
    return float(entered - t_step)


# --------------------------------------------------------------------------- frequency

def _spectral_candidates(ts, ps, p_final, min_cycles):
    """Coarse fundamental frequencies [Hz] from the spectrum of the deviation, best first.

    The subharmonics of the dominant peak that pass the harmonic check (largest k first),
    then the dominant peak itself; empty when the spectrum has no genuine peak in range.

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
    # half-cosine taper over the tail (where the response has settled), so that a trace
    # ending off its final value does not ring across the spectrum; the start is kept
    # whole, since the step is where the oscillation is largest
    m = max(2, int(TAIL_FRACTION * n))
    deviation[n - m:] *= _taper(m)
    nfft = 1 << int(math.ceil(math.log2(8 * n)))
    spectrum = np.abs(_rfft(deviation, nfft))
    freq = np.arange(spectrum.size) * (1.0 / (nfft * dt))     # np.fft.rfftfreq(nfft, dt)
    # the range is one run of bins: freq >= min_cycles / duration and freq <= 0.25 / dt
    lo = int(np.searchsorted(freq, min_cycles / duration, side="left"))
    hi = int(np.searchsorted(freq, 0.25 / dt, side="right")) - 1
    if hi < lo:
        return []
    highest = float(np.max(spectrum[lo:hi + 1]))
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
    if main is None:
        return []
    f_main, h_main = float(freq[main]), spectrum[main]
    candidates = [f_main]
    for k in range(2, _MAX_SUBHARMONIC + 1):
        near = order[np.abs(freq[order] - f_main / k) <= _SUBHARMONIC_TOL * f_main / k]
        sub = best(near, _SUBHARMONIC_HEIGHT * h_main)
        if sub is not None:
            candidates.insert(0, float(freq[sub]))
    return candidates


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
    dd = np.diff(phase)
    if not np.any(np.abs(dd) >= np.pi):     # nothing to correct: np.unwrap adds zeros
        return phase.copy()
    ddmod = np.mod(dd + np.pi, 2 * np.pi) - np.pi
    ddmod[(ddmod == -np.pi) & (dd > 0)] = np.pi
    correct = ddmod - dd
    correct[np.abs(dd) < np.pi] = 0.0
    out = phase.copy()
    out[1:] += np.cumsum(correct)
    return out


def _fit_fundamental(ts, ps, p_final, frequency):
    """Refine ``frequency`` [Hz] from the phase slope of the demodulated fundamental.

    Returns ``(frequency [Hz], centre times [s], envelope of the fundamental [unit of p],
    weighted RMS phase residual [rad])`` of the last pass, or None where the trace is too
    short for the demodulation (under two periods) or holds nothing at ``frequency``.
    """
    for _ in range(3):
        if frequency <= 0 or 2.0 / frequency >= ts[-1] - ts[0]:
            return None
        centres, z, width = _demodulate(ts, ps, p_final, frequency)
        if z.size < 4:
            return None
        magnitude = np.abs(z)
        peak = float(np.max(magnitude))
        if peak == 0.0:
            return None
        strong = np.flatnonzero(magnitude >= 0.05 * peak)
        span = slice(int(strong[0]), int(strong[-1]) + 1)
        tc, zc, mc = centres[span], z[span], magnitude[span]
        if tc.size < 4:
            return None
        phase = _unwrap(np.angle(zc))
        weights = mc / peak
        x = tc - tc[0]
        slope, offset = _line_fit(x, phase, weights)
        frequency = frequency + slope / (2 * np.pi)
    # the last pass's phase residual (the earlier passes' are not used)
    residual = phase - (offset + slope * x)
    incoherence = math.sqrt(float(np.sum(weights * residual ** 2) / np.sum(weights)))
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
    largest = float(np.max(np.abs(y)))
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
        gaps = np.diff(times)
        if np.any(np.abs(gaps / period - 1.0) > 0.15):
            return None
        estimates.append((times.size - 1) / (times[-1] - times[0]))
        weights.append(times.size - 1)
    if not estimates:
        return None
    # np.average(estimates, weights=weights), without its overhead (the same operations)
    return float(sum(e * w for e, w in zip(estimates, weights)) / sum(weights))


def _oscillating_fundamental(ts, ps, p_final, t_step, coarse, largest, min_cycles):
    """Demodulated frequency [Hz] near ``coarse`` if a coherent oscillation lasting at least
    ``min_cycles`` periods above 1 % of ``largest`` is there, else None."""
    fitted = _fit_fundamental(ts, ps, p_final, coarse)
    if fitted is None:
        return None
    frequency, centres, envelope, incoherence = fitted
    if not (incoherence <= _MAX_INCOHERENCE):
        return None
    if not (math.isfinite(frequency) and frequency > 0):
        return None
    if abs(frequency / coarse - 1.0) > 0.5:
        return None  # wandered off to another component
    above = np.flatnonzero(envelope >= OSCILLATION_THRESHOLD * largest)
    if above.size == 0:
        return None
    cycles = frequency * (centres[above[-1]] - t_step)
    if cycles < min_cycles:
        return None
    return float(frequency)


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
    t : array_like       Sample times, strictly increasing, possibly nonuniform, [s]
    p : array_like       Response at ``t``, [any unit]
    t_step : float       Time of the input step, ``t[0] <= t_step < t[-1]``, [s]
    min_cycles : float   Fewest periods [-] (> 0), after ``t_step``, for which the
                         fundamental must exceed 1 % of the largest deviation from the final
                         value for the response to count as oscillating

    Returns
    -------
    float or None  Frequency of the fundamental, [Hz] (cycles per second, not rad/s); None
                   for a response that does not oscillate (monotone, overdamped, or dying
                   away in fewer than ``min_cycles`` periods) or a constant trace.

    Raises
    ------
    ValueError  On invalid ``t``, ``p``, ``t_step`` (see :func:`overshoot`) or
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
    ts, ps, _, p_final, _ = levels
    largest = float(np.max(np.abs(ps - p_final)))
    if largest == 0.0 or largest <= 1e-12 * float(np.max(np.abs(ps))):
        return None
    for coarse in _spectral_candidates(ts, ps, p_final, min_cycles):
        frequency = _oscillating_fundamental(ts, ps, p_final, t_step, coarse, largest,
                                             min_cycles)
        if frequency is None:
            continue
        memo = {}
        for filtering in ("harmonics", "highpass", "raw"):
            crossing = _crossing_frequency(ts, ps, p_final, frequency, filtering, memo)
            if crossing is not None and abs(crossing / frequency - 1.0) < 0.05:
                return crossing
        return frequency
    return None



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
#   settling time    when the pressure stays within 2 % of the change (:func:`port_settling`).

#: Fewest periods of the oscillation the metrics window must hold for an amplitude, [-]: the
#: baseline is a centred mean over one period, so a swing is measured only where a period of
#: signal exists on both sides of the half period it belongs to.
AMPLITUDE_MIN_PERIODS = 2.0
#: Half-width of the settling band relative to the step's pressure change, [-].
SETTLING_BAND = 0.02
#: Periods of the oscillation the window must hold for a decay to be extrapolated, [-].
MIN_PERIODS = 6
#: Largest RMS scatter of ln(peak) about the fitted exponential decay, [-].
MAX_FIT_SCATTER = 0.25
_BASELINE_SAMPLES = 64      # uniform grid of the baseline and amplitude, per period


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
    t : array_like      Sample times, strictly increasing, possibly nonuniform, [s]
    p : array_like      Trace at ``t``, [any unit]
    t_start : float     Start of the window (the disturbance), [s]
    frequency : float   Oscillation frequency, > 0, [Hz]
    t_end : float       End of the window, [s]; the end of ``t`` when None

    Returns
    -------
    grid : ndarray      Uniform times on ``[t_start, t_end]``, 64 per period, [s]
    values : ndarray    The trace on ``grid`` (linear interpolation), [unit of p]
    baseline : ndarray  The baseline on ``grid``, [unit of p]

    Raises
    ------
    ValueError  On an invalid trace or window, ``frequency <= 0``, or a window shorter than
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
    t : array_like       Sample times, strictly increasing, possibly nonuniform, [s]
    p : array_like       Trace at ``t``, [any unit]
    t_step : float       Time of the disturbance, ``t[0] <= t_step < t[-1]``, [s]
    frequency : float    Oscillation frequency, [Hz]; found by :func:`oscillation_frequency`
                         on the window when None
    t_end : float        End of the window, [s]; the end of ``t`` when None

    Returns
    -------
    float or None  Amplitude, >= 0, [unit of p]; 0.0 when no oscillation is detected (no
                   frequency); None when the window holds fewer than
                   :data:`AMPLITUDE_MIN_PERIODS` periods of it.

    Raises
    ------
    ValueError  On an invalid trace or window.
    """
    t, p, t_step, t_end = _window(t, p, t_step, t_end)
    if frequency is None:
        frequency = oscillation_frequency(t, p, t_step)
        if frequency is None:
            return 0.0
    return _amplitude(t, p, t_step, frequency, t_end)


def _amplitude(t, p, t_step, frequency, t_end):
    """:func:`oscillation_amplitude` of a trace checked and cut by :func:`_window`, at a
    given frequency [Hz]."""
    if (t_end - t_step) * frequency < AMPLITUDE_MIN_PERIODS:
        return None
    frequency = float(frequency)
    if not (math.isfinite(frequency) and frequency > 0):
        raise ValueError(f"frequency must be a positive number [Hz], got {frequency!r}")
    grid, values, baseline = _baseline(t, p, t_step, frequency, t_end)
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
    t : array_like     Sample times, increasing, [s]
    p : array_like     Signal at ``t``, [any unit]
    t_step : float     Time of the disturbance, [s]
    t_end : float      End of the window, [s] (None: the record's end)

    Returns
    -------
    float  >= 0, [unit of p], refined by a parabola through the largest sample
    """
    t, p, t_step, t_end = _window(t, p, t_step, t_end)
    ts, ps = _post_step(t, p, t_step)
    return max(0.0, _refined_max(ts, np.abs(ps - ps[0])))


def peak_to_peak(t, p, t_step, t_end=None):
    """``max p - min p`` over ``[t_step, t_end]``, [unit of p] (what a scope's cursors show).

    Parameters
    ----------
    t : array_like     Sample times, increasing, [s]
    p : array_like     Signal at ``t``, [any unit]
    t_step : float     Time of the disturbance, [s]
    t_end : float      End of the window, [s] (None: the record's end)
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


def port_settling(t, p, t_step, t_stop, frequency=None, band=SETTLING_BAND) -> dict:
    """The 2 % settling time of a port pressure after the step, measured or estimated.

    The time after the step from which the pressure stays within ``+-band`` of the step's
    pressure change about its final level.

    ``"measured"``
        The trace settles within the window ``[t_step, t_stop]``: :func:`settling_time` over
        the window (final level: the mean of the window's last 20 %).
    ``"estimated"``
        The trace is still outside the band at ``t_stop`` but is a decaying oscillation of
        frequency ``f`` about a level that has stopped moving. The level is the trace's double
        moving average over one period ``T = 1/f``; the band is ``+-band * |p_final - p0|``
        (or ``band`` times the largest deviation where the net change is below 5 % of it); the
        peaks of ``|p - level|`` in the second half of the window are fitted with
        ``ln A = c - sigma t``; the estimate is ``(t_stop - t_step) + ln(A(t_stop) / band) /
        sigma``. Given only when the window holds at least :data:`MIN_PERIODS` periods, the
        fit is clean (RMS scatter of ``ln A`` below :data:`MAX_FIT_SCATTER`), the level moves
        less than half the band over the last period, and the extrapolation reaches no further
        past ``t_stop`` than the window is long.
    None
        Neither: the note says why.

    Parameters
    ----------
    t : array          Sample times, increasing, [s]
    p : array          Port pressure, [Pa]
    t_step : float     Time of the step, [s]
    t_stop : float     End of the metrics window, [s]
    frequency : float  Oscillation frequency of the trace in the window, [Hz]; None: none
    band : float       Half-width of the band relative to the pressure change, [-]

    Returns
    -------
    dict  ``settling_time_s`` (float from the step [s], or None), ``settling_method``
          ("measured", "estimated" or None) and ``settling_note`` (how it was estimated, or
          why there is none; "" when measured)
    """
    t = np.asarray(t, dtype=float)
    p = np.asarray(p, dtype=float)
    inside = t <= t_stop
    measured = settling_time(t[inside], p[inside], t_step, band)
    return _port_settling(t, p, t_step, t_stop, frequency, band, measured, inside)


def _port_settling(t, p, t_step, t_stop, frequency, band, measured, inside=None):
    """:func:`port_settling` given its measured settling time ``measured`` [s] (None: not
    settled within the window); ``inside``: where ``t <= t_stop`` (None: everywhere)."""
    from .filters import uniform_filter1d   # scipy.ndimage's, in NumPy

    if measured is not None:
        return {"settling_time_s": float(measured), "settling_method": "measured",
                "settling_note": ""}
    window = t_stop - t_step
    where = f"not settled within the metrics window ({window * 1e3:.0f} ms after the step)"

    def none(why):
        return {"settling_time_s": None, "settling_method": None, "settling_note": f"{where}: {why}"}

    def mpa(v):
        return f"{v / 1e6:.3g} MPa"

    if frequency is None or not frequency > 0:
        last = t >= t_stop - 0.1 * window
        if inside is not None:
            last &= inside
        slope = _line_fit(t[last] - t_stop, p[last])[0] if last.sum() >= 2 else 0.0
        return none(f"no oscillation; the pressure still moves {slope / 1e6:+.2g} MPa/s at the "
                    f"window's end")
    period = 1.0 / frequency
    periods = window / period

    def too_few():
        return none(f"{periods:.1f} periods of the {frequency:.3g} Hz oscillation, too few "
                    f"(< {MIN_PERIODS}) to extrapolate its decay")

    if periods < MIN_PERIODS:
        return too_few()
    n = _BASELINE_SAMPLES
    g = t_step + np.arange(int(math.floor(window / period * n)) + 1) * (period / n)
    clear = (g >= t_step + period) & (g <= t_stop - period)
    if not clear.any():
        return too_few()
    y = np.interp(g, t, p)
    level = uniform_filter1d(uniform_filter1d(y, n, mode="nearest"), n, mode="nearest")
    k_end = int(np.flatnonzero(clear)[-1])
    p0, p_final = float(y[0]), float(level[k_end])
    deviation = float(np.max(np.abs(y - p_final)))
    change = abs(p_final - p0)
    tolerance = band * (change if change > 0.05 * deviation else deviation)
    # the last period: samples k_end - n .. k_end (by index: g[k_end - n] equals
    # g[k_end] - period but for round-off, which made the comparison flip)
    last = clear.copy()
    last[:max(k_end - n, 0)] = False
    drift = float(np.max(np.abs(level[last] - p_final)))
    if drift > tolerance / 2:
        return none(f"the mean pressure still moves {mpa(drift)} in its last period, more than "
                    f"half the +-{mpa(tolerance)} band")
    ringing = y - level
    peaks, _ = find_peaks(np.abs(ringing), distance=max(1, int(0.35 * n)))
    peaks = peaks[clear[peaks] & (g[peaks] >= t_step + window / 2)]
    if len(peaks) < 4:
        return none("too few oscillation peaks in the second half of the window to fit a decay")
    log_a = np.log(np.abs(ringing[peaks]))
    slope, c = _line_fit(g[peaks] - t_stop, log_a)
    scatter = float(np.sqrt(np.mean((log_a - (c + slope * (g[peaks] - t_stop))) ** 2)))
    sigma = -float(slope)
    a_stop = math.exp(c)
    if not sigma > 0:
        return none(f"the {frequency:.3g} Hz oscillation does not decay over the window's "
                    f"second half")
    if scatter > MAX_FIT_SCATTER:
        return none(f"the envelope of the {frequency:.3g} Hz oscillation is not a clean "
                    f"exponential decay (scatter {scatter:.2f} in ln A)")
    gap = max(0.0, math.log(a_stop / tolerance) / sigma)
    if gap > window:
        return none(f"the {frequency:.3g} Hz oscillation (+-{mpa(a_stop)} at the window's end, "
                    f"decay rate {sigma:.3g} 1/s) would take about {gap * 1e3:.0f} ms more to "
                    f"enter the +-{mpa(tolerance)} band: longer than the window, not extrapolated")
    return {"settling_time_s": float(window + gap), "settling_method": "estimated",
            "settling_note": f"estimated: the {frequency:.3g} Hz oscillation, +-{mpa(a_stop)} "
                             f"at the window's end {window * 1e3:.0f} ms after the step, decays "
                             f"as exp(-{sigma:.3g} t) (fit over {len(peaks)} peaks) into the "
                             f"+-{mpa(tolerance)} band {gap * 1e3:.0f} ms later"}


def pressure_metrics(t, p, t_step, t_end=None) -> dict:
    """Every metric of one port pressure after a disturbance, over ``[t_step, t_end]``.

    Parameters
    ----------
    t : array_like    Sample times, strictly increasing, [s]
    p : array_like    Pressure, [Pa]
    t_step : float    Time of the disturbance (start of the metrics window), [s]
    t_end : float     End of the metrics window, [s]; the end of ``t`` when None

    Returns
    -------
    dict
        ``frequency_hz``         oscillation frequency, [Hz] (:func:`oscillation_frequency`);
                                 None: no oscillation, or too few periods to tell
        ``amplitude_mpa``        oscillation amplitude, two-sided about the drifting baseline,
                                 [MPa] (:func:`oscillation_amplitude`); 0.0 with a note when no
                                 oscillation is detected, None when the window is too short
        ``first_excursion_mpa``  largest ``|p - p0|``, [MPa] (:func:`first_excursion`)
        ``steady_change_mpa``    settled level minus the pre-step level ``p0``, [MPa]: the
                                 level is the mean over the window's last period of the
                                 oscillation, or over its last 20 % without one; None when
                                 the window is too short to tell
        ``peak_to_peak_mpa``     ``max p - min p`` in the window, [MPa]
        ``settling_time_s``, ``settling_method``, ``settling_note``  (:func:`port_settling`)
        ``amplitude_note``       "" when frequency and amplitude were measured, else why not
                                 (no oscillation; the window holds too few periods)
    """
    # the trace is checked once, and its post-step samples and levels (_levels) are shared
    # by every metric below (each public function would check and compute them again)
    t, p, t_step, t_end = _window(t, p, t_step, t_end)
    duration = t_end - t_step
    levels = _levels(t, p, t_step)
    frequency = _frequency(levels, t_step, 1.5)
    note = ""
    amplitude = 0.0
    if frequency is None:
        rough = _rough_frequency(t, p, t_step, t_end)
        if rough is not None and duration * rough < AMPLITUDE_MIN_PERIODS + 0.5:
            amplitude = None
            note = (f"the window ({duration * 1e3:.0f} ms) holds {duration * rough:.1f} periods of "
                    f"an oscillation near {rough:.3g} Hz; frequency and amplitude need "
                    f"{AMPLITUDE_MIN_PERIODS:g}")
        else:
            note = ("no oscillation: the pressure does not ring (no coherent oscillation above "
                    f"{OSCILLATION_THRESHOLD:.0%} of its excursion for 1.5 periods)")
    elif duration * frequency < AMPLITUDE_MIN_PERIODS:
        amplitude = None
        note = (f"the window ({duration * 1e3:.0f} ms) holds {duration * frequency:.1f} periods of "
                f"the {frequency:.3g} Hz oscillation; an amplitude needs {AMPLITUDE_MIN_PERIODS:g}")
    else:
        amplitude = _amplitude(t, p, t_step, frequency, t_end)
    ts, ps = levels[0], levels[1]       # _post_step(t, p, t_step)
    p0 = float(ps[0])
    if frequency is not None and duration * frequency >= 1.0:
        level, _ = _window_moments(ts, ps, t_end - 1.0 / frequency)
    else:
        level, _ = _window_moments(ts, ps, t_end - TAIL_FRACTION * duration)
    if amplitude is None:      # too short to know where the pressure settles, or when
        settling = {"settling_time_s": None, "settling_method": None,
                    "settling_note": f"not settled within the window: {note}"}
        change = None
    else:
        # port_settling: the window is the whole of t here
        measured = _settling_time(levels, t_step, SETTLING_BAND)
        settling = _port_settling(t, p, t_step, t_end, frequency, SETTLING_BAND, measured)
        change = (level - p0) / 1e6
    return {"frequency_hz": None if frequency is None else float(frequency),
            "amplitude_mpa": None if amplitude is None else float(amplitude) / 1e6,
            "first_excursion_mpa": max(0.0, _refined_max(ts, np.abs(ps - p0))) / 1e6,
            "steady_change_mpa": change,
            "peak_to_peak_mpa": max(0.0, _refined_max(ts, ps) + _refined_max(ts, -ps)) / 1e6,
            **settling, "amplitude_note": note}
