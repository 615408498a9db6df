"""A table of the common engineering units, for reading simple quantities without pint.

Loading pint and building its registry costs about half a second of start-up, more than a
cached simulation. Nearly every quantity hydroline reads is one number and a product of
common units (``"20.7 MPa"``, ``"12.7 mm"``, ``"1.25e9 Pa*s/m^3"``, ``"19 L/min"``), so
:func:`si_value` converts those with this table and answers ``None`` for anything else
(an unknown unit, an angle, a bare number for a dimensional parameter, a dimension mismatch,
text off the simple grammar); :func:`hydroline.units.parse_quantity` then asks pint, which
also words the error messages. The table's factors are the exact SI definitions pint uses
(international inch, avoirdupois pound, standard gravity, US liquid gallon), and the suite
checks every entry against pint.
"""
from __future__ import annotations

import math
import re

__all__ = ["UNITS", "si_value", "unit_factor"]

# Dimension vectors: exponents of (m, kg, s, A).
_L, _M, _T, _I = (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)
_NONE = (0, 0, 0, 0)


def _dim(*pairs):
    out = [0, 0, 0, 0]
    for vec, power in pairs:
        for k in range(4):
            out[k] += vec[k] * power
    return tuple(out)


_PRESSURE = _dim((_M, 1), (_L, -1), (_T, -2))
_FORCE = _dim((_M, 1), (_L, 1), (_T, -2))
_VOLUME = _dim((_L, 3))
_VISCOSITY = _dim((_L, 2), (_T, -1))
_INCH = 0.0254                   # [m], international inch
_POUND = 0.45359237              # [kg], avoirdupois pound
_G0 = 9.80665                    # [m/s^2], standard gravity
_GALLON = 231 * _INCH**3         # [m^3], US liquid gallon = 3.785411784e-3 m^3

#: Unit name -> (factor to SI [SI/unit], dimension exponents of (m, kg, s, A)).
UNITS: dict[str, tuple[float, tuple]] = {
    "in": (_INCH, _L), "inch": (_INCH, _L), "ft": (12 * _INCH, _L), "foot": (12 * _INCH, _L),
    "kg": (1.0, _M), "lb": (_POUND, _M),
    "min": (60.0, _T), "h": (3600.0, _T), "hour": (3600.0, _T),
    "psi": (_POUND * _G0 / _INCH**2, _PRESSURE), "atm": (101325.0, _PRESSURE),
    "lbf": (_POUND * _G0, _FORCE),
    "gal": (_GALLON, _VOLUME), "gallon": (_GALLON, _VOLUME),
    "gpm": (_GALLON / 60.0, _dim((_L, 3), (_T, -1))),
    "%": (0.01, _NONE),
}
_PREFIXES = {"": 1.0, "G": 1e9, "M": 1e6, "k": 1e3, "c": 1e-2, "m": 1e-3, "u": 1e-6,
             "\u00b5": 1e-6, "\u03bc": 1e-6, "n": 1e-9}
for _base, (_f, _d) in {"m": (1.0, _L), "g": (1e-3, _M), "s": (1.0, _T), "Pa": (1.0, _PRESSURE),
                         "bar": (1e5, _PRESSURE), "N": (1.0, _FORCE), "L": (1e-3, _VOLUME),
                         "l": (1e-3, _VOLUME), "Hz": (1.0, _dim((_T, -1))), "A": (1.0, _I),
                         "St": (1e-4, _VISCOSITY)}.items():
    for _p, _pf in _PREFIXES.items():
        UNITS.setdefault(_p + _base, (_pf * _f, _d))   # "min", "kg" keep their own meaning
UNITS["kg"] = (1.0, _M)

_NUMBER = r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d{1,3})?"
_FACTOR = r"([A-Za-z%\u00b5\u03bc]+)(?:\s*(?:\^|\*\*)\s*([+-]?\d))?"
_SIMPLE = re.compile(rf"^\s*({_NUMBER})\s*((?:{_FACTOR})(?:\s*[*/]\s*{_FACTOR})*)?\s*$")
_FACTOR_RE = re.compile(rf"([*/]?)\s*{_FACTOR}")
_DIMENSIONLESS = {"", "-", "1", "dimensionless"}
_CACHE: dict[str, tuple[float, tuple] | None] = {}


def unit_factor(text: str) -> tuple[float, tuple] | None:
    """``(factor to SI, dimension exponents of (m, kg, s, A))`` of a unit expression such as
    ``"Pa*s/m^3"`` (factors joined by ``*`` and ``/``, left to right, one integer exponent
    each), or None when a name is not in :data:`UNITS`.

    Parameters
    ----------
    text : str
        The unit expression, e.g. ``"MPa"``, ``"L/min"``, ``"Pa*s/m^3"``

    Returns
    -------
    tuple or None
        ``(factor, (m, kg, s, A))``: multiply a value in ``text`` by ``factor`` for
        SI; the exponents of metre, kilogram, second and ampere
    """
    text = text.strip()
    if text in _CACHE:
        return _CACHE[text]
    out = None
    if text in _DIMENSIONLESS:
        out = (1.0, _NONE)
    elif re.fullmatch(rf"{_FACTOR}(?:\s*[*/]\s*{_FACTOR})*", text):
        factor, dims = 1.0, [0, 0, 0, 0]
        for op, name, power in _FACTOR_RE.findall(text):
            entry = UNITS.get(name)
            if entry is None:
                break
            e = int(power or 1) * (-1 if op == "/" else 1)
            factor *= entry[0] ** e
            for k in range(4):
                dims[k] += entry[1][k] * e
        else:
            out = (factor, tuple(dims))
    if len(_CACHE) < 1000:
        _CACHE[text] = out
    return out


def si_value(text, unit: str) -> float | None:
    """The quantity ``text`` (``"NUMBER UNIT"``) in the SI unit ``unit``, or None when this
    table cannot say for sure (then ask pint: it reads more and explains refusals).

    Parameters
    ----------
    text : str or float
        E.g. ``"20.7 MPa"``, ``"1.25e9 Pa*s/m^3"``, ``"0.85"``; a plain
        number only for a dimensionless ``unit``, [any unit]
    unit : str
        The SI unit wanted, e.g. ``"Pa"``; ``"-"`` or ``"dimensionless"``, [-]

    Returns
    -------
    float or None
        The value in ``unit``, [unit]
    """
    if not isinstance(text, str):
        if isinstance(text, (int, float)) and not isinstance(text, bool) \
                and str(unit).strip() in _DIMENSIONLESS and math.isfinite(text):
            return float(text)
        return None
    if len(text) > 80:
        return None
    m = _SIMPLE.match(text)
    if m is None:
        return None
    target = unit_factor(str(unit))
    given = unit_factor(m.group(2) or "")
    if target is None or given is None or given[1] != target[1]:
        return None
    if not m.group(2) and target[1] == _NONE and str(unit).strip() not in _DIMENSIONLESS:
        return None   # a bare number for a unit that only looks dimensionless: pint decides
    value = float(m.group(1)) * (given[0] / target[0])
    return value if math.isfinite(value) else None
