"""Figures a person would rather look at than read (Matplotlib, Agg backend)."""
from __future__ import annotations

import numpy as np

__all__ = ["plot_result", "PRESSURE_PANELS"]

#: The paper's Figs. 10-12: valve port pressures, chamber pressures, piston velocity.
PRESSURE_PANELS = (
    ("Supply port [MPa]", ("supply_port_pressure",), 1e-6),
    ("Return port [MPa]", ("return_port_pressure",), 1e-6),
    ("Chamber pressures [MPa]", ("bottom_chamber_pressure", "top_chamber_pressure"), 1e-6),
    ("Piston velocity [m/s]", ("piston_velocity",), 1.0),
)


def _figure(n):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt.subplots(n, 1, figsize=(8, 2.4 * n + 0.6), sharex=True, squeeze=False)


def plot_result(result, signals=None, path=None, title=None):
    """Plot a simulation result; panels of the paper's Figs. 10-12 by default.

    Parameters
    ----------
    result : SimulationResult
    signals : list[str]   Signals to plot, one panel each (SI units); default panels when None
    path : str            Write a PNG there when given
    title : str           Figure title

    Returns
    -------
    matplotlib.figure.Figure
    """
    panels = PRESSURE_PANELS if signals is None else tuple((s, (s,), 1.0) for s in signals)
    panels = tuple(p for p in panels if any(k in result.data for k in p[1]))
    fig, axes = _figure(len(panels))
    t_ms = result.t * 1e3
    for ax, (label, keys, scale) in zip(axes[:, 0], panels):
        for k in keys:
            if k in result.data:
                ax.plot(t_ms, result[k] * scale, lw=1.0, label=k.replace("_", " "))
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    t1 = result.metadata.get("metrics_window_end")
    for ax in axes[:, 0]:
        t0 = result.metadata.get("t_disturbance")
        if t0:
            ax.axvline(t0 * 1e3, color="0.6", lw=0.8, ls=":")
        if t1 and t1 < result.t[-1]:
            ax.axvline(t1 * 1e3, color="r", lw=0.8, ls=":")
    if t1 and t1 < result.t[-1]:
        axes[0, 0].annotate("piston reaches its stop", (t1 * 1e3, 1.0), xycoords=("data", "axes fraction"),
                            fontsize=8, color="r", ha="left", va="top")
    axes[-1, 0].set_xlabel("time [ms]")
    fig.suptitle(title or f"hydroline: {result.metadata.get('scenario', 'simulation')}")
    fig.tight_layout()
    if path:
        fig.savefig(path, dpi=110)
    return fig


def plot_line_response(line, models, f, form, path=None, title=None):
    """Magnitude and phase of every entry of a form: exact (dissipative) vs line models.

    Parameters
    ----------
    line : Line
    models : dict     label -> model with ``transfer(s)``
    f : array         Frequencies, [Hz]
    form : str
    """
    from .lines.line import FORM_PORTS

    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    ins, outs = FORM_PORTS[form]
    s = 2j * np.pi * f
    exact = line.transfer(s, form)
    resp = {k: m.transfer(s) for k, m in models.items()}
    fig, axes = plt.subplots(4, 2, figsize=(11, 11), sharex=True)
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
    fig.suptitle(title or f"{form} line: L = {line.length:g} m, d = {line.diameter * 1e3:g} mm, "
                 f"Dn = {line.dissipation_number:.3g}")
    fig.tight_layout()
    if path:
        fig.savefig(path, dpi=100)
    return fig
