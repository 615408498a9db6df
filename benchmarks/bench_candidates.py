"""Benchmark: the candidates of issue 5 for the compiled path, measured on the default scenario.

Issue 5 asked to measure before choosing between CasADi (CVODES), numba-compiled f and
Jacobian with a compiled integrator, and JAX with diffrax. The project's compiled core
(:mod:`hydroline.compiled`: the network's CasADi SX graph written as C plus a BDF integrator
in C) is compared here with the other two, all generated from the *same* SX graph (the one
:mod:`hydroline.compiled.codegen` writes as C, in states scaled by their typical magnitudes,
every numeric constant read from a run-time array ``c``), by generic emission of the graph's
instructions (no component is rewritten by hand):

* **numba**: the graph as plain Python with ``math`` functions, ``@njit``-compiled: f and the
  sparse Jacobian (CasADi's Jacobian graph emitted the same way, scattered into a dense matrix
  for SciPy). Integrated by SciPy's BDF (Python integrator) and by SciPy's ``ode("vode")``
  (Fortran VODE, BDF), both calling the numba f and J.
* **JAX + diffrax**: the graph as ``jax.numpy``, ``jax.jit``; Jacobian by ``jax.jacfwd``;
  diffrax ``Kvaerno5`` (ESDIRK, stiff) with a PID step-size controller; x64. Also ``vmap`` over
  64 variants (supply section II bulk modulus -10 % .. +10 %: same structure, other constants);
  a batch runs until its slowest member is done, so diffrax's steps are capped there
  (``--max-steps`` per segment) and the variants that did not finish are counted.

All integrate 0.25 s at rtol 1e-6, atol 1e-7 of each state's scale (``simulate()``'s
defaults), output every 0.1 ms, restarting at the network's breakpoints (the 10 ms step) as
:func:`hydroline.engine.integrate` does, from the solved steady state. Error: largest
deviation of the valve port pressures and piston velocity from a CVODES run at rtol 1e-10, in
% of the signal's excursion (as in bench_simulate). Per-evaluation costs of f and J are timed
inside compiled loops (C: a harness compiled with the core's flags; numba: an njit loop;
JAX: ``lax.fori_loop``), so no Python call overhead is in them. One core (XLA limited to one
thread). Prints one table; a candidate whose package is missing is skipped with a line.

Progress lines go to stderr. Takes ~7 min (most of it the vmap batch).

Usage: python benchmarks/bench_candidates.py [--repeat N] [--variants N] [--max-steps N]
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false "
                                   "intra_op_parallelism_threads=1")

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402

from hydroline import compiled  # noqa: E402
from hydroline.rigs import load_rig  # noqa: E402
from hydroline.scenarios import build_scenario  # noqa: E402
from hydroline.engine import integrate, solve_steady_state  # noqa: E402
from hydroline.compiled.codegen import assignments, scaled_functions  # noqa: E402
from hydroline.system import build_network  # noqa: E402

KEYS = ("supply_port_pressure", "return_port_pressure", "piston_velocity")
RTOL, ATOL = 1e-6, 1e-7          # simulate()'s defaults (atol: fraction of each state's scale)
DT_OUT = 1e-4

# ---- generic emission of a CasADi SX function (same walk as hydroline.compiled.codegen) ----
_PY_BIN = {
    ca.OP_ADD: "({a}+{b})", ca.OP_SUB: "({a}-{b})", ca.OP_MUL: "({a}*{b})",
    ca.OP_DIV: "({a}/{b})", ca.OP_POW: "math.pow({a},{b})", ca.OP_CONSTPOW: "math.pow({a},{b})",
    ca.OP_FMIN: "min({a},{b})", ca.OP_FMAX: "max({a},{b})",
    ca.OP_LT: "(1.0 if {a}<{b} else 0.0)", ca.OP_LE: "(1.0 if {a}<={b} else 0.0)",
    ca.OP_EQ: "(1.0 if {a}=={b} else 0.0)", ca.OP_NE: "(1.0 if {a}!={b} else 0.0)",
    ca.OP_AND: "(1.0 if ({a}!=0.0 and {b}!=0.0) else 0.0)",
    ca.OP_OR: "(1.0 if ({a}!=0.0 or {b}!=0.0) else 0.0)",
    ca.OP_IF_ELSE_ZERO: "({b} if {a}!=0.0 else 0.0)", ca.OP_ATAN2: "math.atan2({a},{b})",
    ca.OP_COPYSIGN: "math.copysign({a},{b})", ca.OP_FMOD: "math.fmod({a},{b})",
    ca.OP_HYPOT: "math.hypot({a},{b})",
}
_PY_UN = {
    ca.OP_ASSIGN: "{a}", ca.OP_NEG: "(-{a})", ca.OP_EXP: "math.exp({a})",
    ca.OP_LOG: "math.log({a})", ca.OP_SQRT: "math.sqrt({a})", ca.OP_SQ: "({a}*{a})",
    ca.OP_TWICE: "(2.0*{a})", ca.OP_INV: "(1.0/{a})", ca.OP_SIN: "math.sin({a})",
    ca.OP_COS: "math.cos({a})", ca.OP_TAN: "math.tan({a})", ca.OP_ASIN: "math.asin({a})",
    ca.OP_ACOS: "math.acos({a})", ca.OP_ATAN: "math.atan({a})", ca.OP_SINH: "math.sinh({a})",
    ca.OP_COSH: "math.cosh({a})", ca.OP_TANH: "math.tanh({a})", ca.OP_ASINH: "math.asinh({a})",
    ca.OP_ACOSH: "math.acosh({a})", ca.OP_ATANH: "math.atanh({a})", ca.OP_FABS: "abs({a})",
    ca.OP_SIGN: "(-1.0 if {a}<0.0 else (1.0 if {a}>0.0 else {a}))",
    ca.OP_FLOOR: "np.floor({a})", ca.OP_CEIL: "np.ceil({a})",
    ca.OP_NOT: "(1.0 if {a}==0.0 else 0.0)", ca.OP_ERF: "math.erf({a})",
    ca.OP_LOG1P: "math.log1p({a})", ca.OP_EXPM1: "math.expm1({a})",
}
_JAX_BIN = {
    ca.OP_ADD: "({a}+{b})", ca.OP_SUB: "({a}-{b})", ca.OP_MUL: "({a}*{b})",
    ca.OP_DIV: "({a}/{b})", ca.OP_POW: "jnp.power({a},{b})", ca.OP_CONSTPOW: "jnp.power({a},{b})",
    ca.OP_FMIN: "jnp.fmin({a},{b})", ca.OP_FMAX: "jnp.fmax({a},{b})",
    ca.OP_LT: "jnp.where({a}<{b},1.0,0.0)", ca.OP_LE: "jnp.where({a}<={b},1.0,0.0)",
    ca.OP_EQ: "jnp.where({a}=={b},1.0,0.0)", ca.OP_NE: "jnp.where({a}!={b},1.0,0.0)",
    ca.OP_AND: "jnp.where(({a}!=0.0)&({b}!=0.0),1.0,0.0)",
    ca.OP_OR: "jnp.where(({a}!=0.0)|({b}!=0.0),1.0,0.0)",
    ca.OP_IF_ELSE_ZERO: "jnp.where({a}!=0.0,{b},0.0)", ca.OP_ATAN2: "jnp.arctan2({a},{b})",
    ca.OP_COPYSIGN: "jnp.copysign({a},{b})", ca.OP_FMOD: "jnp.fmod({a},{b})",
    ca.OP_HYPOT: "jnp.hypot({a},{b})",
}
_JAX_UN = {
    ca.OP_ASSIGN: "{a}", ca.OP_NEG: "(-{a})", ca.OP_EXP: "jnp.exp({a})", ca.OP_LOG: "jnp.log({a})",
    ca.OP_SQRT: "jnp.sqrt({a})", ca.OP_SQ: "({a}*{a})", ca.OP_TWICE: "(2.0*{a})",
    ca.OP_INV: "(1.0/{a})", ca.OP_SIN: "jnp.sin({a})", ca.OP_COS: "jnp.cos({a})",
    ca.OP_TAN: "jnp.tan({a})", ca.OP_ASIN: "jnp.arcsin({a})", ca.OP_ACOS: "jnp.arccos({a})",
    ca.OP_ATAN: "jnp.arctan({a})", ca.OP_SINH: "jnp.sinh({a})", ca.OP_COSH: "jnp.cosh({a})",
    ca.OP_TANH: "jnp.tanh({a})", ca.OP_ASINH: "jnp.arcsinh({a})", ca.OP_ACOSH: "jnp.arccosh({a})",
    ca.OP_ATANH: "jnp.arctanh({a})", ca.OP_FABS: "jnp.abs({a})", ca.OP_SIGN: "jnp.sign({a})",
    ca.OP_FLOOR: "jnp.floor({a})", ca.OP_CEIL: "jnp.ceil({a})",
    ca.OP_NOT: "jnp.where({a}==0.0,1.0,0.0)", ca.OP_ERF: "jax.scipy.special.erf({a})",
    ca.OP_LOG1P: "jnp.log1p({a})", ca.OP_EXPM1: "jnp.expm1({a})",
}
_INPUTS = ["t", "z[{nz}]", "p[{nz}]"]


def emit(fun: ca.Function, name: str, lang: str, constants: list) -> str:
    """``fun(t, z, p)`` as Python source ``name(t, z, p, c[, out])``; constants go to ``c``.

    lang "numba": writes the outputs into ``out``; lang "jax": returns them stacked.
    The instruction walk is the C writer's (:func:`hydroline.compiled.codegen.assignments`)."""
    binary, unary = (_PY_BIN, _PY_UN) if lang == "numba" else (_JAX_BIN, _JAX_UN)
    if lang == "numba":
        head, body = f"def {name}(t, z, p, c, out):", []
        output = "out[{nz}]"
    else:
        head, body = f"def {name}(t, z, p, c):", [f"o = [jnp.zeros(())] * {fun.nnz_out(0)}"]
        output = "o[{nz}]"
    body += [f"{target} = {expr}" for target, expr in
             assignments(fun, binary, unary, _INPUTS, output, constants)]
    if lang == "jax":
        body.append("return jnp.stack(o)")
    return head + "\n" + "\n".join("    " + s for s in body) + "\n"


def scaled_graph(net):
    """f and its sparse Jacobian in scaled states z = x / scale, exactly as the C core's."""
    f, jac, _ = scaled_functions(net.compile())
    return f, jac


# ---- the scenario ----------------------------------------------------------------------------
class Scenario:
    def __init__(self, bulk_factor: float = 1.0):
        rig = load_rig(None)
        if bulk_factor != 1.0:
            k = float(rig.get("supply.section2.bulk_modulus"))   # [Pa]
            rig.set("supply.section2.bulk_modulus", f"{k * bulk_factor} Pa")
        sc = build_scenario(rig, "open-loop-step")
        self.net = net = build_network(rig, sc.commands, sc.position_guess)
        self.ss = solve_steady_state(net)
        self.t_end = sc.t_end
        self.scales = np.asarray(net.state_scales, dtype=float)
        self.n = len(self.scales)
        n_out = int(round(self.t_end / DT_OUT))
        self.grid = np.arange(n_out + 1) * DT_OUT
        self.edges = sorted({0.0, self.t_end, *net.breakpoints(self.t_end)})
        self.f_sx, self.jac_sx = scaled_graph(net)

    def segments(self):
        """(a, b, output times in (a, b]) per segment between breakpoints."""
        for a, b in zip(self.edges[:-1], self.edges[1:]):
            sel = (self.grid > a + 1e-12) & (self.grid <= b + 1e-12)
            yield a, b, self.grid[sel]

    def signals(self, X):
        """Signal table of the states X [n_out, n] (SI) on the output grid."""
        model = self.net.compile()
        N = len(self.grid)
        Y = np.asarray(model.signals.map(N)(self.grid, X.T, np.tile(self.ss.p[:, None], N))).T
        return {k: Y[:, self.net.signal_names.index(k)] for k in KEYS}


def best_of(fn, n):
    walls, out = [], None
    for _ in range(n):
        tic = time.perf_counter()
        out = fn()
        walls.append(time.perf_counter() - tic)
    return min(walls), out


# ---- C core ----------------------------------------------------------------------------------
_HARNESS = r"""
#include <stdio.h>
#include <time.h>
static double now(void) { struct timespec s; clock_gettime(CLOCK_MONOTONIC, &s); return s.tv_sec + 1e-9 * s.tv_nsec; }
typedef void (*fun_t)(double, const double*, const double*, const double*, double*);
int main(void) {
  static const double Z0[] = {%(z)s}, P[] = {%(p)s}, C[] = {%(c)s};
  double z[HL_N], out[HL_NNZ > HL_N ? HL_NNZ : HL_N], acc = 0., best[2] = {1e9, 1e9};
  fun_t volatile fs[2] = {hl_f, hl_jac};
  const int n = %(reps)d;
  for (int k = 0; k < HL_N; k++) z[k] = Z0[k];
  for (int w = 0; w < 2; w++)
    for (int r = 0; r < 5; r++) {
      double t0 = now();
      for (int i = 0; i < n; i++) {
        z[0] = Z0[0] * (1. + 1e-12 * (i & 1));
        fs[w](1e-3 + 1e-12 * i, z, P, C, out);
        acc += out[i %% HL_N];
      }
      double dt = (now() - t0) / n;
      if (dt < best[w]) best[w] = dt;
    }
  printf("%%.6g %%.6g %%g\n", best[0] * 1e9, best[1] * 1e9, acc);
  return 0;
}
"""


def c_eval_cost(sc, z0):
    """ns per hl_f and hl_jac call of the generated C, built with the core's flags."""
    gen = compiled.generate(sc.net.compile())
    cc = compiled.toolchain.compiler()
    if cc is None:
        return None
    fmt = lambda a: ",".join(repr(float(v)) for v in a) or "0"  # noqa: E731
    src = gen.source + _HARNESS % {"z": fmt(z0), "p": fmt(sc.ss.p), "c": fmt(gen.constants),
                                   "reps": 200000}
    flags = [f for f in compiled.CFLAGS if f not in ("-shared", "-fPIC")]
    with tempfile.TemporaryDirectory() as tmp:
        with open(os.path.join(tmp, "h.c"), "w") as fh:
            fh.write("#define _POSIX_C_SOURCE 199309L\n" + src)
        exe = os.path.join(tmp, "h")
        subprocess.run([cc, *flags, *compiled.native_flags(), "-o", exe, os.path.join(tmp, "h.c"),
                        "-lm"], check=True, capture_output=True)
        out = subprocess.run([exe], check=True, capture_output=True, text=True).stdout.split()
    return float(out[0]), float(out[1])


# ---- numba -----------------------------------------------------------------------------------
_NUMBA_TAIL = """
@njit(error_model="numpy")
def f(t, z, p, c):
    out = np.empty(N)
    f_into(t, z, p, c, out)
    return out

@njit(error_model="numpy")
def jac_dense(t, z, p, c, rows, cols):
    nz = np.empty(NNZ)
    jnz_into(t, z, p, c, nz)
    J = np.zeros((N, N))
    for k in range(NNZ):
        J[rows[k], cols[k]] = nz[k]
    return J

@njit(error_model="numpy")
def loop_f(reps, z0, p, c):
    z = z0.copy()
    out = np.empty(N)
    acc = 0.0
    for i in range(reps):
        z[0] = z0[0] * (1.0 + 1e-12 * (i & 1))
        f_into(1e-3 + 1e-12 * i, z, p, c, out)
        acc += out[i % N]
    return acc

@njit(error_model="numpy")
def loop_j(reps, z0, p, c):
    z = z0.copy()
    out = np.empty(NNZ)
    acc = 0.0
    for i in range(reps):
        z[0] = z0[0] * (1.0 + 1e-12 * (i & 1))
        jnz_into(1e-3 + 1e-12 * i, z, p, c, out)
        acc += out[i % N]
    return acc
"""


def numba_module(sc):
    constants: list = []
    src = ("import math\nimport numpy as np\nfrom numba import njit\n"
           f"N = {sc.n}\nNNZ = {sc.jac_sx.nnz_out(0)}\n\n@njit(error_model='numpy')\n"
           + emit(sc.f_sx, "f_into", "numba", constants)
           + "\n@njit(error_model='numpy')\n" + emit(sc.jac_sx, "jnz_into", "numba", constants)
           + _NUMBA_TAIL)
    ns: dict = {}
    exec(compile(src, "<hydroline-numba>", "exec"), ns)
    sp = sc.jac_sx.sparsity_out(0)
    rows = np.asarray(sp.row(), dtype=np.int64)
    cols = np.repeat(np.arange(sc.n), np.diff(np.asarray(sp.colind()))).astype(np.int64)
    return ns, np.array(constants), rows, cols


def run_scipy_bdf(sc, f, jac, z0):
    """SciPy's BDF (Python) with numba f and dense J; returns states on the grid and stats."""
    from scipy.integrate import BDF

    X, z, st = [z0], z0.copy(), {"steps": 0, "nfev": 0, "njev": 0, "nlu": 0}
    for a, b, g in sc.segments():
        s = BDF(f, a, z, b, rtol=RTOL, atol=ATOL, jac=jac)
        i = 0
        while s.status == "running":
            s.step()
            if s.status == "failed":
                raise RuntimeError(f"SciPy BDF failed at t = {s.t:g}")
            st["steps"] += 1
            j = np.searchsorted(g, s.t + 1e-15, side="right")
            if j > i:
                X.extend(s.dense_output()(g[i:j]).T)
                i = j
        z = s.y.copy()
        for k in ("nfev", "njev", "nlu"):
            st[k] += getattr(s, k)
    return np.array(X) * sc.scales, st


def run_vode(sc, f, jac_t, z0):
    """SciPy ode("vode", BDF): Fortran VODE calling the numba f and dense J.

    ``jac_t`` returns the *transposed* Jacobian: SciPy 1.17's VODE wrapper reads the returned
    array in the other order (measured over the first 10 ms: with J itself 31 965 steps and
    11 073 Newton convergence failures; with J.T 22 steps; with finite differences 391)."""
    from scipy.integrate import ode

    X, z, st = [z0], z0.copy(), {"steps": 0, "nfev": 0, "njev": 0, "nlu": 0}
    for a, b, g in sc.segments():
        r = ode(f, jac_t).set_integrator("vode", method="bdf", rtol=RTOL, atol=ATOL,
                                       nsteps=10 ** 6, order=5)
        r.set_initial_value(z, a)
        for tk in g:
            X.append(np.array(r.integrate(tk)))
            if not r.successful():
                raise RuntimeError(f"VODE failed at t = {r.t:g}")
        z = X[-1].copy()
        iw = r._integrator.iwork
        st["steps"] += int(iw[10])
        st["nfev"] += int(iw[11])
        st["njev"] += int(iw[12])
        st["nlu"] += int(iw[18])
    return np.array(X) * sc.scales, st


# ---- JAX + diffrax ---------------------------------------------------------------------------
def jax_parts(sc):
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)
    constants: list = []
    src = "import jax\nimport jax.numpy as jnp\n\n" + emit(sc.f_sx, "f", "jax", constants)
    ns: dict = {}
    exec(compile(src, "<hydroline-jax>", "exec"), ns)
    return ns["f"], jnp.asarray(constants), constants


def jax_solver(sc, f, max_steps=200000):
    import diffrax as dfx
    import jax
    import jax.numpy as jnp

    term = dfx.ODETerm(lambda t, y, args: f(t, y, args[0], args[1]))
    segs = list(sc.segments())

    def solve(z0, p, c):
        z, ys, steps, acc, rej, ok = z0, [z0[None, :]], 0, 0, 0, True
        for a, b, g in segs:
            sol = dfx.diffeqsolve(term, dfx.Kvaerno5(), a, b, 1e-6, z, args=(p, c),
                                  saveat=dfx.SaveAt(ts=jnp.asarray(g)),
                                  stepsize_controller=dfx.PIDController(rtol=RTOL, atol=ATOL),
                                  max_steps=max_steps, throw=False)
            ys.append(sol.ys)
            z = sol.ys[-1]
            steps = steps + sol.stats["num_steps"]
            acc = acc + sol.stats["num_accepted_steps"]
            rej = rej + sol.stats["num_rejected_steps"]
            ok = ok & (sol.result == dfx.RESULTS.successful)
        return jnp.concatenate(ys), steps, acc, rej, ok

    return jax.jit(solve), jax.jit(jax.vmap(solve))


def jax_eval_cost(f, z0, p, c, reps=20000):
    """us per f and per jacfwd(f) inside a lax.fori_loop (no Python dispatch)."""
    import jax
    import jax.numpy as jnp

    jf = jax.jacfwd(f, argnums=1)

    def looped(g):
        def body(i, acc):
            z = z0.at[0].multiply(1.0 + 1e-12 * (i % 2))
            return acc + jnp.sum(g(1e-3 + 1e-12 * i, z, p, c))
        return jax.jit(lambda: jax.lax.fori_loop(0, reps, body, 0.0))

    out = []
    for g in (f, jf):
        fn = looped(g)
        fn().block_until_ready()
        wall, _ = best_of(lambda: fn().block_until_ready(), 3)
        out.append(wall / reps * 1e9)
    return out


# ---- main ------------------------------------------------------------------------------------
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=20, help="runs of the compiled core (best)")
    ap.add_argument("--variants", type=int, default=64, help="JAX vmap batch size")
    ap.add_argument("--max-steps", type=int, default=25000,
                    help="diffrax step cap per segment in the vmap batch")
    args = ap.parse_args(argv)
    tic_all = time.perf_counter()
    sc = Scenario()
    z0 = sc.ss.x / sc.scales
    ref = integrate(sc.net, sc.ss.x, sc.t_end, p=sc.ss.p, rtol=1e-10, atol_scale=1e-10,
                    solver="cvodes")
    ref_keys = {k: ref[k] for k in KEYS}

    def err(X):
        Y = sc.signals(X)
        return max(np.max(np.abs(Y[k] - ref_keys[k])) / np.ptp(ref_keys[k]) for k in KEYS) * 100

    rows, notes = [], []

    def row(cand, integ, f_ns, j_ns, compile_s, wall, steps, nfev, njev, e, note=""):
        print(f"  [{time.perf_counter() - tic_all:.0f} s] {cand}: {integ}: {wall} ms",
              file=sys.stderr, flush=True)
        rows.append([cand, integ, f_ns, j_ns, compile_s, wall, steps, nfev, njev, e, note])

    fmt_ns = lambda v: "-" if v is None else f"{v:.0f}"  # noqa: E731

    # C core
    kw = dict(p=sc.ss.p, solver="compiled", rtol=RTOL, atol_scale=ATOL)
    integrate(sc.net, sc.ss.x, sc.t_end, **kw)
    walls, res = [], None
    for _ in range(args.repeat):
        res = integrate(sc.net, sc.ss.x, sc.t_end, **kw)
        walls.append(res.wall_time)
    c_wall = min(walls)
    ce = c_eval_cost(sc, z0)
    st = res.stats
    row("compiled core (C)", "BDF/NDF in C, sparse LU", fmt_ns(ce and ce[0]),
        fmt_ns(ce and ce[1]), f"{compiled.native_model(sc.net).build_time:.2f} (cached)",
        f"{c_wall * 1e3:.2f}", st["nsteps"], st["nfevals"], st["njevals"],
        f"{err(res.data[list(sc.net.state_names)].to_numpy()):.1e}")

    # numba
    if importlib.util.find_spec("numba") is None:
        notes.append("numba: skipped (package not installed: pip install numba)")
    else:
        tic = time.perf_counter()
        ns, c_nb, jr, jc = numba_module(sc)
        p = np.ascontiguousarray(sc.ss.p)
        ns["f"](0.0, z0, p, c_nb)
        ns["jac_dense"](0.0, z0, p, c_nb, jr, jc)
        ns["loop_f"](10, z0, p, c_nb)
        ns["loop_j"](10, z0, p, c_nb)
        t_compile = time.perf_counter() - tic
        reps = 200000
        f_ns = best_of(lambda: ns["loop_f"](reps, z0, p, c_nb), 5)[0] / reps * 1e9
        j_ns = best_of(lambda: ns["loop_j"](reps, z0, p, c_nb), 5)[0] / reps * 1e9
        nf, nj = ns["f"], ns["jac_dense"]
        fcall = best_of(lambda: [nf(1e-3, z0, p, c_nb) for _ in range(10000)], 3)[0] / 1e4 * 1e6
        notes.append(f"numba: f called from Python (SciPy's way) {fcall:.2f} us per call incl. "
                     f"dispatch; compile of f + J + loops {t_compile:.1f} s "
                     f"(error_model='numpy', no fastmath)")
        fun = lambda t, z: nf(t, z, p, c_nb)  # noqa: E731
        jac = lambda t, z: nj(t, z, p, c_nb, jr, jc)  # noqa: E731
        jac_t = lambda t, z: nj(t, z, p, c_nb, jr, jc).T  # noqa: E731  (VODE: see run_vode)
        for label, runner, jf in (("SciPy BDF (Python), dense LU", run_scipy_bdf, jac),
                                  ("SciPy ode vode BDF (Fortran), dense LU", run_vode, jac_t)):
            wall, (X, st) = best_of(lambda: runner(sc, fun, jf, z0), 3)
            row("numba f, J", label, fmt_ns(f_ns), fmt_ns(j_ns), f"{t_compile:.1f}",
                f"{wall * 1e3:.1f}", st["steps"], st["nfev"], st["njev"], f"{err(X):.1e}",
                f"{st['nlu']} LU")

    # JAX + diffrax
    if importlib.util.find_spec("jax") is None or importlib.util.find_spec("diffrax") is None:
        notes.append("JAX + diffrax: skipped (package not installed: pip install jax diffrax)")
    else:
        import jax
        import jax.numpy as jnp

        tic = time.perf_counter()
        f_jx, c_jx, c_list = jax_parts(sc)
        p_jx = jnp.asarray(sc.ss.p)
        jf_ns, jj_ns = jax_eval_cost(f_jx, jnp.asarray(z0), p_jx, c_jx)
        solve, _ = jax_solver(sc, f_jx)
        tic = time.perf_counter()
        out = solve(jnp.asarray(z0), p_jx, c_jx)
        jax.block_until_ready(out)
        first = time.perf_counter() - tic
        wall, out = best_of(lambda: jax.block_until_ready(solve(jnp.asarray(z0), p_jx, c_jx)), 3)
        Z, steps, acc, rej, ok = out
        e = f"{err(np.asarray(Z) * sc.scales):.1e}" if bool(ok) else "failed"
        row("JAX jit f, jacfwd J", "diffrax Kvaerno5 (ESDIRK), dense LU", fmt_ns(jf_ns),
            fmt_ns(jj_ns), f"{first - wall:.1f}", f"{wall * 1e3:.1f}", int(steps), "-", "-", e,
            f"{int(acc)} accepted, {int(rej)} rejected")

        # vmap over variants: same structure, other constants (and steady states)
        factors = np.linspace(0.9, 1.1, args.variants)
        tic = time.perf_counter()
        var = [Scenario(float(k)) for k in factors]
        cs, z0s, ps = [], [], []
        src0 = emit(var[0].f_sx, "f", "jax", [])
        for v in var:
            cl: list = []
            if emit(v.f_sx, "f", "jax", cl) != src0:   # vmap needs one structure
                raise RuntimeError("variant changed the graph's structure")
            cs.append(cl)
            z0s.append(v.ss.x / v.scales)
            ps.append(v.ss.p)
        t_build = time.perf_counter() - tic
        bz, bp, bc = (jnp.asarray(np.array(a)) for a in (z0s, ps, cs))
        # a batch runs until its slowest member is done: cap the steps (~6x what the default
        # variant needs, the hardest finishing one ~20 000 in all) so that a variant Kvaerno5 cannot finish is reported, not waited for
        _, vsolve = jax_solver(var[0], jax_parts(var[0])[0], max_steps=args.max_steps)
        print(f"  [{time.perf_counter() - tic_all:.0f} s] JAX vmap x{args.variants}: compiling",
              file=sys.stderr, flush=True)
        tic = time.perf_counter()
        vsolve = vsolve.lower(bz, bp, bc).compile()
        vfirst = time.perf_counter() - tic
        vwall, vout = best_of(lambda: jax.block_until_ready(vsolve(bz, bp, bc)), 1)
        VZ, vsteps, _, _, vok = vout
        # the same variants through the C core, and the deviation of JAX from it
        c_walls, dev = [], 0.0
        for i, v in enumerate(var):
            r = integrate(v.net, v.ss.x, v.t_end, p=v.ss.p, solver="compiled", rtol=RTOL,
                          atol_scale=ATOL)
            r = integrate(v.net, v.ss.x, v.t_end, p=v.ss.p, solver="compiled", rtol=RTOL,
                          atol_scale=ATOL)
            c_walls.append(r.wall_time)
            if bool(vok[i]):
                Yj = v.signals(np.asarray(VZ[i]) * v.scales)
                dev = max(dev, max(np.max(np.abs(Yj[k] - r[k])) / np.ptp(r[k]) for k in KEYS))
        nv = args.variants
        row(f"JAX vmap x{nv}", "diffrax Kvaerno5, batched", "-", "-", f"{vfirst:.1f}",
            f"{vwall / nv * 1e3:.1f} /variant", f"{int(np.max(vsteps))} max", "-", "-",
            f"{dev * 100:.1e} vs C", f"{int(np.sum(vok))}/{nv} finished within {args.max_steps} steps/segment; "
            f"batch {vwall:.2f} s")
        row(f"compiled core x{nv}", "same variants, one by one", "-", "-", "-",
            f"{np.sum(c_walls) / nv * 1e3:.2f} /variant", "-", "-", "-", "-",
            f"batch {np.sum(c_walls):.3f} s")
        notes.append(f"variants: supply section II bulk modulus x{factors[0]:g}..x{factors[-1]:g};"
                     f" building their networks + steady states (Python, not timed above) "
                     f"{t_build:.1f} s")
        notes.append(f"JAX {jax.__version__}, diffrax {importlib.import_module('diffrax').__version__}"
                     f", device {jax.devices()[0].platform}; XLA_FLAGS={os.environ['XLA_FLAGS']}")

    head = ["candidate", "integrator", "f [ns]", "J [ns]", "compile [s]", "wall [ms]", "steps",
            "f evals", "J evals", "max err [%]", "note"]
    widths = [max(len(str(r[i])) for r in rows + [head]) for i in range(len(head))]
    print(f"Default scenario: {sc.n} states, {sc.t_end:g} s, output every {DT_OUT * 1e3:g} ms, "
          f"rtol {RTOL:g}, atol {ATOL:g} x scale, restart at {sc.edges[1:-1]} s; one core; "
          f"wall = best after warm-up (compiled core: best of {args.repeat})")
    print("  ".join(h.rjust(w) for h, w in zip(head, widths)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(str(c).rjust(w) for c, w in zip(r, widths)))
    print("f, J = one evaluation inside a compiled loop (J: C/numba the sparse Jacobian graph, "
          "658 nonzeros; JAX jacfwd, dense); max err vs CVODES rtol 1e-10, % of excursion")
    for n in notes:
        print("  " + n)
    print(f"  total run time {time.perf_counter() - tic_all:.0f} s; python {sys.version.split()[0]}")


if __name__ == "__main__":
    main()
