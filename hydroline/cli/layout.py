"""``hydroline layout``: the section II hose-layout study (the 2005 paper's Figs. 13-14)."""
from __future__ import annotations

import contextlib
import math

from ..rigs import load_rig
from ..studies.layout import (DEFAULT_LENGTHS, LayoutStudy, conclusion, layout, layout_sections,
                               parse_lengths)
from .common import (SCHEMA_VERSION, add_settling_band_option, add_solver_option,
                     amplitude_cell, atomic_outputs,
                     dump_json, out_dir, print_table, progress_printer, quantity, settling_cell,
                     settling_legend)
from .figure_process import claim_figure_process

_DEFAULT = ",".join(f"{L:g}" for L in DEFAULT_LENGTHS)


def register(sub):
    """Add the ``hydroline layout`` subcommand and its options to the command's parser.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers object of the ``hydroline`` parser
        (from ``add_subparsers``); ``run`` is set as the
        subcommand's ``func``
    """
    p = sub.add_parser(
        "layout", help="hose-layout study: port pressure oscillations against the length of "
        "the sections II (manifold to servovalve), 0 = close-coupled manifold",
        description="Set the supply and return sections II (HSM manifold to servovalve) to each "
        "length, run the open-loop step from the solved steady state, and report per length the "
        "supply and return port oscillation frequency, oscillation amplitude (half the largest swing "
        "about the one-period mean), first excursion |p - p0| and steady change over the metrics "
        "window (step to the stop the piston moves toward), the design conclusion they support, "
        "and the settling time (by default within +-2 % of the final absolute pressure, "
        "--settling-band): measured where the port pressure settles "
        "within the window, '~' estimated from the decay of its oscillation where it is still "
        "ringing at the stop (at least 3 crests after the first period fitted with an exponential "
        "decay), '-' neither (the reason is printed). With --out DIR: layout.csv, layout_traces.csv "
        "and layout.png (the port-pressure traces of every length stacked, as the paper's "
        "Figs. 13-14, plus frequency and amplitude against length).")
    p.add_argument("rig", nargs="?", help="rig TOML file (default: the embedded Ayalew & Kulakowski 2005 rig)")
    p.add_argument("--lengths", default=_DEFAULT,
                   help="comma-separated section II lengths in metres; bare numbers are metres, "
                   "other units may be given per value, e.g. '10 ft,5 ft,0 m'; 0 removes the "
                   f"section (default: {_DEFAULT}, the paper's 10, 7.5, 5, 2.46 ft and 0)")
    p.add_argument("--side", default="both", choices=("both", "supply", "return"),
                   help="which sections II take the lengths (default: both)")
    p.add_argument("--sections", metavar="NAME,NAME",
                   help="the hose sections that take the lengths instead of the sections II: "
                   "on a circuit rig its hose components, e.g. "
                   "'axis1.supply_hose,axis1.return_hose' ('hydroline circuit RIG' lists them); "
                   "default: the rig's supply.section2 and return.section2")
    p.add_argument("--axis", help="a multi-axis rig: the axis whose port pressures are reported "
                   "(default: the axis the first section belongs to, else the stepped axis)")
    p.add_argument("--scenario", metavar="NAME",
                   help="the experiment run per length: open-loop-step, closed-loop-sine, "
                   "position-step or the rig's own [scenario.NAME] (default: the rig's "
                   "rig.scenario, else open-loop-step)")
    p.add_argument("--t-end", help="simulated time with unit, e.g. '0.25 s' (scenario default)")
    add_solver_option(p)
    p.add_argument("--out", help="folder for layout.csv, layout_traces.csv and layout.png")
    p.add_argument("--format", default="csv", choices=LayoutStudy.TRACE_FORMATS,
                   help="the traces' file: csv (layout_traces.csv; default), parquet "
                   "(layout_traces.parquet, units in its metadata) or mat (layout_traces.mat "
                   "for MATLAB, one variable per trace, the struct 'units')")
    p.add_argument("--json", action="store_true",
                   help="print only the JSON document on stdout: {schema_version, rig, "
                   "scenario, sections, axis, conclusion, wall_time_s, rows: [{section2_length_m, "
                   "supply: {every port metric and note}, return: {...}, flow: {...}, "
                   "metrics_window_s, warnings, ...}, ...]} (docs/layout.schema.json)")
    add_settling_band_option(p)
    p.set_defaults(func=run)


def json_document(study) -> dict:
    """The ``--json`` document of a layout study (docs/layout.schema.json).

    Parameters
    ----------
    study : LayoutStudy
        A finished study (:func:`hydroline.studies.layout`).

    Returns
    -------
    dict
        ``schema_version``, ``rig``, ``scenario``, ``sections`` (the hose sections whose length
        was set), ``axis`` (null on a single-axis rig), ``conclusion`` (the sentence printed),
        ``wall_time_s`` (the whole study, [s]) and ``rows``: :meth:`LayoutStudy.records`, one
        per length, with every column of the table.
    """
    return {"schema_version": SCHEMA_VERSION, "rig": study.rig_name, "scenario": study.scenario,
            "sections": list(study.sections), "axis": study.axis,
            "conclusion": conclusion(study), "wall_time_s": float(study.wall_time),
            "rows": study.records()}


def _progress(enabled):
    bar = progress_printer("layout", enabled)
    return None if bar is None else (lambda done, total: bar(done / total))


def _figure_rows(figures, lengths):
    """The study's ``on_run``: each length's trace panels handed to the figure process as its
    run ends (:func:`hydroline.plotting.prepare_layout_row`); None without a figure."""
    if figures is None:
        return None
    from ..plotting import prepare_layout_row

    n = len(parse_lengths(lengths))

    def on_run(k, length, res, summary, axis):
        run, metrics = LayoutStudy.figure_run(res, summary, axis)
        figures.prepare(prepare_layout_row, n, k, float(length), run, metrics)

    return on_run


def run(args) -> int:
    """Run ``hydroline layout``: the hose-layout study (port pressure oscillations against the length of the varied sections), its table, figure and conclusion.

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
    from ..traces.metrics import SettlingBand

    rig = load_rig(args.rig)
    band = SettlingBand.parse(args.settling_band)     # refused before any run
    t_end = quantity(args.t_end, "s", "--t-end") if args.t_end else None
    if t_end is not None and not t_end > 0:
        raise ValueError(f"--t-end must be > 0 s, got {args.t_end!r}")
    sides = ("supply", "return") if args.side == "both" else (args.side,)
    # the folder is checked before the study runs, not after it
    fmt = getattr(args, "format", "csv")
    names = LayoutStudy.file_names(fmt)
    out = out_dir(args.out, tuple(names.values())) if args.out else None
    sections = layout_sections(rig, args.sections, sides)   # refused before any run
    # the figure process (Matplotlib imported meanwhile) makes each length's panels while the
    # next lengths run, and draws the figure once the study's tables are written
    figures = claim_figure_process() if args.out else None
    with figures if figures is not None else contextlib.nullcontext():
        study = layout(rig, args.lengths, sides=sides, sections=sections, axis=args.axis,
                       scenario=args.scenario, t_end=t_end, solver=args.solver,
                       progress=_progress(not args.json), settling_band=band,
                       on_run=_figure_rows(figures, args.lengths))
        files = {}
        if args.out:   # all three files replaced together, or none (a failed write keeps the old)
            with atomic_outputs(out) as temp, figures:
                files = study.save(out, temp, traces_format=fmt, figures=figures)
    if args.json:
        dump_json(json_document(study))
        return 0
    if args.sections:
        what = f"{', '.join(study.sections)} set to each length" + \
            (f", ports of {study.axis}" if study.axis else "")
    else:
        what = f"sections II of {' and '.join(sides)} set to each length"
    print(f"hydroline layout: {study.scenario} on {study.rig_name}, {what} "
          f"({study.wall_time:.1f} s)")
    for side in ("supply", "return"):
        rows = []
        for rec, s in zip(study.records(), study.summaries):
            m = s[side]
            rows.append([rec["section2_length_m"], m["frequency_hz"], amplitude_cell(m),
                         m.get("first_excursion_mpa"), m.get("steady_change_mpa"),
                         settling_cell(m)])
        print(f"  {side} port:")
        print_table(["length [m]", "oscillation [Hz]", "amplitude [MPa]", "first excursion [MPa]",
                     "steady change [MPa]", "settling [ms]"], rows)
    print(f"  {conclusion(study)}")
    rise = [s["flow"]["flow_rise_time_ms"] for s in study.summaries
            if math.isfinite(s["flow"]["flow_rise_time_ms"])]
    trips = [(L, s["flow"]["supply_round_trip_ms"]) for L, s in zip(study.lengths, study.summaries)
             if L > 0 and math.isfinite(s["flow"]["supply_round_trip_ms"])]
    if trips and rise:
        print(f"  The valve's flow rises (10-90 %) in {min(rise):.1f}-{max(rise):.1f} ms; the supply "
              f"section II's round trip 2L/c is " + ", ".join(f"{t:.1f} ms at {L:g} m" for L, t in trips)
              + ": where the round trip is shorter than the rise, the reflection returns before the "
              "flow has risen and less of the water hammer Z0*dQ builds up.")
    print("  amplitude: half the largest swing about the one-period mean; 0 with frequency '-': no "
          "oscillation; '^' near that verdict (amplitude notes below).")
    legend = settling_legend([(side, s[side]) for s in study.summaries
                              for side in ("supply", "return")])
    if legend:
        print(f"  {legend}; measured within the metrics window (step to the stop the piston "
              "moves toward), '-' none:")
    for L, s in zip(study.lengths, study.summaries):
        for side in ("supply", "return"):
            if s[side].get("settling_note"):
                print(f"    L = {L:g} m, {side}: {s[side]['settling_note']}")
    notes = [(L, side, s[side]["amplitude_note"]) for L, s in zip(study.lengths, study.summaries)
             for side in ("supply", "return") if s[side].get("amplitude_note")]
    if notes:
        print("  amplitude notes:")
        for L, side, note in notes:
            print(f"    L = {L:g} m, {side}: {note}")
    for L, s in zip(study.lengths, study.summaries):
        for w in s["warnings"]:
            print(f"  WARNING (L = {L:g} m): {w}")
    if files:
        print(f"  wrote {files['csv']}, {files['traces']}, {files['figure']}")
    else:
        print(f"  (--out DIR writes layout.csv, {names['traces']} and the figure layout.png)")
    return 0
