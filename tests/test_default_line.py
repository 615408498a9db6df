"""The default line model (the exact-pole "residue" line) in the default rig, against
independent references: a method-of-characteristics line with Zielke's unsteady friction
(hydroline.lines.characteristics: no modal code, no Laplace-domain code) driven by the same
boundary conditions the rig's section II sees, and the same rig with 20 modes per section
(the modal truncation converged)."""
import numpy as np
import pytest

import hydroline
from hydroline.fluid import Fluid
from hydroline.lines import DEFAULT_LINE_METHOD, Line
from hydroline.lines.characteristics import CharacteristicsLine
from hydroline.scenarios import metrics_window
from hydroline.traces.metrics import oscillation_amplitude

#: Output step of the rig runs: the characteristics line reads its boundary conditions
#: between these samples by linear interpolation, [s]
DT_OUT = 2e-5


@pytest.fixture(scope="module")
def default_run():
    rig = hydroline.load_rig()
    res = hydroline.simulate(rig, "open-loop-step", dt_out=DT_OUT)
    return rig, res


def _section2_line(rig, side):
    fluid = Fluid(rig["fluid.density"], rig["fluid.kinematic_viscosity"],
                  rig["fluid.bulk_modulus"])
    return Line(rig[f"{side}.section2.length"], rig[f"{side}.section2.diameter"], fluid,
                rig[f"{side}.section2.bulk_modulus"])


def test_the_default_line_is_the_exact_pole_line(default_run):
    rig, _ = default_run
    assert DEFAULT_LINE_METHOD == "residue"
    assert rig["rig.line_method"] == "residue"
    assert hydroline.lines.ModalLine(_section2_line(rig, "supply"), 2).method == "residue"


@pytest.mark.parametrize("side", ["supply", "return"])
def test_section2_port_pressure_against_characteristics_line(default_run, side):
    """Section II between the manifold (pressure imposed: the rig's manifold pressure) and
    the valve port (flow imposed: the rig's port flow) solved by the method of
    characteristics (64 reaches, Zielke friction; its own error ~1 % of a step's swing just
    behind a wave front, class docstring): the rig's port pressure has the same oscillation
    amplitude within 3 %, and the traces differ by at most 2 % of the excursion rms, over the
    metrics window (step to stop). The return section runs from the valve to the manifold:
    the characteristics line is laid the other way (x = 0 at the manifold), so its
    downstream flow is minus the port's flow into the hose."""
    rig, res = default_run
    t0, t1, _ = metrics_window(res)
    t = res.t
    if side == "supply":
        p_manifold, q_port = res["supply.manifold_pressure"], res["supply_port_flow"]
        p_port = res["supply_port_pressure"]
    else:
        p_manifold, q_port = res["return.manifold_pressure"], -res["return_port_flow"]
        p_port = res["return_port_pressure"]
    line = _section2_line(rig, side)
    moc = CharacteristicsLine(line, n_reaches=64).simulate(
        t1, upstream_pressure=lambda s: np.interp(s, t, p_manifold),
        downstream_flow=lambda s: np.interp(s, t, q_port),
        initial_pressure=float(p_manifold[0]), initial_flow=float(q_port[0]))
    assert abs(moc.downstream_pressure[0] - p_port[0]) < 1e-3 * abs(p_port[0])   # same rest
    window = (moc.t >= t0 - moc.t[1]) & (moc.t <= t1)
    tm = moc.t[window]
    ours = np.interp(tm, t, p_port)
    ref = moc.downstream_pressure[window]
    excursion = np.max(np.abs(ref - ref[0]))
    rms = np.sqrt(np.mean((ours - ref) ** 2))
    print(f"{side}: rms {rms / excursion:.2%} of the excursion", end="; ")
    assert rms < 0.02 * excursion, (rms, excursion)
    a_ours = oscillation_amplitude(tm, ours, tm[0], t_end=t1)
    a_ref = oscillation_amplitude(tm, ref, tm[0], t_end=t1)
    print(f"amplitude {a_ours / 1e6:.4f} MPa vs {a_ref / 1e6:.4f} MPa")
    assert a_ours == pytest.approx(a_ref, rel=0.03)


def test_port_amplitudes_converged_in_the_modes(default_run):
    """The default rig's 6 modes per section against 20 (the truncation converged: the
    residue line's poles and residues are exact, so more modes only add its high-frequency
    tail): supply and return amplitudes within 3 %."""
    rig, res = default_run
    fine = rig.copy()
    fine.set("rig.modes_per_section", 20)
    s6 = hydroline.summarize(res)
    # CVODES: no C library of the 20-mode structure to build (~10 s on a quiet machine); the
    # run ends 25 ms after the metrics window (the piston's stop at ~110 ms)
    s20 = hydroline.summarize(hydroline.simulate(fine, "open-loop-step", solver="cvodes",
                                                 t_end=metrics_window(res)[1] + 0.025))
    assert s20["metrics_window_note"] == s6["metrics_window_note"]
    for side in ("supply", "return"):
        assert s6[side]["amplitude_mpa"] == pytest.approx(s20[side]["amplitude_mpa"], rel=0.03)
        assert s6[side]["frequency_hz"] == pytest.approx(s20[side]["frequency_hz"], rel=0.01)
