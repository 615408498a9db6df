"""Port metrics of the design studies, with a settling time that says how it was obtained.

The open-loop step's metrics window ends when the piston reaches its far stop (about 100 ms
after the step on the default rig, :func:`hydroline.scenarios.metrics_window`); a lightly
damped hose oscillation is often still ringing then, so the 2 % settling time measured on the
window alone (:func:`hydroline.analysis.settling_time`) is None for most hose lengths.
:func:`port_settling` keeps that measurement where it exists and otherwise, where the trace
allows it, estimates when the ringing would enter the band from its own exponential decay.

Definition
----------
The 2 % settling time is the time after the step from which the port pressure stays within
``+-2 %`` of the step's pressure change about its final level.

``"measured"``
    The trace settles within the metrics window: :func:`hydroline.analysis.settling_time`
    over the window (final level: the mean of the window's last 20 %).
``"estimated"``
    The trace is still outside the band at the piston stop, but it is a decaying oscillation
    of the reported frequency ``f`` about a level that has stopped moving. With ``T = 1/f``:

    * *level*: the trace's double moving average over exactly one period ``T`` (removes the
      oscillation, its harmonics and nearly all of its decay); the final level ``p_final`` is
      its last value clear of the window's ends (``T`` before the stop), ``p0`` the pressure
      at the step; the band is ``+-2 % * |p_final - p0|`` (or 2 % of the largest deviation
      from ``p_final`` where the net change is below 5 % of it: a disturbance that returns);
    * *envelope*: the peaks of ``|p - level|`` in the second half of the window, fitted by
      least squares with ``ln A = c - sigma t``;
    * the estimate is ``(t_stop - t_step) + ln(A(t_stop) / band) / sigma``: the time at which
      that envelope enters the band.

    Given only when the window holds at least :data:`MIN_PERIODS` periods (so that the decay
    is measured over several cycles), the fit is clean (RMS scatter of ``ln A`` below
    :data:`MAX_FIT_SCATTER`), the level moves less than half the band over the last period,
    and the extrapolation reaches no further past the stop than the window is long.
None
    Neither: the note says why (no oscillation and the pressure still drifting at the stop,
    too few periods, the level still drifting, ...).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.signal import find_peaks

from ..analysis import settling_time
from ..scenarios import summarize

__all__ = ["port_settling", "port_summary", "MIN_PERIODS", "MAX_FIT_SCATTER", "BAND"]

#: Half-width of the settling band relative to the step's pressure change, [-].
BAND = 0.02
#: Periods of the oscillation the window must hold for a decay to be extrapolated, [-].
MIN_PERIODS = 6
#: Largest RMS scatter of ln(peak) about the fitted exponential decay, [-].
MAX_FIT_SCATTER = 0.25
_SAMPLES_PER_PERIOD = 64


def _mpa(v):
    return f"{v / 1e6:.3g} MPa"


def port_settling(t, p, t_step: float, t_stop: float, frequency: float | None = None,
                  band: float = BAND) -> dict:
    """The 2 % settling time of a port pressure after the step (module docstring).

    Parameters
    ----------
    t : array          Sample times, increasing, [s]
    p : array          Port pressure, [Pa]
    t_step : float     Time of the step, [s]
    t_stop : float     End of the metrics window (the piston reaches its stop), [s]
    frequency : float  Oscillation frequency of the trace in the window, [Hz]; None: none
    band : float       Half-width of the band relative to the pressure change, [-]

    Returns
    -------
    dict  ``settling_time_s`` (float from the step [s], or None), ``settling_method``
          ("measured", "estimated" or None) and ``settling_note`` (text: how it was
          estimated, or why there is none; "" when measured)
    """
    t = np.asarray(t, dtype=float)
    p = np.asarray(p, dtype=float)
    inside = t <= t_stop
    measured = settling_time(t[inside], p[inside], t_step, band)
    if measured is not None:
        return {"settling_time_s": float(measured), "settling_method": "measured",
                "settling_note": ""}
    window = t_stop - t_step
    where = f"not settled within the metrics window ({window * 1e3:.0f} ms, step to piston stop)"

    def none(why):
        return {"settling_time_s": None, "settling_method": None, "settling_note": f"{where}: {why}"}

    if frequency is None or not frequency > 0:
        last = inside & (t >= t_stop - 0.1 * window)
        slope = np.polyfit(t[last] - t_stop, p[last], 1)[0] if last.sum() >= 2 else 0.0
        return none(f"no oscillation; the pressure still moves {slope / 1e6:+.2g} MPa/s at the stop")
    period = 1.0 / frequency
    periods = window / period
    n = _SAMPLES_PER_PERIOD
    g = t_step + np.arange(int(math.floor(window / period * n)) + 1) * (period / n)
    y = np.interp(g, t, p)
    level = uniform_filter1d(uniform_filter1d(y, n, mode="nearest"), n, mode="nearest")
    clear = (g >= t_step + period) & (g <= t_stop - period)
    if periods < MIN_PERIODS or not clear.any():
        return none(f"{periods:.1f} periods of the {frequency:.3g} Hz oscillation, too few "
                    f"(< {MIN_PERIODS}) to extrapolate its decay")
    k_end = int(np.flatnonzero(clear)[-1])
    p0, p_final = float(y[0]), float(level[k_end])
    deviation = float(np.max(np.abs(y - p_final)))
    change = abs(p_final - p0)
    tolerance = band * (change if change > 0.05 * deviation else deviation)
    last = clear & (g >= g[k_end] - period)
    drift = float(np.max(np.abs(level[last] - p_final)))
    if drift > tolerance / 2:
        return none(f"the mean pressure still moves {_mpa(drift)} in its last period, more than "
                    f"half the +-{_mpa(tolerance)} band")
    ringing = y - level
    peaks, _ = find_peaks(np.abs(ringing), distance=max(1, int(0.35 * n)))
    peaks = peaks[clear[peaks] & (g[peaks] >= t_step + window / 2)]
    if len(peaks) < 4:
        return none("too few oscillation peaks in the second half of the window to fit a decay")
    log_a = np.log(np.abs(ringing[peaks]))
    slope, c = np.polyfit(g[peaks] - t_stop, log_a, 1)
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
        return none(f"the {frequency:.3g} Hz oscillation (+-{_mpa(a_stop)} at the stop, decay "
                    f"rate {sigma:.3g} 1/s) would take about {gap * 1e3:.0f} ms more to enter the "
                    f"+-{_mpa(tolerance)} band: longer than the window, not extrapolated")
    return {"settling_time_s": float(window + gap), "settling_method": "estimated",
            "settling_note": f"estimated: the {frequency:.3g} Hz oscillation, +-{_mpa(a_stop)} "
                             f"at the piston stop {window * 1e3:.0f} ms after the step, decays "
                             f"as exp(-{sigma:.3g} t) (fit over {len(peaks)} peaks) into the "
                             f"+-{_mpa(tolerance)} band {gap * 1e3:.0f} ms later"}


def port_summary(res) -> dict:
    """:func:`hydroline.scenarios.summarize` of a run, with each port's settling time taken by
    :func:`port_settling` (``settling_method`` and ``settling_note`` added per port)."""
    s = summarize(res)
    t0, t1 = s["metrics_window_s"]
    for side in ("supply", "return"):
        s[side].update(port_settling(res.t, res[f"{side}_port_pressure"], t0, t1,
                                     s[side]["frequency_hz"]))
    return s
