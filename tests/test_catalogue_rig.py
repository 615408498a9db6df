"""The paper's rig from catalogue data (issue 30 item 4), the viscoelastic wall's frequency
shift in a rig, and the actuator's natural frequency with entrained air.

The catalogue rig (``hydroline/rigs/ayalew2005_catalogue.toml``) takes no value fitted to the
paper's traces; its numbers are checked by hand from the sources its comments cite, and its
port frequencies against the band those sources allow (docs/model.md 7).
"""
import re
from pathlib import Path

import numpy as np
import pytest

from hydroline import MINERAL_OIL, load_rig, simulate, summarize
from hydroline.lines import Line, ModalLine
from hydroline.lines.compare import compare_resonances

RIG_FILE = Path(__file__).parents[1] / "hydroline" / "rigs" / "ayalew2005_catalogue.toml"
SECTIONS = ("supply.section1", "supply.section2", "return.section1", "return.section2")

#: The cited inputs: SAE J517 100R2 -8 nominal ID 1/2 in; oil in wire-braided hose
#: 0.1 ... 0.5 GPa (McCloy & Martin 1980); oil 1.5 GPa (the default rig's datasheet value);
#: dynamic / static wall modulus 1.5, assumed in the 1 ... 2 range (Johnston et al. 2010:
#: "significantly and consistently higher").
BORE = 0.5 * 0.0254
STATIC_RANGE = (0.1e9, 0.5e9)
OIL = 1.5e9
RATIO, RATIO_RANGE = 1.5, (1.0, 2.0)
#: The paper's measured open-loop baseline (docs/model.md 7): port frequency [Hz], amplitude [MPa]
MEASURED = {"supply": (40.0, 1.0), "return": (31.0, 0.94)}


def hose_moduli(static, ratio, oil=OIL):
    """Instantaneous modulus beta_e [Pa] and creep compliance J [1/Pa] of oil in a hose whose
    oil-filled static modulus is ``static`` and whose wall is ``ratio`` times stiffer
    dynamically than statically (compliances in series, docs/model.md 10)."""
    wall_static = 1.0 / (1.0 / static - 1.0 / oil)
    wall_dynamic = ratio * wall_static
    return 1.0 / (1.0 / oil + 1.0 / wall_dynamic), 1.0 / wall_static - 1.0 / wall_dynamic


def test_catalogue_rig_values_carry_their_sources_and_none_is_fitted():
    """Every value line of the file names its provenance, none is ``[calibrated]``, and the
    rig loads on the default base."""
    tags = ("[paper]", "[datasheet]", "[assumed]", "[textbook]")
    table, values = None, 0
    for line in RIG_FILE.read_text().splitlines():
        code = line.split("#", 1)[0].strip()
        if code.startswith("["):
            table = code
        elif "=" in code and table != "[rig]":      # [rig]: the base and a label
            values += 1
            comment = line.split("#", 1)[1] if "#" in line else ""
            assert any(t in comment for t in tags), line
            assert "[calibrated]" not in comment, line
    assert values == 19
    rig = load_rig("ayalew2005_catalogue")
    assert rig["fluid.air_content"] == 0.005 and rig["fluid.cavity_pressure"] == 5e3
    assert rig["actuator.moving_mass"] == load_rig(None)["actuator.moving_mass"]


def test_catalogue_hose_numbers_follow_from_the_cited_inputs():
    """Bore 1/2 in; beta_e and J from the geometric middle of the static range and the 1.5
    dynamic/static wall ratio, to the file's 4 digits; their sum is the static modulus."""
    rig = load_rig("ayalew2005_catalogue")
    beta_e, J = hose_moduli(np.sqrt(STATIC_RANGE[0] * STATIC_RANGE[1]), RATIO)
    # by hand: wall_s = 1/(1/223.6e6 - 1/1.5e9) = 262.8 MPa, wall_d = 394.2 MPa
    assert beta_e == pytest.approx(312.1e6, rel=2e-4) and J == pytest.approx(1.268e-9, rel=5e-4)
    for sec in SECTIONS:
        assert rig[f"{sec}.diameter"] == pytest.approx(BORE, rel=1e-12)
        assert rig[f"{sec}.bulk_modulus"] == pytest.approx(beta_e, rel=2e-4)
        (j,), (tau,) = rig[f"{sec}.creep_compliances"], rig[f"{sec}.retardation_times"]
        assert j == pytest.approx(J, rel=5e-4) and tau == 0.1
        static = 1.0 / (1.0 / rig[f"{sec}.bulk_modulus"] + j)
        assert static == pytest.approx(np.sqrt(STATIC_RANGE[0] * STATIC_RANGE[1]), rel=5e-4)


def test_catalogue_wall_is_within_the_residue_lines_accuracy():
    """beta_e J = 0.40 lies above the ~0.3 up to which docs/model.md 10 vouches for the
    viscoelastic residue line; with this slow element (1/tau = 10 1/s, below the modal band)
    the line still meets its own bound against the exact viscoelastic four-pole (resonances
    within 0.1 % in frequency, 1 % in peak), PQ and PP."""
    line = Line(length=3.048, diameter=BORE, fluid=MINERAL_OIL, bulk_modulus=312.1e6,
                creep_compliances=(1.268e-9,), retardation_times=(0.1,))
    for form in ("PQ", "PP"):
        m = ModalLine(line, 6, form, method="residue")
        assert np.max(m.eigenvalues().real) < 0
        for r in compare_resonances(line, m, 6):
            assert abs(r.frequency_error_pct) < 0.1
            assert abs(r.magnitude_error_pct) < 1.0


@pytest.fixture(scope="module")
def catalogue_summary():
    return summarize(simulate(load_rig("ayalew2005_catalogue"), "open-loop-step"))


def test_catalogue_rig_frequencies_lie_in_the_band_its_data_allow(catalogue_summary):
    """The measured 40 / 31 Hz lie within the band the hose data's ranges allow about the
    catalogue rig's own frequencies: the line modulus beta_e spans [100, 750] MPa over the
    static range 0.1 ... 0.5 GPa and the ratio range 1 ... 2 (by hand: beta_e(0.1 GPa, 1) =
    0.1 GPa, beta_e(0.5 GPa, 2) = 750 MPa), and a port frequency moves at most like the hoses'
    wave speed, ``f ~ sqrt(beta_e)`` (elasticity 0.5; the rig's own is 0.35 / 0.43, docs/model.md
    7, as the valve and accumulators do not scale with c). The band is not tuned: it is the
    data's. The catalogue rig lands 24 % / 41 % above the measured frequencies (docs)."""
    lo, _ = hose_moduli(STATIC_RANGE[0], RATIO_RANGE[0])
    hi, _ = hose_moduli(STATIC_RANGE[1], RATIO_RANGE[1])
    nominal, _ = hose_moduli(np.sqrt(STATIC_RANGE[0] * STATIC_RANGE[1]), RATIO)
    assert lo == pytest.approx(100e6) and hi == pytest.approx(750e6)
    band = (np.sqrt(lo / nominal), np.sqrt(hi / nominal))        # 0.566 ... 1.550
    for side, (f_measured, _) in MEASURED.items():
        f = catalogue_summary[side]["frequency_hz"]
        assert band[0] < f_measured / f < band[1], (side, f)
        # and the data alone do not reproduce the paper: the rig is stiffer than measured
        assert f > f_measured


def test_viscoelastic_shift_is_the_dynamic_modulus():
    """The wall's shift of the supply-port frequency in the default rig (both supply sections,
    J = 5e-10 1/Pa, tau = 20 ms) is that of an elastic rig at the line's modulus at the
    oscillation frequency, ``beta / Re(sqrt(W(j omega)))^2`` (M44, the phase speed), over the
    summary's metrics window: within a tenth of the shift. (The shift is 0.14 %, not the
    0.2 % of a bare half-wave line: the port frequency rises with beta at elasticity 0.35,
    not 0.5; an estimate over only the first 70 ms had read half of it, docs/model.md 10.)"""
    beta, J, tau = 203.8e6, 5e-10, 0.02
    base = load_rig(None)

    def supply_frequency(**values):
        rig = base.copy()
        for sec in ("supply.section1", "supply.section2"):
            for key, value in values.items():
                rig.set(f"{sec}.{key}", value)
        return summarize(simulate(rig, "open-loop-step"))["supply"]["frequency_hz"]

    f_el = supply_frequency()
    w = 2 * np.pi * f_el
    beta_dyn = beta / np.sqrt(1 + beta * J / (1 + 1j * w * tau)).real ** 2
    f_dyn = supply_frequency(bulk_modulus=f"{float(beta_dyn)!r} Pa")
    f_ve = supply_frequency(creep_compliances=[f"{J!r} 1/Pa"], retardation_times=[f"{tau!r} s"])
    assert f_dyn < f_el * (1 - 1e-3)          # the dynamic modulus is 0.4 % below beta
    assert abs(f_ve - f_dyn) < 0.1 * (f_el - f_dyn)


def test_actuator_natural_frequency_takes_the_entrained_air():
    """``w_h^2 = (A_b^2 K_b/V_b + A_t^2 K_t/V_t)/m`` with K the oil-air modulus (M40) at the
    chamber's mean pressure; by hand for the default rig with 1 % isothermal air at the
    chambers' 11.1 MPa rest pressure (the actuator's nominal pressure once placed):
    ``v_L = 0.99 exp(-(11.1e6 - 101325)/689.5e6)``, ``v_g = 0.01 * 101325/11.1e6``,
    ``K = (v_L + v_g)/(v_L/689.5e6 + v_g/11.1e6)`` = 685.6 MPa, so 172.00 Hz * sqrt(K/beta_c);
    air-free, the rig's 172 Hz unchanged."""
    from hydroline.system import build_circuit

    def actuator(rig):
        return next(c for c in build_circuit(rig).components if c.name == "actuator")

    plain = actuator(load_rig(None))
    assert plain.hydraulic_natural_frequency(0.0) == pytest.approx(172.0, abs=0.01)
    rig = load_rig(None).set("fluid.air_content", 0.01)
    act = actuator(rig)
    p, K_L, p0 = act.nominal_pressure, 689.5e6, 101325.0
    assert p == pytest.approx(11.1e6, rel=1e-3)
    v_l, v_g = 0.99 * np.exp(-(p - p0) / K_L), 0.01 * p0 / p
    K = (v_l + v_g) / (v_l / K_L + v_g / p)
    assert K == pytest.approx(685.6e6, rel=1e-4)
    hand = plain.hydraulic_natural_frequency(0.0) * np.sqrt(K / K_L)
    assert act.hydraulic_natural_frequency(0.0) == pytest.approx(hand, rel=1e-9)
    # explicit chamber pressures: at 1 MPa the air is 10x larger a share
    v_l, v_g = 0.99 * np.exp(-(1e6 - p0) / K_L), 0.01 * p0 / 1e6
    K1 = (v_l + v_g) / (v_l / K_L + v_g / 1e6)
    assert act.hydraulic_natural_frequency(0.0, 1e6, 1e6) == pytest.approx(
        plain.hydraulic_natural_frequency(0.0) * np.sqrt(K1 / K_L), rel=1e-9)
