"""Experiments as objects: built-in ones by name or as objects, a user's own command per axis
(waveform or CSV) from the rig file, its schema refused in one line."""
from pathlib import Path

import numpy as np
import pytest

import hydroline
from hydroline.cli import main
from hydroline.rigs import RigError, load_rig
from hydroline.scenarios import (AxisCommand, AxisCommands, ClosedLoopSine, OpenLoopStep,
                                 build_scenario, scenario_names, simulate, summarize)

TWO_AXIS = Path(hydroline.__file__).parent / "rigs" / "two_axis.toml"
STEP_CSV = "time [ms], current [mA]\n0, 0\n10, 0\n10.000001, 50\n250, 50\n"


def own_rig(tmp_path, text, base='[rig]\nbase = "default"\n'):
    f = tmp_path / "rig.toml"
    f.write_text(base + text)
    return f


@pytest.fixture(scope="module")
def open_loop_step():
    return simulate(None, "open-loop-step")


def test_csv_step_equals_open_loop_step(tmp_path):
    # a table that rises from 0 to the rated 50 mA in 1 ns at 10 ms is the paper's step
    (tmp_path / "step.csv").write_text(STEP_CSV)
    f = own_rig(tmp_path, '[scenario.csv-step]\ntype = "axis-commands"\nt_end = "0.25 s"\n'
                '[scenario.csv-step.actuator]\nquantity = "current"\nwaveform = "csv"\n'
                'file = "step.csv"\n')
    # (rtol throughout: after the stop simulate() goes on 30x looser by default, where two
    # runs of equal rigs part by up to ~0.2 % of the excursion)
    res = simulate(f, "csv-step", after_stop_rtol=None)
    ref = simulate(None, "open-loop-step", after_stop_rtol=None)
    for k in ("supply_port_pressure", "return_port_pressure", "piston_velocity"):
        # rtol 1e-6: traces agree to 6e-3 % of their excursion (simulate's docstring)
        assert np.max(np.abs(res[k] - ref[k])) < 1e-4 * np.ptp(ref[k]), k
    s, s_ref = summarize(res), summarize(ref)
    assert res.metadata["t_disturbance"] == pytest.approx(0.01)   # the table's first change
    for side in ("supply", "return"):
        assert s[side]["frequency_hz"] == pytest.approx(s_ref[side]["frequency_hz"], rel=1e-4)
        assert s[side]["amplitude_mpa"] == pytest.approx(s_ref[side]["amplitude_mpa"], rel=1e-4)
    assert set(s) == set(s_ref)          # the single-axis summary schema


def test_experiment_object_equals_its_name(open_loop_step):
    res = simulate(None, OpenLoopStep(current=0.05, time=0.01, t_end=0.25))
    assert np.array_equal(res["supply_port_pressure"], open_loop_step["supply_port_pressure"])
    assert res.metadata["scenario"] == "open-loop-step"
    # the same command as a user's own (in Python: a step waveform)
    own = AxisCommands(name="mine", t_end=0.25, axes={"actuator": AxisCommand(
        "current", "step", {"initial": 0.0, "final": 0.05, "time": 0.01})})
    res2 = simulate(None, own)
    assert np.max(np.abs(res2["supply_port_pressure"] - open_loop_step["supply_port_pressure"])) \
        < 1e-6 * np.ptp(open_loop_step["supply_port_pressure"])
    assert summarize(res2)["metrics_window_s"][0] == pytest.approx(0.01)


def test_own_sine_on_axis2_of_two_axis(tmp_path):
    text = TWO_AXIS.read_text() + (
        '\n[scenario.axis2-sine]\ntype = "axis-commands"\nt_end = "0.6 s"\n'
        '[scenario.axis2-sine.axis2]\nquantity = "position"\nwaveform = "sine"\n'
        'amplitude = "5 mm"\nfrequency = "4 Hz"\n')
    f = own_rig(tmp_path, text, base="")
    rig = load_rig(f)
    assert "axis2-sine" in scenario_names(rig)
    res = simulate(rig, "axis2-sine", dt_out=5e-4)
    t, x, r = res.t, res["axis2.piston_position"], res["axis2.position_reference"]
    m = t >= 0.25                       # the start transient (tau = 1/K_v ~ 30 ms) is over
    w = 2 * np.pi * 4.0

    def phasor(y):
        M = np.column_stack([np.sin(w * t[m]), np.cos(w * t[m]), np.ones(m.sum())])
        c = np.linalg.lstsq(M, y[m], rcond=None)[0]
        return c[0] + 1j * c[1]

    ratio = phasor(x) / phasor(r)
    # hand-derived P loop: x/r = 1 / (1 + j w / K_v), K_v = K_p (Q_N / i_N)
    # sqrt((p_P - p_T) / dp_N) / A (M20, M21 at null, no load), times the describing function
    # of the 4 um underlap (double flow gain within +-u): N = 1 + (2/pi)(asin(a) + a sqrt(1-a^2)),
    # a = u / spool amplitude; the 140 Hz valve adds 2 zeta f / f_v rad of lag
    sv = {k: rig[f"circuit.axis2.servovalve.{k}"] for k in
          ("rated_flow", "rated_current", "rated_pressure_drop", "max_opening")}
    dp = np.mean(res["axis2.supply_port_pressure"][m] - res["axis2.return_port_pressure"][m])
    kp = rig["circuit.axis2.controller.proportional_gain"]
    area = rig["circuit.axis2.actuator.bottom_area"]
    spool = kp * abs(phasor(r - x)) / sv["rated_current"] * sv["max_opening"]
    a = rig["circuit.axis2.servovalve.laps"][0] / spool
    N = 1 + 2 / np.pi * (np.arcsin(a) + a * np.sqrt(1 - a * a))
    kv = kp * sv["rated_flow"] / sv["rated_current"] * np.sqrt(dp / sv["rated_pressure_drop"]) / area * N
    expected = 1 / (1 + 1j * w / kv) * np.exp(-1j * 2 * 1.0 * 4.0 / 140.0)
    assert abs(ratio) == pytest.approx(abs(expected), rel=0.03)
    assert np.angle(ratio) == pytest.approx(np.angle(expected), abs=np.radians(3))
    s = summarize(res)
    assert s["axes"]["axis2"]["position_disturbance_mm"] is None      # driven on purpose
    assert s["axes"]["axis1"]["position_disturbance_mm"] < 0.05       # holds its position


@pytest.mark.parametrize("table, key, words", [
    ('quantity = "position"\nwaveform = "sine"\namplitude = 5\nfrequency = "4 Hz"\n',
     "scenario.bad.actuator.amplitude", ["'5 m'"]),
    ('quantity = "current"\nwaveform = "sine"\namplitude = "5 mm"\nfrequency = "4 Hz"\n',
     "scenario.bad.actuator.amplitude", ["A"]),
    ('quantity = "current"\nwaveform = "step"\nfinal = "5 mA"\nfrequency = "4 Hz"\n',
     "scenario.bad.actuator.frequency", ["not a key", "final [A]"]),
    ('waveform = "step"\nfinal = "5 mA"\n',
     "scenario.bad.actuator.quantity", ["[A]", "[m]"]),
    ('quantity = "current"\nwaveform = "step"\nfinal = "5 mA"\n',
     "scenario.bad.actuator.time", ["required", "[s]"]),
    ('quantity = "force"\nwaveform = "step"\n', "scenario.bad.actuator.quantity", ["[A]"]),
    ('quantity = "current"\nwaveform = "csv"\nfile = "missing.csv"\n',
     "scenario.bad.actuator.file", ["not found"]),
])
def test_bad_own_scenario_refused_in_one_line(tmp_path, table, key, words):
    f = own_rig(tmp_path, '[scenario.bad]\ntype = "axis-commands"\nt_end = "0.1 s"\n'
                '[scenario.bad.actuator]\n' + table)
    with pytest.raises(RigError) as e:
        build_scenario(load_rig(f), "bad")
    msg = str(e.value)
    assert msg.startswith(key) and "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_bad_own_scenario_top_level(tmp_path):
    for text, key in (('t_end = 0.1\n', "scenario.bad.t_end"),
                      ('t_end = "0.1 s"\nperiod = "1 s"\n', "scenario.bad.period")):
        f = own_rig(tmp_path, '[scenario.bad]\ntype = "axis-commands"\n' + text)
        with pytest.raises(RigError, match=key.replace(".", r"\.")):
            build_scenario(load_rig(f), "bad")
    f = own_rig(tmp_path, '[scenario.bad]\ntype = "axis-commands"\nt_end = "0.1 s"\n'
                '[scenario.bad.axis9]\nquantity = "current"\nwaveform = "step"\n'
                'final = "1 mA"\ntime = "1 ms"\n')
    with pytest.raises(RigError, match=r"scenario\.bad\.axis9: no axis 'axis9'"):
        build_scenario(load_rig(f), "bad")


def test_cli_runs_own_scenario_and_refuses_unknown(tmp_path, capsys):
    (tmp_path / "step.csv").write_text(STEP_CSV)
    f = own_rig(tmp_path, '[scenario.csv-step]\ntype = "axis-commands"\nt_end = "0.05 s"\n'
                '[scenario.csv-step.actuator]\nquantity = "current"\nwaveform = "csv"\n'
                'file = "step.csv"\n')
    assert main(["simulate", str(f), "--scenario", "csv-step", "--json"]) == 0
    assert '"supply"' in capsys.readouterr().out
    assert main(["simulate", str(f), "--scenario", "no-such", "--json"]) == 2
    err = capsys.readouterr().err
    assert "no-such" in err and "csv-step" in err and "Traceback" not in err


def test_closed_loop_sine_object_validates():
    with pytest.raises(RigError, match=r"frequency: must be > 0 \[Hz\]"):
        ClosedLoopSine(amplitude=0.01, frequency=0.0)


@pytest.mark.parametrize("rig_name", [None, "two_axis"])
def test_run_ending_before_the_disturbance_is_refused_naming_both_times(rig_name, capsys):
    """--t-end 5 ms against a step at 10 ms: one line naming t_end, the step's key and both
    times (the metrics used to fail on a time span without the step)."""
    from hydroline.cli import main

    args = ["simulate"] + ([rig_name] if rig_name else []) + ["--json", "--t-end", "5 ms"]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "t_end: the run would end at 5 ms, before the disturbance" in err[0]
    assert "at 10 ms (scenario." in err[0] and ".time) [s]" in err[0]


def test_every_builtin_scenario_runs_on_the_default_rig(tmp_path, capsys):
    """position-step on the default (template) rig: the rig's [controller] closes the loop, as
    for the closed-loop sine; the piston ends at the rig's step (a P loop on an integrating
    plant has no steady error without a load force: the default rig's load is a mass)."""
    from hydroline.cli.simulate import BUILTIN_SCENARIOS

    rig = load_rig()
    step = rig["scenario.position-step.step"]
    assert 0 < step <= rig["actuator.stroke"] / 2
    assert main(["simulate", "--scenario", "position-step", "--json", "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    import pandas as pd
    tab = pd.read_csv(tmp_path / "results.csv", usecols=["position_reference [m]",
                                                         "piston_position [m]"])
    assert tab["position_reference [m]"].iloc[-1] == pytest.approx(step, rel=1e-9)
    assert tab["piston_position [m]"].iloc[-1] == pytest.approx(step, rel=0.02)
    for scenario in BUILTIN_SCENARIOS:    # the others: the scenario builds (no run)
        assert build_scenario(rig, scenario).t_end > 0


def test_missing_scenario_value_says_what_to_add(tmp_path, capsys):
    """A rig without scenario.position-step.step: one line with the TOML to add (the embedded
    rig's value as an example)."""
    text = TWO_AXIS.read_text()
    f = tmp_path / "no_step.toml"
    f.write_text("\n".join(ln for ln in text.splitlines() if not ln.startswith("step =")))
    assert main(["simulate", str(f), "--scenario", "position-step", "--json"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    raw = load_rig().raw["scenario.position-step.step"]
    assert f'add to the rig file: [scenario.position-step] step = "{raw}"' in err[0]


def test_a_simulation_object_keeps_its_own_models():
    """A :class:`Simulation` of one's own keeps the models of its runs apart from the default
    one that ``hydroline.simulate`` runs on; a repeated run reuses its model (same numbers);
    the oldest model goes beyond ``models_kept``; an experiment object is never kept."""
    import inspect

    from hydroline.scenarios.running import DEFAULT_SIMULATION, Simulation

    rig = load_rig()
    sim = Simulation(models_kept=1)
    before = dict(DEFAULT_SIMULATION.models)
    first = sim.run(rig, "open-loop-step", t_end=0.02)
    assert len(sim.models) == 1 and DEFAULT_SIMULATION.models == before
    model = next(iter(sim.models.values()))
    again = sim.run(rig, "open-loop-step", t_end=0.02)
    assert next(iter(sim.models.values())) is model
    np.testing.assert_array_equal(again.data.to_numpy(), first.data.to_numpy())
    sim.remember(("another", None, ""), "model")
    assert list(sim.models) == [("another", None, "")]      # one kept: the oldest went
    assert Simulation.model_key(rig, OpenLoopStep(t_end=0.02), None) is None
    # simulate() is Simulation.run on the default object (or on ``simulation``): the same
    # keywords and defaults
    run = inspect.signature(Simulation.run).parameters
    assert [p for name, p in inspect.signature(simulate).parameters.items()
            if name != "simulation"] == list(run.values())[1:]


def test_a_model_built_before_its_run_is_built_once(monkeypatch):
    """``Simulation.model`` (what ``hydroline simulate`` reads the model's size from) builds
    the circuit the coming run integrates: the run does not build it again, and runs as a
    simulation without it does."""
    from hydroline.scenarios import running

    built = []
    build = running.build_circuit
    monkeypatch.setattr(running, "build_circuit", lambda *a, **k: built.append(1) or build(*a, **k))
    rig = load_rig()
    sim = running.Simulation(models_kept=1)
    circuit, sc, net = sim.model(rig, None, 0.02)
    res = sim.run(rig, None, 0.02)
    assert len(built) == 1 and next(iter(sim.models.values()))[2] is net
    plain = running.Simulation(models_kept=1).run(rig, None, 0.02)
    np.testing.assert_array_equal(res.data.to_numpy(), plain.data.to_numpy())
