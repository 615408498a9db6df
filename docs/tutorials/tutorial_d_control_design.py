"""
(d) Control design: what the supply line costs in bandwidth
===========================================================

For control design the nonlinear model is linearised about an operating point
(:func:`hydroline.analysis.linearize`, a python-control ``StateSpace`` with named signals).
:func:`hydroline.analysis.bode_analysis` compares three linear models of the same rig:

- ``modal``: the hoses as modal lines (the simulated model, linearised);
- ``exact``: the hoses as the exact dissipative lines (M6), frequency by frequency;
- ``constant-supply``: an ideal supply, constant pressure at the valve ports.

The difference between the first two and the last is what the hoses cost. Run time: ~5 s.
Command-line equivalent: ``hydroline bode --output piston_velocity --compare constant-supply``.
"""

# %%
# Linearise
# ---------
from pathlib import Path

import numpy as np

import hydroline
from hydroline import analysis

OUT = Path("tutorial-out")
OUT.mkdir(exist_ok=True)

ss = analysis.linearize(hydroline.load_rig(), outputs=("piston_velocity", "supply_port_pressure"))
print(f"{ss.nstates} states, inputs {ss.input_labels}, outputs {ss.output_labels}")

# %%
# The oil-spring check
# --------------------
# With an ideal supply the valve-actuator mode is the hydraulic natural frequency
# w_h^2 = beta_c (A_b^2/V_b + A_t^2/V_t)/m (model reference, section 4): 172 Hz in the paper.
ideal = analysis.linearize(hydroline.load_rig(), supply="constant")
poles = ideal.poles()
osc = poles[(poles.imag > 0) & (abs(poles) / (2 * np.pi) > 100) & (abs(poles) / (2 * np.pi) < 300)]
print("ideal-supply poles near 172 Hz:", np.round(abs(osc) / (2 * np.pi), 1), "Hz")

# %%
# Bode with and without the hoses
# -------------------------------
# At rest the valve passes almost no flow and the hoses hardly matter (the three models
# agree; the piston velocity's response is resonant at the 172 Hz oil spring and has no
# -3 dB bandwidth). With the piston moving at a steady velocity the valve draws flow through
# the hoses, their resonances enter the plant and, at high flow, the first line resonance
# becomes the bandwidth limit -- the paper's point.
from hydroline.analysis import OperatingPoint
from hydroline.analysis.frequency import CONSTANT, EXACT, MODAL

f = np.logspace(0, np.log10(500.0), 600)
rows = {}
for v in (0.0, 0.4, 0.8):                          # steady piston velocity, [m/s]
    bode = analysis.bode_analysis(hydroline.load_rig(), OperatingPoint(0.0, v),
                                  "valve_current", ["piston_velocity"], f)
    rows[v] = bode
    # two readings of the -3 dB bandwidth: the first crossing ("*": inside a notch the gain
    # climbs back out of) and the frequency up to which the gain stays within 3 dB
    band = {k: bode.passbands[k].get("piston_velocity") for k in (MODAL, EXACT, CONSTANT)}
    txt = {k: "resonant" if b is None else
           f"{b.first_crossing_hz or float('nan'):.1f}{'*' if b.in_notch else ''}"
           f"/{b.within_3db_up_to_hz or float('nan'):.1f} Hz" for k, b in band.items()}
    print(f"v = {v:.1f} m/s: -3 dB first/within  modal {txt[MODAL]:>14}  exact {txt[EXACT]:>14}"
          f"  constant supply {txt[CONSTANT]:>14}")

# %%
# Plot the three curves at 0.8 m/s
# --------------------------------
import matplotlib.pyplot as plt

bode = rows[0.8]
fig, ax = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
for label, H in bode.curves.items():
    ax[0].semilogx(bode.f, 20 * np.log10(abs(H[:, 0]) / abs(H[0, 0])), label=label)
    ax[1].semilogx(bode.f, np.degrees(np.unwrap(np.angle(H[:, 0]))), label=label)
ax[0].axhline(-3, color="grey", lw=0.5)
ax[0].set_ylabel("|v_p / i_v| [dB re 1 Hz]")
ax[1].set_ylabel("phase [deg]")
ax[1].set_xlabel("frequency [Hz]")
ax[0].legend(fontsize=8)
fig.savefig(OUT / "bode_velocity.png", dpi=100)

# %%
# Reading it
# ----------
# The modal and the exact hose models give nearly the same curves (the modal line is good
# up to its highest retained mode, ``bode.highest_mode_hz``); the ideal supply does not
# have the line resonances at all. The gap between the hose curves and the ideal-supply
# curve is what the supply line costs: a position loop closed around this plant must stay
# below the first line resonance, so the supply line, not the valve, sets the achievable
# test bandwidth.
print(f"highest retained line mode: {bode.highest_mode_hz:.0f} Hz")

# %%
# Gain and phase margins of the position loop
# -------------------------------------------
# The rig's P controller (``controller.proportional_gain`` [A/m]) closes the loop around
# valve current -> piston position. ``control.margin`` on the ~60-state model fails inside
# python-control (it converts to a transfer-function polynomial first); the margins read off
# the frequency response do not: :func:`hydroline.stability_margins` evaluates the response
# directly and reads them through ``control.frd`` (:func:`hydroline.frequency_response_data`
# gives the FRD itself, :func:`hydroline.bode_data` a table of gain and phase).
rig = hydroline.load_rig()
plant = hydroline.linearize(rig, inputs=["valve_current"], outputs=["piston_position"])
m = hydroline.stability_margins(plant, gain=rig["controller.proportional_gain"])
print(f"position loop: phase margin {m['phase_margin_deg']:.0f} deg at "
      f"{m['gain_crossover_hz']:.1f} Hz, gain margin {m['gain_margin_db']:.1f} dB at "
      f"{m['phase_crossover_hz']:.0f} Hz")
