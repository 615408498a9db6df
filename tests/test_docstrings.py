"""Docstrings in the manner of python-control's meta-tests: every public function and method
of the package (the names in each module's ``__all__``, walked over all modules), and every
public class's constructor, documents every parameter, with its unit where it is a quantity
(a float, complex or array parameter needs a ``[unit]``, ``[-]`` when dimensionless), and
every declared component parameter has a unit and a description."""
import dataclasses
import importlib
import inspect
import pkgutil
import re

import pytest

import hydroline
from hydroline.circuit.types import COMPONENT_TYPES

#: Modules other developers are editing right now (the lead includes them after merging).
EXCLUDED = (
    "hydroline.__main__",            # the ``python -m hydroline`` entry point, no API
)


def _excluded(modname: str) -> bool:
    return any(modname == e or modname.startswith(e + ".") for e in EXCLUDED)


#: Every module of the package, walked (a new module is checked without being listed)
MODULES = ["hydroline"] + sorted(
    m.name for m in pkgutil.walk_packages(hydroline.__path__, "hydroline.")
    if not _excluded(m.name))


def _documented(doc: str) -> dict:
    """name -> its whole entry (the ``name : type`` line and its continuation lines), from the
    numpydoc Parameters (and Other Parameters) sections.

    Both layouts are read: the compact one (``p : float   Pressure, [Pa]`` on one line, maybe
    continued on deeper-indented lines) and the numpydoc one (description on the next lines).
    ``a, b : float`` documents both names."""
    doc = inspect.cleandoc(doc)
    out = {}
    for m in re.finditer(r"^(?:Other )?Parameters\n-+\n(.*?)(?=\n\s*\n\w[\w ]*\n-+\n|\Z)", doc,
                         re.S | re.M):
        names = []
        for line in m.group(1).splitlines():
            head = re.match(r"(\*{0,2}\w+(?:\s*,\s*\*{0,2}\w+)*)\s*:(?:\s|$)", line)
            if head and not line[:1].isspace():
                names = [n.strip().lstrip("*") for n in head.group(1).split(",")]
                for name in names:
                    out[name] = line
            elif not line[:1].isspace():
                names = []                          # a line at the left edge ends the entry
            else:
                for name in names:
                    out[name] += "\n" + line
    return out


def _class_doc(cls) -> str | None:
    """The docstrings of a class and its bases in the package, each Attributes section read
    as Parameters: a constructor argument is documented where the class (or the base that
    declares it, e.g. a component's ``name``) lists it."""
    own = cls.__doc__
    if not own:
        return None
    docs = [inspect.cleandoc(b.__doc__) for b in cls.__mro__
            if b.__module__.startswith("hydroline") and b.__doc__]
    return "\n\n".join(re.sub(r"^Attributes\n(?=-+\n)", "Parameters\n", d, flags=re.M)
                       for d in docs)


def _public_functions():
    for modname in MODULES:
        mod = importlib.import_module(modname)
        # public: the names in __all__, and any other name without "_" the module defines
        names = list(getattr(mod, "__all__", []))
        names += [n for n, o in vars(mod).items() if not n.startswith("_") and n not in names
                  and getattr(o, "__module__", None) == modname]
        for name in names:
            obj = getattr(mod, name)
            if _excluded(getattr(obj, "__module__", None) or ""):
                continue                    # a re-export of an excluded module's name
            if inspect.isfunction(obj):
                yield f"{modname}.{name}", obj, obj.__doc__
            elif inspect.isclass(obj):
                if inspect.isfunction(obj.__init__):            # a constructor of its own
                    yield f"{modname}.{name}", obj, _class_doc(obj)
                for mname, meth in vars(obj).items():
                    if inspect.isfunction(meth) and not mname.startswith("_"):
                        # an override of the component protocol is documented on the base
                        doc = meth.__doc__ or next((getattr(b, mname).__doc__ for b in obj.__mro__[1:]
                                                    if getattr(getattr(b, mname, None), "__doc__", None)), None)
                        yield f"{modname}.{name}.{mname}", meth, doc
                    if isinstance(meth, (classmethod, staticmethod)) and not mname.startswith("_"):
                        yield f"{modname}.{name}.{mname}", meth.__func__, meth.__func__.__doc__


CASES = list(_public_functions())


@pytest.mark.parametrize("name, func, doc", CASES, ids=[c[0] for c in CASES])
def test_every_parameter_documented_with_its_unit(name, func, doc):
    params = [p for p in inspect.signature(func).parameters.values()
              if p.name not in ("self", "cls") and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
    assert doc, f"{name}: no docstring"
    if not params:
        return
    documented = _documented(doc)
    for p in params:
        assert p.name in documented, f"{name}: parameter '{p.name}' not documented"
        entry = documented[p.name]
        head = entry.splitlines()[0]
        if re.search(r":\s*(float|complex|ndarray|array_like|array)\b", head):
            assert re.search(r"\[[^\]]+\]", entry), \
                f"{name}: numeric parameter '{p.name}' gives no unit: {entry.strip()}"


@pytest.mark.parametrize("tname", list(COMPONENT_TYPES))
def test_every_declared_parameter_has_unit_and_description(tname):
    """Declared once: each parameter of each circuit component type has a unit (or "-",
    "str") and a description, and its default meets its own bounds."""
    t = COMPONENT_TYPES[tname]
    for key, decl in t.declarations().items():
        assert decl.unit and decl.description, f"{tname}.{key}"
        if decl.default is not None and decl.default is not dataclasses.MISSING:
            assert decl.violation(decl.default) is None, f"{tname}.{key} default {decl.default!r}"


def test_the_walk_covers_the_package():
    """Every module found except the excluded ones; each exclusion names a real module."""
    assert {"hydroline.units", "hydroline.rigs.parameters", "hydroline.traces.peaks",
            "hydroline.fmu.plant", "hydroline.lines.modal", "hydroline.system"} <= set(MODULES)
    assert not any(_excluded(m) for m in MODULES)
    found = {m.name for m in pkgutil.walk_packages(hydroline.__path__, "hydroline.")}
    for e in EXCLUDED:
        assert e in found, f"EXCLUDED names {e}, which is no module of the package"
    assert len(CASES) > 200


def test_meta_test_catches_a_missing_parameter_or_unit():
    """The check fails on an undocumented parameter and on a numeric one without a unit, and
    accepts both docstring layouts (unit at the end of the line or on a continuation line,
    ``a, b : float`` for two)."""
    def orifice(coefficient, opening, pressure_drop):
        """Flow through one metering edge.

        Parameters
        ----------
        coefficient : float   Valve coefficient, [m^2/(s sqrt(Pa))]
        opening : float       Spool opening beyond the lap, [m]
        """

    with pytest.raises(AssertionError, match="'pressure_drop' not documented"):
        test_every_parameter_documented_with_its_unit("orifice", orifice, orifice.__doc__)
    orifice.__doc__ = orifice.__doc__.replace(
        "[m]\n", "[m]\n        pressure_drop : float Drop across the edge, [Pa]\n")
    test_every_parameter_documented_with_its_unit("orifice", orifice, orifice.__doc__)
    orifice.__doc__ = orifice.__doc__.replace(", [m^2/(s sqrt(Pa))]", "")
    with pytest.raises(AssertionError, match="'coefficient' gives no unit"):
        test_every_parameter_documented_with_its_unit("orifice", orifice, orifice.__doc__)

    def edge(alpha, beta, drop):
        """Two layouts.

        Parameters
        ----------
        alpha, beta : float
            Correction factors of the mode, [-]
        drop : float   Pressure drop across the edge, measured between the two
                       tappings upstream and downstream, [Pa]

        Returns
        -------
        float  Flow, [m^3/s]
        """

    test_every_parameter_documented_with_its_unit("edge", edge, edge.__doc__)
    assert set(_documented(edge.__doc__)) == {"alpha", "beta", "drop"}
