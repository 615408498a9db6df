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
    (["--length", "3 m", "--diameter", "12.7 mm", "--modes", "0"], "n_modes"),
])
def test_line_response_bad_input(tmp_path, capsys, args, needle):
    rc = main(["line-response", *args, "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and needle in err and len(err.splitlines()) == 1


def test_simulate_bad_t_end(tmp_path, capsys):
    rc = main(["simulate", "--t-end", "0.1", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 2 and "--t-end" in err
