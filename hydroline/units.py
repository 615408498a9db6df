"""Quantities with units at the edges of hydroline.

Inside hydroline every number is a float in SI units (see ``fluid.py``). Units appear only
where numbers come in from people -- rig files, the command line, notebooks -- and where they
go back out to people. This module converts at those edges with one shared pint
:data:`ureg` and refuses anything ambiguous:

* a bare number for a dimensional parameter (``3.048`` for a length) is an error, because
  "3.048" in a rig file could be metres or feet or inches; write ``"3.048 m"``;
* a value of the wrong dimension (``"3000 psi"`` for a length) is an error;
* NaN and infinite values are errors;
* text must follow one strict grammar (:data:`QUANTITY_GRAMMAR`): one number (optional sign,
  decimal point, optional exponent ``e-3``), then at most one unit expression: unit names
  joined by ``*`` or ``/``, each with at most one exponent (``m^3``, ``m**3``, ``s^-1``).
  Anything else is refused with a message that quotes the text: a decimal comma
  (``"20,7 MPa"``), a unit without a number (``"MPa"``), two numbers (``"2 3 m"``,
  ``"20.7 MPa 3"``), units side by side without ``*`` (``"N m"``), exponent towers
  (``"9**9**9 m"``) and text longer than :data:`MAX_QUANTITY_LENGTH` characters. (pint alone
  reads ``"20,7 MPa"`` as 207 MPa, ``"MPa"`` as 1 MPa and ``"2 3 m"`` as 6 m.)

Every error is a :class:`UnitError` (a :class:`ValueError`) whose message is one line naming
the parameter, so that a rig file with thirty entries points at the wrong one.

Units beyond pint's defaults
----------------------------
``gpm``
    US gallon per minute, 3.785411784e-3 m^3 / 60 s = 6.30901964e-5 m^3/s (pint's
    ``gallon`` is the US liquid gallon of 231 in^3).
``cSt``
    centistokes, 1e-6 m^2/s (pint's ``stokes`` with the SI prefix ``c``).

Pressures
---------
Pressures are taken as given: hydroline has no notion of gauge pressure, and every pressure
in a rig file is absolute unless that rig file says otherwise. Convert gauge readings yourself
(add the atmospheric 101325 Pa) before they go in; pint's ``psi`` and ``bar`` carry no gauge
offset.

Angular and cyclic frequency
----------------------------
pint treats the radian as dimensionless, so it would convert ``"100 rad/s"`` to ``100 Hz``
and ``"1 rpm"`` to ``0.105 Hz``. Both are wrong by 2 pi. :func:`parse_quantity` therefore
refuses to convert between units with and without angles (``rad/s`` or ``rpm`` given where
``Hz`` is expected) instead of silently returning the wrong number.
"""
from __future__ import annotations

import math
import numbers
import re
import reprlib

from .unit_table import si_value

__all__ = ["ureg", "UnitError", "parse_quantity", "format_quantity", "convert_quantity",
           "exact_quantity",
           "split_header", "csv_column", "csv_unit_factor", "QUANTITY_GRAMMAR", "MAX_QUANTITY_LENGTH"]



def _load_pint():
    """Import pint and build :data:`ureg`, the one unit registry of hydroline (quantities
    from other registries are re-read into it), on first use: about half a second that a
    run whose quantities the unit table reads (:mod:`hydroline.unit_table`) never pays."""
    global pint, ureg
    if "ureg" in globals():
        return
    import pint as _pint

    registry = _pint.UnitRegistry()
    if "gpm" not in registry:
        # US liquid gallon per minute; pint's ``gallon`` is the US liquid gallon (231 in^3).
        registry.define("gallon_per_minute = gallon / minute = gpm")
    pint, ureg = _pint, registry


def __getattr__(name):   # PEP 562: hydroline.units.ureg / .pint load pint when first asked for
    if name in ("ureg", "pint"):
        _load_pint()
        return globals()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

#: Unit strings that mean "no unit".
_DIMENSIONLESS = {"", "-", "1", "dimensionless"}


class UnitError(ValueError):
    """A value that cannot be read as a quantity of the expected unit.

    Parameters
    ----------
    *args : str
        The message: one line naming the parameter and the expected unit.
    **kwargs : dict
        None taken (as ``ValueError``).
    """


#: Longest quantity text read, [characters]: a quantity is a number and a unit, not a
#: document (a 100,000-digit number would otherwise take minutes to parse).
MAX_QUANTITY_LENGTH = 80

_NUMBER = r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d{1,4})?"
_UNIT_NAME = r"[A-Za-z_\u00b5\u03bc\u2126%][A-Za-z_\u00b5\u03bc\u2126]*"
_POWER = r"(?:\s*(?:\^|\*\*)\s*[+-]?\d{1,2}(?:\.\d{1,4})?)?"
_FACTOR = _UNIT_NAME + _POWER
_UNIT_EXPR = rf"(?:1\s*/\s*)?{_FACTOR}(?:\s*[*/]\s*{_FACTOR})*"
#: The grammar of a quantity in text: ``NUMBER [UNIT]``, e.g. ``"20.7 MPa"``, ``"1.5e9 Pa"``,
#: ``"19 L/min"``, ``"-5 mm"``, ``"1.25e9 Pa*s/m^3"``, ``"0.85"`` (a regular expression).
QUANTITY_GRAMMAR = rf"^\s*(?P<number>{_NUMBER})\s*(?P<unit>{_UNIT_EXPR})?\s*$"
_QUANTITY_RE = re.compile(QUANTITY_GRAMMAR)
_NUMBER_RE = re.compile(rf"^\s*{_NUMBER}")


def _grammar_error(name: str, text: str, target_text: str) -> UnitError:
    """The one-line reason why ``text`` is not ``NUMBER [UNIT]``."""
    example = f"'20.7 MPa'" if target_text == "Pa" else f"'1.5 {target_text}'"
    expected = f"expected one number and one unit, like {example}"
    if target_text == "dimensionless":
        expected = "expected one plain number, like '0.85'"
    if len(text) > MAX_QUANTITY_LENGTH:
        return UnitError(f"{name}: {text[:20]!r}... is {len(text)} characters long; a quantity "
                         f"has at most {MAX_QUANTITY_LENGTH} ({expected})")
    shown = repr(text)
    if re.match(r"^\s*[+-]?(nan|inf)", text, re.IGNORECASE):
        why = "not a finite number"
    elif re.search(r"\d,\d", text):
        why = "a decimal comma; write a decimal point"
    elif not _NUMBER_RE.match(text):
        why = "no number before the unit" if re.match(r"^\s*[A-Za-z_%]", text) else "no number"
    elif re.search(r"\*\*[^*]*\*\*|\^[^^]*\^|\*\*[^*]*\^|\^[^^*]*\*\*", text):
        why = "an exponent of an exponent"
    elif len(re.findall(_NUMBER, re.sub(r"(\^|\*\*)\s*[+-]?[\d.]+", "", text))) > 1 \
            and not re.search(r"[eE][+-]?\d", text.split()[-1] if text.split() else ""):
        why = "more than one number"
    else:
        why = "not NUMBER UNIT (join units with '*' or '/', one exponent each: 'Pa*s/m^3')"
    return UnitError(f"{name}: cannot read {shown}: {why}; {expected}")


def _read_text(name: str, text: str, target_text: str) -> pint.Quantity:
    """Parse ``NUMBER [UNIT]`` (:data:`QUANTITY_GRAMMAR`) into a Quantity of :data:`ureg`."""
    if len(text) > MAX_QUANTITY_LENGTH:
        raise _grammar_error(name, text, target_text)
    match = _QUANTITY_RE.match(text)
    if match is None:
        raise _grammar_error(name, text, target_text)
    number = float(match["number"])
    unit = match["unit"]
    if unit is None:
        return ureg.Quantity(number, ureg.dimensionless)
    try:
        units = ureg.parse_units(unit.replace("**", "^"))
    except Exception as exc:  # pint raises a zoo of exception types on bad input
        detail = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise UnitError(f"{name}: cannot read {text!r} as a quantity in {target_text}: "
                        f"unknown unit {unit!r} ({detail})") from None
    return ureg.Quantity(number, units)


def _target_units(unit: str) -> pint.Unit:
    """Parse the SI unit a caller asks for (a programming error if it fails)."""
    _load_pint()
    if unit is None or str(unit).strip() in _DIMENSIONLESS:
        return ureg.dimensionless
    try:
        return ureg.parse_units(str(unit).strip())
    except (pint.errors.PintError, AttributeError, TypeError, ValueError, SyntaxError) as exc:
        raise UnitError(f"unknown target unit {unit!r}: {exc}") from None


def _angle_exponent(units: pint.Unit) -> float:
    """Exponent of the radian in the root units (0 for Hz, 1 for rad/s and rpm)."""
    root = ureg.Quantity(1.0, units).to_root_units()
    return float(dict(root.unit_items()).get("radian", 0.0))


def _finite(name: str, magnitude, shown) -> float:
    try:
        value = float(magnitude)
    except (TypeError, ValueError):
        raise UnitError(f"{name}: {shown!r} is not a single number") from None
    if not math.isfinite(value):
        raise UnitError(f"{name}: {shown!r} is not finite")
    return value


def parse_quantity(value, unit: str, name: str = "value") -> float:
    """Read a number with a unit and return it as a float in the SI unit ``unit``.

    Parameters
    ----------
    value : str, pint.Quantity, int or float
        The quantity, e.g. ``"3.048 m"``, ``"12.7mm"``, ``"3000 psi"``, ``"19 L/min"``,
        ``"5 gpm"``, ``"32 cSt"`` or a pint Quantity; [any unit of the dimension of ``unit``].
        A bare number (``3.048`` or ``"3.048"``) is accepted only when ``unit`` is
        dimensionless; ``"50 %"`` is then 0.5.
    unit : str
        The SI unit wanted, e.g. ``"Pa"``, ``"m^3/s"``, ``"N*s/m"``, ``"m^3/s/Pa"``, ``"Hz"``;
        ``"dimensionless"`` (or ``"-"``, ``"1"``, ``""``) for a pure number, [-].
    name : str
        Dotted name of the parameter, used in error messages, e.g.
        ``"supply.section1.length"``, [-].

    Returns
    -------
    float
        The value expressed in ``unit``, [unit]

    Raises
    ------
    UnitError
        On a bare number for a dimensional parameter, a wrong dimension, an angular unit
        where a cyclic one is expected (or the reverse), an unparseable string, a non-scalar
        value, NaN or infinity. The message is one line that starts with ``name``.

    Examples
    --------
    >>> parse_quantity("3000 psi", "Pa", "supply.pressure")  # 3000 * 6894.757 Pa
    20684271.879...
    >>> parse_quantity("19 L/min", "m^3/s", "pump.flow")  # 19e-3 m^3 / 60 s
    0.000316666...
    >>> parse_quantity(3.048, "m", "supply.section1.length")
    Traceback (most recent call last):
    ...
    hydroline.units.UnitError: supply.section1.length: bare number 3.048 is ambiguous, give a unit like '3.048 m'
    """
    if isinstance(value, (str, int, float)):   # "NUMBER UNIT" in common units: no pint needed
        fast = si_value(value, unit)
        if fast is not None:
            return fast
    _load_pint()
    target = _target_units(unit)
    target_text = "dimensionless" if target == ureg.dimensionless else str(unit).strip()
    dimensionless_target = target.dimensionless

    if isinstance(value, bool):
        raise UnitError(f"{name}: {value!r} is not a quantity")

    if isinstance(value, pint.Quantity):
        quantity = value
        if quantity._REGISTRY is not ureg:  # a Quantity from someone else's registry
            try:
                quantity = ureg.Quantity(quantity.magnitude, str(quantity.units))
            except pint.errors.PintError as exc:
                raise UnitError(f"{name}: cannot read {value!r} ({exc})") from None
        shown = str(quantity)
    elif isinstance(value, numbers.Real):
        quantity = ureg.Quantity(_finite(name, value, value), ureg.dimensionless)
        shown = value
    elif isinstance(value, str):
        text = value.strip()
        if not text:
            raise UnitError(f"{name}: empty string, expected a quantity in {target_text}")
        quantity = _read_text(name, text, target_text)
        shown = text
    else:
        raise UnitError(f"{name}: {reprlib.repr(value)} ({type(value).__name__}) is not a "
                        f"quantity, expected a string like '1 {target_text}'")

    magnitude = _finite(name, quantity.magnitude, shown)

    if quantity.units == ureg.dimensionless and not dimensionless_target:
        number = f"{magnitude:g}"
        raise UnitError(f"{name}: bare number {number} is ambiguous, give a unit like "
                        f"'{number} {target_text}'")

    if quantity.dimensionality != target.dimensionality:
        given = "dimensionless" if quantity.dimensionless else str(quantity.dimensionality)
        expected = ("dimensionless (a plain number)" if dimensionless_target
                    else f"{target.dimensionality} (a unit like {target_text})")
        raise UnitError(f"{name}: {shown!r} has dimension {given}, expected {expected}")

    if _angle_exponent(quantity.units) != _angle_exponent(target):
        raise UnitError(f"{name}: {shown!r} mixes angular and cyclic units; give it in a unit "
                        f"like {target_text} (1 Hz = 2*pi rad/s = 60 rpm)")

    try:
        result = float(quantity.to(target).magnitude)
    except pint.errors.PintError as exc:  # e.g. offset units such as degC in products
        raise UnitError(f"{name}: cannot convert {shown!r} to {target_text} ({exc})") from None
    if not math.isfinite(result):
        raise UnitError(f"{name}: {shown!r} is not finite in {target_text}")
    return result


def exact_quantity(value_si: float, unit: str) -> str:
    """An SI value as rig-file text that reads back to the same float, e.g. ``"0.0127 m"``.

    Parameters
    ----------
    value_si : float
        The value in ``unit``, [unit]
    unit : str
        Its SI unit, e.g. ``"Pa"``, [-]

    Returns
    -------
    str
        ``"<repr of the float> <unit>"`` (every digit kept, unlike :func:`format_quantity`)

    Examples
    --------
    >>> exact_quantity(203.8e6, "Pa")
    '203800000.0 Pa'
    """
    return f"{float(value_si)!r} {unit}"


def format_quantity(value_si: float, unit: str, display_unit: str | None = None,
                    digits: int = 3) -> str:
    """Format an SI value for people, e.g. ``20.7e6`` Pa as ``"20.7 MPa"``.

    Parameters
    ----------
    value_si : float
        The value in ``unit``, [unit]
    unit : str
        The unit ``value_si`` is in, e.g. ``"Pa"``, [-]
    display_unit : str
        The unit to show, e.g. ``"MPa"``, ``"bar"``, ``"L/min"``; None shows
        ``unit``, [-]
    digits : int
        Significant digits, >= 1, [-]

    Returns
    -------
    str
        ``"<number> <display_unit>"``, the number with ``digits`` significant digits

    Examples
    --------
    >>> format_quantity(20.684e6, "Pa", "MPa")
    '20.7 MPa'
    >>> format_quantity(3.1667e-4, "m^3/s", "L/min", 4)
    '19 L/min'
    """
    if isinstance(digits, bool) or not isinstance(digits, numbers.Integral) or digits < 1:
        raise ValueError(f"digits must be an integer >= 1, got {digits!r}")
    shown_unit = str(unit).strip() if display_unit is None else str(display_unit).strip()
    shown = convert_quantity(value_si, unit, shown_unit)
    text = f"{shown:.{int(digits)}g}"
    return f"{text} {shown_unit}" if shown_unit not in _DIMENSIONLESS else text


def convert_quantity(value_si: float, unit: str, display_unit: str) -> float:
    """An SI value in another unit of its dimension, e.g. ``2.951e-3`` m^3 in L: ``2.951``.

    Parameters
    ----------
    value_si : float
        The value in ``unit``, [unit]
    unit : str
        The unit ``value_si`` is in, e.g. ``"m^3"``, [-]
    display_unit : str
        The unit wanted, e.g. ``"L"``, [-]

    Returns
    -------
    float
        The value in ``display_unit``, [display_unit]

    Raises
    ------
    UnitError
        ``display_unit`` of another dimension, or mixing angular and cyclic units.

    Examples
    --------
    >>> convert_quantity(2.5e7, "Pa", "MPa")
    25.0
    """
    value = _finite("value_si", value_si, value_si)
    _load_pint()
    source, target = _target_units(unit), _target_units(display_unit)
    if source.dimensionality != target.dimensionality:
        raise UnitError(f"display_unit: {display_unit!r} is not of the dimension of {unit!r}")
    if _angle_exponent(source) != _angle_exponent(target):
        raise UnitError(f"display_unit: {display_unit!r} mixes angular and cyclic units "
                        f"with {unit!r}")
    return float(ureg.Quantity(value, source).to(target).magnitude)


def split_header(col) -> tuple[str, str | None]:
    """``"pressure [MPa]"`` -> ``("pressure", "MPa")``; ``(name, None)`` without brackets.

    Parameters
    ----------
    col : str
        A column header (anything ``str()`` accepts), e.g. ``"time [ms]"``

    Returns
    -------
    tuple
        ``(name, unit)``: the header's name and the unit text between the brackets, or
        None when it has none
    """
    text = str(col).strip()
    if "[" not in text or not text.endswith("]"):
        return text, None
    name, _, unit = text[:-1].partition("[")
    return name.strip(), unit.strip()


def csv_unit_factor(col, unit: str, src: str, example: str | None = None) -> float:
    """The factor that converts a CSV column whose header carries its unit to SI.

    Parameters
    ----------
    col : str
        Column header, e.g. ``"time [ms]"``
    unit : str
        SI unit the column must convert to (dimension check)
    src : str
        File name, for the messages
    example : str
        Name to suggest in the no-unit message (the header's name if None)

    Returns
    -------
    float
        The column's values times this are in ``unit``, [unit / header's unit]

    Raises
    ------
    ValueError
        One line naming the file and the column: a header without a unit, or one of
        another dimension
    """
    name, u = split_header(col)
    if u is None:
        raise ValueError(f"{src}: column '{col}' has no unit; write e.g. '{example or name} [{unit}]'")
    try:
        return parse_quantity(f"1 {u}", unit, f"{src}: column '{col}'")
    except UnitError as e:
        raise ValueError(str(e)) from None


def csv_column(raw, col, unit: str, src: str, example: str | None = None):
    """One column of a CSV table whose header carries its unit, converted to SI.

    Parameters
    ----------
    raw : pandas.DataFrame
        The table as read
    col : str
        Column header, e.g. ``"time [ms]"``
    unit : str
        SI unit the column must convert to (dimension check)
    src : str
        File name, for the messages
    example : str
        Name to suggest in the no-unit message (the header's name if None)

    Returns
    -------
    ndarray
        The values, [unit]

    Raises
    ------
    ValueError
        One line naming the file, the column and, for a bad value, its row
    """
    import numpy as np
    import pandas as pd

    factor = csv_unit_factor(col, unit, src, example)
    values = pd.to_numeric(raw[col], errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        k = int(bad[0])
        raise ValueError(f"{src}: column '{col}' has a missing, NaN or non-numeric value at data "
                         f"row {k + 1} (file line {k + 2}): '{raw[col].iloc[k]}'")
    return values * factor
