"""Figures a person would rather look at than read (Matplotlib, Agg backend)."""
from __future__ import annotations

import numpy as np

__all__ = ["plot_result", "PRESSURE_PANELS", "new_figure", "save_png", "Traces",
           "column_envelope", "figure_title", "TITLE_CHARACTERS"]

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
    t : array_like     Times, [s]
    columns : dict     Name -> values at ``t``, [SI]
    metadata : dict    What the figure reads of the run's metadata (``metrics_window``,
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
    x : array         Abscissae, non-decreasing, [any unit]
    y : array         Ordinates, [any unit]
    x0, x1 : float    Abscissae at the left and right edges of the axes, [unit of x]
    columns : int     Pixel columns between ``x0`` and ``x1``

    Returns
    -------
    numpy.ndarray  Sorted indices into ``x`` (all of them when the line has no more than four
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
    figsize : tuple   (width, height), [inch]
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
    text : str  The title (it may hold a rig's name, of any length)

    Returns
    -------
    str
    """
    text = str(text)
    return text if len(text) <= TITLE_CHARACTERS else text[:TITLE_CHARACTERS - 3] + "..."


def save_png(fig, path, dpi: int = 100) -> None:
    """Write a figure as PNG with light compression (zlib level 1: about 10 % larger files
    than Matplotlib's default level 6, and ~30 ms less per figure at 110 dpi).

    Parameters
    ----------
    fig : matplotlib.figure.Figure  The figure
    path : str or Path              The PNG file to write
    dpi : int                       Resolution, [dots per inch]
    """
    fig.savefig(path, dpi=dpi, pil_kwargs={"compress_level": 1})


def _figure(n):
    fig = new_figure((8, 2.4 * n + 0.6))
    return fig, fig.subplots(n, 1, sharex=True, squeeze=False)


def _window_end(result):
    """End of the metrics window (piston clear of its stops), [s]; None when it is the end."""
    window = result.metadata.get("metrics_window")
    t1 = window[1] if window is not None and window[2] == "stop" else None
    return t1 if t1 is not None and t1 < result.t[-1] else None


def _limits(values, margin=0.08):
    lo, hi = float(np.min(values)), float(np.max(values))
    pad = margin * (hi - lo) if hi > lo else max(abs(hi), 1.0) * 0.05
    return lo - pad, hi + pad


#: Left and right edges of :func:`plot_result`'s panels, [fraction of the figure's width].
PANEL_LEFT, PANEL_RIGHT = 0.11, 0.98


def plot_result(result, signals=None, path=None, title=None):
    """Plot a simulation result; panels of the paper's Figs. 10-12 by default.

    When the piston reaches a stop before the end (the open-loop step), the part after it
    -- a second transient, outside the metrics window -- is drawn in grey on a shaded
    background, and every panel's y-range is set by the metrics window, so the oscillation
    after the step (what the paper's Figs. 10-12 show) fills the panel.

    Parameters
    ----------
    result : SimulationResult or Traces
    signals : list[str]   Signals to plot, one panel each (SI units); default panels when None
    path : str            Write a PNG there when given
    title : str           Figure title

    Returns
    -------
    matplotlib.figure.Figure
    """
    panels = PRESSURE_PANELS if signals is None else tuple((s, (s,), 1.0) for s in signals)
    series = {k: result[k] for k in result.columns}
    if signals is None and "position_reference" in result:   # closed loop: tracking
        series["tracking_error"] = result["position_reference"] - result["piston_position"]
        panels = panels + (("Command and position [mm]", ("position_reference", "piston_position"), 1e3),
                           ("Tracking error [mm]", ("tracking_error",), 1e3))
    panels = tuple(p for p in panels if any(k in series for k in p[1]))
    fig, axes = _figure(len(panels))
    dpi = 110
    # pixel columns of a panel: each line is drawn through its extremes per column
    columns = int(np.ceil(fig.get_figwidth() * (PANEL_RIGHT - PANEL_LEFT) * dpi))
    t_ms = result.t * 1e3
    t1 = _window_end(result)
    inside = result.t <= t1 if t1 is not None else np.ones(len(result.t), bool)
    k1 = int(np.count_nonzero(inside))
    t0 = result.metadata.get("t_disturbance")
    for ax, (label, keys, scale) in zip(axes[:, 0], panels):
        shown = []
        for k in keys:
            if k in series:
                y = series[k] * scale
                i = column_envelope(t_ms[:k1], y[:k1], t_ms[0], t_ms[-1], columns)
                ax.plot(t_ms[i], y[i], lw=1.0, label=k.replace("_", " "))
                if t1 is not None:   # after the stop: grey, and not in the y-range
                    i = k1 - 1 + column_envelope(t_ms[k1 - 1:], y[k1 - 1:], t_ms[0], t_ms[-1],
                                                 columns)
                    ax.plot(t_ms[i], y[i], lw=0.8, color="0.6")
                shown.append(y[:k1])
        if t1 is not None and shown:
            ax.set_ylim(*_limits(np.concatenate(shown)))
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        if len(shown) > 1:   # one curve: the axis label names it (and "best" costs a draw)
            ax.legend(loc="best", fontsize=8)
    for ax in axes[:, 0]:
        if t0:
            ax.axvline(t0 * 1e3, color="0.6", lw=0.8, ls=":")
        if t1 is not None:
            ax.axvspan(t1 * 1e3, t_ms[-1], color="0.88", zorder=0, lw=0)
            ax.axvline(t1 * 1e3, color="r", lw=0.8, ls=":")
        ax.set_xlim(t_ms[0], t_ms[-1])
    if t1 is not None:
        axes[0, 0].annotate(f"piston at its stop ({t1 * 1e3:.0f} ms): outside the metrics window,\n"
                            "greyed, not in the y-range", (t1 * 1e3, 0.98),
                            xycoords=("data", "axes fraction"), xytext=(4, 0),
                            textcoords="offset points", fontsize=8, color="r", ha="left", va="top",
                            bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="none", alpha=0.85))
    axes[-1, 0].set_xlabel("time [ms]")
    height = fig.get_figheight()   # fixed margins, [inch]: tight_layout would draw twice
    default = f"hydroline: {result.metadata.get('scenario', 'simulation')}"
    fig.suptitle(figure_title(title or default), y=1 - 0.1 / height, va="top")
    fig.subplots_adjust(left=PANEL_LEFT, right=PANEL_RIGHT, top=1 - 0.5 / height,
                        bottom=0.5 / height, hspace=0.12)
    if path:
        save_png(fig, path, dpi=dpi)
    return fig


def plot_line_response(line, models, f, form, path=None, title=None):
    """Magnitude and phase of every entry of a form: exact (dissipative) vs line models.

    Parameters
    ----------
    line : Line       The hose section, its exact (dissipative) transfer matrix the reference
    models : dict     label -> model with ``transfer(s)``
    f : array         Frequencies, [Hz]
    form : str        Causality form of the two-port (a key of ``FORM_PORTS``)
    path : str        File to save the figure to (PNG, ...); None: not saved
    title : str       Figure title; None: the line's length, diameter and dissipation number

    Returns
    -------
    matplotlib.figure.Figure  Magnitude [SI] and phase [deg] of the four entries against
                              frequency [Hz]
    """
    from .lines.line import FORM_PORTS

    ins, outs = FORM_PORTS[form]
    s = 2j * np.pi * f
    exact = line.transfer(s, form)
    resp = {k: m.transfer(s) for k, m in models.items()}
    fig = new_figure((11, 11))
    axes = fig.subplots(4, 2, sharex=True)
    for i in range(2):
        for j in range(2):
            am, ap = axes[2 * i, j], axes[2 * i + 1, j]
            am.semilogy(f, np.abs(exact[:, i, j]), "k", lw=1.6, label="exact (dissipative)")
            ap.plot(f, np.degrees(np.angle(exact[:, i, j])), "k", lw=1.6)
            for k, H in resp.items():
                am.semilogy(f, np.abs(H[:, i, j]), "--", lw=1.0, label=k)
                ap.plot(f, np.degrees(np.angle(H[:, i, j])), "--", lw=1.0)
            am.set_title(f"{outs[i]} / {ins[j]}", fontsize=9)
            am.set_ylabel("|H| [SI]")
            ap.set_ylabel("phase [deg]")
            am.grid(True, alpha=0.3)
            ap.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("frequency [Hz]")
    fig.suptitle(figure_title(title or f"{form} line: L = {line.length:g} m, "
                              f"d = {line.diameter * 1e3:g} mm, Dn = {line.dissipation_number:.3g}"))
    fig.tight_layout()
    if path:
        save_png(fig, path, dpi=100)
    return fig
