"""Lumped segmented line: N equal R-I-C segments in the PQ form (cf. model reference §2, M2-M4).

The line is cut into N equal segments, as the segmented-pipeline blocks of commercial
simulation tools do. Segment k (k = 1..N, from the upstream end) carries the flow ``q_k``
through its resistance ``R/N`` and inertance ``I/N`` from node k-1 to node k, and node k
stores the pressure ``p_k`` on the segment's capacitance ``C/N`` (R, I, C of the whole line
from (M2)-(M4)):

    (I/N) q_k' = p_{k-1} - p_k - (R/N) q_k,     p_0 = P_u (input)
    (C/N) p_k' = q_k - q_{k+1},                 q_{N+1} = Q_d (input)

outputs ``P_d = p_N``, ``Q_u = q_1``. The friction is the steady laminar one (R, Hagen-
Poiseuille), as in those tools: the DC gain is the laminar steady state (M12) exactly,
``P_d = P_u - R Q_d``, ``Q_u = Q_d``; the frequency-dependent friction of (M6) is not
represented, so the higher modes are under-damped. With the line blocked (Q_d = 0) the chain
is an LC ladder whose first resonance tends to the quarter-wave frequency c/(4L) as N grows:
without friction, N series inertances I/N and N shunt capacitances C/N between a pressure
source (a short) and a blocked end (open) have the natural frequencies
``w_m = (2N/sqrt(I C)) sin((2m - 1) pi / (2 (2N + 1)))``, so
``f_1 = (4N/pi) sin(pi/(2(2N + 1))) c/(4L) -> c/(4L)`` with a relative error O(1/N).

States, in order: ``segment{k}.flow`` [m^3/s], ``segment{k}.pressure`` [Pa] for k = 1..N.
"""
from __future__ import annotations

import numpy as np

from .line import Line
from .modal import StateSpaceLine

__all__ = ["LumpedLine"]


class LumpedLine(StateSpaceLine):
    """N-segment lumped R-I-C line, PQ form (inputs ``[P_u, Q_d]``, outputs ``[P_d, Q_u]``).

    Parameters
    ----------
    line : Line
        The line (length, diameter, fluid, effective bulk modulus).
    n_segments : int
        Number of equal segments N >= 1.
    form : str
        Causal form; only "PQ".

    Raises
    ------
    ValueError
        For a bad line, segment count or form.

    Examples
    --------
    Without friction the first resonance of N segments is
    ``(4N/pi) sin(pi/(2(2N + 1))) c/(4L)`` (module docstring); with the small laminar
    friction of a real hose it is the same to 0.01 Hz, and 5 % below the quarter-wave
    frequency c/(4L) at N = 10 (the error falls as 1/N):

    >>> import numpy as np
    >>> from hydroline import MINERAL_OIL
    >>> from hydroline.lines import Line
    >>> line = Line(3.048, 0.0159, MINERAL_OIL, bulk_modulus=178e6)
    >>> N = 10
    >>> lumped = LumpedLine(line, N)
    >>> f1 = abs(lumped.eigenvalues()).min() / (2 * np.pi)
    >>> f_ladder = 4 * N / np.pi * np.sin(np.pi / (2 * (2 * N + 1))) * line.wave_speed / (4 * line.length)
    >>> print(f"{f1:.2f} Hz, frictionless ladder {f_ladder:.2f} Hz, c/(4L) = {line.wave_speed / (4 * line.length):.2f} Hz")
    35.30 Hz, frictionless ladder 35.30 Hz, c/(4L) = 37.10 Hz
    """

    def __init__(self, line: Line, n_segments: int = 10, form: str = "PQ"):
        if not isinstance(line, Line):
            raise ValueError(f"line must be a hydroline.lines.Line, got {type(line).__name__}")
        if isinstance(n_segments, bool) or not isinstance(n_segments, (int, np.integer)) \
                or n_segments < 1:
            raise ValueError(f"n_segments must be an integer >= 1 [-], got {n_segments!r}")
        if str(form).upper() != "PQ":
            raise ValueError(f"form: the lumped line is built in the PQ form only, got {form!r}")
        self.line = line
        self.form = "PQ"
        self.n_segments = n = int(n_segments)
        R, I, C = line.resistance / n, line.inertance / n, line.capacitance / n
        A = np.zeros((2 * n, 2 * n))
        B = np.zeros((2 * n, 2))
        Cm = np.zeros((2, 2 * n))
        names = []
        for k in range(n):
            q, p = 2 * k, 2 * k + 1
            names += [f"segment{k + 1}.flow", f"segment{k + 1}.pressure"]
            # inertance: I q' = p_{k-1} - p_k - R q
            A[q, q] = -R / I
            A[q, p] = -1.0 / I
            if k == 0:
                B[q, 0] = 1.0 / I
            else:
                A[q, p - 2] = 1.0 / I
            # capacitance: C p' = q_k - q_{k+1}
            A[p, q] = 1.0 / C
            if k == n - 1:
                B[p, 1] = -1.0 / C
            else:
                A[p, q + 2] = -1.0 / C
        Cm[0, 2 * n - 1] = 1.0     # P_d = p_N
        Cm[1, 0] = 1.0             # Q_u = q_1
        self.A, self.B, self.C, self.D = A, B, Cm, np.zeros((2, 2))
        self.state_names = names
        self._set_ports()

    def __repr__(self):
        return (f"LumpedLine(L={self.line.length:g} m, d={self.line.diameter:g} m, "
                f"n_segments={self.n_segments})")
