"""Start-up path: the pint-free unit table and the SciPy-free peak finder against the
libraries they stand in for, and what ``import hydroline`` / a --json run load."""
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.signal import find_peaks as scipy_find_peaks

from hydroline.traces.peaks import find_peaks, local_maxima
from hydroline.unit_table import UNITS, si_value
from hydroline import units
from hydroline.units import parse_quantity

UREG = units.ureg   # pint's registry as hydroline sets it up


@pytest.mark.parametrize("name", sorted(UNITS))
def test_every_table_unit_equals_pint(name):
    """Factor and dimension of each entry against pint's own definition."""
    factor, dims = UNITS[name]
    q = UREG.Quantity(1.0, "percent" if name == "%" else name).to_base_units()
    assert q.magnitude == pytest.approx(factor, rel=1e-14)
    want = dict(q.dimensionality)
    got = {"[length]": dims[0], "[mass]": dims[1], "[time]": dims[2], "[current]": dims[3]}
    assert {k: v for k, v in got.items() if v} == {k: v for k, v in want.items() if v}


@pytest.mark.parametrize("text, unit", [
    ("20.7 MPa", "Pa"), ("3000 psi", "Pa"), ("12.7 mm", "m"), ("3.048 m", "m"), ("10 ft", "m"),
    ("0.5 in", "m"), ("19 L/min", "m^3/s"), ("5 gpm", "m^3/s"), ("32 cSt", "m^2/s"),
    ("1.25e9 Pa*s/m^3", "Pa*s/m^3"), ("870 kg/m^3", "kg/m^3"), ("2000 N*s/m", "N*s/m"),
    ("-5 mm", "m"), ("1.5e9 Pa", "Pa"), ("0.04 A/m", "A/m"), ("3 cm^3", "m^3"),
    ("12 cm^2", "m^2"), ("50 %", "-"), ("0.85", "dimensionless"), ("250 bar", "Pa"),
    ("10 ms", "s"), ("100 Hz", "Hz"), ("4 um", "m"), ("1 MPa/s", "Pa/s"), ("9.81 m/s^2", "m/s^2"),
    ("2 m**3", "m^3"), ("1 L", "m^3"), ("1 lbf", "N"), ("1 gal/min", "m^3/s"),
])
def test_table_reads_as_pint_does(text, unit):
    want = UREG.parse_expression(text)
    target = "dimensionless" if unit == "-" else unit
    want = float(want.to(target).magnitude) if hasattr(want, "to") else float(want)
    assert si_value(text, unit) == pytest.approx(want, rel=1e-14)
    assert parse_quantity(text, unit, "x") == pytest.approx(want, rel=1e-14)


@pytest.mark.parametrize("text, unit", [
    ("3.048", "m"),        # bare number for a length: pint's path words the refusal
    ("20,7 MPa", "Pa"), ("MPa", "Pa"), ("2 3 m", "m"), ("20.7 MPa 3", "Pa"), ("N m", "N*m"),
    ("100 rad/s", "Hz"), ("600 rpm", "Hz"),   # angles: pint's path checks them
    ("3000 psi", "m"),     # wrong dimension
    ("1 furlong", "m"),    # not in the table
    ("1e999 m", "m"), ("9**9**9 m", "m"),
])
def test_table_leaves_the_doubtful_to_pint(text, unit):
    assert si_value(text, unit) is None


def test_find_peaks_equals_scipy():
    rng = np.random.default_rng(1)
    for trial in range(60):
        n = int(rng.integers(3, 400))
        x = rng.normal(size=n).cumsum() if trial % 2 else rng.normal(size=n)
        if trial % 3 == 0:   # plateaus
            x = np.round(x * 2) / 2
        for prom in (None, 0.0, 0.3, 1.5):
            got, props = find_peaks(x, prominence=prom)
            want, wprops = scipy_find_peaks(x, prominence=prom)
            np.testing.assert_array_equal(got, want)
            if prom is not None:
                np.testing.assert_allclose(props["prominences"], wprops["prominences"])
        for dist in (1, 2.5, 7):
            np.testing.assert_array_equal(find_peaks(x, distance=dist)[0],
                                          scipy_find_peaks(x, distance=dist)[0])
    t = np.linspace(0, 1, 4096)   # a padded spectrum: many ripples, few prominent peaks
    spec = np.abs(np.fft.rfft(np.sin(2 * np.pi * 40 * t) * np.exp(-3 * t), 1 << 15))
    for frac in (0.02, 0.2):
        np.testing.assert_array_equal(find_peaks(spec, prominence=frac * spec.max())[0],
                                      scipy_find_peaks(spec, prominence=frac * spec.max())[0])
    assert local_maxima([1.0, 2.0]).size == 0


def _loaded_modules(code):
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys\n"
                          "print(' '.join(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True).stdout.split()
    return {m.split(".")[0] for m in out} | set(out)


def test_import_hydroline_loads_no_heavy_library():
    loaded = _loaded_modules("import hydroline")
    for heavy in ("pint", "pandas", "matplotlib", "dask", "control", "scipy", "casadi"):
        assert heavy not in loaded, heavy


def test_background_builder_starts_without_numpy():
    """The background builder (``python -c``) imports its work without the compiled
    package's ``__init__`` (the model's modules, NumPy): the quick build's compiler starts
    ~0.1 s of CPU sooner, which a fit's first run waits for."""
    from hydroline.compiled.toolchain import BUILDER_IMPORTS

    loaded = _loaded_modules(BUILDER_IMPORTS + "assert callable(build_from_file)\n")
    for heavy in ("numpy", "casadi", "hydroline.compiled.native", "hydroline.compiled.generated"):
        assert heavy not in loaded, heavy


def test_json_run_loads_only_what_it_uses(tmp_path):
    """``hydroline simulate --json`` (no --out): no files, and no pint, pandas, matplotlib,
    dask, python-control or scipy.signal/stats/optimize in the process; no importlib.resources
    (shipped rigs are read as files) and no difflib (only for messages)."""
    loaded = _loaded_modules(
        "import contextlib, io\nfrom hydroline.cli import main\n"
        f"import os; os.chdir({str(tmp_path)!r})\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    assert main(['simulate', '--json']) == 0\n")
    for heavy in ("pint", "pandas", "matplotlib", "dask", "control", "scipy.signal",
                  "scipy.stats", "scipy.optimize", "importlib.resources", "zipfile", "difflib"):
        assert heavy not in loaded, heavy
    assert list(tmp_path.iterdir()) == []


def test_long_run_cli_streams_the_same_numbers(tmp_path, monkeypatch):
    """A run the CLI treats as long (here: made long by lowering the threshold) keeps only the
    summary's columns in memory and streams results.csv: same summary and same rows (to the
    9 digits written) as the in-memory run; --dt-out keeps every n-th row and the last."""
    import json

    import pandas as pd

    from hydroline.cli import main
    from hydroline.cli import simulate as cli_simulate

    args = ["simulate", "--json", "--t-end", "0.05 s", "--dt-out", "0.5 ms"]
    assert main(args + ["--out", str(tmp_path / "short")]) == 0
    monkeypatch.setattr(cli_simulate, "LONG_ROWS", 100)
    assert main(args + ["--out", str(tmp_path / "long")]) == 0
    short = json.loads((tmp_path / "short" / "summary.json").read_text())
    long = json.loads((tmp_path / "long" / "summary.json").read_text())
    short.pop("wall_time_s"), long.pop("wall_time_s")
    assert long == short
    a = pd.read_csv(tmp_path / "short" / "results.csv")
    b = pd.read_csv(tmp_path / "long" / "results.csv")
    assert list(a.columns) == list(b.columns)
    assert len(a) == len(b) == 101                         # 0, 0.5 ms, ..., 50 ms
    np.testing.assert_allclose(b["time [s]"], np.arange(101) * 5e-4, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(b.to_numpy(), a.to_numpy(), rtol=1e-8, atol=1e-12)
    assert sorted(p.name for p in (tmp_path / "long").iterdir()) == ["pressures.png", "results.csv", "summary.json"]
    assert (tmp_path / "long" / "pressures.png").stat().st_size > 0


def test_output_grid_of_dt_out():
    from hydroline.cli.simulate import output_grid

    assert output_grid(0.25, None) == (1e-4, 1, 2501)
    h, every, rows = output_grid(0.25, 1e-3)
    assert (every, rows) == (10, 251) and h == pytest.approx(1e-4)
    h, every, rows = output_grid(1.0, 2.5e-4)              # not a multiple of 0.1 ms
    assert every == 3 and h == pytest.approx(2.5e-4 / 3) and rows == 4001
    assert output_grid(1.0, 1e-5)[:2] == (1e-5, 1)         # finer than 0.1 ms: every row


def test_lazy_analysis_names_are_the_functions():
    """``hydroline.analysis.linearize`` is the function even after its submodule (of the same
    name) was imported, as with the package's former eager imports."""
    code = ("import types, hydroline.analysis.linearize\n"
            "from hydroline.analysis import linearize, oscillation_frequency\n"
            "import hydroline\n"
            "assert callable(linearize) and not isinstance(linearize, types.ModuleType)\n"
            "assert hydroline.analysis.linearize is linearize\n"
            "assert hydroline.simulate.__module__ == 'hydroline.scenarios.running'\n")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_filters_equal_scipy():
    from scipy.ndimage import maximum_filter1d as smax
    from scipy.ndimage import minimum_filter1d as smin
    from scipy.ndimage import uniform_filter1d as sunif
    from scipy.signal import savgol_filter as ssavgol

    from hydroline.traces import filters

    rng = np.random.default_rng(3)
    for n in (7, 30, 257, 1000):
        x = rng.normal(size=n).cumsum() * 1e6 + 2e7
        for size in (1, 2, 5, 8, 33, n):
            np.testing.assert_array_equal(filters.maximum_filter1d(x, size),
                                          smax(x, size, mode="nearest"))
            np.testing.assert_array_equal(filters.minimum_filter1d(x, size),
                                          smin(x, size, mode="nearest"))
            np.testing.assert_allclose(filters.uniform_filter1d(x, size),
                                       sunif(x, size, mode="nearest"), rtol=1e-12)
        for w in (5, 7, 21):
            if w <= n:
                np.testing.assert_allclose(filters.savgol_filter(x, w, 3),
                                           ssavgol(x, w, 3, mode="interp"), rtol=1e-12)
    with pytest.raises(ValueError):
        filters.savgol_filter(np.zeros(4), 5, 3)


def test_the_command_asks_blas_for_one_thread_unless_the_user_chose():
    """A fresh `hydroline` process sets the BLAS thread variables it finds unset to 1 (before
    NumPy loads), and leaves a user's own setting alone."""
    code = ("import io, os, contextlib\nfrom hydroline.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    try:\n        main(['--version'])\n    except SystemExit:\n        pass\n"
            "print(os.environ['OPENBLAS_NUM_THREADS'], os.environ['OMP_NUM_THREADS'])")
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", code], env=dict(env, OMP_NUM_THREADS="3"),
                         capture_output=True, text=True, check=True).stdout.split()
    assert out == ["1", "3"]


def test_recorded_rest_state_is_the_solved_one(monkeypatch):
    """A rest state read from the cache's table (``solve_steady_state(recorded=True)``, what
    ``hydroline simulate`` does) has the bits of one solved from the components' guess; a
    record whose states do not give the recorded residual is not used (solved again)."""
    import json
    import shutil
    import uuid

    from hydroline.cache import cache_dir
    from hydroline.compiled import records
    from hydroline.engine import solve_steady_state
    from hydroline.rigs import load_rig
    from hydroline.scenarios.experiments import build_scenario
    from hydroline.system import build_circuit

    kind = f"rest_states_test_{uuid.uuid4().hex[:8]}"
    monkeypatch.setattr(records, "REST_STATES", kind)

    def network():
        rig = load_rig()
        circuit = build_circuit(rig)
        return circuit.network(build_scenario(rig, "open-loop-step", None,
                                              axes=circuit.axes).commands)

    def same(a, b):
        assert a.x.tobytes() == b.x.tobytes() and a.p.tobytes() == b.p.tobytes()
        assert (a.residual, a.worst_state) == (b.residual, b.worst_state)

    try:
        solved = solve_steady_state(network())
        same(solve_steady_state(network(), recorded=True), solved)    # solved and recorded
        (entry,) = (cache_dir() / kind).iterdir()
        same(solve_steady_state(network(), recorded=True), solved)    # read
        stored = json.loads(entry.read_text())
        value = dict(stored["value"])
        x = [float.fromhex(v) for v in value["x"]]
        x[0] *= 1 + 1e-9                                   # a valid entry, another state
        value["x"] = [v.hex() for v in x]
        records.record_rest_state(stored["key"], value)
        same(solve_steady_state(network(), recorded=True), solved)    # checked: solved again
        assert json.loads(entry.read_text())["value"] == stored["value"]   # and re-recorded
    finally:
        shutil.rmtree(cache_dir() / kind, ignore_errors=True)


def test_rig_toml_from_the_cache_is_what_tomllib_reads(monkeypatch):
    """A rig file's tables read again come from the cache (no parser) and equal tomllib's
    reading of the text; text with a date (no JSON for it) is parsed each time; bad TOML is
    one RigError naming the source."""
    import shutil
    import tomllib
    import uuid

    from hydroline import rigs
    from hydroline.cache import cache_dir

    kind = f"rig_toml_test_{uuid.uuid4().hex[:8]}"
    monkeypatch.setattr(rigs, "TOML_TABLES", kind)
    text = (rigs.SHIPPED_RIGS / rigs.DEFAULT_RIG).read_text(encoding="utf-8")
    try:
        first = rigs.parse_toml(text, "x")
        assert len(list((cache_dir() / kind).iterdir())) == 1
        monkeypatch.setattr(tomllib, "loads", None)   # read again: the parser is not called
        assert rigs.parse_toml(text, "x") == first
        monkeypatch.undo()
        assert first == tomllib.loads(text)
        monkeypatch.setattr(rigs, "TOML_TABLES", kind)
        assert rigs.parse_toml("[rig]\nwhen = 2005-07-01\n", "x")["rig"]["when"].year == 2005
        assert len(list((cache_dir() / kind).iterdir())) == 1
        with pytest.raises(rigs.RigError, match="^y.toml: not valid TOML"):
            rigs.parse_toml("[rig\n", "y.toml")
    finally:
        shutil.rmtree(cache_dir() / kind, ignore_errors=True)
