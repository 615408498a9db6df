"""Numbers are parameters: a rig that differs from a known one only in numbers runs on the
known compiled library, found without writing C or building a CasADi graph
(:meth:`hydroline.engine.Component.compiled_numbers`, :func:`hydroline.compiled.numbers_key`).

Checked structurally (no timing): every numeric value of the default rig, changed, needs no
build and no graph; the constants such a variant is given are those a full code generation
of it writes; and its run agrees with the SciPy reference path of its own components."""
import time

import numpy as np
import pytest

from hydroline import compiled
from hydroline.engine import Network, solve_steady_state
from hydroline.rigs import RigError, load_rig
from hydroline.scenarios import build_scenario
from hydroline.system import build_network
from rounding_bound import rounding_bound

needs_cc = pytest.mark.skipif(not compiled.available(), reason="no C compiler")


def network_of(rig, scenario="open-loop-step"):
    """The rig's network with the scenario's commands, built anew."""
    sc = build_scenario(rig, scenario)
    return build_network(rig, sc.commands, sc.position_guess)


def numeric_paths(rig):
    """The rig's numeric values (numbers and lists of numbers, the oil's cavity pressure and
    its drop among them), but the rig's own switches (``rig.*``: modes per section, line
    method) and the modes, which are structure."""
    return sorted(path for path, v in rig.values.items()
                  if not path.startswith("rig.") and not path.endswith(".modes")
                  and not isinstance(v, bool)
                  and (isinstance(v, float) or (isinstance(v, list) and v
                                                and all(isinstance(a, float) for a in v))))


def changed(rig, path):
    """The rig with one value moved (by -7 %, else +7 %; a zero to a small plausible
    value), or None where neither move is a valid rig (a current above the rating, ...)."""
    def moved(v, factor):
        return factor * v if v else 1e-12

    for factor in (0.93, 1.07):
        variant = rig.copy()
        v = rig.values[path]
        variant.values[path] = [moved(a, factor) for a in v] if isinstance(v, list) else moved(v, factor)
        try:
            return network_of(variant)
        except RigError:
            continue
    return None


@needs_cc
def test_every_number_of_the_default_rig_runs_on_its_library(monkeypatch):
    """Each numeric value of the default rig changed alone (masses, areas, accumulator
    capacity and pre-charge, fluid properties, valve data, manifold losses, friction, load,
    pressures, hoses, command times): the variant needs no build, and it is found without
    building its CasADi graph (its structure's record holds everything but its numbers)."""
    rig = load_rig()
    compiled.native_model(network_of(rig))       # the structure, built or found once
    paths = numeric_paths(rig)
    assert len(paths) > 50                       # (the rig's numbers are found)

    def no_graph(self):
        raise AssertionError("CasADi graph built for a rig that differs only in numbers")

    monkeypatch.setattr(Network, "compile", no_graph)
    tried = 0
    for path in paths:
        net = changed(rig, path)
        if net is None:
            continue
        tried += 1
        assert not compiled.needs_build(net), path
    assert tried >= len(paths) - 5


@needs_cc
def test_a_variant_gets_the_constants_a_code_generation_writes_and_runs_as_its_components():
    """A variant of other numbers (friction, accumulator, valve, load, pressures) found by its
    structure's record: its constants are exactly those a code generation of its own graph
    writes, and its compiled right-hand side is the components' own Python equations within
    the rounding bound of the evaluation (a number of the known rig left in the constants,
    e.g. 140 for 154 Hz, differs by ~10 % of a term, far above it)."""
    rig = load_rig()
    compiled.native_model(network_of(rig))
    variant = rig.copy()
    for path, factor in (("friction.coulomb_up", 1.3), ("friction.viscous_down", 0.7),
                         ("supply.accumulator.capacity", 1.5), ("return.accumulator.capacity", 0.8),
                         ("servovalve.natural_frequency", 1.1), ("supply.pressure", 0.9)):
        variant.values[path] = rig.values[path] * factor
    variant.values["load.stiffness"] = 2e4     # 0 in the rig: a term the constants dropped
    net = network_of(variant)
    native = compiled.native_model(net)
    assert native.found_by == "numbers"
    from hydroline.compiled import codegen

    np.testing.assert_array_equal(native.generated.constants,
                                  codegen.generate(network_of(variant).compile()).constants)
    ss = solve_steady_state(net)
    x = ss.x * (1.0 + 1e-3)       # the spool and piston moving: every number matters
    x[net.state_names.index("actuator.velocity")] = 0.05
    solver = native.solver(ss.p)
    assert np.all(np.abs(solver.rhs(0.02, x) - net.rhs(0.02, x, ss.p))
                  <= rounding_bound(net, 0.02, x, ss.p))


def test_the_oil_s_models_are_structure_their_numbers_are_not():
    """Whether the oil carries entrained air (M40) and has a cavity model (M42, M45) keys a
    chamber's and a hose end's library; the models' numbers (air content, polytropic
    exponent, cavity pressure and its drop) are runtime numbers of the chambers and hose ends
    that read them, as the oil's density, viscosity and bulk modulus (which reach the graph
    only through the hoses' runtime matrices) are not structure at all."""
    from hydroline.compiled import numbers_key

    rig = load_rig()
    key = numbers_key(network_of(rig))

    def key_with(**values):
        variant = rig.copy()
        variant.values.update({f"fluid.{k}": v for k, v in values.items()})
        return numbers_key(network_of(variant))

    assert key_with(density=0.9 * rig.values["fluid.density"],
                    bulk_modulus=1.1 * rig.values["fluid.bulk_modulus"]) == key
    with_air = key_with(air_content=0.01)
    assert with_air != key                                   # air-free -> air: a new graph
    assert key_with(air_content=0.02, air_polytropic_exponent=1.4) == with_air
    off = key_with(cavity_pressure=None)          # the rig's cavity model (on by default)
    assert off not in (key, with_air)
    assert key_with(cavity_pressure=2e4, cavity_pressure_drop=2e3) == key
    # (the graph takes them as symbols: its numbers, not its constants, hold them)
    variant = rig.copy()
    variant.values.update({"fluid.air_content": 0.01, "fluid.air_polytropic_exponent": 1.2})
    net = network_of(variant)
    assert net.compile().k is not None
    names, values = net.compiled_numbers()
    held = dict(zip(names, values))
    assert held["actuator.fluid.air_content"] == 0.01
    assert held["actuator.fluid.air_polytropic_exponent"] == 1.2
    assert held["actuator.fluid.cavity_pressure"] == 5e3
    assert held["return.section2.fluid.cavity_pressure_drop"] == 1e3
    assert "return.section2.fluid.air_content" not in held   # (a hose end reads no air)


def test_a_python_branch_on_a_number_keeps_that_network_s_numbers_in_its_graph():
    """A component whose equations branch in Python on one of its numbers cannot take them
    as symbols: its graph keeps them as constants (as before), with the same values as its
    own equations."""
    from dataclasses import dataclass

    from hydroline.engine.component import Component, Port

    @dataclass(kw_only=True)
    class Switched(Component):
        gain: float = 2.0
        outputs = {"y": Port("dimensionless")}
        feedthrough = False

        def outputs_of(self, t, x, u, p):
            return {"y": 3.0 * t if self.gain > 1.0 else t}     # a Python branch

    net = Network([Switched(name="s")], warn_lost_flows=False)
    model = net.compile()
    assert model.k is None
    assert float(model.signals(0.5, [], [])) == pytest.approx(1.5)


@needs_cc
def test_a_library_not_built_yet_is_built_in_the_background(monkeypatch, tmp_path):
    """With background builds (the command line's default), a run whose library is not built
    yet goes on with CVODES and starts the build in a process of its own; a later run waits
    for that build (it does not compile again) and gets the compiled core. Both give the
    oscillator's exact step peak, 1 + exp(-pi zeta / sqrt(1 - zeta^2)) mm."""
    from hydroline.cache import BACKGROUND_BUILD_ENV
    from hydroline.compiled import toolchain
    from hydroline.engine import integrate
    from test_compiled import _oscillator_peak, oscillator_network

    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv(BACKGROUND_BUILD_ENV, "1")
    monkeypatch.setattr(toolchain, "_LIBS", {})
    monkeypatch.setattr(compiled.records, "_MODELS", {})
    monkeypatch.setattr(compiled.records, "_NUMBERS", {})
    first = integrate(oscillator_network(omega=223.0), np.zeros(2), 0.05)
    assert first.metadata["solver"] == "cvodes"
    assert "background" in first.metadata["solver_note"]
    real = toolchain._compile_locked

    def built_elsewhere(cc, full, path):
        assert toolchain.library_check(path)[0], "compiled again in this process"
        return real(cc, full, path)

    monkeypatch.setattr(toolchain, "_compile_locked", built_elsewhere)
    native = compiled.native_model(oscillator_network(omega=223.0), wait=True)
    assert native.library_path.exists()
    later = integrate(oscillator_network(omega=223.0), np.zeros(2), 0.05)
    assert later.metadata["solver"] == "compiled"
    for res in (first, later):
        assert res["osc.x"].max() == pytest.approx(_oscillator_peak(), rel=2e-3)


def test_a_quick_build_s_units_define_each_function_once():
    """The quick build's translation units (compiled side by side): f's, the Jacobian's (at
    ``JACOBIAN_LEVEL``), the other generated functions' and the integrator's, each holding the
    generated header; together they define every function once (the others declared); a
    source laid out otherwise is one unit."""
    from hydroline.compiled import toolchain
    from hydroline.compiled.codegen import generate
    from test_compiled import oscillator_network

    full = toolchain.library_location(generate(oscillator_network(omega=223.0).compile()))[1]
    units = toolchain.quick_units(full, "-O1")
    assert [level for _, level in units] == ["-O1", toolchain.JACOBIAN_LEVEL, "-O1", "-O1"]
    header = full[:full.index("static void hl_f(")]
    assert all(text.startswith(header) for text, _ in units)
    for name in ("hl_f(", "hl_jac(", "hl_signals(", "hl_lu_solve(", "hl_init("):
        defined = [k for k, (text, _) in enumerate(units)
                   if any(line.startswith(("void " + name, "int " + name, "static void " + name))
                          and line.endswith(") {") for line in text.splitlines())]
        assert len(defined) == 1, name
    integrator = toolchain.BDF_SOURCE.read_text()
    assert [integrator in text for text, _ in units] == [False, False, False, True]
    for odd in ("int hl_sizes(long long* out) { return 0; }\n", full[:-10]):
        assert toolchain.quick_units(odd, "-O0") == [(odd, "-O0")]


@needs_cc
def test_runs_during_a_background_build_use_its_quick_library(monkeypatch, tmp_path):
    """While a background build goes on, a run finds its quick library (built first, at
    ``QUICK_LEVEL``) and runs compiled, with the oscillator's exact step peak
    1 + exp(-pi zeta / sqrt(1 - zeta^2)) mm; the finished build replaces it (the quick
    file removed) and a later run loads the full library."""
    from hydroline.cache import BACKGROUND_BUILD_ENV
    from hydroline.compiled import toolchain
    from hydroline.engine import integrate
    from test_compiled import _oscillator_peak, oscillator_network

    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv(BACKGROUND_BUILD_ENV, "1")
    monkeypatch.setattr(toolchain, "_LIBS", {})
    monkeypatch.setattr(compiled.records, "_MODELS", {})
    monkeypatch.setattr(compiled.records, "_NUMBERS", {})
    started = {}

    def quick_made(path, full):   # the builder's first half, here: the full build "goes on"
        started["path"], started["full"] = path, full() if callable(full) else full
        toolchain._compile_locked(toolchain.compiler(), started["full"], path,
                                   quick_level=toolchain.QUICK_LEVEL)
        return True

    monkeypatch.setattr(toolchain, "build_in_background", quick_made)
    during = integrate(oscillator_network(omega=223.0), np.zeros(2), 0.05)
    path = started["path"]
    assert during.metadata["solver"] == "compiled"
    # (the quick library is linked from f's, the Jacobian's, the other functions' and the
    # integrator's units)
    assert len(toolchain.quick_units(started["full"], toolchain.QUICK_LEVEL)) == 4
    assert toolchain.quick_location(path).exists() and not path.exists()
    source = tmp_path / "model.c"
    source.write_text(started["full"])
    toolchain.build_from_file(toolchain.compiler(), str(source), str(path))
    assert toolchain.library_check(path)[0] and not toolchain.quick_location(path).exists()
    after = integrate(oscillator_network(omega=223.0), np.zeros(2), 0.05)
    assert after.metadata["solver"] == "compiled"
    assert str(path) in toolchain._LIBS
    for res in (during, after):
        assert res["osc.x"].max() == pytest.approx(_oscillator_peak(), rel=2e-3)


def _slow_background_build(monkeypatch, toolchain, release):
    """``build_in_background`` replaced by a build that holds the library's lock, waits for
    ``release`` and a further 0.3 s, then makes the quick library: a run that asks for it
    meanwhile finds the build going on and its quick library not there yet."""
    import fcntl
    import threading

    started = {}

    def slow(path, full):
        if "path" in started:
            return True
        started["path"] = path
        source = full() if callable(full) else full
        lock = open(path.with_suffix(".lock"), "w")
        fcntl.flock(lock, fcntl.LOCK_EX)

        def build():
            try:
                release.wait(30)
                time.sleep(0.3)
                toolchain._compile_locked(toolchain.compiler(), source, path,
                                          quick_level=toolchain.QUICK_LEVEL)
            finally:
                lock.close()

        started["thread"] = threading.Thread(target=build, daemon=True)
        started["thread"].start()
        return True

    monkeypatch.setattr(toolchain, "build_in_background", slow)
    return started


@needs_cc
@pytest.mark.parametrize("many", [False, True])
def test_a_later_run_waits_for_the_quick_library(monkeypatch, tmp_path, many):
    """While a background build goes on, the first run of a process goes on with CVODES and
    a later run (another model of the same structure: a study's next variant) waits for the
    quick library instead of a second CVODES run; inside ``many_runs`` (a fit, whose every
    run is of one structure) the first run waits too, after the work given to do meanwhile.
    Every run gives the oscillator's
    exact step peak 1 + exp(-pi zeta / sqrt(1 - zeta^2)) mm."""
    import threading

    from hydroline.cache import BACKGROUND_BUILD_ENV
    from hydroline.compiled import toolchain
    from hydroline.engine import integrate
    from test_compiled import _oscillator_peak, oscillator_network

    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv(BACKGROUND_BUILD_ENV, "1")
    for name in ("_LIBS", "_PENDING", "_WAITED"):
        monkeypatch.setattr(toolchain, name, {})
    monkeypatch.setattr(toolchain, "QUICK_WAIT", 60.0)   # (a slow machine's compiler)
    monkeypatch.setattr(compiled.records, "_MODELS", {})
    monkeypatch.setattr(compiled.records, "_NUMBERS", {})
    release = threading.Event()
    started = _slow_background_build(monkeypatch, toolchain, release)
    runs = []
    if many:   # (its work meanwhile done once, by the run that waits)
        done = []
        release.set()
        with toolchain.many_runs(meanwhile=[lambda: done.append(1)]):
            runs.append(integrate(oscillator_network(omega=223.0), np.zeros(2), 0.05))
        assert runs[0].metadata["solver"] == "compiled" and done == [1]
    else:
        runs.append(integrate(oscillator_network(omega=223.0), np.zeros(2), 0.05))
        assert runs[0].metadata["solver"] == "cvodes"
        release.set()
        runs.append(integrate(oscillator_network(omega=223.0), np.zeros(2), 0.05))
        assert runs[1].metadata["solver"] == "compiled"
    assert toolchain._WAITED[str(started["path"])] > 0.2     # it waited for the build
    started["thread"].join()
    for res in runs:
        assert res["osc.x"].max() == pytest.approx(_oscillator_peak(), rel=2e-3)


@needs_cc
def test_many_runs_waits_for_its_first_build_and_runs_another_network_meanwhile(monkeypatch,
                                                                                 tmp_path):
    """Inside ``many_runs`` (a layout study) the first run waits for its background build's
    quick library, started at the command's priority, after the work given to do meanwhile:
    a run of another network (a 0 m length) that starts its own build, niced, and goes on
    with CVODES. Both give the oscillator's exact step peak
    1 + exp(-pi zeta / sqrt(1 - zeta^2)) mm (a one-mode modal block is that oscillator)."""
    import fcntl
    from pathlib import Path

    from hydroline.cache import BACKGROUND_BUILD_ENV
    from hydroline.compiled import toolchain
    from hydroline.engine import integrate
    from test_compiled import Hold, ModalBlock, _oscillator_peak, oscillator_network

    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv(BACKGROUND_BUILD_ENV, "1")
    for name in ("_LIBS", "_PENDING", "_WAITED"):
        monkeypatch.setattr(toolchain, name, {})
    monkeypatch.setattr(toolchain, "_UNAWAITED", set())
    monkeypatch.setattr(toolchain, "QUICK_WAIT", 60.0)   # (a slow machine's compiler)
    monkeypatch.setattr(compiled.records, "_MODELS", {})
    monkeypatch.setattr(compiled.records, "_NUMBERS", {})
    other = []

    def zero_length():
        network = Network([Hold(name="source"), ModalBlock(name="m", omegas=(223.0,),
                                                          zetas=(0.05,), gains=(1.0,))])
        other.append(integrate(network, np.zeros(2), 0.05))

    with toolchain.many_runs(meanwhile=[zero_length]):
        first = integrate(oscillator_network(omega=223.0), np.zeros(2), 0.05)
    assert first.metadata["solver"] == "compiled"
    assert other[0].metadata["solver"] == "cvodes"
    (niced,) = toolchain._UNAWAITED          # the other network's build, niced
    (awaited,) = [path for path in toolchain._PENDING if path != niced]
    assert str(toolchain.quick_location(Path(awaited))) in toolchain._LIBS
    for lock in tmp_path.glob("*.lock"):      # (both builds ended before tmp_path goes)
        with open(lock) as f:
            fcntl.flock(f, fcntl.LOCK_EX)
    assert len(list(tmp_path.glob("hl_*[0-9a-f].so"))) == 2
    assert first["osc.x"].max() == pytest.approx(_oscillator_peak(), rel=2e-3)
    assert other[0]["m.q0"].max() == pytest.approx(_oscillator_peak(), rel=2e-3)
