"""Exact-pole line realisations interpolated over the dissipation number, for sweeps.

In the line's own units (time ``tau = L/c``, pressure ``Z0`` times flow) the exact
transfer matrix of (M6) depends on the dissipation number ``Dn`` alone: ``Gamma`` and
``Zc/Z0`` are functions of ``s tau`` and ``kappa^2 = s tau/Dn``. So is the residue line of
:func:`hydroline.lines.residue.residue_realisation` (form, modes and the viscous clusters
it resolves being given): with the states in the same units (a pressure state over Z0), its
matrices ``A tau``, ``B tau`` and C are functions of Dn, smooth between the Dn where the
number of resolved viscous clusters changes (:func:`~hydroline.lines.residue.viscous_clusters`).

A layout sweep realises a new line per variant (~4 ms each, two hoses a variant: ~40 % of
a variant's CPU). Inside :class:`interpolated_lines` (entered by a sweep's runner) a line
is instead interpolated from nodes on a fixed grid of ``log10 Dn``
(:data:`NODES_PER_DECADE`), each node realised directly (with the target's cluster count,
so that no stencil spans a change of it) and kept in this process and on disk (a later
sweep, or the sweep's other worker, reads it: ~0.3 ms instead of 1-4 ms): a polynomial of degree
:data:`DEGREE` through the nearest nodes, accepted where it differs from the one of the
degree below by at most :data:`TOLERANCE` of each state equation's largest entry; else,
and where a node's realisation made a choice that does not vary smoothly with Dn (the
tail's envelope bound enforced, a lumped viscous pole outside its cluster), the line is
realised directly. PQ and QP forms of elastic-walled lines (a QP node is the PQ node seen
from the line's other end, :func:`_mirrored`: one realisation serves both); the others are
always realised directly.
"""
from __future__ import annotations

import dataclasses
import math
import threading
from pathlib import Path

import numpy as np

from ..cache import load_table, source_tag, store_table
from .line import FORM_PORTS, Line
from .residue import realisation_with_notes, viscous_clusters

__all__ = ["interpolated_lines", "in_use", "interpolated_realisation", "NODES_PER_DECADE",
           "DEGREE", "TOLERANCE"]

#: Grid of the nodes: ``log10 Dn = i/NODES_PER_DECADE``, [-].
NODES_PER_DECADE = 16
#: Degree of the interpolating polynomial in ``log10 Dn`` (DEGREE + 1 nodes), [-].
DEGREE = 5
#: Largest accepted difference between the interpolants of degree DEGREE and DEGREE - 1,
#: relative to the largest entry of the state equation's row of ``[A tau, B tau]``, [-].
#: The direct realisation itself carries up to ~4e-7 of it at 6 modes (a 0.05 m hose: the
#: residues at the viscous roots amplify the roots' last bit), ~2e-5 at 20 modes (a 0.5 m
#: hose: a 1e-6 change of the length moves it by 1.6e-5); the line models' accuracy is ~1e-2.
TOLERANCE = 1e-5
#: A node whose first tail fit came this close to the envelope bound (``|H|/bound``) or
#: above is not interpolated across (the bound's enforcement is a discrete choice), [-].
TAIL_PEAK_LIMIT = 0.98
#: Nor one whose lumped viscous pole lies within this relative distance of its cluster's
#: range of rates (outside it another rule applies), [-].
LUMPED_MARGIN = 1e-3
#: The on-disk cache's table of nodes (:mod:`hydroline.cache`; ~5 kB each, a bounded set:
#: the grid points of the Dn that sweeps met, per form, modes and cluster count), kept
#: for later sweeps and processes (a sweep's other workers among them).
NODE_TABLE = "residue_line_nodes"
#: Nodes kept in this process (~10 kB each), [-].
NODES_KEPT = 4000
#: Stencils kept stacked (~50 kB each; made again from the nodes in ~0.05 ms), [-].
STENCILS_KEPT = 256
#: Grid points whose cluster-independent parts (~0.1 MB each: the modes, every cluster's
#: viscous roots, the tail fit's exact responses) are kept for nodes of other cluster
#: counts there, [-]. (Where the count changes every ~0.02-0.04 decade of Dn, a node of
#: the next count at the same point then costs about a fifth of the first.)
SHARED_KEPT = 64


class _Use(threading.local):
    """Per thread: True inside :class:`interpolated_lines`."""

    on = False


_USE = _Use()
_NODES: dict = {}
_STENCILS: dict = {}
_SHARED: dict = {}
#: The line code's source (the nodes' key on disk)
_SOURCE_TAG = source_tag(*(Path(__file__).with_name(f) for f in (
    "residue_table.py", "residue.py", "line.py", "corrections.py", "bessel.py")))


class interpolated_lines:
    """Context manager: within it (in this thread) :func:`interpolated_realisation` is used
    by :class:`~hydroline.lines.ModalLine` for residue lines (a sweep's runner enters it)."""

    def __enter__(self):
        self._saved, _USE.on = _USE.on, True
        return self

    def __exit__(self, *exc):
        _USE.on = self._saved
        return False


def in_use() -> bool:
    """Whether this thread is inside :class:`interpolated_lines`.

    Returns
    -------
    bool
        True inside it.
    """
    return _USE.on


def _pressures(form: str, names):
    """Which states (``names``), inputs and outputs of a residue line in ``form`` are
    pressures (the rest are flows: :mod:`hydroline.lines.residue`), three boolean arrays."""
    inputs, outputs = FORM_PORTS[form]
    return tuple(np.array(["pressure" in x.rsplit(".", 1)[-1] for x in group])
                 for group in (names, inputs, outputs))


def _units(line: Line, form: str, names):
    """The line's units of its states, inputs and outputs: Z0 for a pressure, 1 for a flow,
    [Pa s/m^3 or 1]."""
    return tuple(np.where(m, line.impedance, 1.0) for m in _pressures(form, names))


def _node(line: Line, n: int, form: str, clusters: int, i: int):
    """The realisation at ``log10 Dn = i/NODES_PER_DECADE`` in the line's units:
    ``(names, A tau, B tau, C, ok)``, ok False where it may not be interpolated across;
    kept in this process and in the on-disk cache (:data:`NODE_TABLE`). A QP node is the
    PQ node seen from the line's other end (:func:`_mirrored`): one realisation serves
    both forms."""
    key = (form, n, clusters, i)
    got = _NODES.get(key)
    if got is not None:
        return got
    if form == "QP":
        got = _mirrored(_node(line, n, "PQ", clusters, i))
    if got is None:
        disk_key = f"{_SOURCE_TAG}|{form}|{n}|{clusters}|{i}/{NODES_PER_DECADE}"
        got = _decoded(load_table(NODE_TABLE, disk_key))
        if got is None:
            got = _realised_node(line, n, form, clusters, i)
            store_table(NODE_TABLE, disk_key, _encoded(got))
    if len(_NODES) >= NODES_KEPT:
        _NODES.clear()
    _NODES[key] = got
    return got


def _ends_swapped(name: str) -> str:
    """A state's name with "upstream" and "downstream" exchanged."""
    return "downstream".join(part.replace("downstream", "upstream")
                             for part in name.split("upstream"))


def _mirrored(node):
    """The QP node of a PQ node, or None where its states do not map one to one.

    The QP line is the PQ line seen from its other end: the ends exchange their names and
    a flow its sign, so that QP's inputs ``(Q_u, P_d)`` are PQ's ``(P_u, Q_d)`` of the
    mirror image as ``(P_d, -Q_u)`` and its outputs ``(P_u, Q_d)`` the mirror's
    ``(P_d, -Q_u)``: ``H_QP = diag(1, -1) H_PQ [[0, 1], [-1, 0]]`` (the exact transfer
    matrices of (M6), and every step of the residue realisation, which fits each entry).
    Its states are PQ's with the ends exchanged and a flow state's sign changed; a lumped
    viscous state ``viscous_{end}{j}`` belongs to input j, which is the other input in the
    mirror. QP's own realisation lists them in PQ's order with the ends exchanged (equal to
    it within ~1e-14 of each row, tests/test_residue_table.py)."""
    names, Ad, Bd, Cd, ok = node
    swapped = [_ends_swapped(x) for x in names]         # QP's states, in order
    source = {}
    for k, x in enumerate(swapped):                     # PQ's state k in the mirror
        if x.startswith("viscous_"):
            head, _, q = x.partition(".")
            j = {"1": "2", "2": "1"}.get(head[-1:])
            if j is None:
                return None
            x = f"{head[:-1]}{j}.{q}"
        source[x] = k
    try:
        perm = np.array([source[x] for x in swapped], dtype=np.intp)
    except KeyError:
        return None
    if len(set(perm.tolist())) != len(perm):
        return None
    pressure, _, _ = _pressures("QP", swapped)
    sign = np.where(pressure, 1.0, -1.0)                # a flow state changes its sign
    A = Ad[np.ix_(perm, perm)] * sign[:, None] * sign[None, :]
    B = Bd[perm][:, [1, 0]] * np.array([-1.0, 1.0]) * sign[:, None]
    C = Cd[:, perm] * np.array([[1.0], [-1.0]]) * sign[None, :]
    return tuple(swapped), A, B, C, ok


def _realised_node(line: Line, n: int, form: str, clusters: int, i: int):
    """:func:`_node`, computed."""
    # the line at that Dn, and what its realisations with other cluster counts share
    at, shared = _SHARED.pop((form, n, i), (None, None))
    if at is None:
        dn = 10.0 ** (i / NODES_PER_DECADE)
        at, shared = dataclasses.replace(line, length=line.length * dn / line.dissipation_number), {}
    _SHARED[(form, n, i)] = at, shared                  # (most recently used last)
    if len(_SHARED) > SHARED_KEPT:
        _SHARED.pop(next(iter(_SHARED)))
    A, B, C, _, names, notes = realisation_with_notes(at, n, form, clusters, shared)
    tau = at.wave_time
    s, w_in, w_out = _units(at, form, names)
    Ad = tau * A * s[None, :] / s[:, None]
    Bd = tau * B * w_in[None, :] / s[:, None]
    Cd = C * s[None, :] / w_out[:, None]
    ok = (notes.get("tail_peak", 0.0) < TAIL_PEAK_LIMIT
          and notes.get("lumped_margin", np.inf) > LUMPED_MARGIN)
    return tuple(names), Ad, Bd, Cd, bool(ok)


def _encoded(node) -> dict:
    """A node as JSON (A by its nonzeros: ~50 of its ~1000 entries)."""
    names, Ad, Bd, Cd, ok = node
    rows, cols = np.nonzero(Ad)
    return {"names": list(names), "rows": rows.tolist(), "cols": cols.tolist(),
            "A": Ad[rows, cols].tolist(), "B": Bd.tolist(), "C": Cd.tolist(), "ok": ok}


def _decoded(stored):
    """:func:`_encoded`'s node, or None where ``stored`` is None or does not fit."""
    if stored is None:
        return None
    try:
        names = tuple(stored["names"])
        N = len(names)
        Ad = np.zeros((N, N))
        Ad[np.array(stored["rows"], dtype=np.intp), np.array(stored["cols"], dtype=np.intp)] = \
            np.array(stored["A"], dtype=float)
        Bd, Cd = np.array(stored["B"], dtype=float), np.array(stored["C"], dtype=float)
        if Bd.shape != (N, 2) or Cd.shape != (2, N):
            return None
        return names, Ad, Bd, Cd, bool(stored["ok"])
    except (TypeError, ValueError, KeyError, IndexError):
        return None


def _lagrange(u, nodes):
    """Weights of the polynomial through ``nodes`` at ``u``, [-]."""
    w = np.ones(len(nodes))
    for k, uk in enumerate(nodes):
        for m, um in enumerate(nodes):
            if m != k:
                w[k] *= (u - um) / (uk - um)
    return w


def interpolated_realisation(line: Line, n_modes: int, form: str):
    """The residue line's matrices (:func:`~hydroline.lines.residue.residue_realisation`)
    interpolated over the dissipation number (module docstring), or None where they are
    not (another form, a viscoelastic wall, a node that may not be interpolated across, an
    interpolant off by more than :data:`TOLERANCE`): the caller realises the line directly.

    Parameters
    ----------
    line : Line
        The line, SI
    n_modes : int
        Retained modes, [-]
    form : str
        Causal form (canonical: "PQ", "QP", "PP" or "QQ")

    Returns
    -------
    tuple or None
        ``(A, B, C, D, state_names)`` as :func:`~hydroline.lines.residue.residue_realisation`.
    """
    if line.viscoelastic or form not in ("PQ", "QP"):
        return None
    clusters = viscous_clusters(line, n_modes, form)
    u = math.log10(line.dissipation_number) * NODES_PER_DECADE
    first = math.floor(u) - (DEGREE - 1) // 2
    stencil = _stencil(line, n_modes, form, clusters, first)
    if stencil is None:
        return None
    names, M, Cd, pressure = stencil
    idx = range(first, first + DEGREE + 1)
    # the weights of degree DEGREE, and of the degree below without the node farthest from u
    W = np.zeros((2, DEGREE + 1))
    W[0] = _lagrange(u, idx)
    drop = 0 if abs(u - idx[0]) > abs(u - idx[-1]) else DEGREE
    keep = [k for k in range(DEGREE + 1) if k != drop]
    W[1, keep] = _lagrange(u, [idx[k] for k in keep])
    hi, lo = np.tensordot(W, M, 1)                     # [A tau, B tau] of both
    if not np.all(np.abs(hi - lo).max(axis=1) <= TOLERANCE * np.abs(hi).max(axis=1)):
        return None
    tau, z0 = line.wave_time, line.impedance
    s, w_in, w_out = (np.where(m, z0, 1.0) for m in pressure)
    N = len(names)
    A = hi[:, :N] * (s[:, None] / tau) / s[None, :]
    B = hi[:, N:] * s[:, None] / (tau * w_in[None, :])
    C = Cd * w_out[:, None] / s[None, :]
    return A, B, C, np.zeros((2, 2)), list(names)


def _stencil(line: Line, n: int, form: str, clusters: int, first: int):
    """The nodes ``first .. first + DEGREE`` together: ``(names, [A tau, B tau] stacked,
    C, (pressure states, inputs, outputs))``, or None where one may not be interpolated
    across or their states differ (kept: a sweep's neighbours share a stencil)."""
    key = (form, n, clusters, first)
    got = _STENCILS.get(key, False)
    if got is not False:
        return got
    nodes = [_node(line, n, form, clusters, i) for i in range(first, first + DEGREE + 1)]
    names, Cd = nodes[0][0], nodes[0][3]
    got = None
    if all(nd[4] and nd[0] == names and np.array_equal(nd[3], Cd) for nd in nodes):
        M = np.stack([np.hstack([nd[1], nd[2]]) for nd in nodes])
        got = names, M, Cd, _pressures(form, names)
    if len(_STENCILS) >= STENCILS_KEPT:
        _STENCILS.clear()
    _STENCILS[key] = got
    return got
