"""The command line: outputs and one-line errors with exit code 2."""
import json

import pytest

from hydroline.cli import main


def test_line_response_writes_figure_and_table(tmp_path, capsys):
    rc = main(["line-response", "--length", "3.048m", "--diameter", "12.7mm", "--bulk-modulus",
               "2.07e8Pa", "--method", "yang-tobler", "--out", str(tmp_path), "--json"])
    assert rc == 0
    report = json.loads(capsys.readouterr().out)
    assert (tmp_path / "line_response.png").stat().st_size > 0
    # c = sqrt(2.07e8/870) = 487.8 m/s; first PQ resonance near c/(4L) = 40 Hz
    assert report["line"]["wave_speed_m_s"] == pytest.approx((2.07e8 / 870) ** 0.5)
    first = [r for r in report["resonances"] if r["mode"] == 1]
    assert len(first) == 4
    for r in first:
        assert r["exact_frequency_hz"] == pytest.approx(487.8 / (4 * 3.048), rel=0.05)
        assert abs(r["frequency_error_pct"]) < 1.0


@pytest.mark.parametrize("args, needle", [
    (["--length", "3.048", "--diameter", "12.7mm"], "--length: bare number"),
    (["--length", "-3 m", "--diameter", "12.7mm"], "length"),
    (["--length", "3 m", "--diameter", "12.7 kg"], "--diameter"),
    (["--length", "3 m", "--diameter", "12.7 mm", "--modes", "0"], "--modes"),
    (["--length", "3 m", "--diameter", "12.7 mm", "--modes", "100000"], "--modes"),  # issue 14
    (["--length", "9**9**9 m", "--diameter", "12.7 mm"], "--length: cannot read"),
])
def test_line_response_bad_input(tmp_path, capsys, args, needle):
    rc = main(["line-response", *args, "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and needle in err and len(err.splitlines()) == 1


def test_simulate_bad_t_end(tmp_path, capsys):
    rc = main(["simulate", "--t-end", "0.1", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 2 and "--t-end" in err


def test_simulate_bad_scenario_initial_position(tmp_path, capsys):
    f = tmp_path / "bad.toml"
    f.write_text('[rig]\nbase = "default"\n[scenario.closed-loop-sine]\ninitial_position = "60 mm"\n')
    rc = main(["simulate", str(f), "--scenario", "closed-loop-sine", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert "scenario.closed-loop-sine.initial_position" in err and "Traceback" not in err


@pytest.mark.parametrize("error", ["steady", "compiler", "integrator"])
def test_simulate_model_failures_are_one_line(tmp_path, capsys, monkeypatch, error):
    """Failures of the model itself (no steady state, no C compiler, integrator gave up)."""
    from hydroline.compiled import CompilerUnavailable
    from hydroline.engine import SteadyStateError

    exc = {"steady": SteadyStateError("steady state not found: scaled residual 0.05 1/s\nmore"),
           "compiler": CompilerUnavailable("no C compiler found (set CC, or install gcc)"),
           "integrator": RuntimeError("compiled integrator failed at t = 0.1 s: step size")}[error]

    def fail(*a, **k):
        raise exc

    monkeypatch.setattr("hydroline.scenarios.running.simulate", fail)   # what the command runs
    rc = main(["simulate", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert str(exc).splitlines()[0] in err


def test_simulate_into_closed_pipe_is_quiet(tmp_path, capsys, monkeypatch):
    """``hydroline simulate | head``: the reader has gone; no traceback, exit code 141."""
    import sys

    class ClosedPipe:
        def write(self, *_):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(sys, "stdout", ClosedPipe())
    rc = main(["simulate", "--t-end", "0.02 s", "--out", str(tmp_path)])
    assert rc == 141
    assert capsys.readouterr().err == ""


def test_simulate_json_warnings_go_to_stderr(tmp_path, capsys):
    """A 0.5 MPa back pressure lets the ~0.94 MPa return swing (docs/model.md 7) fall below zero
    absolute: the cavitation warning is a stderr line; stdout stays the bare JSON schema."""
    f = tmp_path / "low.toml"
    f.write_text('[rig]\nbase = "default"\n[return]\npressure = "0.5 MPa"\n'
                 '[return.accumulator]\nprecharge_pressure = "0.2 MPa"\n')
    rc = main(["simulate", str(f), "--json", "--t-end", "0.06 s", "--out", str(tmp_path)])
    cap = capsys.readouterr()
    assert rc == 0
    s = json.loads(cap.out)
    assert s["warnings"] and {"supply", "return", "metrics_window_s", "settling_band"} <= set(s)
    lines = cap.err.strip().splitlines()
    assert any(ln.startswith("hydroline simulate: warning: return_port_pressure falls below "
                             "0.101 MPa absolute") for ln in lines)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["warnings"]
