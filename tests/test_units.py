"""Units at the edges: hydroline.units.

Expected values are derived by hand from the exact definitions of the units:
1 in = 0.0254 m, 1 lbf = 4.4482216152605 N, so 1 psi = lbf/in^2 = 6894.757293168 Pa;
1 US gal = 231 in^3 = 3.785411784e-3 m^3; 1 L = 1e-3 m^3; 1 St = 1 cm^2/s = 1e-4 m^2/s.
"""
import doctest
import math

import pint
import pytest

import hydroline.units
from hydroline.units import UnitError, format_quantity, parse_quantity, ureg

PSI = 4.4482216152605 / 0.0254**2          # [Pa], exact by definition
US_GALLON = 231 * 0.0254**3                # [m^3], exact by definition


@pytest.mark.parametrize("text, unit, expected", [
    ("3.048 m", "m", 3.048),
    ("3.048m", "m", 3.048),
    ("12.7mm", "m", 0.0127),
    ("0.5 in", "m", 0.0127),                          # 0.5 * 0.0254
    ("3000 psi", "Pa", 3000 * PSI),                   # = 20.684e6 Pa
    ("1000 psi", "Pa", 1000 * PSI),                   # = 6.895e6 Pa
    ("2.07e8Pa", "Pa", 2.07e8),
    ("207 bar", "Pa", 2.07e7),
    ("19 L/min", "m^3/s", 19e-3 / 60),                # = 3.1667e-4 m^3/s
    ("5 gpm", "m^3/s", 5 * US_GALLON / 60),           # = 3.1545e-4 m^3/s
    ("50 mA", "A", 0.05),
    ("32 cSt", "m^2/s", 3.2e-5),
    ("140 Hz", "Hz", 140.0),
    ("10 kN", "N", 1e4),
    ("870 kg/m^3", "kg/m^3", 870.0),
    ("2 kg", "kg", 2.0),
    ("1.5 L", "m^3", 1.5e-3),
    ("1 N*s/mm", "N*s/m", 1e3),
    ("1 N/mm", "N/m", 1e3),
    ("3 m/s", "m/s", 3.0),
    ("5 ms", "s", 5e-3),
    ("1 L/min/bar", "m^3/s/Pa", 1e-3 / 60 / 1e5),
    ("2 bar*s/L", "Pa*s/m^3", 2e5 / 1e-3),
])
def test_parse_quantity_hand_derived(text, unit, expected):
    assert parse_quantity(text, unit, "x") == pytest.approx(expected, rel=1e-12)


def test_the_numbers_quoted_in_the_brief():
    assert parse_quantity("3000 psi", "Pa") == pytest.approx(20.684e6, rel=1e-4)
    assert parse_quantity("19 L/min", "m^3/s") == pytest.approx(3.1667e-4, rel=1e-4)
    assert parse_quantity("5 gpm", "m^3/s") == pytest.approx(3.1545e-4, rel=1e-4)
    assert parse_quantity("32 cSt", "m^2/s") == pytest.approx(3.2e-5, rel=1e-12)
    assert parse_quantity("0.5 in", "m") == pytest.approx(0.0127, rel=1e-12)


def test_gpm_is_the_us_gallon_per_minute():
    # 1 gpm = 231 in^3/min; the imperial gallon (4.546 L) would give 7.577e-5 m^3/s
    assert parse_quantity("1 gpm", "m^3/s") == pytest.approx(6.30901964e-5, rel=1e-9)


def test_pint_quantities_are_accepted_from_any_registry():
    assert parse_quantity(ureg.Quantity(3, "ft"), "m") == pytest.approx(0.9144, rel=1e-12)
    other = pint.UnitRegistry()
    assert parse_quantity(other.Quantity(1, "inch"), "m") == pytest.approx(0.0254, rel=1e-12)


@pytest.mark.parametrize("value, expected", [
    (0.85, 0.85), (2, 2.0), ("0.85", 0.85), ("1e3", 1e3), ("50 %", 0.5),
])
def test_bare_numbers_only_for_dimensionless(value, expected):
    for unit in ("dimensionless", "-", "1", ""):
        assert parse_quantity(value, unit, "x") == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("value", [3.048, 3, "3.048", " 3.048 "])
def test_bare_number_for_a_length_is_ambiguous(value):
    with pytest.raises(UnitError) as err:
        parse_quantity(value, "m", "supply.section1.length")
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith("supply.section1.length: bare number 3")
    assert "ambiguous" in msg and "m'" in msg


def test_bare_number_message_is_exact():
    with pytest.raises(UnitError, match=r"^supply\.section1\.length: bare number 3\.048 is "
                                        r"ambiguous, give a unit like '3\.048 m'$"):
        parse_quantity(3.048, "m", "supply.section1.length")


def test_wrong_dimension_names_parameter_value_and_dimension():
    with pytest.raises(UnitError) as err:
        parse_quantity("3000 psi", "m", "supply.section1.length")
    msg = str(err.value)
    assert msg.startswith("supply.section1.length:")
    assert "3000 psi" in msg and "[length]" in msg and "\n" not in msg


@pytest.mark.parametrize("value, unit", [
    ("3 m", "dimensionless"),      # dimensional value for a pure number
    ("50 %", "m"),                 # a dimensionless unit is not a length
    ("abc", "m"),                  # unknown unit
    ("1 foo", "m"),
    ("3 m +", "m"),                # unparseable
    ("", "m"),
    ("nan m", "m"),
    ("inf Pa", "Pa"),
    ("-inf Pa", "Pa"),
    (float("nan"), "-"),
    (float("inf"), "-"),
    (True, "-"),                   # booleans are not numbers here
    ([1.0], "m"),
    (None, "m"),
    ("100 rad/s", "Hz"),           # pint would say 100 Hz: wrong by 2 pi
    ("600 rpm", "Hz"),             # pint would say 62.8 Hz, it is 10 Hz
    ("10 Hz", "rad/s"),
])
def test_rejections_are_unit_errors_naming_the_parameter(value, unit):
    with pytest.raises(UnitError) as err:
        parse_quantity(value, unit, "rig.param")
    assert str(err.value).startswith("rig.param: ")
    assert "\n" not in str(err.value)
    assert isinstance(err.value, ValueError)


def test_unknown_target_unit_is_an_error():
    with pytest.raises(UnitError):
        parse_quantity("3 m", "furlongz", "x")


def test_angles_convert_among_themselves():
    assert parse_quantity("180 deg", "rad") == pytest.approx(math.pi, rel=1e-12)


def test_format_quantity():
    assert format_quantity(3000 * PSI, "Pa", "MPa") == "20.7 MPa"
    assert format_quantity(19e-3 / 60, "m^3/s", "L/min", 4) == "19 L/min"
    assert format_quantity(2.07e7, "Pa", "bar", 3) == "207 bar"
    assert format_quantity(0.0127, "m") == "0.0127 m"
    assert format_quantity(0.5, "-") == "0.5"
    with pytest.raises(UnitError):
        format_quantity(1.0, "Pa", "m")
    with pytest.raises(ValueError):
        format_quantity(1.0, "Pa", "MPa", 0)
    with pytest.raises(UnitError):
        format_quantity(float("nan"), "Pa", "MPa")


def test_docstring_examples():
    result = doctest.testmod(hydroline.units, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0 and result.attempted > 0


# ---- issue 14: the strict grammar (pint alone misread every one of these)
@pytest.mark.parametrize("text, unit, why", [
    ("20,7 MPa", "Pa", "decimal comma"),         # pint: 207 MPa
    ("MPa", "Pa", "no number"),                  # pint: 1 MPa
    ("cm^2", "m^2", "no number"),                # pint: 1 cm^2
    ("2 3 m", "m", "more than one number"),      # pint: 6 m
    ("20.7 MPa 3", "Pa", "more than one number"),  # pint: 62.1 MPa
    ("9**9**9 m", "m", "exponent of an exponent"),  # pint: hangs
    ("3 N m", "N*m", "join units with '*'"),     # juxtaposed units
    ("nan Pa", "Pa", "not a finite number"),
])
def test_strict_grammar_refuses_with_the_text_quoted(text, unit, why):
    with pytest.raises(UnitError) as err:
        parse_quantity(text, unit, "rig.param")
    msg = str(err.value)
    assert msg.startswith(f"rig.param: cannot read {text!r}: ") and why in msg
    assert "expected one number and one unit" in msg and "\n" not in msg


def test_a_100000_digit_number_is_refused_at_once():
    import time

    text = "1" * 100_000 + " m"
    tic = time.perf_counter()
    with pytest.raises(UnitError, match=r"^x: '1{20}'\.\.\. is 100002 characters long; a quantity "
                                        r"has at most 80"):
        parse_quantity(text, "m", "x")
    assert time.perf_counter() - tic < 1.0       # was 98 s


@pytest.mark.parametrize("text, unit, expected", [
    ("-5 mm", "m", -5e-3),                       # accepted here, refused later by its range
    ("2 m**3", "m^3", 2.0),
    ("1.5e9 Pa", "Pa", 1.5e9),
    ("1.25e9 Pa*s/m^3", "Pa*s/m^3", 1.25e9),
    ("9.81 m/s^2", "m/s^2", 9.81),
    ("+3 m", "m", 3.0),
    (".5 m", "m", 0.5),
    ("5 1/s", "Hz", 5.0),
])
def test_strict_grammar_keeps_ordinary_quantities(text, unit, expected):
    assert parse_quantity(text, unit, "x") == pytest.approx(expected, rel=1e-12)
