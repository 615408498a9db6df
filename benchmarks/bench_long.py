"""Benchmark: a long run -- the closed-loop 2 Hz sine fatigue test streamed to disk.

``hydroline.simulate(scenario="closed-loop-sine", t_end=..., stream_to=path)``: the default
rig tracking the 35 mm, 2 Hz sine under P control for 10 simulated minutes (default),
written to CSV chunk by chunk while it runs, in constant memory (only per-column statistics
are kept). Prints one table: simulated time, rows and file size written, wall time,
real-time factor, integrator steps, peak memory of the process (before and after the run),
and the tracking error and peak port pressures from the streamed statistics.

Usage: python benchmarks/bench_long.py [--duration SECONDS] [--dt-out SECONDS] [--all-columns]
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time

from hydroline.scenarios import simulate

COLUMNS = ["position_reference", "piston_position", "piston_velocity", "valve_current",
           "supply_port_pressure", "return_port_pressure", "bottom_chamber_pressure",
           "top_chamber_pressure"]


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def current_rss_mb() -> float:
    """Resident memory now (not the high-water mark), from /proc; NaN where there is none."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError, IndexError):
        return float("nan")


RSS_SAMPLES: dict = {}   # percent done -> resident MB, sampled by the progress bar


def progress_bar(frac, _state={"t0": None}):
    if _state["t0"] is None:
        _state["t0"] = time.perf_counter()
    for mark in (10, 25, 50, 75, 100):
        if frac * 100 >= mark and mark not in RSS_SAMPLES:
            RSS_SAMPLES[mark] = current_rss_mb()
    n = int(frac * 40)
    el = time.perf_counter() - _state["t0"]
    sys.stderr.write(f"\r  [{'#' * n}{'.' * (40 - n)}] {frac * 100:5.1f} %  {el:6.1f} s")
    if frac >= 1:
        sys.stderr.write("\n")
    sys.stderr.flush()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=600.0, help="simulated time [s] (600)")
    ap.add_argument("--dt-out", type=float, default=1e-3, help="output interval [s] (1e-3)")
    ap.add_argument("--all-columns", action="store_true", help="write every signal and state")
    ap.add_argument("--out", help="CSV path (default: a temporary file, removed afterwards)")
    args = ap.parse_args(argv)
    simulate(scenario="closed-loop-sine", t_end=0.05)            # warm-up: library built/cached
    before = peak_rss_mb()
    with tempfile.TemporaryDirectory() as tmp:
        path = args.out or os.path.join(tmp, "fatigue.csv")
        tic = time.perf_counter()
        res = simulate(scenario="closed-loop-sine", t_end=args.duration, dt_out=args.dt_out,
                       stream_to=path, stream_columns=None if args.all_columns else COLUMNS,
                       progress=progress_bar)
        wall = time.perf_counter() - tic
        size = os.path.getsize(path)
        stats = res.metadata["stream_stats"]
    after = peak_rss_mb()
    st = res.stats
    pos = stats.loc["piston_position"]
    rows = [
        ["simulated time [s]", f"{args.duration:g}"],
        ["rows x columns written", f"{res.metadata['stream_rows']} x {len(stats)}"],
        ["file size [MB]", f"{size / 1e6:.1f}"],
        ["wall time [s]", f"{wall:.1f}"],
        ["integration wall time [s]", f"{res.wall_time:.1f}"],
        ["real-time factor", f"{args.duration / wall:.1f}"],
        ["solver / steps / f evals", f"{res.metadata['solver']} / {st['nsteps']} / {st['nfevals']}"],
        ["peak RSS before / after the run [MB]", f"{before:.0f} / {after:.0f}"],
        ["resident MB at " + " / ".join(f"{k} %" for k in RSS_SAMPLES),
         " / ".join(f"{v:.0f}" for v in RSS_SAMPLES.values())],
        ["piston position min / max [mm]", f"{pos['min'] * 1e3:.1f} / {pos['max'] * 1e3:.1f}"],
        ["supply port pressure min / max [MPa]",
         f"{stats.loc['supply_port_pressure', 'min'] / 1e6:.2f} / "
         f"{stats.loc['supply_port_pressure', 'max'] / 1e6:.2f}"],
    ]
    w = max(len(r[0]) for r in rows)
    print(f"Closed-loop 2 Hz sine fatigue test, streamed to CSV every {args.dt_out * 1e3:g} ms")
    for k, v in rows:
        print(f"  {k.ljust(w)}  {v}")


if __name__ == "__main__":
    main()
