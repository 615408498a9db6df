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
    (["fit", "data.csv", "--json"], True),
    (["fit", "-h"], False),
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


# ---- what the figures say (issue 26 item 6) ---------------------------------------------------

def test_time_axis_unit_follows_the_length_shown():
    from hydroline.plotting import format_time, time_axis

    assert time_axis(0.25) == (1e3, "ms") and time_axis(2.0) == (1e3, "ms")
    assert time_axis(20.0) == (1.0, "s") and time_axis(600.0) == (1.0, "s")
    assert time_axis(3600.0) == (pytest.approx(1 / 60), "min")
    assert time_axis(86400.0) == (pytest.approx(1 / 3600), "h")
    assert format_time(0.113, "ms") == "113 ms" and format_time(0.113, "s") == "0.113 s"


def test_ratio_units_of_the_magnitude_labels():
    from hydroline.plotting import ratio_unit

    assert ratio_unit("Pa", "Pa") == "-"
    assert ratio_unit("Pa", "m^3/s") == "Pa/(m^3/s)"
    assert ratio_unit("m^3/s", "Pa") == "(m^3/s)/Pa"
    assert ratio_unit("m/s", "mA") == "(m/s)/mA"


def _step_run(t_end, n=4001):
    """A synthetic open-loop step: the valve steps at 10 ms, the piston reaches its stop at
    113 ms; after it the bottom chamber pressure climbs to 20 MPa, off the window's range."""
    t = np.linspace(0.0, t_end, n)
    after = t > 0.113
    p = 20.7e6 - 1e6 * np.sin(2 * np.pi * 40 * t) * (t > 0.01)
    bottom = np.where(after, 20e6, 12e6 + 0.5e6 * np.sin(2 * np.pi * 40 * t))
    meta = {"metrics_window": (0.01, 0.113, "stop"), "t_disturbance": 0.01,
            "scenario": "open-loop-step"}
    return Traces(t, {"supply_port_pressure": p, "return_port_pressure": p / 10,
                      "bottom_chamber_pressure": bottom, "top_chamber_pressure": bottom / 2,
                      "piston_velocity": np.where(after, 0.0, 1.0)}, meta)


def _texts(fig):
    out = [t.get_text() for t in fig.texts]
    for ax in fig.axes:
        out += [t.get_text() for t in ax.texts]
        out.append(ax.get_xlabel())
    for legend in fig.legends:
        out += [t.get_text() for t in legend.get_texts()]
    return out


def test_a_long_step_run_is_drawn_in_seconds_with_grey_explained():
    """A 20 s run: the time axis in s, every tick label inside the figure (none clipped),
    the legend saying what grey means, and the grey chamber pressure that ends off the
    window's y-range written at the panel's edge (else it would vanish)."""
    from hydroline.plotting import OUTSIDE_WINDOW_LABEL, plot_result

    fig = plot_result(_step_run(20.0))
    texts = _texts(fig)
    assert "time [s]" in texts and "time [ms]" not in texts
    assert any(t.startswith(OUTSIDE_WINDOW_LABEL) for t in texts)
    assert any("piston at its stop (0.113 s)" in t for t in texts)
    assert any("off scale" in t and "20 MPa" in t for t in texts)
    renderer = fig.canvas.get_renderer()
    fig.draw(renderer)
    frame = fig.bbox
    for ax in fig.axes:
        for label in ax.get_xticklabels() + ax.get_yticklabels():
            if label.get_visible() and label.get_text():
                box = label.get_window_extent(renderer)
                assert frame.x0 <= box.x0 and box.x1 <= frame.x1, label.get_text()


def test_value_labels_overlap_nothing():
    """Crowded points (two curves meeting, points at the panel's right edge): each label
    keeps clear of the others, of every marker and of the panel's edges."""
    from hydroline.plotting import place_value_labels

    fig = new_figure((5, 3))
    ax = fig.subplots()
    L = np.array([0.0, 0.75, 1.52, 2.29, 3.05])
    a, b = np.array([0.0, 0.56, 0.97, 1.02, 1.00]), np.array([0.0, 0.65, 0.89, 0.93, 0.94])
    ax.plot(L, a, "o-")
    ax.plot(L, b, "o-")
    ax.set_xlim(-0.2, 3.4)
    ax.set_ylim(-0.07, 1.2)
    labels = [(x, y, f"{y:.2f}", "C0") for x, y in zip(L, a)] + \
             [(x, y, f"{y:.2f}", "C1") for x, y in zip(L, b)]
    placed = place_value_labels(ax, labels)
    renderer = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(renderer) for t in placed]
    frame = ax.get_window_extent(renderer)
    for i, box in enumerate(boxes):
        assert frame.contains(box.x0, box.y0) and frame.contains(box.x1, box.y1)
        assert not any(box.overlaps(other) for other in boxes[i + 1:])
        for line in ax.get_lines():
            for x, y in ax.transData.transform(np.column_stack(line.get_data())):
                assert not box.contains(x, y)


def test_the_progress_bar_ends_once(monkeypatch):
    """The integrator reports 100 % after its last chunk and again at the segment's end: the
    bar's last line is drawn once."""
    import io

    from hydroline.cli.common import progress_printer

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    err = Terminal()
    monkeypatch.setattr(sys, "stderr", err)
    show = progress_printer("simulating")
    for f in (0.0, 0.5, 1.0, 1.0):
        show(f)
    assert err.getvalue().count("100.0 %") == 1 and err.getvalue().endswith("100.0 %\n")


def test_speed_is_said_as_faster_or_slower_than_real_time():
    from hydroline.cli.simulate import speed_against_real_time

    assert speed_against_real_time(1.0, 0.1) == "10.0x faster than real time"
    assert speed_against_real_time(0.25, 1.0) == "4.0x slower than real time"


def _layout_figure_args(durations=(0.1, 0.1, 0.1)):
    """A layout figure's arguments from made-up runs: decaying rings after a step at 10 ms,
    the piston's stop at 80 ms."""
    runs, summaries = [], []
    for f, t_end in zip((40.0, 65.0, 90.0), durations):
        t = np.linspace(0.0, t_end, 400)
        ring = np.where(t > 0.01, np.sin(2 * np.pi * f * (t - 0.01)) * np.exp(-25 * t), 0.0)
        runs.append(Traces(t, {"supply": 2.0e7 + 3e5 * ring, "return": 3e5 - 1e5 * ring},
                           {"t_disturbance": 0.01, "metrics_window": (0.01, 0.08, "stop")}))
        summaries.append({side: {"frequency_hz": f, "amplitude_mpa": 0.3 * f / 90,
                                 "first_excursion_mpa": 0.4, "settling_time_s": 0.04,
                                 "settling_method": "measured"} for side in ("supply", "return")})
    return dict(lengths=[3.0, 1.5, 0.0], runs=runs, summaries=summaries,
                wave_speeds={"supply": 1200.0, "return": 1150.0}, sides=("supply", "return"),
                title="layout figure, rows made beforehand")


@pytest.mark.parametrize("durations", [(0.1, 0.1, 0.1), (0.1, 0.1, 2.5)],
                         ids=["same time unit", "the last run longer: another unit"])
def test_layout_rows_made_beforehand_draw_the_same_figure(tmp_path, durations):
    """The layout figure's trace rows made while the runs go on (in a figure process, as the
    command does, and in this one) give the PNG drawn at once, byte for byte; where the rows
    were made in another time unit than the whole study's they are not used."""
    from hydroline.cli.figure_process import FigureProcess
    from hydroline.plotting import plot_layout, prepare_layout_row

    args = _layout_figure_args(durations)
    plot_layout(**args, path=tmp_path / "at_once.png")
    prepared = {}
    for r in range(2):
        prepare_layout_row(prepared, 3, r, args["lengths"][r], args["runs"][r],
                           args["summaries"][r])
    assert prepared["layout"]["rows"] == 2
    fig = plot_layout(**args, path=tmp_path / "here.png", prepared=prepared)
    assert (fig is prepared["layout"]["fig"]) == (durations[-1] < 2.0)   # (used where it fits)
    figures = FigureProcess()
    for r in range(3):
        figures.prepare(prepare_layout_row, 3, r, args["lengths"][r], args["runs"][r],
                        args["summaries"][r])
    figures.submit(plot_layout, **args, path=str(tmp_path / "child.png"))
    figures.wait()
    png = (tmp_path / "at_once.png").read_bytes()
    assert (tmp_path / "here.png").read_bytes() == png
    assert (tmp_path / "child.png").read_bytes() == png


def test_a_wrapped_title_has_lines_of_about_equal_length():
    """A title one word too long for a line is broken into two lines of about half its length
    (not a full line and a last word alone), no line wider than the figure allows, no word
    lost; a title that fits stays one line."""
    from hydroline.plotting import wrap_title

    title = ("Section II layout study: open-loop-step on Ayalew & Kulakowski (2005) "
             "fatigue-test system (sections II of supply and return set)")
    allowed = int(0.95 * 11 * 72 / (0.55 * 11))          # wrap_title's characters per line
    assert len(title) > allowed
    lines = wrap_title(title, 11, 11).split("\n")
    assert len(lines) == 2 and max(len(line) for line in lines) <= allowed
    assert abs(len(lines[0]) - len(lines[1])) <= 12
    assert " ".join(lines) == title
    assert wrap_title("a short title", 11, 11) == "a short title"
