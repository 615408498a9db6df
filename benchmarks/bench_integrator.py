"""Benchmark: integrator candidates of the compiled core on the default scenario (issue 13 item 4).

Each candidate is the C core (``hydroline/compiled/bdf.c``) built with other compile-time
settings (``-DHL_DGMAX=...`` etc.: when W = I - cJ is refactored, when a step-size change is
taken) or other tolerances, in its own process and cache directory. Per candidate: accepted
steps, f evaluations, LU factorizations, rejected steps, the largest error of the valve port
pressures and piston velocity against a CVODES rtol 1e-10 reference (% of each signal's
excursion), and the integration's CPU time per run (min and median of ``--repeat`` runs after
a warm-up), with its ratio to the baseline measured right before it (a busy machine drifts:
only the ratio in one pair is meaningful).

Usage: python benchmarks/bench_integrator.py [--repeat 60] [--only baseline,dgmax-0.6]
       [--scenario closed-loop-sine]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

#: (label, extra C flags, rtol, atol_scale): the settings measured before choosing
CANDIDATES = [
    ("baseline", [], 1e-6, 1e-7),
    ("dgmax-0.6", ["-DHL_DGMAX=0.6"], 1e-6, 1e-7),        # refactor W less often
    ("dgmax-1.0", ["-DHL_DGMAX=1.0"], 1e-6, 1e-7),
    ("msbp-200", ["-DHL_MSBP=200"], 1e-6, 1e-7),          # fresh Jacobian less often
    ("msbp-20", ["-DHL_MSBP=20"], 1e-6, 1e-7),
    ("threshold-1.05", ["-DHL_STEP_THRESHOLD=1.05"], 1e-6, 1e-7),   # take small step increases
    ("threshold-1.5", ["-DHL_STEP_THRESHOLD=1.5"], 1e-6, 1e-7),
    ("atol-1e-6", [], 1e-6, 1e-6),                         # looser absolute tolerance
    ("rtol-3e-6", [], 3e-6, 1e-7),
    # round 3: fewer rejected steps (7 % on the step, 11-13 % on the sine)
    ("safety-0.85", ["-DHL_SAFETY=0.85"], 1e-6, 1e-7),    # every step-size choice 0.85 x (0.9)
    ("safety-0.8", ["-DHL_SAFETY=0.8"], 1e-6, 1e-7),
    ("early-0.8", ["-DHL_EARLY=0.8"], 1e-6, 1e-7),        # shrink before q+1 equal steps
    ("max-factor-2", ["-DHL_MAX_FACTOR=2"], 1e-6, 1e-7),  # at most 2x per increase (10x)
    ("safety-0.75", ["-DHL_SAFETY=0.75"], 1e-6, 1e-7),
    ("safety-0.8+rtol-1.5e-6", ["-DHL_SAFETY=0.8"], 1.5e-6, 1e-7),   # the accuracy spent
    ("safety-0.8+rtol-2e-6", ["-DHL_SAFETY=0.8"], 2e-6, 1e-7),
    ("fma", ["-ffp-contract=fast"], 1e-6, 1e-7),
    ("dgmax-0.5", ["-DHL_DGMAX=0.5"], 1e-6, 1e-7),   # (again, after safety 0.8)   # a*b+c as one fused multiply-add (-std=c99: off)
]

CHILD = r"""
import json, sys, time
import numpy as np
from hydroline import compiled
compiled.CFLAGS += {flags!r}
from hydroline.rigs import load_rig
from hydroline.scenarios import build_scenario
from hydroline.simulation import integrate, solve_steady_state
from hydroline.system import build_network
rig = load_rig(None)
sc = build_scenario(rig, {scenario!r})
net = build_network(rig, sc.commands, sc.position_guess)
ss = solve_steady_state(net)
keys = ("supply_port_pressure", "return_port_pressure", "piston_velocity")
ref = np.load({ref!r})
out = {{}}
try:
    cpu = []
    for _ in range({repeat} + 1):
        t = time.process_time()
        r = integrate(net, ss.x, sc.t_end, p=ss.p, solver="compiled", rtol={rtol!r},
                      atol_scale={atol!r})
        cpu.append(time.process_time() - t)
    err = max(np.max(np.abs(r[k] - ref[k])) / np.ptp(ref[k]) for k in keys) * 100
    out = dict(r.stats, err=err, cpu_min=min(cpu[1:]), cpu_med=float(np.median(cpu[1:])))
    out.pop("build_time", None)
except RuntimeError as e:
    out = dict(failed=str(e)[:80])
print(json.dumps(out))
"""


def reference(path, scenario="open-loop-step"):
    """The CVODES rtol 1e-10 reference of the three compared signals, saved as .npz."""
    import numpy as np

    from hydroline.rigs import load_rig
    from hydroline.scenarios import build_scenario
    from hydroline.simulation import integrate, solve_steady_state
    from hydroline.system import build_network

    rig = load_rig(None)
    sc = build_scenario(rig, scenario)
    net = build_network(rig, sc.commands, sc.position_guess)
    ss = solve_steady_state(net)
    r = integrate(net, ss.x, sc.t_end, p=ss.p, rtol=1e-10, atol_scale=1e-10, solver="cvodes")
    np.savez(path, **{k: r[k] for k in ("supply_port_pressure", "return_port_pressure",
                                         "piston_velocity")})


def run(label, flags, rtol, atol, repeat, ref, tmp, scenario="open-loop-step"):
    env = dict(os.environ, HYDROLINE_CACHE_DIR=os.path.join(tmp, "cache-" + label))
    code = CHILD.format(flags=flags, ref=ref, repeat=repeat, rtol=rtol, atol=atol,
                        scenario=scenario)
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        return dict(failed=proc.stderr.strip().splitlines()[-1][:80])
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=60, help="runs per candidate (after a warm-up)")
    ap.add_argument("--only", help="comma-separated labels")
    ap.add_argument("--scenario", default="open-loop-step",
                    help="experiment at its default duration (open-loop-step; closed-loop-sine)")
    args = ap.parse_args(argv)
    chosen = [c for c in CANDIDATES if not args.only or c[0] in args.only.split(",")]
    head = ["candidate", "rtol", "atol", "steps", "f evals", "LU", "rejected", "max err [%]",
            "CPU min [ms]", "CPU median [ms]", "CPU / baseline"]
    rows, notes = [], []
    with tempfile.TemporaryDirectory() as tmp:
        ref = os.path.join(tmp, "ref.npz")
        reference(ref, args.scenario)
        for label, flags, rtol, atol in chosen:
            base = run("baseline", [], 1e-6, 1e-7, args.repeat, ref, tmp, args.scenario)
            got = base if label == "baseline" else run(label, flags, rtol, atol, args.repeat, ref,
                                                       tmp, args.scenario)
            if "failed" in got:
                notes.append(f"{label}: {got['failed']}")
                rows.append([label, f"{rtol:g}", f"{atol:g}", "failed"] + ["-"] * (len(head) - 4))
                continue
            rows.append([label, f"{rtol:g}", f"{atol:g}", got["nsteps"], got["nfevals"], got["nlu"],
                         got["nrejected"], f"{got['err']:.2e}", f"{got['cpu_min'] * 1e3:.2f}",
                         f"{got['cpu_med'] * 1e3:.2f}",
                         f"{got['cpu_min'] / base['cpu_min']:.2f}x"])
    widths = [max(len(str(r[i])) for r in rows + [head]) for i in range(len(head))]
    print(f"Integrator candidates, {args.scenario} (output every 0.1 ms), one process "
          f"each; load average {os.getloadavg()[0]:.1f}; ratio = CPU min against a baseline run "
          f"just before")
    print("  ".join(h.rjust(w) for h, w in zip(head, widths)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(str(c).rjust(w) for c, w in zip(r, widths)))
    for note in notes:
        print(note)


if __name__ == "__main__":
    main()
