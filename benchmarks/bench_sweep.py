"""Benchmark: 1000 variants of the layout study (sections II lengths), wall time on this machine.

The layout study of the 2005 paper (issue 4): the supply and return hoses between manifold and
servovalve (sections II) set to one length, the 50 mA open-loop step run from the solved
steady state, and the supply/return port oscillation frequency, amplitude and settling time
taken (``hydroline.summarize``). Here 1000 lengths from 0.05 m to 3.048 m, spread over worker
processes; every variant has the same network structure, so the compiled core builds one C
library (cached on disk) and each variant only passes its numbers. Prints one table: the
per-variant cost split (network build, steady state, integration, metrics), the wall time of
the whole sweep per worker count, and a few of the results.

Usage: python benchmarks/bench_sweep.py [--variants N] [--workers W ...]
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import time

import numpy as np

from hydroline.rigs import load_rig
from hydroline.scenarios import simulate, summarize

_RIG = None


def _init():
    global _RIG
    _RIG = load_rig(None)


def run_variant(length: float) -> dict:
    """One layout variant: sections II of ``length`` [m] -> metrics and timings."""
    rig = _RIG.copy()
    rig.set("supply.section2.length", f"{length} m")
    rig.set("return.section2.length", f"{length} m")
    tic = time.perf_counter()
    try:
        res = simulate(rig)
        mid = time.perf_counter()
        s = summarize(res)
    except Exception as e:   # a failed variant is recorded, never sinks the sweep
        return {"length_m": length, "error": str(e)}
    end = time.perf_counter()
    return {"length_m": length, "supply_hz": s["supply"]["frequency_hz"],
            "supply_mpa": s["supply"]["amplitude_mpa"], "return_hz": s["return"]["frequency_hz"],
            "return_mpa": s["return"]["amplitude_mpa"], "simulate_s": mid - tic,
            "integrate_s": res.wall_time, "metrics_s": end - mid, "solver": res.metadata["solver"]}


def sweep(lengths, workers: int):
    tic = time.perf_counter()
    if workers == 1:
        _init()
        out = [run_variant(x) for x in lengths]
    else:
        with mp.get_context("fork").Pool(workers, initializer=_init) as pool:
            out = pool.map(run_variant, lengths, chunksize=max(1, len(lengths) // (8 * workers)))
    return out, time.perf_counter() - tic


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", type=int, default=1000)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, os.cpu_count() or 1])
    args = ap.parse_args(argv)
    lengths = np.linspace(0.05, 3.048, args.variants)
    _init()
    run_variant(float(lengths[0]))           # warm-up: the compiled library is built/cached here
    rows, results = [], None
    for w in dict.fromkeys(args.workers):
        results, wall = sweep(lengths, w)
        ok = [r for r in results if "error" not in r]
        rows.append([w, len(results), len(results) - len(ok), f"{wall:.1f}",
                     f"{wall / len(results) * 1e3:.1f}", f"{1000 * wall / len(results):.1f}"])
    ok = [r for r in results if "error" not in r]
    sim = np.mean([r["simulate_s"] for r in ok]) * 1e3
    integ = np.mean([r["integrate_s"] for r in ok]) * 1e3
    met = np.mean([r["metrics_s"] for r in ok]) * 1e3
    head = ["workers", "variants", "failed", "wall [s]", "per variant [ms]", "1000 variants [s]"]
    widths = [max(len(str(r[i])) for r in rows + [head]) for i in range(len(head))]
    print(f"Layout study sweep: sections II from {lengths[0]:g} to {lengths[-1]:g} m, open-loop step "
          f"0.25 s each, solver {ok[0]['solver'] if ok else '-'}, {os.cpu_count()} CPU cores")
    print("  ".join(h.rjust(w) for h, w in zip(head, widths)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(str(c).rjust(w) for c, w in zip(r, widths)))
    print(f"per variant (mean, last sweep): simulate() {sim:.1f} ms, of which integration "
          f"{integ:.1f} ms; metrics {met:.1f} ms")
    for r in ok[:: max(1, len(ok) // 5)]:
        print(f"  L = {r['length_m']:.3f} m: supply {r['supply_hz'] or float('nan'):.1f} Hz "
              f"{r['supply_mpa']:.2f} MPa, return {r['return_hz'] or float('nan'):.1f} Hz "
              f"{r['return_mpa']:.2f} MPa")
    for r in results:
        if "error" in r:
            print(f"  failed: L = {r['length_m']:.3f} m: {r['error']}")


if __name__ == "__main__":
    main()
