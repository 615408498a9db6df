"""Long runs in constant memory (issue 13 item 3): the closed-loop sine's summary computed
chunk by chunk (scenarios.SineSummaryStream) against hand-derived numbers of a synthetic
trace and against the in-memory summary of the same run."""
import numpy as np
import pytest

from hydroline.scenarios import SineSummaryStream, metrics_window, simulate, summarize
from hydroline.simulation import SimulationResult

COLUMNS = ["supply_port_pressure", "return_port_pressure", "piston_position",
           "position_reference"]


def feed(stream, t, table, chunk):
    for k in range(0, len(t), chunk):
        stream.update(t[k:k + chunk], table[k:k + chunk], COLUMNS)


def synthetic(f=2.0, dt=1 / 4000, periods=3, a_supply=0.3e6, a_return=0.1e6, e0=2e-3):
    """A 2 Hz sine trace sampled so that every crest and trough is a sample: per cycle the
    supply ripple is exactly 2 a_supply (a sine at 10 f), the return 2 a_return, and the
    tracking error e0 sin(2 pi f t)."""
    t = np.arange(int(round(periods / f / dt)) + 1) * dt
    ref = 0.02 * np.sin(2 * np.pi * f * t)
    x = ref - e0 * np.sin(2 * np.pi * f * t)
    ps = 20.7e6 + a_supply * np.sin(2 * np.pi * 10 * f * t)
    pr = 0.5e6 + a_return * np.cos(2 * np.pi * 10 * f * t)
    return t, np.column_stack([ps, pr, x, ref])


@pytest.mark.parametrize("chunk", [7, 1000, 100_000])
def test_sine_stream_gives_the_hand_derived_ripple_and_tracking_error(chunk):
    t, table = synthetic()
    s = SineSummaryStream(0.0, stroke=0.1, frequency=2.0)
    feed(s, t, table, chunk)
    out = s.summary(SimulationResult(times=t[-1:], table=table[-1:], columns=COLUMNS,
                                      metadata={"actuator_natural_frequency_hz": 172.0}))
    assert out["supply"]["ripple_pp_mpa_per_cycle"] == pytest.approx([0.6] * 3, rel=1e-12)
    assert out["return"]["ripple_pp_mpa_per_cycle"] == pytest.approx([0.2] * 3, rel=1e-12)
    assert out["supply"]["amplitude_mpa"] == pytest.approx(0.3, rel=1e-12)
    # mean of sin^2 over 3 whole periods of 2000 samples plus the end sample (sin = 0): 1/2
    # of 6000 samples in 6001
    assert out["tracking_error_rms_mm"] == pytest.approx(2.0 * np.sqrt(3000 / 6001), rel=1e-9)
    assert out["tracking_error_max_mm"] == pytest.approx(2.0, rel=1e-9)
    assert out["metrics_window_s"] == [0.0, pytest.approx(1.5)]


def test_sine_stream_ends_the_window_where_the_piston_reaches_its_stop():
    # the piston drifts into the +50 mm stop: the window ends at the first row within 1 mm of
    # it, as metrics_window finds on the whole trace; later rows count for nothing
    t, table = synthetic(periods=4)
    table[:, 2] = 0.06 * t / t[-1] * 2          # reaches 49 mm at t = 0.8167 s
    s = SineSummaryStream(0.0, stroke=0.1, frequency=2.0)
    feed(s, t, table, 333)
    res = SimulationResult(times=t, table=table, columns=COLUMNS,
                           metadata={"stroke": 0.1, "t_disturbance": 0.0,
                                     "actuator_natural_frequency_hz": 172.0})
    t0, t1, reason = metrics_window(res)
    assert reason == "stop" and s.arrived
    assert s.summary(res)["metrics_window_s"] == [t0, t1]
    assert t1 == pytest.approx(0.049 / 0.12 * 2, abs=1 / 4000)
    assert len(s.summary(res)["supply"]["ripple_pp_mpa_per_cycle"]) == 1   # one full cycle
    m = t <= t1
    err = table[m, 3] - table[m, 2]
    assert s.summary(res)["tracking_error_max_mm"] == pytest.approx(np.max(np.abs(err)) * 1e3)


def test_sine_stream_equals_the_in_memory_summary_of_a_run():
    # the same run kept in memory and summarized, and streamed in chunks of 997 rows
    kw = dict(t_end=1.2, dt_out=2e-4, solver="auto")
    res = simulate(None, "closed-loop-sine", **kw)
    ref = summarize(res)
    s = SineSummaryStream(res.metadata["t_disturbance"], res.metadata["stroke"],
                          res.metadata["command_frequency_hz"])
    streamed = simulate(None, "closed-loop-sine", observe=s.update, chunk_rows=997,
                        keep_columns=[], **kw)
    out = s.summary(streamed)
    for k in ("wall_time_s",):
        out.pop(k), ref.pop(k)
    # the squares are summed chunk by chunk there and in one pass here: equal to rounding
    assert out.pop("tracking_error_rms_mm") == pytest.approx(ref.pop("tracking_error_rms_mm"),
                                                             rel=1e-12)
    assert out == ref


def test_long_cli_sine_run_summarizes_as_the_in_memory_run(tmp_path, monkeypatch, capsys):
    """The CLI's long-run path (made long by lowering its threshold) for the closed-loop sine:
    the summary from the chunk-by-chunk statistics equals the one of the run kept in memory."""
    import json

    from hydroline.cli import main
    from hydroline.cli import simulate as cli_simulate

    args = ["simulate", "--scenario", "closed-loop-sine", "--t-end", "0.6 s", "--dt-out", "1 ms"]
    assert main(args + ["--out", str(tmp_path / "short")]) == 0
    monkeypatch.setattr(cli_simulate, "LONG_ROWS", 100)
    assert main(args + ["--out", str(tmp_path / "long")]) == 0
    short = json.loads((tmp_path / "short" / "summary.json").read_text())
    long = json.loads((tmp_path / "long" / "summary.json").read_text())
    short.pop("wall_time_s"), long.pop("wall_time_s")
    # (squares summed chunk by chunk in the long run: equal to rounding)
    assert long.pop("tracking_error_rms_mm") == pytest.approx(short.pop("tracking_error_rms_mm"),
                                                              rel=1e-12)
    assert long == short
    assert len(long["supply"]["ripple_pp_mpa_per_cycle"]) == 1
    assert (tmp_path / "long" / "pressures.png").stat().st_size > 0
    capsys.readouterr()
    assert main(args + ["--json"]) == 0     # long, no files: nothing kept but the times
    printed = json.loads(capsys.readouterr().out)
    assert printed["supply"]["amplitude_mpa"] == short["supply"]["amplitude_mpa"]


def test_streamed_csv_text_is_savetxt_text():
    # result.csv_rows formats a block in one operation: the same text as NumPy's row-by-row
    # savetxt (the format the streamed results.csv always had), signs, exponents, inf and NaN
    import io

    from hydroline.engine.result import csv_rows
    rng = np.random.default_rng(3)
    rows = rng.normal(size=(57, 9)) * 10.0 ** rng.integers(-12, 12, size=(57, 9))
    rows[3, 2], rows[5, 0], rows[7, 7] = np.nan, np.inf, -0.0
    f = io.StringIO()
    np.savetxt(f, rows, fmt="%.9g", delimiter=",")
    assert csv_rows(rows) == f.getvalue()


class _Sink:
    """Records the blocks it is given; raises on the ``fail``-th."""

    def __init__(self, fail=None):
        self.seen, self.fail = [], fail

    def write(self, t, X, Y, model, p):
        if self.fail is not None and len(self.seen) + 1 == self.fail:
            raise OSError("disk full")
        self.seen.append((t[0], p[0]))


def test_row_writer_keeps_the_order_and_the_parameters_of_each_block():
    from hydroline.engine.integrate import RowWriter
    sink = _Sink()
    w = RowWriter(sink, depth=1)
    p = np.zeros(1)
    for k in range(50):
        p[0] = k   # changed in place after each block, as a sampled controller does
        w.write(np.array([float(k)]), None, np.zeros((1, 1)), None, p)
    w.close()
    assert sink.seen == [(float(k), float(k)) for k in range(50)]


def test_row_writer_raises_a_sink_error_in_the_caller():
    from hydroline.engine.integrate import RowWriter
    w = RowWriter(_Sink(fail=3))
    with pytest.raises(OSError, match="disk full"):
        for k in range(100):
            w.write(np.array([float(k)]), None, np.zeros((1, 1)), None, np.zeros(1))
        w.close()
    w.close()   # the error is raised once; closing again is harmless


def test_an_observer_error_ends_a_streamed_run():
    def observe(t, table, columns):
        if t[-1] > 0.05:
            raise ValueError("observer failed")

    with pytest.raises(ValueError, match="observer failed"):
        simulate(None, "closed-loop-sine", t_end=0.2, dt_out=1e-3, chunk_rows=10,
                 keep_columns=[], observe=observe)


def test_statistics_of_chosen_columns_are_those_of_every_row():
    """stats_columns: min/max/mean/rms of only these columns, from every row (numpy's on the
    run kept in memory), the other columns without statistics."""
    full = simulate(None, t_end=0.05)
    kept = simulate(None, t_end=0.05, keep_columns=["piston_position"],
                    stats_columns=["supply_port_pressure", "return_port_pressure"])
    stats = kept.metadata["stream_stats"]
    assert list(stats.index) == ["supply_port_pressure", "return_port_pressure"]
    for k in stats.index:
        p = full[k]
        assert stats.loc[k, "min"] == p.min() and stats.loc[k, "max"] == p.max()
        assert stats.loc[k, "mean"] == pytest.approx(p.mean(), rel=1e-12)
        assert stats.loc[k, "rms"] == pytest.approx(np.sqrt(np.mean(p**2)), rel=1e-12)


def test_long_cli_run_warns_of_gas_release_as_the_in_memory_run(tmp_path, monkeypatch, capsys):
    """The CLI's long-run path keeps statistics of the watched pressures only: with a
    gas-release pressure of 1 MPa (the return port's ringing after the step dips below) it
    warns of the same pressures, with the same lowest values, as the run kept in memory
    (which also says when)."""
    import json
    import re
    from importlib import resources

    from hydroline.cli import main
    from hydroline.cli import simulate as cli_simulate

    text = resources.files("hydroline.rigs").joinpath("ayalew2005.toml").read_text()
    rig = tmp_path / "rig.toml"
    rig.write_text(re.sub(r'gas_release_pressure = "[^"]*"', 'gas_release_pressure = "1 MPa"',
                          text))

    def warned():
        assert main(["simulate", str(rig), "--json"]) == 0
        out = json.loads(capsys.readouterr().out)["warnings"]
        return {w.split()[0]: re.search(r"lowest ([-0-9.e+]+) MPa", w).group(1) for w in out}

    short = warned()
    monkeypatch.setattr(cli_simulate, "LONG_ROWS", 100)
    long = warned()
    assert "return_port_pressure" in short
    assert long == short
