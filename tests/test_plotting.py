"""The simulate figure's drawing path: lines drawn through their extremes per pixel column
(against a hand computation and against the picture drawn from every point), the plain
container the figure process receives, and when the command starts that process early."""
import os
import subprocess
import sys

import numpy as np
import pytest

from hydroline.cli import draws_a_figure
from hydroline.plotting import Traces, column_envelope, new_figure


def test_envelope_keeps_each_columns_min_and_max_by_hand():
    # 12 points over 3 pixel columns of [0, 12): x 0-3, 4-7, 8-11
    y = [0, 5, -1, 2, 3, 3, 9, -4, 7, 1, 1, 8]
    i = column_envelope(np.arange(12.0), y, 0.0, 12.0, 2)   # 6 points per column of x 0-5, 6-11
    # column 0: first 0, max 5 (1), min -1 (2), last 3 (5); column 1: first 9 (6), min -4 (7),
    # max 9 (6), last 8 (11)
    assert i.tolist() == [0, 1, 2, 5, 6, 7, 11]
    # 3 columns (x 0-3, 4-7, 8-11), 4 points each: kept whole (no more than 4 per column)
    assert column_envelope(np.arange(12.0), y, 0.0, 12.0, 3).tolist() == list(range(12))
    # 13 points over 3 columns (x 0-4.33, ...): column 2 (9-12) has min 1 at 9 and 10 (the
    # first kept); first points 0, 5, 9, last 4, 8, 12
    y13 = y + [6]
    i = column_envelope(np.arange(13.0), y13, 0.0, 13.0, 3)
    # column 0 (x 0-4): first 0, max 5 (1), min -1 (2), last 4; column 1 (5-8): first 5,
    # max 9 (6), min -4 (7), last 8; column 2 (9-12): first/min 9, max 8 (11), last 12
    assert i.tolist() == [0, 1, 2, 4, 5, 6, 7, 8, 9, 11, 12]


def test_envelope_per_column_extremes_on_a_long_trace():
    rng = np.random.default_rng(3)
    x = np.sort(rng.uniform(0.0, 250.0, 50_000))
    y = np.sin(2 * np.pi * 0.03 * x) + 0.2 * rng.normal(size=x.size)
    columns = 766
    i = column_envelope(x, y, 0.0, 250.0, columns)
    assert i[0] == 0 and i[-1] == x.size - 1 and np.all(np.diff(i) > 0)
    assert i.size <= 4 * columns
    pixel = np.minimum((x * columns / 250.0).astype(int), columns - 1)
    for col in np.unique(pixel)[::37]:
        here = pixel == col
        kept = here[i]
        assert y[i][kept].min() == y[here].min() and y[i][kept].max() == y[here].max()
        first, last = np.flatnonzero(here)[[0, -1]]
        assert first in i and last in i


def test_envelope_leaves_short_or_non_finite_lines_alone():
    x = np.arange(100.0)
    assert column_envelope(x, np.sin(x), 0.0, 100.0, 25).tolist() == list(range(100))
    y = np.sin(x)
    y[40] = np.nan
    assert column_envelope(x, y, 0.0, 100.0, 10).size == 100


def _pixels(x, y, width_px):
    fig = new_figure((width_px / 100, 1.5))
    ax = fig.add_axes((0, 0, 1, 1))
    ax.plot(x, y, lw=1.0)
    ax.set_xlim(x[0], x[-1])
    ax.set_ylim(-1.6, 1.6)
    ax.axis("off")
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(int)


def _ink_extent(pixels):
    """Per pixel column the top and bottom rows with ink (darker than 64 below white)."""
    ink = (255 - pixels).max(axis=-1) > 64
    return np.argmax(ink, axis=0), ink.shape[0] - 1 - np.argmax(ink[::-1], axis=0)


def _within_a_column(a, b, op):
    """Each column's value of ``a`` reached by ``b`` in that column or a neighbour."""
    padded = np.pad(b, 1, mode="edge")
    near = op(op(padded[:-2], padded[1:-1]), padded[2:])
    return np.all(op(a, near) == near)


@pytest.mark.parametrize("n", [3000, 40_000])
def test_envelope_draws_the_same_picture(n):
    """A noisy oscillation drawn 300 px wide from every point and from its envelope: in every
    pixel column the ink reaches the same highest and lowest rows, give or take where within
    one column a peak sits (a stroke 1.4 px wide reaches into the next column); a smooth line
    gives the same pixels."""
    x = np.linspace(0.0, 1.0, n)
    y = np.sin(2 * np.pi * 7 * x) + 0.3 * np.random.default_rng(5).normal(size=x.size)
    i = column_envelope(x, y, 0.0, 1.0, 300)
    assert i.size <= 1200
    (top, bottom), (top_e, bottom_e) = (_ink_extent(_pixels(x, y, 300)),
                                        _ink_extent(_pixels(x[i], y[i], 300)))
    for a, b in ((top, top_e), (top_e, top)):
        assert _within_a_column(a, b, np.minimum)
    for a, b in ((bottom, bottom_e), (bottom_e, bottom)):
        assert _within_a_column(a, b, np.maximum)
    smooth = np.sin(2 * np.pi * 7 * x)
    i = column_envelope(x, smooth, 0.0, 1.0, 300)
    assert i.size < x.size
    full, envelope = _pixels(x, smooth, 300), _pixels(x[i], smooth[i], 300)
    assert np.abs(full - envelope).max() <= 40      # antialiasing levels only


def test_traces_read_like_a_result():
    t = np.linspace(0.0, 1.0, 5)
    tr = Traces(t, {"a": 2 * t, "b": [1, 2, 3, 4, 5]}, {"scenario": "x"})
    assert tr.columns == ["a", "b"] and "a" in tr and "c" not in tr
    assert tr["b"].dtype == float and tr["a"][-1] == 2.0 and tr.metadata == {"scenario": "x"}


@pytest.mark.parametrize("argv, expected", [
    (["simulate"], True),
    (["simulate", "rig.toml", "--t-end", "1 s"], True),
    (["simulate", "--json", "--out", "d"], True),
    (["simulate", "--json", "--out=d"], True),
    (["simulate", "--json"], False),
    (["simulate", "--help"], False),
    (["sweep", "--set", "a=1"], False),
    ([], False),
])
def test_which_command_lines_start_the_figure_process_early(argv, expected):
    assert draws_a_figure(argv) is expected


@pytest.mark.skipif(not hasattr(os, "fork"), reason="the figure process needs os.fork")
def test_figure_process_draws_without_the_model(tmp_path):
    """The figure process, forked at the command's start, draws the figure it is handed
    without importing the model (CasADi) or Matplotlib's 3-D projection (marked absent: None
    in sys.modules); the PNG is complete when the command returns."""
    report = tmp_path / "modules.txt"
    code = (
        "import sys\n"
        "import hydroline.plotting as plotting\n"
        "draw = plotting.plot_result\n"
        "def plot_and_report(*args, **kwargs):\n"
        "    draw(*args, **kwargs)\n"
        "    loaded = sorted(k for k, m in sys.modules.items() if m)\n"
        f"    open({str(report)!r}, 'w').write(' '.join(loaded))\n"
        "plotting.plot_result = plot_and_report\n"
        "from hydroline.cli import main\n"
        "sys.exit(main(['simulate', '--json', '--t-end', '0.03 s', '--out', "
        f"{str(tmp_path)!r}]))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    loaded = set(report.read_text().split())
    assert "matplotlib.figure" in loaded
    assert not {"casadi", "hydroline.engine", "mpl_toolkits.mplot3d"} & loaded
    assert (tmp_path / "pressures.png").read_bytes().endswith(b"IEND\xaeB`\x82")


_DRAW_AFTER_IMPORT = """
import hashlib, sys
import numpy as np
if sys.argv[1] == "skipped":
    from hydroline.cli.figure_process import import_matplotlib
    import_matplotlib()
import matplotlib.artist as artist
from matplotlib.lines import Line2D
from hydroline.plotting import new_figure
fig = new_figure((4, 3))
ax = fig.subplots()
line, = ax.plot(np.linspace(0, 1, 50), np.sin(np.linspace(0, 6, 50)), label="sine")
line.set(color="r", linewidth=2.0)                  # set() of an artist imported under it
ax.set(xlabel="time [s]", title="t")
ax.legend(loc="best")
fig.canvas.draw()
class Probe(artist.Artist):                         # defined after: full help text again
    def set_probe_value(self, value):
        pass
print(hashlib.sha256(bytes(fig.canvas.buffer_rgba())).hexdigest(),
      "probe_value" in str(Probe.set.__signature__),
      "agg_filter" in artist.kwdoc(Line2D), "__signature__" in vars(Line2D.set))
"""


def test_figure_process_import_skips_only_help_text():
    """The figure process imports Matplotlib without writing its artists' help text: the same
    pixels as after Matplotlib's own import, ``set()`` works, and the hooks are restored after
    the import (a class defined later gets its signature, kwdoc its table)."""
    out = {}
    for how in ("plain", "skipped"):
        proc = subprocess.run([sys.executable, "-c", _DRAW_AFTER_IMPORT, how],
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
        out[how] = proc.stdout.split()
    assert out["skipped"][0] == out["plain"][0]                   # the same pixels
    assert out["plain"][1:] == ["True", "True", "True"]
    assert out["skipped"][1:] == ["True", "True", "False"]        # Line2D.set: not written
