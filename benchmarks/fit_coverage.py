"""Do the confidence intervals of ``hydroline fit`` mean what they say? (Monte Carlo)

Records made by the model with known parameters plus white noise, fitted from the default
rig's values, many noise seeds: the standardised errors z = (ln est - ln truth)/se should
have mean ~0 and standard deviation ~1, and the 95 % intervals should cover the truth in
about 95 % of the records (binomial standard error sqrt(0.05*0.95/n)).

    /tmp/venv/bin/python benchmarks/fit_coverage.py [n_seeds] [case substring]
"""
import sys
import time

import numpy as np
import pandas as pd

from hydroline.analysis.fit import Measurements, fit_parameters, simulate_record
from hydroline.rigs import load_rig

CASES = {
    "open-loop rated step from the stop; section II bulk moduli; port pressures 20 kPa": dict(
        truth={"supply.section2.bulk_modulus": ("200e6 Pa", 200e6),
               "return.section2.bulk_modulus": ("160e6 Pa", 160e6)},
        current=lambda t: np.where(t >= 0.01, 0.05, 0.0), t_end=0.06, start="rest", x0=None,
        noise={"supply_port_pressure": 2e4, "return_port_pressure": 2e4}),
    "held at -20 mm, 5 mA step; manifold loss, viscous friction up; p_S 20 kPa, x_p 10 um": dict(
        truth={"supply.manifold.resistance": ("1.5e9 Pa*s/m^3", 1.5e9),
               "friction.viscous_up": ("1000 N*s/m", 1000.0)},
        current=lambda t: np.where(t >= 0.01, 5e-3, 0.0), t_end=0.06, start="hold", x0=-0.02,
        noise={"supply_port_pressure": 2e4, "piston_position": 1e-5}),
    "open-loop rated step from the stop; supply accumulator pre-charge; p_S 20 kPa": dict(
        truth={"supply.accumulator.precharge_pressure": ("8 MPa", 8e6)},
        current=lambda t: np.where(t >= 0.01, 0.05, 0.0), t_end=0.06, start="rest", x0=None,
        noise={"supply_port_pressure": 2e4}),
    "held at +40 mm, -2 then -10 mA; friction down (viscous, Coulomb); p_b, p_t 20 kPa, x_p 10 um": dict(
        truth={"friction.viscous_down": ("750 N*s/m", 750.0),
               "friction.coulomb_down": ("40 N", 40.0)},
        current=lambda t: np.where(t >= 0.04, -10e-3, np.where(t >= 0.01, -2e-3, 0.0)),
        t_end=0.07, start="hold", x0=0.04,
        noise={"bottom_chamber_pressure": 2e4, "top_chamber_pressure": 2e4, "piston_position": 1e-5}),
}


def record(case, seed):
    truth = load_rig()
    for k, (text, _) in case["truth"].items():
        truth.set(k, text)
    t = np.arange(0.0, case["t_end"] + 1e-12, 1e-4)
    cols = {"time": t, "valve_current": case["current"](t)}
    cols.update({k: np.full_like(t, case["x0"] or 0.0) for k in case["noise"]})
    meas = Measurements(pd.DataFrame(cols), "synthetic")
    y = simulate_record(truth, meas, list(case["noise"]), start=case["start"])
    rng = np.random.default_rng(seed)
    for k, s in case["noise"].items():
        meas.data[k] = y[k] + rng.normal(0.0, s, len(t))
    return meas


def main(n=40, only=None):
    rig = load_rig()
    print(f"{'case':<92} {'parameter':<37} {'mean z':>7} {'std z':>6} {'95% cover':>9} {'s/fit':>6}")
    for label, case in CASES.items():
        if only and only not in label:
            continue
        names = list(case["truth"])
        truth = np.array([case["truth"][k][1] for k in names])
        zs, tic = [], time.perf_counter()
        for seed in range(n):
            res = fit_parameters(rig, record(case, seed), names)
            zs.append((np.log(res.estimate) - np.log(truth)) / res.std_log)
        wall = (time.perf_counter() - tic) / n
        zs = np.array(zs)
        for j, k in enumerate(names):
            print(f"{label:<92} {k:<37} {zs[:, j].mean():7.2f} {zs[:, j].std():6.2f} "
                  f"{np.mean(np.abs(zs[:, j]) < 1.96):9.0%} {wall:6.2f}")
    print(f"(n = {n} seeds; binomial standard error of the coverage {np.sqrt(0.05 * 0.95 / n):.1%})")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 40, sys.argv[2] if len(sys.argv) > 2 else None)
