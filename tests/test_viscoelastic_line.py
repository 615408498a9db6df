"""Viscoelastic hose wall (M44): Kelvin-Voigt creep elements in the exact line model and in
the residue modal line."""
import numpy as np
import pytest

from hydroline import MINERAL_OIL
from hydroline.lines import Line, ModalLine
from hydroline.lines.compare import compare_resonances

HOSE = dict(length=3.048, diameter=0.01415, fluid=MINERAL_OIL, bulk_modulus=194.5e6)


def test_wall_factor_by_hand():
    line = Line(**HOSE, creep_compliances=(2e-10, 1e-10), retardation_times=(0.005, 0.05))
    # W(0) = 1 + beta (J1 + J2) = 1 + 194.5e6 * 3e-10 = 1.05835; W(j/tau1) = 1 + bJ1/(1+j) + bJ2/(1+10j)
    assert line.wall_factor(0.0).real == pytest.approx(1.05835, rel=1e-12)
    s = 1j / 0.005
    assert line.wall_factor(s) == pytest.approx(1 + 194.5e6 * (2e-10 / (1 + 1j) + 1e-10 / (1 + 10j)))
    # the static wave speed falls by sqrt(W0): Gamma/s at s -> 0 (lossless part) grows by it
    h = 1e-6
    assert (line.wall_factor(h) - line.wall_factor(-h)).real / (2 * h) == pytest.approx(
        line.wall_factor_derivative(0.0).real, rel=1e-6)


def test_vanishing_creep_recovers_the_elastic_line():
    elastic = Line(**HOSE)
    s = 2j * np.pi * np.logspace(-1, 3, 50)
    for form in ("PQ", "QP", "PP", "QQ"):
        tiny = Line(**HOSE, creep_compliances=(1e-30,), retardation_times=(0.01,))
        assert np.allclose(tiny.transfer(s, form), elastic.transfer(s, form), rtol=1e-12, atol=0)
        # no elements: the elastic line itself, bit for bit
        assert np.array_equal(Line(**HOSE, creep_compliances=(), retardation_times=()).transfer(s, form),
                              elastic.transfer(s, form))


def test_creep_lowers_and_damps_the_resonances():
    """A wall that creeps 5 % more at DC (W0 = 1.05) has its quarter-wave resonance between
    c/(4L) and c/(4L sqrt(W0)), and a lower peak (the wall dissipates)."""
    el = Line(**HOSE)
    ve = Line(**HOSE, creep_compliances=(0.05 / 194.5e6,), retardation_times=(0.02,))
    m_el, m_ve = ModalLine(el, 6, "PQ"), ModalLine(ve, 6, "PQ")
    r_el = compare_resonances(el, m_el, 1)[0]
    r_ve = compare_resonances(ve, m_ve, 1)[0]
    assert r_el.exact_frequency_hz / np.sqrt(1.05) < r_ve.exact_frequency_hz < r_el.exact_frequency_hz
    assert r_ve.exact_magnitude < r_el.exact_magnitude


#: the paper's pressure hose (13.43 mm): its second viscous rate nu j_{2,2}^2/r^2 = 50.28 1/s
#: lies in the window (1/tau, (1 + beta_e J)/tau) = (50, 55.1) 1/s of a 20 ms element, where
#: W < 0, so modes 1-3 have a complex pair of poles there instead of two real roots
PAPER = dict(length=3.048, diameter=0.01343, fluid=MINERAL_OIL, bulk_modulus=203.8e6)
WALLS = [(HOSE, (5e-10,), (0.02,)), (HOSE, (2e-10, 1e-10), (0.005, 0.05)),
         (PAPER, (5e-10,), (0.02,)), (PAPER, (5e-10,), (0.002,)), (HOSE, (5e-10,), (0.005,))]


@pytest.mark.parametrize("hose, J, tau", WALLS)
@pytest.mark.parametrize("form", ["PQ", "PP"])
def test_residue_line_matches_its_exact_model(form, hose, J, tau):
    """The residue realisation of the viscoelastic line: its modal poles and residues are the
    exact model's (with the complex wall poles, where a viscous rate lies in an element's
    window), so its resonances lie within 0.1 % (frequency) and 1 % (peak) of the exact
    viscoelastic four-pole, as the elastic residue line does (0.5 % on these lines; the
    issue asks 1 % and 3 %), slow and fast elements alike, and it is stable."""
    line = Line(**hose, creep_compliances=J, retardation_times=tau)
    m = ModalLine(line, 6, form, method="residue")
    assert np.max(m.eigenvalues().real) < 0
    for r in compare_resonances(line, m, 6):
        assert abs(r.frequency_error_pct) < 0.1
        assert abs(r.magnitude_error_pct) < 1.0


def test_wall_poles_of_the_paper_hose_include_a_complex_pair():
    """Between 1/tau = 50 1/s and the viscous rate 50.28 1/s, F = Gamma^2 + theta^2 of mode 1
    stays negative on the real axis (no real root), so its two roots there are complex: a
    root of the exact model (checked with :meth:`Line.propagation`, the four-pole's own
    Gamma) off the axis."""
    from hydroline.lines.residue import retardation_poles
    line = Line(**PAPER, creep_compliances=(5e-10,), retardation_times=(0.02,))
    x = np.linspace(50.0, 50.28, 2001)[1:-1]
    assert np.all((line.propagation(-x + 0j)[0] ** 2).real + (np.pi / 2) ** 2 < 0)
    _, wall = retardation_poles(line, "PQ", rate_limit=3300.0)
    pairs = wall[0][wall[0].imag > 0]
    assert pairs.size >= 1
    G = line.propagation(pairs)[0]
    thetas = np.pi * (np.arange(1, 31) - 0.5)
    assert np.any(np.isclose(np.abs(G[:, None] ** 2 + thetas[None, :] ** 2), 0.0, atol=1e-6))


@pytest.mark.parametrize("tau", [0.02, 0.002])
def test_residue_line_smoothed_step_against_the_inverted_exact_model(tau):
    """Blocked end, unit pressure step through the smooth filter that 6 modes resolve: the
    residue line against the numerically inverted exact viscoelastic model within 1 % of the
    step (the elastic line: 0.24 %); the exact step includes the wall (the elastic one
    differs by several %)."""
    from hydroline.cli.line_response import blocked_step_errors
    from hydroline.lines.inverse_laplace import exact_step_response
    from hydroline.cli.line_response import smooth_step_filter
    line = Line(**PAPER, creep_compliances=(5e-10,), retardation_times=(tau,))
    m = ModalLine(line, 6, "PQ", method="residue")
    _, _, _, err = blocked_step_errors(line, {"r": m}, periods=8)
    assert err["r"]["max_smooth_pct"] < 1.0
    t = np.linspace(0.0, 32 * line.wave_time, 161)[1:]
    W, _ = smooth_step_filter(line, 6)
    ve = exact_step_response(line, t, "PQ", (0, 0), input_filter=W)
    el = exact_step_response(Line(**PAPER), t, "PQ", (0, 0), input_filter=W)
    assert np.abs(ve - el).max() > 0.02


def test_yang_tobler_and_qq_refuse_a_viscoelastic_wall():
    line = Line(**HOSE, creep_compliances=(5e-10,), retardation_times=(0.02,))
    with pytest.raises(ValueError, match="residue"):
        ModalLine(line, 6, "PQ", method="yang-tobler")
    with pytest.raises(ValueError, match="QQ"):
        ModalLine(line, 6, "QQ", method="residue")
    with pytest.raises(ValueError, match="as many"):
        Line(**HOSE, creep_compliances=(5e-10,), retardation_times=())


def test_line_response_shows_elastic_and_viscoelastic(tmp_path, capsys):
    import json
    from hydroline.cli import main
    rc = main(["line-response", "--length", "3.048 m", "--diameter", "14.15 mm",
               "--bulk-modulus", "194.5 MPa", "--creep-compliance", "5e-10 1/Pa",
               "--retardation-time", "20 ms", "--no-step", "--json", "--out", str(tmp_path)])
    assert rc == 0
    report = json.loads(capsys.readouterr().out)
    assert {r["method"] for r in report["resonances"]} == {"residue"}
    assert max(abs(r["frequency_error_pct"]) for r in report["resonances"]) < 1.0
    assert (tmp_path / "line_response.png").is_file()


def test_line_response_legend_names_the_walls(tmp_path, monkeypatch):
    """The figure tells the viscoelastic exact, viscoelastic modal and elastic curves apart."""
    from hydroline.cli import main
    from hydroline.cli import line_response
    figures = []
    real = line_response.plot_line_response
    monkeypatch.setattr(line_response, "plot_line_response",
                        lambda *a, **k: figures.append(real(*a, **k)) or figures[-1])
    assert main(["line-response", "--length", "3.048 m", "--diameter", "13.43 mm",
                 "--bulk-modulus", "203.8 MPa", "--creep-compliance", "5e-10 1/Pa",
                 "--retardation-time", "20 ms", "--no-step", "--out", str(tmp_path)]) == 0
    labels = [t.get_text() for t in figures[0].axes[0].get_legend().get_texts()]
    assert labels == ["viscoelastic wall, exact (dissipative)", "elastic wall, exact (dissipative)",
                      "viscoelastic wall, modal residue, n=6", "elastic wall, modal residue, n=6"]


def test_half_wave_resonance_follows_the_dynamic_wave_speed():
    """The exact viscoelastic line's half-wave resonance (PP, 6.1 m: the two supply sections
    of the paper's rig) sits where the phase speed at that frequency puts it:
    ``f = f_elastic / Re sqrt(W(j omega))`` (Gamma = j omega L/c sqrt(W)), 38.205 -> 38.122 Hz
    for J = 5e-10 1/Pa, tau = 20 ms, within 0.05 %."""
    J, tau, beta = 5e-10, 0.02, PAPER["bulk_modulus"]
    f = np.linspace(30.0, 50.0, 20001)

    def peak(line):
        return f[np.argmax(np.abs(line.transfer(2j * np.pi * f, "PP")[:, 0, 0]))]

    hose = dict(PAPER, length=6.096)
    f_el = peak(Line(**hose))
    w = 2 * np.pi * f_el
    hand = f_el / np.sqrt(1 + beta * J / (1 + 1j * w * tau)).real
    assert peak(Line(**hose, creep_compliances=(J,), retardation_times=(tau,))) == pytest.approx(
        hand, rel=5e-4)


def _port_frequency(rig):
    from hydroline import simulate
    from hydroline.traces import oscillation_frequency
    res = simulate(rig, "open-loop-step", t_end=0.08)
    return oscillation_frequency(res.t, res["supply_port_pressure"], 0.01)


def test_rig_hoses_take_a_viscoelastic_wall():
    """``creep_compliances`` / ``retardation_times`` on the template's hose sections: a tiny
    compliance (beta_e J = 2e-5) gives the elastic rig's supply-port oscillation (40 Hz, the
    supply hoses' half wave) within 1e-4; a real one (5e-10 1/Pa, 20 ms) lowers it, but by
    less than the static compliance would (``f / sqrt(1 + beta_e J)``, 38.1 Hz)."""
    from hydroline import load_rig
    base = load_rig(None)
    f_el = _port_frequency(base.copy())

    def walled(J, tau):
        rig = base.copy()
        for sec in ("supply.section1", "supply.section2"):
            rig.set(f"{sec}.creep_compliances", [J]).set(f"{sec}.retardation_times", [tau])
        return rig

    assert _port_frequency(walled("1e-13 1/Pa", "20 ms")) == pytest.approx(f_el, rel=1e-4)
    f_ve = _port_frequency(walled("5e-10 1/Pa", "20 ms"))
    assert f_el / np.sqrt(1 + 203.8e6 * 5e-10) < f_ve < f_el * (1 - 3e-4)
    # unequal lists: one line naming the parameter
    from hydroline.system import build_circuit
    bad = base.copy().set("supply.section2.creep_compliances", ["5e-10 1/Pa"])
    with pytest.raises(ValueError, match="retardation_times"):
        build_circuit(bad)
