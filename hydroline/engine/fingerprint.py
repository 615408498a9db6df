"""What a network's compiled graph is a function of, known before the graph is built.

The CasADi graph of :meth:`Network.compile` (and the C code and constants written from it)
is made by evaluating every component's equations on symbols. It depends on

* each component's class and everything the instance holds: structural options, the
  numbers compiled as constants (areas, lengths, a hose's modal matrices, ...), the values
  of its runtime parameters (kept too: a component may also read one as a constant), its
  name and its wiring (``connections``);
* the public class-level data of those classes (``inputs``, ``outputs``, ``feedthrough``,
  ``RAMP_ROWS``, ...), which a program may change at run time;
* the code: the source of every module that defines one of those classes (a component's
  own, its base classes', a hose's line model's), of the modules they use, and of the engine
  modules that assemble the graph; and what is bound in place of that source at run time:
  where each method of those classes and each function of those modules was defined, and
  their modules' plain constants (a patched method or a rebound constant changes the key);
* the order of the components, the state scales, and the state, parameter and signal names.

:func:`definition_fingerprint` hashes all of it (SHA-256), so that a compiled model recorded
under the fingerprint can be loaded without building the graph. It is conservative: it
gives None (no fingerprint: the caller builds the graph) wherever it cannot be sure, i.e.
an attribute it cannot describe by value (a function, an open file, an object of a class
outside hydroline, a reference cycle), a class defined outside hydroline's package or inside
a function, or a source file changed after this process loaded its code.
"""
from __future__ import annotations

import hashlib
import os
import sys
import time
import types
from functools import cached_property
from pathlib import Path

import numpy as np

from .component import NUMBER_MARK, State

__all__ = ["definition_fingerprint", "components_signature", "module_source_tag",
           "module_bindings", "used_modules", "GRAPH_MODULES"]

#: The modules that turn components into the graph (their code is in every fingerprint).
GRAPH_MODULES = ("hydroline.engine.component", "hydroline.engine.network",
                 "hydroline.engine.ops", "hydroline.engine.fingerprint")
#: Package whose classes and modules a fingerprint can describe.
PACKAGE = "hydroline"
#: Deepest nesting of attributes described, [-] (deeper: no fingerprint).
MAX_DEPTH = 32
#: When this process loaded its code (this module comes with the engine, which a component
#: module imports before its own code runs): a source file modified later may not be the
#: code that runs, [s since the epoch].
LOADED_AT = time.time()


class Undescribable(Exception):
    """Part of a network that cannot be described by value (no fingerprint).

    Parameters
    ----------
    *args : str
        The message: the part.
    **kwargs : dict
        None taken (as ``Exception``).
    """


def _in_package(module_name: str) -> bool:
    return module_name == PACKAGE or module_name.startswith(PACKAGE + ".")


_TAGS: dict = {}


def module_source_tag(name: str) -> str:
    """SHA-256 of a loaded module's source file (read once per process and file version).

    Parameters
    ----------
    name : str
        Module name, e.g. ``"hydroline.components.servovalve"``

    Returns
    -------
    str
        hex digest

    Raises
    ------
    Undescribable
        The module has no file, or its file was modified after this process
        loaded its code (the code that runs may not be the file's)
    """
    path = getattr(sys.modules.get(name), "__file__", None)
    if not path:
        raise Undescribable(f"module {name} has no source file")
    try:
        st = os.stat(path)
        if st.st_mtime > LOADED_AT:
            raise Undescribable(f"{path} changed after this process loaded it")
        version = (path, st.st_mtime_ns, st.st_size)
        tag = _TAGS.get(version)
        if tag is None:
            tag = _TAGS[version] = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError as e:
        raise Undescribable(f"{path}: {e}") from None
    return tag


_USES: dict = {}


def used_modules(name: str) -> frozenset:
    """The hydroline modules that module ``name`` refers to by a global (an imported module,
    function or class), and those they refer to, and so on; ``name`` included.

    Parameters
    ----------
    name : str
        Module name

    Returns
    -------
    frozenset of str
        Module names.
    """
    out = _USES.get(name)
    if out is None:
        seen, todo = set(), [name]
        while todo:
            m = todo.pop()
            if m in seen:
                continue
            seen.add(m)
            module = sys.modules.get(m)
            for value in vars(module).values() if module is not None else ():
                if isinstance(value, types.ModuleType):
                    other = value.__name__
                elif isinstance(value, (type, types.FunctionType)):
                    other = getattr(value, "__module__", None) or ""
                else:
                    continue
                if _in_package(other) and other not in seen:
                    todo.append(other)
        out = _USES[name] = frozenset(seen)
    return out


#: Values that stand for themselves in a description: their repr is exact and says their
#: type (floats round-trip; 1, 1.0, True and '1' differ).
_PLAIN = frozenset({type(None), bool, int, float, complex, str, bytes})


class _Mark:
    """A part of a description that is no Python literal, written ``<...>``: no literal's
    repr has ``<`` outside quotes, so marks cannot be confused with values."""

    __slots__ = ("text",)

    def __init__(self, text: str):
        self.text = text

    def __repr__(self):
        return self.text


_CLASSES: dict = {}


def _class_info(c: type):
    """(mark, attribute names not described, slot names) of a class whose bases are all
    hydroline's (or Python's own); Undescribable otherwise."""
    info = _CLASSES.get(c)
    if info is None:
        skip, slots = set(), []
        for base in c.__mro__:
            mod = base.__module__
            if mod == "builtins":
                continue
            if not _in_package(mod) or "<locals>" in base.__qualname__:
                raise Undescribable(f"class {mod}.{base.__qualname__}")
            slots += [n for n in getattr(base, "__slots__", ()) if isinstance(n, str)]
            for name, attr in vars(base).items():
                if isinstance(attr, cached_property):    # cached values: derived from the rest
                    skip.add(name)
        info = _CLASSES[c] = (_Mark(f"<object {c.__module__}.{c.__qualname__}>"),
                              frozenset(skip), tuple(slots))
    return info


def _class_data(c: type) -> dict:
    """A class's own public class-level data (a program may change it at run time): not its
    methods, properties or other descriptors, nor nested classes."""
    return {name: attr for name, attr in vars(c).items()
            if not name.startswith("_") and not isinstance(attr, type)
            and not hasattr(attr, "__get__")}


def _function_name(f) -> str:
    """Where a function (or method) was defined: a replacement bound in its place at run time
    (a patched method, a rebound module function) names another place."""
    f = getattr(f, "__func__", f)          # staticmethod, classmethod, bound method
    return f"{getattr(f, '__module__', None)}.{getattr(f, '__qualname__', type(f).__qualname__)}"


def _class_code(c: type) -> list:
    """Where each function in a class's own namespace was defined (methods, properties,
    cached properties): the class's source is tagged, but a method replaced at run time is
    not in it."""
    out = []
    for name, attr in vars(c).items():
        if isinstance(attr, property):
            attr = attr.fget
        elif isinstance(attr, cached_property):
            attr = attr.func
        if callable(attr) and not isinstance(attr, type):
            out.append((name, _function_name(attr)))
    return sorted(out)


def module_bindings(name: str) -> list:
    """What a loaded module's global names are bound to now: functions and classes by where
    they were defined, modules by name, plain values (numbers, text) by value, anything else
    by its type. The module's source is tagged (:func:`module_source_tag`); a name rebound at
    run time (a patched function or constant) is not in it. (Data changed in place, e.g. an
    array of the module, is not seen: a component keeps its data as attributes.)

    Parameters
    ----------
    name : str
        Module name

    Returns
    -------
    list
        ``(name, value)`` of a plain value, ``(name, kind, where)`` of anything else.
    """
    out = []   # (name, value) of a plain value, (name, kind, where) of anything else
    for key, value in vars(sys.modules[name]).items():
        if key[:2] == "__":
            continue
        t = type(value)
        if t in _PLAIN:
            out.append((key, value))
        elif t is types.FunctionType or t is types.BuiltinFunctionType:
            out.append((key, "function", f"{value.__module__}.{value.__qualname__}"))
        elif t is types.ModuleType:
            out.append((key, "module", value.__name__))
        elif isinstance(value, type):
            out.append((key, "class", f"{value.__module__}.{value.__qualname__}"))
        elif callable(value):
            out.append((key, "function", _function_name(value)))
        else:
            out.append((key, "object", f"{t.__module__}.{t.__qualname__}"))
    out.sort()
    return out


class _Describer:
    """Turns values into a tree of literals (dictionaries in sorted order, objects as their
    class and attributes, arrays as dtype, shape and SHA-256) whose repr describes them
    exactly; collects the classes met. With ``structure``, a state's typical magnitude
    (``State.scale``, which scales the states, not the equations) and its tolerance ceiling
    (``State.atol_ceiling``, which the integrator reads at run time) stand as marks."""

    def __init__(self, structure: bool = False):
        self.classes: dict = {}     # class -> its info
        self.structure = structure

    def register(self, c: type):
        """A class met (and its bases, whose class data it inherits): its info."""
        info = self.classes.get(c)
        if info is None:
            info = self.classes[c] = _class_info(c)
            for base in c.__mro__[1:]:
                if base.__module__ != "builtins" and base not in self.classes:
                    self.classes[base] = _class_info(base)
        return info

    def freeze(self, v, depth: int = 0):
        t = type(v)
        if t in _PLAIN:
            return v
        if depth > MAX_DEPTH:           # (a reference cycle ends here too)
            raise Undescribable("attributes nested too deep")
        depth += 1
        if t is list or t is tuple:
            return t([x if type(x) in _PLAIN else self.freeze(x, depth) for x in v])
        if t is dict:
            items = [(k, x if type(x) in _PLAIN else self.freeze(x, depth)) for k, x in v.items()]
            if all(type(k) is str for k, _ in items):
                return dict(sorted(items))
            return _Mark("<dict " + repr(sorted((repr(self.freeze(k, depth)), repr(x))
                                                for k, x in items)) + ">")
        if t is set or t is frozenset:
            return _Mark("<set " + repr(sorted(repr(self.freeze(x, depth)) for x in v)) + ">")
        if t is np.ndarray:
            if v.dtype.hasobject:
                raise Undescribable("array of objects")
            data = hashlib.sha256(np.ascontiguousarray(v).tobytes()).hexdigest()
            return _Mark(f"<array {v.dtype.descr} {v.shape} {data}>")
        if isinstance(v, np.generic) and not isinstance(v, np.object_):
            return _Mark(f"<scalar {v.dtype.descr} {v.tobytes().hex()}>")
        if isinstance(v, type):
            return self.register(v)[0]
        if _in_package(t.__module__):   # an object of hydroline: its class and attributes
            mark, state = self.object_state(v)
            return (mark, self.freeze(state, depth))
        raise Undescribable(f"{t.__module__}.{t.__qualname__} value")   # a function, ...

    def object_state(self, v):
        """(class mark, attributes described) of an object of a hydroline class: its
        ``__dict__`` and slots, less its cached properties' values."""
        mark, skip, slots = self.register(type(v))
        state = dict(getattr(v, "__dict__", ()))
        for name in slots:
            if name not in state and hasattr(v, name):
                state[name] = getattr(v, name)
        for name in skip & state.keys():
            del state[name]
        if self.structure and isinstance(v, State):
            state["scale"] = NUMBER_MARK
            if state.get("atol_ceiling") is not None:   # (a tolerance too, as the scale)
                state["atol_ceiling"] = NUMBER_MARK
        return mark, state


def components_signature(components, substitute=None) -> str | None:
    """SHA-256 of components described by value, in order: each one's class and attributes
    (as in :func:`definition_fingerprint`, without the code and class data, which one process
    shares). Two lists of equal signature are made of equal components, so their graphs are
    equal. ``substitute(component, attributes)`` may return other attributes to describe in
    place of a component's own (e.g. a hose's matrices by their pattern only, where their
    values are runtime parameters, so that the graph does not depend on them).

    Parameters
    ----------
    components : sequence
        Components (e.g. ``network.components``)
    substitute : callable
        ``(component, dict) -> dict``, or None

    Returns
    -------
    str or None
        hex digest; None where some part cannot be described by value
    """
    d = _Describer()
    try:
        tree = []
        for c in components:
            mark, state = d.object_state(c)
            if substitute is not None:
                state = substitute(c, state)
            tree.append((mark, d.freeze(state)))
    except Undescribable:
        return None
    return hashlib.sha256(repr(tree).encode("utf-8", "surrogatepass")).hexdigest()


def definition_fingerprint(network, structure: bool = False) -> str | None:
    """SHA-256 of everything the network's compiled graph is a function of (see the module
    docstring), without building the graph; None where some part cannot be described by
    value (then only the graph itself can key the model).

    With ``structure``, of everything but the numbers the compiled model takes at run time:
    each component's own numbers (:meth:`~hydroline.engine.Component.structure_attributes`,
    :meth:`~hydroline.engine.Component.compiled_numbers`) and the state scales stand as
    marks, so that networks that differ only in them share the fingerprint (and, where
    their graph takes those numbers as symbols, one compiled library).

    Parameters
    ----------
    network : Network
        The assembled model
    structure : bool
        Leave out the numbers (see above)

    Returns
    -------
    str or None
        hex digest
    """
    d = _Describer(structure)
    try:
        if structure:
            tree = []
            for c in network.components:
                mark, state = d.object_state(c)
                tree.append((mark, d.freeze(c.structure_attributes(state))))
            scales = len(network.state_scales)
        else:
            tree = [d.freeze(c) for c in network.components]
            scales = d.freeze(np.asarray(network.state_scales, dtype=float))
        tree += [list(network.state_names), list(network.parameter_names),
                 list(network.signal_names), scales]
        described = set()
        while len(described) < len(d.classes):   # class data may name further classes
            for c in sorted(set(d.classes) - described, key=lambda c: d.classes[c][0].text):
                described.add(c)
                tree.append((d.classes[c][0], d.freeze(_class_data(c)), _class_code(c)))
        modules = set()
        for name in sorted({c.__module__ for c in d.classes} | set(GRAPH_MODULES)):
            modules |= used_modules(name)
        # (this module's globals are this process's state, e.g. LOADED_AT: its source only)
        tree.append([(name, module_source_tag(name),
                      module_bindings(name) if name != __name__ else None)
                     for name in sorted(modules)])
    except Undescribable:
        return None
    return hashlib.sha256(repr(tree).encode("utf-8", "surrogatepass")).hexdigest()
