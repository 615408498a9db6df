"""``hydroline fit``: calibrate rig parameters to a measured record (nonlinear least squares)."""
from __future__ import annotations

import functools
import importlib

from ..analysis.figures import plot_fit
from ..analysis.fit import COLUMNS, STARTS, UNRESOLVED_CURVATURE, fit_parameters, read_measurements
from ..compiled.toolchain import many_runs
from ..rigs import load_rig
from .common import atomic_outputs, dump_json, out_dir, print_table
from .figure_process import claim_figure_process

_COLUMN_HELP = ", ".join(f"'{k} [{u}]'" for k, u in COLUMNS.items())
#: Optimisation level of the quick library a first fit's background build makes: a fit's ~14
#: runs on it take ~0.05 s of CPU each at ``-O1`` against ~0.12 s at ``-O0``, for ~0.4 s
#: more of build (a cold fit of the default record: 2.30 -> 1.71 s of CPU; a layout study,
#: three runs on it, is quicker with ``-O0``: benchmarks/README.md, "Round 4")
QUICK_LEVEL = "-O1"


def register(sub):
    """Add the ``hydroline fit`` subcommand and its options to the command's parser.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers object of the ``hydroline`` parser
        (from ``add_subparsers``); ``run`` is set as the
        subcommand's ``func``
    """
    p = sub.add_parser(
        "fit", help="estimate rig parameters from measured time series",
        description="Fit chosen rig parameters (e.g. hose bulk moduli, manifold resistance, "
        "accumulator pre-charge, friction coefficients up/down) to a measured record by "
        "nonlinear least squares on log-parameters; the measured valve current drives the "
        "model. Prints estimates with confidence intervals and writes fit.png (measured vs "
        "fitted), fit.json and the calibrated rig file to --out. CSV columns, one header row "
        f"with units in brackets (any unit of the right dimension): {_COLUMN_HELP}; time and "
        "valve_current are required, plus at least one measured signal. The record must "
        "start at rest.")
    p.add_argument("files", nargs="+", metavar="[RIG.toml] DATA.csv",
                   help="optional rig file (default: the embedded 2005 rig), then the data CSV")
    p.add_argument("--params", required=True,
                   help="comma-separated rig parameters to fit, e.g. "
                   "supply.section2.bulk_modulus,return.section2.bulk_modulus")
    p.add_argument("--signals", help="comma-separated measured signals to fit (default: all in the file)")
    p.add_argument("--confidence", type=float, default=0.95, help="confidence level (default 0.95)")
    p.add_argument("--max-evals", type=int, default=60, help="model runs at most (default 60)")
    p.add_argument("--start", default="auto", choices=STARTS,
                   help="initial state: 'hold' the measured initial position, 'rest' at the first "
                   "current (piston on a stop), or 'auto' (hold when the piston is clear of the stops)")
    p.add_argument("--offsets", help="comma-separated signals with a free constant sensor offset, "
                   "or 'none' (default: piston_position when the model holds the measured initial "
                   "position, none otherwise)")
    p.add_argument("--axis", default=None, help="servo axis the record is of (default: the first; "
                   "`hydroline circuit RIG` lists them): the record's valve_current drives it, "
                   "its columns are that axis's signals, the other axes hold")
    p.add_argument("--keep-unresolved", action="store_true",
                   help="fit every sample; by default the samples the record's sampling does not "
                   "resolve in the model's traces (a stop impact: a one-sample curvature over "
                   f"{100 * UNRESOLVED_CURVATURE:g} %% of a signal's range) are left out, and "
                   "the output says which")
    p.add_argument("--out", default="hydroline-out", help="output folder (default hydroline-out)")
    p.add_argument("--json", action="store_true", help="print the result as JSON on stdout only")
    p.set_defaults(func=run)


def _files(files):
    if len(files) == 1:
        return None, files[0]
    if len(files) == 2:
        return files[0], files[1]
    raise ValueError(f"give [RIG.toml] DATA.csv (one or two files), got {len(files)}")


def run(args) -> int:
    """Run ``hydroline fit``: calibrate rig parameters to a measured record (nonlinear least squares).

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
    # Matplotlib imports in a second process while this one fits (started with the command:
    # hydroline.cli.main); the figure is drawn there
    with claim_figure_process() as figures:
        return _run(args, figures)


def _run(args, figures) -> int:
    rig_path, data_path = _files(args.files)
    if not 0 < args.confidence < 1:
        raise ValueError(f"--confidence must lie in (0, 1), got {args.confidence!r}")
    if args.max_evals < 2:
        raise ValueError(f"--max-evals must be >= 2, got {args.max_evals}")
    rig = load_rig(rig_path)
    out = out_dir(args.out)       # checked before the fit, not after it
    params = [s.strip() for s in args.params.split(",") if s.strip()]
    meas = read_measurements(data_path)
    signals = [s.strip() for s in args.signals.split(",") if s.strip()] if args.signals else None
    offsets = None
    if args.offsets:
        offsets = [] if args.offsets.strip().lower() == "none" else \
            [s.strip() for s in args.offsets.split(",") if s.strip()]
        for s in offsets:
            if s not in meas.names:
                raise ValueError(f"--offsets: '{s}' is not a measured signal of {data_path}")
    t = meas.t
    # the three files replaced together, or none (the figure process stopped first on an error)
    with atomic_outputs(out) as temp, figures:
        png = temp("fit.png")

        def draw(view):   # the figure drawn while the fit's last run (its integration error) goes on
            figures.submit(plot_fit, t - t[0], {s: meas.column(s) for s in view["sigma"]},
                           view["initial"], view["fitted"], path=str(png),
                           title=f"hydroline fit: {data_path}",
                           windows=[(a - t[0], b - t[0]) for a, b in view["windows"]],
                           rms=view["rms"], start_rms=view["start_rms"], worse=view["worse"])

        # (its first run too waits for the quick library, not CVODES; SciPy's optimiser is
        # imported while it waits)
        with many_runs(meanwhile=[functools.partial(importlib.import_module, "scipy.optimize")],
                       quick_level=QUICK_LEVEL):
            res = fit_parameters(rig, meas, params, signals, confidence=args.confidence,
                                 max_evaluations=args.max_evals, start=args.start, offsets=offsets,
                                 axis=args.axis,
                                 unresolved="keep" if args.keep_unresolved else "window",
                                 on_fitted=draw)
        rig_file = out / "calibrated_rig.toml"
        summary = res.to_dict()
        summary.update(data=data_path, rig=rig.source, calibrated_rig=str(rig_file),
                       ignored_columns=meas.ignored)
        temp_rig = temp(rig_file.name)
        temp_rig.write_text(res.calibrated_toml(data_path))
        with open(temp("fit.json"), "w") as fh:     # strict JSON: NaN/inf as null
            dump_json(summary, fh)
        figures.wait()
    if args.json:
        dump_json(summary)
        return 0
    pct = f"{100 * args.confidence:g} %"
    print(f"hydroline fit: {len(params)} parameter(s) of {rig.get('rig.name', rig.source)} to {data_path}")
    print(f"  {res.n_data} residuals from {', '.join(res.sigma)}; {res.n_evaluations} model runs; "
          f"{res.status}")
    for note in res.notes:
        print(f"  note: {note}")
    if meas.ignored:
        shown = ", ".join(meas.ignored[:8]) + (f" and {len(meas.ignored) - 8} more"
                                               if len(meas.ignored) > 8 else "")
        print(f"  ignored columns: {shown}")
    print_table(["parameter", "unit", "start", "estimate", f"{pct} CI low", f"{pct} CI high",
                 "rel. std error"], res.table())
    rows = [[s, res.sigma[s], res.start_rms.get(s), res.rms.get(s)] for s in res.sigma]
    print_table(["signal", "noise sigma [SI]", "rms residual at start [SI]",
                 "rms residual fitted [SI]"], rows)
    for s, v in res.offsets.items():
        print(f"  fitted sensor offset of {s}: {v:.4g} [SI] (measured minus model)")
    print(f"  residual variance s^2 = {res.residual_variance:.3g} (about 1 when the model explains "
          f"the data down to its noise)")
    if not res.success:
        print("  WARNING: the optimiser stopped before converging; raise --max-evals")
    print(f"  wrote {out / 'fit.png'}, {out / 'fit.json'}, {rig_file}")
    return 0
