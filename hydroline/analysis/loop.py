"""Bode data and loop margins of a linearised model, from its frequency response.

:func:`hydroline.analysis.linearize` returns a python-control ``StateSpace`` of ~60 states
(the hoses' modes). ``control.margin`` on it converts the model to a transfer-function
polynomial first and fails on a model that size; the margins read off the frequency
response do not: :func:`frequency_response_data` evaluates ``C (jwI - A)^-1 B + D`` directly
(:func:`~hydroline.analysis.frequency.state_space_response`, balanced by the model's state
scales) and hands it to ``control.frd``; :func:`stability_margins` reads the gain and phase
margins of a loop gain from it.

Example: the margins of the default rig's position loop, P control of gain ``K_p`` [A/m]
closed around the valve-current-to-position channel::

    import hydroline
    rig = hydroline.load_rig()
    plant = hydroline.linearize(rig, inputs=["valve_current"], outputs=["piston_position"])
    m = hydroline.stability_margins(plant, gain=rig["controller.proportional_gain"])
    m["phase_margin_deg"], m["gain_crossover_hz"], m["gain_margin_db"]
"""
from __future__ import annotations

import numpy as np

from .frequency import state_space_response

__all__ = ["bode_data", "frequency_response_data", "stability_margins"]

#: Default frequency grid of :func:`bode_data` and :func:`stability_margins`: 0.1 Hz to 2 kHz,
#: 2000 log-spaced points (the hoses' modes lie between ~30 Hz and ~1 kHz), [Hz].
DEFAULT_FREQUENCIES = (0.1, 2000.0, 2000)


def _grid(f):
    if f is None:
        lo, hi, n = DEFAULT_FREQUENCIES
        return np.logspace(np.log10(lo), np.log10(hi), n)
    f = np.asarray(f, dtype=float)
    if f.ndim != 1 or len(f) < 2 or np.any(np.diff(f) <= 0) or f[0] <= 0:
        raise ValueError("f: frequencies must increase and be > 0 Hz")
    return f


def _channel(sys, input_name, output):
    """Indices of one input and one output of ``sys`` (the only ones when None)."""
    inputs, outputs = list(sys.input_labels), list(sys.output_labels)
    picked = []
    for name, labels, what in ((input_name, inputs, "input"), (output, outputs, "output")):
        if name is None:
            if len(labels) != 1:
                raise ValueError(f"{what}: the model has {len(labels)} {what}s "
                                 f"({', '.join(labels)}); name one")
            picked.append(0)
        elif name not in labels:
            raise ValueError(f"{what}: {name!r} is not one of the model's {what}s "
                             f"({', '.join(labels)})")
        else:
            picked.append(labels.index(name))
    return picked


def frequency_response_data(sys, f=None):
    """The model's frequency response as a python-control FRD (every input and output).

    Parameters
    ----------
    sys : control.StateSpace
        A linearised model (:func:`hydroline.analysis.linearize`); its ``state_scales``
        attribute, where present, balances ``A`` before solving.
    f : array_like
        Increasing frequencies, [Hz] (None: 0.1 Hz to 2 kHz, 2000 log-spaced).

    Returns
    -------
    control.FrequencyResponseData
        Response in SI units (output unit / input unit) at ``omega = 2 pi f`` [rad/s], with
        the model's input and output names: ``control.stability_margins``, ``control.bode_plot``
        and ``control.feedback`` work on it.
    """
    import control

    f = _grid(f)
    H = state_space_response(sys.A, sys.B, sys.C, sys.D, f, getattr(sys, "state_scales", None))
    return control.frd(np.moveaxis(H, 0, -1), 2 * np.pi * f, inputs=list(sys.input_labels),
                       outputs=list(sys.output_labels))


def bode_data(sys, f=None, input_name=None, output=None):
    """Bode data of one channel of a linearised model: gain and phase against frequency.

    Parameters
    ----------
    sys : control.StateSpace
        A linearised model (:func:`hydroline.analysis.linearize`).
    f : array_like
        Increasing frequencies, [Hz] (None: 0.1 Hz to 2 kHz, 2000 log-spaced).
    input_name : str
        The input (None: the model's only one).
    output : str
        The output (None: the model's only one).

    Returns
    -------
    pandas.DataFrame
        Columns ``frequency_hz`` [Hz], ``gain`` (``|H|`` in SI units, output unit / input
        unit, e.g. m/A), ``gain_db`` (``20 log10 |H|``) and ``phase_deg`` (unwrapped, [deg]).
    """
    import pandas as pd

    f = _grid(f)
    i, o = _channel(sys, input_name, output)
    H = state_space_response(sys.A, sys.B, sys.C, sys.D, f,
                             getattr(sys, "state_scales", None))[:, o, i]
    gain = np.abs(H)
    with np.errstate(divide="ignore"):
        db = 20 * np.log10(gain)
    return pd.DataFrame({"frequency_hz": f, "gain": gain, "gain_db": db,
                         "phase_deg": np.degrees(np.unwrap(np.angle(H)))})


def stability_margins(sys, gain=1.0, f=None, input_name=None, output=None) -> dict:
    """Gain and phase margins of the loop gain ``L = gain * H``, ``H`` one channel of ``sys``,
    read from its frequency response (``control.stability_margins`` on
    :func:`frequency_response_data`; the state-space route of ``control.margin`` fails on a
    model with the hoses' ~60 states).

    Parameters
    ----------
    sys : control.StateSpace
        A linearised model (:func:`hydroline.analysis.linearize`), e.g. valve current [A] to
        piston position [m].
    gain : float
        The controller's gain that closes the loop, [input unit / output unit] (e.g. a P
        controller's ``controller.proportional_gain`` [A/m]); negative feedback.
    f : array_like
        Increasing frequencies, [Hz] (None: 0.1 Hz to 2 kHz, 2000 log-spaced); the crossovers
        must lie inside it.
    input_name : str
        The input (None: the model's only one).
    output : str
        The output (None: the model's only one).

    Returns
    -------
    dict
        ``gain_margin`` (factor by which the loop gain may grow, [-]; inf when the phase never
        crosses -180 deg in ``f``), ``gain_margin_db``, ``phase_margin_deg`` [deg; inf when the
        gain never crosses 1], ``phase_crossover_hz`` and ``gain_crossover_hz`` [Hz; None where
        there is none].
    """
    import control

    f = _grid(f)
    i, o = _channel(sys, input_name, output)
    H = state_space_response(sys.A, sys.B, sys.C, sys.D, f,
                             getattr(sys, "state_scales", None))[:, o, i]
    loop = control.frd(gain * H, 2 * np.pi * f)
    gm, pm, _, wpc, wgc, _ = control.stability_margins(loop)

    def hz(w):
        return float(w) / (2 * np.pi) if w is not None and np.isfinite(w) else None

    gm = float(gm) if gm is not None else float("inf")
    return {"gain_margin": gm,
            "gain_margin_db": (float(20 * np.log10(gm)) if np.isfinite(gm) and gm > 0
                               else float("inf")),
            "phase_margin_deg": float(pm) if pm is not None else float("inf"),
            "phase_crossover_hz": hz(wpc), "gain_crossover_hz": hz(wgc)}
