"""Benchmark: a study's run (``metrics_only``) at a looser tolerance against the issue-25
accuracy target: every user metric within 0.05 % and the traces within 0.5 % of a tight
reference up to the stop (the metrics window's end).

For layout variants (sections II lengths, as ``hydroline layout``), each run ends at its metrics
window (``simulate(metrics_only=True)``, compiled core). Per tolerance it prints the steps and
the integration time per variant, the largest trace error (port pressures, piston position and
velocity, % of each one's excursion in the window, against rtol 1e-10) and the largest change
of every numeric metric of the summary (both ports), % of the reference value.

Usage: python benchmarks/bench_study_tolerance.py [--lengths 0.05 0.3 ...] [--rtols 1e-6 1e-5]
       [--atol-scale 1e-7]
"""
from __future__ import annotations

import argparse
import math

import numpy as np

from tables import text_table

TRACES = ("supply_port_pressure", "return_port_pressure", "piston_position", "piston_velocity")
LENGTHS = (0.05, 0.2, 0.4, 0.7512, 1.2, 2.0, 3.048)


def metrics_of(summary) -> dict:
    """Every numeric metric of both ports, name -> value."""
    out = {}
    for side in ("supply", "return"):
        for k, v in summary[side].items():
            if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
                out[f"{side}.{k}"] = float(v)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lengths", type=float, nargs="+", default=LENGTHS, help="sections II [m]")
    ap.add_argument("--rtols", type=float, nargs="+", default=(1e-6, 3e-6, 1e-5))
    ap.add_argument("--atol-scale", type=float, default=1e-7,
                    help="absolute tolerance / state scale (simulate()'s default 1e-7)")
    args = ap.parse_args(argv)
    import hydroline
    from hydroline.scenarios import summarize

    base = hydroline.load_rig()
    rows, worst = [], {}
    for length in args.lengths:
        rig = base.set("supply.section2.length", f"{length} m").set(
            "return.section2.length", f"{length} m")
        ref = hydroline.simulate(rig, solver="compiled", rtol=1e-10, atol_scale=1e-11,
                                 metrics_only=True)
        t0, t1, _ = ref.metadata["metrics_window"]
        ref_metrics = metrics_of(summarize(ref))
        for rtol in args.rtols:
            res = hydroline.simulate(rig, solver="compiled", rtol=rtol, atol_scale=args.atol_scale,
                                     metrics_only=True)
            n = min(len(res.t), len(ref.t))
            window = (ref.t[:n] >= t0) & (ref.t[:n] <= t1)
            trace = max(np.max(np.abs(res[k][:n][window] - ref[k][:n][window]))
                        / np.ptp(ref[k][:n][window]) for k in TRACES) * 100
            got = metrics_of(summarize(res))
            moved, which = 0.0, ""
            for k, b in ref_metrics.items():
                a = got.get(k)
                if a is None:
                    moved, which = math.inf, k + " missing"
                    break
                d = abs(a - b) / abs(b) * 100 if b else 0.0
                if d > moved:
                    moved, which = d, k
            w = worst.setdefault(rtol, [0.0, 0.0, 0, 0.0])
            w[0], w[1] = max(w[0], trace), max(w[1], moved)
            w[2] += res.stats["nsteps"]
            w[3] += res.metadata.get("integration_time", res.wall_time)
            rows.append((f"{length:g}", f"{rtol:g}", res.stats["nsteps"], f"{trace:.3f}",
                         f"{moved:.4f}", which))
    print(f"Layout variants, metrics_only runs on the compiled core (atol_scale {args.atol_scale:g}) "
          "against rtol 1e-10; trace error: % of excursion in the window; metric moved: % of the reference")
    print(text_table(("section II [m]", "rtol", "steps", "trace err [%]", "metric moved [%]",
                      "which"), rows))
    print(text_table(("rtol", "steps (all)", "worst trace [%]", "worst metric [%]",
                      "target met (0.5 %, 0.05 %)"),
                     [(f"{r:g}", w[2], f"{w[0]:.3f}", f"{w[1]:.4f}",
                       "yes" if w[0] <= 0.5 and w[1] <= 0.05 else "no")
                      for r, w in worst.items()]))


if __name__ == "__main__":
    main()
