"""Line library against exact theory (docs/model.md section 2)."""
import numpy as np
import pytest

import hydroline
from hydroline import Fluid, MINERAL_OIL, effective_bulk_modulus
from hydroline.lines import FORMS, Line, ModalLine, RigidColumnLine, correction_factors
from hydroline.lines.compare import compare_resonances

RNG = np.random.default_rng(7)


def hose(length=3.048, diameter=0.0127, bulk=1.0e9):
    return Line(length, diameter, MINERAL_OIL, bulk)


def test_derived_parameters_by_hand():
    # d = 19 mm, nu = 3.2e-5, c = 488 m/s, L = 3.048 m (docs/model.md 2.3 worked example)
    rho = 870.0
    line = Line(3.048, 0.019, Fluid(rho, 3.2e-5, 488.0**2 * rho))
    A = np.pi * 0.019**2 / 4
    assert line.wave_speed == pytest.approx(488.0)
    assert line.impedance == pytest.approx(rho * 488.0 / A)
    assert line.dissipation_number == pytest.approx(4 * 3.2e-5 * 3.048 / (488 * 0.019**2))
    assert line.resistance == pytest.approx(8 * line.impedance * line.dissipation_number)
    assert line.inertance == pytest.approx(rho * 3.048 / A)
    assert line.capacitance == pytest.approx(A * 3.048 / (488.0**2 * rho))


def test_effective_bulk_modulus_series():
    # three compliances in series, by hand
    b = effective_bulk_modulus(1.5e9, wall_bulk_modulus=3.0e9, air_fraction=0.01, pressure=1e7)
    assert b == pytest.approx(1.0 / (1 / 1.5e9 + 1 / 3.0e9 + 0.01 / 1e7))
    assert effective_bulk_modulus(1.5e9) == 1.5e9


def _closed_forms(line, s, form):
    """Lossless four-pole matrices from cosh/sinh of s L/c (independent of Line.transfer)."""
    g = s * line.wave_time
    Z = line.impedance
    ch, sh = np.cosh(g), np.sinh(g)
    M = {
        "PQ": [[1 / ch, -Z * sh / ch], [sh / ch / Z, 1 / ch]],
        "QP": [[Z * sh / ch, 1 / ch], [1 / ch, -sh / ch / Z]],
        "PP": [[ch / sh / Z, -1 / (Z * sh)], [1 / (Z * sh), -ch / sh / Z]],
        "QQ": [[Z * ch / sh, -Z / sh], [Z / sh, -Z * ch / sh]],
    }[form]
    return np.moveaxis(np.array(M), (0, 1), (-2, -1))


@pytest.mark.parametrize("form", FORMS)
def test_lossless_limit_of_every_form(form):
    # viscosity -> 0 makes both friction models lossless
    line = Line(2.0, 0.01, Fluid(870, 1e-14, 1.2e9))
    s = 2j * np.pi * np.array([3.0, 47.0, 210.0, 1234.5])
    for friction in ("dissipative", "linear"):
        np.testing.assert_allclose(line.transfer(s, form, friction), _closed_forms(line, s, form),
                                   rtol=1e-5)


def test_forms_agree_by_algebra_at_random_s():
    line = hose()
    s = RNG.uniform(0, 50, 20) + 1j * RNG.uniform(-3000, 3000, 20)
    for friction in ("dissipative", "linear"):
        PQ = line.transfer(s, "PQ", friction)
        QP = line.transfer(s, "QP", friction)
        PP = line.transfer(s, "PP", friction)
        QQ = line.transfer(s, "QQ", friction)
        # four-pole chain matrix (M5) from PQ: P_u = P_d/H00 ... rebuild outputs from inputs
        pu, qd = (RNG.normal(size=2) + 1j * RNG.normal(size=2)) * [1.0, 1.0 / line.impedance]
        pd = PQ[:, 0, 0] * pu + PQ[:, 0, 1] * qd
        qu = PQ[:, 1, 0] * pu + PQ[:, 1, 1] * qd
        np.testing.assert_allclose(QP[:, 0, 0] * qu + QP[:, 0, 1] * pd, pu, rtol=1e-9)
        np.testing.assert_allclose(QP[:, 1, 0] * qu + QP[:, 1, 1] * pd, qd, rtol=1e-9)
        np.testing.assert_allclose(PP[:, 0, 0] * pu + PP[:, 0, 1] * pd, qu, rtol=1e-8)
        np.testing.assert_allclose(PP[:, 1, 0] * pu + PP[:, 1, 1] * pd, qd, rtol=1e-8)
        np.testing.assert_allclose(QQ[:, 0, 0] * qu + QQ[:, 0, 1] * qd, pu, rtol=1e-8)
        np.testing.assert_allclose(QQ[:, 1, 0] * qu + QQ[:, 1, 1] * qd, pd, rtol=1e-8)


@pytest.mark.parametrize("friction", ["dissipative", "linear"])
def test_dc_limits_are_laminar_steady_state(friction):
    line = hose()
    s = np.array([1e-7j])
    R, C = line.resistance, line.capacitance
    PQ = line.transfer(s, "PQ", friction)[0]
    np.testing.assert_allclose(PQ.real, [[1, -R], [0, 1]], rtol=1e-6, atol=1e-12)
    PP = line.transfer(s, "PP", friction)[0]
    np.testing.assert_allclose(PP.real, np.array([[1, -1], [1, -1]]) / R, rtol=1e-6)
    # QQ: pure capacitance 1/(sC) dominates at DC
    QQ = line.transfer(s, "QQ", friction)[0]
    np.testing.assert_allclose(QQ[0, 0] * s[0] * C, 1.0, rtol=1e-6)


def test_numerically_sound_over_range():
    f = np.logspace(-2, 4, 200)
    s = 2j * np.pi * f
    for d in (0.001, 0.05):
        for L in (0.1, 30.0):
            line = Line(L, d, MINERAL_OIL, 1e9)
            for form in FORMS:
                H = line.transfer(s, form)
                assert np.all(np.isfinite(H)), (d, L, form)


def _mp_transfer(line, f, form, mp):
    """(M5)-(M6) and table 2.1 at s = 2 pi j f in 40-digit arithmetic (mpmath Bessel I)."""
    nu, r, tau, Z0 = (mp.mpf(v) for v in (line.fluid.kinematic_viscosity, line.radius,
                                           line.wave_time, line.impedance))
    s = 2j * mp.pi * mp.mpf(f)
    kappa = r * mp.sqrt(s / nu)
    sq = mp.sqrt(mp.besseli(0, kappa) / mp.besseli(2, kappa))
    G, Zc = s * tau * sq, Z0 * sq
    ch, sh = mp.cosh(G), mp.sinh(G)
    return {"PQ": [[1 / ch, -Zc * sh / ch], [sh / ch / Zc, 1 / ch]],
            "QP": [[Zc * sh / ch, 1 / ch], [1 / ch, -sh / ch / Zc]],
            "PP": [[ch / sh / Zc, -1 / (Zc * sh)], [1 / (Zc * sh), -ch / sh / Zc]],
            "QQ": [[Zc * ch / sh, -Zc / sh], [Zc / sh, -Zc * ch / sh]]}[form]


@pytest.mark.parametrize("d, L, f", [
    (0.05, 30.0, 1e4), (0.05, 0.1, 1e4), (0.001, 0.1, 1e4), (0.001, 30.0, 1e4),   # kappa ~ 20-1100
    (0.0127, 3.048, 2345.6),
    (0.001, 30.0, 0.01), (0.05, 30.0, 0.01), (0.05, 0.1, 0.01), (0.001, 0.1, 0.01)])
def test_exact_four_poles_against_mpmath(d, L, f):
    """Every entry of every form against 40-digit mpmath at the corners of the range.

    Issue 2: numerically sound from 0.01 Hz to 10 kHz for bores 1-50 mm. At 10 kHz the
    Bessel argument |kappa| reaches ~1100 (I0 ~ e^780, beyond double precision unscaled)
    and |Gamma| ~ 1800; at 0.01 Hz kappa and Gamma are small. Measured worst relative
    error 1.3e-12 (50 mm x 0.1 m at 0.01 Hz, where Gamma ~ 1e-5).
    """
    mp = pytest.importorskip("mpmath")
    line = Line(L, d, MINERAL_OIL, 1e9)
    with mp.workdps(40):
        for form in FORMS:
            H = line.transfer(np.array([2j * np.pi * f]), form)[0]
            M = _mp_transfer(line, f, form, mp)
            for i in range(2):
                for j in range(2):
                    ref = complex(M[i][j])
                    assert ref != 0 and np.isfinite(ref)
                    assert abs(H[i, j] - ref) < 1e-10 * abs(ref), (form, i, j, H[i, j], ref)


def test_correction_factors_worked_example():
    # docs/model.md 2.3: d = 19 mm, nu = 3.2e-5, c = 488, L = 3.048: alpha_1 ~ 1.03, beta_1 ~ 5.0,
    # alpha_6 ~ 1.01, beta_6 ~ 15.8
    rho = 870.0
    line = Line(3.048, 0.019, Fluid(rho, 3.2e-5, 488.0**2 * rho))
    alpha, beta = correction_factors(line, 6)
    assert alpha[0] == pytest.approx(1.03, rel=0.02)
    assert beta[0] == pytest.approx(5.0, rel=0.02)
    assert alpha[5] == pytest.approx(1.01, rel=0.02)
    assert beta[5] == pytest.approx(15.8, rel=0.02)


LINES = [(d, L) for d in (0.006, 0.0127, 0.025) for L in (0.5, 3.048, 10.0)]


@pytest.mark.parametrize("form", ["PQ", "QP"])
@pytest.mark.parametrize("n_modes", [6, 10])
def test_pq_qp_dc_gain_exact(form, n_modes):
    for d, L in LINES:
        line = hose(L, d)
        m = ModalLine(line, n_modes, form)
        u = np.array([2.0e7, 3.0e-4]) if form == "PQ" else np.array([3.0e-4, 2.0e7])
        np.testing.assert_allclose(m.outputs(m.initial_state(u), u), line.steady_state(form, u),
                                   rtol=1e-9)


def _worst(rows):
    return (max(abs(r.frequency_error_pct) for r in rows),
            max(abs(r.magnitude_error_pct) for r in rows))


@pytest.mark.parametrize("form", FORMS)
def test_yang_tobler_resonances(form):
    """Yang-Tobler line: issue 2's resonance criterion holds on six of the nine lines only.

    Issue 2 asks for the first n resonances (n = 6-10) within 1 % in frequency and 10 % in
    peak of every entry. The Yang-Tobler line (corrected poles, linear-friction numerators)
    meets that, all n modes, on the six lines with Dn < 0.003: 6 mm x 0.5 m, 12.7 mm x 0.5 m
    and 3.048 m, 25 mm x 0.5, 3.048 and 10 m (worst peak 9.1 %, 12.7 mm x 3.048 m, PQ,
    n = 10). It does NOT on the three more dissipative lines, where this test checks only
    the first n/2 modes, with peaks within 20 %. Measured on all n modes there (worst
    entry, PQ/QP; PP; QQ), n = 6 / n = 10:
    12.7 mm x 10 m (Dn 0.0074): 14.4 / 18.8 %; 3.9 / 9.5 %; 2.7 / 7.9 %;
    6 mm x 3.048 m (Dn 0.010): 16.9 / 22.7 %; 5.2 / 12.0 %; 3.6 / 10.1 %;
    6 mm x 10 m (Dn 0.033): 29.4 / 39.7 %, frequency 1.17 %; 12.1 / 23.5 %;
    9.5 / 20.4 %, frequency 1.28 %.
    The residue line (tests/test_residue.py::test_all_forms_range_of_lines) meets the
    criterion in full on all nine lines.
    """
    for d, L in LINES:
        line = hose(L, d)
        for n in (6, 10):
            m = ModalLine(line, n, form)
            n_check = n if line.dissipation_number < 0.003 else n // 2
            rows = compare_resonances(line, m, n_peaks=n_check)
            assert len(rows) == 4 * n_check, (d, L, n)
            wf, wm = _worst(rows)
            limit_m = 10.0 if line.dissipation_number < 0.003 else 20.0
            assert wf < 1.0, (form, d, L, n, wf)
            assert wm < limit_m, (form, d, L, n, wm)


def test_plain_linear_friction_grossly_underdamped():
    line = hose()
    m = ModalLine(line, 6, "PQ", corrections="none")
    rows = compare_resonances(line, m)
    # peaks many times too high (measured +400 % ... +1500 %)
    assert min(r.magnitude_error_pct for r in rows) > 200.0


@pytest.mark.parametrize("method", ["yang-tobler", "residue"])
@pytest.mark.parametrize("form", ["PP", "QQ"])
def test_pp_qq_low_frequency_k0_term(form, method):
    """Issue 2: the PP/QQ k = 0 term right at low frequency within 2 %.

    Up to a tenth of the first resonance (k pi c/L, k = 1), every entry of the modal line
    (6 modes) within 2 % of the exact model (M6), all nine lines. Measured worst:
    Yang-Tobler 0.84 % (PP) / 1.07 % (QQ); residue 0.22 % (PP) / 0.38 % (QQ).
    """
    for d, L in LINES:
        line = hose(L, d)
        m = ModalLine(line, 6, form, method=method)
        f1 = 1.0 / (2 * line.wave_time)
        s = 2j * np.pi * np.geomspace(1e-4 * f1, 0.1 * f1, 60)
        He, Hm = line.transfer(s, form), m.transfer(s)
        err = np.abs(Hm - He) / np.abs(He)
        assert err.max() < 0.02, (form, method, d, L, err.max())


def test_pp_dc_and_qq_steady_flow():
    line = hose()
    pp = ModalLine(line, 6, "PP")
    u = np.array([2.0e7, 1.9e7])
    np.testing.assert_allclose(pp.outputs(pp.initial_state(u), u), line.steady_state("PP", u), rtol=1e-9)
    qq = ModalLine(line, 6, "QQ")
    q = 3e-4
    x = qq.initial_state([q, q], mean_pressure=1e7)
    pu, pd = qq.outputs(x, [q, q])
    assert pu - pd == pytest.approx(line.resistance * q, rel=1e-9)


def test_rigid_column_line():
    line = hose()
    rc = RigidColumnLine(line)
    s = np.array([2j * np.pi * 5.0])
    H = rc.transfer(s)[0]
    expected = 1.0 / (line.resistance + line.inertance * s[0])
    np.testing.assert_allclose(H, [[expected, -expected], [expected, -expected]], rtol=1e-12)


def test_step_response_matches_transfer_dc():
    line = hose()
    m = ModalLine(line, 6, "PQ")
    y = m.step_response(np.array([0.0, 50.0]), input_index=0)
    assert y[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert y[-1, 0] == pytest.approx(1.0, rel=1e-9)


def test_state_space_shapes_and_names():
    line = hose()
    for form in FORMS:
        m = ModalLine(line, 4, form)
        assert m.A.shape[0] == len(m.state_names) == m.B.shape[0] == m.C.shape[1]
        assert m.transfer(np.array([[1j, 2j]])).shape == (1, 2, 2, 2)
        assert np.all(m.eigenvalues().real < 0) or form == "QQ"
        sys = m.to_control()
        assert sys.ninputs == 2 and sys.noutputs == 2
    pq = ModalLine(line, 2, "PQ")
    assert pq.input_names == ("upstream_pressure", "downstream_flow")
    assert pq.state_names[:2] == ["mode1.pressure", "mode1.flow"]


@pytest.mark.parametrize("kwargs, name", [
    (dict(length=0.0), "length"), (dict(length=-1.0), "length"),
    (dict(diameter=0.0), "diameter"), (dict(diameter=-0.01), "diameter"),
])
def test_bad_line_parameters(kwargs, name):
    args = dict(length=1.0, diameter=0.01, fluid=MINERAL_OIL)
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        Line(**args)


def test_bad_modal_parameters():
    line = hose()
    with pytest.raises(ValueError, match="n_modes"):
        ModalLine(line, 0)
    with pytest.raises(ValueError, match="form"):
        ModalLine(line, 4, "XY")
    with pytest.raises(ValueError, match="form"):
        line.transfer(np.array([1j]), "PX")
    with pytest.raises(ValueError, match="density"):
        hydroline.Fluid(-1, 1e-5, 1e9)
