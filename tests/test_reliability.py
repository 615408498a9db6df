"""Issue 14: inputs, outputs and limits -- the reproducers of the issue, each a clean result or a
one-line error naming the parameter (exit 2).

Numbers asserted are hand-derived: laminar line resistances 128 mu L / (pi d^4) (M12), the
actuator's force capacity p_s A_b - p_t A_t, row counts t_end/dt + 1, the AR(1) variance
inflation (1 + rho)/(1 - rho).
"""
from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pandas as pd
import pytest

import hydroline
from hydroline.analysis.fit import fit_parameters, read_measurements, residual_correlation
from hydroline.cli import main
from hydroline.limits import MAX_TABLE_BYTES, check_output_size, output_estimate
from hydroline.rigs import SCHEMA, RigError, load_rig
from hydroline.rigs.parameters import (ATMOSPHERIC_PRESSURE, PARAMETERS, check_consistency,
                                       check_ranges, defaults_used, steady_state_hint)
from hydroline.scenarios import build_scenario, check_cavitation
from hydroline.engine import SimulationResult, solve_steady_state
from hydroline.system import build_network, validate_rig

SHORT = "0.02 s"


def _rig_file(tmp_path, body, name="r.toml"):
    f = tmp_path / name
    f.write_text('[rig]\nbase = "default"\n' + textwrap.dedent(body))
    return f


def _one_error(capsys, rc, needle):
    """Exit 2 and one error line on stderr (notes of the summary may come before it)."""
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    errors = [ln for ln in lines if ": error: " in ln]
    assert rc == 2, cap.err
    assert len(errors) == 1 and needle in errors[0] and "Traceback" not in cap.err, cap.err
    assert all(": note: " in ln or ": warning: " in ln for ln in lines if ln not in errors)
    return errors[0]


# ------------------------------------------------------------------ the parameter table

def test_parameter_table_covers_the_schema_with_the_same_units():
    for section, keys in SCHEMA.items():
        for key, unit in keys.items():
            path = f"{section}.{key}"
            if unit == "str" or "pressure_profile" in section:
                continue
            assert path in PARAMETERS, path
            assert PARAMETERS[path].unit == unit.replace("list:", ""), path
    for path, p in PARAMETERS.items():
        assert p.low is None or p.high is None or p.low < p.high, path
        if isinstance(p.default, str) and p.default != "required":
            assert p.default in PARAMETERS, path


def test_default_rig_within_every_range_and_reports_no_defaults():
    rig = load_rig()
    check_ranges(rig)
    check_consistency(rig)
    for scenario in ("open-loop-step", "closed-loop-sine"):
        check_consistency(rig, scenario)
        assert defaults_used(rig, scenario) == []


@pytest.mark.parametrize("path, value", [
    ("actuator.area", "1e-30 cm^2"),                     # omega_h 6.6e-29 Hz
    ("actuator.dead_volume", "1e30 cm^3"),
    ("supply.accumulator.capacity", "1e30 L"),
    ("supply.section1.length", "1e-30 m"),               # numpy warnings and a Line repr before
    ("rig.modes_per_section", 200),                      # minutes of run time before
])
def test_absurd_values_refused_naming_the_parameter_and_the_override(path, value):
    rig = load_rig()
    rig.set(path, value)
    with pytest.raises(RigError) as err:
        validate_rig(rig)
    msg = str(err.value)
    assert msg.startswith(f"{path}: ") and "plausible range" in msg
    assert "allow_implausible" in msg and "\n" not in msg
    rig.set("rig.allow_implausible", [path])            # the explicit override
    check_ranges(rig)


def test_negative_leakage_refused_even_with_the_override():
    rig = load_rig()
    rig.set("actuator.internal_leakage", "-1e-12 m^3/s/Pa")
    rig.set("rig.allow_implausible", ["actuator.internal_leakage"])
    with pytest.raises(RigError, match=r"^actuator\.internal_leakage: must be >= 0 \[m\^3/s/Pa\]"):
        check_ranges(rig)
    rig.set("rig.allow_implausible", ["actuator.leakage"])
    with pytest.raises(RigError, match=r"^rig\.allow_implausible: 'actuator\.leakage' is not"):
        check_ranges(rig)


def test_weight_beyond_force_capacity_refused_with_both_forces():
    """A 10 t load: (7.953 + 10000) kg * 9.81 m/s^2 = 98.2 kN against the ~10 kN the
    actuator pushes, (p_s - p_t) A (A_b = A_t = 4.83 cm^2)."""
    rig = load_rig()
    rig.set("load.mass", "10 t")
    capacity = (rig["supply.pressure"] - rig["return.pressure"]) * rig["actuator.area"]
    assert 9e3 < capacity < 10.5e3
    with pytest.raises(RigError) as err:
        validate_rig(rig)
    msg = str(err.value)
    assert msg.startswith("load.mass: ") and "98.2 kN" in msg
    assert f"= {capacity / 1e3:.3g} kN" in msg
    rig.set("rig.allow_implausible", ["load.mass"])
    validate_rig(rig)


def test_step_current_beyond_rating_and_sine_beyond_stroke_refused():
    rig = load_rig()
    rig.set("scenario.open-loop-step.current", "5 A")              # 100x rated, was clipped
    with pytest.raises(RigError, match=r"^scenario\.open-loop-step\.current: '5 A' exceeds the "
                                       r"servovalve's rated current 50 mA"):
        build_scenario(rig, "open-loop-step")
    rig.set("scenario.closed-loop-sine.amplitude", "40 mm")
    rig.set("scenario.closed-loop-sine.offset", "20 mm")           # 60 mm > 51 mm
    with pytest.raises(RigError, match=r"^scenario\.closed-loop-sine\.amplitude: .*60 mm"):
        build_scenario(rig, "closed-loop-sine")


def test_deleted_key_is_reported_as_defaulted(tmp_path, capsys):
    """A deleted hose bulk modulus falls back to the oil's 1.5 GPa: said once on stderr."""
    rig = load_rig()
    del rig.values["supply.section1.bulk_modulus"]
    assert ("supply.section1.bulk_modulus", "fluid.bulk_modulus = 1.5e+09 Pa") in \
        defaults_used(rig, "open-loop-step")
    del rig.raw["supply.section1.bulk_modulus"]
    f = tmp_path / "r.toml"
    f.write_text(rig.to_toml())          # the whole rig, that key deleted
    rc = main(["simulate", str(f), "--json", "--t-end", SHORT, "--out", str(tmp_path / "o")])
    cap = capsys.readouterr()
    assert rc == 0
    notes = [ln for ln in cap.err.splitlines() if "defaults used" in ln]
    assert len(notes) == 1 and "supply.section1.bulk_modulus = fluid.bulk_modulus" in notes[0]


# ------------------------------------------------------------------ gas release

def test_gas_release_warned_from_the_first_crossing():
    t = np.arange(0, 0.0101, 1e-3)
    p = np.full_like(t, 2e5)
    p[3:6] = 0.9e5                     # below 1 atm from 3 ms, lowest 0.8e5 Pa at 4 ms
    p[4] = 0.8e5
    res = SimulationResult(pd.DataFrame({"return_port_pressure": p}, index=pd.Index(t, name="time")))
    (w,) = check_cavitation(res, ATMOSPHERIC_PRESSURE)
    assert w.startswith("return_port_pressure falls below 0.101 MPa absolute from t = 3.0 ms "
                        "(lowest 0.08 MPa at 4.0 ms)")
    assert check_cavitation(res, 0.5e5) == []        # a rig's lower fluid.gas_release_pressure


# ------------------------------------------------------------------ steady state

def test_two_mm_bores_solve_to_the_laminar_line_drops():
    """Valid rig of the issue: every hose 2 mm. At rest the null leakage q flows through the
    lines; pressure drops q * (sum of 128 mu L/(pi d^4) + manifold resistance) (M12)."""
    rig = load_rig()
    for s in ("supply.section1", "supply.section2", "return.section1", "return.section2"):
        rig.set(f"{s}.diameter", "2 mm")
    sc = build_scenario(rig)
    net = build_network(rig, sc.commands, sc.position_guess)
    ss = solve_steady_state(net)
    u = net.signals_at(0.0, ss.x, ss.p)
    mu = 870 * 32e-6

    def r_line(s):
        return 128 * mu * rig[f"{s}.length"] / (np.pi * 0.002**4)

    q = u["return_port_flow"]
    assert q > 0 and u["tank_flow"] == pytest.approx(q, rel=1e-9)
    drop_r = q * (r_line("return.section1") + r_line("return.section2")
                  + rig["return.manifold.resistance"])
    assert u["return_port_pressure"] - u["tank_pressure"] == pytest.approx(drop_r, rel=1e-6)
    drop_s = u["supply_port_flow"] * (r_line("supply.section1") + r_line("supply.section2")
                                      + rig["supply.manifold.resistance"])
    assert u["pump_pressure"] - u["supply_port_pressure"] == pytest.approx(drop_s, rel=1e-6)


def test_zero_laps_solve_and_a_low_precharge_gets_its_true_reason():
    rig = load_rig()
    rig.set("servovalve.laps", ["0 um"] * 4)
    sc = build_scenario(rig)
    ss = solve_steady_state(build_network(rig, sc.commands, sc.position_guess))
    assert ss.residual < 1e-8
    rig = load_rig()
    rig.set("supply.accumulator.precharge_pressure", "0.01 MPa")
    with pytest.raises(RigError) as err:
        validate_rig(rig)
    msg = str(err.value)       # 0.01 / 20.7 = 0.048 % < the model's 0.1 % gas floor
    assert msg.startswith("supply.accumulator.precharge_pressure: '0.01 MPa' is 0.048 % of "
                          "supply.pressure") and "gas-side end" in msg


def test_steady_state_hint_names_parameters():
    assert "return.section2.diameter" in steady_state_hint("return.section2.mode1.pressure")
    assert "supply.accumulator.precharge_pressure" in steady_state_hint("supply.accumulator.flow")
    assert "actuator.initial_position" in steady_state_hint("actuator.position")


# ------------------------------------------------------------------ limits

def test_output_estimate_and_refusal_before_the_run(tmp_path, capsys, monkeypatch):
    est = output_estimate(0.25, 1e-4, 86)
    assert est.rows == 2501 and est.columns == 87 and est.memory_bytes == 8 * 2501 * 87
    with pytest.raises(ValueError, match=r"^--t-end: 1e\+30 s at a 0.0001 s output step"):
        check_output_size(1e30, 1e-4, 86, name="--t-end")
    assert output_estimate(1e30, 1e-4, 86).memory_bytes > MAX_TABLE_BYTES

    def no_run(*a, **k):
        raise AssertionError("the steady state was solved")

    monkeypatch.setattr("hydroline.scenarios.running.solve_steady_state", no_run)
    rc = main(["simulate", "--t-end", "1e30 s", "--out", str(tmp_path)])
    _one_error(capsys, rc, "--t-end: 1e+30 s")


# ------------------------------------------------------------------ outputs

@pytest.mark.parametrize("setup, needle", [
    ("file", "exists and is not a folder"),
    ("under_file", "which is a file, not a folder"),
    ("csv_folder", "results.csv is a folder"),
])
def test_output_path_checked_before_the_run(tmp_path, capsys, monkeypatch, setup, needle):
    monkeypatch.setattr("hydroline.scenarios.running.simulate",
                        lambda *a, **k: pytest.fail("ran before checking --out"))
    target = tmp_path / "out"
    if setup == "file":
        target.write_text("x")
    elif setup == "under_file":
        target.write_text("x")
        target = target / "sub"
    else:
        (target / "results.csv").mkdir(parents=True)
    rc = main(["simulate", "--out", str(target)])
    _one_error(capsys, rc, needle)


def test_failed_write_keeps_the_previous_results(tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    assert main(["simulate", "--json", "--t-end", SHORT, "--out", str(out)]) == 0
    capsys.readouterr()
    before = {f: (out / f).read_bytes() for f in ("results.csv", "summary.json", "pressures.png")}

    # the figure, the last of the three files, fails: drawn in the figure process (its error
    # raised in the parent) and, with that process off, in the command's own
    monkeypatch.setattr("hydroline.plotting.plot_result", figure_on_a_full_disk)
    for process in ("1", "0"):
        monkeypatch.setenv("HYDROLINE_FIGURE_PROCESS", process)
        rc = main(["simulate", "--json", "--t-end", "0.03 s", "--out", str(out)])
        _one_error(capsys, rc, "no space left on the device")
        assert {f: (out / f).read_bytes() for f in before} == before
        assert sorted(os.listdir(out)) == sorted(before)            # no temporary file left


def figure_on_a_full_disk(*args, **kwargs):
    """Stands in for hydroline.plotting.plot_result (module level: the figure process
    receives it by name)."""
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_full_stdout_is_one_line(tmp_path, capsys, monkeypatch):
    class Full:
        def write(self, s):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        def flush(self):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(sys, "stdout", Full())
    rc = main(["simulate", "--json", "--t-end", SHORT, "--out", str(tmp_path)])
    _one_error(capsys, rc, "cannot write to stdout: No space left on device")


def test_deeply_nested_lists_are_one_line(tmp_path, capsys):
    f = tmp_path / "nested.toml"
    f.write_text('[rig]\nbase = "default"\n[servovalve]\nlaps = ' + "[" * 5000 + '"1 um"'
                 + "]" * 5000 + "\n")
    rc = main(["simulate", str(f), "--out", str(tmp_path)])
    _one_error(capsys, rc, "nested too deeply")


def test_results_csv_has_units_and_is_read_by_fit(tmp_path):
    """The round trip of issue 14: simulate -> results.csv -> fit. Noise-free, started at the
    truth: the interval covers it (the time-correlated misfit of a sampled current
    step widens it, and the message says why)."""
    res = hydroline.simulate(t_end=0.06)
    res.to_csv(tmp_path / "results.csv")
    head = (tmp_path / "results.csv").read_text().splitlines()[0].split(",")
    assert head[0] == "time [s]" and "supply_port_pressure [Pa]" in head
    assert "piston_velocity [m/s]" in head and "valve_current [A]" in head
    meas = read_measurements(tmp_path / "results.csv")
    assert np.allclose(meas.data["supply_port_pressure"], res["supply_port_pressure"])
    truth = load_rig()["supply.section2.bulk_modulus"]
    fit = fit_parameters(load_rig(), meas, ["supply.section2.bulk_modulus"],
                         signals=["supply_port_pressure", "return_port_pressure"])
    assert fit.ci_low[0] <= truth <= fit.ci_high[0]
    assert "correlated in time" in fit.message


def test_residual_correlation_of_an_ar1_series():
    rng = np.random.default_rng(3)
    e = rng.standard_normal(200_000)
    r = np.empty_like(e)
    r[0] = e[0]
    for k in range(1, len(e)):
        r[k] = 0.9 * r[k - 1] + e[k]
    rho, inflation = residual_correlation([r])
    assert rho == pytest.approx(0.9, abs=0.01)
    assert inflation == pytest.approx(1.9 / 0.1, rel=0.1)
    assert residual_correlation([rng.standard_normal(10_000)])[1] == pytest.approx(1.0, abs=0.05)


# ------------------------------------------------------------------ exit codes, --version

def test_version(capsys):
    with pytest.raises(SystemExit) as ex:
        main(["--version"])
    assert ex.value.code == 0
    assert capsys.readouterr().out.strip() == f"hydroline {hydroline.__version__}"


def test_sigterm_exits_143(monkeypatch, capsys):
    import hydroline.cli.simulate as cli_sim

    def killed(args):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)
        return 0

    monkeypatch.setattr(cli_sim, "run", killed)
    assert main(["simulate"]) == 143
    assert "terminated (SIGTERM)" in capsys.readouterr().err


def test_sweep_script_without_main_guard(tmp_path):
    """The README's design-study block saved as a script: the workers must not run it again
    (they did: three studies, every variant 'WorkerDied')."""
    script = tmp_path / "study.py"
    script.write_text(textwrap.dedent("""\
        import hydroline
        print("script body")
        sw = hydroline.studies.sweep({"supply.section2.diameter": "12.7 mm, 15.9 mm"},
                                     out="bore-sweep", workers=2, t_end=0.02)
        print("failed", sw.n_failed, "rows", len(sw.table))
        """))
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("script body") == 1
    assert "failed 0 rows 2" in done.stdout
    table = pd.read_csv(tmp_path / "bore-sweep" / "sweep.csv")
    assert table["error"].isna().all()


def write_checksum(data, path):
    """Stands in for a figure: writes the SHA-256 of the array it received (module level: the
    figure process receives it by name)."""
    import hashlib

    with open(path, "w") as f:
        f.write(hashlib.sha256(data.tobytes()).hexdigest())


@pytest.mark.skipif(not hasattr(os, "fork"), reason="the figure process needs os.fork")
def test_figure_process_takes_a_job_larger_than_a_pipe(tmp_path):
    """The job (a figure's columns, ~0.1-1 MB) is larger than a pipe holds (64 kB): submit()
    hands it over from a thread and returns, so the command writes its CSV meanwhile; the child
    receives every byte."""
    import hashlib

    from hydroline.cli.figure_process import FigureProcess

    data = np.random.default_rng(1).normal(size=500_000)     # 4 MB
    figures = FigureProcess()
    figures.submit(write_checksum, data, str(tmp_path / "sum.txt"))
    (tmp_path / "meanwhile.txt").write_text("the parent went on")   # before the child is done
    figures.wait()
    assert (tmp_path / "sum.txt").read_text() == hashlib.sha256(data.tobytes()).hexdigest()
    assert figures.pid is None
