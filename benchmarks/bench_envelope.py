"""Benchmark: the performance envelope of the default rig (issue 29's done-when: 20
frequencies, 0.5-200 Hz, in under a minute on 2 cores).

Runs :func:`hydroline.studies.envelope.envelope` (the lines and the constant supply, 5 %
distortion) on ``--workers`` processes, prints the wall time against the 60 s target, the
runs and periods it took, and per frequency the two curves with what limits them and the
ratio of the lines' amplitude to the constant supply's. Both searches try the same grid of
amplitudes, so a ratio above 1 is physics, not the search: the lines' port pulsation at twice
the test frequency raising the valve's flow (``port_ripple_gain``); the ratio should not
exceed that gain by more than the grid's step. The first call builds or loads the compiled
model (cached on disk): run it twice for the warm figure.

Usage: python benchmarks/bench_envelope.py [--points 20] [--workers 2] [--json FILE]
"""
from __future__ import annotations

import argparse
import json
import os
import time

from tables import text_table

TARGET_S = 60.0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=20, help="frequencies, 0.5-200 Hz")
    ap.add_argument("--workers", type=int, default=2, help="worker processes")
    ap.add_argument("--json", help="also write the envelope's JSON here")
    args = ap.parse_args(argv)
    from hydroline.studies.envelope import envelope

    tic = time.perf_counter()
    res = envelope(points=args.points, workers=args.workers)
    wall = time.perf_counter() - tic
    rows = []
    for k, f in enumerate(res.frequency_hz):
        h, c = res.hoses[k], res.constant_supply[k]
        xh, xc = h["displacement_amplitude_m"], c["displacement_amplitude_m"]
        rows.append((f"{f:.3g}", f"{xh * 1e3:.3g}", h["limited_by"], f"{xc * 1e3:.3g}",
                     c["limited_by"], f"{xh / xc:.3f}" if xc else "-", h["runs"], c["runs"]))
    print(text_table(("f [Hz]", "lines [mm]", "limited by", "constant [mm]", "limited by",
                      "lines/constant", "runs", "runs (const)"), rows))
    runs = sum(p["runs"] for p in res.hoses + res.constant_supply)
    periods = sum(p["periods"] for p in res.hoses + res.constant_supply)
    print(f"\n{args.points} frequencies, {args.workers} workers, {os.cpu_count()} CPUs: "
          f"{wall:.1f} s ({res.wall_time:.1f} s in envelope()), target {TARGET_S:.0f} s: "
          f"{wall / TARGET_S:.2f} of it; {runs} closed-loop runs, {periods} periods")
    # the lines may lie above the constant supply only by what their ports' pulsation adds to
    # the valve's flow (port_ripple_gain) and one grid step of the bisection (2 %)
    above = [(f, p["displacement_amplitude_m"] / q["displacement_amplitude_m"],
              p["port_ripple_gain"])
             for f, p, q in zip(res.frequency_hz, res.hoses, res.constant_supply)
             if q["displacement_amplitude_m"] and p["displacement_amplitude_m"]
             > q["displacement_amplitude_m"]]
    print("lines above the constant supply at: " +
          (", ".join(f"{f:.3g} Hz ({r:.3f}, port pulsation gain {g:.3f})" for f, r, g in above)
           if above else "none"))
    beyond = [f for f, r, g in above if r > max(1.0, g) * 1.02 * (1 + 1e-9)]
    print("beyond the port pulsation's gain and a grid step: " +
          (", ".join(f"{f:.3g} Hz" for f in beyond) if beyond else "none"))
    if res.errors:
        print("errors: " + "; ".join(res.errors))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(res.to_dict(), fh, indent=1)


if __name__ == "__main__":
    main()
