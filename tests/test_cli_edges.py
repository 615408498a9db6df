"""Issue 24 items 5 and 6: the command line's edges (one line, exit 2, no traceback; exit 141
on a closed stdout; no stray file after Ctrl-C; a sweep's levels checked before its first
variant; one line for Matplotlib's glyph warnings) and the note before an expensive run.

Every case runs in-process and stops before a simulation where it can (a refused command line,
or ``hydroline.scenarios.running.simulate`` replaced); the few that run, run 20 ms of the default rig.
"""
from __future__ import annotations

import importlib
import os
import subprocess
import sys
import textwrap
import time
from importlib import resources

import numpy as np
import pytest

from hydroline import compiled
from hydroline.cli import main
from hydroline.plotting import TITLE_CHARACTERS, Traces, figure_title, plot_result
from hydroline.rigs import load_rig
from hydroline.studies.design import parse_parameters
from hydroline.studies.sweep import check_levels


def _one_error(capsys, rc, *needles):
    """Exit 2, exactly one line on stderr (the error), naming each of ``needles``."""
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 2, err
    assert len(lines) == 1 and ": error: " in lines[0] and "Traceback" not in err, err
    for needle in needles:
        assert needle in lines[0], err
    return lines[0]


def _no_run(*args, **kwargs):
    raise AssertionError("the command ran a simulation")


# ------------------------------------------------------------------ empty values

@pytest.mark.parametrize("argv, name", [
    (["simulate", "--t-end", ""], "--t-end"),
    (["simulate", "--scenario", ""], "--scenario"),
    (["simulate", "--out", ""], "--out"),
    (["simulate", "--json", "--out", " "], "--out"),
    (["simulate", "--dt-out", ""], "--dt-out"),
    (["simulate", ""], "RIG"),
    (["circuit", "--png", ""], "--png"),
    (["sweep", "--set", ""], "--set"),
    (["sweep", "--out", ""], "--out"),
])
def test_an_empty_value_is_refused_not_taken_as_the_default(tmp_path, monkeypatch, capsys,
                                                            argv, name):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("hydroline.scenarios.running.simulate", _no_run)
    _one_error(capsys, main(argv), f"{name}: empty value")
    assert os.listdir(tmp_path) == []         # --out "" wrote nothing into the current folder


# ------------------------------------------------------------------ rig names and arguments

def test_a_missing_rig_file_is_not_the_shipped_rig_of_its_name(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)               # no two_axis.toml here
    monkeypatch.setattr("hydroline.scenarios.running.simulate", _no_run)
    _one_error(capsys, main(["simulate", "two_axis.toml", "--json"]),
               "rig file not found: two_axis.toml", "'two_axis'")
    assert main(["circuit", "two_axis", "--json"]) == 0   # the shipped name still loads it


@pytest.mark.parametrize("extra, needle", [
    (["two_axis.tom"], "'two_axis.tom'"),
    (["--json"], "--json"),
    (["--png", "c.png"], "--png"),
])
def test_circuit_types_takes_no_other_argument(tmp_path, monkeypatch, capsys, extra, needle):
    monkeypatch.chdir(tmp_path)
    _one_error(capsys, main(["circuit", "--types", *extra]), "--types", needle)
    assert os.listdir(tmp_path) == []


def test_an_output_step_longer_than_the_run_is_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("hydroline.scenarios.running.simulate", _no_run)
    _one_error(capsys, main(["simulate", "--t-end", "50 ms", "--dt-out", "10 s", "--json"]),
               "--dt-out: 10 s", "0.05 s")


def test_export_fmu_of_a_two_axis_rig_says_single_axis_first(tmp_path, capsys):
    if not compiled.available():
        pytest.skip("no C compiler: export-fmu stops at that first")
    _one_error(capsys, main(["export-fmu", "two_axis", "--out", str(tmp_path / "p.fmu")]),
               "2 servo axes (axis1, axis2)", "single-axis")


def test_a_missing_key_is_named_once(tmp_path, capsys):
    # the embedded rig with the supply hose's first section's bore deleted (no default)
    text = resources.files("hydroline.rigs").joinpath("ayalew2005.toml").read_text()
    head, _, tail = text.partition("[supply.section1]")
    kept = [ln for ln in tail.splitlines(keepends=True)]
    i = next(k for k, ln in enumerate(kept) if ln.startswith("diameter"))
    f = tmp_path / "no_bore.toml"
    f.write_text(head + "[supply.section1]" + "".join(kept[:i] + kept[i + 1:]))
    line = _one_error(capsys, main(["circuit", str(f)]), "supply.section1.diameter: not set")
    assert line.count("supply.section1") == 1


# ------------------------------------------------------------------ the sweep's levels

@pytest.mark.parametrize("rig, spec, path", [
    (None, "supply.pressure=20 MPa,1e30 MPa", "supply.pressure"),
    (None, "supply.section2.diameter=15.9 mm,-5 mm", "supply.section2.diameter"),
    ("two_axis", "circuit.axis2.supply_hose.length=1.5 m,1e9 m",
     "circuit.axis2.supply_hose.length"),
])
def test_sweep_refuses_an_implausible_level_before_any_variant(tmp_path, monkeypatch, capsys,
                                                              rig, spec, path):
    study = importlib.import_module("hydroline.studies.sweep")   # (the module, not the function)
    monkeypatch.setattr(study.VariantRunner, "__call__", _no_run)
    out = tmp_path / "sweep"
    argv = ["sweep", *([rig] if rig else []), "--set", spec, "--workers", "1", "--out", str(out)]
    _one_error(capsys, main(argv), path)
    assert not out.exists()                  # refused before the results file is opened


def test_sweep_levels_checked_alone_not_their_combinations():
    rig = load_rig(None)
    # a distribution's ends are levels too
    with pytest.raises(ValueError, match="supply.pressure: .* plausible range"):
        check_levels(rig, parse_parameters(["supply.pressure=uniform(20 MPa, 1e30 MPa)"], rig))
    # each level within its range; a 25 MPa pre-charge above a 20 MPa supply is a variant
    # that fails with its reason, not a level no variant can run (with 30 MPa it runs)
    check_levels(rig, parse_parameters(["supply.pressure=20 MPa,30 MPa",
                                        "supply.accumulator.precharge_pressure=25 MPa"], rig))


# ------------------------------------------------------------------ closed stdout, Ctrl-C

@pytest.mark.parametrize("argv", [
    ["simulate", "--json", "--t-end", "0.02 s"],
    ["circuit"],
])
def test_a_closed_stdout_exits_141_without_a_traceback(monkeypatch, capsys, argv):
    """``hydroline simulate --json >&-``: Python starts with sys.stdout None."""
    monkeypatch.setattr(sys, "stdout", None)
    assert main(argv) == 141
    err = capsys.readouterr().err
    assert "Traceback" not in err and "error" not in err


def slow_figure(*args, path=None, **kwargs):
    """Stands in for hydroline.plotting.plot_result (module level: the figure process receives
    it by name): still drawing when the command is interrupted, then writes its file."""
    time.sleep(0.3)
    with open(path, "wb") as f:
        f.write(b"\x89PNG")


def interrupted(*args, **kwargs):
    raise KeyboardInterrupt


def test_ctrl_c_while_the_figure_is_drawn_leaves_no_temporary_file(tmp_path, monkeypatch,
                                                                    capsys):
    monkeypatch.setattr("hydroline.plotting.plot_result", slow_figure)
    monkeypatch.setattr("hydroline.scenarios.summaries.summarize", interrupted)  # after hand-over
    out = tmp_path / "out"
    assert main(["simulate", "--t-end", "0.02 s", "--out", str(out)]) == 130
    assert "interrupted" in capsys.readouterr().err
    time.sleep(0.5)                          # a figure process left running would write now
    assert os.listdir(out) == []


def test_a_killed_sweep_leaves_no_semaphore_warning():
    """The process that started the workers is killed (SIGKILL) holding a semaphore: the
    resource tracker releases it and, unless quietened, warns in two lines."""
    body = textwrap.dedent("""\
        import multiprocessing as mp, os, signal
        {quiet}
        lock = mp.get_context("forkserver").Lock()
        os.kill(os.getpid(), signal.SIGKILL)
        """)
    quiet = "from hydroline.studies.executors import quiet_resource_tracker\n" \
            "quiet_resource_tracker()"
    if "forkserver" not in __import__("multiprocessing").get_all_start_methods():
        pytest.skip("no forkserver start method")
    errs = {}
    for name, q in (("plain", ""), ("quiet", quiet)):
        done = subprocess.run([sys.executable, "-c", body.format(quiet=q)], capture_output=True,
                              text=True, timeout=60, env={**os.environ, "PYTHONWARNINGS": ""})
        errs[name] = done.stderr
    assert "leaked semaphore" in errs["plain"]        # what the check would see
    assert "leaked" not in errs["quiet"] and "Warning" not in errs["quiet"]


# ------------------------------------------------------------------ glyphs, long names

def test_glyph_warnings_of_a_non_latin_rig_name_are_one_line(tmp_path, capfd):
    """(capfd: the figure is drawn in a second process, which writes to the file descriptor)"""
    f = tmp_path / "named.toml"
    f.write_text('[rig]\nbase = "default"\nname = "試験台 Prüfstand испытание 𓀀"\n')
    assert main(["simulate", str(f), "--t-end", "0.02 s", "--out", str(tmp_path / "o")]) == 0
    err = capfd.readouterr().err
    assert "Glyph" not in err and "UserWarning" not in err and "savefig" not in err
    glyphs = [ln for ln in err.splitlines() if "cannot draw" in ln]
    assert len(glyphs) <= 1                 # (none where a font has every character)
    assert all(ln.startswith("hydroline simulate: warning: ") for ln in glyphs)


def test_a_long_name_is_cut_in_the_figure_title():
    name = "x" * 10**6
    assert figure_title(name) == "x" * (TITLE_CHARACTERS - 3) + "..."
    assert figure_title("short") == "short"
    t = np.linspace(0.0, 0.02, 21)
    traces = Traces(t, {c: np.full_like(t, 1e7) for c in ("supply_port_pressure",
                                                          "return_port_pressure")})
    fig = plot_result(traces, signals=["supply_port_pressure"], title=name)
    assert max(len(x.get_text()) for x in fig.texts) == TITLE_CHARACTERS


# ------------------------------------------------------------------ cost notes

@pytest.mark.skipif(not compiled.available(), reason="no C compiler: no compiled core to build")
def test_a_note_before_a_large_run(tmp_path, monkeypatch, capsys):
    """rig.modes_per_section = 40: 4 hose sections x (40 modes x 2 states + 4 viscous and 16
    tail states of the exact-pole line) + 10 states of the valve, actuator, accumulators and
    friction = 410 states (138 at the default 6). Its first build takes seconds, not the
    minutes it took when the compiled core's code grew with the cube of the states: no note
    on the default 0.25 s. 60 s simulated is a large run (~25 s: 60 s / 45 x (410 / 58)^1.5,
    hydroline.limits): the note comes before it (the run itself is stopped here)."""
    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path / "cache"))   # nothing built yet
    monkeypatch.setattr("hydroline.scenarios.running.simulate", interrupted)
    f = tmp_path / "modes.toml"
    f.write_text('[rig]\nbase = "default"\nmodes_per_section = 40\n')
    assert main(["simulate", str(f), "--json"]) == 130
    assert "large run" not in capsys.readouterr().err
    assert main(["simulate", str(f), "--t-end", "60 s", "--dt-out", "10 ms", "--json"]) == 130
    notes = [ln for ln in capsys.readouterr().err.splitlines() if "note: a large run" in ln]
    assert len(notes) == 1 and "410 states, 60 s simulated" in notes[0]
    assert main(["simulate", "--json"]) == 130                # the default rig: no note
    assert "large run" not in capsys.readouterr().err


def test_every_command_with_a_solver_offers_every_solver_the_engine_has():
    """``--solver``'s choices are the engine's :data:`SOLVERS` (radau included), in every
    command that takes one."""
    import argparse

    from hydroline.cli.common import add_solver_option
    from hydroline.engine.backends import SOLVERS

    parser = argparse.ArgumentParser()
    add_solver_option(parser)
    for solver in SOLVERS:
        assert parser.parse_args(["--solver", solver]).solver == solver
    for command in ("simulate", "layout", "sweep", "envelope", "optimize"):
        with pytest.raises(SystemExit) as stop:
            main([command, "--solver", "euler"])
        assert stop.value.code == 2
