"""The design of a parameter study: which rig parameters vary, over which values.

A *parameter* is one or more rig paths (``supply.section2.bulk_modulus``, or
``supply.section2.length+return.section2.length`` for paths that move together) and either a
list of values or a probability distribution. Values carry units, in the rig file's syntax;
they are read with the unit that :data:`hydroline.rigs.SCHEMA` gives the path, so a bare
number is refused wherever a unit matters.

Value syntax (the text after ``PATH=`` of ``hydroline sweep --set``)
---------------------------------------------------------------------

=================================  ===========================================================
text                               values
=================================  ===========================================================
``150 MPa,178 MPa,220 MPa``        levels of a full factorial (one value: a constant override)
``linspace(150 MPa, 220 MPa, 8)``  8 evenly spaced levels, ends included
``uniform(LOW, HIGH)``             random: uniform on [LOW, HIGH]
``loguniform(LOW, HIGH)``          random: log-uniform on [LOW, HIGH] (LOW > 0)
``normal(MEAN, STD)``              random: Gaussian (not truncated; a variant drawn outside
                                   the physical range fails with its reason, e.g. a negative
                                   bulk modulus)
``lognormal(MEDIAN, SIGMA)``       random: ``MEDIAN * exp(SIGMA * z)``, z standard normal;
                                   SIGMA is a plain number (the standard deviation of ln X)
``triangular(LOW, MODE, HIGH)``    random: triangular
``choice(V1, V2, ...)``            random: one of the values, equally likely
=================================  ===========================================================

A full factorial takes every combination of the levels; the first parameter varies slowest,
and variant ``i`` is the mixed-radix number of the level indices. A random design
(``samples=N``) draws variant ``i`` from its own random stream ``numpy.random.default_rng(
[seed, i])``, parameters in the order given: a variant does not depend on N, so a sweep of
200 samples extends one of 100 (``--resume``) without recomputing the first 100. There a list
of values is a ``choice`` and a single value a constant.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..rigs import SCHEMA, Rig, RigError

__all__ = ["Parameter", "Design", "Distribution", "parse_parameter", "parse_parameters",
           "parameter_unit", "DISTRIBUTIONS"]

_CALL = re.compile(r"^\s*([A-Za-z_]\w*)\s*\((.*)\)\s*$", re.S)


def parameter_unit(path: str, rig: Rig | None = None) -> str:
    """SI unit of a rig path ("-" dimensionless, "str" text).

    Template paths (``supply.section2.length``) take it from :data:`hydroline.rigs.SCHEMA`;
    circuit paths (``circuit.<component>.<parameter>``) from the declaration of the
    component's type in ``rig`` (:mod:`hydroline.circuit.types`).

    Parameters
    ----------
    path : str
        Dotted rig path
    rig : Rig
        The rig the path belongs to (needed for circuit paths)

    Returns
    -------
    str
        The SI unit, "-" for a dimensionless and "str" for a text parameter.

    Raises
    ------
    RigError
        One line, for a path the rig does not know or that cannot be swept.
    """
    path = path.strip()
    if path.startswith("circuit."):
        return _circuit_unit(path, rig)
    section, _, key = path.rpartition(".")
    if section not in SCHEMA:
        raise RigError(f"{path}: unknown component/section '{section or key}' "
                       f"(known: {', '.join(sorted(SCHEMA))})")
    unit = SCHEMA[section].get(key)
    if unit is None:
        raise RigError(f"{path}: unknown parameter '{key}' of '{section}' "
                       f"(known: {', '.join(sorted(SCHEMA[section]))})")
    if unit.startswith("list:"):
        raise RigError(f"{path}: a list parameter cannot be swept; sweep a scalar parameter")
    return unit


def _circuit_unit(path: str, rig: Rig | None) -> str:
    """The declared SI unit of a circuit component's parameter in ``rig``."""
    from ..circuit import CircuitError, parse_circuit_value

    if rig is None:
        raise RigError(f"{path}: a circuit parameter needs its rig (the component's type "
                       f"declares the unit)")
    parts = path.split(".")
    if parts[-1] == "type" or any(p in ("ports", "terms") for p in parts[2:]):
        raise RigError(f"{path}: a component's type, ports and flow terms are its structure "
                       f"and cannot be swept; sweep a numeric parameter")
    found = []

    def capture(p, raw_value, unit):    # parse_circuit_value's reader: keep the unit
        found.append(unit)
        return raw_value

    try:
        parse_circuit_value(path, None, rig.raw, capture)
    except CircuitError as e:
        raise RigError(f"{str(e)} (rig {rig.source})") from None
    if not found:
        raise RigError(f"{path}: not a parameter of a circuit component of rig {rig.source}")
    unit = found[0]
    if unit.startswith("list:"):
        raise RigError(f"{path}: a list parameter cannot be swept; sweep a scalar parameter")
    return unit


def _read_value(path: str, text, unit: str, rig: Rig | None = None):
    """One value of a parameter, read exactly as :meth:`Rig.set` reads it -> SI float or text."""
    probe = Rig({}, dict(rig.raw) if rig is not None else {}, "--set")
    probe.set(path, text.strip() if isinstance(text, str) else text)
    return probe.values[path]


def _split_args(text: str) -> list[str]:
    parts = [a.strip() for a in text.split(",")]
    return [a for a in parts if a] if len(parts) > 1 or parts[0] else []


@dataclass(frozen=True)
class Distribution:
    """A probability distribution of one parameter, in SI units.

    Attributes
    ----------
    kind : str
        One of :data:`DISTRIBUTIONS`
    args : tuple
        Its arguments in SI units (``lognormal``'s SIGMA dimensionless,
        ``choice``'s the values), [unit of the parameter]
    """

    kind: str
    args: tuple

    def sample(self, rng: np.random.Generator):
        """One draw, [unit of the parameter].

        Parameters
        ----------
        rng : numpy.random.Generator
            The sweep's random generator (seeded: reproducible)

        Returns
        -------
        float or object
            The drawn value, [unit of the parameter] (``choice``: one of its values).
        """
        a = self.args
        if self.kind == "uniform":
            return float(rng.uniform(a[0], a[1]))
        if self.kind == "loguniform":
            return float(math.exp(rng.uniform(math.log(a[0]), math.log(a[1]))))
        if self.kind == "normal":
            return float(rng.normal(a[0], a[1]))
        if self.kind == "lognormal":
            return float(a[0] * math.exp(a[1] * rng.standard_normal()))
        if self.kind == "triangular":
            return float(rng.triangular(a[0], a[1], a[2]))
        if self.kind == "choice":
            return a[int(rng.integers(len(a)))]
        raise ValueError(f"unknown distribution {self.kind!r}")

    def describe(self, unit: str = "") -> str:
        """The distribution as text, e.g. ``uniform(150 MPa, 210 MPa)``.

        Parameters
        ----------
        unit : str
            The parameter's SI unit, shown after each value ("-", "str": none)

        Returns
        -------
        str
            The text.
        """
        u = "" if unit in ("-", "str") else f" {unit}"
        if self.kind == "lognormal":
            return f"lognormal({self.args[0]:g}{u}, {self.args[1]:g})"
        return f"{self.kind}(" + ", ".join(f"{v:g}{u}" if isinstance(v, float) else str(v)
                                           for v in self.args) + ")"


#: Distribution name -> number of arguments (None: one or more).
DISTRIBUTIONS = {"uniform": 2, "loguniform": 2, "normal": 2, "lognormal": 2, "triangular": 3,
                 "choice": None}


@dataclass(frozen=True)
class Parameter:
    """One varied parameter: rig path(s) set together, and its levels or distribution.

    Attributes
    ----------
    paths : tuple[str]
        Rig paths that take the same value
    unit : str
        Their SI unit ("-" dimensionless, "str" text)
    levels : tuple
        Factorial levels in SI (None for a distribution)
    distribution : Distribution
        For random designs (None for levels)
    spec : str
        The values as given (for the results file's header)
    """

    paths: tuple
    unit: str
    levels: tuple | None = None
    distribution: Distribution | None = None
    spec: str = ""

    @property
    def name(self) -> str:
        """The paths joined by ``+`` (as given on the command line)."""
        return "+".join(self.paths)

    def describe(self) -> str:
        """The parameter's levels or distribution as text, with its unit.

        Returns
        -------
        str
            E.g. ``150 MPa, 220 MPa`` or ``uniform(150 MPa, 220 MPa)``.
        """
        if self.distribution is not None:
            return self.distribution.describe(self.unit)
        u = "" if self.unit in ("-", "str") else f" {self.unit}"
        shown = [f"{v:g}{u}" if isinstance(v, float) else str(v) for v in self.levels]
        if len(shown) > 6:
            shown = shown[:3] + [f"... ({len(shown)} levels)"] + shown[-1:]
        return ", ".join(shown)


def _parse_paths(text: str, rig: Rig | None = None) -> tuple:
    paths = tuple(p.strip() for p in text.split("+"))
    if not all(paths):
        raise RigError(f"--set {text}=...: empty parameter path")
    units = {parameter_unit(p, rig) for p in paths}
    if len(units) > 1:
        raise RigError(f"--set {text}: paths set together must share one unit, "
                       f"got {', '.join(sorted(units))}")
    return paths


def parse_parameter(path, values, rig: Rig | None = None) -> Parameter:
    """A :class:`Parameter` from a path (``"a.b.c"`` or ``"a.b.c+d.e.f"``) and its values.

    Parameters
    ----------
    path : str
        Rig path(s), joined by ``+`` to set several to the same value
    values : str, list or Distribution
        Text in the syntax of the module docstring (``"150 MPa,220 MPa"``,
        ``"uniform(150 MPa, 220 MPa)"``), a list of quantities (strings with units, pint
        Quantities, plain numbers for dimensionless parameters), or a :class:`Distribution`
        already in SI units
    rig : Rig
        The rig swept (needed for ``circuit.<component>.<parameter>`` paths, whose
        unit the component's type declares)

    Returns
    -------
    Parameter
        The paths, their SI unit and the levels or distribution.

    Raises
    ------
    RigError, UnitError
        (ValueErrors) One line naming the path and its unit.
    """
    paths = _parse_paths(path, rig)
    unit = parameter_unit(paths[0], rig)
    name = "+".join(paths)
    if isinstance(values, Distribution):
        _check_distribution(name, values, unit)
        return Parameter(paths, unit, distribution=values, spec=values.describe(unit))
    if isinstance(values, (list, tuple)):
        if not values:
            raise RigError(f"{name}: no values given")
        levels = tuple(_read_value(paths[0], v, unit, rig) for v in values)
        return Parameter(paths, unit, levels=levels, spec=",".join(map(str, values)))
    if not isinstance(values, str):
        values = [values]
        return parse_parameter(path, values, rig)
    text = values.strip()
    m = _CALL.match(text)
    if m and m.group(1).lower() in (*DISTRIBUTIONS, "linspace"):
        kind, args = m.group(1).lower(), _split_args(m.group(2))
        if kind == "linspace":
            if len(args) != 3:
                raise RigError(f"{name}: linspace takes (FIRST, LAST, COUNT), got {text!r}")
            a, b = (_read_value(paths[0], v, unit, rig) for v in args[:2])
            n = _count(name, args[2])
            levels = tuple(float(v) for v in np.linspace(a, b, n))
            return Parameter(paths, unit, levels=levels, spec=text)
        if kind == "lognormal":
            if len(args) != 2:
                raise RigError(f"{name}: lognormal takes (MEDIAN, SIGMA), got {text!r}")
            parsed = (_read_value(paths[0], args[0], unit, rig), _plain_number(name, args[1]))
        else:
            n = DISTRIBUTIONS[kind]
            if (n is not None and len(args) != n) or not args:
                raise RigError(f"{name}: {kind} takes {n or 'one or more'} values with units, "
                               f"got {text!r}")
            parsed = tuple(_read_value(paths[0], v, unit, rig) for v in args)
        dist = Distribution(kind, tuple(parsed))
        _check_distribution(name, dist, unit)
        return Parameter(paths, unit, distribution=dist, spec=text)
    if m:
        raise RigError(f"{name}: unknown distribution {m.group(1)!r} "
                       f"(known: {', '.join(DISTRIBUTIONS)}, and linspace for levels)")
    args = _split_args(text)
    if not args:
        raise RigError(f"{name}: no values given")
    return Parameter(paths, unit, levels=tuple(_read_value(paths[0], v, unit, rig) for v in args),
                     spec=text)


def _count(name, text):
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1 or str(n) != text.strip():
        raise RigError(f"{name}: linspace COUNT must be an integer >= 1, got {text!r}")
    return n


def _plain_number(name, text):
    try:
        v = float(text)
    except ValueError:
        raise RigError(f"{name}: lognormal SIGMA is a plain number (std of ln X), got {text!r}") from None
    if not (math.isfinite(v) and v >= 0):
        raise RigError(f"{name}: lognormal SIGMA must be >= 0, got {text!r}")
    return v


def _check_distribution(name, d: Distribution, unit):
    if d.kind not in DISTRIBUTIONS:
        raise RigError(f"{name}: unknown distribution {d.kind!r}")
    if unit == "str" and d.kind != "choice":
        raise RigError(f"{name}: a text parameter takes choice(...), not {d.kind}")
    a = d.args
    if d.kind in ("uniform", "loguniform") and not a[0] < a[1]:
        raise RigError(f"{name}: {d.kind}(LOW, HIGH) needs LOW < HIGH")
    if d.kind == "loguniform" and not a[0] > 0:
        raise RigError(f"{name}: loguniform(LOW, HIGH) needs LOW > 0")
    if d.kind == "normal" and not a[1] > 0:
        raise RigError(f"{name}: normal(MEAN, STD) needs STD > 0")
    if d.kind == "lognormal" and not a[0] > 0:
        raise RigError(f"{name}: lognormal(MEDIAN, SIGMA) needs MEDIAN > 0")
    if d.kind == "triangular" and not (a[0] <= a[1] <= a[2] and a[0] < a[2]):
        raise RigError(f"{name}: triangular(LOW, MODE, HIGH) needs LOW <= MODE <= HIGH, LOW < HIGH")


def parse_parameters(parameters, rig: Rig | None = None) -> list[Parameter]:
    """Parameters from ``["PATH=SPEC", ...]`` (the CLI's ``--set``), a dict ``{PATH: values}``
    or a list of :class:`Parameter`; a path may appear once.

    Parameters
    ----------
    parameters : list or dict
        As :func:`hydroline.studies.sweep` takes them
    rig : Rig
        The rig swept (units of circuit paths)

    Returns
    -------
    list[Parameter]
        The parameters, in the order given.
    """
    out = []
    if isinstance(parameters, dict):
        items = list(parameters.items())
    else:
        items = []
        for p in parameters:
            if isinstance(p, Parameter):
                items.append(p)
            elif isinstance(p, str):
                path, eq, spec = p.partition("=")
                if not eq or not path.strip():
                    raise RigError(f"--set {p!r}: expected PATH=VALUES, e.g. "
                                   f"supply.section2.bulk_modulus=150 MPa,220 MPa")
                items.append((path, spec))
            else:
                items.append(tuple(p))
    for it in items:
        out.append(it if isinstance(it, Parameter) else parse_parameter(*it, rig=rig))
    seen = set()
    for p in out:
        for path in p.paths:
            if path in seen:
                raise RigError(f"{path}: set more than once")
            seen.add(path)
    if not out:
        raise RigError("no parameter to vary: give at least one --set PATH=VALUES")
    return out


@dataclass
class Design:
    """The variants of a study: a full factorial, or ``samples`` random draws.

    Parameters
    ----------
    parameters : list[Parameter]
        The varied parameters (:func:`parse_parameters`).
    samples : int
        Number of random variants; None for the full factorial
    seed : int
        Seed of the random design (variant i uses ``default_rng([seed, i])``)
    """

    parameters: list
    samples: int | None = None
    seed: int = 0
    _sizes: list = field(init=False, repr=False)

    def __post_init__(self):
        if self.samples is None:
            bad = [p for p in self.parameters if p.distribution is not None]
            if bad:
                raise RigError(f"{bad[0].name}: a distribution ({bad[0].spec}) needs a random "
                               f"design: give --samples N")
            self._sizes = [len(p.levels) for p in self.parameters]
        else:
            if int(self.samples) != self.samples or self.samples < 1:
                raise RigError(f"--samples must be an integer >= 1, got {self.samples!r}")
            self.samples = int(self.samples)
        if int(self.seed) != self.seed or self.seed < 0:
            raise RigError(f"--seed must be an integer >= 0, got {self.seed!r}")
        self.seed = int(self.seed)

    @property
    def kind(self) -> str:
        """"factorial" or "random"."""
        return "factorial" if self.samples is None else "random"

    def __len__(self) -> int:
        return math.prod(self._sizes) if self.samples is None else self.samples

    @property
    def columns(self) -> list[str]:
        """One input column per rig path, in parameter order."""
        return [path for p in self.parameters for path in p.paths]

    def variant(self, i: int) -> dict:
        """Rig path -> SI value of variant ``i`` (0-based).

        Parameters
        ----------
        i : int
            Variant number, 0 <= i < len(design)

        Returns
        -------
        dict
            Rig path -> value, [SI]
        """
        if not 0 <= i < len(self):
            raise IndexError(f"variant {i} out of range 0..{len(self) - 1}")
        chosen = []
        if self.samples is None:
            rest = i
            digits = []
            for n in reversed(self._sizes):
                rest, k = divmod(rest, n)
                digits.append(k)
            chosen = [p.levels[k] for p, k in zip(self.parameters, reversed(digits))]
        else:
            rng = np.random.default_rng([self.seed, i])
            for p in self.parameters:
                if p.distribution is not None:
                    chosen.append(p.distribution.sample(rng))
                elif len(p.levels) == 1:
                    chosen.append(p.levels[0])
                else:
                    chosen.append(p.levels[int(rng.integers(len(p.levels)))])
        return {path: v for p, v in zip(self.parameters, chosen) for path in p.paths}

    def __iter__(self):
        return (self.variant(i) for i in range(len(self)))

    def describe(self) -> str:
        """The design as text: full factorial (its sizes) or random samples (count, seed).

        Returns
        -------
        str
            E.g. ``full factorial 3 x 2 = 6 variants`` or ``16 random variants (seed 1)``.
        """
        if self.samples is None:
            if len(self._sizes) == 1:
                return f"full factorial, {len(self)} variants"
            return "full factorial " + " x ".join(str(n) for n in self._sizes) + \
                f" = {len(self)} variants"
        return f"{self.samples} random variants (seed {self.seed})"

    def header(self) -> dict:
        """What identifies the design in a results file (N excluded: samples extend).

        Returns
        -------
        dict
            JSON-ready: the kind, the seed and each parameter's paths, unit, levels or
            distribution.
        """
        return {"kind": self.kind, "seed": self.seed if self.samples is not None else None,
                "parameters": [{"paths": list(p.paths), "unit": p.unit,
                                "levels": None if p.levels is None else list(p.levels),
                                "distribution": None if p.distribution is None else
                                [p.distribution.kind, list(p.distribution.args)]}
                               for p in self.parameters]}
