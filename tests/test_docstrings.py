"""Docstrings in the manner of python-control's meta-tests: every public function of the
circuit layer documents every parameter, with its unit where it is a quantity, and every
declared component parameter has a unit and a description."""
import dataclasses
import importlib
import inspect
import re

import pytest

from hydroline.circuit.types import COMPONENT_TYPES

MODULES = ["hydroline.circuit.builder", "hydroline.circuit.types", "hydroline.circuit.drawing",
           "hydroline.engine.component", "hydroline.components.pump",
           "hydroline.components.relief_valve", "hydroline.engine.network",
           "hydroline.engine.steady_state", "hydroline.engine.backends",
           "hydroline.engine.integrate", "hydroline.engine.result", "hydroline.traces.metrics"]


def _documented(doc: str) -> dict:
    """name -> its line, from the numpydoc Parameters section."""
    m = re.search(r"Parameters\n\s*-+\n(.*?)(\n\s*\n\s*\w+\n\s*-+\n|\Z)", doc, re.S)
    if not m:
        return {}
    out = {}
    for line in m.group(1).splitlines():
        head = re.match(r"\s*([\w, ]+?)\s*:\s*(.*)", line)
        if head and not line.startswith(" " * 12):
            for name in head.group(1).split(","):
                out[name.strip()] = line
    return out


def _public_functions():
    for modname in MODULES:
        mod = importlib.import_module(modname)
        for name in getattr(mod, "__all__", []):
            obj = getattr(mod, name)
            if inspect.isfunction(obj):
                yield f"{modname}.{name}", obj, obj.__doc__
            elif inspect.isclass(obj):
                for mname, meth in vars(obj).items():
                    if inspect.isfunction(meth) and not mname.startswith("_"):
                        # an override of the component protocol is documented on the base
                        doc = meth.__doc__ or next((getattr(b, mname).__doc__ for b in obj.__mro__[1:]
                                                    if getattr(getattr(b, mname, None), "__doc__", None)), None)
                        yield f"{modname}.{name}.{mname}", meth, doc
                    if isinstance(meth, classmethod) and not mname.startswith("_"):
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
        line = documented[p.name]
        if re.search(r":\s*float\b", line):
            assert "[" in line, f"{name}: float parameter '{p.name}' gives no unit: {line.strip()}"


@pytest.mark.parametrize("tname", list(COMPONENT_TYPES))
def test_every_declared_parameter_has_unit_and_description(tname):
    """Declared once: each parameter of each circuit component type has a unit (or "-",
    "str") and a description, and its default meets its own bounds."""
    t = COMPONENT_TYPES[tname]
    for key, decl in t.declarations().items():
        assert decl.unit and decl.description, f"{tname}.{key}"
        if decl.default is not None and decl.default is not dataclasses.MISSING:
            assert decl.violation(decl.default) is None, f"{tname}.{key} default {decl.default!r}"
