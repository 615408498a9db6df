"""Shifted linear systems ``(s I - J) dz = b`` of a compiled model, solved through its bordered
Jacobian (:mod:`.codegen`): the steady state's Newton and pseudo-transient steps.

``J`` (the Jacobian of the scaled states, dense in blocks: every state of a hose section moves
every other through the signals at its ends) is never formed: with ``F_z, F_v, H_z, H_v`` the
blocks of the bordered Jacobian (the connections cut open at ``v``),

    [ s I - F_z    -F_v   ] [dz]   [b]
    [   -H_z     I - H_v  ] [dv] = [0]

has as many nonzeros as the components' own blocks. Solved with LAPACK below
:data:`SPARSE_STATES` states (SciPy's sparse modules cost more to import than these solves),
with SciPy's SuperLU from there: its factors grow with the number of states where J's grow
with their square (the default rig's rest state at 30 modes per hose section, 330 states:
0.02 s of CPU against 0.8 s on J; at 40, 410 states: 0.4 s against 2.1 s). The rest state
found is J's to the solver's tolerance.
"""
from __future__ import annotations

import ctypes

import numpy as np

__all__ = ["BorderedSystem", "SPARSE_STATES"]

#: Bordered systems of at least this size are solved sparse (SuperLU), smaller ones with
#: LAPACK (the default rig's: 161 unknowns, ~15 solves of ~0.5 ms), [-].
SPARSE_STATES = 200


class BorderedSystem:
    """The bordered Jacobian of one compiled model, and sparse solves with it.

    Parameters
    ----------
    native : NativeModel
        The compiled model (:func:`hydroline.compiled.native_model`)
    """

    def __init__(self, native):
        lib = native.lib
        dp = ctypes.POINTER(ctypes.c_double)
        llp = ctypes.POINTER(ctypes.c_longlong)
        lib.hl_bordered_sizes.argtypes = [llp]
        lib.hl_bordered_pattern.argtypes = [llp, llp]
        lib.hl_bordered_jacobian.argtypes = [ctypes.c_double, dp, dp, dp, dp, dp]
        sizes = (ctypes.c_longlong * 3)()
        lib.hl_bordered_sizes(sizes)
        self.n, self.size, nnz = (int(v) for v in sizes)
        colind = np.zeros(self.size + 1, dtype=np.int64)
        row = np.zeros(max(nnz, 1), dtype=np.int64)
        lib.hl_bordered_pattern(colind.ctypes.data_as(llp), row.ctypes.data_as(llp))
        nnz = int(colind[-1])
        self._lib = lib
        self._constants = np.ascontiguousarray(native.generated.constants if
                                               native.generated.constants.size else np.zeros(1))
        self._scales = np.ascontiguousarray(np.asarray(native.network.state_scales, dtype=float))
        self._values = np.zeros(max(int(sizes[2]), 1))
        cols = np.repeat(np.arange(self.size), np.diff(colind))
        rows = row[:nnz]
        # the matrix's nonzeros: the bordered Jacobian's, negated, then the identity's
        # diagonal (states: times the shift; signals: 1)
        diag = np.arange(self.size)
        self._rows = np.concatenate([rows, diag])
        self._cols = np.concatenate([cols, diag])
        self._nnz = nnz

    def jacobian_nonzeros(self, t: float, x, p) -> np.ndarray:
        """The bordered Jacobian's nonzeros at (t, x) in its compressed-column order, states
        scaled, [1/s] (the cut signals' rows and columns in SI).

        Parameters
        ----------
        t : float
            Time, [s]
        x : ndarray
            States, [SI]
        p : ndarray
            Runtime parameters, [SI]

        Returns
        -------
        ndarray
            The nonzeros, [1/s] (cut signals' rows and columns in SI).
        """
        dp = ctypes.POINTER(ctypes.c_double)
        x = np.ascontiguousarray(np.asarray(x, dtype=float))
        p = np.ascontiguousarray(np.asarray(p, dtype=float))
        if p.size == 0:
            p = np.zeros(1)
        self._lib.hl_bordered_jacobian(float(t), x.ctypes.data_as(dp), p.ctypes.data_as(dp),
                                       self._constants.ctypes.data_as(dp),
                                       self._scales.ctypes.data_as(dp),
                                       self._values.ctypes.data_as(dp))
        return self._values[:self._nnz]

    def solve_shifted(self, t: float, x, p, shift: float, b) -> np.ndarray:
        """dz solving ``(shift I - J) dz = b``, J the Jacobian of the scaled states at (t, x).

        Parameters
        ----------
        t : float
            Time, [s]
        x : ndarray
            States, [SI]
        p : ndarray
            Runtime parameters, [SI]
        shift : float
            s, [1/s] (0: a Newton step, ``-J dz = b``)
        b : ndarray
            Right-hand side, scaled states per second, [1/s]

        Returns
        -------
        ndarray
            dz, scaled states, [-]

        Raises
        ------
        numpy.linalg.LinAlgError
            The matrix is singular
        """
        diag = np.ones(self.size)
        diag[:self.n] = shift
        values = np.concatenate([-self.jacobian_nonzeros(t, x, p), diag])
        rhs = np.zeros(self.size)
        rhs[:self.n] = b
        if self.size < SPARSE_STATES:      # LAPACK on the (small) bordered matrix
            M = np.zeros((self.size, self.size))
            M[self._rows[:self._nnz], self._cols[:self._nnz]] = values[:self._nnz]
            M[self._rows[self._nnz:], self._cols[self._nnz:]] += values[self._nnz:]
            return np.linalg.solve(M, rhs)[:self.n]
        from scipy.sparse import csc_matrix
        from scipy.sparse.linalg import splu

        M = csc_matrix((values, (self._rows, self._cols)), shape=(self.size, self.size))
        try:
            sol = splu(M).solve(rhs)
        except RuntimeError as e:          # SuperLU: "Factor is exactly singular"
            raise np.linalg.LinAlgError(str(e)) from None
        return sol[:self.n]
