"""Benchmark: the default scenario (embedded rig, 50 mA open-loop step, 0.25 s) per solver.

Prints one table: for the reference SciPy path, CasADi CVODES and the compiled C core (at the
default and looser tolerances) the first call in a fresh process (build/compile included),
the integration wall time after warm-up (best of N), the whole ``simulate()`` (network build,
steady state, integration, output table), steps, f/Jacobian evaluations, LU factorizations,
the real-time factor (simulated / integration wall time) and the largest error of the valve
port pressures and piston velocity against a tight CVODES reference (rtol 1e-10), in % of the
signal's excursion.

Also shown (issue 3 item 9): ``hydroline.simulate()`` wall time and its real-time factor.

Usage: python benchmarks/bench_simulate.py [--repeat N]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from hydroline import compiled
from hydroline.rigs import load_rig
from hydroline.scenarios import build_scenario, simulate
from hydroline.engine import integrate, solve_steady_state
from hydroline.system import build_network

KEYS = ("supply_port_pressure", "return_port_pressure", "piston_velocity")
FIRST_CALL = ("import time; t = time.perf_counter(); import hydroline; "
              "r = hydroline.simulate(solver={solver!r}); "
              "print(time.perf_counter() - t, r.metadata['solver'])")


def fresh_process(solver: str, cache: str | None) -> tuple[float, str]:
    """Seconds of import + first simulate() in a new interpreter (cache dir as given)."""
    env = dict(os.environ)
    if cache:
        env["HYDROLINE_CACHE_DIR"] = cache
    out = subprocess.run([sys.executable, "-c", FIRST_CALL.format(solver=solver)], env=env,
                         capture_output=True, text=True, check=True).stdout.split()
    return float(out[0]), out[1]


def best_of(fn, n):
    walls, res = [], None
    for _ in range(n):
        res = fn()
        walls.append(res.wall_time)
    return min(walls), res


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=20, help="runs per timing (best is shown)")
    args = ap.parse_args(argv)

    rig = load_rig(None)
    sc = build_scenario(rig, "open-loop-step")
    net = build_network(rig, sc.commands, sc.position_guess)
    ss = solve_steady_state(net)
    t_end = sc.t_end
    ref = integrate(net, ss.x, t_end, p=ss.p, rtol=1e-10, atol_scale=1e-10, solver="cvodes")

    def err(res):
        return max(np.max(np.abs(res[k] - ref[k])) / np.ptp(ref[k]) for k in KEYS) * 100

    with tempfile.TemporaryDirectory() as cold:
        first = {"compiled (cold cache)": fresh_process("compiled", cold),
                 "compiled (cached)": fresh_process("compiled", cold)}
    first["cvodes"] = fresh_process("cvodes", None)

    rows = []
    import inspect

    from hydroline import scenarios
    default_rtol = inspect.signature(scenarios.simulate).parameters["rtol"].default
    default_atol = inspect.signature(scenarios.simulate).parameters["atol_scale"].default
    cases = [("scipy (reference)", "scipy", 1e-7, 1e-8, 2),
             ("cvodes", "cvodes", 1e-7, 1e-8, args.repeat),
             ("cvodes", "cvodes", default_rtol, default_atol, args.repeat),
             ("compiled", "compiled", 1e-7, 1e-8, args.repeat),
             ("compiled", "compiled", default_rtol, default_atol, args.repeat),
             ("compiled", "compiled", 1e-5, 1e-6, args.repeat)]
    for label, solver, rtol, atol, n in cases:
        wall, res = best_of(lambda: integrate(net, ss.x, t_end, p=ss.p, solver=solver, rtol=rtol,
                                              atol_scale=atol), n)
        total = "-"
        if (rtol, atol) == (default_rtol, default_atol):   # simulate()'s defaults
            label += " *"
            totals = []
            for _ in range(min(n, 5)):
                tic = time.perf_counter()
                simulate(solver=solver)
                totals.append(time.perf_counter() - tic)
            total = f"{min(totals) * 1e3:.1f}"
        st = res.stats
        if solver == "scipy":
            fc = "-"
        elif solver == "cvodes":
            fc = f"{first['cvodes'][0]:.2f}"
        else:
            fc = f"{first['compiled (cold cache)'][0]:.2f} / {first['compiled (cached)'][0]:.2f}"
        rows.append([label, f"{rtol:g}", fc, f"{wall * 1e3:.2f}", total,
                     st.get("nsteps") or "-", st.get("nfevals"), st.get("njevals"),
                     st.get("nlu", "-"), f"{t_end / wall:.1f}", f"{err(res):.1e}"])

    head = ["solver", "rtol", "first call [s]", "integrate [ms]", "simulate() [ms]", "steps",
            "f evals", "J evals", "LU", "x real time", "max err [%]"]
    widths = [max(len(str(r[i])) for r in rows + [head]) for i in range(len(head))]
    print(f"Default scenario: {len(net.state_names)} states, {t_end:g} s simulated, output every "
          f"0.1 ms; one core; best of {args.repeat} after warm-up")
    print("  ".join(h.rjust(w) for h, w in zip(head, widths)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(str(c).rjust(w) for c, w in zip(r, widths)))
    print(f"* = simulate()'s default tolerances (rtol {default_rtol:g}, atol_scale {default_atol:g})")
    print("first call = fresh interpreter: import + build + steady state + integration "
          "(compiled: empty cache / library cached on disk)")
    print(f"compiler: {compiled.toolchain.compiler()}  flags: {' '.join(compiled.CFLAGS + compiled.native_flags())}")


if __name__ == "__main__":
    main()
