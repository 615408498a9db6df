"""The exported FMU against hydroline itself on the open-loop step (issue 16): wall time of
the run, and the FMU's cost per communication step.

    python benchmarks/bench_fmu.py [--steps 1e-4,1e-3]

Prints one table (no assertions): hydroline.simulate (compiled core, steady state solved in
Python) and the FMI 2.0 co-simulation FMU through fmpy (rest state baked in, hydroline's BDF
inside), for communication steps of 0.1 ms and 1 ms, with the max error of the supply port
pressure as a fraction of its excursion, and the ratio FMU / simulate; before it, the
export time of the default rig and of a rig that differs only in numbers (HSM-to-valve hose
2.5 m, supply accumulator 0.8 L: the binary of the structure is reused, issue 25).
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", default="1e-4,1e-3", help="communication steps [s], comma-separated")
    args = ap.parse_args()
    import fmpy

    import hydroline
    from hydroline.fmu import export_fmu

    hydroline.simulate(None, "open-loop-step")       # warm the compiled core's cache
    tic = time.perf_counter()
    ref = hydroline.simulate(None, "open-loop-step")
    t_sim = time.perf_counter() - tic
    with tempfile.TemporaryDirectory() as tmp:
        tic = time.perf_counter()
        fmu = str(export_fmu(None, Path(tmp) / "bench.fmu", kind="cs"))
        t_export = time.perf_counter() - tic
        variant = hydroline.load_rig().set("supply.section2.length", "2.5 m").set(
            "supply.accumulator.capacity", "0.8 L")
        tic = time.perf_counter()
        export_fmu(variant, Path(tmp) / "variant.fmu", kind="cs")
        t_variant = time.perf_counter() - tic
        u = np.array([(0.0, 0.0), (0.01, 0.0), (0.01, 0.05), (0.25, 0.05)],
                     dtype=[("time", float), ("valve_current", float)])
        rows = [("hydroline.simulate (compiled)", "-", t_sim, "-", "1")]
        for h in (float(s) for s in args.steps.split(",")):
            fmpy.simulate_fmu(fmu, stop_time=0.25, output_interval=h, input=u,
                              output=["supply_port_pressure"])        # load once
            tic = time.perf_counter()
            r = fmpy.simulate_fmu(fmu, stop_time=0.25, output_interval=h, input=u,
                                  output=["supply_port_pressure"])
            wall = time.perf_counter() - tic
            p_ref = np.interp(r["time"], ref.t, ref["supply_port_pressure"])
            err = float(np.max(np.abs(r["supply_port_pressure"] - p_ref)) / np.ptp(ref["supply_port_pressure"]))
            n = int(round(0.25 / h))
            rows.append((f"FMU co-simulation via fmpy, step {h * 1e3:g} ms", f"{wall / n * 1e6:.0f} us",
                         wall, f"{err * 100:.4f} %", f"{wall / t_sim:.2f}"))
    print(f"export (rest state; code generation and cc -O2 unless the structure's binary is "
          f"cached): {t_export:.2f} s")
    print(f"export of a rig differing only in numbers (binary reused): {t_variant:.2f} s")
    print(f"{'run':46s} {'per step':>9s} {'wall [s]':>9s} {'p_s error':>10s} {'ratio':>6s}")
    for name, per, wall, err, ratio in rows:
        print(f"{name:46s} {per:>9s} {wall:9.3f} {err:>10s} {ratio:>6s}")


if __name__ == "__main__":
    main()
