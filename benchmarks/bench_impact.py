"""Benchmark: what the piston's impact on its end stop costs the compiled core, per 10 ms window.

For one rig (sections II of ``--length``) and one method of the C core (``bdf``: its NDF/BDF,
``radau``: its Radau IIA) at ``--rtol`` (atol = rtol / 10 on the scaled states, as
``simulate(atol_scale=rtol/10)``), it prints per 10 ms window of the default run the CPU of
the integration (the run split at the network's breakpoints, as ``simulate`` does), the steps,
f evaluations, Jacobians, factorisations, rejected steps and Newton failures.

With ``--events`` it also bounds what event location (CVODE's rootfinding, Modelica's events
for non-smooth functions) could save at the stop's kinks: the run is restarted exactly at each
crossing of the stop's switching functions (penetration 0, where ``fmax(x - half, 0)`` kinks,
and the damping ramp's end, where ``fmin(penetration / 1e-5 m, 1)`` kinks), found from a run at
rtol 1e-10; a located event can do no better on the steps than a restart there.

Usage: python benchmarks/bench_impact.py [--method radau] [--length 0.3] [--rtol 1e-5]
       [--events]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from tables import text_table

RAMP = 1e-5     # [m] penetration over which the stop's damping engages (actuator.stop_force)


def load(length: float):
    """(network, rest state) of the default run with sections II of ``length`` [m]."""
    import hydroline
    from hydroline.scenarios.running import Simulation

    rig = hydroline.load_rig()
    if length != 3.048:
        rig = rig.set("supply.section2.length", f"{length} m").set(
            "return.section2.length", f"{length} m")
    sim = Simulation()
    ref = sim.run(rig, solver="compiled")
    (_, _, net, ss), = sim.models.values()
    return net, ss, float(ref.t[-1])


def windows(net, ss, t_end: float, method: str, rtol: float, width: float = 0.01):
    """Per-window rows: (window, CPU [ms], steps, f, J, LU, rejected, Newton failures)."""
    from hydroline import compiled
    from hydroline.engine.integrate import segments

    edges = segments(t_end, net.breakpoints(t_end))
    sol = compiled.native_model(net).solver(ss.p, rtol=rtol, atol=rtol / 10, method=method)
    sol.start(0.0, np.asarray(ss.x, float), edges[1])
    k, rows, prev = 1, [], sol.stats()
    for a in np.arange(0.0, t_end - 1e-12, width):
        grid = np.linspace(a, min(a + width, t_end), 101)[1:]
        cpu = time.process_time()
        while len(grid):
            if grid[0] > edges[k] + 1e-12:
                x, _ = sol.state()
                sol.start(edges[k], x, edges[k + 1])
                k += 1
            part = grid[grid <= edges[k] + 1e-12]
            sol.advance(part, signals=False)
            grid = grid[len(part):]
        cpu = time.process_time() - cpu
        s = sol.stats()
        d = {key: s[key] - prev[key] for key in s}
        prev = s
        rows.append((f"{a:.2f}-{a + width:.2f}", f"{cpu * 1e3:.2f}", d["nsteps"], d["nfevals"],
                     d["njevals"], d["nlu"], d["nrejected"], d["nnewton_fail"]))
    return rows


def stop_crossings(net, ss, t_end: float) -> list:
    """Times [s] at which the piston's penetration into its top stop crosses 0 and RAMP."""
    from hydroline import compiled

    names = list(net.state_names)
    ix = names.index("actuator.position")
    half = net.component("actuator").stroke / 2
    model = compiled.native_model(net)
    tight = model.solver(ss.p, rtol=1e-10, atol=1e-11, method="bdf")
    tight.start(0.0, np.asarray(ss.x, float), t_end)
    t = np.arange(1e-5, t_end, 1e-5)
    X, _ = tight.advance(t, signals=False)
    out = []
    for level in (0.0, RAMP):
        g = X[:, ix] - half - level
        for i in np.nonzero(np.sign(g[1:]) != np.sign(g[:-1]))[0]:
            # the crossing to ~1e-9 s: the 10 us around it again, 5 000 rows
            fine = model.solver(ss.p, rtol=1e-10, atol=1e-11, method="bdf")
            fine.start(t[i], X[i], t[i + 1])
            tf = np.linspace(t[i], t[i + 1], 5001)[1:]
            gf = fine.advance(tf, signals=False)[0][:, ix] - half - level
            j = int(np.nonzero(np.sign(gf) != np.sign(g[i]))[0][0])
            t0, g0 = (tf[j - 1], gf[j - 1]) if j else (t[i], g[i])
            out.append(t0 - g0 * (tf[j] - t0) / (gf[j] - g0))
    return sorted(out)


def restarted_run(net, ss, t_end: float, method: str, rtol: float, restarts: list):
    """(CPU [s], stats) of the whole run restarted at each time of ``restarts``."""
    from hydroline import compiled

    sol = compiled.native_model(net).solver(ss.p, rtol=rtol, atol=rtol / 10, method=method)
    bounds = sorted(set(restarts) | set(net.breakpoints(t_end)) | {t_end})
    grid = np.arange(1e-4, t_end + 1e-12, 1e-4)
    t0, x = 0.0, np.asarray(ss.x, float)
    cpu = time.process_time()
    for b in (b for b in bounds if 0 < b <= t_end):
        sol.start(t0, x, b)
        part = grid[(grid > t0) & (grid <= b)]
        if len(part):
            sol.advance(part, signals=False)
        x, t0 = sol.state()
    return time.process_time() - cpu, sol.stats()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", choices=("bdf", "radau"), default="radau")
    ap.add_argument("--length", type=float, default=0.3, help="sections II [m] (3.048: default)")
    ap.add_argument("--rtol", type=float, default=1e-5)
    ap.add_argument("--events", action="store_true", help="also the restarts at the stop's kinks")
    args = ap.parse_args(argv)
    net, ss, t_end = load(args.length)
    rows = windows(net, ss, t_end, args.method, args.rtol)
    print(f"{args.method}, sections II {args.length:g} m, rtol {args.rtol:g}, per 10 ms window")
    print(text_table(("window [s]", "CPU [ms]", "steps", "f", "J", "LU", "rejected",
                      "Newton failures"), rows))
    if args.events:
        kinks = stop_crossings(net, ss, t_end)
        print("stop kinks at " + ", ".join(f"{k * 1e3:.4f}" for k in kinks) + " ms")
        for label, restarts in (("plain", []), ("restarted at the kinks", kinks)):
            cpu, s = min((restarted_run(net, ss, t_end, args.method, args.rtol, restarts)
                          for _ in range(5)), key=lambda r: r[0])
            print(f"{label:24s} CPU {cpu * 1e3:6.2f} ms  steps {s['nsteps']}  f {s['nfevals']}  "
                  f"J {s['njevals']}  LU {s['nlu']}  rejected {s['nrejected']}  "
                  f"Newton failures {s['nnewton_fail']}")


if __name__ == "__main__":
    main()
