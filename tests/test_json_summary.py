"""``simulate --json`` and ``layout --json`` (issue 26): the whole summary, a schema_version, and
the JSON Schemas in docs/ checked against real output. The metrics are recomputed from the
written results.csv / layout.csv by their definitions (docs/metrics.md), not by the code."""
import json
from pathlib import Path

import jsonschema
import numpy as np
import pandas as pd
import pytest
from referencing import Registry, Resource

from hydroline.cli import main
from hydroline.cli.simulate import json_summary

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _schemas():
    docs = {name: json.loads((DOCS / name).read_text())
            for name in ("summary.schema.json", "layout.schema.json")}
    registry = Registry().with_resources(
        (s["$id"], Resource.from_contents(s)) for s in docs.values())
    return docs, registry


def _validate(doc, name):
    docs, registry = _schemas()
    schema = docs[name]
    jsonschema.Draft202012Validator.check_schema(schema)
    jsonschema.Draft202012Validator(schema, registry=registry).validate(doc)


def validate_summary(doc):
    """Validate a ``simulate --json`` document against docs/summary.schema.json."""
    _validate(doc, "summary.schema.json")


def _csv(path):
    """results.csv with its unit suffixes dropped from the column names."""
    tab = pd.read_csv(path)
    tab.columns = [c.split(" [")[0] for c in tab.columns]
    return tab


def test_simulate_json_is_the_summary(tmp_path, capsys):
    assert main(["simulate", "--json", "--t-end", "60 ms", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert doc.keys() >= summary.keys() and doc["schema_version"] == 1
    for side in ("supply", "return"):
        assert doc[side].keys() >= summary[side].keys()
        assert {"first_excursion_mpa", "steady_change_mpa", "peak_to_peak_mpa",
                "settling_note", "amplitude_note"} <= doc[side].keys()
    assert {"metrics_window_s", "metrics_window_note", "warnings"} <= doc.keys()
    validate_summary(doc)
    validate_summary(summary)
    # first excursion and peak-to-peak by their definitions (max |p - p0|, max p - min p over
    # the metrics window) from the written trace: same rows, so to rounding of "%.9g"
    tab = _csv(tmp_path / "results.csv")
    t0, t1 = doc["metrics_window_s"]
    t = tab["time"].to_numpy()
    w = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
    for side in ("supply", "return"):
        p = tab[f"{side}_port_pressure"].to_numpy()
        p0 = np.interp(t0, t, p)
        # a maximum read on another grid (the summary's metrics grid, the window's end between
        # two rows) differs by at most one row's change of the trace
        step = np.max(np.abs(np.diff(p[w]))) / 1e6
        assert doc[side]["first_excursion_mpa"] == pytest.approx(
            np.max(np.abs(p[w] - p0)) / 1e6, rel=1e-4, abs=step)
        assert doc[side]["peak_to_peak_mpa"] == pytest.approx(np.ptp(p[w]) / 1e6, rel=1e-4,
                                                              abs=2 * step)


def test_closed_loop_sine_json_has_tracking_error_and_ripple(tmp_path, capsys):
    assert main(["simulate", "--scenario", "closed-loop-sine", "--json", "--t-end", "0.25 s",
                 "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    validate_summary(doc)
    for side in ("supply", "return"):
        assert {"ripple_pp_mpa", "ripple_pp_mpa_per_cycle"} <= doc[side].keys()
    # the tracking error by its definition, reference - position over the window, from the CSV
    tab = _csv(tmp_path / "results.csv")
    t0, t1 = doc["metrics_window_s"]
    t = tab["time"].to_numpy()
    w = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
    err = (tab["position_reference"] - tab["piston_position"]).to_numpy()[w]
    assert doc["tracking_error_rms_mm"] == pytest.approx(np.sqrt(np.mean(err**2)) * 1e3, rel=1e-3)
    assert doc["tracking_error_max_mm"] == pytest.approx(np.max(np.abs(err)) * 1e3, rel=1e-3)


def test_json_summary_passes_every_key_through():
    """A key the summary gains (e.g. a new settling metric) reaches --json without a code change;
    the schema allows it (additionalProperties) while requiring the documented ones."""
    port = {"frequency_hz": 40.0, "amplitude_mpa": 1.0, "settling_time_s": None,
            "settling_band_mpa": 0.3}
    summary = {"supply": port, "return": port, "actuator_natural_frequency_hz": 172.0,
               "wall_time_s": 1.0, "metrics_window_s": [0.01, 0.1], "metrics_window_note": "",
               "warnings": [], "some_new_metric_s": 0.5}
    doc = json_summary(summary)
    assert doc == {"schema_version": 1, **summary}
    validate_summary(doc)
    with pytest.raises(jsonschema.ValidationError):
        validate_summary({k: v for k, v in doc.items() if k != "metrics_window_s"})
    with pytest.raises(jsonschema.ValidationError):
        validate_summary({**doc, "supply": {"frequency_hz": 40.0}})


def test_layout_json_rows_carry_every_table_column(tmp_path, capsys):
    assert main(["layout", "--lengths", "3.048,0", "--t-end", "60 ms", "--json",
                 "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    _validate(doc, "layout.schema.json")
    assert doc["schema_version"] == 1 and doc["sections"] == ["supply.section2", "return.section2"]
    rows = doc["rows"]
    tab = pd.read_csv(tmp_path / "layout.csv", keep_default_na=False)
    assert [r["section2_length_m"] for r in rows] == list(tab["section2_length_m"])
    for row, (_, line) in zip(rows, tab.iterrows()):
        assert {"first_excursion_mpa", "steady_change_mpa"} <= row["supply"].keys()
        for col in tab.columns:     # supply_x -> row["supply"]["x"]; flow columns under "flow"
            side, _, key = col.partition("_")
            if col in row:
                value = row[col]
            elif side in ("supply", "return") and key in row[side]:
                value = row[side][key]
            else:
                assert col in row["flow"], col
                value = row["flow"][col]
            if col == "warnings":
                assert "; ".join(value) == line[col]
            elif isinstance(value, str) or value is None and line[col] == "":
                assert (value or "") == line[col], col
            elif col != "wall_time_s":
                assert value == pytest.approx(float(line[col]), rel=1e-9), col


def test_two_axis_closed_loop_sine_json_per_axis(tmp_path, capsys):
    """A multi-axis closed-loop sine: ripple and tracking error per axis, by their definition
    from the CSV (``<axis>.position_reference - <axis>.piston_position`` over the window)."""
    assert main(["simulate", "two_axis", "--scenario", "closed-loop-sine", "--json",
                 "--t-end", "0.15 s", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    validate_summary(doc)
    tab = _csv(tmp_path / "results.csv")
    t0, t1 = doc["metrics_window_s"]
    t = tab["time"].to_numpy()
    w = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
    for name, a in doc["axes"].items():
        assert "ripple_pp_mpa_per_cycle" in a["supply"]
        err = (tab[f"{name}.position_reference"] - tab[f"{name}.piston_position"]).to_numpy()[w]
        assert a["tracking_error_rms_mm"] == pytest.approx(np.sqrt(np.mean(err**2)) * 1e3,
                                                           rel=1e-3, abs=1e-6)
        assert a["tracking_error_max_mm"] == pytest.approx(np.max(np.abs(err)) * 1e3,
                                                           rel=1e-3, abs=1e-6)
