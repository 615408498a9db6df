"""Frequency responses of the linearised test system: modal lines, exact lines, ideal supply.

Three linear views of one operating point (:mod:`hydroline.analysis.linearize`):

* **modal** -- the Jacobian of the whole compiled network, hoses as modal lines (M8-M13);
* **exact lines** -- the same valve, actuator, HSM resistances, check valve and accumulators,
  with every hose replaced by its exact dissipative four-pole (M5, M6) in its causal form;
* **constant supply** -- valve and actuator with ideal constant supply and return pressures.

Exact lines: a frequency-domain linear fractional transformation
-----------------------------------------------------------------
Lines are linear, so only the rest of the network needs linearising. Cut every
:class:`~hydroline.components.HoseSection` out of the network: its two output signals ``w``
(e.g. PQ: downstream pressure, upstream flow) become inputs of the rest, held at their
operating values by sources, and its two input signals ``r`` become outputs of the rest. The
rest is linearised to ``[y; r] = G(s) [u; w]``; the hoses close the loop with ``w = L(s) r``,
``L`` block-diagonal of their 2x2 transfer matrices (docs/model.md table 2.1). Then

    r = (I - G_rw L)^-1 G_ru u,      y = G_yu u + G_yw L r.

With ``L`` the modal matrices this reproduces the full Jacobian's response exactly (a check
of the cut); with ``L`` the exact matrices (M6) it is the linearised system with exact lines,
the truth the modal model approximates, at any frequency. Accumulator connection lines stay
in the rest (version II, M18, is lumped anyway).

Resonances of the exact-line system are the zeros of ``det(I - G_rw(s) L(s))`` in the left
half plane; :func:`exact_resonances` finds them by Muller's method, starting from the modal
model's poles.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import components as comp
from ..components import HoseSection
from ..engine import Network
from ..rigs import Rig, load_rig
from .linearize import (OperatingPoint, SolvedOperatingPoint, axis_signal, balancing_scales,
                        check_names, friction_slope, input_parameter, jacobians, linear_network,
                        transfer_state, solve_operating_point)

__all__ = ["state_space_response", "bandwidth", "passband", "Passband", "Resonance", "resonances",
           "LineCoupledModel", "line_coupled_model", "exact_resonances", "highest_retained_mode"]


def state_space_response(A, B, C, D, f, scales=None):
    """Frequency response ``C (j w I - A)^-1 B + D`` of a state-space model.

    Parameters
    ----------
    A, B, C, D : ndarray
        State-space matrices, [SI]
    f : array_like
        Frequencies, [Hz]
    scales : array_like
        Typical state magnitudes to balance A before solving, [SI]

    Returns
    -------
    ndarray
        Complex response, shape ``(len(f), n_outputs, n_inputs)``, [output unit / input unit]
    """
    f = np.atleast_1d(np.asarray(f, dtype=float))
    return _response(A, B, C, D, 2j * np.pi * f, scales)


def _response(A, B, C, D, s, scales=None):
    s = np.atleast_1d(np.asarray(s, dtype=complex))
    A, B, C = np.asarray(A, float), np.asarray(B, float), np.asarray(C, float)
    if scales is not None:
        sc = np.asarray(scales, dtype=float)
        A, B, C = A * sc[None, :] / sc[:, None], B / sc[:, None], C * sc[None, :]
    n = A.shape[0]
    if n == 0:
        return np.broadcast_to(np.asarray(D, complex), s.shape + np.shape(D)).copy()
    if len(s) >= SCHUR_POINTS:
        return C @ _schur_solve(A, B, s) + D
    # (frequencies a block at a time: the whole stack of (s I - A), 1202 x 138 x 138 complex
    # on the default rig, is 370 MB of memory traffic; the same solves, 5x quicker)
    Bc = B.astype(complex)
    blocks = []
    for i in range(0, len(s), RESPONSE_BLOCK):
        sb = s[i:i + RESPONSE_BLOCK]
        M = sb[:, None, None] * np.eye(n) - A
        blocks.append(C @ np.linalg.solve(M, np.broadcast_to(Bc, sb.shape + B.shape)) + D)
    return np.concatenate(blocks) if blocks else np.zeros(s.shape + np.shape(D), complex)


#: Frequencies whose ``(s I - A)`` are solved together, [-]
RESPONSE_BLOCK = 64
#: From this many values of s on, ``(s I - A)^-1 B`` is solved through A's Schur form
#: (:func:`_schur_solve`) instead of one LU per s, [-]
SCHUR_POINTS = 32


def _schur_solve(A, B, s):
    """``X[k] = (s[k] I - A)^-1 B`` for many s: A's complex Schur form ``A = Z T Z^H`` once
    (O(n^3)), then per s a back-substitution with the triangular ``s I - T`` (O(n^2), every s
    at once), and one step of iterative refinement with the residual in A's own basis, which
    brings the outputs' error (up to ~4e-11 relative after the back-substitution alone, on
    the default rig's port pressures) to that of an LU solve per s (~1e-14, against
    40-digit solves). The default rig's 1202 frequencies: 0.1 s instead of 0.55 s.

    Parameters
    ----------
    A : ndarray
        (n, n) real, [1/s]
    B : ndarray
        (n, m) real, [SI]
    s : ndarray
        Values of the Laplace variable, complex, [1/s]

    Returns
    -------
    ndarray
        Complex, shape ``(len(s), n, m)``, [SI]

    Raises
    ------
    numpy.linalg.LinAlgError
        Some ``s I - A`` is singular (s an eigenvalue of A).
    """
    from scipy.linalg import schur

    n, m = B.shape
    T, Z = schur(A, output="complex")
    shifted = s[None, :] - np.diag(T)[:, None]              # (n, len(s)): diagonal of s I - T
    if not np.all(shifted != 0):
        raise np.linalg.LinAlgError("Singular matrix")
    ZH = Z.conj().T

    def triangular(rhs):   # rhs (n, len(s), m) in the Schur basis -> (s I - T)^-1 rhs
        for j in range(n - 1, -1, -1):
            if j < n - 1:
                rhs[j] += np.tensordot(T[j, j + 1:], rhs[j + 1:], axes=(0, 0))
            rhs[j] /= shifted[j][:, None]
        return rhs

    Y = triangular(np.broadcast_to((ZH @ B)[:, None, :], (n, len(s), m)).copy())
    X = (Z @ Y.reshape(n, -1)).reshape(n, len(s), m)
    residual = B[:, None, :] - s[None, :, None] * X + (A @ X.reshape(n, -1)).reshape(X.shape)
    X += (Z @ triangular((ZH @ residual.reshape(n, -1)).reshape(X.shape)).reshape(n, -1)
          ).reshape(X.shape)
    return np.moveaxis(X, 0, 1)


def bandwidth(f, H, reference=None):
    """-3 dB bandwidth: the first frequency at which ``|H|`` falls below ``|H_ref|/sqrt(2)``.

    This is :func:`passband`'s first crossing; :func:`passband` also gives the "within 3 dB
    up to" reading.

    Parameters
    ----------
    f : array_like
        Increasing frequencies, [Hz]
    H : array_like
        Complex (or magnitude) response at f, [any unit]
    reference : float
        Reference gain ``|H_ref|``, [unit of H]; the gain at the lowest frequency when None
        (the response must be flat there: type 0, not an integrator).

    Returns
    -------
    float or None
        Bandwidth, [Hz] (log-log interpolated; ``f[0]`` when already below the level
        there), None if ``|H|`` stays above the level up to ``f[-1]``.

    Examples
    --------
    A first-order lag ``1/(1 + j f/f_c)`` falls to -3 dB at its corner ``f_c`` = 10 Hz:

    >>> import numpy as np
    >>> f = np.logspace(-2, 3, 5001)
    >>> round(bandwidth(f, 1 / (1 + 1j * f / 10.0)), 2)
    10.0
    """
    band = passband(f, H, reference)
    if band.first_crossing_hz is None and band.within_3db_up_to_hz is None and band.note:
        return float(np.asarray(f, dtype=float)[0])          # below the level from the start
    return band.first_crossing_hz


#: The -3 dB level: half the power, ``20 log10(1/sqrt(2))``, [dB].
LEVEL_DB = 20 * np.log10(1 / np.sqrt(2.0))
#: A notch or peak within this many dB of the -3 dB level is named: a small change of the
#: parameters can carry it across the level, and a crossing frequency then jumps, [dB].
NOTCH_MARGIN_DB = 0.5


@dataclass
class Passband:
    """Where a low-pass gain leaves its -3 dB band, read two ways (:func:`passband`).

    Attributes
    ----------
    first_crossing_hz : float or None
        First fall of the gain below -3 dB, [Hz] (None: none
        in the range)
    within_3db_up_to_hz : float or None
        Last fall below -3 dB, after which the gain stays
        below it to the end of the range: the gain is within
        3 dB up to there, notches aside, [Hz] (None: within
        3 dB to the end of the range)
    notch : tuple or None
        (frequency [Hz], depth [dB]) of the notch the first
        crossing falls in -- a local minimum below -3 dB
        that the gain climbs out of -- else None
    note : str
        A notch or peak within ``NOTCH_MARGIN_DB`` of the
        level (where a reading jumps), or ""
    reference : float
        The gain the levels are relative to, [unit of H]
    """

    first_crossing_hz: float | None
    within_3db_up_to_hz: float | None
    notch: tuple | None = None
    note: str = ""
    reference: float = 1.0

    @property
    def in_notch(self) -> bool:
        """True when the first -3 dB crossing lies in a notch the gain recovers from."""
        return self.notch is not None


def _crossing(f, db, k):
    """Frequency where ``db`` passes the level between samples k and k + 1 (log f linear)."""
    x0, x1 = np.log(f[k]), np.log(f[k + 1])
    return float(np.exp(x0 + (LEVEL_DB - db[k]) * (x1 - x0) / (db[k + 1] - db[k])))


def passband(f, H, reference=None) -> Passband:
    """The -3 dB readings of a low-pass gain: first crossing and "within 3 dB up to".

    A gain with a notch (a line mode's anti-resonance) that dips below -3 dB and recovers
    has two readings: its first -3 dB crossing lies in the notch, the frequency up to which
    it stays within 3 dB (notches aside) lies beyond. Each moves continuously with the
    parameters except where a notch crosses the level: its minimum falling below -3 dB
    carries the first crossing down into the notch, a peak beyond the last crossing rising
    above -3 dB carries the within-3-dB reading up past it. Such a notch or peak within
    ``NOTCH_MARGIN_DB`` of the level is named in the note.

    Parameters
    ----------
    f : array_like
        Increasing frequencies, [Hz]
    H : array_like
        Complex (or magnitude) response at f, [any unit]
    reference : float
        Reference gain ``|H_ref|``, [unit of H]; the gain at the lowest frequency when None.

    Returns
    -------
    Passband
        The crossings, log-log interpolated between samples; None where the gain is below
        -3 dB at ``f[0]`` already (see :func:`bandwidth`).
    """
    f = np.asarray(f, dtype=float)
    g = np.abs(np.asarray(H))
    ref = g[0] if reference is None else float(reference)
    db = 20 * np.log10(np.maximum(g / ref, 1e-300))
    above = db >= LEVEL_DB
    if not above[0]:
        return Passband(None, None, None, f"below {f[0]:.4g} Hz", ref)
    falls = np.flatnonzero(above[:-1] & ~above[1:])          # k: above at k, below at k + 1
    rises = np.flatnonzero(~above[:-1] & above[1:])
    first = _crossing(f, db, falls[0]) if falls.size else None
    last = _crossing(f, db, falls[-1]) if falls.size and not above[-1] else None
    notch = None
    if falls.size and rises.size and rises[0] > falls[0]:    # the gain climbs back: a notch
        k = falls[0] + 1 + int(np.argmin(db[falls[0] + 1:rises[0] + 1]))
        notch = (float(f[k]), float(db[k]))
    notes = []
    if notch is not None:
        notes.append(f"the first -3 dB crossing lies in a notch ({notch[1]:.2f} dB at "
                     f"{notch[0]:.4g} Hz), the gain back within 3 dB from "
                     f"{_crossing(f, db, rises[0]):.4g} Hz")
    # notches and peaks near the level, where a reading jumps as they cross it
    interior = np.arange(1, len(db) - 1)
    minima = interior[(db[1:-1] < db[:-2]) & (db[1:-1] <= db[2:])]
    maxima = interior[(db[1:-1] > db[:-2]) & (db[1:-1] >= db[2:])]
    end = falls[-1] if last is not None else len(db)
    here = f"{first:.4g} Hz" if first is not None else f"above {f[-1]:.4g} Hz"
    shallow = [k for k in minima if (not falls.size or k <= falls[0])
               and LEVEL_DB <= db[k] <= LEVEL_DB + NOTCH_MARGIN_DB]
    if shallow:
        which = ", ".join(f"{db[k]:.2f} dB at {f[k]:.4g} Hz" for k in shallow)
        notes.append(f"{'a notch reaches' if len(shallow) == 1 else 'notches reach'} {which}, "
                     f"within {NOTCH_MARGIN_DB:g} dB above -3 dB: should "
                     f"{'it' if len(shallow) == 1 else 'one'} dip below, the first crossing "
                     f"jumps from {here} down into it")
    if notch is not None and notch[1] >= LEVEL_DB - NOTCH_MARGIN_DB:
        after = f"{_crossing(f, db, falls[1]):.4g} Hz" if falls.size > 1 else f"above {f[-1]:.4g} Hz"
        notes.append(f"the notch lies {LEVEL_DB - notch[1]:.2f} dB below -3 dB: should it rise "
                     f"above, the first crossing jumps up to {after}")
    low_peaks = [k for k in maxima if falls.size and falls[0] < k < end
                 and LEVEL_DB <= db[k] <= LEVEL_DB + NOTCH_MARGIN_DB]
    if low_peaks:
        k = min(low_peaks, key=lambda k: db[k])
        notes.append(f"between notch and band edge the gain climbs back only to {db[k]:.2f} dB "
                     f"at {f[k]:.4g} Hz: should it stay below -3 dB, the within-3-dB reading "
                     f"jumps down below it")
    if last is not None:
        near = [k for k in maxima if k > end and db[k] >= LEVEL_DB - NOTCH_MARGIN_DB]
        if near:
            k = max(near, key=lambda k: db[k])
            notes.append(f"beyond {last:.4g} Hz a peak reaches {db[k]:.2f} dB at {f[k]:.4g} Hz, "
                         f"{LEVEL_DB - db[k]:.2f} dB below -3 dB: should it rise above, the "
                         f"within-3-dB reading jumps up past it")
    return Passband(first, last, notch, "; ".join(notes), float(ref))


@dataclass
class Resonance:
    """One lightly damped pole pair.

    Attributes
    ----------
    frequency_hz : float
        Undamped natural frequency ``|lambda|/2pi``, [Hz]
    damping_ratio : float
        ``-Re(lambda)/|lambda|``, [-]
    strength : dict
        Output name -> its resonance peak ``|residue|/|Re lambda|`` relative to the strongest
        pole in that channel, [-]
    eigenvalue : complex
        The pole ``lambda``, [1/s]
    """

    frequency_hz: float
    damping_ratio: float
    strength: dict
    eigenvalue: complex

    @property
    def strongest_in(self) -> str:
        """The output in which this resonance is strongest ("" when none is listed)."""
        return max(self.strength, key=self.strength.get) if self.strength else ""


def resonances(sys, input_name: str, outputs=None, f_max: float = 1000.0,
               max_damping: float = 0.7, min_strength: float = 0.01) -> list:
    """Lightly damped poles of a linear model that show in the chosen channels.

    The peak a pole pair puts into ``output/input`` is about ``|r_k|/|Re lambda_k|`` with
    ``r_k`` its residue (from the eigendecomposition of A); a pole is listed when that peak
    is at least ``min_strength`` times the strongest pole's in some listed output.

    Parameters
    ----------
    sys : object
        A linear model with named inputs and outputs: a python-control ``StateSpace`` from
        :func:`~hydroline.analysis.linearize`, or a
        :class:`~hydroline.analysis.linearize.LinearModel`
    input_name : str
        Input channel
    outputs : list[str]
        Output channels (all when None)
    f_max : float
        Highest natural frequency listed, [Hz]
    max_damping : float
        Highest damping ratio listed, [-]
    min_strength : float
        Threshold relative to the strongest pole, [-]

    Returns
    -------
    list[Resonance]
        The listed poles, by frequency.
    """
    outputs = list(sys.output_labels) if outputs is None else list(outputs)
    scales = getattr(sys, "state_scales", np.ones(sys.nstates))
    A = sys.A * scales[None, :] / scales[:, None]
    B = sys.B / scales[:, None]
    C = sys.C * scales[None, :]
    lam, V = np.linalg.eig(A)
    W = np.linalg.inv(V)
    j = list(sys.input_labels).index(input_name)
    rows = [list(sys.output_labels).index(o) for o in outputs]
    wb = W @ B[:, j]
    peak = {}
    for o, i in zip(outputs, rows):
        r = (C[i] @ V) * wb
        peak[o] = np.abs(r) / np.maximum(np.abs(lam.real), 1e-12 * np.abs(lam) + 1e-300)
    # candidates only: a critically damped pair (the valve's, zeta_v = 1) is nearly defective
    # and its residues are numerically meaningless
    fn = np.abs(lam) / (2 * np.pi)
    zeta = -lam.real / np.maximum(np.abs(lam), 1e-300)
    cand = np.flatnonzero((lam.imag > 0) & (fn <= f_max) & (zeta <= max_damping))
    out = []
    for k in cand:
        strength = {o: float(peak[o][k] / max(np.max(peak[o][cand]), 1e-300)) for o in outputs}
        if max(strength.values()) >= min_strength:
            out.append(Resonance(float(fn[k]), float(zeta[k]), strength, complex(lam[k])))
    return sorted(out, key=lambda r: r.frequency_hz)


class LineCoupledModel:
    """The linearised rest of the network with its hoses cut out (module docstring).

    Made by :func:`line_coupled_model`.

    Parameters
    ----------
    hoses : list[HoseSection]
        The cut hoses.
    inputs, outputs : list[str]
        External channels u and y.
    A, B, C, D : ndarray
        The rest: inputs ``[u, w]``, outputs ``[y, r]``, [SI]
    scales : ndarray
        Typical state magnitudes of the rest, [SI]
    operating_point : SolvedOperatingPoint
        The operating point the rest is linearised about.
    """

    def __init__(self, hoses, inputs, outputs, A, B, C, D, scales, operating_point):
        self.hoses, self.inputs, self.outputs = hoses, list(inputs), list(outputs)
        self.A, self.B, self.C, self.D, self.scales = A, B, C, D, scales
        self.operating_point = operating_point
        self._nu, self._ny = len(self.inputs), len(self.outputs)

    def line_matrix(self, s, lines: str = "exact"):
        """Block-diagonal ``L(s)`` mapping the hoses' inputs r to their outputs w.

        Parameters
        ----------
        s : array_like complex
            Laplace variable, [1/s]
        lines : str
            "exact" (dissipative, M6) or "modal" (the network's models)

        Returns
        -------
        ndarray
            Complex, shape ``(len(s), 2 n_hoses, 2 n_hoses)``, [SI]
        """
        s = np.atleast_1d(np.asarray(s, dtype=complex))
        n = 2 * len(self.hoses)
        L = np.zeros(s.shape + (n, n), dtype=complex)
        for k, h in enumerate(self.hoses):
            m = h.model
            if lines == "exact":
                T = m.line.transfer(s, m.form)
            elif lines == "modal":
                T = m.transfer(s)
            else:
                raise ValueError(f"lines must be 'exact' or 'modal'; got {lines!r}")
            L[:, 2 * k:2 * k + 2, 2 * k:2 * k + 2] = T
        return L

    def rest_response(self, s):
        """``G(s)`` of the rest (the network without its hoses).

        Parameters
        ----------
        s : array_like complex
            Laplace variable, [1/s]

        Returns
        -------
        ndarray
            Complex, shape ``(len(s), ny + nr, nu + nw)``, [SI]
        """
        return _response(self.A, self.B, self.C, self.D, s, self.scales)

    def response_s(self, s, lines: str = "exact"):
        """Closed-loop response ``y/u`` at complex s.

        Parameters
        ----------
        s : array_like complex
            Laplace variable, [1/s]
        lines : str
            "exact" (dissipative, M6) or "modal" (the network's models)

        Returns
        -------
        ndarray
            Complex, shape ``(len(s), ny, nu)``, [output unit / input unit]
        """
        G = self.rest_response(s)
        L = self.line_matrix(s, lines)
        nu, ny = self._nu, self._ny
        Gyu, Gyw = G[:, :ny, :nu], G[:, :ny, nu:]
        Gru, Grw = G[:, ny:, :nu], G[:, ny:, nu:]
        eye = np.eye(Grw.shape[1])
        r = np.linalg.solve(eye - Grw @ L, Gru)
        return Gyu + Gyw @ (L @ r)

    def response(self, f, lines: str = "exact"):
        """Frequency response ``y/u`` with exact or modal lines.

        Parameters
        ----------
        f : array_like
            Frequencies, [Hz]
        lines : str
            "exact" or "modal"

        Returns
        -------
        ndarray
            Complex, shape ``(len(f), n_outputs, n_inputs)``, [output unit / input unit]
        """
        f = np.atleast_1d(np.asarray(f, dtype=float))
        return self.response_s(2j * np.pi * f, lines)

    def characteristic(self, s, lines: str = "exact"):
        """``det(I - G_rw(s) L(s))``, whose zeros are the coupled system's poles [-].

        Parameters
        ----------
        s : array_like complex
            Laplace variable, [1/s]
        lines : str
            "exact" (dissipative, M6) or "modal" (the network's models)

        Returns
        -------
        ndarray
            Complex, shape ``(len(s),)``, [-]
        """
        G = self.rest_response(s)
        L = self.line_matrix(s, lines)
        Grw = G[:, self._ny:, self._nu:]
        return np.linalg.det(np.eye(Grw.shape[1]) - Grw @ L)


def line_coupled_model(rig: Rig | str | None = None, operating_point: OperatingPoint | None = None,
                       inputs=("valve_current",), outputs=("piston_velocity",),
                       friction: str = "viscous", solved: SolvedOperatingPoint | None = None,
                       axis: str | None = None) -> LineCoupledModel:
    """Cut the hoses out of the linearised network (see the module docstring).

    Parameters
    ----------
    rig : Rig, str or None
        The rig
    operating_point : OperatingPoint
        As for :func:`~hydroline.analysis.linearize`
    inputs, outputs : sequence of str
        Channels (names as for ``linearize``).
    friction : str
        "viscous" or "model" (as for ``linearize``)
    solved : SolvedOperatingPoint
        A solved operating point to reuse (then
        ``operating_point`` and ``axis`` are ignored)
    axis : str
        The axis (None: the first), as for ``linearize``

    Returns
    -------
    LineCoupledModel
    """
    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    inputs, outputs = list(inputs), list(outputs)
    check_names(inputs, outputs)
    if friction not in ("viscous", "model"):
        raise ValueError(f"friction must be 'viscous' or 'model'; got {friction!r}")
    if solved is None:
        solved = solve_operating_point(rig, operating_point, "lines", axis=axis)
    ax = solved.axis
    sig = solved.signals
    viscous = friction == "viscous" and ax.friction is not None
    fr = solved.network.component(ax.friction) if ax.friction else None
    f0 = sig[fr.signal("friction_force")] if viscous else None
    full = linear_network(rig, "lines", solved.valve_current, friction_force=f0, axis=ax.name)
    hoses = [c for c in full.components if isinstance(c, HoseSection)]
    parts = [c for c in full.components if not isinstance(c, HoseSection)]
    w_params, r_signals = [], []
    for h in hoses:
        for port in h.model.output_names:
            name = f"{h.name}:{port}"
            value = sig[h.signal(port)]
            parts.append(comp.StepCommand(name=name, quantity=h.outputs[port].quantity,
                                          initial=value, final=value, time=0.0,
                                          connections={"command": h.signal(port)}))
            w_params.append(f"{name}.final")
        r_signals += [h.signal(port) for port in h.model.input_names]
    rest = Network(parts, warn_lost_flows=False)   # the hoses' ends are cut open on purpose
    x, p = transfer_state(solved, rest)
    for h in hoses:
        for port in h.model.output_names:
            p[rest.parameter_names.index(f"{h.name}:{port}.final")] = sig[h.signal(port)]
    params = [input_parameter(rest, ax, u) for u in inputs] + w_params
    if viscous:
        params.append(f"{ax.friction}.final")
    A, B, C, D = jacobians(rest, x, p, params, [axis_signal(ax, y) for y in outputs] + r_signals)
    if viscous:
        slope = friction_slope(fr, sig[ax.velocity])
        iv = rest.state_names.index(f"{ax.actuator}.velocity")
        A[:, iv] += slope * B[:, -1]
        C[:, iv] += slope * D[:, -1]
        B, D = B[:, :-1], D[:, :-1]
    return LineCoupledModel(hoses, inputs, outputs, A, B, C, D, balancing_scales(rest, x), solved)


def highest_retained_mode(model: LineCoupledModel) -> float:
    """Lowest, over the hoses, of the undamped frequency of the highest modal-model mode, [Hz].

    PQ/QP modes sit at ``(i - 1/2) c/(2L)`` (M9), PP/QQ at ``i c/(2L)``.

    Parameters
    ----------
    model : LineCoupledModel
        The model whose hoses are read (:func:`line_coupled_model`)

    Returns
    -------
    float
        Frequency, [Hz] (inf when no hose has a modal model)
    """
    out = np.inf
    for h in model.hoses:
        m, ln = h.model, h.model.line
        n = getattr(m, "n_modes", None)
        if n is None:
            continue
        k = n - 0.5 if m.form in ("PQ", "QP") else n
        out = min(out, k / (2 * ln.wave_time))
    return float(out)


def _muller(fun, z0, h, tol=1e-10, max_iter=60):
    """A zero of an analytic function near z0 by Muller's method; None if it wanders."""
    x = [z0 - h, z0 + h, z0]
    y = [complex(fun(v)) for v in x]
    for _ in range(max_iter):
        q = (x[2] - x[1]) / (x[1] - x[0])
        a = q * y[2] - q * (1 + q) * y[1] + q * q * y[0]
        b = (2 * q + 1) * y[2] - (1 + q) ** 2 * y[1] + q * q * y[0]
        c = (1 + q) * y[2]
        disc = np.sqrt(b * b - 4 * a * c)
        den = b + disc if abs(b + disc) >= abs(b - disc) else b - disc
        if den == 0:
            return None
        x_new = x[2] - (x[2] - x[1]) * 2 * c / den
        if not np.isfinite(x_new):
            return None
        x = [x[1], x[2], x_new]
        y = [y[1], y[2], complex(fun(x_new))]
        if abs(x[2] - x[1]) < tol * abs(x[2]):
            return x[2]
    return None


def exact_resonances(model: LineCoupledModel, modal: list, f_max: float | None = None) -> dict:
    """Poles of the exact-line system next to each modal resonance (Muller from the modal pole).

    Parameters
    ----------
    model : LineCoupledModel
        The cut network (:func:`line_coupled_model`).
    modal : list[Resonance]
        Modal resonances (from :func:`resonances` on the full model).
    f_max : float
        Skip modal poles above this, [Hz]

    Returns
    -------
    dict
        Modal eigenvalue -> (frequency [Hz], damping ratio [-]) of the exact-line pole, or
        None where the search did not converge to a nearby pole.
    """
    out = {}

    def char(s):
        return model.characteristic(np.array([s]))[0]

    for r in modal:
        lam = r.eigenvalue
        if f_max is not None and r.frequency_hz > f_max:
            out[lam] = None
            continue
        root = _muller(char, lam, 0.01 * abs(lam))
        if root is None or abs(root - lam) > 0.2 * abs(lam) or root.real >= 0:
            out[lam] = None
        else:
            out[lam] = (abs(root) / (2 * np.pi), -root.real / abs(root))
    return out


#: Labels of the model variants in :class:`BodeResult` and the figure.
MODAL, EXACT, CONSTANT = "hoses, modal lines", "hoses, exact lines (M6)", "constant supply and return"


def rated_velocity(rig: Rig, axis: str | None = None) -> float:
    """Piston velocity at the valve's rated flow, ``Q_N / A_b``, [m/s] (upward).

    Parameters
    ----------
    rig : Rig
        Parameters (SI).
    axis : str
        The axis (None: the first).

    Returns
    -------
    float
        Rated piston velocity, [m/s]
    """
    from ..system import build_circuit
    from .linearize import select_axis

    ax = select_axis(rig, axis)
    circuit = build_circuit(rig)
    return float(circuit.component(ax.valve).rated_flow / circuit.component(ax.actuator).bottom_area)


def _low_frequency_gain(f_low, H_low):
    """(DC gain, integrating?) from the response at two frequencies a decade apart, far below
    the band: an integrator falls like 1/f there, a type-0 response is flat."""
    g = np.abs(H_low)
    if g[0] == 0:
        return 0.0, False
    slope = np.log(g[1] / g[0]) / np.log(f_low[1] / f_low[0])
    return float(g[0]), bool(slope < -0.5)


@dataclass
class BodeResult:
    """Frequency responses of one input to several outputs for the model variants.

    Attributes
    ----------
    f : ndarray
        Frequencies, [Hz]
    input : str
        The input channel.
    outputs : list[str]
        The output channels.
    curves : dict
        Variant label -> complex ``(len(f), len(outputs))``, [SI]
    bandwidths : dict
        Label -> {output: first -3 dB crossing [Hz] or None}; None
        also where ``|H|`` rises more than 3 dB above its low-frequency gain
        (resonant, not low-pass: e.g. the port pressures)
    notes : dict
        Label -> {output: why there is no bandwidth, or the notch the
        first crossing lies in and the notches near -3 dB}
    passbands : dict
        Label -> {output: :class:`Passband`} of the low-pass channels:
        first -3 dB crossing and "gain within 3 dB up to", and the notch
    resonances : dict
        Label -> list[Resonance] (modal and constant-supply models)
    exact_poles : dict
        Modal eigenvalue -> (frequency [Hz], damping [-]) of the
        exact-line pole next to it, or None
    operating_points : dict
        Label -> SolvedOperatingPoint
    highest_mode_hz : float
        Lowest, over the hoses, of the highest retained mode, [Hz]
    """

    f: np.ndarray
    input: str
    outputs: list
    curves: dict
    bandwidths: dict
    notes: dict
    resonances: dict
    exact_poles: dict
    operating_points: dict
    highest_mode_hz: float
    passbands: dict = field(default_factory=dict)


def bode_analysis(rig: Rig | str | None = None, operating_point: OperatingPoint | None = None,
                  input_name: str = "valve_current", outputs=("piston_velocity",), f=None,
                  compare: bool = True, exact: bool = True, friction: str = "viscous",
                  axis: str | None = None) -> BodeResult:
    """Bode data with modal lines, exact lines and (optionally) ideal constant supply.

    The -3 dB bandwidth of a channel is measured against its low-frequency gain and only for
    a low-pass response, read two ways (:func:`passband`): the first -3 dB crossing, marked
    when it lies in a notch the gain recovers from, and the frequency up to which the gain
    stays within 3 dB, notches aside. Where ``|H|`` rises more than 3 dB above that gain anywhere in ``f``
    (the port pressures' line resonances, the chamber pressures' actuator resonance, or the
    piston velocity at rest, +16 dB at 172 Hz on the default rig) it is None with the note
    "resonant, not low-pass"; integrating outputs (piston position) have none either.

    Parameters
    ----------
    rig : Rig, str or None
        The rig
    operating_point : OperatingPoint
        See :func:`~hydroline.analysis.linearize`
    input_name : str
        Input channel (:data:`~hydroline.analysis.linearize.INPUTS`)
    outputs : sequence of str
        Output signals
    f : array_like
        Frequencies [Hz]; 1-500 Hz, 1200 log-spaced when None
    compare : bool
        Add the constant-supply variant
    exact : bool
        Add the exact-line variant
    friction : str
        "viscous" or "model"
    axis : str
        The axis whose valve drives (None: the first); its
        position loop open, the other axes hold

    Returns
    -------
    BodeResult
        The curves, bandwidths, resonances and operating points of every variant.
    """
    from .linearize import linear_model as linearize   # (plain arrays: no python-control)

    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    outputs = list(outputs)
    f = np.logspace(0, np.log10(500.0), 1200) if f is None else np.asarray(f, dtype=float)
    if f.ndim != 1 or len(f) < 2 or np.any(np.diff(f) <= 0) or f[0] <= 0:
        raise ValueError("frequencies must increase and be > 0 Hz")
    f_low = f[0] * np.array([1e-3, 1e-2])          # quasi-DC, for the reference gain
    fa = np.concatenate([f_low, f])
    sys = linearize(rig, operating_point, [input_name], outputs, "lines", friction, axis=axis)
    curves = {MODAL: state_space_response(sys.A, sys.B, sys.C, sys.D, fa, sys.state_scales)[:, :, 0]}
    ops = {MODAL: sys.operating_point}
    res = {MODAL: resonances(sys, input_name, outputs, f_max=f[-1])}
    exact_poles, f_top = {}, float("nan")
    if exact:
        model = line_coupled_model(rig, inputs=[input_name], outputs=outputs, friction=friction,
                                   solved=sys.operating_point)
        curves[EXACT] = model.response(fa, "exact")[:, :, 0]
        ops[EXACT] = sys.operating_point
        exact_poles = exact_resonances(model, res[MODAL])
        f_top = highest_retained_mode(model)
    if compare:
        ideal = linearize(rig, operating_point, [input_name], outputs, "constant", friction,
                          axis=axis)
        curves[CONSTANT] = state_space_response(ideal.A, ideal.B, ideal.C, ideal.D, fa,
                                                ideal.state_scales)[:, :, 0]
        ops[CONSTANT] = ideal.operating_point
        res[CONSTANT] = resonances(ideal, input_name, outputs, f_max=f[-1])
    bws, notes, bands = {}, {}, {}
    for label in list(curves):
        H_low, H = curves[label][:2], curves[label][2:]
        curves[label] = H
        bws[label], notes[label], bands[label] = {}, {}, {}
        for j, out in enumerate(outputs):
            dc, integrating = _low_frequency_gain(f_low, H_low[:, j])
            bw = None
            if not np.any(np.abs(H[:, j]) > 0):
                notes[label][out] = "held constant in this model"
            elif integrating:
                notes[label][out] = "integrating output (no DC gain)"
            else:
                g = np.abs(H[:, j])
                k = int(np.argmax(g))
                if g[k] > np.sqrt(2.0) * dc:
                    # a -3 dB point of a response that climbs above its low-frequency gain
                    # (a port pressure's line resonance, +25 dB) says nothing about how fast
                    # the channel follows: a bandwidth only means something for a low-pass
                    notes[label][out] = (f"resonant, not low-pass (peak "
                                         f"{20 * np.log10(g[k] / dc):+.1f} dB re low-frequency "
                                         f"gain, at {f[k]:.4g} Hz)")
                else:
                    band = passband(f, H[:, j], reference=dc)
                    bands[label][out] = band
                    bw = band.first_crossing_hz
                    if band.note:
                        notes[label][out] = band.note
                    elif bw is None:
                        notes[label][out] = f"above {f[-1]:g} Hz"
            bws[label][out] = bw
    return BodeResult(f, input_name, outputs, curves, bws, notes, res, exact_poles, ops, f_top,
                      bands)
