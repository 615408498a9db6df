"""Do the bode readings move continuously with the supply hose? Fine sweeps of the supply
section II length and bulk modulus (the hose whose quarter wave, c/4L with the manifold
accumulator as the open end, puts a notch into the piston velocity near -3 dB at rated
flow): the first -3 dB crossing and the "gain within 3 dB up to" frequency at each value,
and every jump between neighbours larger than ``JUMP`` with whether the output stated the
notch that causes it (a first crossing in a notch on one side and not on the other, or a
note naming a notch or peak within 0.5 dB of -3 dB).

    python benchmarks/bandwidth_sweep.py [line_method] [points]

line_method: the rig's (default) or e.g. residue, yang-tobler; points per sweep (default 41).
"""
import sys
import time

import numpy as np

from hydroline.analysis import OperatingPoint, bode_analysis
from hydroline.analysis.frequency import MODAL, rated_velocity
from hydroline.rigs import load_rig

#: A change between neighbours larger than this (relative) is a jump, [-].
JUMP = 0.05


def readings(rig, f):
    op = OperatingPoint(0.0, rated_velocity(rig))
    res = bode_analysis(rig, op, "valve_current", ["piston_velocity"], f, compare=False, exact=False)
    return res.passbands[MODAL]["piston_velocity"]


def sweep(name, values, method, f):
    print(f"\n{name} ({method or 'the rig default'} line)")
    print(f"{'value':>12} {'first [Hz]':>16} {'within 3 dB to [Hz]':>20}  note")
    rows = []
    for v in values:
        rig = load_rig()
        if method:
            rig.set("rig.line_method", method)
        rig.set(name, v)
        b = readings(rig, f)
        rows.append(b)
        first = "-" if b.first_crossing_hz is None else f"{b.first_crossing_hz:.2f}"
        first += " (notch)" if b.in_notch else ""
        within = "-" if b.within_3db_up_to_hz is None else f"{b.within_3db_up_to_hz:.2f}"
        print(f"{v:>12} {first:>16} {within:>20}  {'notch near -3 dB stated' if b.note else ''}")
    unstated = 0
    for k in range(1, len(rows)):
        a, b = rows[k - 1], rows[k]
        for key in ("first_crossing_hz", "within_3db_up_to_hz"):
            x, y = getattr(a, key), getattr(b, key)
            if x is None or y is None:
                continue
            if abs(y - x) > JUMP * min(x, y):
                stated = bool(a.note or b.note) or a.in_notch != b.in_notch
                unstated += not stated
                print(f"  {key} jumps {x:.2f} -> {y:.2f} Hz between {values[k - 1]} and "
                      f"{values[k]}: {'stated' if stated else 'NOT STATED'}")
    return unstated


def main(method=None, n=41):
    f = np.logspace(np.log10(5.0), np.log10(400.0), 800)
    tic = time.perf_counter()
    bad = sweep("supply.section2.length", [f"{x:.4f} m" for x in np.linspace(2.6, 3.5, n)], method, f)
    bad += sweep("supply.section2.bulk_modulus", [f"{x:.1f} MPa" for x in np.linspace(170, 220, n)],
                 method, f)
    print(f"\n{bad} unstated jump(s); {time.perf_counter() - tic:.0f} s")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 and sys.argv[1] != "default" else None,
         int(sys.argv[2]) if len(sys.argv) > 2 else 41)
