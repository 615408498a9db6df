"""Benchmark: what a rig with new numbers costs (issue 25): a changed-numbers rig's whole
process against the unchanged rig's, a hose line realised for new numbers, and a layout
variant's CPU stage by stage.

Three measurements, each for this tree and, with ``--before TREE``, for another one in
alternation (the machine is shared: a row's two trees run in the same minutes):

* ``changed``: whole ``hydroline simulate --json`` processes in a warm cache of each tree's
  own: the default rig, then a rig file changing one hose's bulk modulus, then one changing
  one section's length (values never run before), ``--rounds`` rounds; medians and the
  median of each round's ratio to its own unchanged run;
* ``line``: CPU time (``time.thread_time``) of one exact-pole line realisation
  (``residue._realise``, no cache) of the default rig's supply hose at 60 lengths
  0.05-3.048 m, per line;
* ``variant``: the layout sweep's runner (``VariantRunner``, its shared model: the sweep's
  own path) over ``--variants`` section II lengths in one process, CPU time per variant and
  in its stages (the two hoses' line realisations -- since issue 25 item 3 the nodes of the
  sweep's Dn table that were realised, none where the cache held them --, rest state,
  integration, metrics, the rest), means; CPU, not wall: other jobs move it less.

Usage: python benchmarks/bench_numbers.py [--only changed,line,variant] [--rounds 10]
                                          [--variants 60] [--before TREE]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from tables import text_table  # noqa: E402

CHILD_ENV = {k: v for k, v in os.environ.items()
             if k not in ("PYTHONDONTWRITEBYTECODE", "HYDROLINE_CACHE_DIR", "PYTHONPATH")}


def changed(trees: dict, rounds: int) -> dict:
    """Whole processes per tree: medians [s] of the unchanged, bulk-modulus and length runs,
    and the medians of the per-round ratios."""
    work = Path(tempfile.mkdtemp(prefix="bench_numbers_"))

    def run(tree, rig=None):
        env = dict(CHILD_ENV, HYDROLINE_CACHE_DIR=str(work / f"cache_{tree}"), MPLBACKEND="Agg")
        if trees[tree]:
            env["PYTHONPATH"] = trees[tree]
        cmd = [sys.executable, "-m", "hydroline", "simulate", *([str(rig)] if rig else []),
               "--json"]
        tic = time.perf_counter()
        subprocess.run(cmd, env=env, cwd=work, stdout=subprocess.DEVNULL, check=True)
        return time.perf_counter() - tic

    for tree in trees:
        run(tree)               # warm: the library built, bytecode written
        run(tree)
    got = {t: {"same": [], "bulk": [], "length": []} for t in trees}
    k = 0
    for r in range(rounds):
        for tree in (list(trees) if r % 2 == 0 else list(trees)[::-1]):
            k += 1
            bulk, length = work / f"bulk_{k}.toml", work / f"length_{k}.toml"
            bulk.write_text(f'[rig]\nbase = "default"\n\n[supply.section1]\n'
                            f'bulk_modulus = "{190 + 0.37 * k:.2f} MPa"\n')
            length.write_text(f'[rig]\nbase = "default"\n\n[supply.section2]\n'
                              f'length = "{2.5 + 0.0131 * k:.4f} m"\n')
            got[tree]["same"].append(run(tree))
            got[tree]["bulk"].append(run(tree, bulk))
            got[tree]["length"].append(run(tree, length))
    out = {}
    for tree, d in got.items():
        out[tree] = {key: statistics.median(v) for key, v in d.items()}
        for key in ("bulk", "length"):
            out[tree][f"{key}_ratio"] = statistics.median(
                a / b for a, b in zip(d[key], d["same"]))
    return out


#: Run in a child per tree: CPU per line realised, and per layout variant by stage
CHILD = r'''
import importlib, json, os, sys, time
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import numpy as np
import hydroline
from hydroline.lines import Line, residue
only, n_variants = sys.argv[1].split(","), int(sys.argv[2])
out = {}
rig = hydroline.load_rig(None)
if "line" in only:
    fluid = hydroline.Fluid(870.0, 3.2e-5, 1.5e9)
    lines = [Line(x, 0.01343, fluid, bulk_modulus=1.2e9) for x in np.linspace(0.05, 3.048, 60)]
    residue._realise(lines[0], 6, "PQ")
    tic = time.thread_time()
    for line in lines:
        residue._realise(line, 6, "PQ")
    out["line"] = (time.thread_time() - tic) / len(lines)
if "variant" in only:
    sweep = importlib.import_module("hydroline.studies.sweep")
    from hydroline.scenarios import running
    import hydroline.engine as engine
    spent = {}

    def timed(module, name, stage):
        original = getattr(module, name)

        def wrapper(*args, **kwargs):
            tic = time.thread_time()
            try:
                return original(*args, **kwargs)
            finally:
                spent[stage] = spent.get(stage, 0.0) + time.thread_time() - tic
        setattr(module, name, wrapper)

    timed(residue, "_realise", "line realisations")
    timed(running, "rest_state", "rest state")
    timed(engine, "integrate", "integration")
    timed(sweep, "port_summary", "metrics")
    runner = sweep.VariantRunner(rig)
    runner(0, {"supply.section2.length": 1.0, "return.section2.length": 1.0})
    spent.clear()
    lengths = np.linspace(0.05, 3.048, n_variants) + np.random.default_rng().uniform(0, 1e-6)
    per = []
    for k, x in enumerate(map(float, lengths)):
        tic = time.thread_time()
        runner(k + 1, {"supply.section2.length": x, "return.section2.length": x})
        per.append(time.thread_time() - tic)
    stages = {k: v / n_variants for k, v in spent.items()}
    stages["the rest"] = sum(per) / n_variants - sum(stages.values())
    out["variant"] = {"mean": float(np.mean(per)), "median": float(np.median(per)),
                      "max": float(np.max(per)), "stages": stages}
print(json.dumps(out))
'''


def in_process(tree, only, variants) -> dict:
    env = dict(CHILD_ENV, MPLBACKEND="Agg")
    if tree:
        env["PYTHONPATH"] = tree
    # (in a neutral directory: ``python -c`` puts the working directory first on sys.path,
    # so run from a source tree both children imported that tree)
    done = subprocess.run([sys.executable, "-c", CHILD, ",".join(only), str(variants)],
                          env=env, capture_output=True, text=True, cwd=tempfile.gettempdir())
    if done.returncode:
        raise SystemExit(f"bench_numbers: the run failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def ms(x) -> str:
    return f"{x * 1e3:.1f} ms"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="changed,line,variant")
    ap.add_argument("--rounds", type=int, default=10, help="rounds of the whole processes")
    ap.add_argument("--variants", type=int, default=60, help="layout variants (in-process)")
    ap.add_argument("--before", metavar="TREE", help="another source tree (PYTHONPATH)")
    args = ap.parse_args()
    only = args.only.split(",")
    this = str(HERE.parent)         # (without it a child imports the installed package)
    trees = {"this": this} if not args.before else {"before": os.path.abspath(args.before),
                                                    "this": this}
    print(f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} at the start")
    if "changed" in only:
        got = changed(trees, args.rounds)
        rows = [(t, ms(g["same"]), f"{ms(g['bulk'])} ({g['bulk_ratio']:.2f}x)",
                 f"{ms(g['length'])} ({g['length_ratio']:.2f}x)") for t, g in got.items()]
        print(text_table(("tree", "unchanged rig", "one bulk modulus changed",
                          "one length changed"), rows))
    rest = [w for w in only if w in ("line", "variant")]
    if rest:
        runs = {}
        for _ in range(2):                      # alternately, twice
            for t, path in trees.items():
                runs.setdefault(t, []).append(in_process(path, rest, args.variants))
        if "line" in rest:
            print(text_table(("tree", "CPU per line realised (two runs)"),
                             [(t, " / ".join(ms(r["line"]) for r in rs))
                              for t, rs in runs.items()]))
        if "variant" in rest:
            names = list(runs["this"][0]["variant"]["stages"])
            head = ("layout variant, CPU (two runs)", *trees)
            rows = [("whole, mean", *[" / ".join(ms(r["variant"]["mean"]) for r in runs[t])
                                      for t in trees]),
                    ("whole, median", *[" / ".join(ms(r["variant"]["median"]) for r in runs[t])
                                        for t in trees]),
                    ("slowest variant", *[" / ".join(ms(r["variant"]["max"]) for r in runs[t])
                                          for t in trees])]
            rows += [(name, *[" / ".join(ms(r["variant"]["stages"].get(name, float("nan")))
                                         for r in runs[t]) for t in trees]) for name in names]
            print(text_table(head, rows))
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
