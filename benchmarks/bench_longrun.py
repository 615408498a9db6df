"""Benchmark: issue 26 item 2 -- ``hydroline simulate --scenario closed-loop-sine --t-end "600 s"``
with defaults in <= 15 s wall and <= 400 MB resident.

Runs the command line as a user does (a fresh process each time: imports, the cached compiled
model, the figure process, results.csv decimated to ~200 MB, summary.json, pressures.png) for
each simulated time and prints one table: wall time, CPU time (user + system of the process and
the children it waited for), peak resident memory (the largest of those processes), the
real-time factor of the whole command (simulated s per wall s) and of the integrator alone (as
the command prints it), the tracking error and supply ripple it reports, and the machine's load
average at the start (two cores shared with other work: wall times follow the load, CPU times
much less).

Usage: python benchmarks/bench_longrun.py [--t-end 60 600] [--repeat 1] [--format csv]
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time

from tables import text_table


def run_once(t_end: float, fmt: str) -> dict:
    """One ``hydroline simulate`` of the closed-loop sine in a fresh process.

    Parameters
    ----------
    t_end : float
        Simulated time, [s]
    fmt : str
        ``--format`` (csv, parquet or mat)

    Returns
    -------
    dict
        ``wall`` [s], ``cpu`` [s], ``rss`` [MB], ``integrator`` (the printed real-time
        factor, [-]), ``summary`` (summary.json), ``load`` (1-min load average at the start).
    """
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "hydroline", "simulate", "--scenario", "closed-loop-sine",
               "--t-end", f"{t_end:g} s", "--out", out, "--format", fmt]
        load = os.getloadavg()[0]
        tic = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        text = proc.stdout.read()
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - tic
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            raise SystemExit(f"hydroline simulate failed ({proc.returncode}):\n{text}")
        m = re.search(r"the integrator: ([0-9.]+)x faster", text)
        with open(os.path.join(out, "summary.json")) as f:
            summary = json.load(f)
    return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime, "rss": usage.ru_maxrss / 1024,
            "integrator": float(m.group(1)) if m else float("nan"), "summary": summary,
            "load": load}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, nargs="+", default=[60.0, 600.0],
                    help="simulated times, [s]")
    ap.add_argument("--repeat", type=int, default=1, help="runs per simulated time")
    ap.add_argument("--format", default="csv", choices=("csv", "parquet", "mat"))
    args = ap.parse_args(argv)
    run_once(1.0, args.format)   # (the compiled model built and cached first, not timed)
    rows = []
    for t_end in args.t_end:
        for _ in range(args.repeat):
            r = run_once(t_end, args.format)
            s = r["summary"]
            rows.append([f"{t_end:g}", f"{r['load']:.1f}", f"{r['wall']:.2f}", f"{r['cpu']:.2f}",
                         f"{r['rss']:.0f}", f"{t_end / r['wall']:.1f}", f"{r['integrator']:.1f}",
                         f"{s['tracking_error_rms_mm']:.4f}", f"{s['tracking_error_max_mm']:.4f}",
                         f"{s['supply']['ripple_pp_mpa']:.4f}"])
            print(" ".join(rows[-1]), file=sys.stderr, flush=True)
    print(text_table(["t_end [s]", "load", "wall [s]", "cpu [s]", "RSS [MB]", "x real time",
                      "integrator [x]", "track rms [mm]", "track max [mm]",
                      "supply ripple [MPa]"], rows))


if __name__ == "__main__":
    main()
