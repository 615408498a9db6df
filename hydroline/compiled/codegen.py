"""C code for an assembled network: right-hand side, sparse Jacobian, signals, sparse LU.

The network's CasADi SX graph (:class:`~hydroline.engine.CompiledModel`) is walked
instruction by instruction and written out as straight-line C. Every numeric constant of the
graph (areas, lengths, modal matrices, state scales, ...) is read from a runtime array ``c``
instead of being written into the code, so the C source depends only on the network's
*structure*: the variants of a design study (other hose lengths, bulk moduli, accumulator
sizes) share one compiled library, and the library's cache key is a hash of the source.

Generated functions (``z`` are the states scaled by their typical magnitudes, ``x = z s``):

``hl_f(t, z, p, c, dz)``
    dz/dt of the scaled states (docs/model.md M1-M24 as assembled)
``hl_jac(t, z, p, c, jnz)``
    the bordered Jacobian (below), nonzeros in compressed-column
    order (``hl_ext_colind``, ``hl_ext_row``)
``hl_signals(t, z, p, c, y)``
    every network signal, [SI]
``hl_lu_factor(jnz, g, a)``
    sparse LU of the bordered ``W = I - g J`` without pivoting, in
    a fill-reducing (minimum degree) order fixed at generation
    time; returns the 1-based failing pivot or 0
``hl_lu_solve(a, b)``
    solves ``W v = b`` in place with the factors
``hl_lu_*`` tables
    the factors' pattern (slots, updates, and by rows), from which ``bdf.c``
    factors and solves ``W`` for a complex ``g`` too (its Radau IIA)

The bordered Jacobian. A hose section's states couple to its neighbours' only through the
few signals at its ends (a pressure, a flow), yet every state of one section moves every
other's derivative through them: the Jacobian d(dz/dt)/dz of a network of hoses is dense in
blocks (138 states at 6 modes per section: 3 400 nonzeros; 330 states at 30 modes: 23 900),
and so are its LU factors (24 000 slots, 1 Mflop a factorisation) and the code that writes
them. The connections are cut open instead (:func:`interface_signals`): with ``v`` the cut
signals, each component's derivatives ``F(z, v)`` and outputs ``H(z, v)`` depend on its own
states and its inputs only, and Newton's linear system ``(I - g J) dz = b`` is solved as

    [ I - g F_z   -g F_v ] [dz]   [b]
    [   -H_z     I - H_v ] [dv] = [0]

whose matrix has as many nonzeros as the components' own blocks (``J = F_z + F_v (I - H_v)^-1
H_z`` is its Schur complement; the solution dz is the same). Its LU, in minimum-degree order,
eliminates each section's modes into the few signals at its ends: factors, code and compile
time grow with the number of states, not its square.
"""
from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass

import casadi as ca
import numpy as np

from .generated import GeneratedModel, UnsupportedOperation, number_prefix

__all__ = ["GeneratedModel", "generate", "UnsupportedOperation", "structure_key",
           "constant_positions", "constants_at", "scaled_functions", "number_prefix",
           "interface_signals", "bordered_jacobian", "schur_pattern"]


_BINARY = {
    ca.OP_ADD: "({a}+{b})", ca.OP_SUB: "({a}-{b})", ca.OP_MUL: "({a}*{b})",
    ca.OP_DIV: "({a}/{b})", ca.OP_POW: "pow({a},{b})", ca.OP_CONSTPOW: "pow({a},{b})",
    ca.OP_FMIN: "fmin({a},{b})", ca.OP_FMAX: "fmax({a},{b})",
    ca.OP_LT: "({a}<{b})", ca.OP_LE: "({a}<={b})", ca.OP_EQ: "({a}=={b})",
    ca.OP_NE: "({a}!={b})", ca.OP_AND: "({a}&&{b})", ca.OP_OR: "({a}||{b})",
    ca.OP_IF_ELSE_ZERO: "({a}?{b}:0.)", ca.OP_ATAN2: "atan2({a},{b})",
    ca.OP_COPYSIGN: "copysign({a},{b})", ca.OP_FMOD: "fmod({a},{b})",
    ca.OP_HYPOT: "hypot({a},{b})",
}
_UNARY = {
    ca.OP_ASSIGN: "{a}", ca.OP_NEG: "(-{a})", ca.OP_EXP: "exp({a})", ca.OP_LOG: "log({a})",
    ca.OP_SQRT: "sqrt({a})", ca.OP_SQ: "({a}*{a})", ca.OP_TWICE: "(2.*{a})",
    ca.OP_INV: "(1./{a})", ca.OP_SIN: "sin({a})", ca.OP_COS: "cos({a})", ca.OP_TAN: "tan({a})",
    ca.OP_ASIN: "asin({a})", ca.OP_ACOS: "acos({a})", ca.OP_ATAN: "atan({a})",
    ca.OP_SINH: "sinh({a})", ca.OP_COSH: "cosh({a})", ca.OP_TANH: "tanh({a})",
    ca.OP_ASINH: "asinh({a})", ca.OP_ACOSH: "acosh({a})", ca.OP_ATANH: "atanh({a})",
    ca.OP_FABS: "fabs({a})", ca.OP_SIGN: "hl_sign({a})", ca.OP_FLOOR: "floor({a})",
    ca.OP_CEIL: "ceil({a})", ca.OP_NOT: "(!{a})", ca.OP_ERF: "erf({a})",
    ca.OP_LOG1P: "log1p({a})", ca.OP_EXPM1: "expm1({a})",
}


def assignments(fun: ca.Function, binary: dict, unary: dict, inputs: list[str], output: str,
                constants: list[float]):
    """The straight-line program of an SX function as ``(target, expression)`` pairs.

    Parameters
    ----------
    fun : casadi.Function
        An SX function
    binary, unary : dict
        CasADi operation code -> expression template (``{a}``, ``{b}``):
        the target language's spelling of each operation
    inputs : list[str]
        Per function input, how to read nonzero ``{nz}`` (``"z[{nz}]"``)
    output : str
        How to write output nonzero ``{nz}`` (``"dz[{nz}]"``)
    constants : list[float]
        Constants found are appended here and read as ``c[k]``

    Returns
    -------
    list of tuple
        ``(target, expression)`` pairs, in execution order.

    Raises
    ------
    UnsupportedOperation
        An operation without a template (e.g. a call to an interpolant)

    Notes
    -----
    Work variables are ``w0, w1, ...`` (``fun.sz_w()`` of them).
    """
    for k in range(fun.n_instructions()):
        op = fun.instruction_id(k)
        if op == ca.OP_CONST:
            (o,) = fun.instruction_output(k)
            yield f"w{o}", f"c[{len(constants)}]"
            constants.append(float(fun.instruction_constant(k)))
        elif op == ca.OP_INPUT:
            (o,) = fun.instruction_output(k)
            i, nz = fun.instruction_input(k)
            yield f"w{o}", inputs[i].format(nz=nz)
        elif op == ca.OP_OUTPUT:
            (a,) = fun.instruction_input(k)
            _, nz = fun.instruction_output(k)
            yield output.format(nz=nz), f"w{a}"
        elif op in binary:
            a, b = fun.instruction_input(k)
            (o,) = fun.instruction_output(k)
            yield f"w{o}", binary[op].format(a=f"w{a}", b=f"w{b}")
        elif op in unary:
            (a,) = fun.instruction_input(k)
            (o,) = fun.instruction_output(k)
            yield f"w{o}", unary[op].format(a=f"w{a}")
        else:
            raise UnsupportedOperation(f"CasADi operation code {op} in {fun.name()}")


def _function_c(fun: ca.Function, name: str, inputs: list[str], output: str,
                constants: list[float], attributes: str = "") -> str:
    """One SX function as C; its constants are appended to ``constants`` (read as c[k]);
    ``attributes`` go before its definition (e.g. ``HL_RARELY_CALLED``)."""
    lines = [f"{attributes + ' ' if attributes else ''}static void {name}(double t, const double* z, "
             f"const double* p, const double* c, double* {output}) {{"]
    nw = fun.sz_w()
    if nw:
        lines.append("  double " + ", ".join(f"w{i}" for i in range(nw)) + ";")
    body = [f"  {target}={expr};" for target, expr in
            assignments(fun, _BINARY, _UNARY, inputs, output + "[{nz}]", constants)]
    if not body:
        body.append("  (void)t; (void)z; (void)p; (void)c;")
    lines.extend(body)
    lines.append("  (void)t; (void)z; (void)p; (void)c;")
    lines.append("}")
    return "\n".join(lines)


def scaled_functions(model):
    """f, its bordered Jacobian and the signals of a compiled model in scaled states z = x/scale.

    Where the model's graph takes the components' numbers as symbols (``model.k``,
    :class:`~hydroline.engine.CompiledModel`), the functions take them, the state scales and
    their inverses as a fourth input ``c = [numbers, scales, 1/scales]``
    (:func:`number_prefix`): their C reads them from the constants array, and depends on the
    structure only.

    Parameters
    ----------
    model : CompiledModel
        The network's CasADi graph

    Returns
    -------
    (f, jac, signals) : tuple of casadi.Function
        Functions of (t, z, p) or (t, z, p, c): dz/dt, the bordered
        Jacobian (:func:`bordered_jacobian`; d(dz/dt)/dz itself where the network is not
        cut), every signal [SI]
    """
    scales = np.asarray(model.network.state_scales, dtype=float)
    n = len(scales)
    z = ca.SX.sym("z", n)
    k = getattr(model, "k", None)
    if k is None:
        s, inverse, inputs = ca.DM(scales), ca.DM(1.0 / scales), [model.t, z, model.p]
        dx, y, equations = model.dx, model.y, None
    else:
        s, inverse = ca.SX.sym("s", n), ca.SX.sym("inverse_s", n)
        inputs = [model.t, z, model.p, ca.vertcat(k, s, inverse)]
        dx, y, equations = model.dx_general, model.y_general, model.number_equations
    x_of_z = z * s
    # times 1/scale, not divided by it: a division per state costs as much as the rest of a
    # hose section's derivative (x / s and x * (1/s) differ by at most an ulp)
    dz = ca.substitute(dx, model.x, x_of_z) * inverse
    y = ca.substitute(y, model.x, x_of_z)
    return (ca.Function("hl_f", inputs, [dz]),
            ca.Function("hl_jac", inputs,
                        [bordered_jacobian(model, z, x_of_z, y, dz, inverse, equations)]),
            ca.Function("hl_signals", inputs, [y]))


def interface_signals(network) -> list:
    """The connections the bordered Jacobian cuts open: every signal some component reads
    whose producer has states or feed-through (a value that moves with the states), in the
    network's signal order, then every component's
    :attr:`~hydroline.engine.component.Component.internal_signals` as ``(component name,
    internal name)`` (a hose end's cavity-free pressure: read by all the section's states,
    it would make its block dense); none where the network cannot be evaluated cut open (a
    model without :meth:`~hydroline.engine.Network.evaluate`, e.g. the FMU's plant).

    Parameters
    ----------
    network : Network
        The assembled model

    Returns
    -------
    list
        Signal names (str), in the network's signal order, then (component name, internal
        signal name) pairs.
    """
    if not callable(getattr(network, "evaluate", None)) or not hasattr(network, "producer"):
        return []
    read = {c.signal(port) for c in network.components for port in c.inputs}
    out = []
    for sig in network.signal_names:
        c, _ = network.producer[sig]
        if sig in read and (c.states or c.feedthrough):
            out.append(sig)
    return out + [(c.name, name) for c in network.components for name in c.internal_signals]


def bordered_jacobian(model, z, x_of_z, y, dz, inverse_scales=None, equations=None):
    """The bordered Jacobian of a network cut open at its :func:`interface_signals` ``v``:
    ``[[F_z, F_v], [H_z, H_v]]`` of the scaled derivatives ``F`` and the cut signals' values
    ``H`` as functions of (z, v), at v = the signals' values at z (module docstring);
    d(dz/dt)/dz itself where no signal is cut.

    Parameters
    ----------
    model : CompiledModel
        The network's CasADi graph
    z : casadi.SX
        The scaled states, [-]
    x_of_z : casadi.SX
        The states in terms of z, [SI]
    y : casadi.SX
        Every signal in terms of z, [SI]
    dz : casadi.SX
        dz/dt in terms of z, [1/s]
    inverse_scales : casadi.SX or DM
                            1 / each state's scale, [1/SI] (symbols where the numbers
                            are); None: the network's
    equations : dict
        Component name -> the object whose equations stand for it (its
        numbers as symbols, :meth:`~hydroline.engine.Network.evaluate`);
        None: the components' own

    Returns
    -------
    casadi.SX
        (n + n_v) x (n + n_v), sparse
    """
    net = model.network
    cut = interface_signals(net)
    if not cut:
        return ca.jacobian(dz, z)
    v = ca.SX.sym("v", len(cut))
    n, m = z.numel(), model.p.numel()
    dx, sig = net.evaluate(model.t, [x_of_z[i] for i in range(n)], [model.p[i] for i in range(m)],
                           equations, given={s: v[k] for k, s in enumerate(cut)})
    if inverse_scales is None:
        inverse_scales = ca.DM(1.0 / np.asarray(net.state_scales, dtype=float))
    rows = ca.vertcat(*[ca.SX(d) * inverse_scales[i] for i, d in enumerate(dx)],
                      *[ca.SX(sig[s]) for s in cut])
    jac = ca.jacobian(rows, ca.vertcat(z, v))
    at = {s: k for k, s in enumerate(net.signal_names)}
    # (an internal signal's value is its component's, of the states alone: sig holds it)
    return ca.substitute(jac, v, ca.vertcat(*[y[at[s]] if s in at else ca.SX(sig[s])
                                              for s in cut]))


def schur_pattern(n: int, colind, row):
    """The pattern of ``J = F_z + F_v (I - H_v)^-1 H_z`` from the bordered Jacobian's pattern
    (compressed column, ``n`` states first): what d(dz/dt)/dz can hold.

    Parameters
    ----------
    n : int
        States, [-]
    colind : array
        Column starts of the bordered pattern, [-]
    row : array
        Row of each of its nonzeros, [-]

    Returns
    -------
    (colind, row) : ndarray, ndarray
        J's compressed-column pattern, rows ascending, [-]
    """
    size = len(colind) - 1
    M = np.zeros((size, size), dtype=bool)
    M[np.asarray(row, dtype=np.intp), np.repeat(np.arange(size), np.diff(colind))] = True
    Fz, Fv, Hz, Hv = M[:n, :n], M[:n, n:], M[n:, :n], M[n:, n:]
    reach = np.eye(size - n, dtype=bool)       # (I - H_v)^-1: the signals each one reads through
    while True:
        more = reach | ((Hv.astype(np.int64) @ reach) > 0)
        if (more == reach).all():
            break
        reach = more
    J = Fz | ((Fv.astype(np.int64) @ ((reach.astype(np.int64) @ Hz) > 0)) > 0)
    rows_j, cols_j = np.nonzero(J.T)           # column by column, rows ascending
    colind_j = np.concatenate([[0], np.cumsum(np.bincount(rows_j, minlength=n))])
    return colind_j.astype(np.int64), cols_j.astype(np.int64)


# ---- sparse LU with a fixed order ----------------------------------------------------------
def minimum_degree_order(n: int, pattern) -> list[int]:
    """Greedy minimum-degree elimination order of the symmetrised pattern (ties: lowest index).

    Parameters
    ----------
    n : int
        Matrix size (states), [-]
    pattern : iterable
        ``(row, column)`` pairs of the nonzeros

    Returns
    -------
    list of int
        The elimination order.
    """
    adj = [set() for _ in range(n)]
    for i, j in pattern:
        if i != j:
            adj[i].add(j)
            adj[j].add(i)
    alive = set(range(n))
    order = []
    while alive:
        k = min(alive, key=lambda v: (len(adj[v]), v))
        nb = adj[k]
        for u in nb:
            adj[u] |= nb - {u}
            adj[u].discard(k)
        alive.remove(k)
        order.append(k)
        adj[k] = set()
    return order


@dataclass
class LUPlan:
    """Symbolic LU of ``W = I - g J`` in a fixed pivot order (diagonal pivots).

    Parameters
    ----------
    order : list
        Pivot k is state ``order[k]``
    slots : dict
        (i, j) in pivot coordinates -> index in the factor array
    lower : list
        ``lower[k]``: rows i > k with L[i, k] != 0
    upper : list
        ``upper[k]``: columns j > k with U[k, j] != 0
    flops : int
        Multiply-adds of one factorisation, [-]
    """

    order: list          # pivot k is state order[k]
    slots: dict          # (i, j) in pivot coordinates -> index in the factor array
    lower: list          # lower[k]: rows i > k with L[i, k] != 0
    upper: list          # upper[k]: columns j > k with U[k, j] != 0
    flops: int


def lu_plan(n: int, rows, cols) -> LUPlan:
    """The symbolic LU of ``I - g J`` for the Jacobian's pattern, in minimum-degree order.

    Parameters
    ----------
    n : int
        Matrix size (states), [-]
    rows : list
        Row index of each Jacobian nonzero
    cols : list
        Column index of each Jacobian nonzero

    Returns
    -------
    LUPlan
        Elimination order, fill-in slots, the L and U entries and the flop count.
    """
    pattern = set(zip(rows, cols)) | {(i, i) for i in range(n)}
    order = minimum_degree_order(n, pattern)
    pos = {s: k for k, s in enumerate(order)}
    pat = {(pos[i], pos[j]) for i, j in pattern}
    rows_of = [set() for _ in range(n)]   # column k -> rows
    cols_of = [set() for _ in range(n)]   # row k -> columns
    for i, j in pat:
        rows_of[j].add(i)
        cols_of[i].add(j)
    lower, upper, flops = [], [], 0
    for k in range(n):
        lk = sorted(i for i in rows_of[k] if i > k)
        uk = sorted(j for j in cols_of[k] if j > k)
        lower.append(lk)
        upper.append(uk)
        for i in lk:
            for j in uk:
                if (i, j) not in pat:
                    pat.add((i, j))
                    rows_of[j].add(i)
                    cols_of[i].add(j)
        flops += len(lk) * (1 + 2 * len(uk))
    slots = {ij: s for s, ij in enumerate(sorted(pat, key=lambda ij: (ij[1], ij[0])))}
    return LUPlan(order, slots, lower, upper, flops)


#: Terms of a back-solve sum above which it is written as :data:`_ACCUMULATORS` interleaved
#: partial sums: a cut signal's row gathers every state of its hose section (80 at 30 modes
#: per section), and one chain of dependent multiply-adds waits ~4 cycles per term.
_CHAIN = 12
_ACCUMULATORS = 4


def _sum_c(first: str, terms) -> str:
    """C for ``first - sum a[s] * v[k]`` over ``terms`` (slot s, index k): one chain of
    subtractions, or for more than :data:`_CHAIN` terms :data:`_ACCUMULATORS` interleaved
    partial sums added pairwise (chains that do not wait for each other)."""
    if len(terms) <= _CHAIN:
        return first + "".join(f"-a[{s}]*v[{k}]" for s, k in terms)
    parts = ["(" + "+".join(f"a[{s}]*v[{k}]" for s, k in terms[g::_ACCUMULATORS]) + ")"
             for g in range(_ACCUMULATORS)]
    while len(parts) > 1:
        parts = [f"({parts[i]}+{parts[i + 1]})" if i + 1 < len(parts) else parts[i]
                 for i in range(0, len(parts), 2)]
    return f"{first}-{parts[0]}"


def _lu_c(n: int, jrows, jcols, plan: LUPlan) -> str:
    """Factorization as loops over index tables (compiles fast), solve as straight-line code.

    ``n`` states come first; rows from ``n`` on are the cut signals' (the bordered matrix:
    their entries are not multiplied by g, and their right-hand side is zero)."""
    size = len(plan.order)
    pos = {s: k for k, s in enumerate(plan.order)}
    S = plan.slots
    jslot = [S[(pos[r], pos[c])] for r, c in zip(jrows, jcols)]
    signal_nz = [k for k, r in enumerate(jrows) if r >= n]
    diag = [S[(k, k)] for k in range(size)]
    lstart, lslot, ustart, tgt, src = [0], [], [0], [], []
    for k in range(size):
        for i in plan.lower[k]:
            lslot.append(S[(i, k)])
            for j in plan.upper[k]:
                tgt.append(S[(i, j)])
                src.append(S[(k, j)])
            ustart.append(len(tgt))
        lstart.append(len(lslot))

    def table(name, values):
        return f"static const int {name}[] = {{" + (",".join(map(str, values)) or "0") + "};"

    # the factors' pattern by rows (pivot coordinates), for solves other than the real
    # straight-line one (bdf.c's complex system, Radau IIA): pivot -> row or column of the
    # matrix, each L row's columns and slots, each U row's columns and slots
    lower_rows = [[] for _ in range(size)]
    for k in range(size):
        for i in plan.lower[k]:
            lower_rows[i].append(k)
    lrowstart, lcol, lrslot = [0], [], []
    for i in range(size):
        for k in lower_rows[i]:
            lcol.append(k)
            lrslot.append(S[(i, k)])
        lrowstart.append(len(lcol))
    urowstart, ucol, uslot = [0], [], []
    for k in range(size):
        for j in plan.upper[k]:
            ucol.append(j)
            uslot.append(S[(k, j)])
        urowstart.append(len(ucol))
    out = [f"#define HL_LU_NJ {len(jslot)}", f"#define HL_LU_NSIG {len(signal_nz)}",
           table("hl_lu_jslot", jslot), table("hl_lu_diag", diag), table("hl_lu_lstart", lstart),
           table("hl_lu_lslot", lslot), table("hl_lu_ustart", ustart), table("hl_lu_tgt", tgt),
           table("hl_lu_src", src), table("hl_lu_signal_nz", signal_nz),
           table("hl_lu_perm", plan.order), table("hl_lu_lrowstart", lrowstart),
           table("hl_lu_lcol", lcol), table("hl_lu_lrslot", lrslot),
           table("hl_lu_urowstart", urowstart), table("hl_lu_ucol", ucol),
           table("hl_lu_uslot", uslot)]
    out.append(f"""static int hl_lu_factor(const double* jnz, double g, double* a) {{
  memset(a, 0, sizeof(double) * HL_NLU);
  for (int k = 0; k < {len(jslot)}; k++) a[hl_lu_jslot[k]] = -g * jnz[k];
  for (int k = 0; k < {len(signal_nz)}; k++) a[hl_lu_jslot[hl_lu_signal_nz[k]]] = -jnz[hl_lu_signal_nz[k]];
  for (int k = 0; k < {size}; k++) a[hl_lu_diag[k]] += 1.;
  for (int k = 0; k < {size}; k++) {{
    double piv = a[hl_lu_diag[k]];
    if (!(fabs(piv) > HL_PIVOT_TOL)) return k + 1;
    double inv = 1. / piv;
    a[hl_lu_diag[k]] = inv;
    for (int m = hl_lu_lstart[k]; m < hl_lu_lstart[k + 1]; m++) {{
      double l = a[hl_lu_lslot[m]] * inv;
      a[hl_lu_lslot[m]] = l;
      for (int q = hl_lu_ustart[m]; q < hl_lu_ustart[m + 1]; q++) a[hl_lu_tgt[q]] -= l * a[hl_lu_src[q]];
    }}
  }}
  return 0;
}}""")
    out.append("static void hl_lu_solve(const double* a, double* b) {")
    out.append(f"  double v[{size}];")
    # forward substitution by rows: each v[i] written once, its terms in the order of the
    # columns (the same sums as column by column, fewer stores); a cut signal's right-hand
    # side is zero (lower_rows: above)
    for i in range(size):
        first = f"b[{plan.order[i]}]" if plan.order[i] < n else "0."
        out.append(f"  v[{i}]={_sum_c(first, [(S[(i, k)], k) for k in lower_rows[i]])};")
    for k in reversed(range(size)):
        terms = _sum_c(f"v[{k}]", [(S[(k, j)], j) for j in plan.upper[k]])
        out.append(f"  v[{k}]=({terms})*a[{S[(k, k)]}];")
    for k in range(size):
        if plan.order[k] < n:
            out.append(f"  b[{plan.order[k]}]=v[{k}];")
    out.append("}")
    return "\n".join(out)


def structure_key(functions) -> str:
    """SHA-256 of the straight-line programs of ``(f, jac, signals)`` with every constant's
    value masked: equal keys mean the same C source (:func:`generate`), whatever the numbers.

    Parameters
    ----------
    functions : tuple
        ``(f, jac, signals)`` of :func:`scaled_functions`

    Returns
    -------
    str
        Hex digest.
    """
    h = hashlib.sha256()
    for fun in functions:
        h.update(_CONSTANT_LINE.sub(r"\1 = c;", fun.str(True)).encode())
        h.update(b"\0")
    return h.hexdigest()


#: A constant instruction in CasADi's algorithm listing, ``@3 = -22798.5;`` (operands of other
#: instructions are ``@k``, ``input[i][j]`` or calls with parentheses).
_CONSTANT_LINE = re.compile(r"^(@\d+) = [^;@\[\]()]*;$", re.M)


def constant_positions(functions) -> list[list[int]]:
    """Per function, the indices of its constant instructions, in the order :func:`generate`
    numbers the constants ``c[k]``.

    Parameters
    ----------
    functions : tuple
        ``(f, jac, signals)`` of :func:`scaled_functions`

    Returns
    -------
    list of list of int
        Instruction indices, one list per function.
    """
    return [[k for k in range(fun.n_instructions()) if fun.instruction_id(k) == ca.OP_CONST]
            for fun in functions]


def constants_at(functions, positions, network=None) -> np.ndarray:
    """The constants ``c`` of a model whose structure is known (its :func:`constant_positions`):
    what :func:`generate` would return as ``constants``, without writing the C.

    Parameters
    ----------
    functions : tuple
        ``(f, jac, signals)`` of :func:`scaled_functions`
    positions : list
        Per function, the indices of its constant instructions
    network : Network
        The model's network, whose numbers and scales come first where the
        functions take them (:func:`number_prefix`); None: the graph's
        constants only

    Returns
    -------
    ndarray
        The constants ``c``, [SI] (numbers and state scales first where the functions take them).
    """
    graph = np.array([fun.instruction_constant(k) for fun, ks in zip(functions, positions)
                      for k in ks], dtype=float)
    if network is None or functions[0].n_in() < 4:
        return graph
    return np.concatenate([number_prefix(network), graph])


def generate(model, functions=None) -> GeneratedModel:
    """C source and constants of a :class:`~hydroline.engine.CompiledModel` (scaled states).

    Parameters
    ----------
    model : CompiledModel
        The network's CasADi graph (``network.compile()``)
    functions : tuple
        Its :func:`scaled_functions`, when already made

    Returns
    -------
    GeneratedModel
        The C source, its key, the constants [SI] and the sizes.
    """
    net = model.network
    n, m = len(net.state_names), len(net.parameter_names)
    f, jac, sig = scaled_functions(model) if functions is None else functions
    sp = jac.sparsity_out(0)                  # the bordered Jacobian: n states, then signals
    size = sp.size1()
    ext_colind = np.asarray(sp.colind(), dtype=np.int64)
    ext_row = np.asarray(sp.row(), dtype=np.int64)
    ext_cols = np.repeat(np.arange(size), np.diff(ext_colind))
    if size > n:
        colind, row = schur_pattern(n, ext_colind, ext_row)
    else:
        colind, row = ext_colind, ext_row
    inputs = ["t", "z[{nz}]", "p[{nz}]", "c[{nz}]"]
    # (the numbers and scales first, where the functions take them: the graph's own
    # constants follow them in c)
    constants: list[float] = (number_prefix(net).tolist() if f.n_in() == 4 else [])
    parts = [_function_c(f, "hl_f", inputs, "dz", constants),
             _function_c(jac, "hl_jac", inputs, "jnz", constants, "HL_RARELY_CALLED"),
             _function_c(sig, "hl_signals", inputs, "y", constants)]
    plan = lu_plan(size, ext_row.tolist(), ext_cols.tolist())

    def table(name, values):
        return f"static const long long {name}[] = {{" + (",".join(map(str, values)) or "0") + "};"

    header = [
        "/* Generated by hydroline.compiled.codegen: one network structure. */",
        "#include <math.h>",
        "#include <string.h>",
        f"#define HL_N {n}",
        f"#define HL_NP {max(m, 1)}",
        f"#define HL_NC {max(len(constants), 1)}",
        f"#define HL_NY {max(sig.nnz_out(0), 1)}",
        f"#define HL_NNZ {max(len(row), 1)}",
        f"#define HL_NV {size - n}",
        f"#define HL_NE {size}",
        f"#define HL_NENZ {max(sp.nnz(), 1)}",
        f"#define HL_NLU {len(plan.slots)}",
        "#define HL_PIVOT_TOL 1e-10",
        # the Jacobian is evaluated once per factorisation (every ~30 steps): GCC's -O3 spends
        # twice -O1's time on its thousands of stores (0.9 s of a 30-modes-per-section build)
        "#if defined(__GNUC__) && !defined(__clang__)",
        '#define HL_RARELY_CALLED __attribute__((optimize("O1")))',
        "#else",
        "#define HL_RARELY_CALLED",
        "#endif",
        "static double hl_sign(double x) { return x < 0 ? -1. : (x > 0 ? 1. : x); }",
        table("hl_jac_colind", colind), table("hl_jac_row", row),
        table("hl_ext_colind", ext_colind), table("hl_ext_row", ext_row),
    ]
    source = "\n".join(header + parts + [_lu_c(n, ext_row.tolist(), ext_cols.tolist(), plan)]) + "\n"
    key = hashlib.sha256(source.encode()).hexdigest()
    return GeneratedModel(source, key, np.array(constants, dtype=float), n, m,
                          sig.nnz_out(0), len(row), colind, row, len(plan.slots), plan.flops)
