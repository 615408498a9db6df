"""Benchmark: 1000 variants of the layout study through ``hydroline.studies.sweep``, wall time
on this machine, and where one variant's time goes.

The layout study of the 2005 paper (issue 4): the supply and return hoses between manifold and
servovalve (sections II) set to one length, the 50 mA open-loop step run from the solved
steady state, and the port metrics taken (``hydroline.summarize``). Here N lengths from
0.05 m to 3.048 m (nudged by < 1 um per run, so that no variant's model is already on disk
from an earlier run), run by the sweep itself (its runner, executors and row formatting;
rows kept in memory) on 1 and 2 worker processes. Every variant has the same network
structure: one compiled C library serves them all.

Prints one table of wall times, then the cost of one variant split into its stages (measured
in this process on ``--stages`` variants): with the model built anew (what ``simulate()``
does) rig copy and set, network build (components and wiring), CasADi graph,
compiled-model lookup (fingerprint, structure key, constants), steady state, integration
(C), metrics (``summarize``); the whole ``run_variant()``; pickling the row and writing its
journal line; and on the sweep's shared model (``VariantRunner``: network built with the
hoses' matrix entries in p, graph signature, steady state, integration, metrics, whole). ``--before TREE`` runs the same measurement on another source tree (e.g. a
``git archive`` of main) in a subprocess, alternately with this one, and prints the ratios
(the machine is shared and noisy: only ratios from one run mean much).

Usage: python benchmarks/bench_sweep.py [--variants N] [--workers W ...] [--stages N]
                                        [--before TREE] [--repeat R] [--first]
"""
from __future__ import annotations

import argparse
import inspect
import json
import os
import pickle
import subprocess
import sys
import tempfile
import time

import numpy as np

from tables import text_table

PARAMETER = "supply.section2.length+return.section2.length"


def lengths_of(n: int, seed: int | None = None) -> np.ndarray:
    """n section II lengths from 0.05 to 3.048 m, each nudged by < 1 um (new numbers per
    run: no model of an earlier run is found on disk by its fingerprint), [m]."""
    rng = np.random.default_rng(seed)
    return np.linspace(0.05, 3.048, n) + rng.uniform(0, 1e-6, n)


def sweep(lengths, workers: int):
    """The layout-like sweep through :func:`hydroline.studies.sweep`.

    Returns
    -------
    (rows, wall)  rows: one dict per variant (``length_m``, the supply/return frequency and
                  amplitude, ``error`` only where it failed); wall time [s]
    """
    from hydroline.studies import sweep as run_sweep

    tic = time.perf_counter()
    res = run_sweep({PARAMETER: [f"{float(x)!r} m" for x in lengths]}, None, workers=workers,
                    scenario="open-loop-step")
    wall = time.perf_counter() - tic
    rows = []
    for r in res.table.to_dict("records"):
        row = {"length_m": r["supply.section2.length"], "supply_hz": r["supply_frequency_hz"],
               "supply_mpa": r["supply_amplitude_mpa"], "return_hz": r["return_frequency_hz"],
               "return_mpa": r["return_amplitude_mpa"], "wall_s": r["wall_time_s"]}
        if r["error"]:
            row["error"] = r["error"]
        rows.append(row)
    return rows, wall


def stages(lengths) -> dict:
    """Mean time of each stage of one variant, [s], measured here on these lengths: the
    model built anew per variant (what ``simulate()`` does), and -- where the tree has it --
    the sweep's shared model (``VariantRunner``: the network built with the hoses' matrix
    entries in p, compared with the shared one, p swapped)."""
    from hydroline import compiled
    from hydroline.rigs import load_rig
    from hydroline.scenarios import build_scenario, summarize, simulate
    from hydroline.simulation import integrate, solve_steady_state
    from hydroline.studies.sweep import run_variant
    from hydroline.system import build_circuit

    try:
        from hydroline.studies.journal import json_line
    except ImportError:      # before the split: the sweep module's private helper
        from hydroline.studies.sweep import _json_line as json_line
    try:
        from hydroline.components.hose import coefficients_as_parameters
        from hydroline.studies.sweep import VariantRunner, graph_signature
    except ImportError:      # no shared models in this tree
        VariantRunner = None
    try:                     # hose variants without a network build (issue 13, round 3)
        from hydroline.lines.corrections import kept_in_memory
        from hydroline.scenarios import describe_run, rest_state
        from hydroline.studies.sweep import SharedModel, simulate_defaults
    except ImportError:
        SharedModel = None
    rig = load_rig(None)
    simulate(rig)
    acc: dict = {}
    defaults = inspect.signature(simulate).parameters
    tolerances = {k: defaults[k].default for k in ("rtol", "atol_scale") if k in defaults}

    def add(name, dt):
        acc[name] = acc.get(name, 0.0) + dt

    def finish(res, sc, circuit, net):
        res.metadata.update(scenario="open-loop-step", t_disturbance=sc.t_disturbance,
                            axes=circuit.axes, stroke=net.component(
                                next(iter(circuit.axes.values())).actuator).stroke,
                            actuator_natural_frequency_hz=0.0)
        summarize(res)

    runner = VariantRunner(rig) if VariantRunner else None
    shared = None
    with tempfile.TemporaryFile("w") as journal:
        for k, x in enumerate(map(float, lengths)):
            t0 = time.perf_counter()
            r = rig.copy()
            r.set("supply.section2.length", f"{x!r} m")
            r.set("return.section2.length", f"{x!r} m")
            t1 = time.perf_counter()
            circuit = build_circuit(r)
            sc = build_scenario(r, "open-loop-step", None, axes=circuit.axes)
            net = circuit.network(sc.commands)
            t2 = time.perf_counter()
            net.compile()
            t3 = time.perf_counter()
            compiled.native_model(net)
            t4 = time.perf_counter()
            ss = solve_steady_state(net, t0=0.0)
            t5 = time.perf_counter()
            res = integrate(net, ss.x, sc.t_end, p=ss.p, **tolerances)    # simulate()'s
            t6 = time.perf_counter()
            finish(res, sc, circuit, net)
            t7 = time.perf_counter()
            for name, dt in (("rig copy + set", t1 - t0), ("network build", t2 - t1),
                             ("CasADi graph", t3 - t2), ("compiled-model lookup", t4 - t3),
                             ("steady state", t5 - t4), ("integration (C)", res.wall_time),
                             ("integrate() beyond the C", (t6 - t5) - res.wall_time),
                             ("metrics (summarize)", t7 - t6)):
                add(name, dt)
            x2 = x + 1e-7           # new numbers: no model of this variant in any cache
            values = {"supply.section2.length": x2, "return.section2.length": x2}
            t8 = time.perf_counter()
            row = run_variant(rig, k, values, "open-loop-step")
            t9 = time.perf_counter()
            add("run_variant(), model built anew", t9 - t8)
            blob = pickle.dumps(row)
            pickle.loads(blob)
            t10 = time.perf_counter()
            journal.write(json_line(row) + "\n")
            journal.flush()
            t11 = time.perf_counter()
            add("pickling the row", t10 - t9)
            add("journal line", t11 - t10)
            if runner is None:
                continue
            if SharedModel is not None:
                # the shared model, stage by stage (as simulate_shared does it now)
                x3 = x + 2e-7
                r = rig.copy()
                r.set("supply.section2.length", f"{x3!r} m")
                r.set("return.section2.length", f"{x3!r} m")
                if shared is None:
                    with coefficients_as_parameters():
                        circuit = build_circuit(r)
                        sc = build_scenario(r, "open-loop-step", None, axes=circuit.axes)
                        net = circuit.network(sc.commands)
                    shared = SharedModel(net, circuit, sc, r.values)
                    shared.rest = rest_state(net).x
                    integrate(net, shared.rest, sc.t_end, p=net.parameter_values)
                    r = rig.copy()
                    r.set("supply.section2.length", f"{x3 + 1e-7!r} m")
                    r.set("return.section2.length", f"{x3 + 1e-7!r} m")
                s0 = time.perf_counter()
                with kept_in_memory():          # as in the sweep's runner: no cache file
                    p = shared.hose_parameters(r)
                s1 = time.perf_counter()
                net = shared.network
                net.parameter_values = p
                ss = rest_state(net, x_guess=shared.rest)
                shared.rest = ss.x
                s2 = time.perf_counter()
                res = integrate(net, ss.x, shared.scenario.t_end, p=ss.p, **simulate_defaults())
                s3 = time.perf_counter()
                describe_run(res, r, shared.circuit, net, shared.scenario, ss, s0)
                s4 = time.perf_counter()
                summarize(res)
                s5 = time.perf_counter()
                x4 = x + 3e-7
                runner(k, {"supply.section2.length": x4, "return.section2.length": x4})
                s6 = time.perf_counter()
                if k:
                    for name, dt in (("shared: hose entries of p (no network build)", s1 - s0),
                                     ("shared: steady state", s2 - s1),
                                     ("shared: integration (C)", res.wall_time),
                                     ("shared: integrate() beyond the C", (s3 - s2) - res.wall_time),
                                     ("shared: metadata (describe_run)", s4 - s3),
                                     ("shared: metrics (summarize)", s5 - s4),
                                     ("sweep's runner, shared model: whole", s6 - s5)):
                        add(name, dt)
                continue
            # the shared model, stage by stage (as simulate_shared did it before round 3)
            x3 = x + 2e-7
            r = rig.copy()
            r.set("supply.section2.length", f"{x3!r} m")
            r.set("return.section2.length", f"{x3!r} m")
            s0 = time.perf_counter()
            with coefficients_as_parameters():
                circuit = build_circuit(r)
                sc = build_scenario(r, "open-loop-step", None, axes=circuit.axes)
                net = circuit.network(sc.commands)
            s1 = time.perf_counter()
            key = graph_signature(net)
            s2 = time.perf_counter()
            if shared is None or shared[0] != key:
                shared = (key, net)
                net.compile()
                compiled.native_model(net)
            base = shared[1]
            base.parameter_values = net.parameter_values.copy()
            s3 = time.perf_counter()
            ss = solve_steady_state(base, t0=0.0, x_guess=net.guess())
            s4 = time.perf_counter()
            res = integrate(base, ss.x, sc.t_end, p=ss.p)
            s5 = time.perf_counter()
            finish(res, sc, circuit, net)
            s6 = time.perf_counter()
            x4 = x + 3e-7
            runner(k, {"supply.section2.length": x4, "return.section2.length": x4})
            s7 = time.perf_counter()
            if k:               # the first builds the shared model
                for name, dt in (("shared: network build (hoses' entries in p)", s1 - s0),
                                 ("shared: graph signature", s2 - s1),
                                 ("shared: steady state", s4 - s3),
                                 ("shared: integration (C)", res.wall_time),
                                 ("shared: integrate() beyond the C", (s5 - s4) - res.wall_time),
                                 ("shared: metrics (summarize)", s6 - s5),
                                 ("sweep's runner, shared model: whole", s7 - s6)):
                    add(name, dt)
    n = len(lengths)
    out = {}
    for name, v in acc.items():
        out[name] = v / (n - 1 if name.startswith(("shared", "sweep's")) else n)
    return out


def measure(args) -> dict:
    """Everything for one tree: wall per worker count, stages, a few results."""
    seed = int(time.time() * 1e6) % (2**32)
    out = {"walls": {}, "failed": {}, "python": sys.executable}
    sweep(lengths_of(4, seed), max(args.workers))        # warm-up: the library built/cached
    for w in dict.fromkeys(args.workers):
        if args.first:           # a first sweep: none of the line table's nodes on disk
            import shutil

            from hydroline.cache import cache_dir
            shutil.rmtree(cache_dir() / "residue_line_nodes", ignore_errors=True)
        rows, wall = sweep(lengths_of(args.variants, seed + w), w)
        out["walls"][w] = wall
        out["failed"][w] = sum("error" in r for r in rows)
        out["rows"] = rows[:: max(1, len(rows) // 5)]
    if args.stages:
        out["stages"] = stages(lengths_of(args.stages, seed + 99))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", type=int, default=1000)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--stages", type=int, default=30, help="variants timed stage by stage (0: skip)")
    ap.add_argument("--before", metavar="TREE", help="source tree to compare with (PYTHONPATH)")
    ap.add_argument("--repeat", type=int, default=1, help="alternate runs per tree (--before)")
    ap.add_argument("--first", action="store_true",
                    help="each sweep starts with no line-table nodes in the cache (a first sweep)")
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.json:
        print(json.dumps(measure(args)))
        return
    trees = {"this": None}
    if args.before:
        trees = {"before": os.path.abspath(args.before), "this": None}
    results = {name: [] for name in trees}
    for _ in range(args.repeat if args.before else 1):
        for name, tree in trees.items():
            env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
            if tree:
                env["PYTHONPATH"] = tree
            cmd = [sys.executable, os.path.abspath(__file__), "--json", "--variants",
                   str(args.variants), "--stages", str(args.stages), "--workers",
                   *map(str, args.workers), *(["--first"] if args.first else [])]
            cwd = tree or os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
            done = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
            if done.returncode:
                sys.exit(f"bench_sweep: the {name} run failed:\n{done.stderr[-2000:]}")
            results[name].append(json.loads(done.stdout.strip().splitlines()[-1]))
    best = {name: {w: min(r["walls"][str(w)] for r in runs) for w in args.workers}
            for name, runs in results.items()}
    print(f"Layout-like sweep through hydroline.studies.sweep: {PARAMETER} from 0.05 to "
          f"3.048 m, open-loop step 0.25 s each, {os.cpu_count()} CPU cores, load average "
          f"{os.getloadavg()[0]:.1f}; best of {len(next(iter(results.values())))} run(s)")
    head = ["workers", *[f"{n}: wall [s]" for n in trees], *[f"{n}: 1000 variants [s]" for n in trees]]
    if args.before:
        head.append("before / this")
    rows = []
    for w in args.workers:
        row = [w, *[f"{best[n][w]:.1f}" for n in trees],
               *[f"{best[n][w] * 1000 / args.variants:.1f}" for n in trees]]
        if args.before:
            row.append(f"{best['before'][w] / best['this'][w]:.2f}")
        rows.append(row)
    print(text_table(head, rows))
    failed = {n: runs[-1]["failed"] for n, runs in results.items()}
    print("failed variants: " + "; ".join(f"{n}: {f}" for n, f in failed.items()))
    if args.stages:
        names = list(results["this"][-1]["stages"])
        for runs in results.values():       # then the stages only another tree has
            names += [s for s in runs[-1]["stages"] if s not in names]
        for runs in results.values():       # stages only one tree has
            for r in runs:
                for s in names:
                    r["stages"].setdefault(s, float("nan"))
        head = ["stage of one variant", *[f"{n} [ms]" for n in trees]]
        if args.before:
            head.append("before / this")
        rows = []
        for s in names:
            vals = {n: min(r["stages"][s] for r in runs) * 1e3 for n, runs in results.items()}
            row = [s, *[f"{vals[n]:.2f}" if vals[n] == vals[n] else "-" for n in trees]]
            if args.before:
                ok = vals["this"] > 0 and vals["before"] == vals["before"]
                row.append(f"{vals['before'] / vals['this']:.2f}" if ok else "-")
            rows.append(row)
        print(f"\nwhere one variant's time goes (in-process, mean over {args.stages} variants, "
              f"best run):")
        print(text_table(head, rows))
    for r in results["this"][-1]["rows"]:
        hz = lambda v: float("nan") if v is None else v  # noqa: E731
        print(f"  L = {r['length_m']:.3f} m: supply {hz(r['supply_hz']):.1f} Hz "
              f"{hz(r['supply_mpa']):.2f} MPa, return {hz(r['return_hz']):.1f} Hz "
              f"{hz(r['return_mpa']):.2f} MPa")


if __name__ == "__main__":
    main()
