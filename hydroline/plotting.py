"""Figures a person would rather look at than read (Matplotlib, Agg backend)."""
from __future__ import annotations

import numpy as np

__all__ = ["plot_result", "plot_long_run", "PRESSURE_PANELS", "new_figure", "save_png", "tight_layout", "Traces",
           "column_envelope", "figure_title", "TITLE_CHARACTERS", "time_axis", "format_time",
           "shade_outside_window", "outside_window_handle", "metrics_window_of",
           "OUTSIDE_WINDOW_COLOR", "OUTSIDE_TRACE_COLOR", "OUTSIDE_WINDOW_LABEL",
           "ratio_unit", "place_value_labels", "wrap_title", "plot_layout",
           "layout_panels", "layout_trace_row", "prepare_layout_row"]

#: The paper's Figs. 10-12: valve port pressures, chamber pressures, piston velocity.
PRESSURE_PANELS = (
    ("Supply port [MPa]", ("supply_port_pressure",), 1e-6),
    ("Return port [MPa]", ("return_port_pressure",), 1e-6),
    ("Chamber pressures [MPa]", ("bottom_chamber_pressure", "top_chamber_pressure"), 1e-6),
    ("Piston velocity [m/s]", ("piston_velocity",), 1.0),
)


class Traces:
    """Columns against time, what a figure reads of a run: ``t``, ``traces[name]``, ``name in
    traces``, ``columns`` and ``metadata``, as :class:`hydroline.engine.SimulationResult` has
    them. Made of NumPy arrays and plain values only, so that the figure process receives it
    without importing the model (its module pulls in CasADi: ~45 ms on the figure's branch).

    Parameters
    ----------
    t : array_like
        Times, [s]
    columns : dict
        Name -> values at ``t``, [SI]
    metadata : dict
        What the figure reads of the run's metadata (``metrics_window``,
        ``t_disturbance``, ``scenario``, ...)
    """

    def __init__(self, t, columns: dict, metadata: dict | None = None):
        self.t = np.asarray(t, dtype=float)
        self._columns = {k: np.asarray(v, dtype=float) for k, v in columns.items()}
        self.columns = list(self._columns)
        self.metadata = {} if metadata is None else metadata

    def __getitem__(self, name) -> np.ndarray:
        return self._columns[name]

    def __contains__(self, name) -> bool:
        return name in self._columns


def column_envelope(x, y, x0: float, x1: float, columns: int) -> np.ndarray:
    """Indices of the points of a line that keep its picture at a given width: per pixel
    column of ``[x0, x1]`` the first and the last point, the one with the smallest and the one
    with the largest ``y`` (M4 decimation: Jugel et al., VLDB 2014). Drawn through these points
    the line has in every pixel column the same extremes, and the same segments from one
    column to the next, as drawn through all of them.

    Parameters
    ----------
    x : array
        Abscissae, non-decreasing, [any unit]
    y : array
        Ordinates, [any unit]
    x0, x1 : float
        Abscissae at the left and right edges of the axes, [unit of x]
    columns : int
        Pixel columns between ``x0`` and ``x1``

    Returns
    -------
    numpy.ndarray
        Sorted indices into ``x``, [-] (all of them when the line has no more than four
        points per column, or a value that is not finite)
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    n = len(x)
    if n <= 4 * columns or not x1 > x0 or not np.all(np.isfinite(y)):
        return np.arange(n)
    pixel = np.clip(((x - x0) * (columns / (x1 - x0))).astype(np.int64), 0, columns - 1)
    starts = np.flatnonzero(np.r_[True, pixel[1:] != pixel[:-1]])
    ends = np.r_[starts[1:], n]
    segment = np.repeat(np.arange(len(starts)), ends - starts)
    keep = [starts, ends - 1]
    for extreme in (np.minimum, np.maximum):
        at = np.flatnonzero(y == extreme.reduceat(y, starts)[segment])
        keep.append(at[np.r_[True, segment[at][1:] != segment[at][:-1]]])   # the first in each
    return np.unique(np.concatenate(keep))


def new_figure(figsize):
    """A Matplotlib figure on the Agg canvas, without pyplot (whose import and backend
    selection cost a command's start-up a few hundred ms); ``savefig`` works as usual.

    Parameters
    ----------
    figsize : tuple
        (width, height), [inch]

    Returns
    -------
    matplotlib.figure.Figure
        An empty figure of that size
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig


#: Longest title a figure draws, [characters]: a longer one (a rig name of 10^6 characters)
#: is cut, since laying out its text takes minutes and hundreds of MB.
TITLE_CHARACTERS = 160


def figure_title(text: str) -> str:
    """A figure's title as drawn: at most :data:`TITLE_CHARACTERS` characters, a longer one
    cut and ended with "...".

    Parameters
    ----------
    text : str
        The title (it may hold a rig's name, of any length)

    Returns
    -------
    str
        The title as drawn
    """
    text = str(text)
    return text if len(text) <= TITLE_CHARACTERS else text[:TITLE_CHARACTERS - 3] + "..."


def wrap_title(text: str, width: float, fontsize: float = 12.0) -> str:
    """A figure's title (:func:`figure_title`) broken into lines that fit the figure's width
    (at ~0.55 em a character), as few as fit and of about equal length (no last line of one
    word).

    Parameters
    ----------
    text : str
        The title
    width : float
        The figure's width, [inch]
    fontsize : float
        The title's size, [points]

    Returns
    -------
    str
        The title, lines joined by newlines.
    """
    import textwrap

    text = figure_title(text)
    characters = max(int(0.95 * width * 72 / (0.55 * fontsize)), 20)
    lines = textwrap.wrap(text, characters)
    # the narrowest width that still needs no more lines: lines of about equal length
    for narrower in range(-(-len(text) // max(len(lines), 1)), characters):
        balanced = textwrap.wrap(text, narrower)
        if len(balanced) == len(lines):
            lines = balanced
            break
    return "\n".join(lines) or text


def save_png(fig, path, dpi: int = 100) -> None:
    """Write a figure as PNG with light compression (zlib level 1: about 10 % larger files
    than Matplotlib's default level 6, and ~30 ms less per figure at 110 dpi).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure
    path : str or Path
        The PNG file to write
    dpi : int
        Resolution, [dots per inch]
    """
    fig.savefig(path, dpi=dpi, pil_kwargs={"compress_level": 1})


def tight_layout(fig) -> None:
    """Lay a figure out as ``fig.tight_layout()`` does, without leaving it the placeholder
    layout engine that call leaves: ``savefig`` draws a figure that has an engine once
    without rendering before it draws it (a placeholder lays out nothing), a fifth of the
    figure's drawing time; the figure written is the same.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure, its panels in place
    """
    from matplotlib.layout_engine import TightLayoutEngine

    if fig.get_layout_engine() is not None:   # (rcParams' figure.autolayout, ...): as asked
        fig.tight_layout()
        return
    TightLayoutEngine().execute(fig)


def _figure(n):
    fig = new_figure((8, 2.4 * n + 1.0))
    return fig, fig.subplots(n, 1, sharex=True, squeeze=False)


#: The one meaning of grey in every figure: the part of a run outside its metrics window (before
#: the disturbance, after the piston reached its stop), shaded in this colour.
OUTSIDE_WINDOW_COLOR = "0.9"
#: Traces outside the metrics window are drawn in this grey.
OUTSIDE_TRACE_COLOR = "0.6"
#: What the grey means, for the figures' legends.
OUTSIDE_WINDOW_LABEL = "grey: outside the metrics window"


def time_axis(duration: float):
    """The unit a time axis is drawn in, chosen by the length shown: ms up to 2 s, s up to
    20 min, min up to 2 h, then h.

    Parameters
    ----------
    duration : float
        Length of the time axis, [s]

    Returns
    -------
    tuple
        (factor from s, unit): the axis shows ``t * factor`` [unit].
    """
    duration = abs(float(duration))
    if duration <= 2.0:
        return 1e3, "ms"
    if duration <= 1200.0:
        return 1.0, "s"
    if duration <= 7200.0:
        return 1 / 60, "min"
    return 1 / 3600, "h"


def format_time(t: float, unit: str) -> str:
    """A time for a figure's text in the unit of its axis, e.g. ``"113 ms"``, ``"0.113 s"``.

    Parameters
    ----------
    t : float
        Time, [s]
    unit : str
        "ms", "s", "min" or "h" (:func:`time_axis`)

    Returns
    -------
    str
        The time with its unit
    """
    factor = {"ms": 1e3, "s": 1.0, "min": 1 / 60, "h": 1 / 3600}[unit]
    return f"{t * factor:.3g} {unit}"


def shade_outside_window(ax, t0, t1, t_start: float, t_end: float, factor: float = 1.0) -> bool:
    """Shade in grey (:data:`OUTSIDE_WINDOW_COLOR`) the parts of ``[t_start, t_end]`` outside
    the metrics window ``[t0, t1]``.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        The panel
    t0 : float
        Start of the metrics window, [s] (None: the start)
    t1 : float
        Its end, [s] (None: the end)
    t_start : float
        First time shown, [s]
    t_end : float
        Last time shown, [s]
    factor : float
        The axis's factor from s, [axis unit/s] (:func:`time_axis`)

    Returns
    -------
    bool
        True when something was shaded.
    """
    shaded = False
    for a, b in ((t_start, t0), (t1, t_end)):
        if a is not None and b is not None and b > a:
            ax.axvspan(a * factor, b * factor, color=OUTSIDE_WINDOW_COLOR, zorder=0, lw=0)
            shaded = True
    return shaded


def outside_window_handle(text: str = OUTSIDE_WINDOW_LABEL):
    """A legend entry for the grey of :func:`shade_outside_window`.

    Parameters
    ----------
    text : str
        The entry's text

    Returns
    -------
    matplotlib.patches.Patch
        The legend entry for grey
    """
    from matplotlib.patches import Patch

    return Patch(facecolor=OUTSIDE_WINDOW_COLOR, edgecolor="0.75", label=text)


def metrics_window_of(result):
    """The metrics window of a run's figure: ``(t0, t1, reason)`` from its metadata, t1 None
    when the window runs to the end; None when the run has none.

    Parameters
    ----------
    result : SimulationResult or Traces
        The run

    Returns
    -------
    tuple or None
        (start [s], end [s] or None, "stop" or "end").
    """
    window = result.metadata.get("metrics_window")
    if window is None:
        return None
    t0, t1, reason = window
    if t1 is not None and (reason != "stop" or not t1 < result.t[-1]):
        t1 = None
    return t0, t1, reason


def _limits(values, margin=0.08):
    lo, hi = float(np.min(values)), float(np.max(values))
    pad = margin * (hi - lo) if hi > lo else max(abs(hi), 1.0) * 0.05
    return lo - pad, hi + pad


#: Left and right edges of :func:`plot_result`'s panels, [fraction of the figure's width]
#: (the right margin holds half the last tick label).
PANEL_LEFT, PANEL_RIGHT = 0.11, 0.96


def plot_result(result, signals=None, path=None, title=None):
    """Plot a simulation result; panels of the paper's Figs. 10-12 by default.

    Grey means outside the metrics window, in this as in every figure (the legend says so):
    the time before the disturbance is shaded, and when the piston reaches a stop before the
    end (the open-loop step) the part after it -- a second transient -- is drawn in grey on a
    shaded background. Every panel's y-range is set by the metrics window, so that the
    oscillation after the step (what the paper's Figs. 10-12 show) fills the panel; a grey
    trace that ends off that range has its end value written at the panel's edge. The time
    axis is in ms, s, min or h by the run's length (:func:`time_axis`).

    Parameters
    ----------
    result : SimulationResult or Traces
        The run's traces (time [s], signals in SI units)
    signals : list[str]
        Signals to plot, one panel each (SI units); default panels when None
    path : str
        Write a PNG there when given
    title : str
        Figure title

    Returns
    -------
    matplotlib.figure.Figure
        The figure (also written to ``path`` when given)
    """
    from matplotlib.lines import Line2D

    series = {k: result[k] for k in result.columns}
    if signals is None and "position_reference" in result:   # closed loop: tracking
        series["tracking_error"] = result["position_reference"] - result["piston_position"]
    panels = (_panels(series) if signals is None else
              tuple(p for p in ((s, (s,), 1.0) for s in signals) if p[1][0] in series))
    fig, axes = _figure(len(panels))
    dpi = 110
    # pixel columns of a panel: each line is drawn through its extremes per column
    columns = int(np.ceil(fig.get_figwidth() * (PANEL_RIGHT - PANEL_LEFT) * dpi))
    factor, unit = time_axis(result.t[-1] - result.t[0])
    ts = result.t * factor
    window = metrics_window_of(result)
    t_window, t1 = (window[0], window[1]) if window is not None else (None, None)
    inside = result.t <= t1 if t1 is not None else np.ones(len(result.t), bool)
    k1 = int(np.count_nonzero(inside))
    t_step = result.metadata.get("t_disturbance")
    for ax, (label, keys, scale) in zip(axes[:, 0], panels):
        shown, greyed = [], []
        for k in keys:
            if k in series:
                y = series[k] * scale
                i = column_envelope(ts[:k1], y[:k1], ts[0], ts[-1], columns)
                ax.plot(ts[i], y[i], lw=1.0, label=k.replace("_", " "))
                if t1 is not None:   # after the stop: grey, and not in the y-range
                    i = k1 - 1 + column_envelope(ts[k1 - 1:], y[k1 - 1:], ts[0], ts[-1],
                                                 columns)
                    ax.plot(ts[i], y[i], lw=0.8, color=OUTSIDE_TRACE_COLOR)
                    greyed.append((k, y[-1]))
                shown.append(y[:k1])
        if t1 is not None and shown:
            lo, hi = _limits(np.concatenate(shown))
            ax.set_ylim(lo, hi)
            _off_scale_ends(ax, greyed, lo, hi, label, len(keys) > 1)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        if len(shown) > 1:   # one curve: the axis label names it (and "best" costs a draw)
            ax.legend(loc="best", fontsize=8)
    shaded = False
    for ax in axes[:, 0]:
        if t_step:
            ax.axvline(t_step * factor, color="k", lw=0.8, ls=":")
        if window is not None:
            shaded = shade_outside_window(ax, t_window, t1, result.t[0], result.t[-1], factor)
        if t1 is not None:
            ax.axvline(t1 * factor, color="r", lw=0.8, ls=":")
        ax.set_xlim(ts[0], ts[-1])
    handles = []
    if shaded:
        handles.append(outside_window_handle(
            OUTSIDE_WINDOW_LABEL + (" (after the stop: not in the y-range)"
                                    if t1 is not None else "")))
    if t_step:
        handles.append(Line2D([], [], color="k", lw=0.8, ls=":",
                              label=f"disturbance ({format_time(t_step, unit)})"))
    if t1 is not None:
        handles.append(Line2D([], [], color="r", lw=0.8, ls=":",
                              label=f"piston at its stop ({format_time(t1, unit)})"))
    axes[-1, 0].set_xlabel(f"time [{unit}]")
    height = fig.get_figheight()   # fixed margins, [inch]: tight_layout would draw twice
    default = f"hydroline: {result.metadata.get('scenario', 'simulation')}"
    fig.suptitle(figure_title(title or default), y=1 - 0.1 / height, va="top")
    rows = 0
    if handles:   # (in two columns: one line of three entries is wider than the figure)
        ncol = min(len(handles), 2)
        rows = -(-len(handles) // ncol)
        fig.legend(handles=handles, loc="upper center", ncol=ncol, fontsize=8,
                   frameon=False, bbox_to_anchor=(0.5, 1 - 0.38 / height))
    fig.subplots_adjust(left=PANEL_LEFT, right=PANEL_RIGHT,
                        top=1 - (0.5 + 0.2 * rows) / height, bottom=0.5 / height, hspace=0.12)
    if path:
        save_png(fig, path, dpi=dpi)
    return fig


def _panels(columns):
    """The default panels (label, keys, scale) of a run's figure that has ``columns``: the
    paper's Figs. 10-12 and, closed loop, command, position and tracking error."""
    panels = PRESSURE_PANELS
    if "position_reference" in columns:
        panels = panels + (("Command and position [mm]", ("position_reference", "piston_position"),
                            1e3), ("Tracking error [mm]", ("tracking_error",), 1e3))
    return tuple(p for p in panels if any(k in columns for k in p[1]))


def plot_long_run(lowest, mean, highest, tail, path=None, title=None):
    """A long run's figure (a fatigue test of minutes): in the left column the envelope over
    the whole run -- per time bin the band from the lowest to the highest value, taken from
    every row, and the bin's mean as a line -- so that drift or growth shows; in the right
    column the last rows at full rate (the last command cycles), where the waveform and its
    ripple can be read. Panels as :func:`plot_result`'s; grey, as in every figure, is outside
    the metrics window (the legend says so).

    Parameters
    ----------
    lowest : Traces
        Per bin (``t``: the bin's middle, [s]) the lowest value of each column, [SI]
        (:meth:`hydroline.traces.BinnedEnvelope.bands`)
    mean : Traces
        Per bin the mean, [SI]; its metadata: ``metrics_window``, ``t_disturbance``,
        ``scenario``, ``bin_width`` [s] and ``run`` (first and last time, [s])
    highest : Traces
        Per bin the highest value, [SI]
    tail : Traces
        The last rows, every one, [SI]; ``metadata["label"]``: what they are
        (e.g. the last two command cycles)
    path : str
        Write a PNG there when given
    title : str
        Figure title

    Returns
    -------
    matplotlib.figure.Figure
        The figure (also written to ``path`` when given)
    """
    from matplotlib.lines import Line2D

    panels = _panels(mean.columns)
    n = len(panels)
    fig = new_figure((12, 2.0 * n + 1.3))
    axes = fig.subplots(n, 2, squeeze=False, sharex="col", gridspec_kw=dict(width_ratios=(2.5, 1)))
    t_first, t_last = mean.metadata.get("run", (mean.t[0], mean.t[-1]))
    factor, unit = time_axis(t_last - t_first)
    tm = mean.t * factor
    window = mean.metadata.get("metrics_window")
    t0, t1 = (window[0], window[1]) if window is not None else (None, None)
    if t1 is not None and (window[2] != "stop" or not t1 < t_last):
        t1 = None
    inside = mean.t <= t1 if t1 is not None else np.ones(len(mean.t), bool)
    k1 = int(np.count_nonzero(inside))
    tail_factor, tail_unit = time_axis(tail.t[-1] - tail.t[0]) if len(tail.t) > 1 else (1.0, "s")
    tt = (tail.t - tail.t[0]) * tail_factor if len(tail.t) else tail.t
    t_step = mean.metadata.get("t_disturbance")
    for (left, right), (label, keys, scale) in zip(axes, panels):
        shown = []
        for j, k in enumerate(keys):
            if k not in mean:
                continue
            color = f"C{j}"
            lo, mid, hi = lowest[k] * scale, mean[k] * scale, highest[k] * scale
            name = k.replace("_", " ")
            left.fill_between(tm[:k1], lo[:k1], hi[:k1], color=color, alpha=0.3, lw=0, step="mid")
            left.plot(tm[:k1], mid[:k1], color=color, lw=0.8, label=name)
            if k1 < len(tm):   # after the stop: grey, and not in the y-range
                s = slice(max(k1 - 1, 0), None)
                left.fill_between(tm[s], lo[s], hi[s], color=OUTSIDE_TRACE_COLOR, alpha=0.3, lw=0,
                                  step="mid")
                left.plot(tm[s], mid[s], color=OUTSIDE_TRACE_COLOR, lw=0.8)
            shown += [lo[:k1], hi[:k1]]
            if k in tail:
                right.plot(tt, tail[k] * scale, color=color, lw=0.9, label=name)
        if t1 is not None and shown:
            left.set_ylim(*_limits(np.concatenate(shown)))
        left.set_ylabel(label)
        for ax in (left, right):
            ax.grid(True, alpha=0.3)
        if len(keys) > 1:
            left.legend(loc="upper right", fontsize=8)
    shaded = False
    for left, right in axes:
        if t_step:
            left.axvline(t_step * factor, color="k", lw=0.8, ls=":")
        if window is not None:
            shaded = shade_outside_window(left, t0, t1, t_first, t_last, factor) or shaded
            if len(tail.t):   # (in the tail's time, from its first row)
                a = tail.t[0]
                shaded = shade_outside_window(right, None if t0 is None else t0 - a,
                                              None if t1 is None else t1 - a, 0.0,
                                              tail.t[-1] - a, tail_factor) or shaded
        left.set_xlim(t_first * factor, t_last * factor)
        if len(tt):
            right.set_xlim(tt[0], tt[-1])
    width = mean.metadata.get("bin_width")
    axes[0, 0].set_title("whole run: band = lowest to highest value per "
                         + (format_time(width, time_axis(width)[1]) if width else "bin")
                         + " (every row), line = its mean", fontsize=9)
    axes[0, 1].set_title(tail.metadata.get("label", "the end of the run, every row"), fontsize=9)
    axes[-1, 0].set_xlabel(f"time [{unit}]")
    if len(tail.t):
        axes[-1, 1].set_xlabel(f"time - {format_time(tail.t[0], 's')} [{tail_unit}]")
    handles = []
    if shaded:
        handles.append(outside_window_handle(
            OUTSIDE_WINDOW_LABEL + (" (after the stop: not in the y-range)"
                                    if t1 is not None else "")))
    if t_step:
        handles.append(Line2D([], [], color="k", lw=0.8, ls=":",
                              label=f"disturbance ({format_time(t_step, unit)})"))
    height = fig.get_figheight()   # fixed margins, [inch]
    default = f"hydroline: {mean.metadata.get('scenario', 'simulation')}"
    fig.suptitle(figure_title(title or default), y=1 - 0.1 / height, va="top")
    rows = 0
    if handles:
        ncol = min(len(handles), 2)
        rows = -(-len(handles) // ncol)
        fig.legend(handles=handles, loc="upper center", ncol=ncol, fontsize=8,
                   frameon=False, bbox_to_anchor=(0.5, 1 - 0.38 / height))
    fig.subplots_adjust(left=0.07, right=0.985, top=1 - (0.9 + 0.2 * rows) / height,
                        bottom=0.5 / height, hspace=0.12, wspace=0.16)
    if path:
        save_png(fig, path, dpi=100)
    return fig


def _off_scale_ends(ax, greyed, lo, hi, label, named):
    """Write at a panel's top or bottom edge the end value of each grey trace that ends off
    the y-range ``[lo, hi]`` (else it would vanish from the panel)."""
    unit = label[label.rfind("[") + 1:-1] if label.endswith("]") else ""
    above = [(k, v) for k, v in greyed if v > hi]
    below = [(k, v) for k, v in greyed if v < lo]
    for side, items in ((1.0, above), (0.0, below)):
        if not items:
            continue
        text = "; ".join((f"{k.replace('_', ' ')} " if named else "") + f"{v:.3g} {unit}"
                         for k, v in items)
        arrow = "\u2191" if side else "\u2193"
        ax.text(0.995, side - 0.03 if side else 0.03, f"{arrow} at the end, off scale: {text}",
                transform=ax.transAxes, ha="right", va="top" if side else "bottom",
                fontsize=7, color="0.35",
                bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.8))


#: Where :func:`place_value_labels` tries a label, in order: offset from its point [points]
#: and alignment (right, below-right, left, above, below, and further out).
LABEL_SPOTS = (((5, 4), "left", "bottom"), ((5, -4), "left", "top"),
               ((-5, 4), "right", "bottom"), ((-5, -4), "right", "top"),
               ((0, 7), "center", "bottom"), ((0, -7), "center", "top"),
               ((9, 0), "left", "center"), ((-9, 0), "right", "center"),
               ((5, 13), "left", "bottom"), ((5, -13), "left", "top"),
               ((-5, 13), "right", "bottom"), ((-5, -13), "right", "top"))


def place_value_labels(ax, labels, avoid=(), fontsize: float = 7, draw_first: bool = True):
    """Write value labels beside their points where none overlaps another, a marker, a line
    of the panel, its legend or the panel's edge: each label takes the first free spot of
    :data:`LABEL_SPOTS`; when none is free, the one overlapping least, a line counting a
    quarter of a marker, a label or the edge (a label across a line stays readable). Call it
    when the panel's limits and legend are set.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        The panel (its figure on a canvas)
    labels : list
        ``(x, y, text, color)`` per label, x and y in data units
    avoid : sequence
        More display-space boxes (``matplotlib.transforms.Bbox``) to
        keep clear of, [pixels]
    fontsize : float
        Size of the labels, [points]
    draw_first : bool
        Draw the figure (without rendering) first, so that autoscaled limits and a legend's
        place are those drawn; False where the panel's limits are set and its legend has a
        fixed location (found when asked, without a draw): the layout figure's labels, where
        that draw was a third of the figure's drawing time

    Returns
    -------
    list
        The ``matplotlib.text.Annotation`` of each label.
    """
    fig = ax.figure
    renderer = fig.canvas.get_renderer()
    if draw_first:
        fig.draw_without_rendering()   # the legend's place and the limits as they will be drawn
    frame = ax.get_window_extent(renderer)
    # boxes as rows (x0, y0, x1, y1), [pixels]; their overlaps with a label summed in order
    # (as Python's sum: the same costs to the last bit, the same places)
    boxes = [(b.x0, b.y0, b.x1, b.y1) for b in avoid]
    legend = ax.get_legend()
    if legend is not None:
        b = legend.get_window_extent(renderer)
        boxes.append((b.x0, b.y0, b.x1, b.y1))
    segments = [np.empty((0, 4))]   # points along the lines: a quarter of the weight
    px = fig.dpi / 72.0
    for line in ax.get_lines():   # markers and (sampled) segments
        xy = ax.transData.transform(np.column_stack(line.get_data()).astype(float))
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        if not len(xy):
            continue
        r = max(line.get_markersize(), 2.0) * px / 2 if line.get_marker() not in (None, "None", "") \
            else 1.5 * px
        for (x0, y0), (x1, y1) in zip(xy[:-1], xy[1:]):
            n = int(min(max(np.hypot(x1 - x0, y1 - y0) / (4 * px), 1), 200))
            f = np.linspace(0, 1, n + 1)[1:-1]
            x, y = x0 + f * (x1 - x0), y0 + f * (y1 - y0)
            segments.append(np.column_stack([x - 1.5 * px, y - 1.5 * px, x + 1.5 * px,
                                             y + 1.5 * px]))
        x, y = xy[:, 0], xy[:, 1]
        boxes.extend(np.column_stack([x - r, y - r, x + r, y + r]))
    segments = np.concatenate(segments)

    def overlap(a, others):   # the overlap areas of box a with each row, summed in order
        if not len(others):
            return 0.0
        others = np.asarray(others, dtype=float)
        w = np.minimum(a.x1, others[:, 2]) - np.maximum(a.x0, others[:, 0])
        h = np.minimum(a.y1, others[:, 3]) - np.maximum(a.y0, others[:, 1])
        return float(np.add.accumulate(np.where((w > 0) & (h > 0), w * h, 0.0))[-1])

    placed = []
    for x, y, text, color in labels:
        best = None
        rows = np.asarray(boxes, dtype=float).reshape(-1, 4)
        for offset, ha, va in LABEL_SPOTS:
            t = ax.annotate(text, (x, y), textcoords="offset points", xytext=offset,
                            fontsize=fontsize, color=color, ha=ha, va=va)
            box = t.get_window_extent(renderer)
            outside = (max(frame.x0 - box.x0, 0) + max(box.x1 - frame.x1, 0)
                       + max(frame.y0 - box.y0, 0) + max(box.y1 - frame.y1, 0)) * box.height
            cost = outside + overlap(box, rows) + 0.25 * overlap(box, segments)
            if best is None or cost < best[0]:
                if best is not None:
                    best[1].remove()
                best = (cost, t, box)
            else:
                t.remove()
            if cost == 0:
                break
        boxes.append((best[2].x0, best[2].y0, best[2].x1, best[2].y1))
        placed.append(best[1])
    return placed


def ratio_unit(numerator: str, denominator: str) -> str:
    """The unit of a ratio of two quantities, as a figure's label writes it: ``"-"`` when they
    are the same, a compound unit in parentheses (``ratio_unit("m/s", "mA")`` is
    ``"(m/s)/mA"``, ``ratio_unit("Pa", "m^3/s")`` is ``"Pa/(m^3/s)"``).

    Parameters
    ----------
    numerator : str
        Unit of the output, e.g. "Pa"
    denominator : str
        Unit of the input, e.g. "m^3/s"

    Returns
    -------
    str
        The unit of the ratio
    """
    if numerator == denominator:
        return "-"

    def grouped(u):
        return f"({u})" if any(c in u for c in "/* ") else u

    return f"{grouped(numerator)}/{grouped(denominator)}"


#: SI unit of a line's port quantity, by the last word of the port's name.
PORT_UNITS = {"pressure": "Pa", "flow": "m^3/s"}


def plot_line_response(line, models, f, form, path=None, title=None, references=None):
    """Magnitude and phase of every entry of a form: exact (dissipative) vs line models.

    Parameters
    ----------
    line : Line
        The hose section, its exact (dissipative) transfer matrix the reference
        (labelled "viscoelastic wall, exact" for a viscoelastic wall, M44)
    models : dict
        label -> model with ``transfer(s)``
    f : array
        Frequencies, [Hz]
    form : str
        Causality form of the two-port (a key of ``hydroline.lines.line.FORM_PORTS``)
    path : str
        File to save the figure to (PNG, ...); None: not saved
    title : str
        Figure title; None: the line's length, diameter and dissipation number
    references : dict
        label -> further Line whose exact transfer matrix is drawn (thin, solid,
        grey), e.g. the elastic line beside a viscoelastic one; None: none

    Returns
    -------
    matplotlib.figure.Figure
        Magnitude (in its own unit: Pa/(m^3/s), (m^3/s)/Pa or - for the
        form's entries) and phase [deg] of the four entries against
        frequency [Hz]
    """
    ins, outs = line.form_ports(form)
    s = 2j * np.pi * f
    exact = line.transfer(s, form)
    resp = {k: m.transfer(s) for k, m in models.items()}
    refs = {k: ref.transfer(s, form) for k, ref in (references or {}).items()}
    exact_label = ("viscoelastic wall, exact (dissipative)" if getattr(line, "viscoelastic", False)
                   else "exact (dissipative)")
    fig = new_figure((11, 11))
    axes = fig.subplots(4, 2, sharex=True)
    for i in range(2):
        for j in range(2):
            am, ap = axes[2 * i, j], axes[2 * i + 1, j]
            am.semilogy(f, np.abs(exact[:, i, j]), "k", lw=1.6, label=exact_label)
            ap.plot(f, np.degrees(np.angle(exact[:, i, j])), "k", lw=1.6)
            for k, H in refs.items():
                am.semilogy(f, np.abs(H[:, i, j]), "-", color="0.6", lw=0.9, label=k)
                ap.plot(f, np.degrees(np.angle(H[:, i, j])), "-", color="0.6", lw=0.9)
            for k, H in resp.items():
                am.semilogy(f, np.abs(H[:, i, j]), "--", lw=1.0, label=k)
                ap.plot(f, np.degrees(np.angle(H[:, i, j])), "--", lw=1.0)
            am.set_title(f"{outs[i]} / {ins[j]}", fontsize=9)
            unit = ratio_unit(PORT_UNITS[outs[i].rsplit("_", 1)[-1]],
                              PORT_UNITS[ins[j].rsplit("_", 1)[-1]])
            am.set_ylabel(f"|H| [{unit}]")
            ap.set_ylabel("phase [deg]")
            am.grid(True, alpha=0.3)
            ap.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("frequency [Hz]")
    fig.suptitle(figure_title(title or f"{form} line: L = {line.length:g} m, "
                              f"d = {line.diameter * 1e3:g} mm, Dn = {line.dissipation_number:.3g}"))
    tight_layout(fig)
    if path:
        save_png(fig, path, dpi=100)
    return fig


def layout_panels(n: int, factor: float, unit: str) -> dict:
    """The layout figure (:func:`plot_layout`) before its panels: the figure and its grid,
    for ``n`` lengths drawn in the time unit ``unit`` (``factor`` per second); its trace
    panels are added, a length at a time, by :func:`layout_trace_row` (in a figure process
    while the next lengths run: :func:`prepare_layout_row`).

    Parameters
    ----------
    n : int
        Number of lengths
    factor : float
        Time unit per second (:func:`time_axis`), [unit/s]
    unit : str
        The time unit's name

    Returns
    -------
    dict
        What :func:`layout_trace_row` and :func:`plot_layout` build on: ``fig``, the grids,
        the rows made (``rows``) and what they found.
    """
    fig = new_figure((11, 1.7 * n + 4.4))
    outer = fig.add_gridspec(2, 1, height_ratios=[1.7 * n, 2.6], hspace=0.16)
    return {"fig": fig, "outer": outer, "grid": outer[0].subgridspec(n, 2, hspace=0.12),
            "n": n, "factor": factor, "unit": unit, "rows": 0, "first": {}, "lims": {},
            "shaded": False, "stopped": False, "measured": False, "inputs": []}


def layout_trace_row(panels: dict, r: int, length: float, res, summary: dict) -> None:
    """Add one length's port-pressure panels (supply left, return right) to the layout figure
    (:func:`layout_panels`), rows in order.

    Parameters
    ----------
    panels : dict
        The figure being made (:func:`layout_panels`)
    r : int
        The row: the length's index
    length : float
        The section length, [m]
    res : Traces
        Its run: ``supply`` and ``return`` port pressures [Pa], ``t_disturbance`` [s] and
        ``metrics_window`` in its metadata
    summary : dict
        Its metrics per port (``settling_time_s`` [s], ``settling_method``)
    """
    if r != panels["rows"]:
        raise ValueError(f"layout figure: row {r} given after {panels['rows']} rows")
    ports = ("supply", "return")
    fig, gs, first, lims = panels["fig"], panels["grid"], panels["first"], panels["lims"]
    n, factor, unit = panels["n"], panels["factor"], panels["unit"]
    L = length
    t_s = res.t * factor
    t0 = res.metadata.get("t_disturbance", 0.0)
    window = metrics_window_of(res)
    t1 = window[1] if window is not None else None
    for c, side in enumerate(ports):
        ax = fig.add_subplot(gs[r, c], sharex=first.get("x"), sharey=first.get(side))
        first.setdefault("x", ax)
        first.setdefault(side, ax)
        y = res[side] / 1e6
        k1 = int(np.count_nonzero(res.t <= t1)) if t1 else y.size
        ax.plot(t_s[:k1], y[:k1], lw=0.9, color="C0" if side == "supply" else "C3")
        lims.setdefault(side, []).extend([float(np.min(y[:k1])), float(np.max(y[:k1]))])
        if t1:   # after the far stop: grey, outside the metrics
            ax.plot(t_s[k1 - 1:], y[k1 - 1:], lw=0.7, color=OUTSIDE_TRACE_COLOR)
            ax.axvline(t1 * factor, color="r", lw=0.7, ls=":")
            panels["stopped"] = True
        if window is not None:
            panels["shaded"] |= shade_outside_window(ax, window[0], t1, res.t[0], res.t[-1],
                                                     factor)
        ax.axvline(t0 * factor, color="k", lw=0.7, ls=":")
        ts = summary[side].get("settling_time_s")
        if ts is not None and summary[side].get("settling_method") == "measured":
            ax.axvline((t0 + ts) * factor, color="C2", lw=0.8, ls="--")   # (an estimate
            # lies past the stop, where the trace shows the stop's own transient)
            panels["measured"] = True
        ax.grid(True, alpha=0.3)
        label = "close-coupled (0 m)" if L == 0 else f"L = {L:g} m"
        ax.text(0.99, 0.93, label, transform=ax.transAxes, ha="right", va="top", fontsize=8,
                bbox=dict(facecolor="white", edgecolor="none", alpha=0.7))
        if r == 0:
            ax.set_title(f"{side} port pressure [MPa]", fontsize=10)
        if r < n - 1:
            ax.tick_params(labelbottom=False)
        else:
            ax.set_xlabel(f"time [{unit}]")
            ax.set_xlim(t_s[0], t_s[-1])
    panels["rows"] += 1
    panels["inputs"].append((L, res, summary))


def _same_rows(panels, n, factor, lengths, runs, summaries) -> bool:
    """Whether the rows made beforehand (:func:`prepare_layout_row`) are the first rows of this
    figure: the same number of lengths, time unit and, row by row, inputs."""
    if panels["n"] != n or panels["factor"] != factor or panels["rows"] > n:
        return False
    for (L, res, summary), L1, res1, summary1 in zip(panels["inputs"], lengths, runs, summaries):
        same = (L == L1 and summary == summary1 and res.metadata == res1.metadata
                and np.array_equal(res.t, res1.t)
                and all(np.array_equal(res[p], res1[p]) for p in ("supply", "return")))
        if not same:
            return False
    return True


def prepare_layout_row(prepared: dict, n: int, r: int, length: float, res, summary: dict) -> None:
    """In a figure process (:meth:`hydroline.cli.figure_process.FigureProcess.prepare`), while
    the next lengths run: one length's trace panels of the layout figure, made now in the
    time unit of this run's length (the first row makes the figure); :func:`plot_layout`
    goes on from them where it finds the same rows and time unit, else starts anew.

    Parameters
    ----------
    prepared : dict
        What the figure process keeps for the figure (``"layout"``: the panels)
    n : int
        Number of lengths of the study
    r : int
        The length's index
    length : float
        The section length, [m]
    res : Traces
        Its run, as :func:`layout_trace_row` takes it
    summary : dict
        Its metrics per port, as :func:`layout_trace_row` takes them
    """
    if r == 0:
        prepared["layout"] = layout_panels(n, *time_axis(res.t[-1] - res.t[0]))
    panels = prepared.get("layout")
    if panels is not None and panels["rows"] == r:
        layout_trace_row(panels, r, length, res, summary)


def plot_layout(lengths, runs, summaries, wave_speeds, sides, title, path=None,
                prepared=None):
    """The layout study's figure (:meth:`hydroline.studies.LayoutStudy.plot`): port-pressure
    traces of every length stacked (the paper's Figs. 13-14: supply left, return right;
    dotted: step and piston stop, green dashed: a measured settling time; grey, as in every
    figure, outside the metrics window, said in the legend) above frequency and amplitude
    against length, each point labelled with its value where the label overlaps nothing
    (:func:`place_value_labels`). Its arguments are arrays and plain values
    (:meth:`~hydroline.studies.LayoutStudy.figure_data`), so that a figure process draws it
    without importing the model.

    Parameters
    ----------
    lengths : list of float
        Section lengths, [m]
    runs : list of Traces
        Per length, the ``supply`` and ``return`` port pressures [Pa]; ``t_disturbance``
        [s] and ``metrics_window`` in its metadata
    summaries : list of dict
        Per length, ``{"supply": {...}, "return": {...}}``: ``frequency_hz`` [Hz],
        ``amplitude_mpa``, ``first_excursion_mpa`` [MPa], ``settling_time_s`` [s] and
        ``settling_method`` (None where a metric does not exist)
    wave_speeds : dict
        Side -> wave speed of its section II, [m/s]
    sides : tuple
        The sides whose sections were set
    title : str
        Figure title
    path : str or Path
        Write the figure there (PNG) when given
    prepared : dict
        What a figure process made beforehand (:func:`prepare_layout_row`): its trace panels
        are used where they are this figure's first rows

    Returns
    -------
    matplotlib.figure.Figure
        The figure (written as PNG to ``path`` when given).
    """
    from matplotlib.lines import Line2D

    ports = ("supply", "return")
    n = len(lengths)
    factor, unit = time_axis(max(res.t[-1] - res.t[0] for res in runs))
    panels = prepared.get("layout") if prepared else None
    if panels is None or not _same_rows(panels, n, factor, lengths, runs, summaries):
        panels = layout_panels(n, factor, unit)   # (those made while the runs went on: as they are)
    for r in range(panels["rows"], n):
        layout_trace_row(panels, r, lengths[r], runs[r], summaries[r])
    fig, first, lims = panels["fig"], panels["first"], panels["lims"]
    outer, shaded, stopped, measured = (panels[k] for k in ("outer", "shaded", "stopped",
                                                             "measured"))
    for side, values in lims.items():   # y-range from the metrics windows only
        lo, hi = min(values), max(values)
        pad = 0.08 * (hi - lo) if hi > lo else 0.05
        first[side].set_ylim(lo - pad, hi + pad)
    sub = outer[1].subgridspec(1, 2, wspace=0.25)
    ax_f, ax_a = fig.add_subplot(sub[0, 0]), fig.add_subplot(sub[0, 1])
    order = np.argsort(np.asarray(lengths, dtype=float), kind="quicksort")   # (as a table sorts)
    by_length = np.asarray(lengths, dtype=float)[order]

    def metric(side, key):   # one metric of every length, in the order of by_length; NaN: none
        values = [summaries[k][side].get(key) for k in order]
        return np.array([np.nan if v is None else v for v in values], dtype=float)

    values = {"f": [], "a": []}   # value labels, placed when the panels are laid out
    for side, color in (("supply", "C0"), ("return", "C3")):
        frequency, amplitude = metric(side, "frequency_hz"), metric(side, "amplitude_mpa")
        ax_f.plot(by_length, frequency, "o-", color=color, label=side)
        ax_a.plot(by_length, amplitude, "o-", color=color, label=f"{side}: oscillation amplitude")
        ax_a.plot(by_length, metric(side, "first_excursion_mpa"), "^:", color=color, alpha=0.6,
                  ms=4, label=f"{side}: first excursion |p - p0|")
        for L, fv, av in zip(by_length, frequency, amplitude):
            if np.isfinite(fv):
                values["f"].append((L, fv, f"{fv:.0f}", color))
            if np.isfinite(av):
                values["a"].append((L, av, f"{av:.2f}", color))
        c = wave_speeds.get(side)
        if c and side in sides and max(lengths) > 0:
            lo = min([L for L in lengths if L > 0] + [max(lengths)])
            Ls = np.linspace(0.8 * lo, max(lengths), 100)
            ax_f.plot(Ls, c / (4 * Ls), ls="--", lw=0.8, color=color,
                      label=f"{side}: c/(4L) of section II alone")
    ax_f.set_ylabel("oscillation frequency [Hz]")
    ax_a.set_ylabel("port pressure [MPa]")
    longest = max(max(lengths), 1e-3)
    for ax in (ax_f, ax_a):
        ax.set_xlabel("section II length [m]")
        ax.grid(True, alpha=0.3)
        # room on the right for the labels of the longest section's points
        ax.set_xlim(-0.06 * longest, 1.1 * longest)
    ax_f.legend(fontsize=7, loc="upper right")
    ax_a.legend(fontsize=7, loc="lower right")
    lo, hi = ax_a.get_ylim()   # from 0 (markers at 0 whole), room above the top labels
    ax_a.set_ylim(-0.06 * hi, 1.08 * hi)
    lo, hi = ax_f.get_ylim()
    ax_f.set_ylim(lo - 0.06 * (hi - lo), hi + 0.06 * (hi - lo))
    flat = sorted({L for L, s in zip(lengths, summaries)
                   if any(s[side].get("frequency_hz") is None for side in ports)})
    if flat:
        ax_f.text(0.02, 0.04, "no point at " + ", ".join(f"{L:g}" for L in flat) +
                  " m: no oscillation", transform=ax_f.transAxes, fontsize=8, color="0.4")
    height = fig.get_figheight()
    text = wrap_title(title, fig.get_figwidth(), 11)
    fig.suptitle(text, fontsize=11, y=1 - 0.08 / height, va="top")
    extra = 0.2 * text.count("\n")   # [inch] below a title of more lines
    handles = [outside_window_handle(OUTSIDE_WINDOW_LABEL + (
        " (after the piston's stop: not in the y-range)" if stopped else ""))] \
        if shaded else []
    handles.append(Line2D([], [], color="k", lw=0.7, ls=":", label="valve step"))
    if stopped:
        handles.append(Line2D([], [], color="r", lw=0.7, ls=":", label="piston at its stop"))
    if measured:
        handles.append(Line2D([], [], color="C2", lw=0.8, ls="--",
                              label="settled (measured settling time)"))
    fig.legend(handles=handles, loc="upper center", ncol=len(handles), fontsize=8,
               frameon=False, bbox_to_anchor=(0.5, 1 - (0.3 + extra) / height))
    fig.subplots_adjust(left=0.07, right=0.98, top=1 - (0.85 + extra) / height, bottom=0.05)
    # (both panels' limits set above, their legends at fixed corners: no draw needed first)
    place_value_labels(ax_f, values["f"], draw_first=False)
    place_value_labels(ax_a, values["a"], draw_first=False)
    if path is not None:
        save_png(fig, path, dpi=110)
    return fig
