"""Issues 25/30: the CVODES path (``solver="cvodes"``: no C compiler, or a first run while the
compiled library builds) on the ODE against the network cut open at its interface signals
(``hydroline.engine.backends.CUT_OPEN``: SUNDIALS IDAS on the index-1 DAE, the compiled
core's bordered structure), the default rig with the cavity model "off" and on (M42 + M45).

Prints, per rig and path: steps, f and Jacobian evaluations, the integration CPU (median of
interleaved repeats of ``Simulation.run`` with the model built once, default tolerances), the
largest deviation of the port pressures and the piston position from a tight reference (the
ODE on CVODES at rtol 1e-10) over their excursion, the worst port metric's deviation, and
the Jacobian's nonzeros; then the CPU of a whole cold `hydroline simulate --json` (empty
cache: the run goes to this path while the library builds in the background).

Usage: python benchmarks/bench_cvodes_path.py [--repeat 9] [--cold 3]
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
from pathlib import Path

import numpy as np

from hydroline.engine import backends
from hydroline.rigs import load_rig
from hydroline.scenarios.running import Simulation
from hydroline.scenarios.summaries import summarize

TRACES = ("supply_port_pressure", "return_port_pressure", "piston_position")
METRICS = ("frequency_hz", "amplitude_mpa", "first_excursion_mpa", "settling_time_s")


def rig_of(kind):
    """The default rig with the cavity model "off" or on (5 kPa)."""
    rig = copy.deepcopy(load_rig(None))
    return rig.set("fluid.cavity_pressure", "off" if kind == "off" else "5 kPa")


def run(sim, rig, cut, **kw):
    """One CVODES-path run on the ODE (cut False) or cut open (True)."""
    saved, backends.CUT_OPEN = backends.CUT_OPEN, cut
    try:
        return sim.run(rig, solver="cvodes", **kw)
    finally:
        backends.CUT_OPEN = saved


def jacobian_nonzeros(rig, cut):
    """Nonzeros of the Jacobian the path factorises: d(dz/dt)/dz, or the DAE's in (z, v)."""
    import casadi as ca

    from hydroline.scenarios import build_scenario
    from hydroline.system import build_network

    sc = build_scenario(rig, "open-loop-step")
    net = build_network(rig, sc.commands, sc.position_guess)
    saved, backends.CUT_OPEN = backends.CUT_OPEN, cut
    try:
        d = backends.CvodesBackend(net, 1e-6, 1e-7).dae
    finally:
        backends.CUT_OPEN = saved
    if "z" not in d:
        return ca.jacobian(d["ode"], d["x"]).nnz()
    return ca.jacobian(ca.vertcat(d["ode"], d["alg"]), ca.vertcat(d["x"], d["z"])).nnz()


def cold_cpu(kind, cut):
    """CPU [s] (own and waited children) and wall [s] of `hydroline simulate --json` in a
    fresh process with an empty cache."""
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "rig.toml"
        text = '"off"' if kind == "off" else '"5 kPa"'
        f.write_text(f'[rig]\nbase = "default"\n[fluid]\ncavity_pressure = {text}\n')
        env = {**os.environ, "HYDROLINE_CACHE_DIR": str(Path(d) / "cache")}
        code = ("import sys, hydroline.engine.backends as b; b.CUT_OPEN = " + repr(cut) + "; "
                "from hydroline.cli import main; sys.exit(main(sys.argv[1:]))")
        before, tic = os.times(), time.perf_counter()
        subprocess.run([sys.executable, "-c", code, "simulate", str(f), "--json"], env=env,
                       check=True, capture_output=True)
        wall, after = time.perf_counter() - tic, os.times()
    return (after.children_user + after.children_system - before.children_user
            - before.children_system), wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=9)
    ap.add_argument("--cold", type=int, default=3)
    a = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}")
    for kind in ("off", "M42+M45"):
        rig = rig_of(kind)
        ref = run(Simulation(), rig, False, rtol=1e-10, atol_scale=1e-11)
        ref_sum = summarize(ref)
        sims = {cut: Simulation() for cut in (False, True)}
        first = {cut: run(sims[cut], rig, cut) for cut in sims}
        cpu = {cut: [] for cut in sims}
        for _ in range(a.repeat):
            for cut in sims:
                tic = time.process_time()
                run(sims[cut], rig, cut)
                cpu[cut].append(time.process_time() - tic)
        base = statistics.median(cpu[False])
        for cut, res in first.items():
            trace = max(np.abs(np.interp(ref.t, res.t, res[k]) - ref[k]).max() / np.ptp(ref[k])
                        for k in TRACES)
            s = summarize(res)
            metric = max(abs(s[port][m] / ref_sum[port][m] - 1) for port in ("supply", "return")
                         for m in METRICS if ref_sum[port][m])
            c = statistics.median(cpu[cut])
            print(f"{kind:8s} {'cut open (IDAS)' if cut else 'ODE (CVODES)':16s} "
                  f"steps {res.stats['nsteps']:5d} f {res.stats['nfevals']:5d} "
                  f"J {res.stats['njevals']:4d}  CPU {c * 1e3:7.1f} ms ({c / base - 1:+.0%})  "
                  f"traces {trace:.1e}  metrics {metric:.1e}  "
                  f"J nonzeros {jacobian_nonzeros(rig, cut)}")
    for kind in ("off", "M42+M45"):
        for cut in (False, True):
            runs = [cold_cpu(kind, cut) for _ in range(a.cold)]
            print(f"cold simulate --json {kind:8s} {'cut open' if cut else 'ODE':8s} CPU "
                  + " ".join(f"{c:.2f}" for c, _ in runs) + " s, wall "
                  + " ".join(f"{w:.2f}" for _, w in runs) + " s")
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
