"""``hydroline simulate``: run a scenario on a rig; CSV, JSON summary and the pressure figure."""
from __future__ import annotations

import contextlib
import sys

from .common import (SCHEMA_VERSION, add_settling_band_option, add_solver_option,
                     amplitude_cell, atomic_outputs,
                     dump_json, note_cost, out_dir, print_table, progress_printer, quantity,
                     settling_cell, settling_legend)
from .figure_process import claim_figure_process

#: The files written to --out.
OUTPUT_FILES = ("results.csv", "summary.json", "pressures.png")
#: --format -> the time-series file it writes (SimulationResult.to_csv / to_parquet / to_mat).
RESULT_FILES = {"csv": "results.csv", "parquet": "results.parquet", "mat": "results.mat"}

#: The built-in experiments (:data:`hydroline.scenarios.SCENARIOS`, named here so that the
#: parser is built without importing the model: the figure process forks before that import).
BUILTIN_SCENARIOS = ("open-loop-step", "closed-loop-sine", "position-step")


def register(sub):
    """Add the ``hydroline simulate`` subcommand and its options to the command's parser.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers object of the ``hydroline`` parser
        (from ``add_subparsers``); ``run`` is set as the
        subcommand's ``func``
    """
    p = sub.add_parser("simulate", help="simulate the test system (default: the 2005 paper's rig, "
                       "50 mA open-loop step)",
                       description="Simulate a rig from its solved steady state. Writes results.csv, "
                       "summary.json and pressures.png to --out and prints a summary.")
    p.add_argument("rig", nargs="?", help="rig TOML file or the name of a shipped rig, e.g. "
                   "two_axis (default: the embedded Ayalew & Kulakowski 2005 rig)")
    p.add_argument("--scenario", default=None, metavar="NAME",
                   help=f"experiment: {', '.join(BUILTIN_SCENARIOS)} or one the rig defines "
                   f"([scenario.NAME] type = \"axis-commands\") (default: the rig's "
                   f"rig.scenario, else open-loop-step)")
    p.add_argument("--t-end", help="simulated time with unit, e.g. '0.25 s' (scenario default)")
    p.add_argument("--out", help="output folder (default: hydroline-out; with --json no files "
                   "are written unless --out is given)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout "
                   "(and write the files only when --out is given)")
    p.add_argument("--dt-out", help="interval of the rows written to results.csv, with unit, "
                   "e.g. '1 ms' (default: every 0.1 ms output row, or on a long run the finest "
                   "of 0.2, 0.5, 1, 2, 5 ms, ... that keeps the file under about 200 MB, with "
                   "a note; '0.1 ms' writes every row; the summary always uses every 0.1 ms "
                   "row)")
    p.add_argument("--format", default="csv", choices=tuple(RESULT_FILES),
                   help="time-series file: csv (results.csv, units in the header; default), "
                   "parquet (results.parquet, units in its metadata: pandas.read_parquet(...)"
                   ".attrs['units']; needs pyarrow) or mat (results.mat for MATLAB: one "
                   "variable per signal, the struct 'units'); hydroline fit reads all three")
    add_solver_option(p)
    add_settling_band_option(p)
    p.set_defaults(func=run)


def json_summary(summary: dict) -> dict:
    """The ``--json`` document, also what ``summary.json`` holds: ``schema_version`` then every
    key of the summary (:func:`hydroline.summarize`), nested as it is: per port every metric
    and note, the metrics window and its note, the warnings, the experiment's own metrics
    (tracking error and ripple of the closed-loop sine) and, on a multi-axis rig, the same
    per axis under ``"axes"``. Documented in docs/summary.schema.json. NaN and infinities
    (a metric that does not exist) are written as null by :func:`dump_json`.

    Parameters
    ----------
    summary : dict
        :func:`hydroline.summarize` of a run.

    Returns
    -------
    dict
        ``{"schema_version": SCHEMA_VERSION, **summary}`` (the summary is not modified).
    """
    return {"schema_version": SCHEMA_VERSION, **summary}


#: Output interval of the integration, [s]: what the summary's metrics are computed from.
DT_OUT = 1e-4
#: Output rows above which a run is long: kept in memory only in the columns the summary needs
#: and streamed to results.csv as it goes (the full table of ~90 columns would take 140 MB).
LONG_ROWS = 200_000
#: Columns the summary needs at every output row, and the figure's (a decimated copy).
SUMMARY_COLUMNS = ("supply_port_pressure", "return_port_pressure", "piston_position")
#: Time bins of a long run's figure: per bin the lowest, mean and highest value of each trace,
#: from every row (:class:`hydroline.traces.BinnedEnvelope`), [-].
FIGURE_BINS = 1500
#: Command cycles at the end of a long closed-loop sine drawn at full rate beside the envelope,
#: [-]; another long run shows its last :data:`TAIL_SECONDS` so.
TAIL_CYCLES = 2
TAIL_SECONDS = 0.5
FIGURE_COLUMNS = ("supply_port_pressure", "return_port_pressure", "bottom_chamber_pressure",
                  "top_chamber_pressure", "piston_velocity", "piston_position")


#: How the summary names an integrator other than the compiled BDF (``metadata["solver"]``):
#: ``solver="auto"`` takes Radau IIA where the hoses' modes cap the BDF (docs/engine.md)
INTEGRATOR_NAMES = {"radau": ", Radau IIA", "cvodes": ", CVODES", "scipy": ", SciPy"}


def speed_against_real_time(simulated: float, wall: float) -> str:
    """How fast a run went against the time it simulated, in words: ``"10.1x faster than
    real time"`` or ``"3.2x slower than real time"``.

    Parameters
    ----------
    simulated : float
        Simulated time, [s]
    wall : float
        Wall-clock time it took, [s]

    Returns
    -------
    str
    """
    ratio = simulated / max(wall, 1e-9)
    if ratio >= 1.0:
        return f"{ratio:.1f}x faster than real time"
    return f"{1.0 / max(ratio, 1e-12):.1f}x slower than real time"


def output_grid(t_end: float, dt_out: float | None):
    """(integration output interval [s], write every n-th row, rows written) for --dt-out.

    Parameters
    ----------
    t_end : float
        Simulated time, [s]
    dt_out : float
        Interval of the rows written, [s] (None: every 0.1 ms row)

    Returns
    -------
    tuple
        ``(h, every, rows)``: integration output interval [s], write every ``every``-th
        row [-], rows written [-].
    """
    if dt_out is None:
        return DT_OUT, 1, int(round(t_end / DT_OUT)) + 1
    every = max(1, int(-(-dt_out // DT_OUT)))   # ceil: the summary's rows no coarser than DT_OUT
    h = dt_out / every
    n = int(round(t_end / h))
    return h, every, n // every + 1 + (n % every != 0)


#: Most bytes a run writes without being asked (no --dt-out): beyond it the written rows are
#: decimated (:func:`written_interval`), [B]. Counted at the CSV's bound of
#: :data:`hydroline.limits.CSV_BYTES_PER_VALUE` per value for every format, so that each
#: format holds the same rows (Parquet and MAT files are then about half of it).
WRITE_BYTES = 200e6
#: Coarsest interval a long run's written rows are decimated to by default, [s]: a run whose
#: file would pass :data:`WRITE_BYTES` even so (days of simulated time) writes more, and is
#: refused when it would not fit on the disk.
COARSEST_WRITTEN = 1.0


def written_interval(t_end: float, n_columns: int, limit: float | None = None):
    """The interval of the rows a run writes when --dt-out is not given: every output row
    (None) while the file stays within ``limit``, else the finest of 0.2, 0.5, 1, 2, 5, 10 ms,
    ... (multiples of :data:`DT_OUT`) that does, at most :data:`COARSEST_WRITTEN`.

    Parameters
    ----------
    t_end : float
        Simulated time, [s].
    n_columns : int
        Columns written (time, signals and states), [-].
    limit : float
        Most bytes to write, [B] (None: :data:`WRITE_BYTES`).

    Returns
    -------
    float or None
        The interval, [s]; None: every :data:`DT_OUT` row.
    """
    from ..limits import CSV_BYTES_PER_VALUE

    limit = WRITE_BYTES if limit is None else limit

    def size(dt):
        return (int(round(t_end / dt)) + 1) * n_columns * CSV_BYTES_PER_VALUE

    if size(DT_OUT) <= limit:
        return None
    decade = 1
    while True:
        for step in (2, 5, 10):
            dt = step * decade * DT_OUT
            if size(dt) <= limit or dt >= min(t_end, COARSEST_WRITTEN) * (1 - 1e-9):
                return min(dt, COARSEST_WRITTEN)
        decade *= 10


def _bytes(n: float) -> str:
    return f"{n / 1e9:.3g} GB" if n >= 1e9 else f"{n / 1e6:.0f} MB"


def run(args) -> int:
    """Run ``hydroline simulate``: a scenario on a rig from its solved steady state; the
    summary printed (or as JSON), results.csv, summary.json and pressures.png written.

    Bad input raises a ``ValueError`` (or one of its kind) whose one-line message
    :func:`hydroline.cli.main` prints.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line, with the options :func:`register` adds

    Returns
    -------
    int
        Exit code, 0 on success
    """
    write = args.out is not None or not args.json
    # Matplotlib (and NumPy) import in a second process while this one imports the model and
    # simulates: on two cores the figure costs what the longer branch costs, not the sum. It
    # was forked when the command started (hydroline.cli.main), before the arguments were read
    figures = claim_figure_process() if write else None
    try:
        return _prepare(args, write, figures)
    finally:
        if figures is not None:
            figures.cancel()


def _prepare(args, write, figures) -> int:
    from ..limits import CSV_BYTES_PER_VALUE, MAX_TABLE_BYTES, check_output_size, output_estimate
    from ..rigs import load_rig
    from ..rigs.parameters import defaults_used
    from ..scenarios.experiments import build_scenario, default_scenario, scenario_names
    from ..traces.metrics import SettlingBand

    rig = load_rig(args.rig)
    args.settling_band = SettlingBand.parse(args.settling_band)   # refused before the run
    t_end = quantity(args.t_end, "s", "--t-end") if args.t_end else None
    if t_end is not None and not t_end > 0:
        raise ValueError(f"--t-end must be > 0 s, got {args.t_end!r}")
    dt_out = quantity(args.dt_out, "s", "--dt-out") if args.dt_out else None
    if dt_out is not None and not dt_out > 0:
        raise ValueError(f"--dt-out must be > 0 s, got {args.dt_out!r}")
    scenario = args.scenario or default_scenario(rig)
    if scenario not in scenario_names(rig):
        raise ValueError(f"{'--scenario' if args.scenario else 'rig.scenario'}: unknown "
                         f"experiment {scenario!r} (known: {', '.join(scenario_names(rig))})")
    duration = t_end or rig.get(f"scenario.{scenario}.t_end") or build_scenario(rig, scenario).t_end
    if dt_out is not None and dt_out > duration:
        raise ValueError(f"--dt-out: {args.dt_out} is longer than the run ({duration:g} s): "
                         f"results.csv would hold only its first and last rows; give at most "
                         f"{duration:g} s")
    # (the run's model, built once: its size for the estimates, then run; a rest state
    # solved before for this model and numbers is read from the cache)
    from ..scenarios.running import Simulation

    simulation = Simulation(models_kept=1, recorded_rest_states=True)
    circuit, _, network = simulation.model(rig, args.scenario, t_end)
    columns = 1 + len(network.signal_names) + len(network.state_names)
    fmt = getattr(args, "format", "csv")
    decimated = None
    if dt_out is None and write:   # a long run: the rows written decimated, and said so
        dt_out = decimated = written_interval(duration, columns)
    h, every, rows = output_grid(duration, dt_out)
    long_run = round(duration / h) + 1 > LONG_ROWS and len(circuit.axes) == 1
    name = "--t-end" if args.t_end else f"scenario.{scenario}.t_end"
    out = None
    if write:
        out = out_dir(args.out if args.out is not None else "hydroline-out",
                      (RESULT_FILES[fmt],) + OUTPUT_FILES[1:])
        if fmt == "parquet":   # refused before the run, not when its file is written
            from ..engine.result import parquet_writer

            parquet_writer(out / RESULT_FILES[fmt])
    if long_run:   # (memory bounded: streamed, or only the written rows kept)
        if write and fmt != "csv":   # the rows written are kept until the file is written
            est = output_estimate(duration, h * every, columns - 1)
            if est.memory_bytes > MAX_TABLE_BYTES:
                raise ValueError(f"--format {fmt}: {est.rows:,} rows x {columns} columns would "
                                 f"take {est.memory_bytes / 1e9:.1f} GB in memory before "
                                 f"{RESULT_FILES[fmt]} is written; give a larger --dt-out, or "
                                 f"--format csv (streamed to the file as the run goes)")
        if write:
            check_output_size(duration, h * every, columns - 1,
                              stream_to=out / RESULT_FILES[fmt], name=name)
    else:
        check_output_size(duration, h, columns - 1, csv_folder=out, name=name)
    if decimated is not None:
        full = (int(round(duration / DT_OUT)) + 1) * columns * CSV_BYTES_PER_VALUE
        kept = rows * columns * CSV_BYTES_PER_VALUE
        print(f"hydroline simulate: note: {duration:g} s at every {DT_OUT * 1e3:g} ms row "
              f"would write up to {_bytes(full)}; writing every {decimated * 1e3:g} ms row to "
              f"{RESULT_FILES[fmt]} (up to {_bytes(kept)} as CSV); the summary uses every "
              f"row; --dt-out '{DT_OUT * 1e3:g} ms' writes them all", file=sys.stderr)
    note_cost("simulate", network, args.solver, duration, rows, columns, streamed=long_run,
              write=write, dt_out=dt_out, file=RESULT_FILES[fmt])
    defaults = defaults_used(rig, scenario)
    if defaults:   # every key that changes the result is given or reported (once)
        print("hydroline simulate: note: not in the rig, defaults used: "
              + "; ".join(f"{path} = {value}" for path, value in defaults), file=sys.stderr)
    # a long run's statistics from every row: of the pressures the gas-release check reads
    from ..scenarios.running import axes_pressures

    known = set(network.signal_names) | set(network.state_names)
    watched = [k for k in axes_pressures(circuit.axes) if k in known]
    shown = [c for c in FIGURE_COLUMNS + ("position_reference",) if c in known]
    return _run(args, rig, t_end, scenario, h, every, long_run, write, out, figures, watched,
                figure_columns=shown, duration=duration, simulation=simulation)


def figure_result(res, columns=None, metadata=("metrics_window", "t_disturbance", "scenario")):
    """The columns and metadata a figure reads, as :class:`hydroline.plotting.Traces` (what is
    sent to the figure process: plain arrays, so that it does not import the model).

    Parameters
    ----------
    res : SimulationResult
        The run (or its preview)
    columns : list
        Columns to keep (those of them ``res`` has); None: what
        :func:`hydroline.plotting.plot_result` draws
    metadata : tuple
        Metadata keys to keep (those ``res`` has)

    Returns
    -------
    Traces
        Time [s] and the kept columns [SI] with the kept metadata.
    """
    from ..plotting import Traces

    if columns is None:
        columns = FIGURE_COLUMNS + ("position_reference", "piston_position")
    meta = {k: res.metadata[k] for k in metadata if k in res.metadata}
    return Traces(res.t, {c: res[c] for c in dict.fromkeys(columns) if c in res}, meta)


def figure_envelope(duration: float, h: float, columns, period: float | None = None):
    """What a long run's figure is drawn from, gathered as the rows arrive: per time bin
    (at most :data:`FIGURE_BINS` over the run; under a periodic command a whole number of its
    periods, so that a bin's mean is the cycle's and does not beat) the lowest, mean and
    highest value of each column from every row, and the last :data:`TAIL_CYCLES` command cycles (or :data:`TAIL_SECONDS`) of
    rows as they are; the tracking error too when the position and its reference are there.

    Parameters
    ----------
    duration : float
        Simulated time, [s]
    h : float
        Output interval of the rows, [s]
    columns : list[str]
        The figure's columns the run has
    period : float
        Command period, [s] (None: not a periodic command)

    Returns
    -------
    tuple
        ``(envelope, label)``: the :class:`hydroline.traces.BinnedEnvelope` (pass its
        ``update`` as ``observe`` to :func:`hydroline.simulate`) and what its last rows are,
        in words.
    """
    import numpy as np

    from ..traces import BinnedEnvelope

    span = min(TAIL_CYCLES * period if period else TAIL_SECONDS, duration)
    tracking = ("position_reference", "piston_position")
    differences = ({"tracking_error": tracking} if all(c in columns for c in tracking) else None)
    bins, t_end = FIGURE_BINS, duration
    if period:   # whole cycles per bin
        width = period * -(-duration // (period * FIGURE_BINS))
        bins = max(1, int(np.ceil(duration / width * (1 - 1e-12))))
        t_end = bins * width
    envelope = BinnedEnvelope(columns, 0.0, t_end, bins=bins,
                              tail_rows=int(round(span / h)) + 1, differences=differences)
    cycles = {1: "command cycle", 2: "two command cycles"}.get(TAIL_CYCLES,
                                                             f"{TAIL_CYCLES} command cycles")
    label = (f"the last {cycles} ({1 / period:g} Hz),\nevery {h * 1e3:g} ms row" if period
             else f"the last {span:g} s,\nevery {h * 1e3:g} ms row")
    return envelope, label


def envelope_traces(envelope, metadata: dict, label: str = "the last rows",
                    run: tuple | None = None):
    """A long run's figure data (:func:`hydroline.plotting.plot_long_run`'s arguments) from
    its :func:`figure_envelope`: plain arrays, for the figure process.

    Parameters
    ----------
    envelope : BinnedEnvelope
        The envelope gathered during the run
    metadata : dict
        The run's metadata (``metrics_window``, ``t_disturbance``, ``scenario`` are kept)
    label : str
        What the envelope's last rows are, in words (the right column's title)
    run : tuple
        First and last time of the run, [s] (None: the bins' span)

    Returns
    -------
    tuple
        ``(lowest, mean, highest, tail)``, each a :class:`hydroline.plotting.Traces`, [SI].
    """
    from ..plotting import Traces

    t, lowest, mean, highest = envelope.bands()
    tail_t, tail = envelope.tail()
    edges = envelope.edges
    meta = {k: metadata[k] for k in ("metrics_window", "t_disturbance", "scenario")
            if k in metadata}
    meta.update(bin_width=float(edges[1] - edges[0]),
                run=tuple(map(float, run)) if run else (float(edges[0]), float(edges[-1])))
    return (Traces(t, lowest), Traces(t, mean, meta), Traces(t, highest),
            Traces(tail_t, tail, {"label": label}))


def _run(args, rig, t_end, scenario, h, every, long_run, write, out, figures,
         watched=None, figure_columns=(), duration=None, simulation=None) -> int:
    from ..scenarios.running import simulate
    from ..scenarios.summaries import summarize
    from ..plotting import plot_long_run, plot_result

    # (on an error or Ctrl-C the figure process is stopped first, then the temporary files
    # are removed: a figure still being drawn would write its file again)
    fmt = getattr(args, "format", "csv")
    with (atomic_outputs(out) if write else contextlib.nullcontext()) as temp, \
            (figures if figures is not None else contextlib.nullcontext()):
        options = {}
        stream = None
        if long_run:   # bounded memory: the summary's columns in full, a preview for the figure
            keep = list(SUMMARY_COLUMNS)
            stream = _sine_summary_stream(rig, scenario, t_end)
            # (min/max/mean/rms of ~170 columns at every row cost ~1.5 s of a 10-minute run;
            # only the watched pressures' minimum is read, by the gas-release check)
            if stream is not None:
                keep.append(stream.names[3])   # the position reference
                # constant memory: the summary computed chunk by chunk as the rows arrive
                options = dict(observe=stream.update, keep_columns=[])
            else:
                options = dict(keep_columns=keep)
            if watched:
                options["stats_columns"] = watched
            if write:
                if fmt == "csv":   # written as the run goes
                    options.update(stream_to=temp("results.csv"), stream_every=every)
                    if stream is not None:
                        del options["keep_columns"]
                else:   # the rows written kept, the file written at the end
                    written = WrittenRows(every)
                    observers = [written.update] + ([stream.update] if stream else [])
                    options["observe"] = _each(observers)
                # the figure: the envelope of every row over the run, and its end at full rate
                envelope, tail_label = figure_envelope(duration, h, figure_columns,
                                           stream.period if stream is not None else None)
                options["observe"] = (_each([options["observe"], envelope.update])
                                      if "observe" in options else envelope.update)
        # (rows written to a file are a record, read back and fitted at simulate's rtol:
        # integrated at rtol throughout, as a streamed run is; a run only printed goes on
        # at simulate()'s looser tolerance after the stop, where no metric looks)
        res = simulate(rig, args.scenario, t_end, dt_out=h, solver=args.solver,
                       progress=progress_printer("simulating", not args.json),
                       after_stop_rtol=None if write else "auto", simulation=simulation,
                       **options)
        if stream is not None:
            summary = stream.summary(res)
            t0, t1 = summary["metrics_window_s"]
            res.metadata["metrics_window"] = (t0, t1, "stop" if stream.arrived else "end")
        scenario = res.metadata["scenario"]
        single = len(res.metadata.get("axes") or {}) <= 1   # (a multi-axis figure: _report_axes)
        if write and single:   # drawn by the figure process while the summary and CSV are made
            title = f"{scenario} on {rig.get('rig.name', rig.source)}"
            if long_run:
                drawn = envelope_traces(envelope, res.metadata, tail_label, (0.0, float(res.t[-1])))
                figures.submit(plot_long_run, *drawn, path=str(temp("pressures.png")), title=title)
            else:
                figures.submit(plot_result, figure_result(res), path=str(temp("pressures.png")),
                               title=title)
        if stream is None:
            summary = summarize(res, settling_band=args.settling_band)
        if write:   # replaced together, or none (previous results kept)
            if not long_run:
                getattr(res, f"to_{fmt}")(temp(RESULT_FILES[fmt]), every=every)
            elif fmt != "csv":
                getattr(written.result(res.metadata["units"]), f"to_{fmt}")(
                    temp(RESULT_FILES[fmt]))
            with open(temp("summary.json"), "w") as f:
                dump_json(json_summary(summary), f)
            if single:
                figures.wait()
    if "axes" in summary:
        return _report_axes(args, rig, res, summary, scenario, figures)
    if args.json:
        for w in summary["warnings"]:
            print(f"hydroline simulate: warning: {w}", file=sys.stderr)
        for side in ("supply", "return"):
            if summary[side].get("amplitude_note"):
                print(f"hydroline simulate: note: {side} port: {summary[side]['amplitude_note']}",
                      file=sys.stderr)
        dump_json(json_summary(summary))
        return 0
    print(f"hydroline simulate: {scenario} on {rig.get('rig.name', rig.source)}")
    print(f"  {res.metadata['n_states']} states, steady-state residual {res.steady_state.residual:.1e} 1/s, "
          f"wall time {summary['wall_time_s']:.2f} s "
          f"(the integrator{INTEGRATOR_NAMES.get(res.metadata.get('solver'), '')}: "
          f"{speed_against_real_time(res.t[-1], res.wall_time)})")
    print(f"  {summary['metrics_window_note']}")
    if scenario == "closed-loop-sine":
        rows = [[f"{side} port", summary[side].get("ripple_pp_mpa"),
                 len(summary[side].get("ripple_pp_mpa_per_cycle", []))]
                for side in ("supply", "return")]
        print_table(["pressure", "ripple peak-to-peak, largest cycle [MPa]", "full cycles"], rows)
        print(f"  tracking error (reference - position): rms {summary['tracking_error_rms_mm']:.2f} mm, "
              f"max {summary['tracking_error_max_mm']:.2f} mm")
    else:
        rows = []
        for side in ("supply", "return"):
            m = summary[side]
            rows.append([f"{side} port", m["frequency_hz"], amplitude_cell(m),
                         m["first_excursion_mpa"], m["steady_change_mpa"], m["peak_to_peak_mpa"],
                         settling_cell(m)])
        print_table(["pressure", "oscillation [Hz]", "amplitude [MPa]", "first excursion [MPa]",
                     "steady change [MPa]", "peak-to-peak [MPa]", "settling [ms]"], rows)
        print("  amplitude: half the largest swing about the pressure's one-period mean (+-); "
              "'^' near the 'no oscillation' verdict (below); first excursion: largest |p - p0|")
        print(f"  {settling_legend([(side, summary[side]) for side in ('supply', 'return')])}")
        for side in ("supply", "return"):
            m = summary[side]
            if m.get("amplitude_note"):
                print(f"  {side} port: {m['amplitude_note']}")
            if m.get("settling_note") and m.get("amplitude_mpa") is not None:
                mark = " '-'" if m["settling_time_s"] is None else ""
                print(f"  {side} port settling{mark}: {m['settling_note']}")
    print(f"  actuator hydraulic natural frequency: {summary['actuator_natural_frequency_hz']:.1f} Hz")
    for w in summary["warnings"]:
        print(f"  WARNING: {w}")
    print(f"  wrote {out / RESULT_FILES[getattr(args, 'format', 'csv')]}, {out / 'summary.json'}, "
          f"{out / 'pressures.png'}")
    return 0


class WrittenRows:
    """The rows a long run writes to a Parquet or MAT file, kept as the run goes: every
    ``every``-th output row and the last (as results.csv's streamed rows), every column.
    Pass :meth:`update` as ``observe`` to :func:`hydroline.simulate`.

    Parameters
    ----------
    every : int
        Keep every n-th output row, [-].
    """

    def __init__(self, every: int):
        self.every = max(int(every), 1)
        self.rows, self.parts, self.columns, self.last = 0, [], None, None

    def update(self, t, table, columns) -> None:
        """Take in one block of output rows.

        Parameters
        ----------
        t : numpy.ndarray
            Times of the block, [s].
        table : numpy.ndarray
            Its rows, one column per name in ``columns``, [SI].
        columns : list[str]
            The column names.
        """
        import numpy as np

        if not len(t):
            return
        t, table = np.asarray(t), np.asarray(table)
        keep = (np.arange(self.rows, self.rows + len(t)) % self.every) == 0
        self.rows += len(t)
        self.columns = columns
        if keep.any():
            self.parts.append((t[keep], table[keep]))
        # the run's last row is written too: held until a later block shows it was not
        self.last = None if keep[-1] else (t[-1:], table[-1:].copy())

    def result(self, units: dict):
        """The rows kept, and the run's last row, as a :class:`hydroline.SimulationResult`
        that writes them.

        Parameters
        ----------
        units : dict
            Column -> SI unit (the run's ``metadata["units"]``).

        Returns
        -------
        SimulationResult
        """
        import numpy as np

        from ..engine import SimulationResult

        parts = self.parts + ([self.last] if self.last is not None else [])
        self.parts, self.last = [], None   # (the blocks freed once joined: one copy held)
        times = np.concatenate([p[0] for p in parts])
        table = np.vstack([p[1] for p in parts])
        del parts
        return SimulationResult(times=times, table=table, columns=list(self.columns),
                                metadata={"units": units})


def _each(observers):
    """One ``observe`` callable that calls each of ``observers`` in turn."""
    def observe(t, table, columns):
        for f in observers:
            f(t, table, columns)
    return observe


def _sine_summary_stream(rig, scenario, t_end):
    """The summary accumulator of a long closed-loop sine on a single-axis rig (t_end [s],
    None: the experiment's own); None for any other experiment."""
    from ..scenarios.experiments import ClosedLoopSine, experiment
    from ..scenarios.summaries import SineSummaryStream
    from ..system import build_circuit

    exp = experiment(rig, scenario, t_end)
    if not isinstance(exp, ClosedLoopSine):
        return None
    ax = next(iter(build_circuit(rig).axes.values()))
    return SineSummaryStream(exp.t_disturbance, ax.stroke, float(exp.frequency),
                             ax.supply_pressure, ax.return_pressure, ax.position,
                             ax.reference_signal, window_start=exp.window_start)


def plot_axes(res, summary, path, title=""):
    """Per-axis figure of a multi-axis run: valve supply and return port pressures [MPa] and
    piston position change [mm] of every axis against time (ms, s, ... by the run's length);
    grey, as in every figure, is outside the metrics window.

    Parameters
    ----------
    res : SimulationResult
        The run (``metadata["axes"]`` holds the handles)
    summary : dict
        Its summary (for the metrics window)
    path : str or Path
        PNG to write
    title : str
        Figure title
    """
    import numpy as np

    from ..plotting import (figure_title, new_figure, outside_window_handle, save_png,
                            shade_outside_window, tight_layout, time_axis)

    axes = res.metadata["axes"]
    t0, t1 = summary["metrics_window_s"]
    fig = new_figure((9, 9))
    ax = fig.subplots(3, 1, sharex=True)
    factor, unit = time_axis(res.t[-1] - res.t[0])
    t = res.t * factor
    i0 = int(np.searchsorted(res.t, t0))
    for name, a in axes.items():
        ax[0].plot(t, res[a.supply_pressure] / 1e6, label=name)
        ax[1].plot(t, res[a.return_pressure] / 1e6, label=name)
        x = res[a.position]
        ax[2].plot(t, (x - x[i0]) * 1e3, label=name)
    for a_, lab in zip(ax, ("Supply port [MPa]", "Return port [MPa]", "Position change [mm]")):
        a_.set_ylabel(lab)
        shaded = shade_outside_window(a_, t0, t1, res.t[0], res.t[-1], factor)
        handles, _ = a_.get_legend_handles_labels()
        if shaded and a_ is ax[0]:   # (said once)
            handles.append(outside_window_handle())
        a_.legend(handles=handles, loc="best", fontsize=8)
        a_.grid(alpha=0.3)
        a_.set_xlim(t[0], t[-1])
    ax[2].set_yscale("symlog", linthresh=1e-4)
    ax[2].set_xlabel(f"time [{unit}]")
    fig.suptitle(figure_title(title), fontsize=10)
    tight_layout(fig)
    save_png(fig, path, dpi=110)


def _report_axes(args, rig, res, summary, scenario, figures) -> int:
    """Print a multi-axis run: per axis the port metrics and the position disturbance."""
    if args.out is not None or not args.json:
        out = out_dir(args.out if args.out is not None else "hydroline-out")
        columns = [c for a in res.metadata["axes"].values()
                   for c in (a.supply_pressure, a.return_pressure, a.position)]
        with atomic_outputs(out) as temp, figures:
            figures.draw(plot_axes, figure_result(res, columns, ("axes",)), summary,
                         str(temp("pressures.png")),
                         f"{scenario} on {rig.get('rig.name', rig.source)}")
    if args.json:
        for w in summary["warnings"]:
            print(f"hydroline simulate: warning: {w}", file=sys.stderr)
        dump_json(json_summary(summary))
        return 0
    print(f"hydroline simulate: {scenario} on {rig.get('rig.name', rig.source)}")
    print(f"  {res.metadata['n_states']} states, wall time {summary['wall_time_s']:.2f} s")
    print(f"  {summary['metrics_window_note']}")
    rows = []
    for name, a in summary["axes"].items():
        for side in ("supply", "return"):
            m = a[side]
            rows.append([f"{name} {side} port", m["frequency_hz"], amplitude_cell(m),
                         m.get("first_excursion_mpa"), m.get("peak_to_peak_mpa"), settling_cell(m)])
    print_table(["pressure", "oscillation [Hz]", "amplitude [MPa]", "first excursion [MPa]",
                 "peak-to-peak [MPa]", "settling [ms]"], rows)
    legend = settling_legend([(f"{name} {side}", a[side]) for name, a in summary["axes"].items()
                              for side in ("supply", "return")])
    if legend:
        print(f"  {legend}")
    for name, a in summary["axes"].items():
        d = a["position_disturbance_mm"]
        what = (f"moved {a['position_change_mm']:.3g} mm (driven by the experiment)" if d is None
                else f"position disturbance {d * 1e3:.3g} um")
        if "tracking_error_rms_mm" in a:
            what += (f", tracking error (reference - position) rms {a['tracking_error_rms_mm']:.2f}"
                     f" mm, max {a['tracking_error_max_mm']:.2f} mm")
        print(f"  {name}: {what}")
    for w in summary["warnings"]:
        print(f"  warning: {w}")
    print(f"  wrote {out / RESULT_FILES[getattr(args, 'format', 'csv')]}, {out / 'summary.json'}, "
          f"{out / 'pressures.png'}")
    return 0
