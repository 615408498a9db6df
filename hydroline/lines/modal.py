"""Modal state-space approximations of a hydraulic line, all four causal forms.

PQ form (model reference §2.2, M8-M13, the 2005 paper's eq. 8-14). Mode i has states
``[mode{i}.pressure, mode{i}.flow] = [p_di, q_ui]`` (its contributions to the downstream
pressure [Pa] and upstream flow [m^3/s]); inputs ``u = [upstream_pressure, downstream_flow]``;
outputs ``[downstream_pressure, upstream_flow] = sum_i [p_di, q_ui]`` (M11). The input matrix
carries the steady-state modifier G (M13) so the DC gain is the laminar steady state (M12).

QP form: the PQ line seen from its other end (the line is symmetric): with the PQ inputs
``[P_d, -Q_u]`` the PQ outputs are ``[P_u, -Q_d]``; same states.

PP and QQ forms (model reference §2.4): the partial fractions of ``coth Gamma`` and ``csch Gamma``,

    coth G = 1/G + sum_k 2G/(G^2 + k^2 pi^2),   csch G = 1/G + sum_k (-1)^k 2G/(G^2 + k^2 pi^2),

with the linear friction Gamma (M7) and the per-mode corrections alpha_k, beta_k (M15) give,
with ``a_k = 32 nu beta_k/(d^2 alpha_k)``, ``b_k = (k pi c/L)^2/alpha_k^2``, ``tau = L/c``,
a rank-one 2x2 residue ``[1, (-1)^k]^T [1, -(-1)^k]`` per mode times

    PP:  g_k(s) = (2 C/(tau^2 alpha_k^2)) s/(s^2 + a_k s + b_k)       (admittance)
    QQ:  h_k(s) = (2 Z0/tau) (s + a_k)/(s^2 + a_k s + b_k)             (impedance)

realised with two states each: PP ``[mode{k}.volume, mode{k}.flow]`` (v' = q,
q' = -b v - a q + K w), QQ ``[mode{k}.pressure_integral, mode{k}.pressure]`` (m' = p - a m,
p' = -b m + K w), where ``w = (first input) - (-1)^k (second input)``.

The k = 0 terms: PP, ``1/(Zc Gamma)``, the fluid column with frequency-dependent wall friction.
``Zc Gamma = I s I0(kappa)/I2(kappa)`` is not first order: its inertance falls from 4/3 I to I
and its resistance rises from R as kappa grows, so a plain ``R + I s`` misses it by up to
27 % between the viscous and the inertial regime. It is realised as Zielke's friction with
the weighting function approximated by Schohl's five exponentials (G. A. Schohl, J. Fluids
Eng. 115 (1993) 420-424: m = 1.051, 2.358, 9.021, 29.47, 79.55; n = 26.65, 100.0, 669.6,
6497, 57990), which reproduces ``s I0/I2`` within 0.5 % at all frequencies:

    I q' = (P_u - P_d) - R q - (R/2) sum_i m_i (q - w_i),   w_i' = (n_i nu/r^2)(q - w_i)

(states ``column.flow`` q and ``column.friction{i}`` w_i, [m^3/s]). Its DC gain 1/R is exact
and the modes k >= 1 have none, so the PP steady state (M12) holds without a modifier. QQ, ``Zc/Gamma = 1/(s C)`` exactly, a capacitance
(state ``column.volume``, the net volume stored, pressure = volume/C on both ends); the DC
offsets ``Zc coth Gamma - 1/(sC) -> R/3`` and ``Zc csch Gamma - 1/(sC) -> -R/6`` (from the
Laurent series, any friction model) are restored by a feed-through D minus what the
truncated modes give, so ``P_u - P_d = R Q`` at steady flow (M12).
"""
from __future__ import annotations

import numpy as np

from .corrections import check_modes, correction_factors, modal_angles
from .line import FORM_PORTS, Line, check_form

__all__ = ["ModalLine", "RigidColumnLine", "StateSpaceLine"]

#: The modal line of every rig, circuit hose and :class:`ModalLine` unless one asks for
#: another: the exact poles and residues of the dissipative model. Its resonances lie within
#: ~0.5 % of the exact model's where the Yang-Tobler corrections' are off by up to ~12 %
#: (``hydroline line-response``, tests/test_modal_vs_characteristics.py); "yang-tobler" is
#: the 2005 paper's method, kept selectable (``rig.line_method``, a hose's ``method``).
DEFAULT_LINE_METHOD = "residue"
LINE_METHODS = ("residue", "yang-tobler")

#: Schohl (1993) five-term approximation of Zielke's weighting function,
#: W(tau) ~ sum_i m_i exp(-n_i nu tau / r^2).
SCHOHL_M = np.array([1.051, 2.358, 9.021, 29.47, 79.55])
SCHOHL_N = np.array([26.65, 100.0, 669.6, 6497.0, 57990.0])


class StateSpaceLine:
    """Common behaviour of linear line models ``x' = A x + B u, y = C x + D u``.

    Subclasses (:class:`ModalLine`, :class:`RigidColumnLine`,
    :class:`~hydroline.lines.lumped.LumpedLine`) set the matrices and names.

    Attributes
    ----------
    A, B, C, D : ndarray
        State-space matrices, [SI].
    state_names : list of str
        Names of the states, in order.
    input_names, output_names : tuple of str
        Port signals in the order of the form, e.g. ``("upstream_pressure",
        "downstream_flow")``.
    """

    form: str
    line: Line

    def _set_ports(self):
        self.input_names, self.output_names = FORM_PORTS[self.form]

    @property
    def n_states(self) -> int:
        """Number of states."""
        return self.A.shape[0]

    def transfer(self, s):
        """Frequency response ``C (sI - A)^-1 B + D``.

        Parameters
        ----------
        s : complex or array_like
            Laplace variable (e.g. ``2j*pi*f``), [1/s].

        Returns
        -------
        complex ndarray
            Shape ``s.shape + (2, 2)``, entry ``[..., i, j]`` from input j to output i, in
            the units of :meth:`hydroline.lines.Line.transfer`, [SI].
        """
        s = np.asarray(s, dtype=complex)
        H = np.zeros(s.shape + self.D.shape, dtype=complex)
        H += self.D
        # A is block diagonal (one block per mode pair, tail pair, column branch): solve
        # each group of equally sized blocks at once; the same as solving sI - A whole, up
        # to the order of round-off, at a fraction of the cost for a 40-state line
        for idx in self.diagonal_blocks():
            k = idx.shape[1]
            Ab = self.A[idx[:, :, None], idx[:, None, :]]               # (blocks, k, k)
            Bb = self.B[idx]                                             # (blocks, k, inputs)
            sb = s[..., None]
            if k == 1:
                X = Bb / (sb - Ab[:, 0, 0])[..., None, None]
            elif k == 2:                  # (sI - Ab)^-1 = adj / det, explicitly
                a, b, c, d = Ab[:, 0, 0], Ab[:, 0, 1], Ab[:, 1, 0], Ab[:, 1, 1]
                det = (sb - a) * (sb - d) - b * c
                x0 = ((sb - d)[..., None] * Bb[:, 0] + b[:, None] * Bb[:, 1]) / det[..., None]
                x1 = (c[:, None] * Bb[:, 0] + (sb - a)[..., None] * Bb[:, 1]) / det[..., None]
                X = np.stack([x0, x1], axis=-2)
            else:
                M = s[..., None, None, None] * np.eye(k) - Ab
                X = np.linalg.solve(M, np.broadcast_to(Bb, M.shape[:-1] + Bb.shape[-1:]))
            H += np.einsum("onk,...nkj->...oj", self.C[:, idx], X)
        return H

    def diagonal_blocks(self):
        """State indices of the diagonal blocks of A, grouped by block size.

        Two states are in one block when A couples them, directly or through others (the
        connected components of A's sparsity pattern); ``sI - A`` is then block diagonal
        and the frequency response a sum over the blocks.

        Returns
        -------
        list of int ndarray
            One array of shape ``(blocks, k)`` per block size k, each row the ascending
            state indices of one block, [-].
        """
        A = self.A
        cached = getattr(self, "_diagonal_blocks_of", None)
        if cached is not None and cached[0].shape == A.shape and np.array_equal(cached[0], A):
            return cached[1]
        from scipy.sparse.csgraph import connected_components

        if A.shape[0] == 0:
            groups = []
        else:
            count, label = connected_components(A != 0, directed=False)
            members = [np.flatnonzero(label == c) for c in range(count)]
            sizes = sorted({len(m) for m in members})
            groups = [np.array([m for m in members if len(m) == k]) for k in sizes]
        self._diagonal_blocks_of = (A.copy(), groups)
        return groups

    def eigenvalues(self):
        """Eigenvalues of A.

        Returns
        -------
        complex ndarray
            The poles of the line model, [1/s].
        """
        return np.linalg.eigvals(self.A)

    def initial_state(self, u0, mean_pressure: float | None = None):
        """Steady state for constant inputs u0 (M14): ``x = -A^-1 B u0``.

        Parameters
        ----------
        u0 : array_like
            The two inputs in form order, pressures [Pa] and flows [m^3/s].
        mean_pressure : float or None
            QQ form only: the pressure level stored in ``column.volume``, [Pa]; 0 when None.

        Returns
        -------
        ndarray
            The state vector, [SI, per :attr:`state_names`].

        Raises
        ------
        ValueError
            For the QQ form (which integrates net flow) when the two input flows differ.
        """
        u0 = np.asarray(u0, dtype=float).reshape(2)
        if self.form != "QQ":
            return np.linalg.solve(self.A, -self.B @ u0)
        if not np.isclose(u0[0], u0[1], rtol=1e-9, atol=1e-15):
            raise ValueError("QQ line has a steady state only for equal inflow and outflow "
                             f"(upstream_flow={u0[0]!r}, downstream_flow={u0[1]!r} m^3/s)")
        x = np.zeros(self.n_states)
        modes = slice(1, None)
        Am, Bm = self.A[modes, modes], self.B[modes]
        x[modes] = np.linalg.solve(Am, -Bm @ u0)
        x[0] = self.line.capacitance * (0.0 if mean_pressure is None else float(mean_pressure))
        return x

    def outputs(self, x, u):
        """Outputs ``C x + D u`` in form order.

        Parameters
        ----------
        x : array_like
            State vector, [SI, per :attr:`state_names`].
        u : array_like
            The two inputs in form order, [Pa] / [m^3/s].

        Returns
        -------
        ndarray
            The two outputs in form order, [Pa] / [m^3/s].
        """
        return self.C @ np.asarray(x) + self.D @ np.asarray(u)

    def to_control(self):
        """The line as a python-control ``StateSpace`` with named states, inputs, outputs.

        Returns
        -------
        control.StateSpace
            ``(A, B, C, D)`` with :attr:`state_names`, :attr:`input_names` and
            :attr:`output_names`, SI units.
        """
        import control

        return control.ss(self.A, self.B, self.C, self.D, states=list(self.state_names),
                          inputs=list(self.input_names), outputs=list(self.output_names))

    def step_response(self, t, input_index: int = 0, amplitude: float = 1.0, x0=None):
        """Exact response of the outputs to a step of one input at t = 0 from x0 (rest).

        Computed from the eigen-decomposition of A (no time stepping).

        Parameters
        ----------
        t : array_like
            Times >= 0, [s].
        input_index : int
            Which input steps, 0 or 1 (form order).
        amplitude : float
            Step size, [Pa] for a pressure input, [m^3/s] for a flow input.
        x0 : array_like or None
            Initial state, [SI]; zero when None.

        Returns
        -------
        ndarray
            Shape ``(len(t), 2)``: the outputs in form order, [Pa] / [m^3/s].
        """
        t = np.asarray(t, dtype=float)
        u = np.zeros(2)
        u[input_index] = amplitude
        lam, V = np.linalg.eig(self.A)
        x0 = np.zeros(self.n_states) if x0 is None else np.asarray(x0, dtype=float)
        b = self.B @ u
        z0 = np.linalg.solve(V, x0.astype(complex))
        zb = np.linalg.solve(V, b.astype(complex))
        with np.errstate(divide="ignore", invalid="ignore"):
            em1 = np.where(np.abs(lam) > 0, np.expm1(np.outer(t, lam)) / lam, t[:, None])
        z = np.exp(np.outer(t, lam)) * z0 + em1 * zb
        x = np.real(z @ V.T)
        return x @ self.C.T + self.D @ u


def _resolve_corrections(line, n_modes, form, corrections):
    if isinstance(corrections, str):
        if corrections == "exact":
            return correction_factors(line, n_modes, form)
        if corrections == "none":
            return np.ones(n_modes), np.ones(n_modes)
        raise ValueError(f"corrections must be 'exact', 'none' or (alpha, beta) arrays; got {corrections!r}")
    alpha, beta = (np.broadcast_to(np.asarray(v, dtype=float), (n_modes,)).copy() for v in corrections)
    if np.any(alpha <= 0) or np.any(beta <= 0):
        raise ValueError("correction factors alpha and beta must be positive [-]")
    return alpha, beta


class ModalLine(StateSpaceLine):
    """Modal state-space line with Yang-Tobler frequency/damping corrections (M9)-(M15).

    Parameters
    ----------
    line : Line
        The line (geometry, fluid, effective bulk modulus).
    n_modes : int
        Number of modes (two states each), >= 1.
    form : str
        Causal form "PQ", "QP", "PP" or "QQ" (model reference table 2.1).
    corrections : str or tuple of array_like
        "exact": alpha_i, beta_i from the dissipative model's roots (M15); "none": plain
        linear friction (alpha = beta = 1); or an ``(alpha, beta)`` pair of arrays, [-].
        Used by method "yang-tobler" only.
    method : str, optional
        "residue" (:data:`DEFAULT_LINE_METHOD`: exact poles and exact residues of the
        dissipative model, see :mod:`hydroline.lines.residue`) or "yang-tobler" (the 2005
        paper's model: Yang-Tobler frequency and damping corrections of linear friction).
        None: "yang-tobler" where ``corrections`` is given other than "exact", else the
        default.

    Attributes
    ----------
    A, B, C, D : ndarray
        State-space matrices; states, inputs and outputs as in the module docstring, inputs
        and outputs in form order, [SI].
    alpha, beta : ndarray or None
        Correction factors used, [-]; None for the residue method.
    state_names : list of str
        e.g. ``["mode1.pressure", "mode1.flow", ...]``.
    input_names, output_names : tuple of str
        e.g. ``("upstream_pressure", "downstream_flow")``.

    Raises
    ------
    ValueError
        For a bad line, number of modes, form, method or correction factors.

    Examples
    --------
    A 10 ft, 15.9 mm hose (effective bulk modulus 178 MPa) with six modes: the DC gain is
    the laminar steady state (M12), ``P_d = P_u - R Q_d`` and ``Q_u = Q_d``, exactly, thanks
    to the modifier G (M13); the first mode has the natural frequency of the exact
    dissipative model's first root, the quarter-wave frequency c/(4L) = 37.1 Hz lowered by
    alpha_1 (M9), (M15):

    >>> import numpy as np
    >>> from hydroline import MINERAL_OIL
    >>> from hydroline.lines import Line
    >>> line = Line(3.048, 0.0159, MINERAL_OIL, bulk_modulus=178e6)
    >>> m = ModalLine(line, 6, "PQ", method="yang-tobler")
    >>> dc = m.transfer(0.0).real
    >>> print(np.round(dc[0] / [1.0, -line.resistance], 9), np.round(dc[1], 9))
    [1. 1.] [0. 1.]
    >>> f1 = abs(m.eigenvalues()).min() / (2 * np.pi)
    >>> print(f"{f1:.2f} Hz = c/(4L)/alpha_1 = {line.wave_speed / (4 * line.length) / m.alpha[0]:.2f} Hz")
    35.90 Hz = c/(4L)/alpha_1 = 35.90 Hz
    """

    def __init__(self, line: Line, n_modes: int = 6, form: str = "PQ", corrections="exact",
                 method: str | None = None):
        if not isinstance(line, Line):
            raise ValueError(f"line must be a hydroline.lines.Line, got {type(line).__name__}")
        explicit = not (isinstance(corrections, str) and corrections == "exact")
        if method is None:   # corrections given: they are the Yang-Tobler line's
            method = "yang-tobler" if explicit else DEFAULT_LINE_METHOD
        if method == "residue" and explicit:
            raise ValueError("corrections apply to method 'yang-tobler' only; the residue line "
                             "has exact poles and residues")
        self.line = line
        self.n_modes = check_modes(n_modes)
        self.form = check_form(form)
        self.method = method
        if method == "residue":
            from .residue import residue_realisation
            from .residue_table import in_use, interpolated_realisation

            self.alpha = self.beta = None
            # (a sweep's runner: interpolated over Dn where that is within its tolerance)
            got = interpolated_realisation(line, self.n_modes, self.form) if in_use() else None
            self.A, self.B, self.C, self.D, self.state_names = (
                got if got is not None else residue_realisation(line, self.n_modes, self.form))
            self._set_ports()
            return
        if method != "yang-tobler":
            raise ValueError(f"method must be one of {', '.join(LINE_METHODS)}; got {method!r}")
        if line.viscoelastic:
            raise ValueError("a viscoelastic wall (M44) needs method 'residue' (the Yang-Tobler "
                             "line has the linear-friction numerators of an elastic wall)")
        self.alpha, self.beta = _resolve_corrections(line, self.n_modes, self.form, corrections)
        build = {"PQ": self._build_pq, "QP": self._build_qp,
                 "PP": self._build_pp, "QQ": self._build_qq}[self.form]
        self.A, self.B, self.C, self.D, self.state_names = build()
        self._set_ports()

    def __repr__(self):
        return f"ModalLine(L={self.line.length:g} m, d={self.line.diameter:g} m, n_modes={self.n_modes}, form={self.form!r})"

    # ---- PQ (M9-M13) -----------------------------------------------------------------
    def _build_pq(self):
        ln = self.line
        n = self.n_modes
        nu, d, Z0, Dn = ln.fluid.kinematic_viscosity, ln.diameter, ln.impedance, ln.dissipation_number
        omega = modal_angles(n, "PQ") / ln.wave_time                  # (M9)
        sg = (-1.0) ** np.arange(n)                                  # (-1)^(i+1), i from 1
        al, be = self.alpha, self.beta
        # mode i's blocks (M10): A_i = [[0, a], [b, c]], B_i = [[0, e], [f, 0]]
        a = sg * Z0 * omega
        b = -sg * omega / (Z0 * al**2)
        c = -32.0 * nu * be / (d**2 * al)
        e = -8.0 * nu * Z0 / (d**2 * Dn)
        f = 8.0 * nu / (d**2 * Z0 * Dn * al**2)
        A = np.zeros((2 * n, 2 * n))
        Bm = np.zeros((2 * n, 2))
        rows = 2 * np.arange(n)
        A[rows, rows + 1], A[rows + 1, rows], A[rows + 1, rows + 1] = a, b, c
        Bm[rows, 1], Bm[rows + 1, 0] = e, f
        names = [f"mode{i + 1}.{q}" for i in range(n) for q in ("pressure", "flow")]
        # sum of A_i^-1 B_i, each [[-a f, c e], [0, -b e]] / det(A_i), det(A_i) = -a b
        det = -a * b
        sum_AinvB = np.array([[np.sum(-a * f / det), np.sum(c * e / det)],
                              [0.0, np.sum(-b * e / det)]])
        G = -np.linalg.solve(sum_AinvB, np.array([[1.0, -8.0 * Z0 * Dn], [0.0, 1.0]]))  # (M13)
        C = np.tile(np.eye(2), (1, n))                                # (M11)
        return A, Bm @ G, C, np.zeros((2, 2)), names

    def _build_qp(self):
        A, B, C, D, names = self._build_pq()
        swap_in = np.array([[0.0, 1.0], [-1.0, 0.0]])     # [P_d, -Q_u] = swap_in @ [Q_u, P_d]
        flip_out = np.diag([1.0, -1.0])                   # [P_u, Q_d] = flip_out @ [P_d', Q_u']
        return A, B @ swap_in, flip_out @ C, D, names

    # ---- PP and QQ (model reference §2.4) ------------------------------------------------------
    def _mode_coefficients(self):
        ln = self.line
        nu, d = ln.fluid.kinematic_viscosity, ln.diameter
        omega = modal_angles(self.n_modes, "PP") / ln.wave_time
        a = 32.0 * nu * self.beta / (d**2 * self.alpha)
        b = omega**2 / self.alpha**2
        sign = (-1.0) ** np.arange(1, self.n_modes + 1)
        return a, b, sign

    def _build_pp(self):
        ln = self.line
        n = self.n_modes
        a, b, sign = self._mode_coefficients()
        nf = len(SCHOHL_M)
        N = 2 * n + 1 + nf
        A, B, C = np.zeros((N, N)), np.zeros((N, 2)), np.zeros((2, N))
        I, R = ln.inertance, ln.resistance
        rates = SCHOHL_N * ln.fluid.kinematic_viscosity / ln.radius**2
        A[0, 0] = -(R + 0.5 * R * SCHOHL_M.sum()) / I
        A[0, 1:1 + nf] = 0.5 * R * SCHOHL_M / I
        A[1:1 + nf, 0] = rates
        A[1:1 + nf, 1:1 + nf] = -np.diag(rates)
        B[0] = [1.0 / I, -1.0 / I]
        C[:, 0] = 1.0
        names = ["column.flow"] + [f"column.friction{i + 1}" for i in range(nf)]
        tau = ln.wave_time
        for k in range(n):
            v, q = 1 + nf + 2 * k, 2 + nf + 2 * k
            K = 2.0 * ln.capacitance / (tau**2 * self.alpha[k] ** 2)
            A[v, q] = 1.0
            A[q, v], A[q, q] = -b[k], -a[k]
            B[q] = [K, -sign[k] * K]
            C[:, q] = [1.0, sign[k]]
            names += [f"mode{k + 1}.volume", f"mode{k + 1}.flow"]
        return A, B, C, np.zeros((2, 2)), names

    def _build_qq(self):
        ln = self.line
        n = self.n_modes
        a, b, sign = self._mode_coefficients()
        N = 2 * n + 1
        A, B, C = np.zeros((N, N)), np.zeros((N, 2)), np.zeros((2, N))
        B[0] = [1.0, -1.0]
        C[:, 0] = 1.0 / ln.capacitance
        names = ["column.volume"]
        R = ln.resistance
        D = np.array([[R / 3.0, R / 6.0], [-R / 6.0, -R / 3.0]])   # exact DC offsets
        K = 2.0 * ln.impedance / ln.wave_time
        for k in range(n):
            m, p = 1 + 2 * k, 2 + 2 * k
            A[m, m], A[m, p] = -a[k], 1.0
            A[p, m] = -b[k]
            B[p] = [K, -sign[k] * K]
            C[:, p] = [1.0, sign[k]]
            dc = K * a[k] / b[k]
            D -= dc * np.outer([1.0, sign[k]], [1.0, -sign[k]])
            names += [f"mode{k + 1}.pressure_integral", f"mode{k + 1}.pressure"]
        return A, B, C, D, names


class RigidColumnLine(StateSpaceLine):
    """Reduced first-order PP line: a resistance in series with an inertance (M18).

    ``I dq/dt = P_u - P_d - R q``, ``Q_u = Q_d = q`` (state ``column.flow`` [m^3/s]), the 2005
    paper's accumulator connection line ("version II").

    Parameters
    ----------
    line : Line
        The line (R and I from its geometry and fluid).
    inertance_factor : float
        Multiplier of the plug-flow inertance rho L/A, [-]; 1 as in the 2005 paper (4/3 is the
        laminar-profile low-frequency value).

    Examples
    --------
    Its single pole is at ``-R/I`` and its DC admittance is ``1/R``:

    >>> from hydroline import MINERAL_OIL
    >>> from hydroline.lines import Line
    >>> line = Line(0.3, 0.0254, MINERAL_OIL)
    >>> col = RigidColumnLine(line)
    >>> round(float(col.eigenvalues()[0].real) / (-line.resistance / line.inertance), 12)
    1.0
    >>> round(float(col.transfer(0.0)[0, 0].real) * line.resistance, 12)
    1.0
    """

    def __init__(self, line: Line, inertance_factor: float = 1.0):
        self.line = line
        self.form = "PP"
        I = inertance_factor * line.inertance
        R = line.resistance
        self.A = np.array([[-R / I]])
        self.B = np.array([[1.0 / I, -1.0 / I]])
        self.C = np.array([[1.0], [1.0]])
        self.D = np.zeros((2, 2))
        self.state_names = ["column.flow"]
        self._set_ports()
