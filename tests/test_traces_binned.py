"""BinnedEnvelope: per time bin min/mean/max from every row, fed block by block (issue 26)."""
import numpy as np
import pytest

from hydroline.traces import BinnedEnvelope


def _signal(n=200_003, seed=3):
    # a 2 Hz sine with a 40 Hz ripple and noise at 0.1 ms rows (uneven start: not on bin edges)
    rng = np.random.default_rng(seed)
    t = 0.01 + 1e-4 * np.arange(n)
    a = np.sin(2 * np.pi * 2 * t) + 0.1 * np.sin(2 * np.pi * 40 * t) + 0.01 * rng.standard_normal(n)
    b = 0.5 * np.cos(2 * np.pi * 2 * t) + 1e-3 * t
    return t, np.column_stack([b, a, -a])


def _fed(env, t, table, columns, blocks):
    cuts = np.unique(np.r_[0, blocks, len(t)])
    for i, j in zip(cuts[:-1], cuts[1:]):
        env.update(t[i:j], table[i:j], columns)
    return env


def test_bands_equal_numpy_per_bin_whatever_the_blocks():
    t, table = _signal()
    columns = ["b", "a", "minus_a"]
    bins = 137
    rng = np.random.default_rng(1)
    blocks = np.sort(rng.integers(0, len(t), 40))   # uneven blocks, some within one bin
    env = _fed(BinnedEnvelope(["a", "b"], t[0], t[-1], bins=bins, differences={"d": ("a", "b")}),
               t, table, columns, blocks)
    # independent: the bins by np.digitize, each bin's rows reduced by NumPy
    edges = np.linspace(t[0], t[-1], bins + 1)
    k = np.clip(np.digitize(t, edges) - 1, 0, bins - 1)
    tm, lo, mean, hi = env.bands()
    assert len(tm) == bins
    np.testing.assert_allclose(tm, 0.5 * (edges[:-1] + edges[1:]))
    series = {"a": table[:, 1], "b": table[:, 0], "d": table[:, 1] - table[:, 0]}
    for name, y in series.items():
        want_lo = np.array([y[k == i].min() for i in range(bins)])
        want_hi = np.array([y[k == i].max() for i in range(bins)])
        want_mean = np.array([y[k == i].mean() for i in range(bins)])
        np.testing.assert_array_equal(lo[name], want_lo)      # min/max: exact
        np.testing.assert_array_equal(hi[name], want_hi)
        # a mean of ~1500 values summed in another order: a few ulps of the values' size
        np.testing.assert_allclose(mean[name], want_mean, rtol=0, atol=1e-12)


def test_tail_is_the_last_rows_and_memory_is_bounded():
    t, table = _signal(n=50_000)
    columns = ["b", "a", "minus_a"]
    env = BinnedEnvelope(["minus_a"], t[0], t[-1], bins=50, tail_rows=777)
    sizes = []
    for i in range(0, len(t), 300):   # blocks shorter than the tail
        env.update(t[i:i + 300], table[i:i + 300], columns)
        sizes.append(sum(len(p[0]) for p in env.tail_parts))
    tt, values = env.tail()
    np.testing.assert_array_equal(tt, t[-777:])
    np.testing.assert_array_equal(values["minus_a"], table[-777:, 2])
    assert max(sizes) < 777 + 300            # the tail held: its rows and one block at most
    assert env.lowest.shape == (50, 1)       # per bin and column, whatever the rows
    big = BinnedEnvelope(["a"], t[0], t[-1], bins=50, tail_rows=10)
    big.update(t, table, columns)            # one block longer than the tail
    np.testing.assert_array_equal(big.tail()[0], t[-10:])


def test_bins_without_rows_are_left_out_and_bad_bounds_refused():
    env = BinnedEnvelope(["y"], 0.0, 10.0, bins=10)
    env.update(np.array([0.5, 0.7, 9.99, 10.0, 12.0]), np.array([[1.0], [3.0], [5.0], [7.0], [9.0]]),
               ["y"])
    tm, lo, mean, hi = env.bands()
    np.testing.assert_allclose(tm, [0.5, 9.5])   # rows at and after t_end count in the last bin
    np.testing.assert_array_equal(lo["y"], [1.0, 5.0])
    np.testing.assert_array_equal(hi["y"], [3.0, 9.0])
    np.testing.assert_allclose(mean["y"], [2.0, 7.0])
    with pytest.raises(ValueError, match="t_end"):
        BinnedEnvelope(["y"], 1.0, 1.0)


def test_long_run_figure_draws_the_band_and_the_tail(tmp_path):
    from hydroline.plotting import Traces, plot_long_run

    t, table = _signal(n=60_000)
    columns = ["supply_port_pressure", "piston_velocity", "x"]
    env = BinnedEnvelope(columns[:2], t[0], t[-1], bins=12, tail_rows=5000)
    env.update(t, table, columns)
    tm, lo, mean, hi = env.bands()
    tail_t, tail = env.tail()
    fig = plot_long_run(Traces(tm, lo), Traces(tm, mean, {"run": (t[0], t[-1])}), Traces(tm, hi),
                        Traces(tail_t, tail, {"label": "the last 0.5 s"}),
                        path=tmp_path / "long.png")
    assert (tmp_path / "long.png").stat().st_size > 0
    axes = fig.axes
    assert len(axes) == 4                        # two panels, envelope and tail side by side
    band = axes[0].collections[0].get_paths()[0].vertices[:, 1] * 1e6   # [MPa] -> [Pa]
    np.testing.assert_allclose([band.min(), band.max()], [table[:, 0].min(), table[:, 0].max()])
    assert axes[1].get_title() == "the last 0.5 s"
    np.testing.assert_allclose(axes[1].get_xlim(), (0, (tail_t[-1] - tail_t[0]) * 1e3))   # [ms]
