"""numpydoc docstrings of the documented modules, in the manner of python-control's test.

(tests/test_docstrings.py checks the circuit layer's compact docstrings the same way.)

The modules listed in ``docs/numpydoc_modules.txt`` (the list grows as modules are converted)
must have numpydoc docstrings on every public function, class, method and property:

* every argument of the signature is documented under Parameters, and nothing else is;
* every parameter has a description, and a numeric one (float, complex, array) states its
  unit in brackets, ``[Pa]``, ``[m^3/s]``, ``[-]`` for dimensionless;
* a function that returns a value has a Returns section, with a unit for a numeric result;
* the Examples run (doctest) and give the numbers they print.

The API reference (``docs/api``) renders these modules with numpydoc, so a docstring that
fails here would also read wrongly there.
"""
from __future__ import annotations

import ast
import dataclasses
import doctest
import importlib
import inspect
import re
import textwrap
from pathlib import Path

import numpy as np
import pytest
from numpydoc.docscrape import ClassDoc, FunctionDoc

LIST = Path(__file__).resolve().parents[1] / "docs" / "numpydoc_modules.txt"
MODULES = [line.strip() for line in LIST.read_text().splitlines()
           if line.strip() and not line.startswith("#")]

UNIT = re.compile(r"\[[^\]]+\]")
#: Parameter types that are numbers with a physical dimension (or [-])
NUMERIC = re.compile(r"\b(float|complex|array_like|array|ndarray)\b")


def _inherits_its_docstring(cls, mname: str, member) -> bool:
    """True for a method that overrides a documented method of a base class without writing a
    docstring of its own: it reads the base's, which is checked in the base's module (a
    component's ``outputs_of`` documents nothing the engine's ``Component.outputs_of`` does
    not; the API reference shows it as the base's module writes it)."""
    func = member.fget if isinstance(member, property) else getattr(member, "__func__", member)
    if getattr(func, "__doc__", None) is not None:
        return False
    for base in cls.__mro__[1:]:
        inherited = base.__dict__.get(mname)
        if inherited is None:
            continue
        inherited = inherited.fget if isinstance(inherited, property) else \
            getattr(inherited, "__func__", inherited)
        return bool(getattr(inherited, "__doc__", None))
    return False


def _public_members(module):
    """(qualified name, object, kind) of the public API a module defines itself (a method that
    inherits its docstring is the base's: :func:`_inherits_its_docstring`)."""
    out = []
    for name, obj in vars(module).items():
        if name.startswith("_") or getattr(obj, "__module__", None) != module.__name__:
            continue
        if inspect.isfunction(obj):
            out.append((f"{module.__name__}.{name}", obj, "function"))
        elif inspect.isclass(obj):
            out.append((f"{module.__name__}.{name}", obj, "class"))
            for mname, member in vars(obj).items():
                if mname.startswith("_") or _inherits_its_docstring(obj, mname, member):
                    continue
                qual = f"{module.__name__}.{name}.{mname}"
                if isinstance(member, property):
                    out.append((qual, member.fget, "property"))
                elif isinstance(member, (staticmethod, classmethod)):
                    out.append((qual, member.__func__, "method"))
                elif inspect.isfunction(member):
                    out.append((qual, member, "method"))
    return out


def _members():
    items = []
    for modname in MODULES:
        module = importlib.import_module(modname)
        items += _public_members(module)
    return items


MEMBERS = _members()


def _signature_params(obj, kind):
    if kind == "class" and obj.__init__ is object.__init__:
        return []                               # no constructor arguments
    target = obj.__init__ if kind == "class" else obj
    try:
        sig = inspect.signature(target)
    except (TypeError, ValueError):
        return []
    names = []
    for p in sig.parameters.values():
        if p.name in ("self", "cls"):
            continue
        if p.kind is p.VAR_POSITIONAL:
            names.append("*" + p.name)
        elif p.kind is p.VAR_KEYWORD:
            names.append("**" + p.name)
        else:
            names.append(p.name)
    return names


def _documented(doc, fields_too=False):
    """name -> (type, description) of the Parameters section; 'a, b : float' gives both.

    For a dataclass (``fields_too``) the Attributes section documents the constructor too."""
    out = {}
    for p in doc["Parameters"] + doc["Other Parameters"] + (doc["Attributes"] if fields_too else []):
        for name in p.name.split(","):
            out[name.strip()] = (p.type, " ".join(p.desc).strip())
    return out


def _returns_value(func) -> bool:
    """True when the function's own body has ``return <value>`` (not nested functions)."""
    try:
        src = textwrap.dedent(inspect.getsource(func))
    except (OSError, TypeError):
        return False
    tree = ast.parse(src)
    fn = tree.body[0]

    def walk(node):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
                continue
            if isinstance(child, ast.Return) and child.value is not None:
                if not (isinstance(child.value, ast.Constant) and child.value.value is None):
                    return True
            if walk(child):
                return True
        return False

    return walk(fn)


def test_the_list_is_not_empty_and_modules_import():
    assert "hydroline.lines.line" in MODULES and "hydroline.fluid" in MODULES
    assert len(MEMBERS) > 40


@pytest.mark.parametrize("qualname, obj, kind", MEMBERS, ids=[m[0] for m in MEMBERS])
def test_documented(qualname, obj, kind):
    doc_text = inspect.getdoc(obj)
    assert doc_text and doc_text.strip(), f"{qualname}: no docstring"
    if kind == "property":
        return                                  # one line, unit in brackets where it has one
    doc = ClassDoc(obj, config={"show_class_members": False}) if kind == "class" else FunctionDoc(obj)
    assert doc["Summary"], f"{qualname}: no one-line summary"
    documented = _documented(doc, fields_too=kind == "class" and dataclasses.is_dataclass(obj))
    sig = _signature_params(obj, kind)
    missing = [p for p in sig if p.lstrip("*") not in documented and p not in documented]
    assert not missing, f"{qualname}: parameters not documented: {missing}"
    if kind == "class" and dataclasses.is_dataclass(obj):
        documented = {k: v for k, v in documented.items() if k in sig}   # properties may be listed
    extra = [p for p in documented if p not in sig and "*" + p not in sig and "**" + p not in sig
             and p.lstrip("*") not in [s.lstrip("*") for s in sig]]
    assert not extra, f"{qualname}: documented but not in the signature: {extra}"
    for name, (ptype, desc) in documented.items():
        assert desc, f"{qualname}: parameter {name!r} has no description"
        if NUMERIC.search(ptype or ""):
            assert UNIT.search(desc), (f"{qualname}: numeric parameter {name!r} ({ptype}) "
                                       f"states no unit in brackets: {desc!r}")
    if kind in ("function", "method") and _returns_value(obj):
        returns = doc["Returns"] or doc["Yields"]
        assert returns, f"{qualname}: returns a value but has no Returns section"
        for r in returns:
            text = " ".join(r.desc)
            if NUMERIC.search(r.type or "") or NUMERIC.search(r.name or ""):
                assert UNIT.search(text) or UNIT.search(r.type or ""), \
                    f"{qualname}: numeric result {r.name or r.type!r} states no unit"


def test_meta_test_fails_on_an_undocumented_parameter():
    """The check above catches a parameter missing from Parameters, and a missing unit."""
    def orifice(coefficient, opening, pressure_drop):
        """Flow through one metering edge.

        Parameters
        ----------
        coefficient : float
            Valve coefficient, [m^2/(s sqrt(Pa))].
        opening : float
            Spool opening beyond the lap.

        Returns
        -------
        float
            Flow, [m^3/s].
        """
        return coefficient * opening * np.sqrt(pressure_drop)

    orifice.__module__ = "hydroline.fluid"
    with pytest.raises(AssertionError, match="not documented: \\['pressure_drop'\\]"):
        test_documented("orifice", orifice, "function")
    orifice.__doc__ = orifice.__doc__.replace(
        "            Spool opening beyond the lap.",
        "            Spool opening beyond the lap.\n        pressure_drop : float\n"
        "            Drop across the edge, [Pa].")
    with pytest.raises(AssertionError, match="'opening'.*no unit"):
        test_documented("orifice", orifice, "function")


@pytest.mark.parametrize("modname", MODULES)
def test_doctests(modname):
    module = importlib.import_module(modname)
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    with np.printoptions(precision=6, suppress=True, legacy="1.25"):
        for test in finder.find(module, modname):
            runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{modname}: {result.failed} doctest(s) failed (see output)"


def test_some_examples_reproduce_exact_model_numbers():
    """The converted modules carry Examples; at least these have one."""
    from hydroline.fluid import effective_bulk_modulus
    from hydroline.lines import Line, ModalLine, correction_factors

    for obj in (effective_bulk_modulus, Line, correction_factors, ModalLine):
        assert ">>>" in (inspect.getdoc(obj) or ""), obj.__qualname__


def test_an_override_is_checked_unless_it_reads_its_base_docstring():
    """A method without a docstring that overrides a documented one is the base's to check;
    one with its own docstring, or overriding nothing documented, is checked here."""
    class Base:
        def law(self, dp):
            """Base law. (Checked in the base's module.)"""

    class Own(Base):
        def law(self, dp):
            return dp

        def extra(self, dp):
            return dp

    class Written(Base):
        def law(self, dp):
            """Its own law."""
            return dp

    assert _inherits_its_docstring(Own, "law", vars(Own)["law"])
    assert not _inherits_its_docstring(Own, "extra", vars(Own)["extra"])
    assert not _inherits_its_docstring(Written, "law", vars(Written)["law"])
