"""Summaries of runs: the metrics window (the disturbance to the piston's arrival at the stop it
moves toward), the port pressure metrics of a step, the ripple per command cycle of a sine
and the tracking error; :class:`SineSummaryStream` gives the sine's summary chunk by chunk in
constant memory. :func:`summarize` is what ``hydroline simulate`` prints.
"""
from __future__ import annotations

import math

import numpy as np

from ..traces.metrics import SETTLING_BAND, SettlingBand, pressure_metrics
from ..engine import SimulationResult

__all__ = ["summarize", "run_summary", "metrics_window", "ripple_metrics", "SineSummaryStream",
           "COMMAND_START", "window_of", "WindowEnd"]

#: Where a command's metrics window starts, in the summary note (an experiment's
#: ``window_start`` unless it names its own disturbance, e.g. "the valve step").
COMMAND_START = "the start of the command"


def metrics_window(res: SimulationResult, margin: float = 1e-3) -> tuple[float, float, str]:
    """The part of a run the metrics are taken over: ``(t_start, t_end, why_it_ends)``.

    It starts at the disturbance (the valve step; 0 for the closed-loop sine) and ends when the
    piston arrives at the stop it moves *toward* -- the end stop on the side of its first
    clear displacement (more than ``margin``) after the disturbance -- or at the end of the run
    if it never gets there. What follows an arrival is a second transient (the flow stops),
    not the response to the step. A piston that starts resting on one stop and moves away from
    it does not end the window there.

    Parameters
    ----------
    res : SimulationResult
        With ``piston_position`` [m] and metadata ``t_disturbance`` [s],
        ``stroke`` [m]
    margin : float
        Distance from a stop that counts as arrived, [m]

    Returns
    -------
    tuple
        ``(t_start [s], t_end [s], reason)``; ``reason`` is "stop" (the piston reached the
        stop it moves toward) or "end" (the run ended first)
    """
    t0 = float(res.metadata.get("t_disturbance", 0.0))
    axes = res.metadata.get("axes") or {}
    pairs = [(ax.position, ax.stroke) for ax in axes.values()] or \
        [("piston_position", res.metadata.get("stroke", np.inf))]
    return window_of(res.t, {signal: (res[signal], stroke) for signal, stroke in pairs
                             if signal in res}, t0, margin)


def window_of(t, pistons: dict, t0: float, margin: float = 1e-3) -> tuple[float, float, str]:
    """:func:`metrics_window` of traces: ``(t_start, t_end, why_it_ends)``.

    Parameters
    ----------
    t : ndarray
        Output times, ascending, [s]
    pistons : dict
        Per axis, its position signal -> (position trace at ``t`` [m], full
        stroke [m])
    t0 : float
        The disturbance, the window's start, [s]
    margin : float
        Distance from a stop that counts as arrived, [m]

    Returns
    -------
    tuple
        ``(t_start [s], t_end [s], reason)``, as :func:`metrics_window`
    """
    end, reason = float(t[-1]), "end"
    for x, stroke in pistons.values():     # the first axis to arrive at the stop it moves toward
        half = stroke / 2
        after = t >= t0
        x0 = float(np.interp(t0, t, x))
        moved = np.flatnonzero(after & (np.abs(x - x0) > margin))
        if moved.size == 0 or not np.isfinite(half):
            continue
        direction = math.copysign(1.0, x[moved[0]] - x0)
        arrived = np.flatnonzero(after & (direction * x >= half - margin) & (t > t[moved[0]] - 1e-12))
        if arrived.size and float(t[arrived[0]]) < end:
            end, reason = float(t[arrived[0]]), "stop"
    return t0, end, reason


class WindowEnd:
    """Whether a run's rows so far reach the end of its metrics window (the first axis's
    piston at the stop it moves toward, :func:`metrics_window`): pass as ``until`` to
    :func:`hydroline.engine.integrate`, so that a run whose metrics are all it is for stops
    there. The rows it keeps then give the same window, and so the same metrics. Each call
    looks at the rows it has not seen (a long run costs what its rows cost). After a call that
    said False, :meth:`time_ahead` estimates how soon it may say True (the pistons at their
    last speeds): :func:`~hydroline.engine.integrate` shortens its blocks toward it, so that
    the run ends within a few rows of the window's end rather than within a block.

    Parameters
    ----------
    t0 : float
        The disturbance, the window's start, [s]
    pistons : dict
        Per axis, its position signal -> full stroke [m]
    margin : float
        Distance from a stop that counts as arrived, [m]
    """

    def __init__(self, t0: float, pistons: dict, margin: float = 1e-3):
        self.t0, self.margin = float(t0), margin
        self.pistons = {k: stroke / 2 for k, stroke in pistons.items() if np.isfinite(stroke)}
        self.index = None
        self.seen = 0
        self.x0 = {}          # signal -> position at t0
        self.moved = {}       # signal -> (direction, time of the first clear displacement)
        self.ahead = math.inf  # time_ahead(): [s] from the last row looked at

    def __call__(self, t, rows, columns) -> bool:
        """True when the rows so far (times ``t`` [s], the run's table ``rows`` with its
        ``columns``) hold the window's end.

        Parameters
        ----------
        t : ndarray
            The run's output times so far, [s]
        rows : ndarray
            Its rows so far, signals and states side by side, [SI]
        columns : list
            The rows' column names
        """
        if len(t) == 0 or t[-1] < self.t0:
            return False
        if self.index is None:
            self.index = {k: list(columns).index(k) for k in self.pistons if k in columns}
        start = max(self.seen - 1, 0)
        self.seen = len(t)
        self.ahead = math.inf
        for signal, i in self.index.items():
            x = rows[:, i]
            if signal not in self.x0:      # (as metrics_window: interpolated at t0)
                self.x0[signal] = float(np.interp(self.t0, t, x))
            tt, xx = t[start:], x[start:]
            if signal not in self.moved:
                after = tt >= self.t0
                k = np.flatnonzero(after & (np.abs(xx - self.x0[signal]) > self.margin))
                if k.size == 0:
                    continue
                self.moved[signal] = (math.copysign(1.0, xx[k[0]] - self.x0[signal]), tt[k[0]])
            direction, t_moved = self.moved[signal]
            # the rows after t0 and after the first clear displacement (t ascends: one search
            # each, rather than masks over the rows)
            j = max(int(np.searchsorted(tt, self.t0, "left")),
                    int(np.searchsorted(tt, t_moved - 1e-12, "right")))
            if j < len(tt) and (direction * xx[j:] >= self.pistons[signal] - self.margin).any():
                return True
            if len(tt) >= 2 and tt[-1] > tt[-2]:   # at its last speed toward the stop
                speed = direction * (xx[-1] - xx[-2]) / (tt[-1] - tt[-2])
                if speed > 0:
                    gap = self.pistons[signal] - self.margin - direction * xx[-1]
                    self.ahead = min(self.ahead, gap / speed)
        return False

    def time_ahead(self) -> float:
        """How soon, after the last row looked at, the window may end: the least time any
        moving piston needs at its last speed to come within ``margin`` of the stop it moves
        toward (inf before a piston has clearly moved or while none moves toward its stop).
        An estimate: a piston that speeds up arrives sooner.

        Returns
        -------
        float
            Time, [s]
        """
        return self.ahead


def _window_note(t0, t1, reason, start):
    if reason == "stop":
        return (f"metrics from {start} at {t0 * 1e3:.0f} ms to {t1 * 1e3:.0f} ms, when the piston "
                f"reaches the stop it moves toward")
    return (f"metrics from {start} at {t0 * 1e3:.0f} ms to the end of the run at {t1 * 1e3:.0f} ms "
            f"(the piston has not reached a stop)")


def _cycle_ripple(t, p, t0, t1, frequency):
    """Peak-to-peak [Pa] of ``p`` in each full command cycle within ``[t0, t1]``."""
    period = 1.0 / frequency
    out = []
    k = 0
    # t ascends: each cycle's samples t0 + k T <= t <= t0 + (k + 1) T are one slice (a mask
    # over the whole trace per cycle made a 600 s run's summary take ~40 s)
    while t0 + (k + 1) * period <= t1 + 1e-9:
        i = int(np.searchsorted(t, t0 + k * period, side="left"))
        j = int(np.searchsorted(t, t0 + (k + 1) * period, side="right"))
        if j - i >= 2:
            out.append(float(np.ptp(p[i:j])))
        k += 1
    return out


def ripple_metrics(ripple) -> dict:
    """A port's summary entries under a sine command from its peak-to-peak pressure ripple
    per full command cycle (the largest one as the amplitude; no oscillation frequency or
    settling time).

    Parameters
    ----------
    ripple : list of float
        Peak-to-peak pressure of each full cycle in the window, [Pa]

    Returns
    -------
    dict
        ``frequency_hz``, ``amplitude_mpa``, ``ripple_pp_mpa``, ``ripple_pp_mpa_per_cycle``,
        ``settling_time_s`` and ``amplitude_note`` (why there is no amplitude)
    """
    top = max(ripple) if ripple else None
    return {"frequency_hz": None,
            "amplitude_mpa": None if top is None else top / 2e6,
            "ripple_pp_mpa": None if top is None else top / 1e6,
            "ripple_pp_mpa_per_cycle": [r / 1e6 for r in ripple],
            "settling_time_s": None,
            "amplitude_note": "" if ripple else "the window holds no full command cycle"}


def summarize(res: SimulationResult, settling_band=SETTLING_BAND) -> dict:
    """The summary of a run (what ``hydroline simulate`` prints and ``summary.json`` holds):
    its experiment's :meth:`Experiment.summary`.

    Open-loop step (and a user's own experiment): per port (``"supply"``, ``"return"``) the
    metrics of :func:`hydroline.traces.metrics.pressure_metrics` over :func:`metrics_window`:
    frequency [Hz], two-sided oscillation amplitude [MPa], first excursion [MPa], steady
    change [MPa], peak-to-peak [MPa], settling time [s] in ``settling_band`` (by default
    +-2 % of the final absolute pressure; measured or estimated, with its method, note, band
    and half-width ``settling_band_mpa``), and a note where an amplitude cannot be given.

    Closed-loop sine (no step, a forced response): per port the peak-to-peak ripple in each
    full command cycle (``ripple_pp_mpa_per_cycle``, its maximum ``ripple_pp_mpa``);
    ``amplitude_mpa`` is half that maximum, ``frequency_hz`` and ``settling_time_s`` are None;
    the tracking error (reference minus position) as rms and max [mm].

    Also: ``actuator_natural_frequency_hz``, ``wall_time_s``, ``metrics_window_s``,
    ``metrics_window_note``, ``warnings``. A multi-axis rig gives these per axis under
    ``"axes"``. The result is not modified.

    Parameters
    ----------
    res : SimulationResult
        A run of :func:`simulate`
    settling_band : SettlingBand or str
        The port pressures' settling band
        (:meth:`hydroline.traces.metrics.SettlingBand.parse`: "2%" of the
        final absolute pressure, the default, or e.g. "5% of change")

    Returns
    -------
    dict
    """
    settling_band = SettlingBand.parse(settling_band)
    exp = res.metadata.get("experiment")
    if exp is not None:
        # (an experiment of a user's own that overrides summary(result) keeps the default band)
        return exp.summary(res) if settling_band == SETTLING_BAND else \
            exp.summary(res, settling_band=settling_band)
    scenario = res.metadata.get("scenario")
    return run_summary(res, "the valve step" if scenario == "open-loop-step"
                       else COMMAND_START, sine=scenario == "closed-loop-sine",
                       settling_band=settling_band)


def run_summary(res: SimulationResult, window_start: str, sine: bool,
                settling_band=SETTLING_BAND) -> dict:
    """The summary of a run (:func:`summarize`) whose metrics window starts at ``window_start``:
    the step metrics per port, or with ``sine`` the ripple per command cycle and the tracking
    error; per axis on a multi-axis rig.

    Parameters
    ----------
    res : SimulationResult
        A run of :func:`hydroline.scenarios.running.simulate`
    window_start : str
        What the metrics window starts at (its note)
    sine : bool
        Ripple per command cycle and tracking error instead of step metrics
    settling_band : SettlingBand
        The port pressures' settling band

    Returns
    -------
    dict
    """
    t0, t1, reason = metrics_window(res)
    m = res.t <= t1
    t = res.t[m]
    axes = res.metadata.get("axes") or {}
    if len(axes) > 1:
        return _summarize_axes(res, axes, t0, t1, m, reason, window_start, sine,
                               settling_band)
    ax = next(iter(axes.values()), None)
    out = {}
    for side, key in (("supply", ax.supply_pressure if ax else "supply_port_pressure"),
                      ("return", ax.return_pressure if ax else "return_port_pressure")):
        p = res[key][m]
        if sine:
            out[side] = ripple_metrics(_cycle_ripple(t, p, t0, t1,
                                                     res.metadata["command_frequency_hz"]))
        else:
            out[side] = pressure_metrics(t, p, t0, t1, settling_band)
    out["actuator_natural_frequency_hz"] = float(res.metadata["actuator_natural_frequency_hz"])
    out["wall_time_s"] = float(res.metadata.get("total_wall_time", res.wall_time))
    if sine:
        err = (res[ax.reference_signal if ax else "position_reference"]
               - res[ax.position if ax else "piston_position"])[m]
        out["tracking_error_rms_mm"] = float(np.sqrt(np.mean(err**2)) * 1e3)
        out["tracking_error_max_mm"] = float(np.max(np.abs(err)) * 1e3)
    out["metrics_window_s"] = [t0, t1]
    out["metrics_window_note"] = _window_note(t0, t1, reason, window_start)
    if not sine:
        out["settling_band"] = settling_band.describe()
    out["warnings"] = list(res.warnings)
    return out


class SineSummaryStream:
    """The closed-loop sine's summary (:func:`summarize`) computed chunk by chunk as a long run
    goes, in constant memory: pass :meth:`update` as ``observe`` to
    :func:`hydroline.simulation.integrate` (through :func:`simulate`), then call :meth:`summary`.

    Same numbers as :func:`summarize` on the whole trace: the metrics window of
    :func:`metrics_window` (its end found as the rows arrive), per port the peak-to-peak in each
    full command cycle, the tracking error's rms and max up to the window's end.

    Parameters
    ----------
    t_disturbance : float
        Start of the metrics window, [s]
    stroke : float
        Full stroke, [m]
    frequency : float
        Command frequency, [Hz]
    supply, ret, position, reference : str
        Signal names: port pressures [Pa], piston
        position and its reference [m]
    margin : float
        Distance from a stop that counts as arrived, [m]
    window_start : str
        What the metrics window starts at (its note)
    """

    def __init__(self, t_disturbance, stroke, frequency, supply="supply_port_pressure",
                 ret="return_port_pressure", position="piston_position",
                 reference="position_reference", margin=1e-3,
                 window_start=COMMAND_START):
        self.t0, self.half, self.margin = float(t_disturbance), stroke / 2, margin
        self.window_start = window_start
        self.period = 1.0 / frequency
        self.names = (supply, ret, position, reference)
        self.index = None
        self.prev = None          # last row before this chunk (t, x): x0 by interpolation
        self.x0 = self.direction = self.t_moved = None
        self.t_end, self.arrived = None, False
        self.cycles = {}          # k -> [min supply, max supply, min return, max return, rows]
        self.n = 0
        self.sumsq = 0.0
        self.err_max = 0.0

    def update(self, t, table, columns):
        """Take in one block of output rows (pass as ``observe`` to :func:`simulate`).

        Parameters
        ----------
        t : ndarray
            Ascending output times, [s]
        table : ndarray
            One row per time: signals and states side by side, [SI]
        columns : list[str]
            Names of the table's columns
        """
        if self.arrived or len(t) == 0:
            return
        if self.index is None:
            self.index = [list(columns).index(k) for k in self.names]
        # one pass over the rows gathers the four columns (contiguous: each later pass is cheap)
        ps, pr, x, ref = np.ascontiguousarray(table[:, self.index].T)
        end = len(t)
        if self.x0 is None and t[-1] >= self.t0:   # the piston's position at the disturbance
            tt, xx = (t, x) if self.prev is None else (np.r_[self.prev[0], t], np.r_[self.prev[1], x])
            self.x0 = float(np.interp(self.t0, tt, xx))
        if self.x0 is not None and math.isfinite(self.half):
            after = t >= self.t0
            if self.direction is None:
                moved = np.flatnonzero(after & (np.abs(x - self.x0) > self.margin))
                if moved.size:
                    self.direction = math.copysign(1.0, x[moved[0]] - self.x0)
                    self.t_moved = float(t[moved[0]])
            if self.direction is not None:
                hit = np.flatnonzero(after & (self.direction * x >= self.half - self.margin)
                                     & (t > self.t_moved - 1e-12))
                if hit.size:   # the window ends here: rows after it are not the sine's response
                    end = int(hit[0]) + 1
                    self.arrived = True
        t, ps, pr = t[:end], ps[:end], pr[:end]
        err = ref[:end] - x[:end]
        self.n += end
        # (not np.dot: BLAS's threads on a busy machine took ~8 ms per 20 000 rows)
        self.sumsq += float(np.sum(err * err))
        self.err_max = max(self.err_max, float(np.max(np.abs(err))))
        k = max(int(np.floor((t[0] - self.t0) / self.period)) - 1, 0)
        while self.t0 + k * self.period <= t[-1]:   # (same bounds as _cycle_ripple)
            i = int(np.searchsorted(t, self.t0 + k * self.period, side="left"))
            j = int(np.searchsorted(t, self.t0 + (k + 1) * self.period, side="right"))
            if j > i:
                c = self.cycles.setdefault(k, [np.inf, -np.inf, np.inf, -np.inf, 0])
                c[0], c[1] = min(c[0], ps[i:j].min()), max(c[1], ps[i:j].max())
                c[2], c[3] = min(c[2], pr[i:j].min()), max(c[3], pr[i:j].max())
                c[4] += j - i
            k += 1
        self.prev = (t[-1], x[end - 1])
        self.t_end = float(t[-1])

    def summary(self, res: SimulationResult) -> dict:
        """The summary dict of :func:`summarize` (closed-loop sine), from the rows seen and the
        run's metadata and warnings.

        Parameters
        ----------
        res : SimulationResult
            The run (need not hold the trace: its metadata and warnings)

        Returns
        -------
        dict
        """
        t0, t1 = self.t0, self.t_end
        reason = "stop" if self.arrived else "end"
        out = {}
        for side, lo in (("supply", 0), ("return", 2)):
            ripple = []
            k = 0
            while t0 + (k + 1) * self.period <= t1 + 1e-9:
                c = self.cycles.get(k)
                if c is not None and c[4] >= 2:
                    ripple.append(float(c[lo + 1] - c[lo]))
                k += 1
            out[side] = ripple_metrics(ripple)
        out["actuator_natural_frequency_hz"] = float(res.metadata["actuator_natural_frequency_hz"])
        out["wall_time_s"] = float(res.metadata.get("total_wall_time", res.wall_time))
        out["tracking_error_rms_mm"] = float(np.sqrt(self.sumsq / max(self.n, 1)) * 1e3)
        out["tracking_error_max_mm"] = float(self.err_max * 1e3)
        out["metrics_window_s"] = [t0, t1]
        out["metrics_window_note"] = _window_note(t0, t1, reason, self.window_start)
        out["warnings"] = list(res.warnings)
        return out


def _summarize_axes(res, axes, t0, t1, m, reason, window_start, sine=False,
                    settling_band=SETTLING_BAND):
    """Per-axis summary of a multi-axis run: port metrics, position disturbance, w_h.

    ``position_disturbance_mm`` is the largest excursion of the piston from where it stood at
    the disturbance, over the metrics window, for every axis but the stepped one (null there:
    it moves on purpose; ``position_change_mm`` gives its travel), [mm]. ``sine``: per axis
    the ripple per command cycle instead of the step metrics, and the tracking error
    (reference minus position, rms and max [mm]), as :func:`run_summary` gives a single axis.
    """
    t = res.t[m]
    i0 = int(np.searchsorted(res.t, t0))
    driven = res.metadata.get("driven_axes", [res.metadata.get("stepped_axis")])
    out = {"axes": {}}
    for name, ax in axes.items():
        x = res[ax.position][m]
        dev = float(np.max(np.abs(x[i0:] - x[i0])) * 1e3) if len(x) > i0 else 0.0
        ports = (("supply", ax.supply_pressure), ("return", ax.return_pressure))
        if sine:
            f = res.metadata["command_frequency_hz"]
            entry = {side: ripple_metrics(_cycle_ripple(t, res[key][m], t0, t1, f))
                     for side, key in ports}
            err = (res[ax.reference_signal] - res[ax.position])[m]
            entry["tracking_error_rms_mm"] = float(np.sqrt(np.mean(err**2)) * 1e3)
            entry["tracking_error_max_mm"] = float(np.max(np.abs(err)) * 1e3)
        else:
            entry = {side: pressure_metrics(t, res[key][m], t0, t1, settling_band)
                     for side, key in ports}
        entry["position_disturbance_mm"] = None if name in driven else dev
        if name in driven:
            entry["position_change_mm"] = float((x[-1] - x[i0]) * 1e3)
        entry["actuator_natural_frequency_hz"] = float(
            res.metadata["axis_natural_frequency_hz"][name])
        out["axes"][name] = entry
    out["wall_time_s"] = float(res.metadata.get("total_wall_time", res.wall_time))
    out["metrics_window_s"] = [t0, t1]
    out["metrics_window_note"] = _window_note(t0, t1, reason, window_start)
    out["settling_band"] = settling_band.describe()
    out["warnings"] = list(res.warnings)
    return out


SimulationResult.summarizer = staticmethod(summarize)   # what a result's repr shows
