"""Modal line with exact poles and exact residues (ModalLine(..., method="residue")).

Every expected value comes from the exact dissipative model (M5)-(M6) through
:meth:`Line.transfer` or :func:`hydroline.lines.inverse_laplace.exact_step_response`, never
from stored output of this code. Run with ``-s`` to see the error tables (Yang-Tobler beside
the residue line).
"""
import functools

import numpy as np
import pytest
from scipy import special

from hydroline import MINERAL_OIL, Fluid
from hydroline.lines import FORMS, Line, ModalLine
from hydroline.lines.compare import compare_resonances, resonance_f_max
from hydroline.lines.inverse_laplace import exact_step_response, talbot
from hydroline.lines.modal import StateSpaceLine
from hydroline.lines.residue import (column_branches, exact_moments, modal_angles,
                                     modal_poles, modal_residues, residue_realisation,
                                     tail_groups, viscous_poles)

OIL = Fluid(870.0, 3.2e-5, 1.5e9)          # the rig's oil (docs/model.md 2.3 worked example)


@functools.lru_cache(maxsize=None)
def residue_line(line, n, form="PQ"):
    """The residue line, built once per (line, n, form) for the whole module (Line is a
    frozen dataclass, so equal lines share one build; no test modifies a model)."""
    return ModalLine(line, n, form, method="residue")


def _series(*blocks):
    """State-space series connection: the first block's outputs feed the second's inputs."""
    (A1, B1, C1, D1), (A2, B2, C2, D2) = blocks
    n1, n2 = A1.shape[0], A2.shape[0]
    A = np.block([[A1, np.zeros((n1, n2))], [B2 @ C1, A2]])
    B = np.vstack([B1, B2 @ D1])
    C = np.hstack([D2 @ C1, C2])
    return A, B, C, D2 @ D1


class _Plain(StateSpaceLine):
    def __init__(self, A, B, C, D):
        self.A, self.B, self.C, self.D = A, B, C, D


# ---------------------------------------------------------------------------------------
# poles, residues, moments
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("form", FORMS)
def test_realised_residues_equal_contour_integrals_of_the_exact_model(form):
    # residue of Line.transfer at each modal pole by a circle integral (independent of the
    # analytic derivative used by the module), against the realised state-space model's
    line = Line(3.048, 0.0127, OIL, 1.0e9)
    n = 5
    model = residue_line(line, n, form)
    lam, V = np.linalg.eig(model.A)
    W = np.linalg.inv(V)
    poles = modal_poles(line, n, form)
    spacing = np.pi / line.wave_time
    phi = 2 * np.pi * np.arange(64) / 64
    for p, R_mod in zip(poles, modal_residues(line, poles, form)):
        rho = 0.2 * spacing
        s = p + rho * np.exp(1j * phi)
        R_int = np.mean(line.transfer(s, form) * (rho * np.exp(1j * phi))[:, None, None], axis=0)
        k = np.argmin(np.abs(lam - p))
        assert abs(lam[k] - p) < 1e-9 * abs(p)
        R_ss = np.outer(model.C @ V[:, k], W[k] @ model.B)
        scale = np.abs(R_int)
        np.testing.assert_allclose(np.abs(R_ss - R_int) / scale, 0, atol=1e-6)
        np.testing.assert_allclose(np.abs(R_mod - R_int) / scale, 0, atol=1e-6)
        # rank one: each complex pair needs only two real states
        assert abs(np.linalg.det(R_int)) < 1e-6 * abs(R_int[0, 0] * R_int[1, 1])


@pytest.mark.parametrize("form", ["PQ", "QQ"])
def test_viscous_poles_are_roots_of_the_bessel_equation(form):
    # x^4 J0(x) Dn^2 = theta^2 J2(x) on the negative real axis (viscous_poles' docstring),
    # written with scipy's jv (the module evaluates J2 = 2 J1/x - J0 with j0, j1, which
    # differ from jv by <= 6e-16): every root lies within 10 ulp of a sign change (the
    # bisection's own bracket is ~1e-15 wide; measured: all within 10, all but 1 of 2400
    # within 3), between the zero of J2 and the next zero of J0
    for line in (Line(10.0, 0.006, MINERAL_OIL, 1.0e9), Line(0.5, 0.025, MINERAL_OIL, 1.0e9)):
        p = viscous_poles(line, form, rate_limit=1e12)
        x = line.radius * np.sqrt(-p / line.fluid.kinematic_viscosity)
        q = (modal_angles(x.shape[1], form)[None, :] / line.dissipation_number) ** 2

        def g(x):
            return x**4 * special.jv(0, x) - q * special.jv(2, x)

        du = 10.0 * np.spacing(x)
        assert np.all(np.sign(g(x - du)) != np.sign(g(x + du)))
        j2 = special.jn_zeros(2, x.shape[0])[:, None]
        assert np.all(x > j2) and np.all(x < special.jn_zeros(0, x.shape[0] + 1)[1:, None])


@pytest.mark.parametrize("method", ["residue", "yang-tobler"])
def test_transfer_by_blocks_equals_the_whole_solve(method):
    # StateSpaceLine.transfer sums A's diagonal blocks; C (sI - A)^-1 B + D in one solve
    line = Line(10.0, 0.006, MINERAL_OIL, 1.0e9)
    s = 2j * np.pi * np.linspace(0.1, 3.0, 400) / line.wave_time
    for form in FORMS:
        m = residue_line(line, 10, form) if method == "residue" else ModalLine(line, 10, form)
        whole = m.C @ np.linalg.solve(s[:, None, None] * np.eye(m.n_states) - m.A, m.B) + m.D
        np.testing.assert_allclose(m.transfer(s), whole, rtol=0, atol=1e-10 * np.abs(whole).max())
        np.testing.assert_allclose(m.transfer(s[7]), whole[7], rtol=1e-10)


@pytest.mark.parametrize("form", FORMS)
def test_exact_moments_against_the_transfer_matrix(form):
    # H(0), H'(0) of exact_moments (a series in Gamma^2) against Line.transfer near s = 0:
    # a polynomial fit on small real s; QQ, whose 1/(sC) pole must be removed first (a
    # cancellation of ~13 digits), at 40 digits with mpmath
    line = Line(3.048, 0.0127, MINERAL_OIL, 1.0e9)
    H0, H1 = exact_moments(line, form)
    if form != "QQ":
        s = 2e-3 * line.fluid.kinematic_viscosity / line.radius**2 * np.arange(1, 7)
        H = line.transfer(s, form).real.reshape(len(s), 4)
        coef = np.polynomial.polynomial.polyfit(s, H, 4)
        ref0, ref1 = coef[0].reshape(2, 2), coef[1].reshape(2, 2)
    else:
        import mpmath as mp

        mp.mp.dps = 40
        nu, r, tau, Z0 = (mp.mpf(v) for v in (line.fluid.kinematic_viscosity, line.radius,
                                               line.wave_time, line.impedance))

        def regular(x, which):        # Zc coth G - 1/(sC) or Zc csch G - 1/(sC), C = tau/Z0
            k = r * mp.sqrt(x / nu)
            B = mp.besseli(0, k) / mp.besseli(2, k)
            G, Zc = x * tau * mp.sqrt(B), Z0 * mp.sqrt(B)
            return (Zc * (mp.coth(G) if which == 0 else mp.csch(G))) - Z0 / (tau * x)

        x0 = mp.mpf("1e-9")
        c0, s0 = (float(regular(x0, w)) for w in (0, 1))
        c1, s1 = (float(mp.diff(lambda x: regular(x, w), x0)) for w in (0, 1))
        ref0 = np.array([[c0, -s0], [s0, -c0]])
        ref1 = np.array([[c1, -s1], [s1, -c1]])
    scale0 = np.abs(H0).max(axis=1, keepdims=True)
    scale1 = np.abs(H1).max(axis=1, keepdims=True)
    np.testing.assert_allclose((H0 - ref0) / scale0, 0, atol=1e-7)
    np.testing.assert_allclose((H1 - ref1) / scale1, 0, atol=1e-5)


def test_pp_column_branches_against_bessel_column():
    """The PP k = 0 term against ``1/(Zc Gamma) = I2(kappa)/(s I I0(kappa))`` (M6).

    Exact: DC conductance 1/R (M12) and first moment (4/3) I/R^2 (the Laurent series of
    I0/I2 = 8/kappa^2 + 4/3 + ...); high-frequency inertance I (plug flow) to 0.1 %; the
    admittance within 0.7 % from 1e-4 to 1e7 times nu/r^2 (the branch design: 0.61 %).
    """
    line = Line(3.048, 0.0127, MINERAL_OIL, 1.0e9)
    I, R = line.inertance, line.resistance
    br = column_branches(line)
    assert len(br) == 6 and all(Lb > 0 and Rb > 0 for Lb, Rb in br)     # passive branches
    assert sum(1.0 / Rb for _, Rb in br) == pytest.approx(1.0 / R, rel=1e-12)
    assert sum(Lb / Rb**2 for Lb, Rb in br) == pytest.approx(4.0 / 3.0 * I / R**2, rel=1e-12)
    assert sum(1.0 / Lb for Lb, _ in br) == pytest.approx(1.0 / I, rel=1e-3)
    j01 = special.jn_zeros(0, 1)[0]                    # the first branch is the exact one
    assert br[0][0] == pytest.approx(I * j01**2 / 4, rel=1e-12)
    rate = line.fluid.kinematic_viscosity / line.radius**2
    s = 1j * rate * np.logspace(-4, 7, 600)
    kappa = line.radius * np.sqrt(s / line.fluid.kinematic_viscosity)
    exact = special.ive(2, kappa) / (special.ive(0, kappa) * s * I)
    model = sum(1.0 / (Lb * s + Rb) for Lb, Rb in br)
    assert np.abs(model / exact - 1.0).max() < 0.007


@pytest.mark.parametrize("form", FORMS)
def test_dc_gain_and_first_moment_exact(form):
    for line in (Line(3.048, 0.0127, OIL, 1.0e9), Line(10.0, 0.006, MINERAL_OIL, 1.0e9),
                 Line(0.5, 0.025, MINERAL_OIL, 0.3e9)):
        for n in (1, 6, 10):
            m = residue_line(line, n, form)
            assert np.all(m.D == 0)                     # strictly proper: no algebraic loops
            A, B, C = m.A, m.B, m.C
            if form == "QQ":                             # the exact 1/(sC) integrator
                assert m.state_names[0] == "column.volume"
                A, B, C = A[1:, 1:], B[1:], C[:, 1:]
                np.testing.assert_allclose(m.C[:, 0], 1.0 / line.capacitance)
                np.testing.assert_allclose(m.B[0], [1.0, -1.0])
                np.testing.assert_allclose(m.A[:, 0], 0.0, atol=0)
            X = np.linalg.solve(A, B)
            H0, H1 = -C @ X, -C @ np.linalg.solve(A, X)
            E0, E1 = exact_moments(line, form)
            scale = np.abs(E0).max(axis=1, keepdims=True)
            np.testing.assert_allclose((H0 - E0) / scale, 0, atol=1e-9)
            np.testing.assert_allclose((H1 - E1) / np.abs(E1).max(axis=1, keepdims=True), 0,
                                       atol=1e-8)
            # the laminar steady state (M12) through the model's own initial state
            if form != "QQ":
                u0 = np.array([2.0e7, 1.0e-4]) if form in ("PQ", "QP") else np.array([2.0e7, 1.9e7])
                if form == "QP":
                    u0 = u0[::-1]
                y = m.outputs(m.initial_state(u0), u0)
                exact = line.steady_state(form, u0)
                np.testing.assert_allclose(y, exact, rtol=1e-9)
            else:
                q = 1.0e-4
                y = m.outputs(m.initial_state([q, q], mean_pressure=1.0e7), [q, q])
                assert (y[0] - y[1]) == pytest.approx(line.resistance * q, rel=1e-9)
                assert 0.5 * (y[0] + y[1]) == pytest.approx(1.0e7, rel=1e-9)


# ---------------------------------------------------------------------------------------
# blocked line, pressure step (PQ entry (0, 0))
# ---------------------------------------------------------------------------------------
def _line_with_dn(Dn, d=0.006, fluid=MINERAL_OIL, bulk=1.0e9):
    c = np.sqrt(bulk / fluid.density)
    return Line(Dn * c * d**2 / (4 * fluid.kinematic_viscosity), d, fluid, bulk)


def _blocked_line_response(line, t, W, n_terms=24):
    """Exact P_d of a blocked line (PQ entry (0, 0)) for the input W(s)/s, [Pa/Pa].

    The wave series ``sech G = 2 sum_j (-1)^j exp(-(2j+1) G)`` as in
    :func:`exact_step_response` ("wavefront"), each delayed wave inverted with the public
    :func:`talbot`; ``G - s tau`` from ``I0/I2 - 1 = 2 I1/(kappa I2)`` without cancellation.
    W(s) must be analytic off the negative real axis (here: real poles).
    """
    tau, nu, r = line.wave_time, line.fluid.kinematic_viscosity, line.radius

    def excess(s):
        k = r * np.sqrt(s / nu)
        bm1 = 2.0 * special.ive(1, k) / (k * special.ive(2, k))
        return s * tau * bm1 / (np.sqrt(1.0 + bm1) + 1.0)

    out = np.zeros_like(t)
    for j in range(int(t.max() / tau) // 2 + 1):
        m = 2 * j + 1
        sel = t > m * tau * (1 + 1e-12)
        if np.any(sel):
            out[sel] += 2.0 * (-1) ** j * talbot(
                lambda s: np.exp(-m * excess(s)) * W(s) / s, t[sel] - m * tau, n_terms)
    return out


@pytest.mark.parametrize("Dn", [0.01, 0.05])
def test_blocked_line_pressure_step(Dn):
    """Issue 7: blocked end (Q_d = 0), unit step of P_u, P_d over 20 wave periods (80 L/c).

    Why not the literal "within 1 % over 20 wave periods" on the raw step: the exact
    response (wave-front inverse Laplace, exact jumps; checked against mpmath in
    tests/test_inverse_laplace.py) jumps by ~2 at t = L/c and by ~2 at every later
    arrival, steeply for a while. A modal line is a finite sum of damped sinusoids, so
    it cannot follow a jump: next to the first fronts any n-mode line is off by about half
    the jump (Gibbs), ~59 % / 27 % of the step (Dn = 0.01 / 0.05) for the residue line with
    10 modes and 52 % / 24 % for Yang-Tobler -- a property of truncation, which only more
    modes shrink (residue, 40 modes: 32 % / 4.5 %), not of the residues. So the 1 %
    criterion is checked where it means something:

    (a) the raw step after the first two wave periods (t > 8 L/c), once the fronts have
        spread: residue 10 modes 0.58 % / 0.003 %;
    (b) over all 20 periods for a step that 10 modes resolve (rise time ~0.6 L/c): the unit
        step through ``W(s) = prod_k a_k/(s + a_k)``, ``a_k = (4/T)(0.8, 0.93, 1.07, 1.2)``,
        ``T = 20/omega_n`` (|W| < 1e-3 at the first dropped mode); exact by the same wave
        series and Talbot inversion (converged: 24 and 32 nodes agree), models by their
        exact matrix exponential: residue 0.31 % / 0.05 %, Yang-Tobler 4.9 % / 7.6 %;
    (c) convergence, on (a): the residue line's error falls from 10 to 20 modes (to 0.09 %
        / 0.0003 %) while Yang-Tobler's stalls above 1 % (2.4 -> 1.6 % / 1.42 -> 1.42 %):
        the linear-friction residues, not the truncation, limit it.
    """
    line = _line_with_dn(Dn)
    assert line.dissipation_number == pytest.approx(Dn)
    n = 10
    tau = line.wave_time
    t = np.linspace(0.0, 80 * tau, 2001)[1:]
    exact = exact_step_response(line, t, "PQ", (0, 0))
    sub = slice(None, None, 40)
    assert np.abs(exact_step_response(line, t[sub], "PQ", (0, 0), n_terms=32)
                  - exact[sub]).max() < 1e-8                                  # converged

    omega_n = (n - 0.5) * np.pi / tau
    a = 4.0 / (20.0 / omega_n) * np.array([0.8, 0.93, 1.07, 1.2])
    Af = np.diag(-a) + np.diag(a[1:], -1)                    # the four lags in series
    Bf = np.zeros((4, 2))
    Bf[0, 0] = a[0]
    Cf = np.zeros((2, 4))
    Cf[0, 3] = 1.0

    def W(s):
        return np.prod(a / (s[..., None] + a), axis=-1)

    smooth = _blocked_line_response(line, t, W)
    # the wave series here and the library's: 1.3e-12 apart (was < 1e-12 while the two ran
    # the same operations on the same array shapes; the library now evaluates the Bessel
    # functions of all fronts in one array, and the Talbot sum amplifies last-bit
    # differences ~1e4 times: round-off, documented as ~1e-10 of the response scale)
    assert np.abs(_blocked_line_response(line, t[sub], lambda s: 1.0) - exact[sub]).max() < 5e-12
    assert np.abs(_blocked_line_response(line, t[sub], W, 32) - smooth[sub]).max() < 1e-8
    assert np.abs(exact_step_response(line, t[sub], "PQ", (0, 0), input_filter=W)
                  - smooth[sub]).max() < 1e-10      # the library's filtered step (CLI table)

    late = t > 8 * tau
    errors = {}
    models = (("residue", residue_line(line, n)), ("yang-tobler", ModalLine(line, n, "PQ", method="yang-tobler")))
    for name, model in models:
        y = model.step_response(t, 0)[:, 0]
        filt = _Plain(*_series((Af, Bf, Cf, np.zeros((2, 2))),
                               (model.A, model.B, model.C, model.D)))
        ys = filt.step_response(t, 0)[:, 0]
        errors[name] = (np.abs(y - exact).max(), np.abs(y - exact)[late].max(),
                        np.sqrt(np.mean((y - exact) ** 2)), np.abs(ys - smooth).max())
    print(f"\nblocked line Dn = {Dn}, {n} modes, 20 wave periods; error in % of the step:")
    print("  model         raw max   raw after 2 periods   raw rms   smoothed-step max")
    for name, e in errors.items():
        print(f"  {name:12s} {100 * e[0]:7.2f}   {100 * e[1]:19.3f}   {100 * e[2]:7.3f}"
              f"   {100 * e[3]:17.3f}")
    res = errors["residue"]
    assert res[1] < 0.01
    assert res[3] < 0.01
    # (c) 20 modes: the residue line converges, Yang-Tobler does not get below ~1 %
    late20 = {name: np.abs(model.step_response(t, 0)[:, 0] - exact)[late].max()
              for name, model in (("residue", residue_line(line, 20)),
                                  ("yang-tobler", ModalLine(line, 20, "PQ", method="yang-tobler")))}
    print(f"  after 2 periods, 20 modes: residue {100 * late20['residue']:.4f} %, "
          f"Yang-Tobler {100 * late20['yang-tobler']:.3f} %")
    assert late20["residue"] < 0.5 * res[1]
    assert late20["yang-tobler"] > 0.01
    assert late20["yang-tobler"] > 10.0 * late20["residue"]


def test_blocked_line_step_after_the_fronts():
    """Issue 11 item 6: "a blocked line under a pressure step (10 modes, Dn 0.01) should stay
    within 1.5 % of the exact response from half a wave time after the first front on
    (today 2.1 %)" -- what that measure is, and why 10 modes cannot meet it.

    Measure (the one that reproduces "2.1 %" on the code before the remainder change,
    18dbb77, and on today's): Dn = 0.01, PQ entry (0, 0) (P_d of the blocked line for a unit
    step of P_u), the largest |P_d,model - P_d,exact| in % of the step height over
    t >= 6 L/c (1.5 wave periods of 4 L/c; the largest error sits at the front that
    arrives at 7 L/c), on a grid of 0.01 L/c: 2.05 % (2.11 % on a 0.005 L/c grid).
    Literally from half a wave time after the first front's arrival (t >= 1.5 L/c) the
    same error is 16.1 % on the 2001-point grid of test_blocked_line_pressure_step (19.0 %
    resolved; still 4.8 % with 32 modes), and 2.11 % at Dn = 0.05 (that test's grid; 1.47 %
    with 12 modes): the Gibbs error at the reflected front (3 L/c).

    Why 10 modes cannot: with exact poles and residues, the error at t >= 6 L/c is minus the
    dropped modes' own step terms ``sum_{k>n} 2 Re(R_k e^{p_k t}/p_k)`` (1.99 % at most)
    to within 0.08 % (the lumped viscous poles); the remainder T decays within L/c and is
    gone by then. So the bound needs the modes themselves: 13 modes give 1.23 % (12: 1.45 %,
    too close to the grid's resolution of the front). Both asserted here.
    """
    line = _line_with_dn(0.01)
    tau = line.wave_time
    t = np.arange(6.0, 24.0, 0.01) * tau
    exact = exact_step_response(line, t, "PQ", (0, 0))
    poles = modal_poles(line, 120, "PQ")
    res = modal_residues(line, poles, "PQ")[:, 0, 0]
    err = {}
    for n in (10, 13):
        y = residue_line(line, n).step_response(t, 0)[:, 0]
        dropped = 2.0 * (res[n:, None] / poles[n:, None] * np.exp(poles[n:, None] * t)).real.sum(0)
        err[n] = np.abs(y - exact).max()
        print(f"\nblocked line Dn = 0.01, {n} modes, t >= 6 L/c: max error {100 * err[n]:.2f} % of "
              f"the step; dropped modes' terms {100 * np.abs(dropped).max():.2f} %")
        assert np.abs(y - exact + dropped).max() < 0.001       # the error is the truncation
    assert np.abs(dropped).max() > 0.01                         # still > 1 % at n = 13
    assert err[13] < 0.015                                      # the 1.5 %


# ---------------------------------------------------------------------------------------
# resonance peaks
# ---------------------------------------------------------------------------------------
def _rig_hoses():
    # the hoses of the issue (SAE 100R2 -8 and -12, 10 ft, beta_e 0.8..1.2 GPa) and the
    # default rig file's calibrated sections
    hoses = [Line(3.048, d, OIL, b) for d in (0.0127, 0.01905) for b in (0.8e9, 1.2e9)]
    try:
        from hydroline.rigs import load_rig
    except ImportError:                    # rig layer absent: the hoses suffice
        return hoses
    rig = load_rig()
    fluid = Fluid(rig["fluid.density"], rig["fluid.kinematic_viscosity"],
                  rig["fluid.bulk_modulus"])
    for sec in ("supply.section1", "supply.section2", "return.section1", "return.section2"):
        hoses.append(Line(rig[f"{sec}.length"], rig[f"{sec}.diameter"], fluid,
                          rig[f"{sec}.bulk_modulus"]))
    return hoses


@pytest.mark.parametrize("n", [6, 10])
def test_rig_hoses_pq_peaks(n):
    worst_res, worst_yt = (0.0, 0.0), (0.0, 0.0)
    for line in _rig_hoses():
        model = residue_line(line, n, "PQ")
        rows = compare_resonances(line, model)
        assert len(rows) == 4 * n
        mag = max(abs(r.magnitude_error_pct) for r in rows)
        frq = max(abs(r.frequency_error_pct) for r in rows)
        assert mag < 2.0, (line, [(r.entry, r.mode, r.magnitude_error_pct) for r in rows])
        assert frq < 1.0
        worst_res = max(worst_res[0], mag), max(worst_res[1], frq)
        yt = compare_resonances(line, ModalLine(line, n, "PQ")) if n == 10 else rows
        worst_yt = (max(worst_yt[0], max(abs(r.magnitude_error_pct) for r in yt)),
                    max(worst_yt[1], max(abs(r.frequency_error_pct) for r in yt)))
        u0 = np.array([2.07e7, 2.0e-4])
        np.testing.assert_allclose(model.outputs(model.initial_state(u0), u0),
                                   line.steady_state("PQ", u0), rtol=1e-9)
    print(f"\nrig hoses, PQ, {n} modes: worst peak magnitude / frequency error "
          f"residue {worst_res[0]:.2f} % / {worst_res[1]:.3f} %"
          + (f", Yang-Tobler {worst_yt[0]:.2f} % / {worst_yt[1]:.3f} %" if n == 10 else ""))


@pytest.mark.parametrize("n", [6, 10])
@pytest.mark.parametrize("form", FORMS)
def test_all_forms_range_of_lines(form, n):
    """Issue 2's resonance criterion, in full, for the residue line.

    Lines spanning the range (bores 6, 12.7, 25 mm x lengths 0.5, 3.048, 10 m, mineral
    oil; Dn 1e-4 ... 0.033), n = 6 and 10 modes, every entry of every form: the first n
    resonances within 1 % in frequency and 10 % in peak magnitude of the exact dissipative
    model (M6). Measured worst: frequency 0.13 %; n = 6: peaks 1 .. n-1 <= 0.89 %, peak n
    1.8 %; n = 10: peaks 1 .. 7 <= 1.4 %, peak n 7.6 % (QQ; PQ/QP 6.4 %, PP 4.7 %; d = 6 mm,
    L = 10 m), the n-th peak being next to the first dropped mode; on that line peaks n-2,
    n-1 up to 2.5 % and 4.6 % (see the assertion). (Yang-Tobler: tests/test_lines.py.)
    """
    worst = np.zeros(n)
    worst_f = 0.0
    for d in (0.006, 0.0127, 0.025):
        for L in (0.5, 3.048, 10.0):
            line = Line(L, d, MINERAL_OIL, 1.0e9)
            rows = compare_resonances(line, residue_line(line, n, form))
            assert len(rows) == 4 * n, (d, L)
            for r in rows:
                worst[r.mode - 1] = max(worst[r.mode - 1], abs(r.magnitude_error_pct))
                worst_f = max(worst_f, abs(r.frequency_error_pct))
    print(f"\n{form}, n = {n}: worst peak magnitude error per mode (%): "
          f"{np.round(worst, 2).tolist()}, frequency {worst_f:.3f} %")
    assert worst_f < 1.0                   # the limits, every mode and entry
    assert worst.max() < 10.0
    # modes 1 .. n-1 converge much further; with n = 10 on the lossiest line (6 mm x 10 m,
    # Dn = 0.033): modes n-2, n-1 up to 2.5 % and 4.6 % (QQ; PQ/QP 2.2 / 4.0 %, PP 1.0 /
    # 2.3 %), the price of a remainder that stays under the exact envelope above the band
    # (there the exact response is within ~1.5 Zc of Zc, and the dropped modes' in-band
    # reactance must hand over to it within about one mode spacing); PP/QQ before, with the
    # light pseudo-mode that peaked at 2-9 times the envelope above the band: <= 1.08 %
    assert worst[:-3].max() < 1.5
    assert worst[:-1].max() < (5.0 if n == 10 else 1.5)


# ---------------------------------------------------------------------------------------
# stability and passivity
# ---------------------------------------------------------------------------------------
def _random_lines(count, seed):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        d = 10 ** rng.uniform(np.log10(0.004), np.log10(0.05))
        L = 10 ** rng.uniform(np.log10(0.2), np.log10(30.0))
        nu = 10 ** rng.uniform(np.log10(1e-5), np.log10(1e-4))
        beta = 10 ** rng.uniform(np.log10(1e8), np.log10(2e9))
        line = Line(L, d, Fluid(870.0, nu, 1.5e9), beta)
        if line.dissipation_number <= 0.05:          # the valid range of modal lines
            out.append((line, int(rng.integers(1, 13))))
    return out


def test_eigenvalues_in_open_left_half_plane():
    for line, n in _random_lines(20, seed=2024):
        for form in FORMS:
            lam = residue_line(line, n, form).eigenvalues()
            if form == "QQ":                            # drop the exact 1/(sC) integrator
                k = np.argmin(np.abs(lam))
                assert abs(lam[k]) < 1e-9 * np.abs(lam).max()
                lam = np.delete(lam, k)
            assert np.all(lam.real < 0), (form, line, n, lam.real.max())


def test_pp_admittance_passive():
    """Hermitian part of the port admittance [Q_u, -Q_d] = diag(1, -1) Y [P_u, P_d] is PSD.

    On a grid from 1e-6/tau to 1e3/tau; near DC the common-mode part is O(omega^2) and below
    round-off, so its leading coefficient is checked from the moments: the real part of
    ``[1, 1] Y_port [1, 1]`` is ``-omega^2 h2`` with ``h2 = [1, 1] S (-C A^-3 B) [1, 1]``,
    which must be <= 0 (exact: ``-8 Dn tau C/12``).
    """
    S = np.diag([1.0, -1.0])
    for line, n in _random_lines(20, seed=7):
        m = residue_line(line, n, "PP")
        w = np.logspace(-6, 3, 3000) / line.wave_time
        Yp = S @ m.transfer(1j * w)
        herm = 0.5 * (Yp + np.conj(np.swapaxes(Yp, -1, -2)))
        eig = np.linalg.eigvalsh(herm)
        assert np.all(eig[:, 0] >= -1e-9 * eig[:, 1]), (line, n, (eig[:, 0] / eig[:, 1]).min())
        Ai = np.linalg.inv(m.A)
        h2 = np.ones(2) @ S @ (-m.C @ Ai @ Ai @ Ai @ m.B) @ np.ones(2)
        assert h2 < 0


def test_qq_impedance_passive():
    S = np.diag([1.0, -1.0])
    for line, n in _random_lines(10, seed=8):
        m = residue_line(line, n, "QQ")
        w = np.logspace(-4, 3, 2000) / line.wave_time
        Zp = m.transfer(1j * w) @ S
        eig = np.linalg.eigvalsh(0.5 * (Zp + np.conj(np.swapaxes(Zp, -1, -2))))
        assert np.all(eig[:, 0] >= -1e-9 * np.abs(eig[:, 1])), (line, n)


def test_state_names_and_sizes():
    line = Line(3.048, 0.0127, OIL, 1.0e9)
    for form, extra in (("PQ", 0), ("QP", 0), ("PP", 6), ("QQ", 1)):
        A, B, C, D, names = residue_realisation(line, 4, form)
        # a pair per tail group and output (PQ/QP) or port channel (PP/QQ)
        n_tail = 4 * len(tail_groups(4, form))
        assert A.shape == (8 + 4 + n_tail + extra,) * 2 and B.shape == (A.shape[0], 2)
        assert C.shape == (2, A.shape[0]) and len(names) == A.shape[0] == len(set(names))
        kinds = {nm.split(".")[1].rstrip("0123456789") for nm in names}
        assert kinds <= {"pressure", "flow", "volume", "pressure_integral"}
    m = residue_line(line, 3, "PQ")
    assert m.state_names[:2] == ["mode1.pressure", "mode1.flow"]
    assert m.input_names == ("upstream_pressure", "downstream_flow")
    with pytest.raises(ValueError):
        residue_realisation(line, 0, "PQ")
    with pytest.raises(ValueError):
        residue_realisation(line, 3, "XY")


# ---------------------------------------------------------------------------------------
# above the retained band: the remainder must not invent a resonance (issue 11, item 6)
# ---------------------------------------------------------------------------------------
def _nine_lines():
    return [Line(L, d, MINERAL_OIL, 1.0e9) for d in (0.006, 0.0127, 0.025)
            for L in (0.5, 3.048, 10.0)]


def _default_rig_hoses():
    from hydroline.rigs import load_rig

    rig = load_rig()
    fluid = Fluid(rig["fluid.density"], rig["fluid.kinematic_viscosity"],
                  rig["fluid.bulk_modulus"])
    hoses = {}
    for sec in ("supply.section1", "supply.section2", "return.section1", "return.section2"):
        key = tuple(rig[f"{sec}.{k}"] for k in ("length", "diameter", "bulk_modulus"))
        hoses[key] = Line(key[0], key[1], fluid, key[2])
    return list(hoses.values())


def exact_envelope_ratio(line, model, top=8.0, per_spacing=40):
    """Largest ``|H_model| / E`` above the retained band, per entry, and where, [-], [Hz].

    The envelope of the exact response above the band is, for each entry,
    ``E(f) = max_{f' >= f} |H_exact(2 pi j f')|``: the running maximum from above, i.e. the
    height of the next exact resonance peak at or beyond f (the exact peaks fall with
    frequency, so E is the curve through the peaks, stepped down at each peak).
    Evaluated from the band edge ``f_b`` (half a mode spacing above mode n,
    :func:`resonance_f_max`) to ``top * f_b``, on a grid of ``per_spacing`` points per mode
    spacing ``1/(2 tau)``, the exact response two spacings further so that E near the top
    still sees the next peak. ``H_exact`` is (M6) through :meth:`Line.transfer`.
    """
    fb = resonance_f_max(line, model.form, model.n_modes)
    df = 1.0 / (2.0 * line.wave_time)
    f = np.arange(fb, top * fb + 2 * df, df / per_spacing)
    s = 2j * np.pi * f
    exact = np.abs(line.transfer(s, model.form))
    env = np.maximum.accumulate(exact[::-1], axis=0)[::-1]
    sel = f <= top * fb
    ratio = (np.abs(model.transfer(s[sel])) / env[sel]).reshape(-1, 4)
    k = ratio.argmax(axis=0)
    return ratio.max(axis=0).reshape(2, 2), f[sel][k].reshape(2, 2)


def _port_passivity_margin(model, line, per_spacing=16, top=4.0):
    """Smallest eigenvalue of the Hermitian part of the port admittance (PP:
    ``diag(1, -1) Y``) or impedance (QQ: ``Z diag(1, -1)``), relative to the larger one, on
    a dense grid: 200 log-spaced points from 1e-4 of the first mode to the band edge and
    ``per_spacing`` points per mode spacing from there to ``top`` times the band edge, [-].
    >= 0 (to round-off) for a passive port; the exact line's is > 0."""
    S = np.diag([1.0, -1.0])
    fb = resonance_f_max(line, model.form, model.n_modes)
    df = 1.0 / (2.0 * line.wave_time)
    f = np.concatenate([np.geomspace(1e-4 * df, fb, 200), np.arange(0.5 * df / per_spacing,
                                                                    top * fb, df / per_spacing)])
    H = model.transfer(2j * np.pi * f)
    P = S @ H if model.form == "PP" else H @ S
    eig = np.linalg.eigvalsh(0.5 * (P + np.conj(np.swapaxes(P, -1, -2))))
    return (eig[:, 0] / np.abs(eig[:, 1])).min()


@pytest.mark.parametrize("n", [6, 10])
def test_nothing_above_the_band_exceeds_the_exact_envelope(n):
    """Above mode n no entry of any causal form rises above 1.1 times the exact envelope.

    Envelope as in :func:`exact_envelope_ratio` (running maximum of |H_exact| from above),
    checked from half a spacing above mode n to 8 times that frequency. On the nine lines of
    :func:`test_all_forms_range_of_lines` (n = 6; n = 10: the three 10 m lines, the
    lossiest, to keep the suite's time) and the default rig's hoses, forms PQ, QP, PP, QQ.
    PP and QQ also keep their port passive (the fit's constraint, checked here on a
    denser grid than the fit's: :func:`_port_passivity_margin` >= -1e-9). The earlier
    remainder (one pseudo-mode per output, zeta = 0.05, at ~1.75 f_b) peaked at 2-3 times
    the envelope (Dn ~ 0.003: the default supply hose, 777 Hz), up to 9.6 times (Dn = 0.033).
    Measured now: <= 1.075 (n = 6 and 10; the construction bounds it at 1.08 on a coarser
    grid).
    """
    worst = (0.0, None)
    lines = _nine_lines() if n == 6 else [_nine_lines()[k] for k in (2, 5, 8)]
    for line in lines + _default_rig_hoses():
        for form in FORMS:
            model = residue_line(line, n, form)
            ratio, where = exact_envelope_ratio(line, model)
            i, j = np.unravel_index(ratio.argmax(), ratio.shape)
            assert ratio[i, j] <= 1.1, (form, line, (i, j), where[i, j], ratio[i, j])
            if ratio[i, j] > worst[0]:
                worst = (ratio[i, j], (form, line.length, line.diameter, (i, j)))
            if form in ("PP", "QQ"):
                assert _port_passivity_margin(model, line) >= -1e-9, (form, line)
    print(f"\nn = {n}: largest |H_model|/envelope above the band {worst[0]:.3f} at {worst[1]}")


def test_default_supply_hose_has_no_pseudo_resonance():
    """The issue's case: default supply hose, 6 modes, PQ (15.9 mm, 178 MPa: |H12|, |H21| peaked
    at 777 Hz, 2.1-2.2 times the exact highest value above the band).

    Above the band the model now stays below the exact response's largest value there
    (previously 2.1-2.2 times it), and below 1.1 times the envelope everywhere.
    """
    rig_hose = _default_rig_hoses()[0]
    for line in (Line(3.048, 0.0159, rig_hose.fluid, 178e6), rig_hose):
        model = residue_line(line, 6, "PQ")
        fb = resonance_f_max(line, "PQ", 6)
        f = np.linspace(fb, 8 * fb, 4000)
        exact = np.abs(line.transfer(2j * np.pi * f, "PQ")).max(axis=0)
        mod = np.abs(model.transfer(2j * np.pi * f)).max(axis=0)
        print(f"\nsupply hose d = {line.diameter * 1e3:.2f} mm above {fb:.0f} Hz: model/exact "
              f"highest value {np.round(mod / exact, 3).tolist()}")
        assert np.all(mod <= exact)


@pytest.mark.parametrize("form", FORMS)
def test_remainder_well_damped(form):
    """The remainder's poles decay within one wave time L/c and faster than any kept mode.

    The earlier pseudo-mode (zeta = 0.05 at ~1.75 times the band edge) decayed in ~5 L/c,
    as slowly as the retained modes, and rang at its own frequency.
    """
    for line in (_nine_lines()[2], _default_rig_hoses()[0], _nine_lines()[6]):
        for n in (1, 6, 10):
            A, B, C, D, names = residue_realisation(line, n, form)
            tail = [k for k, nm in enumerate(names) if nm.startswith("tail")]
            assert len(tail) == 4 * len(tail_groups(n, form))
            lam_t = np.linalg.eigvals(A[np.ix_(tail, tail)])
            modes = [k for k, nm in enumerate(names) if nm.startswith("mode")]
            lam_m = np.linalg.eigvals(A[np.ix_(modes, modes)])
            rate_t = -lam_t.real * line.wave_time
            assert rate_t.min() > 1.0, (line, n, rate_t.min())          # decays within L/c
            assert rate_t.min() > 3.0 * (-lam_m.real * line.wave_time).max()
            zeta = -lam_t.real / np.abs(lam_t)
            assert zeta.min() > 0.1
