"""Design studies (issue 4): the section II layout study and parameter sweeps.

Physics: a section II alone between an ideal pressure source and a blocked end is a
quarter-wave resonator; its step response rings at the first root of cosh Gamma(s) = 0 of
the dissipative line (M5-M6), which the test finds independently of hydroline's root finder.
Bookkeeping: a sweep interrupted (in-process, and a real SIGTERM to the CLI) and resumed gives
the table of an uninterrupted one; a bad variant is reported and sinks nothing; a Dask cluster
on loopback gives the local-process table.
"""
from __future__ import annotations

import io
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import jsonschema
import numpy as np
import pandas as pd
import pytest
from scipy import optimize, special

from hydroline import components as comp
from hydroline.analysis import oscillation_frequency
from hydroline.cli import main
from hydroline.lines import ModalLine
from hydroline.engine import Network
from hydroline.rigs import RigError, load_rig
from hydroline.engine import integrate, solve_steady_state
from hydroline.studies import (DEFAULT_LENGTHS, Design, LayoutStudy, SweepFileError, layout,
                               parse_lengths, parse_parameter, parse_parameters, read_journal,
                               sweep)
from hydroline.studies.design import parameter_unit
from hydroline.studies.sweep import METRIC_COLUMNS
from hydroline.system import make_fluid, make_line

T_END = 0.12      # [s]: the metrics window of the open-loop step ends at the piston stop, ~0.11 s
SWEEP_SETS = ["supply.section2.bulk_modulus=150 MPa,178 MPa,200 MPa",
              "supply.accumulator.precharge_pressure=10 MPa,14 MPa"]
#: 12 variants (~50 ms each): long enough for a signal to land midway through the CLI's run.
KILL_SETS = ["supply.section2.bulk_modulus=linspace(150 MPa, 200 MPa, 4)",
             "supply.accumulator.precharge_pressure=10 MPa,12 MPa,14 MPa"]


# --------------------------------------------------------------------------- physics

def _first_dissipative_pole(line):
    """First root of cosh Gamma(s) = 0, i.e. Gamma(s) = j pi/2 (M6), by Newton from the
    lossless quarter-wave value; Gamma written here from scratch with scipy's I0, I2:
    Gamma = (s L/c) sqrt(I0(kappa)/I2(kappa)), kappa = r sqrt(s/nu)  [1/s]."""
    L, c, r, nu = line.length, line.wave_speed, line.radius, line.fluid.kinematic_viscosity

    def residual(z):
        s = complex(z[0], z[1])
        k = r * np.sqrt(s / nu)
        g = s * L / c * np.sqrt(special.iv(0, k) / special.iv(2, k)) - 0.5j * np.pi
        return [g.real, g.imag]

    sol = optimize.fsolve(residual, [0.0, 2 * np.pi * c / (4 * L)], xtol=1e-13)
    return complex(*sol)


@pytest.mark.parametrize("length", [3.048, 0.7512])
def test_section2_alone_rings_at_quarter_wave(length):
    """PressureSource -> section II (modal PQ, 6 modes) -> blocked end (zero flow): the blocked
    end's pressure after a 1 MPa step oscillates at the quarter-wave frequency of the line:
    c/(4L) lossless, lowered by friction to the first dissipative pole (M6)."""
    rig = load_rig()
    rig.set("supply.section2.length", f"{length} m")
    line = make_line(rig, "supply.section2", make_fluid(rig))
    p0, t_step = 20.7e6, 0.005
    net = Network([
        comp.PressureSource(name="source", pressure=p0, step_time=t_step, step_to=p0 - 1e6,
                            connections={"pressure": "inlet_pressure"}),
        comp.HoseSection(name="hose", model=ModalLine(line, 6, "PQ"), nominal_pressure=p0,
                         connections={"upstream_pressure": "inlet_pressure",
                                      "downstream_flow": "end_flow",
                                      "downstream_pressure": "end_pressure",
                                      "upstream_flow": "inlet_flow"}),
        comp.StepCommand(name="blocked_end", quantity="flow", initial=0.0, final=0.0, time=1.0,
                         connections={"command": "end_flow"}),
    ])
    ss = solve_steady_state(net)
    quarter_wave = line.wave_speed / (4 * length)                          # [Hz]
    res = integrate(net, ss.x, t_step + 8 / quarter_wave, dt_out=2e-5, p=ss.p)
    f = oscillation_frequency(res.t, res["end_pressure"], t_step)
    exact = _first_dissipative_pole(line).imag / (2 * np.pi)
    assert f == pytest.approx(exact, rel=5e-3)          # modal accuracy (M15 corrections)
    # friction lowers the lossless quarter-wave value a little (Dn ~ 0.003-0.0007 here)
    assert exact < quarter_wave
    assert f == pytest.approx(quarter_wave, rel=0.05)


# --------------------------------------------------------------------------- layout

#: The issue's ``--json`` schema.
#: What every row of ``layout --json`` holds at least (docs/layout.schema.json has the whole
#: document; tests/test_json_summary.py checks real output against it).
LAYOUT_SCHEMA = {
    "type": "array",
    "items": {
        "type": "object",
        "required": ["section2_length_m", "supply", "return", "settling_band"],
        "properties": {"section2_length_m": {"type": "number"},
                       "supply": {"$ref": "#/$defs/port"},
                       "return": {"$ref": "#/$defs/port"},
                       "settling_band": {"type": ["string", "null"]}},
    },
    "$defs": {"port": {
        "type": "object",
        "required": ["frequency_hz", "amplitude_mpa", "settling_time_s", "settling_band_mpa"],
        "properties": {"frequency_hz": {"type": ["number", "null"]},
                       "amplitude_mpa": {"type": ["number", "null"]},
                       "settling_time_s": {"type": ["number", "null"]},
                       "settling_band_mpa": {"type": ["number", "null"]}}}},
}


@pytest.fixture(scope="module")
def default_layout():
    return layout()


def test_layout_runs_a_0_m_length_second_and_hands_runs_on_in_order():
    """The 0 m lengths (another network, on CVODES while the first one's library builds) run
    right after the first length; ``on_run`` still sees the lengths in their order, and a
    length's metrics do not depend on the order (those of a study of that length alone)."""
    from hydroline.studies.layout import run_order

    assert run_order([3.048, 2.286, 1.524, 0.7512, 0.0]) == [0, 4, 1, 2, 3]
    assert run_order([2.0, 0.0, 1.0, 0.0, 3.0]) == [0, 1, 3, 2, 4]
    assert run_order([0.0, 1.2, 2.0]) == [0, 1, 2]
    assert run_order([1.0, 0.5]) == [0, 1]
    assert run_order([]) == []
    handed = []
    # (on CVODES: the same numbers whichever library a cold cache would have when)
    study = layout(None, [0.5, 0.25, 0.0], t_end=0.06, solver="cvodes",
                   on_run=lambda k, length, res, summary, axis: handed.append((k, length, res)))
    assert [(k, length) for k, length, _ in handed] == [(0, 0.5), (1, 0.25), (2, 0.0)]
    assert all(res is study.results[k] for k, _, res in handed)
    alone = layout(None, [0.25], t_end=0.06, solver="cvodes")
    for side in ("supply", "return"):
        assert study.records()[1][side] == alone.records()[0][side]


def test_layout_default_lengths_give_finite_metrics(default_layout):
    recs = default_layout.records()
    assert [r["section2_length_m"] for r in recs] == pytest.approx(list(DEFAULT_LENGTHS))
    for r in recs:
        for side in ("supply", "return"):
            m = r[side]
            for k in ("frequency_hz", "settling_time_s"):
                assert m[k] is None or (math.isfinite(m[k]) and m[k] >= 0)
            if r["section2_length_m"] > 0:       # a hose section II rings
                assert math.isfinite(m["frequency_hz"])
                assert math.isfinite(m["amplitude_mpa"]) and m["amplitude_mpa"] > 0
                # and its settling time is reported (issue 23: in the band of +-2 % of the
                # final absolute pressure, measured or estimated from the ringing's decay)
                assert math.isfinite(m["settling_time_s"]) and m["settling_time_s"] > 0
            else:   # close-coupled: no ringing, or a ripple of the manifold's own passages
                # (under 5 % of the longest hose's: the modal line's higher modes)
                assert m["amplitude_mpa"] < 0.05 * recs[0][side]["amplitude_mpa"]
        # the close-coupled supply port settles within the window (checked in the next test)
        if r["section2_length_m"] == 0.0:
            assert math.isfinite(r["supply"]["settling_time_s"])
    for side in ("supply", "return"):
        # a shorter section II rings faster (quarter-wave frequency ~ 1/L, docs/model.md 2)
        f = [r[side]["frequency_hz"] for r in recs if r["section2_length_m"] > 0]
        assert all(b > a for a, b in zip(f, f[1:]))
        # and the longest one near its quarter-wave value c/(4L): the accumulator holds the
        # manifold end near constant pressure, the valve nearly blocks the other end
        c = default_layout.wave_speeds[side]
        assert f[0] == pytest.approx(c / (4 * DEFAULT_LENGTHS[0]), rel=0.15)


def _piston_stop(res):
    """The first instant after the step at which the piston is within 1 mm of its far stop."""
    t, x = res.t, res["piston_position"]
    t0, half = res.metadata["t_disturbance"], res.metadata["stroke"] / 2
    return t0, float(t[np.flatnonzero((t > t0 + 5e-3) & (x > half - 1e-3))[0]])


def test_layout_settling_times_against_independent_estimates(default_layout):
    """The close-coupled supply port settles within the window: a plain scan of the trace
    against +-2 % of its final absolute pressure (to within a period of a ripple, whose
    one-period mean the band then follows). (Estimates past the stop are checked on
    synthetic decays in test_settling_verdicts.)"""
    by_length = dict(zip(default_layout.lengths, zip(default_layout.results,
                                                     default_layout.summaries)))
    # close-coupled: settled before the stop, measured
    res, summ = by_length[0.0]
    t0, t1 = _piston_stop(res)
    t, p = res.t, res["supply_port_pressure"]
    w = (t >= t0) & (t <= t1)
    tw, pw = t[w], p[w]
    p_final = pw[tw >= t1 - 0.2 * (t1 - t0)].mean()
    band = 0.02 * abs(p_final)
    last_outside = tw[np.flatnonzero(np.abs(pw - p_final) > band)[-1]]
    ripple = summ["supply"]["frequency_hz"]
    assert summ["supply"]["settling_method"] == "measured"
    assert summ["supply"]["settling_time_s"] == pytest.approx(
        last_outside - t0, abs=2e-4 + (1 / ripple if ripple else 0.0))
    assert summ["supply"]["settling_time_s"] < t1 - t0
    assert summ["supply"]["settling_band_mpa"] == pytest.approx(band / 1e6, rel=0.01)

    # every ringing length has one; where it is estimated, the note says how
    tab = default_layout.table().set_index("section2_length_m")
    for L in DEFAULT_LENGTHS[:-1]:
        for side in ("supply", "return"):
            assert np.isfinite(tab.loc[L, f"{side}_settling_time_s"])
            if tab.loc[L, f"{side}_settling_method"] == "estimated":
                assert "decays as exp(-" in tab.loc[L, f"{side}_settling_note"]
        assert tab.loc[L, "settling_band"] == "+-2 % of the final absolute pressure"


def test_layout_json_validates_against_schema(default_layout):
    recs = json.loads(json.dumps(default_layout.records(), allow_nan=False))   # strict JSON
    jsonschema.validate(recs, LAYOUT_SCHEMA)
    assert len(recs) == len(DEFAULT_LENGTHS)
    # a metric that came out NaN is written as null, never as the non-JSON NaN
    port = {"frequency_hz": float("nan"), "amplitude_mpa": 0.1, "settling_time_s": float("nan"),
            "settling_band_mpa": 0.4}
    study = LayoutStudy([1.0], [{"supply": port, "return": port}], [])
    rec = json.loads(json.dumps(study.records(), allow_nan=False))[0]
    assert rec["supply"] == {"frequency_hz": None, "amplitude_mpa": 0.1, "settling_time_s": None,
                             "settling_band_mpa": 0.4}


def test_layout_cli_json_and_files(tmp_path, capsys):
    assert main(["layout", "--lengths", "3.048,0", "--json"]) == 0
    recs = json.loads(capsys.readouterr().out)["rows"]
    jsonschema.validate(recs, LAYOUT_SCHEMA)
    assert [r["section2_length_m"] for r in recs] == [3.048, 0.0]
    assert main(["layout", "--lengths", "10 ft,0 m", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "3.048" in out                                   # 10 ft = 3.048 m exactly
    tab = pd.read_csv(tmp_path / "layout.csv")
    assert list(tab["section2_length_m"]) == pytest.approx([3.048, 0.0])
    assert (tmp_path / "layout.png").stat().st_size > 10_000
    assert "time_s" in pd.read_csv(tmp_path / "layout_traces.csv", nrows=2)


def test_parse_lengths_bare_metres_and_units():
    assert parse_lengths("3.048,2.286,1.524,0.7512,0") == [3.048, 2.286, 1.524, 0.7512, 0.0]
    assert parse_lengths("10 ft, 30 in,0 m") == pytest.approx([3.048, 0.762, 0.0])  # by definition of ft, in
    assert parse_lengths([1, "2 m"]) == [1.0, 2.0]
    for bad in ("-1", "1,,2", "3 psi", "abc"):
        with pytest.raises(ValueError, match="--lengths"):
            parse_lengths(bad)


def test_layout_cli_bad_length_is_one_line(capsys):
    assert main(["layout", "--lengths", "1 m,-2 m"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--lengths[1]" in err and ">= 0 m" in err


# --------------------------------------------------------------------------- design

def test_full_factorial_order_and_units():
    d = Design(parse_parameters(SWEEP_SETS + ["rig.modes_per_section=4"]))
    assert len(d) == 3 * 2 * 1
    assert d.variant(0) == {"supply.section2.bulk_modulus": 150e6,
                            "supply.accumulator.precharge_pressure": 10e6,
                            "rig.modes_per_section": 4.0}
    # first parameter slowest: variant 1 changes the second, variant 2 the first
    assert d.variant(1)["supply.accumulator.precharge_pressure"] == 14e6
    assert d.variant(2)["supply.section2.bulk_modulus"] == 178e6
    assert len({tuple(v.values()) for v in d}) == 6
    lin = parse_parameters(["supply.section2.length+return.section2.length=linspace(0 m, 3 m, 4)"])[0]
    assert lin.levels == pytest.approx((0.0, 1.0, 2.0, 3.0))
    assert Design([lin]).variant(3) == {"supply.section2.length": 3.0, "return.section2.length": 3.0}
    assert parse_parameters(["supply.section2.diameter=0.5 in"])[0].levels == (0.0127,)


def test_random_design_reproducible_and_distributions():
    params = parse_parameters(["supply.section2.bulk_modulus=uniform(150 MPa, 220 MPa)",
                               "return.section2.bulk_modulus=normal(178 MPa, 10 MPa)",
                               "supply.accumulator.capacity=lognormal(1 L, 0.2)",
                               "rig.line_method=choice(yang-tobler, residue)"])
    d = Design(params, samples=4000, seed=3)
    # variant i does not depend on N: a longer sample extends a shorter one
    assert Design(params, samples=10, seed=3).variant(7) == d.variant(7)
    assert Design(params, samples=10, seed=4).variant(7) != d.variant(7)
    v = pd.DataFrame(list(d))
    u = v["supply.section2.bulk_modulus"]
    assert u.min() >= 150e6 and u.max() <= 220e6
    n = len(v)
    # sample mean within 4 standard errors of the distribution's mean
    assert abs(u.mean() - 185e6) < 4 * (70e6 / math.sqrt(12)) / math.sqrt(n)
    g = v["return.section2.bulk_modulus"]
    assert abs(g.mean() - 178e6) < 4 * 10e6 / math.sqrt(n)
    assert g.std() == pytest.approx(10e6, rel=0.05)
    ln = np.log(v["supply.accumulator.capacity"])
    assert abs(np.median(v["supply.accumulator.capacity"]) - 1e-3) < 2e-5  # median 1 L = 1e-3 m^3
    assert ln.std() == pytest.approx(0.2, rel=0.05)
    assert set(v["rig.line_method"]) == {"yang-tobler", "residue"}


@pytest.mark.parametrize("spec, match", [
    ("supply.section2.bulk_modulus=150,178", "bare number"),
    ("supply.section2.bulk_modulus=150 m", "dimension"),
    ("supply.section2.bulk_modulus=gauss(1 MPa, 2 MPa)", "unknown distribution"),
    ("supply.section2.bulk_modulus=uniform(2 MPa, 1 MPa)", "LOW < HIGH"),
    ("supply.nozzle=1 m", "unknown parameter"),
    ("supply.section2.length+supply.pressure=1 m", "one unit"),
    ("supply.section2.length", "PATH=VALUES"),
])
def test_bad_parameter_specs_are_one_line(spec, match):
    with pytest.raises(ValueError, match=match) as e:
        parse_parameters([spec])
    assert "\n" not in str(e.value)


def test_distribution_needs_samples():
    with pytest.raises(RigError, match="--samples"):
        Design(parse_parameters(["supply.section2.bulk_modulus=normal(178 MPa, 10 MPa)"]))


# --------------------------------------------------------------------------- sweep

def _without_timing(df):
    return df.drop(columns=["wall_time_s"]).reset_index(drop=True)


def _same_rows(a, b):
    """Two sweeps' rows, equal to the solver's tolerance: a variant's rest state starts from
    the previous variant's on its worker (another one after a resume or on another worker),
    and the rest state is found to its tolerance (the exact-pole line's Jacobian has a
    condition number ~1e8), so a row's traces may differ by the integrator's rtol 1e-6 of
    ~20 MPa (~20 Pa) and its metrics by a few times that in relative terms (a settling time
    extrapolated from crests); 1e-4 relative bounds them, except the settling times estimated
    by extrapolating a decay up to ~250 ms past the window (a 1e-5 change of the fitted
    decay rate moves them by ~1e-4 of their span per crest): 2e-3."""
    a, b = _without_timing(a), _without_timing(b)
    settling = [c for c in a.columns if c.endswith("settling_time_s")]
    pd.testing.assert_frame_equal(a.drop(columns=settling), b.drop(columns=settling),
                                  check_exact=False, rtol=1e-4)
    pd.testing.assert_frame_equal(a[settling], b[settling], check_exact=False, rtol=2e-3)


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """The reference: the whole sweep in one go on 2 worker processes."""
    out = tmp_path_factory.mktemp("sweep_full")
    return sweep(SWEEP_SETS, t_end=T_END, workers=2, out=out)


class _Stop(Exception):
    pass


def _stop_after(n, seen):
    """A sweep callback that records each finished variant and interrupts at the n-th."""
    def callback(row):
        seen.append(row["variant"])
        if len(seen) == n:
            raise _Stop
    return callback


def test_sweep_interrupted_and_resumed_equals_uninterrupted(uninterrupted, tmp_path):
    ref = uninterrupted.table
    assert len(ref) == 6 and ref["error"].isna().all()
    assert ref["supply_frequency_hz"].notna().all()
    with pytest.raises(_Stop):
        sweep(SWEEP_SETS, t_end=T_END, workers=1, out=tmp_path, callback=_stop_after(2, []))
    header, rows = read_journal(tmp_path / "sweep.jsonl")
    assert sorted(rows) == [0, 1]
    # a kill in the middle of writing a row leaves half a line: it is dropped and rerun
    with open(tmp_path / "sweep.jsonl", "a") as f:
        f.write('{"variant": 2, "supply.section2.bulk_mod')
    with pytest.raises(SweepFileError, match="--resume"):
        sweep(SWEEP_SETS, t_end=T_END, workers=2, out=tmp_path)
    with pytest.raises(SweepFileError, match="parameters"):
        sweep(SWEEP_SETS[:1], t_end=T_END, workers=2, out=tmp_path, resume=True)
    with pytest.raises(SweepFileError, match="--t-end"):
        sweep(SWEEP_SETS, t_end=0.2, workers=2, out=tmp_path, resume=True)
    res = sweep(SWEEP_SETS, t_end=T_END, workers=2, out=tmp_path, resume=True)
    assert res.n_computed == 4 and res.complete
    _same_rows(res.table, ref)
    csv = pd.read_csv(tmp_path / "sweep.csv")
    _same_rows(csv, pd.read_csv(uninterrupted.files["csv"]))
    # resuming a finished sweep runs nothing
    assert sweep(SWEEP_SETS, t_end=T_END, workers=2, out=tmp_path, resume=True).n_computed == 0


def test_sweep_interrupted_on_worker_processes_keeps_the_running_variants(uninterrupted,
                                                                          tmp_path):
    """Stopped at its first row on 2 worker processes, the sweep waits for the variant the
    other worker is running and records it too: nothing already computed is lost."""
    seen = []
    with pytest.raises(_Stop):
        sweep(SWEEP_SETS, t_end=T_END, workers=2, out=tmp_path, callback=_stop_after(1, seen))
    rows = read_journal(tmp_path / "sweep.jsonl")[1]
    # the first, the other worker's, and any already handed to a worker (not cancellable)
    assert len(rows) >= 2
    assert sorted(rows) == sorted(seen)             # every recorded row was reported
    res = sweep(SWEEP_SETS, t_end=T_END, workers=2, out=tmp_path, resume=True)
    assert res.n_computed == 6 - len(rows)
    _same_rows(res.table, uninterrupted.table)


def test_sweep_parquet_matches_csv(uninterrupted):
    pytest.importorskip("pyarrow")
    pq = pd.read_parquet(uninterrupted.files["parquet"])
    csv = pd.read_csv(uninterrupted.files["csv"])
    assert list(pq.columns) == list(csv.columns) and len(pq) == 6
    # CSV has no empty text or None: both read back as NaN
    pd.testing.assert_frame_equal(pq.replace("", np.nan).fillna(np.nan), csv, check_dtype=False)
    pd.testing.assert_frame_equal(pq, uninterrupted.table)


def test_sweep_without_pyarrow_says_so(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)          # import pyarrow -> ImportError
    assert main(["sweep", "--set", "supply.section2.bulk_modulus=178 MPa", "--t-end", "0.12 s",
                 "--workers", "1", "--out", str(tmp_path)]) == 0
    assert "sweep.parquet not written: pip install pyarrow" in capsys.readouterr().out
    assert (tmp_path / "sweep.csv").exists() and not (tmp_path / "sweep.parquet").exists()


def test_sweep_resumed_with_fewer_samples_keeps_the_extra_rows(tmp_path):
    spec = ["supply.section2.bulk_modulus=uniform(150 MPa, 200 MPa)"]
    first = sweep(spec, samples=3, seed=5, t_end=T_END, workers=1, out=tmp_path)
    assert len(first.table) == 3 and not first.notes
    fewer = sweep(spec, samples=2, seed=5, t_end=T_END, workers=1, out=tmp_path, resume=True)
    assert fewer.n_computed == 0 and len(fewer.table) == 2
    assert len(read_journal(tmp_path / "sweep.jsonl")[1]) == 3      # nothing dropped
    assert any("--samples 3" in n for n in fewer.notes)
    pd.testing.assert_frame_equal(fewer.table, first.table.iloc[:2])


@pytest.fixture(scope="module")
def kill_reference():
    """The 12-variant sweep of the kill tests, uninterrupted, in memory (as its CSV reads)."""
    table = sweep(KILL_SETS, t_end=T_END, workers=2).table
    return pd.read_csv(io.StringIO(table.to_csv(index=False)))


def _kill_args(out, workers):
    return ["sweep", *sum((["--set", s] for s in KILL_SETS), []), "--t-end", f"{T_END} s",
            "--workers", str(workers), "--out", str(out)]


def _proc_stat(pid):
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None


def _descendants(root):
    children = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit() and (st := _proc_stat(d.name)) is not None:
            children.setdefault(int(st[1]), []).append(int(d.name))
    found, todo = [], [root]
    while todo:
        for c in children.get(todo.pop(), []):
            found.append(c)
            todo.append(c)
    return found


def _running(pid):
    st = _proc_stat(pid)
    return st is not None and st[0] not in ("Z", "X")       # zombies have ended


def _start_and_signal(tmp_path, workers, sig):
    """Run the CLI sweep and send it ``sig`` once its first row is in the results file;
    (out, returncode, stderr, descendant pids at the signal). Tried again in a fresh folder
    if the sweep had already finished (a heavily loaded machine)."""
    for attempt in range(3):
        out = tmp_path / f"run{attempt}"
        proc = subprocess.Popen([sys.executable, "-m", "hydroline", *_kill_args(out, workers)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        journal = out / "sweep.jsonl"
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            if journal.exists() and journal.read_text().count("\n") >= 2:     # header + 1 row
                break
            time.sleep(0.005)
        pids = _descendants(proc.pid) if Path("/proc/self/stat").exists() else []
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
        if proc.returncode != 0:
            return out, proc.returncode, err, pids
    pytest.fail("the sweep finished three times before the signal reached it")


@pytest.mark.parametrize("workers", [1, 2])
def test_sweep_cli_killed_with_sigterm_resumes(kill_reference, tmp_path, workers):
    """A real kill: SIGTERM to ``hydroline sweep`` midway, then ``--resume``. On worker
    processes the variants running at the signal are finished and recorded as well."""
    out, code, err, _ = _start_and_signal(tmp_path, workers, signal.SIGTERM)
    assert code == 143, err                       # stopped midway, cleanly; 128 + SIGTERM
    assert "--resume" in err
    rows = read_journal(out / "sweep.jsonl")[1]
    assert 1 <= len(rows) < 12
    if workers == 2:      # the first row, and at least the variant the other worker ran
        assert len(rows) >= 2
    # the message counts what this run recorded, the in-flight variants included
    assert f"terminated (SIGTERM) after {len(rows)} variants" in err
    assert main([*_kill_args(out, 2), "--resume"]) == 0     # resumed on 2 workers: faster
    _same_rows(pd.read_csv(out / "sweep.csv"), kill_reference)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_sweep_cli_killed_with_sigkill_leaves_no_workers(tmp_path):
    """SIGKILL gives the CLI no chance to stop its pool: the worker processes notice that
    it is gone and end (and with them the forkserver). (Resuming after a kill that cuts a
    line short: test_sweep_interrupted_and_resumed_equals_uninterrupted.)"""
    out, code, err, pids = _start_and_signal(tmp_path, 2, signal.SIGKILL)
    assert code == -signal.SIGKILL
    assert len(pids) >= 3          # forkserver, 2 workers (and the resource tracker)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and any(_running(p) for p in pids):
        time.sleep(0.05)
    left = [p for p in pids if _running(p)]
    for p in left:                 # clean up before failing
        os.kill(p, signal.SIGKILL)
    assert not left, "worker processes outlived the killed sweep"


def test_sweep_with_invalid_variant_finishes_the_others(tmp_path, capsys):
    # each level is within its range (a level outside it refuses the whole sweep,
    # test_cli_edges.py); 25 MPa is above the rig's 20.7 MPa supply: no oil in the
    # accumulator, a variant that fails with its reason
    res = sweep(["supply.accumulator.precharge_pressure=6.9 MPa,25 MPa,10 MPa"], t_end=T_END,
                workers=2, out=tmp_path)
    tab = res.table
    assert len(tab) == 3 and res.n_failed == 1
    bad = tab.iloc[1]
    assert bad["supply.accumulator.precharge_pressure"] == 25e6
    assert "supply.accumulator.precharge_pressure" in bad["error"] and "below" in bad["error"]
    assert np.isnan(bad["supply_frequency_hz"])
    good = tab.iloc[[0, 2]]
    assert good["error"].isna().all()
    assert np.isfinite(good[["supply_frequency_hz", "supply_amplitude_mpa",
                             "return_frequency_hz", "return_amplitude_mpa"]].to_numpy()).all()
    csv = pd.read_csv(tmp_path / "sweep.csv")
    assert csv["error"].notna().tolist() == [False, True, False]
    # the results file is strict JSON: the failed row's missing metrics are null, not NaN
    lines = (tmp_path / "sweep.jsonl").read_text().splitlines()
    rows = {r["variant"]: r for r in (json.loads(line, parse_constant=_no_constant)
                                      for line in lines[1:])}
    assert rows[1]["supply_frequency_hz"] is None and rows[1]["error"]
    # the CLI reports it, writes the table and exits 1 with the count on stderr
    assert main(["sweep", "--set", "return.accumulator.precharge_pressure=2 MPa", "--t-end",
                 "0.12 s", "--workers", "1", "--out", str(tmp_path / "cli")]) == 1
    cap = capsys.readouterr()
    assert "1 failed" in cap.out and "return.accumulator.precharge_pressure" in cap.out
    failed = [ln for ln in cap.err.splitlines() if ln.startswith("hydroline sweep: ")]
    assert len(failed) == 1 and failed[0].startswith("hydroline sweep: 1 of 1 variants failed")
    # and --json is strict JSON too (null for the metrics of the failed variant)
    assert main(["sweep", "--set", "return.accumulator.precharge_pressure=2 MPa,0.35 MPa",
                 "--t-end", "0.12 s", "--workers", "1", "--out", str(tmp_path / "cli_json"),
                 "--json"]) == 1
    rows = json.loads(capsys.readouterr().out, parse_constant=_no_constant)
    assert rows[0]["supply_amplitude_mpa"] is None and rows[0]["error"]
    assert rows[1]["supply_amplitude_mpa"] > 0 and rows[1]["error"] is None
    json.dumps(rows, allow_nan=False)


def _no_constant(name):
    raise ValueError(f"{name} is not JSON")


def test_sweep_on_dask_cluster_matches_local_processes(tmp_path):
    distributed = pytest.importorskip("distributed")
    sets = SWEEP_SETS[:1] + ["supply.accumulator.precharge_pressure=10 MPa,14 MPa",
                             "return.section2.length=1 m,2 m"]
    sets[0] = "supply.section2.bulk_modulus=150 MPa,178 MPa"
    local = sweep(sets, t_end=T_END, workers=2)
    assert len(local.table) == 8
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        assert address.startswith("tcp://127.0.0.1:")
        remote = sweep(sets, t_end=T_END, scheduler=address, out=tmp_path)
    assert remote.n_failed == 0
    _same_rows(remote.table, local.table)


def test_sweep_cli_on_local_dask_cluster(uninterrupted, tmp_path, capsys):
    """``--scheduler local``: a dask.distributed cluster on loopback, started and closed by
    the CLI; its rows equal those of the same variants on local processes."""
    pytest.importorskip("distributed")
    assert main(["sweep", "--set", "supply.section2.bulk_modulus=150 MPa,178 MPa",
                 "--set", "supply.accumulator.precharge_pressure=14 MPa", "--t-end", "0.12 s",
                 "--scheduler", "local", "--workers", "1", "--out", str(tmp_path), "--json"]) == 0
    got = pd.DataFrame(json.loads(capsys.readouterr().out))
    ref = uninterrupted.table.iloc[[1, 3]]          # 150/14 MPa and 178/14 MPa
    for col in ("supply.section2.bulk_modulus", "supply_frequency_hz", "supply_amplitude_mpa",
                "return_frequency_hz", "return_amplitude_mpa"):
        # to the solver's tolerance: each started from another neighbour's rest (_same_rows)
        assert got[col].tolist() == pytest.approx(ref[col].tolist(), rel=1e-4)


def test_studies_reachable_from_import_hydroline():
    """``import hydroline`` alone (a fresh interpreter) gives hydroline.studies.layout/sweep."""
    code = ("import hydroline; assert callable(hydroline.studies.layout) and "
            "callable(hydroline.studies.sweep); print('ok')")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr


# --------------------------------------------------------------------------- circuit rigs

CIRCUIT_RIG = Path(__file__).parent / "data" / "ayalew2005_circuit.toml"


def _quarter_wave_hz(rig, hose, length):
    """c / (4 L) of a circuit hose, c = sqrt(K / rho) from its effective bulk modulus (M2),
    by hand: the lossless quarter-wave resonance of a section between a stiff manifold and a
    nearly blocked valve port."""
    c = math.sqrt(rig[f"circuit.{hose}.bulk_modulus"] / rig["fluid.density"])
    return c / (4 * length)


def test_circuit_parameter_unit_from_the_component_declaration():
    rig = load_rig("two_axis")
    assert parameter_unit("circuit.axis2.supply_hose.length", rig) == "m"
    assert parameter_unit("circuit.supply.accumulator.precharge_pressure", rig) == "Pa"
    p = parse_parameter("circuit.axis2.supply_hose.length", "10 ft, 5 ft", rig)
    assert p.levels == pytest.approx((3.048, 1.524))          # ft = 0.3048 m by definition
    for path, match in (("circuit.axis2.supply_hose.ports.upstream_pressure", "structure"),
                        ("circuit.axis9.hose.length", "no component"),
                        ("circuit.axis2.supply_hose.colour", "no parameter 'colour'")):
        with pytest.raises(ValueError, match=match) as e:
            parameter_unit(path, rig)
        assert len(str(e.value).splitlines()) == 1
    with pytest.raises(ValueError, match="10 psi"):            # the declared unit is a length
        parse_parameter("circuit.axis2.supply_hose.length", "10 psi", rig)


def test_sweep_on_two_axis_rig_has_per_axis_columns_and_quarter_wave():
    rig = load_rig("two_axis")
    res = sweep({"circuit.axis1.supply_hose.length": "10 ft"}, rig, workers=1)
    row = res.table.iloc[0]
    assert row["error"] is None
    assert res.axes == ["axis1", "axis2"] and res.scenario == "position-step"
    for col in ("axis1.supply.amplitude_mpa", "axis2.return.frequency_hz",
                "axis2.position_disturbance_mm", "axis1.position_change_mm",
                "axis1.supply.settling_method"):
        assert col in res.table.columns
    assert "supply_amplitude_mpa" not in res.table.columns
    f = _quarter_wave_hz(rig, "axis1.supply_hose", 3.048)
    assert row["axis1.supply.frequency_hz"] == pytest.approx(f, rel=0.05)
    assert np.isnan(row["axis1.position_disturbance_mm"])     # the stepped axis moves on purpose
    assert row["axis1.position_change_mm"] == pytest.approx(40, rel=0.05)   # the 40 mm step
    assert 0 < row["axis2.position_disturbance_mm"] < 1


def test_circuit_written_out_by_hand_gives_the_template_sweep_row():
    """The paper's rig as a circuit file and as the template: one sweep row each, the same
    numbers within the solver tolerance."""
    template = sweep({"supply.section2.length+return.section2.length": "1.524 m"}, None,
                     workers=1, scenario="open-loop-step").table.iloc[0]
    circuit = sweep({"circuit.supply.section2.length+circuit.return.section2.length": "1.524 m"},
                    str(CIRCUIT_RIG), workers=1, scenario="open-loop-step").table.iloc[0]
    assert template["error"] is None and circuit["error"] is None
    for col in METRIC_COLUMNS:
        if col == "wall_time_s" or col.endswith("settling_time_s"):
            continue
        assert circuit[col] == pytest.approx(template[col], rel=1e-3, abs=1e-4), col


def test_layout_on_circuit_rig_varies_the_named_hoses():
    rig = load_rig("two_axis")
    study = layout(rig, [1.524], sections="axis1.supply_hose,circuit.axis1.return_hose")
    assert study.sections == ("axis1.supply_hose", "axis1.return_hose") and study.axis == "axis1"
    rec = study.records()[0]
    assert rec["supply"]["frequency_hz"] == pytest.approx(
        _quarter_wave_hz(rig, "axis1.supply_hose", 1.524), rel=0.05)
    assert rec["return"]["frequency_hz"] == pytest.approx(
        _quarter_wave_hz(rig, "axis1.return_hose", 1.524), rel=0.08)
    c = math.sqrt(rig["circuit.axis1.supply_hose.bulk_modulus"] / rig["fluid.density"])
    assert study.table()["supply_round_trip_ms"][0] == pytest.approx(2 * 1.524 / c * 1e3, rel=0.02)
    # the traces (file and figure) are those of the reported axis's ports (they were looked
    # up as the single-axis rig's supply_port_pressure: a KeyError)
    res = study.results[0]
    traces = study.traces()
    np.testing.assert_array_equal(traces["supply_port_pressure_pa@L=1.524m"],
                                  res["axis1.supply_port_pressure"])
    np.testing.assert_array_equal(traces["return_port_pressure_pa@L=1.524m"],
                                  res["axis1.return_port_pressure"])
    assert study.plot() is not None


def test_layout_on_circuit_rig_without_sections_is_one_line_naming_the_rig(capsys):
    assert main(["layout", "two_axis"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "two_axis" in err and "--sections" in err and "axis1.supply_hose" in err
    assert main(["layout", "two_axis", "--sections", "axis1.hose"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no hose section 'axis1.hose'" in err


# --------------------------------------------------------------------------- shared models

def test_variants_of_one_structure_share_one_model_and_give_simulates_rows():
    """Hose variants (length, bulk modulus) run on one shared model with their own p give
    the rows of simulate() + summarize() within the integrator's accuracy (5.5e-3 % of the
    excursion at the defaults: differences come from the graph's constants now being p)."""
    from hydroline.studies.sweep import VariantRunner

    rig = load_rig()
    shared, plain = VariantRunner(rig), VariantRunner(rig, share_models=False)
    variants = [{"supply.section2.length": 1.5, "return.section2.length": 1.5},
                {"supply.section2.length": 0.9, "return.section2.length": 0.9},
                {"supply.section2.length": 0.9, "return.section2.length": 0.9,
                 "supply.section2.bulk_modulus": 1.6e8},
                {"supply.section2.length": 1.2, "return.section2.length": 2.0,
                 "return.section2.diameter": 0.02}]
    for i, values in enumerate(variants):
        a, b = shared(i, values), plain(i, values)
        assert a["error"] is None and b["error"] is None
        for k in METRIC_COLUMNS:
            if k == "wall_time_s":
                continue
            if k.endswith("settling_time_s"):
                assert (a[k] is None) == (b[k] is None), k
                if a[k] is not None:
                    assert a[k] == pytest.approx(b[k], abs=1e-3), k
            else:
                assert a[k] == pytest.approx(b[k], rel=2e-4, abs=1e-4), k
    assert shared.shared_runs == 3          # the 2nd to 4th ran on the 1st's model,
    assert shared.hose_runs == 3            # with only their hoses' entries made anew


def test_shared_model_trace_and_rest_state_equal_simulates():
    """On a shared model (hose entries in p, rest state started from the previous variant's)
    a variant's rest state is simulate()'s to 1e-12 of each state's scale, and its port
    pressures stay within the integrator's accuracy of simulate()'s: each run is within
    ~1e-4 of the excursion of a tight reference at simulate()'s tolerances (rtol 1e-6);
    the short 0.3 m hose rings at ~330 Hz, the hardest case for the step control. Both end
    with the metrics window (a row's run is for its metrics: ``metrics_only``)."""
    from hydroline.scenarios import simulate
    from hydroline.studies.sweep import VariantRunner

    rig = load_rig()
    runner = VariantRunner(rig)
    for i, length in enumerate((0.9, 0.3)):
        r = rig.copy()
        r.set("supply.section2.length", f"{length} m")
        r.set("return.section2.length", "2 m")
        shared, plain = runner.simulate(r), simulate(r, metrics_only=True)
        t0, t1, why = plain.metadata["metrics_window"]
        assert len(shared.t) == len(plain.t) and why == "stop"
        assert t1 <= plain.t[-1] <= t1 + 200 * 1e-4 + 1e-9   # (ended within a block of it)
        scales = runner.models[-1].network.state_scales
        assert np.max(np.abs(shared.steady_state.x - plain.steady_state.x) / scales) < 1e-12
        for k in ("supply_port_pressure", "return_port_pressure"):
            excursion = np.ptp(plain[k])
            assert np.max(np.abs(shared[k] - plain[k])) < 5e-4 * excursion, k
    assert runner.hose_runs == 1


def test_sweep_variants_write_no_cache_file_per_hose(monkeypatch):
    """A sweep's hoses are new lines in every variant: their line numbers (the exact-pole
    realisation of the default line, here interpolated from nodes over the dissipation
    number, the Yang-Tobler corrections) stay in the worker's memory instead of one cache
    file each (and a repeated line is not solved again)."""
    from hydroline.lines import memo, residue, residue_table
    from hydroline.studies.sweep import VariantRunner

    written, solved = [], []
    monkeypatch.setattr(memo, "store_table", lambda kind, key, value: written.append(kind))
    # (the table's nodes realised here, not read from an earlier run's cache)
    monkeypatch.setattr(residue_table, "load_table", lambda kind, key: None)
    monkeypatch.setattr(residue_table, "store_table", lambda kind, key, value: None)
    residue_table._NODES.clear()
    residue_table._STENCILS.clear()
    real_realise = residue._realise
    monkeypatch.setattr(residue, "_realise",
                        lambda *a: solved.append(a[0].length) or real_realise(*a))
    runner = VariantRunner(load_rig())
    counts = []
    for i, length in enumerate((1.234567, 2.345678, 1.234567)):
        row = runner(i, {"supply.section2.length": length, "return.section2.length": length})
        assert row["error"] is None
        counts.append(len(solved))
    assert "residue_lines" not in written and "correction_factors" not in written
    assert counts[1] > counts[0] > 0 and counts[2] == counts[1]   # the repeat: none solved


def test_graph_signature_tells_structures_apart():
    from hydroline.components.hose import coefficients_as_parameters
    from hydroline.scenarios import build_scenario
    from hydroline.studies.sweep import graph_signature
    from hydroline.system import build_circuit

    def signature(**lengths):
        rig = load_rig()
        for path, value in lengths.items():
            rig.set(path.replace("__", "."), value)
        with coefficients_as_parameters():
            circuit = build_circuit(rig)
            net = circuit.network(build_scenario(rig, axes=circuit.axes).commands)
        return graph_signature(net), net

    base, net = signature()
    assert any(k.startswith("supply.section2.A") for k in net.parameter_names)
    assert signature(supply__section2__length="1 m")[0] == base          # numbers only: in p
    assert signature(supply__section2__length="0 m")[0] != base          # section removed
    assert signature(supply__accumulator__precharge_pressure="8 MPa")[0] != base  # a constant
    circuit = build_circuit(load_rig())                 # outside too: the default since the
    assert any(".A" in k for k in circuit.network(      # exact-pole line became the default
        build_scenario(load_rig(), axes=circuit.axes).commands).parameter_names)
    other = signature()[1]
    assert graph_signature(other) == base
    other.components[0].note = lambda: None       # not describable by value: its own
    assert graph_signature(other) != base and graph_signature(other) != graph_signature(net)


@pytest.mark.parametrize("cavity_pressure", ["off", "5 kPa"])
def test_hose_variant_parameters_equal_a_full_build(cavity_pressure):
    """A variant that differs only in hose length, bore or bulk modulus gets, without a
    network build, exactly the p a full build of it gives (the hoses' matrix entries, M8-M14,
    with the cavity model their end cavities' gains C b, M45, and every other parameter);
    anything else (a section removed, another pre-charge, a fluid property) is left to the
    full build."""
    from hydroline.components.hose import coefficients_as_parameters
    from hydroline.scenarios import build_scenario
    from hydroline.studies.sweep import SharedModel
    from hydroline.system import build_circuit

    def built(rig):
        with coefficients_as_parameters():
            circuit = build_circuit(rig)
            sc = build_scenario(rig, axes=circuit.axes)
            return circuit.network(sc.commands), circuit, sc

    base = load_rig()
    base.set("fluid.cavity_pressure", cavity_pressure)
    model = SharedModel(*built(base), base.values)
    assert any(k.endswith(".cavity_gain0") for k in model.network.parameter_names) \
        == (cavity_pressure != "off")
    for changes in ({"supply.section2.length": "0.4 m", "return.section2.length": "2.5 m"},
                    {"supply.section1.diameter": "20 mm", "return.section2.bulk_modulus": "300 MPa"},
                    {"supply.section2.length": "1.7 m", "supply.section2.bulk_modulus": "150 MPa"}):
        rig = base.copy()
        for path, value in changes.items():
            rig.set(path, value)
        p = model.hose_parameters(rig)
        full = built(rig)[0]
        assert full.parameter_names == model.network.parameter_names
        np.testing.assert_array_equal(p, full.parameter_values)
    for path, value in (("supply.section2.length", "0 m"),
                        ("supply.accumulator.precharge_pressure", "8 MPa"),
                        ("fluid.kinematic_viscosity", "40 mm^2/s")):
        rig = base.copy()
        rig.set(path, value)
        assert model.hose_parameters(rig) is None, path
    rig = base.copy()
    rig.set("supply.section2.length", "-1 m")           # checked as a full build checks it
    with pytest.raises(RigError, match="supply.section2.length"):
        model.hose_parameters(rig)


def test_metrics_equal_with_and_without_scipy_fft(monkeypatch):
    """A sweep's workers load scipy.fft so that the metrics' spectra are computed by it; the
    port metrics are the same numbers as with NumPy's FFT (a single run's path)."""
    import scipy.fft  # noqa: F401
    from hydroline.traces.metrics import pressure_metrics

    t = np.linspace(0.0, 0.1, 1001)
    p = 2e7 + 1e6 * np.exp(-30 * t) * np.sin(2 * np.pi * 95.0 * t) * (t > 0.01)
    with_scipy = pressure_metrics(t, p, 0.01)
    monkeypatch.delitem(sys.modules, "scipy.fft")
    assert pressure_metrics(t, p, 0.01) == with_scipy
    assert with_scipy["frequency_hz"] == pytest.approx(95.0, rel=3e-3)   # the sine's own


def test_a_new_models_first_rest_state_starts_from_the_base_rigs(monkeypatch):
    """The first variant of a hose sweep on a worker, 0.05 m hoses, starts from the base
    rig's rest state (3.048 m hoses): Newton alone solves it, and it is simulate()'s rest
    state (from the components' guess: Newton with shifted steps, ~7 ms, where it once
    needed the pseudo-transient continuation, ~0.7 s) to 1e-9 of each state's scale (Newton
    stops at steps below 1e-10 of it; measured 1.6e-12)."""
    from hydroline.engine import steady_state
    from hydroline.scenarios import simulate
    from hydroline.studies.sweep import VariantRunner

    continued = []
    real = steady_state.pseudo_transient
    monkeypatch.setattr(steady_state, "pseudo_transient",
                        lambda model, t0, x, p, *a: continued.append(p.copy()) or
                        real(model, t0, x, p, *a))
    rig = load_rig()
    r = rig.copy()
    r.set("supply.section2.length", "0.05 m")
    r.set("return.section2.length", "0.05 m")
    runner = VariantRunner(rig)
    shared = runner.simulate(r)
    model = runner.models[-1]
    assert not any(np.array_equal(p, model.p) for p in continued)     # the variant's: Newton
    continued.clear()
    plain = simulate(r, metrics_only=True)
    assert not continued           # (from the guess too: shifted steps, no continuation)
    scales = model.network.state_scales
    assert np.max(np.abs(shared.steady_state.x - plain.steady_state.x) / scales) < 1e-9
