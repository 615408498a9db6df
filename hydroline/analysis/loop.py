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

from .frequency import bandwidth, state_space_response

__all__ = ["bode_data", "frequency_response_data", "stability_margins", "closed_loop_bandwidth",
           "closed_loop_position_response", "position_bandwidth"]

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


def closed_loop_position_response(f, H, proportional_gain, integral_gain=0.0,
                                  derivative_gain=0.0):
    """Frequency response of a position loop closed around a plant, reference to position.

    The loop is the :class:`~hydroline.components.PositionController`'s: ``i = Kp e + Ki
    int(e) - Kd v`` (the derivative on the measured velocity), ``e = x_ref - x``, so that
    with the plant ``x = H i``

        T = H (Kp + Ki/s) / (1 + H (Kp + Ki/s + Kd s)),     s = j 2 pi f,

    the current limit left out (a linear, small-signal loop).

    Parameters
    ----------
    f : array_like
        Frequencies, [Hz] (> 0)
    H : array_like
        The plant's response from valve current to piston position at f, [m/A]
    proportional_gain : float
        Kp, [A/m]
    integral_gain : float
        Ki, [A/(m s)]
    derivative_gain : float
        Kd, [A s/m]

    Returns
    -------
    ndarray
        Complex ``T`` at f, [m/m]
    """
    s = 2j * np.pi * np.asarray(f, dtype=float)
    H = np.asarray(H, dtype=complex)
    reference = proportional_gain + integral_gain / s
    return H * reference / (1.0 + H * (reference + derivative_gain * s))


def closed_loop_bandwidth(f, H, proportional_gain, integral_gain=0.0, derivative_gain=0.0):
    """-3 dB bandwidth of a position loop closed around a plant's frequency response.

    :func:`~hydroline.analysis.frequency.bandwidth` of
    :func:`closed_loop_position_response` against its gain at ``f[0]`` (take ``f[0]`` a
    few decades below the bandwidth: a lag of corner f_c has lost ``(f[0]/f_c)^2/2`` there).

    Parameters
    ----------
    f : array_like
        Increasing frequencies, [Hz]; ``f[0]`` well below the bandwidth (the reference gain)
    H : array_like
        The plant's response from valve current to piston position at f, [m/A]
    proportional_gain : float
        Kp, [A/m]
    integral_gain : float
        Ki, [A/(m s)]
    derivative_gain : float
        Kd, [A s/m]

    Returns
    -------
    float or None
        Bandwidth, [Hz]; None where ``|T|`` stays within 3 dB up to ``f[-1]``.

    Examples
    --------
    An integrating plant ``H = Kv/s`` under P control closes to a first-order lag of corner
    ``Kp Kv / (2 pi)``: 1.5 A/m and 20 m/(s A) give 4.77 Hz.

    >>> import numpy as np
    >>> f = np.logspace(-2, 3, 5001)
    >>> round(closed_loop_bandwidth(f, 20.0 / (2j * np.pi * f), 1.5), 2)
    4.77
    """
    return bandwidth(f, closed_loop_position_response(f, H, proportional_gain, integral_gain,
                                                      derivative_gain))


#: Frequencies :func:`position_bandwidth` first evaluates: 0.1 Hz to 2 kHz, 12 per decade
#: (the crossing is then refined between the two samples around it), [Hz].
BANDWIDTH_SEARCH = (0.1, 2000.0, 52)
#: The frequency of :func:`position_bandwidth`'s reference gain (the closed loop's
#: low-frequency gain, 1 for an integrating plant), [Hz].
BANDWIDTH_REFERENCE_HZ = 1e-4
#: Samples of the refinement between the two search frequencies around the crossing, [-].
BANDWIDTH_REFINE = 32


def position_bandwidth(rig=None, axis=None, operating_point=None):
    """-3 dB bandwidth of an axis's closed position loop, from the linearised model.

    The plant is :func:`~hydroline.analysis.linearize` from the axis's valve current to its
    piston position (the hoses as modal lines, viscous friction slope) about
    ``operating_point``; the loop is closed by the axis's position controller -- the
    circuit's, else the rig's ``[controller]`` table -- as :func:`closed_loop_bandwidth`.
    The response is evaluated on :data:`BANDWIDTH_SEARCH` and again on
    :data:`BANDWIDTH_REFINE` points between the two samples around the first -3 dB crossing
    (a notch narrower than the search spacing, 1/12 decade, may be missed), against the
    gain at :data:`BANDWIDTH_REFERENCE_HZ`.

    Parameters
    ----------
    rig : Rig, str or None
        The rig (None: the embedded 2005 paper's)
    axis : str
        The axis (None: the first)
    operating_point : OperatingPoint
        See :func:`~hydroline.analysis.linearize` (None: at rest at mid-stroke, the holding
        current solved for)

    Returns
    -------
    float or None
        Bandwidth, [Hz]; None where the closed loop stays within 3 dB up to 2 kHz.

    Raises
    ------
    RigError
        The axis has no position controller and the rig no ``controller.proportional_gain``.
    """
    from ..rigs import Rig, load_rig
    from ..scenarios.experiments import template_controller
    from ..system import build_circuit
    from .linearize import linearize, select_axis

    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    ax = select_axis(rig, axis)
    c = (build_circuit(rig).component(ax.controller) if ax.controller
         else template_controller(rig, ax))
    plant = linearize(rig, operating_point, ["valve_current"], ["piston_position"], axis=axis)

    def closed(f):
        H = state_space_response(plant.A, plant.B, plant.C, plant.D, f,
                                 plant.state_scales)[:, 0, 0]
        return closed_loop_position_response(f, H, c.proportional_gain, c.integral_gain,
                                             c.derivative_gain)

    lo, hi, n = BANDWIDTH_SEARCH
    f = np.logspace(np.log10(lo), np.log10(hi), n)
    reference = abs(closed([BANDWIDTH_REFERENCE_HZ])[0])
    bw = bandwidth(f, closed(f), reference)
    if bw is None or bw <= f[0]:
        return bw
    k = int(np.searchsorted(f, bw))          # f[k - 1] < bw <= f[k]
    fine = np.logspace(np.log10(f[k - 1]), np.log10(f[k]), BANDWIDTH_REFINE)
    return bandwidth(fine, closed(fine), reference)
