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
