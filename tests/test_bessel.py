"""hydroline.lines.bessel (NumPy Bessel functions for the line models) against SciPy's, and
against values from tables (Abramowitz & Stegun 9.8, 9.5, 6.4)."""
import math

import numpy as np
import pytest
from scipy import special

from hydroline.lines.bessel import bessel_j01, bessel_j_zeros, polygamma, scaled_bessel_i012

#: Few units in the last place of the largest of I0, I1, I2 at the point, plus the argument's
#: own rounding: ive's phase e^{i Im z} moves by |Im z| eps when z is rounded (SciPy alike)
ULPS = 16


def test_scaled_i012_matches_scipy_over_the_right_half_plane():
    rng = np.random.default_rng(25)
    size = 10 ** rng.uniform(-4, 4, 20000)
    phase = rng.uniform(-np.pi / 2, np.pi / 2, size.size)
    phase[:500], phase[500:1000], phase[1000:1500] = np.pi / 2, -np.pi / 2, np.pi / 4
    z = size * np.exp(1j * phase)
    ours = scaled_bessel_i012(z)
    ref = [special.ive(v, z) for v in range(3)]
    scale = np.sqrt(sum(np.abs(r) ** 2 for r in ref))
    bound = ULPS * np.finfo(float).eps * (1.0 + np.abs(z.imag))
    for v in range(3):
        assert np.all(np.abs(ours[v] - ref[v]) <= bound * scale), v


def test_scaled_i012_table_values():
    # A&S table 9.8: e^-x I0(x), e^-x I1(x) at x = 1 and 10; I2 = I0 - 2 I1/x
    i0, i1, i2 = scaled_bessel_i012(np.array([1.0, 10.0]))
    assert i0.real == pytest.approx([0.4657596077, 0.1278333372], rel=1e-9)
    assert i1.real == pytest.approx([0.2079104154, 0.1212626814], rel=1e-9)
    assert i2.real == pytest.approx(i0.real - 2 * i1.real / np.array([1.0, 10.0]), rel=1e-8)


def test_j01_and_zeros_match_scipy():
    x = np.concatenate([np.linspace(0.0, 2.0, 201), np.linspace(2.0, 20.0, 5001),
                        np.linspace(20.0, 400.0, 5001)])
    j0, j1 = bessel_j01(x)
    assert np.max(np.abs(j0 - special.j0(x))) < 2e-15
    assert np.max(np.abs(j1 - special.j1(x))) < 2e-15
    for order in (0, 2):
        assert bessel_j_zeros(order, 45) == pytest.approx(special.jn_zeros(order, 45),
                                                          rel=1e-15, abs=0)
    # A&S table 9.5: j_{0,1}, j_{2,1}
    assert bessel_j_zeros(0, 1)[0] == pytest.approx(2.4048255577, abs=1e-10)
    assert bessel_j_zeros(2, 1)[0] == pytest.approx(5.1356223018, abs=1e-10)


def test_polygamma_matches_scipy_and_zeta_values():
    x = np.array([0.5, 1.0, 1.5, 6.5, 7.0, 7.5, 12.0, 30.5, 100.5, 1e4])
    for m in (1, 3):
        assert polygamma(m, x) == pytest.approx(special.polygamma(m, x), rel=1e-15)
    # psi1(1) = zeta(2) = pi^2/6, psi3(1) = 6 zeta(4) = pi^4/15
    assert polygamma(1, 1.0) == pytest.approx(math.pi**2 / 6, rel=1e-15)
    assert polygamma(3, 1.0) == pytest.approx(math.pi**4 / 15, rel=1e-15)


def test_a_line_realised_without_scipy_special():
    """A changed-numbers rig realises its lines again: none of it may import scipy.special
    (~0.15-0.3 s of a whole process)."""
    import subprocess
    import sys

    code = ("import sys\n"
            "from hydroline import Fluid\n"
            "from hydroline.lines import Line\n"
            "from hydroline.lines.memo import kept_in_memory\n"
            "from hydroline.lines.residue import residue_realisation\n"
            "from hydroline.lines.corrections import correction_factors\n"
            "with kept_in_memory():\n"
            "    line = Line(2.345, 0.019, Fluid(870.0, 3.2e-5, 1.5e9), bulk_modulus=2.01e8)\n"
            "    residue_realisation(line, 6, 'PQ')\n"
            "    residue_realisation(line, 6, 'QP')\n"
            "    correction_factors(line, 6)\n"
            "print('scipy.special' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"
