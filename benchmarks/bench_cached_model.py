"""Benchmark: ``hydroline.simulate()`` in one process with a new rig object per call (issue 13,
Deliver 1: a model seen before loads without building its CasADi graph).

Each call loads the default rig anew and sets ``supply.section2.length``, so the rig, its
network and its components are new objects and ``simulate()``'s own per-process memory (the
last 8 rigs) does not hold them. Two cases, median wall per call:

* seen numbers: ``--values`` lengths (more than that memory holds), each run once before
  the timing: every call's model is known (by its definition's record, or -- on a tree
  without those -- by its graph's fingerprint);
* new numbers: a length no run has used (nudged by < 1 um per call): the graph is built, the
  structure's record gives its constants.

The second part splits one call of each case into its stages (rig, network build, compiled
model found, steady state, integration, the rest of ``simulate()``). Run it under two trees
to compare (another tree: ``PYTHONPATH=TREE:SITE python -S benchmarks/bench_cached_model.py``,
``-S`` keeping the editable install's path hook away; the machine is shared and noisy:
compare the two trees' runs made one after the other, several times).

Usage: python benchmarks/bench_cached_model.py [--calls 30] [--values 10]
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np


def new_rig(length: float):
    """The default rig loaded anew with ``supply.section2.length`` set, [m]."""
    from hydroline.rigs import load_rig

    rig = load_rig()
    rig.set("supply.section2.length", f"{float(length)!r} m")
    return rig


def per_call(lengths) -> float:
    """Median wall of ``simulate()`` per call, a new rig object each, [s]."""
    import hydroline

    walls = []
    for length in lengths:
        tic = time.perf_counter()
        hydroline.simulate(new_rig(length))
        walls.append(time.perf_counter() - tic)
    return statistics.median(walls)


def stages(length: float) -> dict:
    """Where one call's time goes, [s]: what ``simulate()`` does, step by step."""
    from hydroline import compiled
    from hydroline.engine import integrate, solve_steady_state
    from hydroline.scenarios import build_scenario
    from hydroline.system import build_circuit

    t0 = time.perf_counter()
    rig = new_rig(length)
    t1 = time.perf_counter()
    circuit = build_circuit(rig)
    sc = build_scenario(rig, "open-loop-step", None, axes=circuit.axes)
    net = circuit.network(sc.commands)
    t2 = time.perf_counter()
    native = compiled.native_model(net)
    t3 = time.perf_counter()
    ss = solve_steady_state(net)
    t4 = time.perf_counter()
    res = integrate(net, ss.x, sc.t_end, p=ss.p, rtol=1e-6, atol_scale=1e-7)
    t5 = time.perf_counter()
    return {"rig load + set": t1 - t0, "network build": t2 - t1,
            f"compiled model ({getattr(native, 'found_by', 'graph or structure')})": t3 - t2,
            "steady state": t4 - t3, "integration (C)": res.wall_time,
            "integrate() beyond the C": t5 - t4 - res.wall_time}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--calls", type=int, default=30, help="timed calls per case")
    ap.add_argument("--values", type=int, default=10, help="distinct lengths of the seen case")
    args = ap.parse_args(argv)
    import hydroline

    seen = list(2.0 + 0.05 * np.arange(args.values))
    per_call(seen)                                         # warm-up: every model recorded
    rng = np.random.default_rng()
    fresh = 2.0 + 0.01 * np.arange(args.calls) + rng.uniform(0, 1e-6, args.calls)
    cycle = [seen[k % len(seen)] for k in range(args.calls)]
    print(f"hydroline from {hydroline.__file__}")
    print(f"simulate() per call, new rig object, median of {args.calls}:")
    print(f"  seen numbers ({args.values} lengths in turn): {per_call(cycle) * 1e3:7.1f} ms")
    print(f"  new numbers (never run before):  {per_call(fresh) * 1e3:7.1f} ms")
    for what, length in (("seen", seen[0]), ("new", 2.9 + rng.uniform(0, 1e-6))):
        runs = [stages(length if what == "seen" else length + 1e-7 * k) for k in range(5)]
        print(f"one call's stages, {what} numbers (median of 5), ms:")
        for name in runs[0]:
            values = [r[name] for r in runs if name in r]
            print(f"  {name:40s} {statistics.median(values) * 1e3:7.2f}")


if __name__ == "__main__":
    main()
