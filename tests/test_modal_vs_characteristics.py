"""Time domain: the modal PQ line against the independent method-of-characteristics line."""
import numpy as np
import pytest
from scipy.signal import lsim

from hydroline.fluid import Fluid
from hydroline.lines import Line, ModalLine
from hydroline.lines.characteristics import CharacteristicsLine

FLUID = Fluid(870.0, 3.2e-5, 1.5e9)


def _ramped_step(q0, rise):
    """Flow step with a raised-cosine rise of ``rise`` seconds (a valve opens in a few ms)."""
    return lambda t: q0 * np.where(t < rise, 0.5 * (1 - np.cos(np.pi * np.clip(t, 0, None) / rise)), 1.0)


#: (rms, max) limits in fractions of the surge pressure Z0 q0 / of q0, per modal method
LIMITS = {"yang-tobler": (0.05, 0.20), "residue": (0.01, 0.03)}


@pytest.mark.parametrize("method", ["yang-tobler", "residue"])
@pytest.mark.parametrize("length, diameter", [(3.048, 0.0127), (10.0, 0.006)])
def test_flow_step_modal_agrees_with_characteristics(length, diameter, method):
    """Step in q_d (upstream pressure held), rising over one wave time L/c; p_d and q_u over
    ten wave periods (40 L/c). Errors relative to the step's surge pressure Z0 q0 and to q0.

    The characteristics line (128 reaches, Zielke friction; within 0.08 % of Z0 q0 of its
    64- and 256-reach solutions) is the reference. Measured, 10 modes, rms / max of
    (p_d, q_u):

    * Yang-Tobler: 3.048 m x 12.7 mm: 3.9, 3.7 % / 11.9, 9.4 %; 10 m x 6 mm: 4.2, 4.0 % /
      15.8, 16.0 %. Its linear-friction residues leave a few % however many modes are
      kept, so it is held to 5 % rms and 20 % at worst.
    * Residue (exact poles and residues): 0.53, 0.05 % / 1.9, 0.3 %; 0.18, 0.03 % /
      1.3, 0.2 %: held to 1 % rms and 3 % at worst. What is left is the Gibbs ringing of
      a truncated modal line at the sharp wave front.
    """
    line = Line(length, diameter, FLUID, 1.0e9)
    q0, tau = 1e-4, line.wave_time
    q_d = _ramped_step(q0, tau)
    moc = CharacteristicsLine(line, n_reaches=128).simulate(40 * tau, upstream_pressure=0.0,
                                                            downstream_flow=q_d)
    m = ModalLine(line, 10, "PQ", method=method)
    u = np.c_[np.zeros_like(moc.t), q_d(moc.t)]
    _, y, _ = lsim((m.A, m.B, m.C, m.D), u, moc.t)
    dp = (y[:, 0] - moc.downstream_pressure) / (line.impedance * q0)
    dq = (y[:, 1] - moc.upstream_flow) / q0
    rms_limit, max_limit = LIMITS[method]
    assert np.sqrt(np.mean(dp**2)) < rms_limit
    assert np.sqrt(np.mean(dq**2)) < rms_limit
    assert np.max(np.abs(dp)) < max_limit
    assert np.max(np.abs(dq)) < max_limit


def test_characteristics_line_converges_on_flow_step():
    line = Line(3.048, 0.0127, FLUID, 1.0e9)
    q0 = 1e-4
    tau = line.wave_time
    t = np.linspace(0.15, 9.85, 60) * 4 * tau
    ref = CharacteristicsLine(line, n_reaches=256).simulate(40 * tau, 0.0, q0)
    errs = []
    for n in (32, 64, 128):
        r = CharacteristicsLine(line, n_reaches=n).simulate(40 * tau, 0.0, q0)
        p = np.interp(t, r.t, r.downstream_pressure)
        errs.append(np.max(np.abs(p - np.interp(t, ref.t, ref.downstream_pressure))))
    assert errs[0] > errs[1] > errs[2]
