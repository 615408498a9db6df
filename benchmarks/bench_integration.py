"""Benchmark: the issue-25 integration target -- >= 50x real time with every user metric within
0.05 % and the traces within 0.5 % of a tight reference up to the stop (stretch >= 90x).

For the default rig and a short-hose variant (sections II 0.3 m, lightly damped fast ringing),
per integrator setting (tolerances, the C core's method -- its BDF, or ``solver="radau"``, its
Radau IIA --, the treatment after the piston's stop) it prints:
the integration time of the whole default run (median and best of ``--repeat``, wall of the
integration loop on one core, each result dropped before the next run) and the median's
real-time factor (simulated s per s), the steps taken before the
valve step, while the piston moves (the valve step to the stop) and after the stop, the largest
trace error up to the stop (port pressures, piston position and velocity, % of each one's
excursion there) and over the whole run, and the largest change of every numeric metric of both
ports (% of the reference value), all against the compiled core at rtol 1e-10 / atol 1e-11
throughout. "defaults" is simulate()'s own: rtol 1e-6 and 30x that after the stop
(``after_stop_rtol="auto"``); every other setting keeps its rtol throughout unless it names
a tolerance after the stop.

Usage: python benchmarks/bench_integration.py [--repeat 15] [--lengths 3.048 0.3]
       [--settings 1e-6/1e-7 "radau 1e-5/1e-6" ...] [--modes 30]
"""
from __future__ import annotations

import argparse
import math

import numpy as np

from tables import text_table

TRACES = ("supply_port_pressure", "return_port_pressure", "piston_position", "piston_velocity")
#: name -> keywords of simulate() (the compiled core); a setting that names no treatment after
#: the stop keeps its rtol throughout (``after_stop_rtol=None``, added in :func:`main`)
SETTINGS = {
    "defaults (1e-6, 3e-5 after stop)": dict(after_stop_rtol="auto"),
    "1e-6/1e-7": dict(rtol=1e-6, atol_scale=1e-7),
    "1e-7/1e-8": dict(rtol=1e-7, atol_scale=1e-8),
    "3e-6/3e-7": dict(rtol=3e-6, atol_scale=3e-7),
    "1e-5/1e-6": dict(rtol=1e-5, atol_scale=1e-6),
    "1e-6, 1e-4 after stop": dict(rtol=1e-6, atol_scale=1e-7, after_stop_rtol=1e-4),
    "1e-6, 1e-5 after stop": dict(rtol=1e-6, atol_scale=1e-7, after_stop_rtol=1e-5),
    "1e-6, 3e-4 after stop": dict(rtol=1e-6, atol_scale=1e-7, after_stop_rtol=3e-4),
    "3e-6, 1e-4 after stop": dict(rtol=3e-6, atol_scale=3e-7, after_stop_rtol=1e-4),
    "1e-7, 1e-4 after stop": dict(rtol=1e-7, atol_scale=1e-8, after_stop_rtol=1e-4),
    "1e-8/1e-9": dict(rtol=1e-8, atol_scale=1e-9),
    # the C core's Radau IIA (order 5, L-stable) instead of its BDF
    "radau 1e-5/1e-6": dict(solver="radau", rtol=1e-5, atol_scale=1e-6),
    "radau 3e-6/3e-7": dict(solver="radau", rtol=3e-6, atol_scale=3e-7),
    "radau 1e-6/1e-7": dict(solver="radau", rtol=1e-6, atol_scale=1e-7),
    "radau 3e-5/3e-6": dict(solver="radau", rtol=3e-5, atol_scale=3e-6),
    "radau 6e-5/6e-6": dict(solver="radau", rtol=6e-5, atol_scale=6e-6),
    "radau 1e-4/1e-5": dict(solver="radau", rtol=1e-4, atol_scale=1e-5),
    # simulate()'s default: the BDF, or Radau IIA at 30x the tolerances where the model's
    # modes cap the BDF's orders (NativeSolver's method "auto")
    "auto 1e-6/1e-7": dict(solver="auto", rtol=1e-6, atol_scale=1e-7),
    "auto 1e-6, 1e-4 after stop": dict(solver="auto", rtol=1e-6, atol_scale=1e-7,
                                       after_stop_rtol=1e-4),
    "auto 1e-6, 1e-5 after stop": dict(solver="auto", rtol=1e-6, atol_scale=1e-7,
                                       after_stop_rtol=1e-5),
}


def metrics_of(summary) -> dict:
    """Every numeric metric of both ports, name -> value."""
    out = {}
    for side in ("supply", "return"):
        for k, v in summary[side].items():
            if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
                out[f"{side}.{k}"] = float(v)
    return out


def compare(res, ref, ref_metrics, t_stop):
    """(trace error up to the stop [%], over the run [%], worst metric [%], its name)."""
    from hydroline.scenarios import summarize

    n = min(len(res.t), len(ref.t))
    upto = ref.t[:n] <= t_stop
    err = []
    for mask in (upto, np.ones(n, bool)):
        err.append(max(np.max(np.abs(res[k][:n][mask] - ref[k][:n][mask]))
                        / np.ptp(ref[k][:n][mask]) for k in TRACES) * 100)
    got = metrics_of(summarize(res))
    moved, which = 0.0, ""
    for k, b in ref_metrics.items():
        a = got.get(k)
        if a is None:
            return err[0], err[1], math.inf, k + " missing"
        d = abs(a - b) / abs(b) * 100 if b else 0.0
        if d > moved:
            moved, which = d, k
    return err[0], err[1], moved, which


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15, help="timed runs per setting")
    ap.add_argument("--lengths", type=float, nargs="+", default=(3.048, 0.3),
                    help="sections II [m] (3.048: the default rig)")
    ap.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=list(SETTINGS))
    ap.add_argument("--modes", type=int, default=None, help="modes per hose section (rig default: 6)")
    args = ap.parse_args(argv)
    import hydroline
    from hydroline.scenarios import summarize

    rows = []
    for length in args.lengths:
        rig = hydroline.load_rig()
        rig = rig if length == 3.048 else rig.set("supply.section2.length", f"{length} m").set(
            "return.section2.length", f"{length} m")
        if args.modes:
            rig = rig.set("rig.modes_per_section", args.modes)
        ref = hydroline.simulate(rig, solver="compiled", rtol=1e-10, atol_scale=1e-11,
                                 after_stop_rtol=None)
        t0, t_stop, _ = ref.metadata["metrics_window"]
        t_end = float(ref.t[-1])
        ref_metrics = metrics_of(summarize(ref))
        for name in args.settings:
            kw = {"solver": "compiled", "after_stop_rtol": None, **SETTINGS[name]}
            res = hydroline.simulate(rig, **kw)
            walls = [res.wall_time]
            for _ in range(args.repeat - 1):
                walls.append(hydroline.simulate(rig, **kw).wall_time)
            steps = [hydroline.simulate(rig, t_end=t, **kw).stats["nsteps"]
                     for t in (t0 + 1e-4, t_stop)] + [res.stats["nsteps"]]
            up, whole, moved, which = compare(res, ref, ref_metrics, t_stop)
            best, median = min(walls), float(np.median(walls))
            rows.append((f"{length:g}", name, f"{median * 1e3:.2f} ({best * 1e3:.2f})",
                         f"{t_end / median:.0f}x",
                         f"{steps[0]}/{steps[1] - steps[0]}/{steps[2] - steps[1]}",
                         f"{up:.3f}", f"{whole:.3f}", f"{moved:.4f}", which))
    print("Compiled core, whole default run; steps: before the valve step (+0.1 ms) / while the piston "
          "moves / after its stop; errors against rtol 1e-10 / atol 1e-11")
    print(text_table(("section II [m]", "setting", "integration [ms]: median (best)",
                      "real time (median)",
                      "steps", "trace to stop [%]", "trace all [%]", "worst metric [%]",
                      "which"), rows))


if __name__ == "__main__":
    main()
