"""How much bandwidth do the hoses cost? -3 dB bandwidth of piston velocity per valve current
against the operating velocity, modal lines, exact lines (M6) and ideal constant supply.

At rest an underlapped valve draws the same supply flow whichever way the spool moves (to
first order), so the hoses hardly matter; with flow through the valve the supply and return
line resonances enter the plant, and at high flow the first line resonance becomes the
bandwidth limit (the 2005 paper's point). Where the piston velocity's response rises more
than 3 dB above its low-frequency gain (at rest: the 172 Hz actuator resonance, +16 dB) it is
resonant, not low-pass, and has no -3 dB bandwidth ('-'; bode_analysis notes why).

    /tmp/venv/bin/python benchmarks/bandwidth_vs_flow.py
"""
import time

import numpy as np

from hydroline.analysis import OperatingPoint, bode_analysis
from hydroline.analysis.frequency import CONSTANT, EXACT, MODAL, rated_velocity
from hydroline.rigs import load_rig


def _hz(band):
    """The two -3 dB readings [Hz], first crossing ('*': in a notch) / within 3 dB up to, or
    '-' where the response is resonant (not low-pass) and has none."""
    if band is None:
        return "-"
    first = "-" if band.first_crossing_hz is None else f"{band.first_crossing_hz:.1f}"
    within = "-" if band.within_3db_up_to_hz is None else f"{band.within_3db_up_to_hz:.1f}"
    return f"{first}{'*' if band.in_notch else ''}/{within}"


def main():
    rig = load_rig()
    f = np.logspace(0, np.log10(500.0), 1500)
    v_rated = rated_velocity(rig)
    print(f"rated-flow velocity Q_N/A_b = {v_rated:.3f} m/s; piston at mid-stroke, moving up")
    print("-3 dB readings: first crossing ('*': in a notch) / gain within 3 dB up to, [Hz]")
    print(f"{'v [m/s]':>8} {'i [mA]':>7} {'modal':>13} {'exact':>13} {'constant':>14} {'wall [s]':>9}")
    for v in (0.0, 0.2, 0.4, 0.6, v_rated, 0.7, 0.75, 0.8, 0.9):
        tic = time.perf_counter()
        res = bode_analysis(rig, OperatingPoint(0.0, v), "valve_current", ["piston_velocity"], f)
        bw = {k: res.passbands[k].get("piston_velocity") for k in (MODAL, EXACT, CONSTANT)}
        print(f"{v:8.3f} {res.operating_points[MODAL].valve_current * 1e3:7.2f} {_hz(bw[MODAL]):>13} "
              f"{_hz(bw[EXACT]):>13} {_hz(bw[CONSTANT]):>14} {time.perf_counter() - tic:9.2f}")


if __name__ == "__main__":
    main()
