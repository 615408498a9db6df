"""Issue 30: what the cavity model (fluid.cavity_pressure: M42 in chambers and volumes, M45
at hose ends), on by default at 5 kPa since issue 30, changes against "off". Prints three
tables:

1. the default rig's open-loop-step metrics per port without and with the model (compiled C
   core and CVODES);
2. its run cost: steps, f and Jacobian evaluations, integration CPU (median of interleaved
   repeats, model built once), cold-cache CPU of a whole `hydroline simulate --json` in a
   fresh process, with M42 alone (hose-end cavities left out) beside M42 + M45; the
   compiled model's size: the bordered Jacobian's nonzeros, the CasADi instructions of f
   and J, the sparse LU's slots and flops, the C source;
3. the lowest watched absolute pressure of the shipped rigs and of the fuzz campaigns'
   plausible cavitating rigs, without the model, with M42 alone and with M42 + M45.

Usage: python benchmarks/bench_cavity_default.py [--cavity-pressure "5 kPa"] [--repeat 60]
(~2 min on the 2-core development machine).
"""
from __future__ import annotations

import argparse
import copy
import os
import statistics
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager, nullcontext
from pathlib import Path

from hydroline.components import hose
from hydroline.rigs import load_rig
from hydroline.scenarios.running import Simulation, watched_pressures
from hydroline.scenarios.summaries import summarize

RIGS = Path(__file__).resolve().parent.parent / "hydroline" / "rigs"
REPRO = Path("/work/shared/repro")
#: name -> (rig file or None for the default, changes)
CASES = {**{n: (RIGS / f"{n}.toml", {}) for n in (
    "ayalew2005", "ayalew2005_catalogue", "ayalew2005_circuit", "ayalew2005_yang_tobler",
    "two_axis")},
    "return 0.3x bore + valve 3x": (None, {"return.section2.diameter": "4.08 mm",
                                           "servovalve.rated_flow": "57 L/min"}),
    "valve 10x (p3_11)": (None, {"servovalve.rated_flow": "190 L/min"}),
    **{n: (REPRO / f"{n}.toml", {}) for n in ("p1_1094_combo", "p1_1135_combo")}}
METRICS = ("frequency_hz", "amplitude_mpa", "first_excursion_mpa", "settling_time_s")


@contextmanager
def chambers_only():
    """M42 alone: hose sections hold no end cavity (M45) while models are built."""
    saved = hose.HoseSection._cavity_ends
    hose.HoseSection._cavity_ends = lambda self: ()
    try:
        yield
    finally:
        hose.HoseSection._cavity_ends = saved


def variant(rig, cav, kind):
    """(Simulation with the model built, rig) for kind "off", "M42" or "M42+M45"."""
    rig = copy.deepcopy(rig)                 # Rig.set changes the rig itself
    rig.set("fluid.cavity_pressure", "off" if kind == "off" else cav)
    sim = Simulation()
    if kind == "M42":
        with chambers_only():
            sim.run(rig, solver="compiled")
    return sim, rig


def model_size(rig, kind):
    """The compiled model's size: bordered Jacobian nonzeros, f + J instructions, LU."""
    from hydroline.compiled import codegen
    from hydroline.scenarios import build_scenario
    from hydroline.system import build_circuit

    with chambers_only() if kind == "M42" else nullcontext():
        circuit = build_circuit(rig)
        sc = build_scenario(rig, axes=circuit.axes)
        model = circuit.network(sc.commands).compile()
    f, jac, _ = codegen.scaled_functions(model)
    gen = codegen.generate(model, (f, jac, _))
    return (f"bordered J {jac.sparsity_out(0).size1()}^2, {jac.sparsity_out(0).nnz()} nonzeros; "
            f"instructions f {f.n_instructions()} + J {jac.n_instructions()}; "
            f"LU {gen.lu_slots} slots, {gen.lu_flops} flops; C source {len(gen.source) / 1e3:.0f} kB")


def cold_cpu(cav):
    """CPU [s] of `hydroline simulate --json` in a fresh process with an empty cache."""
    out = []
    for text in ('[fluid]\ncavity_pressure = "off"\n', f'[fluid]\ncavity_pressure = "{cav}"\n'):
        with tempfile.TemporaryDirectory() as d:
            f = Path(d) / "rig.toml"
            f.write_text('[rig]\nbase = "default"\n' + text)
            env = {**os.environ, "HYDROLINE_CACHE_DIR": str(Path(d) / "cache")}
            before = os.times()
            subprocess.run([sys.executable, "-m", "hydroline", "simulate", str(f), "--json"],
                           env=env, check=True, capture_output=True)
            after = os.times()
            out.append(after.children_user + after.children_system
                       - before.children_user - before.children_system)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cavity-pressure", default="5 kPa")
    ap.add_argument("--repeat", type=int, default=60)
    a = ap.parse_args()
    cav = a.cavity_pressure
    base = load_rig(None)

    print(f"1. default rig, open-loop step: metrics without / with cavity_pressure = {cav}")
    for solver in ("compiled", "cvodes"):
        sums = [summarize(sim.run(rig, solver=solver))
                for sim, rig in (variant(base, cav, k) for k in ("off", "M42+M45"))]
        for port in ("supply", "return"):
            row = "  ".join(f"{m} {sums[0][port][m]:.7g} / {sums[1][port][m]:.7g}"
                            for m in METRICS)
            print(f"  {solver:8s} {port:6s} {row}")

    print(f"\n2. run cost of the default rig (integration CPU: median of {a.repeat} "
          f"interleaved runs, model built once)")
    sims = {k: variant(base, cav, k) for k in ("off", "M42", "M42+M45")}
    for solver, n in (("compiled", a.repeat), ("cvodes", max(a.repeat // 12, 3))):
        cpu = {k: [] for k in sims}
        stats = {}
        for k, (sim, rig) in sims.items():
            stats[k] = sim.run(rig, solver=solver).stats
        for _ in range(n):
            for k, (sim, rig) in sims.items():
                tic = time.process_time()
                sim.run(rig, solver=solver)
                cpu[k].append(time.process_time() - tic)
        ref = statistics.median(cpu["off"])
        for k in sims:
            c = statistics.median(cpu[k])
            print(f"  {solver:8s} {k:8s} steps {stats[k]['nsteps']:5d}  f {stats[k]['nfevals']:5d}"
                  f"  J {stats[k]['njevals']:4d}  run CPU {c * 1e3:8.2f} ms ({c / ref - 1:+.0%})")
    for k, (sim, rig) in sims.items():
        print(f"  compiled model {k:8s} " + model_size(rig, k))
    off, on = cold_cpu(cav)
    print(f"  cold `simulate --json` (empty cache, fresh process) CPU: {off:.2f} s off, "
          f"{on:.2f} s M42+M45 ({on / off - 1:+.0%})")

    print("\n3. lowest watched absolute pressure [kPa] (compiled): off / M42 / M42+M45")
    for name, (path, changes) in CASES.items():
        if path is not None and not path.exists():
            print(f"  {name:30s} (no file {path})")
            continue
        rig = load_rig(path)
        for key, value in changes.items():
            rig = rig.set(key, value)
        cells = []
        for k in ("off", "M42", "M42+M45"):
            sim, r = variant(rig, cav, k)
            res = sim.run(r, solver="compiled")
            lows = {s: float(res[s].min()) for s in watched_pressures(res)}
            low = min(lows, key=lows.get)
            cells.append(f"{lows[low] / 1e3:10.2f} ({low})")
        print(f"  {name:30s} " + "  ".join(cells))


if __name__ == "__main__":
    main()
