"""How the default rig (hydroline/rigs/ayalew2005.toml) is calibrated, and how firmly.

Run by hand: ``python tools/calibrate_ayalew2005.py [--sensitivities-only] [--line-method M]``
(about 20 s for the calibration, a minute or two for the elasticities). ``--line-method
yang-tobler`` calibrates the paper's line instead of the default exact-pole line (what
``hydroline/rigs/ayalew2005_yang_tobler.toml`` holds).

Targets: the 2005 paper's open-loop baseline (the model reference, section 7): supply-port
oscillation 40 Hz / 1.0 MPa, return port 31 Hz / 0.94 MPa, after a 50 mA step, with the
amplitude of :func:`hydroline.analysis.oscillation_amplitude` (two-sided, about the drifting
baseline) over the metrics window of :func:`hydroline.scenarios.metrics_window`.

Four calibrated values, one per target, found together by a fixed-point iteration:

* the hoses' effective bulk modulus (sections I and II equal), per side, sets the wave speed
  c = sqrt(beta / rho) (M2), hence the quarter-wave frequency: ``beta <- beta (f_target / f)^2``;
* the hoses' bore, per side, sets the characteristic impedance Z0 = rho c / A (M3), hence the
  water-hammer swing Z0 * dQ that the step starts: ``d <- d sqrt(a / a_target)``.

Then the elasticities ``d ln(target) / d ln(value)`` of every target to every calibrated and
assumed value (central differences, +-5 %), which the rig file quotes: a value whose
elasticities are all small cannot be pinned by these targets and is marked [assumed].
"""
from __future__ import annotations

import argparse
import math

import hydroline
from hydroline.rigs import SCHEMA

TARGETS = {"supply_frequency_hz": 40.0, "supply_amplitude_mpa": 1.0,
           "return_frequency_hz": 31.0, "return_amplitude_mpa": 0.94}
SIDES = ("supply", "return")


def measure(rig) -> dict:
    s = hydroline.summarize(hydroline.simulate(rig, "open-loop-step"))
    return {f"{side}_{k}": s[side][k] for side in SIDES for k in ("frequency_hz", "amplitude_mpa")}


def unit(path):
    section, key = path.rsplit(".", 1)
    return SCHEMA.get(section, {}).get(key, "")


def set_side(rig, side, key, value):
    for section in (1, 2):
        path = f"{side}.section{section}.{key}"
        rig.set(path, f"{value!r} {unit(path)}")


def calibrate(rig, iterations=8, tol=1e-3):
    for k in range(iterations):
        m = measure(rig)
        err = max(abs(m[key] / v - 1) for key, v in TARGETS.items())
        print(f"  iteration {k}: " + ", ".join(f"{key} {m[key]:.4g}" for key in TARGETS)
              + f"  (largest error {err:.2%})")
        if err < tol:
            break
        for side in SIDES:
            beta = rig[f"{side}.section2.bulk_modulus"] * (TARGETS[f"{side}_frequency_hz"]
                                                           / m[f"{side}_frequency_hz"]) ** 2
            d = rig[f"{side}.section2.diameter"] * math.sqrt(m[f"{side}_amplitude_mpa"]
                                                             / TARGETS[f"{side}_amplitude_mpa"])
            set_side(rig, side, "bulk_modulus", beta)
            set_side(rig, side, "diameter", d)
    return rig


CALIBRATED = ("supply.section*.bulk_modulus", "supply.section*.diameter",
              "return.section*.bulk_modulus", "return.section*.diameter")
OTHERS = ("supply.manifold.resistance", "return.manifold.resistance",
          "supply.accumulator.capacity", "supply.accumulator.precharge_pressure",
          "return.accumulator.capacity", "return.pressure", "fluid.kinematic_viscosity",
          "fluid.density", "servovalve.rated_pressure_drop", "actuator.moving_mass",
          "actuator.bulk_modulus")


def elasticities(rig, rel=0.05):
    rows = {}
    for name in CALIBRATED + OTHERS:
        res = []
        for f in (1 - rel, 1 + rel):
            variant = rig.copy()
            if "*" in name:
                side, key = name.split(".section*.")
                set_side(variant, side, key, rig[f"{side}.section2.{key}"] * f)
            else:
                variant.set(name, f"{rig[name] * f!r} {unit(name)}")
            res.append(measure(variant))
        rows[name] = {key: (math.log(res[1][key] / res[0][key]) / math.log((1 + rel) / (1 - rel)))
                      for key in TARGETS}
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sensitivities-only", action="store_true")
    ap.add_argument("--line-method", default=None,
                    help="rig.line_method to calibrate (default: the rig's, the exact-pole line)")
    args = ap.parse_args(argv)
    rig = hydroline.load_rig()
    if args.line_method:
        rig.set("rig.line_method", args.line_method)
    if not args.sensitivities_only:
        print("calibrating the four values to the four targets:")
        calibrate(rig)
        for side in SIDES:
            print(f"  {side}: bulk_modulus = {rig[f'{side}.section2.bulk_modulus'] / 1e6:.1f} MPa, "
                  f"diameter = {rig[f'{side}.section2.diameter'] * 1e3:.2f} mm")
    print("\nelasticities d ln(target) / d ln(value), +-5 % central differences:")
    rows = elasticities(rig)
    print(f"{'value':40s}" + "".join(f"{k:>22s}" for k in TARGETS))
    for name, row in rows.items():
        print(f"{name:40s}" + "".join(f"{row[k]:22.3f}" for k in TARGETS))


if __name__ == "__main__":
    main()
