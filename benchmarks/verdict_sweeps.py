"""Issue 23 item 4: the port metrics' verdicts over the fine sweeps, run whole.

Sweeps (on the default rig with the exact-pole line and Merritt's actuator pair, 689 MPa and
7.95 kg, where the issue saw the flicker; ``--rig-as-is`` keeps the rig as it is):

* sections II 0.05-0.8 m in 1 cm steps (both sides);
* the piston's viscous friction x1-x20 and the moving mass x0.25-x4 (geometric steps), at
  sections II of 0.7512 m and 3.048 m.

Between neighbours it checks the issue's done-when: the amplitude moves by no more than the
traces' own max |dp| (over the common metrics window) plus 10 kPa, and no "no oscillation"
beside an amplitude above 0.05 MPa. It prints one line per variant (frequency, amplitude and
settling time per port, and the near-verdict notes) and, per sweep, the violations, the worst
neighbour jump (how far |dA| lies above or below the traces' max |dp| + 10 kPa) and the
largest amplitude beside a 'no oscillation'. No assertions; ``tests/test_settling_verdicts.py``
checks a few of these neighbours in the suite.

Usage::

    python benchmarks/verdict_sweeps.py [--steps 21] [--only length,friction,mass] [--rig-as-is]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import hydroline
from hydroline.scenarios import summarize

SIDES = ("supply", "return")


def _rig(as_is):
    rig = hydroline.load_rig()
    if not as_is:
        rig.set("rig.line_method", "residue")
        rig.set("actuator.bulk_modulus", "689 MPa")
        rig.set("actuator.moving_mass", "7.95 kg")
    return rig


def _lengths(L):
    return {"supply.section2.length": f"{L:.4g} m", "return.section2.length": f"{L:.4g} m"}


def sweeps(steps, base_mass):
    """Sweep name -> list of (label, changes)."""
    out = {"length": [(f"L={L:.2f} m", _lengths(L)) for L in np.arange(0.05, 0.8001, 0.01)]}
    for L in (0.7512, 3.048):
        out[f"friction@{L:g}m"] = [
            (f"friction x{x:.3g}", {**_lengths(L), "friction.viscous_up": f"{800 * x:.6g} N*s/m",
                                    "friction.viscous_down": f"{800 * x:.6g} N*s/m"})
            for x in np.geomspace(1, 20, steps)]
        out[f"mass@{L:g}m"] = [
            (f"mass x{x:.3g}", {**_lengths(L), "actuator.moving_mass": f"{base_mass * x:.6g} kg"})
            for x in np.geomspace(0.25, 4, steps)]
    return out


def run(rig, changes):
    variant = rig.copy()
    for k, v in changes.items():
        variant.set(k, v)
    res = hydroline.simulate(variant)
    keep = res.t <= res.metadata["metrics_window"][1]
    return summarize(res), {s: res[f"{s}_port_pressure"][keep] for s in SIDES}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=21, help="points of the friction and mass sweeps")
    ap.add_argument("--only", default="length,friction,mass",
                    help="comma-separated: length, friction, mass")
    ap.add_argument("--rig-as-is", action="store_true",
                    help="the default rig as it is (no residue line, no Merritt pair)")
    args = ap.parse_args()
    rig = _rig(args.rig_as_is)
    base_mass = rig["actuator.moving_mass"]
    wanted = args.only.split(",")
    total = 0
    tic = time.perf_counter()
    for name, variants in sweeps(args.steps, base_mass).items():
        if not any(name.startswith(w) for w in wanted):
            continue
        print(f"\n== {name} ({len(variants)} variants)")
        previous, bad, near = None, [], 0
        worst = None        # (excess of |dA| over dp + 10 kPa [MPa], description)
        beside = None       # (largest amplitude beside 'no oscillation' [MPa], description)
        for label, changes in variants:
            s, traces = run(rig, changes)
            cells = []
            for side in SIDES:
                m = s[side]
                f = "-" if m["frequency_hz"] is None else f"{m['frequency_hz']:.0f} Hz"
                a = "-" if m["amplitude_mpa"] is None else f"{m['amplitude_mpa']:.3f}"
                ts = "-" if m["settling_time_s"] is None else \
                    f"{'~' if m['settling_method'] == 'estimated' else ''}{m['settling_time_s'] * 1e3:.0f} ms"
                flag = " (near verdict)" if "near the 'no oscillation'" in m["amplitude_note"] else ""
                near += bool(flag)
                cells.append(f"{side} {f:>8} {a:>6} MPa {ts:>8}{flag}")
            print(f"  {label:>16}  " + "  |  ".join(cells))
            if previous is not None:
                s0, tr0, label0 = previous
                for side in SIDES:
                    a0, a1 = s0[side]["amplitude_mpa"], s[side]["amplitude_mpa"]
                    n = min(tr0[side].size, traces[side].size)
                    dp = float(np.max(np.abs(traces[side][:n] - tr0[side][:n]))) / 1e6
                    if a0 is not None and a1 is not None:
                        jump = (f"{label0} -> {label} {side}: amplitude {a0:.3f} -> {a1:.3f} MPa, "
                                f"traces differ by {dp:.3f} MPa")
                        excess = abs(a1 - a0) - (dp + 0.01)
                        if worst is None or excess > worst[0]:
                            worst = (excess, jump)
                        if excess > 0:
                            bad.append(jump)
                    for quiet, other in ((s0, s), (s, s0)):
                        if quiet[side]["frequency_hz"] is None:
                            a = other[side]["amplitude_mpa"] or 0.0
                            if beside is None or a > beside[0]:
                                beside = (a, f"{label0} / {label} {side}")
                            if a > 0.05:
                                bad.append(f"{label0} / {label} {side}: 'no oscillation' beside "
                                           f"{a:.3f} MPa")
            previous = (s, traces, label)
        total += len(bad)
        print(f"  -> {len(bad)} violations; {near} port readings flagged near the verdict")
        if worst is not None:
            print(f"     worst neighbour jump: |dA| {worst[0] * 1e3:+.1f} kPa over (dp + 10 kPa): "
                  f"{worst[1]}")
        if beside is not None:
            print(f"     largest amplitude beside 'no oscillation': {beside[0]:.3f} MPa "
                  f"({beside[1]})")
        for line in bad:
            print(f"     {line}")
    print(f"\n{total} violations in all ({time.perf_counter() - tic:.0f} s)")


if __name__ == "__main__":
    main()
