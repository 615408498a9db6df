"""Figures of the analysis tools: Bode plots, measured vs fitted traces, friction maps.

Matplotlib with the Agg backend; every function returns the figure and writes a PNG when
given a path.
"""
from __future__ import annotations

import numpy as np

from ..plotting import figure_title, ratio_unit, tight_layout

__all__ = ["plot_bode", "plot_fit", "plot_friction", "SIGNAL_DISPLAY"]

#: How signals are shown: name -> (label, unit shown, factor from SI).
SIGNAL_DISPLAY = {
    "supply_port_pressure": ("supply port pressure", "MPa", 1e-6),
    "return_port_pressure": ("return port pressure", "MPa", 1e-6),
    "bottom_chamber_pressure": ("bottom chamber pressure", "MPa", 1e-6),
    "top_chamber_pressure": ("top chamber pressure", "MPa", 1e-6),
    "piston_position": ("piston position", "mm", 1e3),
    "piston_velocity": ("piston velocity", "m/s", 1.0),
    "valve_current": ("valve current", "mA", 1e3),
    "external_force": ("external force", "kN", 1e-3),
    "pump_pressure": ("pump pressure", "MPa", 1e-6),
    "tank_pressure": ("tank pressure", "MPa", 1e-6),
}


class _Figures:
    """``subplots`` as pyplot has it, on a figure made without pyplot (Agg canvas)."""

    @staticmethod
    def subplots(nrows=1, ncols=1, figsize=None, **kw):
        from ..plotting import new_figure

        fig = new_figure(figsize)
        return fig, fig.subplots(nrows, ncols, **kw)


def _save_png(fig, path):
    from ..plotting import save_png

    save_png(fig, path, dpi=100)


def _plt():
    return _Figures


def _display(name):
    return SIGNAL_DISPLAY.get(name, (name.replace("_", " "), "SI", 1.0))


def plot_bode(f, curves: dict, input_name: str, outputs, bandwidths: dict | None = None,
              path=None, title=None, highest_mode_hz: float | None = None,
              passbands: dict | None = None):
    """Magnitude and phase of ``output/input`` for several model variants.

    Parameters
    ----------
    f : array
        Frequencies, [Hz]
    curves : dict
        Label -> complex array ``(len(f), len(outputs))`` in SI units
    input_name : str
        Input channel (for the axis labels)
    outputs : list[str]
        Output channels, one column of panels each
    bandwidths : dict
        Label -> {output: -3 dB bandwidth [Hz] or None}, drawn as dotted
        lines and listed in each panel's lower left, in the curves' colours
    path : str
        PNG to write
    title : str
        Figure title
    highest_mode_hz : float
        Highest retained mode of the modal lines (the frequency up to
        which they follow the exact lines), drawn as a grey vertical
        line, [Hz]
    passbands : dict
        Label -> {output: :class:`~hydroline.analysis.frequency.Passband`}:
        a first crossing in a notch is marked so, and the frequency up to
        which the gain stays within 3 dB is listed beside it

    Returns
    -------
    matplotlib.figure.Figure
        The figure (also written to ``path`` when given)
    """
    plt = _plt()
    outputs = list(outputs)
    f_top = highest_mode_hz if highest_mode_hz is not None and np.isfinite(highest_mode_hz) \
        and f[0] < highest_mode_hz < f[-1] else None
    n = len(outputs)
    fig, axes = plt.subplots(2, n, figsize=(max(4.6 * n + 0.8, 8.0), 7.0), sharex=True, squeeze=False)
    styles = ["-", "--", ":", "-."]
    colors = ["C0", "k", "C3", "C2"]
    in_label, in_unit, in_factor = _display(input_name)
    for j, out in enumerate(outputs):
        o_label, o_unit, o_factor = _display(out)
        am, ap = axes[0, j], axes[1, j]
        notes = []
        for k, (label, H) in enumerate(curves.items()):
            h = np.asarray(H)[:, j] * o_factor / in_factor
            mag = np.abs(h)
            if not np.any(mag > 0):
                am.plot([], [], styles[k % 4], color=colors[k % 4], label=f"{label} (held constant)")
                continue
            with np.errstate(divide="ignore"):
                am.semilogx(f, 20 * np.log10(mag), styles[k % 4], color=colors[k % 4], lw=1.3,
                            label=label)
            phase = np.degrees(np.unwrap(np.angle(h)))
            phase -= 360.0 * np.floor((phase[0] + 270.0) / 360.0)   # start in [-270, 90) deg
            ap.semilogx(f, phase, styles[k % 4], color=colors[k % 4], lw=1.3)
            bw = (bandwidths or {}).get(label, {}).get(out)
            band = (passbands or {}).get(label, {}).get(out)
            if bw:
                am.axvline(bw, color=colors[k % 4], lw=0.8, ls=(0, (2, 3)))
                text = f"{bw:.1f} Hz"
                if band is not None and band.in_notch:
                    up = band.within_3db_up_to_hz
                    text += (" in a notch; within 3 dB up to "
                             + (f"{up:.1f} Hz" if up is not None else f"{f[-1]:.0f} Hz and beyond"))
                notes.append((text, colors[k % 4]))
        for k, (text, color) in enumerate(notes):
            am.text(0.02, 0.03 + 0.08 * (len(notes) - 1 - k), ("-3 dB: " if k == 0 else "") + text,
                    transform=am.transAxes, fontsize=8, color=color, ha="left", va="bottom")
        if f_top is not None:
            for ax in (am, ap):
                ax.axvline(f_top, color="C4", lw=1.0, ls="-.",
                           label=f"highest retained mode, {f_top:.0f} Hz" if ax is am else None)
        am.set_title(f"{o_label} / {in_label}", fontsize=10)
        am.set_ylabel(f"|H| [dB re 1 {ratio_unit(o_unit, in_unit)}]")
        ap.set_ylabel("phase [deg]")
        ap.set_xlabel("frequency [Hz]")
        for ax in (am, ap):
            ax.grid(True, which="both", alpha=0.3)
    axes[0, 0].legend(fontsize=8, loc="best")
    fig.suptitle(figure_title(title or "hydroline bode"), fontsize=10)
    tight_layout(fig)
    if path:
        _save_png(fig, path)
    return fig


def plot_fit(t, measured: dict, initial: dict, fitted: dict, path=None, title=None,
             windows=None, rms=None, start_rms=None, worse=None):
    """Measured, initial-model and fitted-model traces, one panel per signal.

    Parameters
    ----------
    t : array
        Times, [s]
    measured, initial, fitted : dict
        Signal name -> array in SI (initial may be empty)
    path : str
        PNG to write
    title : str
        Figure title
    windows : list
        (first, last) times of samples the fit left out, shaded, [s]
    rms, start_rms : dict
        Signal -> rms residual of the fitted / initial model, [SI], shown
        in the legend
    worse : dict
        Signal -> why the fitted model is worse than the start there: written
        in that panel (a panel never shows it worse without saying why)

    Returns
    -------
    matplotlib.figure.Figure
        The figure (also written to ``path`` when given)
    """
    from ..plotting import time_axis

    plt = _plt()
    names = list(measured)
    rms, start_rms, worse = rms or {}, start_rms or {}, worse or {}
    t = np.asarray(t, dtype=float)
    tf, unit_t = time_axis(t[-1] - t[0] if len(t) else 0.0)
    ts = t * tf
    fig, axes = plt.subplots(len(names), 1, figsize=(8, 2.3 * len(names) + 0.8), sharex=True,
                             squeeze=False)
    for ax, k in zip(axes[:, 0], names):
        label, unit, factor = _display(k)

        def with_rms(text, table):
            return f"{text} (rms {table[k] * factor:.3g} {unit})" if k in table else text

        ax.plot(ts, measured[k] * factor, ".", ms=2, color="k", label="measured")
        if k in initial:
            ax.plot(ts, initial[k] * factor, ":", color="C1", lw=1.0,
                    label=with_rms("initial model", start_rms))
        if k in fitted:
            ax.plot(ts, fitted[k] * factor, "-", color="C0", lw=1.2,
                    label=with_rms("fitted model", rms))
        for j, (a, b) in enumerate(windows or []):
            ax.axvspan(a * tf, b * tf, color="C3", alpha=0.15, lw=0,
                       label="left out: not resolved by the sampling" if j == 0 else None)
        if k in worse:
            ax.text(0.01, 0.03, _wrap(f"fitted worse than the start here: {worse[k]}", 110),
                    transform=ax.transAxes, fontsize=7, color="C3", ha="left", va="bottom")
        ax.set_ylabel(f"{label} [{unit}]", fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    axes[-1, 0].set_xlabel(f"time [{unit_t}]")
    fig.suptitle(figure_title(title or "hydroline fit: measured vs fitted"))
    tight_layout(fig)
    if path:
        _save_png(fig, path)
    return fig


def _wrap(text, width):
    import textwrap

    return "\n".join(textwrap.wrap(text, width))


def plot_friction(points: dict, fit, path=None, title=None):
    """Friction force against piston velocity: identified points and the fitted (M24).

    Parameters
    ----------
    points : dict
        Label -> (velocity [m/s], friction force [N]) arrays
    fit : StribeckFit
        The fitted model (None to show the points only)
    path : str
        PNG to write
    title : str
        Figure title

    Returns
    -------
    matplotlib.figure.Figure
        The figure (also written to ``path`` when given)
    """
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    marks = ["o", ".", "s", "^"]
    for k, (label, (v, F)) in enumerate(points.items()):
        ax.plot(np.asarray(v) * 1e3, F, marks[k % 4], ms=3 if marks[k % 4] == "." else 5,
                alpha=0.6, label=label)
    if fit is not None:
        vmax = max(np.max(np.abs(v)) for v, _ in points.values()) if points else 0.1
        v = np.linspace(-vmax, vmax, 801)
        label = "(M24) fitted, up/down separately"
        if not getattr(fit, "static_identified", True):
            # the hump (F_s, C_s) is not identified: draw only where points are
            vmin = min(np.min(np.abs(pv)) for pv, _ in points.values()) if points else 0.0
            v = np.where(np.abs(v) >= vmin, v, np.nan)
            label += f"; F_s, C_s not identified: not drawn below {vmin * 1e3:.3g} mm/s"
        ax.plot(v * 1e3, fit.force(v), "k", lw=1.5, label=label)
    ax.axhline(0, color="0.6", lw=0.6)
    ax.axvline(0, color="0.6", lw=0.6)
    ax.set_xlabel("piston velocity [mm/s]")
    ax.set_ylabel("friction force [N]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(figure_title(title or "friction identification"))
    tight_layout(fig)
    if path:
        _save_png(fig, path)
    return fig
