"""
(f) Choosing a line model
=========================

hydroline has several models of one hose; this tutorial puts them side by side on the rig's
supply hose and on a lossier, narrower line, against the exact dissipative model (M6):

- ``ModalLine(method="yang-tobler")``: the 2005 paper's modal line, linear friction with
  per-mode corrections alpha_i, beta_i (M7)-(M15);
- ``ModalLine(method="residue")``: exact poles and exact residues of (M6)
  (:doc:`../residue_line`);
- ``ModalLine(corrections="none")``: plain linear friction, alpha = beta = 1;
- ``LumpedLine``: N R-I-C segments, as commercial segmented-pipe blocks;
- ``CharacteristicsLine``: method of characteristics with Zielke's unsteady friction, an
  independent time-domain reference.

Run time: about 10 s. Command line (a hose of your own): ``hydroline line-response
--length "3.048 m" --diameter "15.9 mm" --bulk-modulus "178 MPa" --method both``.
"""

# %%
# Two lines
# ---------
import numpy as np

from hydroline import MINERAL_OIL, load_rig
from hydroline.lines import Line, ModalLine
from hydroline.lines.characteristics import CharacteristicsLine
from hydroline.lines.compare import compare_resonances
from hydroline.lines.lumped import LumpedLine

rig = load_rig()
lines = {
    "rig supply hose": Line(rig["supply.section2.length"], rig["supply.section2.diameter"],
                            MINERAL_OIL, bulk_modulus=rig["supply.section2.bulk_modulus"]),
    "lossy 6 mm line": Line(3.0, 0.006, MINERAL_OIL, bulk_modulus=178e6),
}
for name, line in lines.items():
    print(f"{name}: c = {line.wave_speed:.0f} m/s, Z0 = {line.impedance:.3g} Pa s/m^3, "
          f"Dn = {line.dissipation_number:.4f}, c/(4L) = {line.wave_speed / (4 * line.length):.1f} Hz")

# %%
# Frequency domain: resonances against the exact model
# ----------------------------------------------------
# For every entry of the PQ transfer matrix, the first six resonance peaks of each model are
# compared with those of (M6): the worst frequency and peak-height errors.
def worst(line, model):
    rows = compare_resonances(line, model, n_peaks=6)
    return (max(abs(r.frequency_error_pct) for r in rows),
            max(abs(r.magnitude_error_pct) for r in rows))


print(f"{'line':16s} {'model':24s} {'freq. err %':>11s} {'peak err %':>10s}")
for name, line in lines.items():
    models = {
        "residue, 6 modes": ModalLine(line, 6, "PQ", method="residue"),
        "Yang-Tobler, 6 modes": ModalLine(line, 6, "PQ", method="yang-tobler"),
        "alpha = beta = 1": ModalLine(line, 6, "PQ", corrections="none"),
        "lumped, 24 segments": LumpedLine(line, 24),
    }
    for label, model in models.items():
        f_err, m_err = worst(line, model)
        print(f"{name:16s} {label:24s} {f_err:11.2f} {m_err:10.1f}")

# %%
# DC: the laminar steady state (M12)
# ----------------------------------
# Every model must give P_d = P_u - R Q_d and Q_u = Q_d at constant inputs.
line = lines["rig supply hose"]
u = np.array([20.7e6, 3e-4])                       # P_u [Pa], Q_d [m^3/s]
exact = line.steady_state("PQ", u)
for label, model in (("residue", ModalLine(line, 6, method="residue")),
                     ("Yang-Tobler", ModalLine(line, 6, method="yang-tobler"))):
    y = model.outputs(model.initial_state(u), u)
    print(f"{label:12s} P_d error {y[0] - exact[0]:.2e} Pa, Q_u error {y[1] - exact[1]:.2e} m^3/s")

# %%
# Time domain: a flow step at the valve end
# -----------------------------------------
# The downstream flow steps by 0.3 L/s, rising over one wave time L/c, with the upstream
# pressure held; the downstream pressure drops by about Z0 * dQ (water hammer) and rings for
# ten wave periods. Reference: the characteristics line; errors as a fraction of Z0 * dQ.
from scipy.signal import lsim

dq, tau = 3e-4, line.wave_time


def q_d(t):
    """Raised-cosine flow step over one wave time, [m^3/s]."""
    return dq * np.where(t < tau, 0.5 * (1 - np.cos(np.pi * np.clip(t, 0, None) / tau)), 1.0)


ref = CharacteristicsLine(line, n_reaches=128).simulate(40 * tau, upstream_pressure=0.0,
                                                        downstream_flow=q_d)
surge = line.impedance * dq
u = np.c_[np.zeros_like(ref.t), q_d(ref.t)]
for label, model in (("residue", ModalLine(line, 10, method="residue")),
                     ("Yang-Tobler", ModalLine(line, 10, method="yang-tobler"))):
    _, y, _ = lsim((model.A, model.B, model.C, model.D), u, ref.t)
    err = (y[:, 0] - ref.downstream_pressure) / surge
    print(f"{label:12s} downstream pressure: rms {100 * np.sqrt(np.mean(err**2)):.2f} %, "
          f"max {100 * np.max(abs(err)):.2f} % of Z0 dQ = {surge / 1e6:.2f} MPa")

# %%
# Which to use
# ------------
# * In system simulations (``modes_per_section`` in the rig file): the residue line, the
#   default of every rig (``rig.line_method = "residue"``), is the more accurate at the same
#   size, especially on lossy lines, and its error falls as modes are added. The Yang-Tobler
#   line is the paper's (``rig.line_method = "yang-tobler"`` to reproduce it), adequate for
#   hoses with Dn below about 0.003; on the default rig its port swing is 6-12 % high.
# * Never alpha = beta = 1 for hydraulic hoses: the resonance peaks come out many times too
#   high.
# * A lumped segmented line needs many segments for the same frequencies, and its steady
#   friction under-damps the higher modes.
# * The characteristics line is the reference for checking, not for system models.
