"""Per evaluation (issue 25): a run only for its metrics ends with its metrics window, with
the metrics of the whole run; hydroline's small dense solves run on one BLAS thread and give
the program's thread count back. Checked against independent facts: the whole run's own
metrics window and metrics, the piston's arrival at its stop, OpenBLAS's own count."""
import numpy as np
import pytest

import hydroline
from hydroline.blas import one_blas_thread
from hydroline.scenarios.summaries import WindowEnd, metrics_window, summarize, window_of


def test_a_metrics_only_run_ends_at_the_stop_with_the_whole_run_s_metrics():
    """The default step's piston reaches its stop at ~113 ms: a run only for its metrics
    ends within a few rows after it (the piston is then within 1 mm of the stop; it arrives
    at a steady ~1 m/s, so the watch's estimate of its arrival holds and the blocks shrink to
    NEAR_ROWS rows before it), its rows are the whole run's rows up to there, and its summary
    is the whole run's."""
    from hydroline.engine.integrate import NEAR_ROWS

    rig = hydroline.load_rig()
    whole = hydroline.simulate(rig)
    short = hydroline.simulate(rig, metrics_only=True)
    t0, t1, why = metrics_window(whole)
    assert why == "stop" and metrics_window(short) == (t0, t1, why)
    assert t1 <= short.t[-1] <= t1 + NEAR_ROWS * 1e-4 + 1e-12 < whole.t[-1]
    half = whole.metadata["stroke"] / 2
    assert abs(short["piston_position"][short.t <= t1][-1]) >= half - 1e-3   # at the stop
    n = len(short.t)
    for k in ("supply_port_pressure", "return_port_pressure", "piston_position"):
        np.testing.assert_array_equal(short[k], whole[k][:n])
    a, b = summarize(whole), summarize(short)
    for s in (a, b):
        s.pop("wall_time_s")
    assert a == b


def test_the_window_watch_stops_where_the_window_ends_block_by_block():
    """A piston moving down from 0 to its stop at -50 mm (stroke 100 mm) and resting there:
    the watch, fed growing blocks of rows, first says "reached" in the block holding the first
    sample within 1 mm of the stop (not before), where :func:`window_of` of all rows ends."""
    t = np.linspace(0.0, 0.2, 2001)
    x = np.where(t < 0.01, 0.0, -np.minimum((t - 0.01) * 0.5, 0.05))
    t0, t1, why = window_of(t, {"pos": (x, 0.1)}, 0.01)
    assert why == "stop" and t1 == pytest.approx(0.01 + 0.049 / 0.5, abs=1e-4)
    watch = WindowEnd(0.01, {"pos": 0.1})
    rows = x[:, None]
    first = next(k for k in range(50, 2001, 50) if watch(t[:k], rows[:k], ["pos"]))
    assert t[first - 50] < t1 <= t[first - 1]


def test_the_window_watch_estimates_the_arrival_at_the_piston_s_speed():
    """time_ahead after rows up to t: unknown (inf) before the piston has clearly moved;
    then the gap to 1 mm short of the stop over the speed, (0.049 - 0.5 (t - 0.01)) / 0.5 s
    for a piston moving down at 0.5 m/s from 0 at 10 ms toward its stop at -50 mm; inf again
    for a piston that moves away from the stop it first moved toward."""
    t = np.linspace(0.0, 0.2, 2001)
    x = np.where(t < 0.01, 0.0, -np.minimum((t - 0.01) * 0.5, 0.05))
    watch = WindowEnd(0.01, {"pos": 0.1})
    assert not watch(t[:101], x[:101, None], ["pos"]) and watch.time_ahead() == np.inf
    for k in (200, 400, 900):
        assert not watch(t[:k], x[:k, None], ["pos"])
        assert watch.time_ahead() == pytest.approx((0.049 - 0.5 * (t[k - 1] - 0.01)) / 0.5,
                                                   rel=1e-9)
    back = WindowEnd(0.01, {"pos": 0.1})
    y = np.where(t < 0.03, x, x[300] + (t - 0.03) * 0.5)   # turns at 30 ms, 10 mm down
    assert not back(t[:400], y[:400, None], ["pos"]) and back.time_ahead() == np.inf


def test_one_blas_thread_sets_one_and_gives_the_count_back():
    """Inside, every OpenBLAS NumPy loaded runs one thread; afterwards the program's own
    count is back (read from OpenBLAS itself)."""
    from hydroline.blas import openblas_controls

    controls = openblas_controls()
    if not controls:
        pytest.skip("no OpenBLAS found in this process")
    setter, getter = controls[0]
    before = getter()
    setter(2)
    try:
        with one_blas_thread():
            assert all(get() == 1 for _, get in controls)
        assert getter() == 2
    finally:
        setter(before)
