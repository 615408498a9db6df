"""
(e) Calibrating bulk moduli and friction from measured data
===========================================================

The hoses' effective bulk modulus (oil, hose wall and entrained air together, section 2 of
the model reference) is rarely known to better than 20 %; the piston friction (M24) even
less. Both can be estimated from records of the rig.

1. :func:`hydroline.analysis.fit_parameters`: nonlinear least squares of chosen rig
   parameters to measured port pressures after a valve step, with confidence intervals.
2. :func:`hydroline.analysis.identify_friction`: friction points by Newton's law (M23) from
   steady-velocity runs, and the Stribeck curve (M24) fitted up and down separately.

Here the "measurements" are made by the model itself with known parameters plus noise, so
we can see whether the estimates come back. With real data, read the CSV with
:func:`hydroline.analysis.read_measurements` (a header row ``name [unit]``, any units).
Run time: about 30 s. Command line: ``hydroline fit`` and ``hydroline friction-id``.
"""

# %%
# A synthetic record
# ------------------
# The "true" rig has section-II bulk moduli of 200 MPa (supply) and 160 MPa (return); the
# fit starts from the default rig's values. 60 ms after a 50 mA step, supply and return port
# pressures with 20 kPa of white sensor noise, written as a CSV with units in its header.
from pathlib import Path

import numpy as np
import pandas as pd

from hydroline import analysis, load_rig
from hydroline.analysis.fit import Measurements, simulate_record

OUT = Path("tutorial-out")
OUT.mkdir(exist_ok=True)

truth = load_rig()
truth.set("supply.section2.bulk_modulus", "200 MPa")
truth.set("return.section2.bulk_modulus", "160 MPa")
t = np.arange(0.0, 0.06, 1e-4)
channels = ["supply_port_pressure", "return_port_pressure"]
template = Measurements(pd.DataFrame({"time": t, "valve_current": np.where(t >= 0.01, 0.05, 0.0),
                                      **{c: np.zeros_like(t) for c in channels}}), "synthetic")
y = simulate_record(truth, template, channels, start="rest")
rng = np.random.default_rng(0)
csv = pd.DataFrame({"time [ms]": 1e3 * t, "valve_current [mA]": 1e3 * template.data["valve_current"],
                    **{f"{c} [MPa]": (y[c] + rng.normal(0.0, 2e4, t.size)) / 1e6 for c in channels}})
csv.to_csv(OUT / "step_record.csv", index=False)
print(csv.head(3).to_string(index=False))

# %%
# Fit the two bulk moduli
# -----------------------
meas = analysis.read_measurements(OUT / "step_record.csv")
params = ["supply.section2.bulk_modulus", "return.section2.bulk_modulus"]
fit = analysis.fit_parameters(load_rig(), meas, params)
for name, start, est, lo, hi in zip(fit.names, fit.start, fit.estimate, fit.ci_low, fit.ci_high):
    print(f"{name:30s} start {start / 1e6:6.1f} MPa -> {est / 1e6:6.1f} MPa "
          f"(95 % CI {lo / 1e6:.1f} .. {hi / 1e6:.1f}); truth {truth[name] / 1e6:.0f} MPa")
print(f"weighted residual variance {fit.residual_variance:.2f} (1 = the noise, no model error)")
print(f"noise levels estimated from the data: "
      f"{ {k: round(v / 1e3, 1) for k, v in fit.sigma.items()} } kPa")

# %%
# Friction from steady-velocity runs
# ----------------------------------
# The paper's procedure: hold the piston, step the current, and once the velocity is steady
# Newton's law (M23) gives the friction force from the chamber pressures. Here
# :func:`~hydroline.studies.friction_tests.virtual_friction_tests` runs those experiments on the
# model (a few current steps up and down, no closed-loop sine, to stay quick), and the fit
# is compared with the rig's own (M24) coefficients.
from hydroline.studies.friction_tests import virtual_friction_tests

rig = load_rig()
steady, sine = virtual_friction_tests(rig, currents=[0.5e-3, 1.5e-3, 5e-3, 12.5e-3,
                                                     -0.5e-3, -1.5e-3, -5e-3, -12.5e-3],
                                      sine=False, slow_currents=())
ident = analysis.identify_friction(rig, steady=steady)
units = {"viscous": "N s/m", "coulomb": "N"}
for key in ("viscous_up", "coulomb_up", "viscous_down", "coulomb_down"):
    kind = key.split("_")[0]
    print(f"{key:13s} identified {getattr(ident.fit, key):8.2f}  rig {rig['friction.' + key]:8.2f} "
          f"[{units[kind]}]")
# Static friction and the Stribeck velocity need slow runs (slow_currents=... against a
# damper, see virtual_friction_tests); the fit says so rather than guessing:
print(ident.fit.static_note)
