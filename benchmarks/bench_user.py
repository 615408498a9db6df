"""Benchmark: the speed a user feels (issue 13), every figure beside its target, one command.

Whole processes are timed from outside (``subprocess`` + the children's ``getrusage``: wall,
CPU, peak resident memory), the median of ``--repeat`` runs after one warm-up (the compiled
library and the correction-factor tables are then cached, as on any second run):

* ``python -c "import hydroline"``
* ``hydroline simulate --json`` (summary on stdout, no files)
* ``hydroline simulate --out DIR`` (results.csv, summary.json, pressures.png)
* ``hydroline.simulate()`` in one process, default scenario: wall per call after a warm-up,
  and the integration's real-time factor
* the layout sweep (``benchmarks/bench_sweep.py``'s variants, 2 workers; ``--sweep N``
  variants, the wall scaled to 1000)
* ``hydroline simulate --scenario closed-loop-sine --t-end "600 s" --dt-out "10 ms"``
  (``--long``; minutes on a busy machine)

Usage: python benchmarks/bench_user.py [--repeat 5] [--sweep 200] [--long]
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
BIN = Path(sys.executable).with_name("hydroline")

#: The children run as a user's would: Python caches compiled bytecode. With
#: PYTHONDONTWRITEBYTECODE set (as in some sandboxes and CI images) every process compiles
#: hydroline's ~60 modules from source again, ~0.13 s of each command on the development machine.
CHILD_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def whole_process(cmd, repeat, cwd=None):
    """Median wall [s], CPU [s] and peak resident memory [MB] of a command run ``repeat``
    times after one warm-up."""
    walls, cpus, rss = [], [], []
    for k in range(repeat + 1):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        tic = time.perf_counter()
        proc = subprocess.run(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                              text=True, env=CHILD_ENV)
        wall = time.perf_counter() - tic
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(map(str, cmd))} failed: {proc.stderr.strip()[-500:]}")
        if k:   # the first run warms the caches
            walls.append(wall)
            cpus.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
            rss.append(after.ru_maxrss / 1024)
    return statistics.median(walls), statistics.median(cpus), max(rss)


def in_process(repeat):
    import hydroline

    rig = hydroline.load_rig()
    hydroline.simulate(rig)
    walls, integ = [], []
    for _ in range(max(repeat, 5) * 4):
        tic = time.perf_counter()
        res = hydroline.simulate(rig)
        walls.append(time.perf_counter() - tic)
        integ.append(res.wall_time)
    return statistics.median(walls), statistics.median(integ), res.t[-1]


def sweep(variants):
    sys.path.insert(0, str(HERE))
    import numpy as np
    from bench_sweep import sweep as run_sweep

    run_sweep(np.linspace(0.05, 3.048, 8), 2)   # warm both workers' caches
    rows, wall = run_sweep(np.linspace(0.05, 3.048, variants), 2)
    failed = sum("error" in r for r in rows)
    return wall * 1000 / variants, failed


def yardstick() -> float:
    """Seconds of a fixed pure-Python loop (best of 3): the machine's speed, to compare tables
    taken in different sessions."""
    best = float("inf")
    for _ in range(3):
        tic = time.perf_counter()
        total = 0
        for i in range(10_000_000):
            total += i
        best = min(best, time.perf_counter() - tic)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--sweep", type=int, default=200, help="variants of the layout sweep (0: skip)")
    ap.add_argument("--long", action="store_true", help="also the 600 s closed-loop CLI run")
    args = ap.parse_args()
    rows = []
    wall, cpu, _ = whole_process([sys.executable, "-c", "import hydroline"], args.repeat)
    rows.append(("import hydroline (whole process)", f"{wall:.2f} s wall, {cpu:.2f} s CPU", "<= 0.3 s"))
    with tempfile.TemporaryDirectory() as tmp:
        wall, cpu, rss = whole_process([str(BIN), "simulate", "--json"], args.repeat, cwd=tmp)
        rows.append(("hydroline simulate --json (whole process)",
                     f"{wall:.2f} s wall, {cpu:.2f} s CPU, {rss:.0f} MB", "<= 0.5 s"))
        wall, cpu, rss = whole_process([str(BIN), "simulate", "--out", tmp], args.repeat)
        rows.append(("hydroline simulate, CSV + PNG (whole process)",
                     f"{wall:.2f} s wall, {cpu:.2f} s CPU, {rss:.0f} MB", "<= 1.0 s"))
    call, integ, t_end = in_process(args.repeat)
    rows.append(("hydroline.simulate() in-process, default scenario", f"{call * 1e3:.1f} ms",
                 "<= 10 ms"))
    rows.append(("integration, default scenario", f"{integ * 1e3:.1f} ms, {t_end / integ:.0f}x real time",
                 ">= 150x"))
    if args.sweep:
        per_1000, failed = sweep(args.sweep)
        rows.append((f"layout sweep, 2 workers ({args.sweep} variants, scaled)",
                     f"{per_1000:.1f} s per 1000 ({failed} failed)", "<= 8 s"))
    if args.long:
        with tempfile.TemporaryDirectory() as tmp:
            wall, cpu, rss = whole_process(
                [str(BIN), "simulate", "--scenario", "closed-loop-sine", "--t-end", "600 s",
                 "--dt-out", "10 ms", "--out", tmp], 1)
        rows.append(('CLI closed-loop sine --t-end "600 s" --dt-out "10 ms"',
                     f"{wall:.1f} s wall, {cpu:.1f} s CPU, {rss:.0f} MB", "<= 15 s, <= 400 MB"))
    print(f"hydroline {sys.version.split()[0]}, {os.cpu_count()} CPUs, median of {args.repeat} "
          f"after a warm-up; load average {os.getloadavg()[0]:.1f} (other jobs inflate every "
          f"figure: compare runs at equal load); yardstick: a 10-million-step Python loop takes "
          f"{yardstick():.2f} s on this machine now (the machine speed varies between sessions)")
    if "PYTHONDONTWRITEBYTECODE" in os.environ:
        print("PYTHONDONTWRITEBYTECODE is set here: the timed processes ran without it, as a "
              "user's do (bytecode cached)")
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    print(f"{'what':<{w0}}  {'measured':<{w1}}  target")
    print(f"{'-' * w0}  {'-' * w1}  ------")
    for what, got, target in rows:
        print(f"{what:<{w0}}  {got:<{w1}}  {target}")


if __name__ == "__main__":
    main()
