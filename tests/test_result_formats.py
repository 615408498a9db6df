"""``hydroline simulate --format csv|parquet|mat`` (issue 26): the same rows in each file, the
units with them, and ``hydroline fit``'s reader takes all three."""
import numpy as np
import pandas as pd
import pytest
from scipy.io import loadmat

from hydroline.analysis.fit import read_measurements
from hydroline.cli import main
from hydroline.engine.result import matlab_names


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """One 30 ms run written in each format (the run is deterministic: same rows)."""
    out = {}
    for fmt in ("csv", "parquet", "mat"):
        folder = tmp_path_factory.mktemp(fmt)
        assert main(["simulate", "--t-end", "30 ms", "--json", "--format", fmt,
                     "--out", str(folder)]) == 0
        out[fmt] = folder / f"results.{fmt}"
    return out


def test_mat_holds_one_variable_per_signal_with_units(written):
    csv = pd.read_csv(written["csv"])
    mat = loadmat(written["mat"], squeeze_me=True)
    units = mat["units"]
    assert str(units["supply_port_pressure"]) == "Pa" and str(units["time"]) == "s"
    assert np.array_equal(mat["supply_port_pressure"], csv["supply_port_pressure [Pa]"])
    assert np.array_equal(mat["time"], csv["time [s]"])
    # every CSV column is a variable, under its MATLAB name, its hydroline name in 'names'
    names = mat["names"]
    assert str(names["supply_section2_mode3_flow"]) == "supply.section2.mode3.flow"
    assert len(names.dtype.names) == len(csv.columns)


def test_parquet_round_trips_through_pandas_with_units(written):
    csv = pd.read_csv(written["csv"])
    pq = pd.read_parquet(written["parquet"])
    assert pq.attrs["units"]["supply_port_pressure"] == "Pa"
    assert pq.attrs["units"]["time"] == "s"
    assert [f"{c} [{pq.attrs['units'][c]}]" if c in pq.attrs["units"] else c
            for c in pq.columns] == list(csv.columns)
    assert np.array_equal(pq.to_numpy(), csv.to_numpy(), equal_nan=True)


def test_fit_reads_all_three(written):
    records = {fmt: read_measurements(path) for fmt, path in written.items()}
    ref = records["csv"].data
    assert {"time", "valve_current", "supply_port_pressure"} <= set(ref.columns)
    for fmt in ("parquet", "mat"):
        pd.testing.assert_frame_equal(records[fmt].data, ref, check_exact=True)


def test_matlab_names_are_valid_and_distinct():
    names = matlab_names(["time", "a.b", "a_b", "1x", "x" * 70, "x" * 70, "units"])
    assert names[:4] == ["time", "a_b", "a_b_2", "x1x"]
    assert len(set(names)) == len(names) and all(len(n) <= 63 for n in names)
    assert all(n[0].isalpha() and n.replace("_", "").isalnum() for n in names)
    assert names[-1] != "units"          # 'units' and 'names' hold the structs


# ---- a long run's written rows (issue 26 item 2) ----------------------------------------------

def test_written_interval_by_hand():
    """The default interval of the written rows: every 0.1 ms row while the file stays within
    200 MB at 17 bytes a value, else the first of 0.2, 0.5, 1, 2, 5, 10 ms ... that does."""
    from hydroline.cli.simulate import written_interval

    assert written_interval(0.25, 168) is None            # 2501 x 168 x 17 B = 7.1 MB
    # 20 s: 0.1 ms 571 MB, 0.2 ms 286 MB, 0.5 ms 40001 x 168 x 17 = 114 MB
    assert written_interval(20.0, 168) == pytest.approx(5e-4)
    # 600 s: 5 ms 120001 x 168 x 17 = 343 MB, 10 ms 60001 x 168 x 17 = 171 MB
    assert written_interval(600.0, 168) == pytest.approx(1e-2)
    # a limit below one row's worth: the interval stops at the run's length, or at 1 s
    assert written_interval(0.5, 168, limit=1.0) == pytest.approx(0.5)
    assert written_interval(1e30, 168) == pytest.approx(1.0)


def test_a_default_run_over_the_limit_writes_fewer_rows_and_says_so(written, tmp_path,
                                                                    monkeypatch, capsys):
    """With the limit set just below the 30 ms run's file, the default run writes every
    second row (0.2 ms) and says so on stderr, with how to get every row."""
    from hydroline.cli import simulate as cli_simulate

    full = pd.read_csv(written["csv"])
    monkeypatch.setattr(cli_simulate, "WRITE_BYTES", len(full) * full.shape[1] * 17 - 1)
    assert main(["simulate", "--t-end", "30 ms", "--json", "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "every 0.2 ms row" in err and "--dt-out '0.1 ms' writes them all" in err
    half = pd.read_csv(tmp_path / "results.csv")
    assert len(half) == 151                                # 0, 0.2 ms, ..., 30 ms
    pd.testing.assert_frame_equal(half, full.iloc[::2].reset_index(drop=True))


def test_a_long_run_writes_the_same_rows_to_mat(written, tmp_path, monkeypatch):
    """A run the CLI treats as long (threshold lowered) keeps the rows it writes to a MAT
    file as it goes: every 7th of the 301 rows, 0 ... 294, and the last, 300."""
    from hydroline.cli import simulate as cli_simulate

    monkeypatch.setattr(cli_simulate, "LONG_ROWS", 100)
    assert main(["simulate", "--t-end", "30 ms", "--json", "--format", "mat", "--dt-out",
                 "0.7 ms", "--out", str(tmp_path)]) == 0
    mat = loadmat(tmp_path / "results.mat", squeeze_me=True)
    full = pd.read_csv(written["csv"])
    rows = list(range(0, 295, 7)) + [300]
    np.testing.assert_array_equal(mat["time"], full["time [s]"].to_numpy()[rows])
    # the long run integrates in chunks: equal to the in-memory run within its tolerance
    np.testing.assert_allclose(mat["supply_port_pressure"],
                               full["supply_port_pressure [Pa]"].to_numpy()[rows], rtol=1e-6)
    assert str(mat["units"]["supply_port_pressure"]) == "Pa"


def test_layout_traces_in_each_format(tmp_path):
    """``hydroline layout --format parquet|mat``: the traces of layout_traces.csv, the units
    in the file."""
    args = ["layout", "--lengths", "0", "--t-end", "20 ms", "--json"]
    for fmt in ("csv", "parquet", "mat"):
        assert main(args + ["--format", fmt, "--out", str(tmp_path / fmt)]) == 0
    csv = pd.read_csv(tmp_path / "csv" / "layout_traces.csv")
    pq = pd.read_parquet(tmp_path / "parquet" / "layout_traces.parquet")
    assert pq.attrs["units"] == {"time": "s", "supply_port_pressure@L=0m": "Pa",
                                 "return_port_pressure@L=0m": "Pa"}
    np.testing.assert_array_equal(pq.to_numpy(), csv.to_numpy())
    mat = loadmat(tmp_path / "mat" / "layout_traces.mat", squeeze_me=True)
    assert str(mat["units"]["supply_port_pressure_L_0m"]) == "Pa"
    np.testing.assert_array_equal(mat["supply_port_pressure_L_0m"],
                                  csv["supply_port_pressure_pa@L=0m"])


def test_parquet_without_pyarrow_says_what_to_install(tmp_path, monkeypatch):
    import sys

    import hydroline

    res = hydroline.simulate(t_end=0.02)
    monkeypatch.setitem(sys.modules, "pyarrow", None)      # import pyarrow -> ImportError
    with pytest.raises(ValueError, match="needs pyarrow: pip install pyarrow"):
        res.to_parquet(tmp_path / "r.parquet")


def test_simulate_without_pyarrow_refuses_parquet_before_the_run(tmp_path, monkeypatch, capsys):
    """``simulate --format parquet`` without pyarrow: one line naming the file and what to
    install, exit 2, before any run (a long run found it only when writing, at its end)."""
    import sys

    from hydroline.scenarios import running

    monkeypatch.setitem(sys.modules, "pyarrow", None)      # import pyarrow -> ImportError

    def no_run(*args, **kwargs):
        raise AssertionError("the run started")

    monkeypatch.setattr(running, "simulate", no_run)
    assert main(["simulate", "--t-end", "600 s", "--scenario", "closed-loop-sine", "--format",
                 "parquet", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "results.parquet: writing Parquet needs pyarrow" in err[0]


def test_csv_table_is_the_text_pandas_writes(tmp_path):
    """``write_csv_table`` (the layout's and bode's CSV files without pandas' import) writes
    what ``DataFrame(columns).to_csv(index=False)`` writes: every kind of column a table of
    metrics holds (floats with NaN and None, integers, integers beside floats, notes with
    commas, quotes and line breaks, flags, empty text), drawn from a seeded pool."""
    import io

    from hydroline.engine.result import write_csv_table

    pool = [None, np.nan, 1, 2.5, np.float64(3.0), np.int64(4), True, False, "x", "a,b", 'q"',
            "", "two\nlines", -0.0, np.inf, -np.inf, 1e-300, 12345678901234567.0, 7]
    rng = np.random.default_rng(25)
    for _ in range(300):
        rows = int(rng.integers(1, 5))
        columns = {f"c{j}, [unit]": [pool[i] for i in rng.integers(0, len(pool), rows)]
                   for j in range(int(rng.integers(2, 5)))}
        columns["floats"] = rng.standard_normal(rows) * 10.0 ** rng.integers(-30, 30, rows)
        expected = io.StringIO()
        pd.DataFrame(columns).to_csv(expected, index=False)
        write_csv_table(tmp_path / "t.csv", columns)
        assert (tmp_path / "t.csv").read_bytes().decode() == expected.getvalue(), columns
