"""A compiled model found by its definition, before any CasADi graph is built
(hydroline.engine.fingerprint, hydroline.compiled.definition_key).

Checked against independent facts: the CasADi graph itself (equal definitions give equal
graphs, a changed number or structure a new key), the SciPy reference integration of the
per-component Python right-hand side, and a process's own list of loaded modules."""
import json
import os
import subprocess
import sys
from dataclasses import dataclass

import numpy as np
import pytest

from hydroline import compiled
from hydroline.engine import Network, fingerprint, integrate, solve_steady_state
from hydroline.engine.component import Component, Port
from hydroline.rigs import load_rig
from hydroline.scenarios import build_scenario
from hydroline.system import build_network
from rounding_bound import rounding_bound

needs_cc = pytest.mark.skipif(not compiled.available(), reason="no C compiler")


def default_network(rig=None, scenario="open-loop-step"):
    """The default rig's network with the scenario's commands, built anew."""
    rig = load_rig() if rig is None else rig
    sc = build_scenario(rig, scenario)
    return build_network(rig, sc.commands, sc.position_guess)


def changed(path, value):
    rig = load_rig()
    rig.set(path, value)
    return default_network(rig)


def test_one_number_or_structure_changed_gives_another_key_as_the_graph_does():
    """Networks built anew from one rig share a fingerprint (and a graph); a rig changed in
    one number, or in its structure, gets a fingerprint of its own, as its graph differs."""
    base = default_network()
    again = default_network()
    key = base.definition_fingerprint()
    assert key is not None and len(key) == 64
    assert again.definition_fingerprint() == key
    assert compiled.model_fingerprint(again.compile()) == compiled.model_fingerprint(base.compile())
    variants = {
        "hose length (in p: hose.COEFFICIENTS_AS_PARAMETERS)": changed("supply.section2.length",
                                                                  "2.9 m"),
        "valve natural frequency": changed("servovalve.natural_frequency", "141 Hz"),
        "modes per section (structure)": changed("rig.modes_per_section", 4),
        "closed loop (another scenario)": default_network(scenario="closed-loop-sine"),
    }
    keys = {what: net.definition_fingerprint() for what, net in variants.items()}
    assert len(set(keys.values()) | {key}) == len(keys) + 1, keys
    for what, net in variants.items():   # the graphs differ too: the key follows the graph
        same = what.startswith("hose length")   # a hose's numbers are runtime parameters
        assert (compiled.model_fingerprint(net.compile()) == compiled.model_fingerprint(
            base.compile())) == same, what


def test_fingerprint_is_the_same_in_another_process():
    """A record is only useful to the next process if it computes the same key (another
    hash seed: no set or dict order leaks into it)."""
    code = ("import sys\nsys.path.insert(0, %r)\n"
            "from test_definition_fingerprint import default_network\n"
            "print(default_network().definition_fingerprint())\n" % os.path.dirname(__file__))
    env = dict(os.environ, PYTHONHASHSEED="12345")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == default_network().definition_fingerprint()


def test_edited_component_source_gives_another_key(monkeypatch):
    """The source of the component modules is part of the key (here: the servovalve's
    module reads as edited), and a source file modified after the process loaded its code
    gives no key at all (the code that runs may not be the file's)."""
    key = default_network().definition_fingerprint()
    real = fingerprint.module_source_tag

    def edited(name):
        return "edited" if name == "hydroline.components.servovalve" else real(name)

    monkeypatch.setattr(fingerprint, "module_source_tag", edited)
    assert default_network().definition_fingerprint() not in (None, key)
    monkeypatch.setattr(fingerprint, "module_source_tag", real)
    assert default_network().definition_fingerprint() == key
    monkeypatch.setattr(fingerprint, "LOADED_AT", 0.0)   # every file "changed" since
    assert default_network().definition_fingerprint() is None


@dataclass(kw_only=True)
class OutsideSource(Component):
    """A component whose class lives outside hydroline (its code is not tagged)."""

    pressure: float = 1e5
    outputs = {"pressure": Port("pressure")}
    feedthrough = False

    def outputs_of(self, t, x, u, p):
        return {"pressure": self.pressure}


def test_what_cannot_be_described_gives_no_key(monkeypatch):
    """Conservative: a class outside hydroline, or an attribute that is no value (a
    function), gives no fingerprint; class-level data changed at run time gives another;
    a cached property (derived from the other attributes) changes nothing."""
    assert Network([OutsideSource(name="source")], warn_lost_flows=False) \
        .definition_fingerprint() is None
    net = default_network()
    key = net.definition_fingerprint()
    net.component("servovalve").flow_law = np.sqrt
    assert net.definition_fingerprint() is None
    del net.component("servovalve").flow_law
    assert net.definition_fingerprint() == key
    from hydroline.components import Servovalve

    monkeypatch.setattr(Servovalve, "feedthrough", False)   # public class data
    assert net.definition_fingerprint() not in (None, key)
    monkeypatch.undo()
    from hydroline.components import TableCommand

    table = TableCommand(name="table", quantity="current", times=[0.0, 0.1], values=[0.0, 0.01],
                         connections={"command": "unused_current"})
    net2 = Network([table], warn_lost_flows=False)
    before = net2.definition_fingerprint()
    assert before is not None
    table.interpolant   # a cached CasADi object, made from times and values
    assert net2.definition_fingerprint() == before


def test_code_replaced_at_run_time_gives_another_key(monkeypatch):
    """A method patched on a component class, or a function or constant rebound in a module
    the graph uses, is not in any source file: it changes the key (a hit would give the old
    physics); undone, the key is the old one again."""
    from hydroline.components import Servovalve
    from hydroline.engine import ops

    net = default_network()
    key = net.definition_fingerprint()
    real = Servovalve.outputs_of

    def outputs_of(self, t, x, u, p):   # the same equations, defined elsewhere
        return real(self, t, x, u, p)

    monkeypatch.setattr(Servovalve, "outputs_of", outputs_of)
    assert net.definition_fingerprint() not in (None, key)
    monkeypatch.undo()
    assert net.definition_fingerprint() == key
    monkeypatch.setattr(ops, "smooth_sqrt", lambda x, eps: ops.sqrt(x))
    assert net.definition_fingerprint() not in (None, key)
    monkeypatch.undo()
    from hydroline.components import hose

    monkeypatch.setattr(hose, "COEFFICIENTS_AS_PARAMETERS", False)   # a module's constant
    assert net.definition_fingerprint() not in (None, key)
    monkeypatch.undo()
    assert net.definition_fingerprint() == key


@needs_cc
def test_model_loaded_from_its_record_builds_no_graph_and_integrates_as_built(monkeypatch):
    """A fresh process's view (no model or library in memory): the default rig's model is
    found by its definition; its steady state and integration build no CasADi graph, give
    the same numbers as the model built from its graph, and agree with the SciPy reference
    path (per-component Python right-hand side) within the integrator's tolerance."""
    kw = dict(dt_out=1e-4, rtol=1e-6, atol_scale=1e-7)
    built = default_network()
    native = compiled.native_model(built)      # records it under its definition (if new)
    ss = solve_steady_state(built)
    res = integrate(built, ss.x, 0.02, p=ss.p, solver="compiled", **kw)
    monkeypatch.setattr(compiled.toolchain, "_LIBS", {})
    monkeypatch.setattr(compiled.records, "_MODELS", {})
    monkeypatch.setattr(compiled.records, "_NUMBERS", {})

    def no_graph(self):
        raise AssertionError("CasADi graph built for a model known by its definition")

    monkeypatch.setattr(Network, "compile", no_graph)
    loaded = default_network()
    ss2 = solve_steady_state(loaded)
    # (its structure's record: the C takes the numbers at run time)
    assert compiled.native_model(loaded).found_by == "numbers"
    assert compiled.native_model(loaded).library_path == native.library_path
    res2 = integrate(loaded, ss2.x, 0.02, p=ss2.p, solver="compiled", **kw)
    assert res2.metadata["solver"] == "compiled"
    np.testing.assert_array_equal(ss2.x, ss.x)
    assert res2.columns == res.columns
    np.testing.assert_array_equal(np.column_stack([res2[c] for c in res2.columns]),
                                  np.column_stack([res[c] for c in res.columns]))
    # the rest state is one of the Python reference right-hand side
    assert np.max(np.abs(loaded.rhs(0.0, ss2.x, ss2.p) / loaded.state_scales)) < 1e-8
    monkeypatch.undo()
    ref = integrate(loaded, ss2.x, 0.02, p=ss2.p, solver="scipy", **kw)
    for k in ("supply_port_pressure", "return_port_pressure", "piston_velocity"):
        assert np.max(np.abs(res2[k] - ref[k])) < 300 * kw["rtol"] * np.ptp(ref[k]), k


@needs_cc
def test_compiled_signals_are_the_components_python_signals():
    """The signals the steady state's settling and a run's first row now take from the
    compiled code, against the components' own Python evaluation at the same state."""
    net = default_network()
    ss = solve_steady_state(net)
    x = ss.x + 0.05 * np.random.default_rng(3).normal(size=len(ss.x)) * net.state_scales
    y = compiled.native_model(net).solver(ss.p).signals(0.02, x)
    ref = net.signals_at(0.02, x, ss.p)
    assert len(y) == len(net.signal_names) == len(ref)
    for name, value in zip(net.signal_names, y):
        assert value == pytest.approx(ref[name], rel=1e-9, abs=1e-15), name


@needs_cc
def test_a_component_changed_after_its_graph_is_never_recorded_by_definition(monkeypatch,
                                                                              tmp_path):
    """A graph built before a component changed does not hold the change: its model must
    not be recorded under the changed network's definition (another process would load the
    old constants for the new numbers). Built after the change, it is, and a network of
    that definition then loads it; each compiled right-hand side against the components'
    own Python equations at the same state, within the rounding bound of the evaluation
    (a stale constant, 140 for 150.000x Hz, differs by ~1e-6 of a term, far above it)."""
    from hydroline.cache import load_table

    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))   # nothing recorded before
    monkeypatch.setattr(compiled.records, "_NUMBERS", {})        # (nor in this process)
    frequency = 150.0 + np.random.default_rng(24).uniform(0.0, 1e-3)   # new numbers, [Hz]

    def retuned():
        net = default_network()
        net.component("servovalve").natural_frequency = frequency
        return net

    def compiled_rhs_is_the_components(net):
        x = solve_steady_state(net).x * (1.0 + 1e-3)   # the spool moving: w_v matters
        solver = compiled.native_model(net).solver()
        ref = net.rhs(0.0, x)
        return bool(np.all(np.abs(solver.rhs(0.0, x) - ref) <= rounding_bound(net, 0.0, x)))

    stale = default_network()
    stale.compile()                                        # the graph of the 140 Hz valve
    stale.component("servovalve").natural_frequency = frequency
    assert compiled.native_model(stale).found_by != "definition"
    assert load_table("models", compiled.definition_key(stale)) is None
    fresh = retuned()
    assert compiled.native_model(fresh).found_by == "structure"
    assert compiled_rhs_is_the_components(fresh)
    monkeypatch.setattr(compiled.records, "_MODELS", {})
    monkeypatch.setattr(compiled.records, "_NUMBERS", {})
    again = retuned()
    assert compiled.native_model(again).found_by == "numbers"   # its C takes the numbers
    assert compiled_rhs_is_the_components(again)


@needs_cc
def test_cached_json_run_imports_no_casadi(tmp_path):
    """``hydroline simulate --json`` a second time (model recorded by the first): CasADi is
    never imported, and the summary is the first run's."""
    code = ("import contextlib, io, json, sys\nfrom hydroline.cli import main\n"
            "out = io.StringIO()\n"
            "with contextlib.redirect_stdout(out):\n"
            "    assert main(['simulate', '--json']) == 0\n"
            "summary = json.loads(out.getvalue())\nsummary.pop('wall_time_s', None)\n"
            "print(json.dumps({'casadi': 'casadi' in sys.modules, 'summary': summary}))\n")
    env = dict(os.environ, HYDROLINE_BACKGROUND_BUILD="0")   # (the first run builds it)
    runs = [json.loads(subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                                      capture_output=True, text=True, check=True).stdout)
            for _ in range(2)]
    assert runs[1]["casadi"] is False
    assert runs[1]["summary"] == runs[0]["summary"]


def test_a_state_s_tolerance_ceiling_is_a_number_not_structure():
    """A state's tolerance ceiling (State.atol_ceiling), like its scale, is read by the
    integrator at run time and is in no equation: with ``structure`` two states differing
    only in it describe alike, as do two scales; without it, each number counts."""
    from hydroline.engine.component import State

    def described(state, structure):
        return repr(fingerprint._Describer(structure=structure).freeze(state))

    a = State("velocity", "m/s", 1.0, atol_ceiling=1e-5)
    b = State("velocity", "m/s", 2.0, atol_ceiling=3e-5)
    assert described(a, True) == described(b, True)
    assert described(a, False) != described(b, False)
    none = State("velocity", "m/s", 1.0)
    assert described(none, True) != described(a, True)   # a ceiling or none: not a number
