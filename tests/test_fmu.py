"""FMU export (issue 16), checked with fmpy -- an FMI client no one here wrote.

The references are hydroline's own scenario runs (``hydroline.simulate``: steady state solved
in Python, integration by the compiled core or CVODES with its breakpoints), reached through a
different path than the FMU's (FMI 2.0 calls from fmpy, inputs set by the importer, the rest
state re-solved in C when parameters are tuned). Each FMU is built once per module.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import hydroline
from hydroline import compiled
from hydroline.cli import main

pytestmark = pytest.mark.skipif(not compiled.available(),
                                reason="no C compiler: an FMU's binary is built with the system C compiler")

import fmpy  # noqa: E402  (the test extra)
from fmpy.fmi2 import FMU2Model, FMU2Slave  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

T_END = 0.25
OUTPUTS = ["supply_port_pressure", "return_port_pressure", "bottom_chamber_pressure",
           "top_chamber_pressure", "piston_position", "piston_velocity"]


@pytest.fixture(scope="module")
def default_fmu(tmp_path_factory):
    """The default rig's plant, both kinds, open-loop rest state (the Python API)."""
    from hydroline.fmu import export_fmu

    return export_fmu(None, tmp_path_factory.mktemp("fmu") / "ayalew2005.fmu", kind="both")


@pytest.fixture(scope="module")
def open_loop_reference():
    return hydroline.simulate(None, "open-loop-step")


def step_input(t_step=0.01, current=0.05):
    """Valve current stepped at t_step: fmpy's input table (a repeated time is a jump)."""
    return np.array([(0.0, 0.0), (t_step, 0.0), (t_step, current), (T_END, current)],
                    dtype=[("time", float), ("valve_current", float)])


def excursion_error(result, reference, key):
    """max |FMU - reference| over the run, as a fraction of the reference's excursion."""
    ref = np.interp(result["time"], reference.t, reference[key])
    return np.max(np.abs(result[key] - ref)) / np.ptp(reference[key])


def run_step(fmu, fmi_type, start_values=None):
    return fmpy.simulate_fmu(str(fmu), fmi_type=fmi_type, stop_time=T_END, output_interval=1e-4,
                             input=step_input(), start_values=start_values or {},
                             output=OUTPUTS, relative_tolerance=1e-6)


def variables(fmu):
    md = fmpy.read_model_description(str(fmu))
    return md, {v.name: v for v in md.modelVariables}


def test_default_fmu_validates_and_declares_its_interface(default_fmu):
    assert validate_fmu(str(default_fmu)) == []
    md, v = variables(default_fmu)
    assert md.fmiVersion == "2.0" and md.coSimulation and md.modelExchange
    units = {"valve_current": "A", "external_force": "N", "pump_pressure": "Pa",
             "tank_pressure": "Pa", "piston_position": "m", "piston_velocity": "m/s",
             "supply_port_pressure": "Pa", "top_chamber_pressure": "Pa"}
    for name, unit in units.items():
        assert v[name].unit == unit and v[name].description, name
    assert {n for n, x in v.items() if x.causality == "input"} == {
        "valve_current", "external_force", "pump_pressure", "tank_pressure"}
    assert {n for n, x in v.items() if x.causality == "output"} == set(OUTPUTS)
    tunable = {n for n, x in v.items() if x.variability == "tunable"}
    assert {"actuator.bulk_modulus", "load.mass", "friction.coulomb_up",
            "supply.manifold.resistance", "return.manifold.resistance"} <= tunable
    # start values are the rig's (SI) and the open-loop rest: valve closed, piston on its stop
    rig = hydroline.load_rig()
    assert float(v["actuator.bulk_modulus"].start) == rig["actuator.bulk_modulus"]
    assert float(v["pump_pressure"].start) == rig["supply.pressure"]
    assert float(v["valve_current"].start) == 0.0
    assert float(v["actuator.position"].start) < -rig["actuator.stroke"] / 2 + 1e-4
    # no runtime Python: a binary for this platform and the sources to build others
    import zipfile

    names = zipfile.ZipFile(default_fmu).namelist()
    assert any(n.startswith("binaries/") for n in names)
    assert {"sources/fmi2_wrapper.c", "sources/model.c", "sources/bdf.c",
            "sources/fmu_data.h", "resources/plant_numbers.txt"} <= set(names)


@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
def test_open_loop_step_matches_hydroline_simulate(default_fmu, open_loop_reference, fmi_type):
    """The paper's test through fmpy: within 0.5 % of the port pressure excursion (issue 16)
    -- the whole run, the stop transient after ~110 ms included."""
    res = run_step(default_fmu, fmi_type)
    for key in ("supply_port_pressure", "return_port_pressure"):
        assert excursion_error(res, open_loop_reference, key) < 0.005, key
    for key in ("bottom_chamber_pressure", "top_chamber_pressure", "piston_velocity"):
        assert excursion_error(res, open_loop_reference, key) < 0.005, key
    # before the step the FMU rests where it started (the solved steady state)
    before = res["time"] < 0.01
    assert np.ptp(res["supply_port_pressure"][before]) < 1e-6 * open_loop_reference[
        "supply_port_pressure"][0]


def test_a_rig_differing_only_in_numbers_reuses_the_binary(default_fmu, open_loop_reference,
                                                           monkeypatch, tmp_path, capsys):
    """Numbers are parameters (issue 25): a rig that differs from the default one only in
    numbers -- the HSM-to-valve hose 1.5 m instead of 3.048 m, the supply accumulator 0.3 L
    instead of 1 L -- is exported without compiling: the default rig's binary (built for the
    module's FMU, kept in the cache under the structure's key) with the variant's numbers in
    resources/. Its FMU follows hydroline.simulate of the variant within the tolerance of the
    default rig's test, and misses the default rig's run by far more (its numbers are used)."""
    import zipfile

    from hydroline.fmu import export

    builds = []
    compile_binary = export._compile
    monkeypatch.setattr(export, "_compile", lambda *a: builds.append(a) or compile_binary(*a))
    rig = hydroline.load_rig().set("supply.section2.length", "1.5 m").set(
        "supply.accumulator.capacity", "0.3 L")
    out = export.export_fmu(rig, tmp_path / "ayalew2005.fmu", kind="both")
    assert builds == []
    old, new = zipfile.ZipFile(default_fmu), zipfile.ZipFile(out)
    differ = {n for n in old.namelist() if old.read(n) != new.read(n)}
    assert "resources/plant_numbers.txt" in differ
    assert not any(n.startswith(("binaries/", "sources/")) for n in differ)
    md = fmpy.read_model_description(str(out))
    assert md.guid != fmpy.read_model_description(str(default_fmu)).guid
    # the binary reads the numbers of its own FMU only: another FMU's numbers file is refused
    unzipped = Path(fmpy.extract(str(out)))
    (unzipped / "resources" / "plant_numbers.txt").write_bytes(
        old.read("resources/plant_numbers.txt"))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=str(unzipped),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="other")
    with pytest.raises(Exception, match="instantiate"):
        slave.instantiate()
    assert "does not match its numbers file" in capsys.readouterr().out
    ref = hydroline.simulate(rig, "open-loop-step")
    res = run_step(out, "CoSimulation")
    for key in ("supply_port_pressure", "return_port_pressure", "piston_velocity"):
        assert excursion_error(res, ref, key) < 0.005, key
    assert excursion_error(res, open_loop_reference, "supply_port_pressure") > 0.1


@pytest.mark.parametrize("start_values, rig_values", [
    ({"load.mass": 20.0, "friction.coulomb_up": 120.0, "actuator.bulk_modulus": 1.0e9,
      "supply.manifold.resistance": 2.0e9}, None),
    ({"external_force": 2000.0}, {"load.applied_force": 2000.0}),
    ({"pump_pressure": 18.0e6}, {"supply.pressure": 18.0e6}),
], ids=["tunable-parameters", "external-force", "pump-pressure"])
def test_other_values_match_a_rig_with_those_values(default_fmu, start_values, rig_values):
    """Tunable parameters enter the generated code exactly, and inputs are runtime values: the
    FMU started with other values (rest state and accumulator charge re-solved in C at
    initialization) against hydroline.simulate of the rig set so."""
    rig = hydroline.load_rig()
    for k, val in (rig_values or start_values).items():
        rig.values[k] = val
    ref = hydroline.simulate(rig, "open-loop-step")
    res = run_step(default_fmu, "CoSimulation", start_values=start_values)
    for key in ("supply_port_pressure", "return_port_pressure", "piston_velocity"):
        assert excursion_error(res, ref, key) < 0.005, key


def test_model_exchange_jacobian_is_the_derivative_of_the_derivatives(default_fmu):
    """fmi2GetDirectionalDerivative (exact sparse Jacobian) against central differences of
    fmi2GetDerivatives, at a state off the rest state (piston mid-stroke, moving)."""
    from ctypes import c_double

    md, v = variables(default_fmu)
    m = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(default_fmu)),
                  modelIdentifier=md.modelExchange.modelIdentifier, instanceName="jac")
    m.instantiate()
    try:
        m.setupExperiment(startTime=0.0)
        m.enterInitializationMode()
        m.exitInitializationMode()
        m.enterContinuousTimeMode()
        states = [d.variable.derivative for d in md.derivatives]
        n = len(states)
        buf = (c_double * n)()
        m.getContinuousStates(buf, n)
        x = np.array(buf)
        x[[s.name for s in states].index("actuator.position")] = 0.0
        x[[s.name for s in states].index("actuator.velocity")] = 0.3
        scale = np.array([float(s.nominal) for s in states])
        direction = np.random.default_rng(1).standard_normal(n) * scale

        def f(xx):
            m.setContinuousStates((c_double * n)(*xx), n)
            m.getDerivatives(buf, n)
            return np.array(buf)

        f(x)
        exact = np.array(m.getDirectionalDerivative([d.variable.valueReference for d in md.derivatives],
                                                    [s.valueReference for s in states],
                                                    list(direction)))
        h = 1e-6
        fd = (f(x + h * direction) - f(x - h * direction)) / (2 * h)
        np.testing.assert_allclose(exact / scale, fd / scale, rtol=1e-4,
                                   atol=1e-6 * np.max(np.abs(fd / scale)))
        # the declared dependencies (ModelStructure) hold every nonzero of the Jacobian
        der_vr = [d.variable.valueReference for d in md.derivatives]
        state_of_vr = {st.valueReference: j for j, st in enumerate(states)}
        declared = np.zeros((n, n), dtype=bool)
        for i, d in enumerate(md.derivatives):
            for dep in d.dependencies:
                if dep.valueReference in state_of_vr:
                    declared[i, state_of_vr[dep.valueReference]] = True
        for j, st in enumerate(states):
            col = np.array(m.getDirectionalDerivative(der_vr, [st.valueReference], [1.0]))
            assert not np.any((col != 0) & ~declared[:, j]), st.name
        # sparse: an importer can use it; each hose end's cavity (M45, on by default) adds its
        # rank-one block (A b) c^T to its section's (the end pressure read by every state)
        from hydroline.system import build_circuit

        circuit = build_circuit(hydroline.load_rig())
        rank_one = 0
        for c in circuit.components:
            for _, i, j, _ in getattr(c, "cavity_ends", ()):
                A, B, C = (np.asarray(getattr(c.model, k), dtype=float) for k in "ABC")
                rank_one += np.count_nonzero(A @ B[:, j]) * np.count_nonzero(C[i])
        assert rank_one > 0
        assert declared.sum() < 0.2 * n * n + rank_one
    finally:
        m.terminate()
        m.freeInstance()


@pytest.fixture(scope="module")
def closed_loop_fmu(tmp_path_factory):
    from hydroline.fmu import export_fmu

    return export_fmu(None, tmp_path_factory.mktemp("fmu") / "held.fmu", kind="cs",
                      start="closed-loop-sine")


def p_loop(fmu, h, t_end=1.0):
    """The closed-loop-sine test run by a P controller in Python around the co-simulation FMU:
    at each communication point i = clip(Kp (x_ref - x_p)), held over the step."""
    rig = hydroline.load_rig()
    kp, limit = rig["controller.proportional_gain"], rig["controller.current_limit"]
    amp = rig["scenario.closed-loop-sine.amplitude"]
    freq = rig["scenario.closed-loop-sine.frequency"]
    md, v = variables(fmu)
    s = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="loop")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    out = [v[k].valueReference for k in ("piston_position", "supply_port_pressure")]
    u = v["valve_current"].valueReference
    n = int(round(t_end / h))
    rows = []
    for k in range(n + 1):
        t = k * h
        x, p_s = s.getReal(out)
        rows.append((t, x, p_s))
        if k == n:
            break
        s.setReal([u], [float(np.clip(kp * (amp * np.sin(2 * np.pi * freq * t) - x), -limit, limit))])
        s.doStep(t, h)
    s.terminate()
    s.freeInstance()
    return np.array(rows)


def test_p_loop_around_the_fmu_matches_the_sampled_closed_loop_sine(closed_loop_fmu):
    """A sampled P controller (1 ms zero-order hold) is exactly what a co-simulation master
    with 1 ms steps does: the same test in hydroline (``controller.sample_time``) agrees."""
    rig = hydroline.load_rig().set("controller.sample_time", "1 ms")
    ref = hydroline.simulate(rig, "closed-loop-sine")
    run = p_loop(closed_loop_fmu, 1e-3)
    amp = rig["scenario.closed-loop-sine.amplitude"]
    x_ref = np.interp(run[:, 0], ref.t, ref["piston_position"])
    assert np.max(np.abs(run[:, 1] - x_ref)) < 1e-4 * amp
    p_ref = np.interp(run[:, 0], ref.t, ref["supply_port_pressure"])
    assert np.max(np.abs(run[:, 2] - p_ref)) < 1e-3 * np.ptp(ref["supply_port_pressure"])


def test_p_loop_converges_to_the_continuous_closed_loop_sine(closed_loop_fmu):
    """The default (continuous) P loop: the FMU loop's zero-order hold delays the current by
    about h/2, so its error falls like h -- 10x smaller step, about 10x smaller error -- and
    at h = 0.1 ms the piston follows hydroline's run within 0.1 % of the 35 mm amplitude."""
    rig = hydroline.load_rig()
    ref = hydroline.simulate(rig, "closed-loop-sine")
    amp = rig["scenario.closed-loop-sine.amplitude"]
    err = {}
    for h in (1e-3, 1e-4):
        run = p_loop(closed_loop_fmu, h)
        err[h] = np.max(np.abs(run[:, 1] - np.interp(run[:, 0], ref.t, ref["piston_position"])))
    assert err[1e-4] < 1e-3 * amp
    assert 5 < err[1e-3] / err[1e-4] < 20
    # the rms tracking error of the FMU loop is the scenario's (P-loop lag, hydroline summary)
    res = hydroline.summarize(ref)["tracking_error_rms_mm"]
    xr = amp * np.sin(2 * np.pi * rig["scenario.closed-loop-sine.frequency"] * run[:, 0])
    assert np.sqrt(np.mean((xr - run[:, 1]) ** 2)) * 1e3 == pytest.approx(res, rel=0.01)


def test_other_structure_as_fmi3_through_the_cli(tmp_path):
    """Supply section II removed (HSM close-coupled) and return section II shortened: another
    network structure, exported by ``hydroline export-fmu --fmi 3`` (FMI 3.0, both kinds),
    validated and run."""
    rig = hydroline.load_rig().set("supply.section2.length", "0 m").set(
        "return.section2.length", "0.75 m")
    rig_file = tmp_path / "close_coupled.toml"
    rig_file.write_text("[rig]\nbase = \"default\"\n\n[supply.section2]\nlength = \"0 m\"\n\n"
                        "[return.section2]\nlength = \"0.75 m\"\n")
    out = tmp_path / "close_coupled.fmu"
    assert main(["export-fmu", str(rig_file), "--out", str(out), "--fmi", "3", "--kind", "both"]) == 0
    assert validate_fmu(str(out)) == []
    md, v = variables(out)
    assert md.fmiVersion == "3.0" and v["time"].causality == "independent"
    assert not any(n.startswith("supply.section2.") for n in v)      # the removed section
    assert any(n.startswith("return.section2.") for n in v)
    assert "supply.node.pressure" in v                               # the HSM block's oil volume
    ref = hydroline.simulate(rig, "open-loop-step")
    for fmi_type in ("CoSimulation", "ModelExchange"):
        res = run_step(out, fmi_type)
        for key in ("supply_port_pressure", "return_port_pressure"):
            assert excursion_error(res, ref, key) < 0.005, (fmi_type, key)


def test_fmu_state_restores_a_co_simulation_step(default_fmu):
    """fmi2GetFMUstate/SetFMUstate (canGetAndSetFMUstate): a step repeated from a restored
    state gives the same outputs as the first time, also through serialization."""
    md, v = variables(default_fmu)
    s = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(default_fmu)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="state")
    s.instantiate()
    try:
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        out = [v[k].valueReference for k in OUTPUTS]
        s.setReal([v["valve_current"].valueReference], [0.05])
        s.doStep(0.0, 0.01)
        saved = s.serializeFMUState(s.getFMUState())
        s.doStep(0.01, 0.01)
        first = s.getReal(out)
        s.setFMUState(s.deserializeFMUState(saved))
        s.doStep(0.01, 0.01)
        assert s.getReal(out) == first
    finally:
        s.terminate()
        s.freeInstance()


@pytest.mark.parametrize("args, word", [
    (["--fmi", "4"], "--fmi"),
    (["--kind", "hybrid"], "--kind"),
    (["--out", "plant.zip"], "--out"),
    (["--start", "fatigue"], "--start"),
    (["no_such_rig.toml"], "no_such_rig.toml"),
    (["--out", "/dev/null/plant.fmu"], "--out"),
    ([str(Path(hydroline.__file__).parent / "rigs" / "two_axis.toml"), "--start", "position-step"],
     "single-axis"),
])
def test_bad_arguments_give_one_line_and_exit_2(capsys, args, word):
    assert main(["export-fmu", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and word in err


def test_no_compiler_gives_one_line(monkeypatch, capsys, tmp_path):
    monkeypatch.setenv("PATH", str(tmp_path))          # nothing to compile with
    monkeypatch.delenv("CC", raising=False)
    assert main(["export-fmu", "--out", str(tmp_path / "plant.fmu")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "C compiler" in err
