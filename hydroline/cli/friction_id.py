"""``hydroline friction-id``: friction by Newton's law, (M24) fitted up and down separately."""
from __future__ import annotations

import numpy as np

from ..analysis.figures import plot_friction
from ..analysis.fit import read_measurements
from ..analysis.friction_id import FRICTION_COLUMNS, friction_table, identify_friction
from ..studies.friction_tests import virtual_friction_tests
from ..rigs import load_rig
from .common import atomic_outputs, dump_json, out_dir, print_table, quantity


def register(sub):
    """Add the ``hydroline friction-id`` subcommand and its options to the command's parser.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers object of the ``hydroline`` parser
        (from ``add_subparsers``); ``run`` is set as the
        subcommand's ``func``
    """
    p = sub.add_parser(
        "friction-id", help="identify piston friction (M24) from open-loop runs and a closed-loop sine",
        description="Friction force by Newton's law (M23) from measured chamber pressures and "
        "piston position: one point per steady-velocity open-loop run (--steady) and every "
        "moving sample of a closed-loop sine (--sine); then (M24) fitted up and down "
        "separately, as in the 2005 paper. Static friction and the Stribeck velocity are "
        "claimed (and written) only when steady-velocity runs slower than about twice C_s "
        "pin them in both directions; otherwise the rig's values are kept. CSV columns as for "
        "'hydroline fit' (needs " + ", ".join(FRICTION_COLUMNS) + "; an external_force column, "
        "a load cell, is used when present). Writes friction.png, friction.json and "
        "friction_rig.toml (the rig with the fitted coefficients) to --out.")
    p.add_argument("rig", nargs="?", help="rig TOML file (default: the embedded 2005 rig)")
    p.add_argument("--steady", nargs="*", default=[], metavar="RUN.csv",
                   help="open-loop runs at constant valve current")
    p.add_argument("--sine", nargs="*", default=[], metavar="SINE.csv", help="closed-loop sine records")
    p.add_argument("--virtual", action="store_true",
                   help="run the paper's friction experiments on the model itself instead of data "
                   "(checks the identification against the rig's own coefficients); adds slow "
                   "runs (a few mm/s) against a damper specimen whose force is recorded, so that "
                   "static friction and the Stribeck velocity are identifiable")
    p.add_argument("--axis", default=None, help="servo axis the records are of (default: the "
                   "first; `hydroline circuit RIG` lists them): its actuator, load and friction")
    p.add_argument("--window", default="2 ms", help="derivative window (default '2 ms'; longer for noisy data)")
    p.add_argument("--min-speed", default="0.2 mm/s", help="slowest point used in the fit")
    p.add_argument("--sine-min-speed", default="20 mm/s",
                   help="slowest sine sample used (near reversals the piston sticks)")
    p.add_argument("--out", default="hydroline-out", help="output folder (default hydroline-out)")
    p.add_argument("--json", action="store_true", help="print the result as JSON on stdout only")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``hydroline friction-id``: identify friction by Newton's law and fit (M24) up and down separately.

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
    rig = load_rig(args.rig)
    out = out_dir(args.out)       # checked before the identification, not after it
    window = quantity(args.window, "s", "--window")
    if not window > 0:
        raise ValueError(f"--window must be > 0 s, got {args.window!r}")
    min_speed = quantity(args.min_speed, "m/s", "--min-speed")
    sine_min = quantity(args.sine_min_speed, "m/s", "--sine-min-speed")
    if args.virtual:
        if args.steady or args.sine:
            raise ValueError("--virtual runs the model's own experiments: give no --steady/--sine files")
        steady, sine = virtual_friction_tests(rig, axis=args.axis)
        source = "virtual experiments on the model"
    else:
        if not args.steady and not args.sine:
            raise ValueError("give --steady RUN.csv ... and/or --sine SINE.csv (or --virtual)")
        need = ("time",) + FRICTION_COLUMNS[1:]
        steady = [read_measurements(f, required=need, need_signal=False) for f in args.steady]
        sine = [read_measurements(f, required=need, need_signal=False) for f in args.sine]
        source = ", ".join(args.steady + args.sine)
    ident = identify_friction(rig, steady, sine, window=window, min_speed=min_speed,
                              sine_min_speed=sine_min, axis=args.axis)
    fit = ident.fit
    table = friction_table(rig, args.axis)
    calibrated = fit.apply(rig, table)
    rig_file = out / "friction_rig.toml"
    static_keys = ("static_up", "static_down", "stribeck_velocity")
    rows = []
    for k in ("viscous", "coulomb", "static"):
        unit = "N*s/m" if k == "viscous" else "N"
        for d in ("up", "down"):
            name = f"{k}_{d}"
            rows.append([f"{table}.{name}", unit, rig.get(f"{table}.{name}"), getattr(fit, name),
                         fit.std.get(name)])
    rows.append([f"{table}.stribeck_velocity", "m/s", rig.get(f"{table}.stribeck_velocity"),
                 fit.stribeck_velocity, fit.std.get("stribeck_velocity")])
    coefficients = {}
    for path, unit, rig_value, value, se in rows:
        held = path.rsplit(".", 1)[1] in static_keys and not fit.static_identified
        coefficients[path] = {"unit": unit, "rig": rig_value,
                              "identified": None if held else float(value),
                              "fitted": float(value), "std_error": se,
                              "written": calibrated.get(path)}
    summary = {"source": source, "points": {k: len(v[0]) for k, v in ident.points.items()},
               "coefficients": coefficients,
               "static_identified": fit.static_identified,
               "static_note": fit.static_note,
               "rms_residual_n": {"up": fit.rms_up, "down": fit.rms_down},
               "rig_file": str(rig_file)}
    with atomic_outputs(out) as temp:   # the three files replaced together, or none
        plot_friction(ident.points, fit, path=temp("friction.png"),
                      title=f"friction identification: {source}")
        temp(rig_file.name).write_text(
            f"# friction (M24) identified by 'hydroline friction-id' from {source}\n\n"
            + calibrated.to_toml())
        with open(temp("friction.json"), "w") as fh:     # strict JSON: NaN/inf as null
            dump_json(summary, fh)
    if args.json:
        dump_json(summary)
        return 0
    print(f"hydroline friction-id: {source}")
    for k, (v, _) in ident.points.items():
        print(f"  {k}: {len(v)} points, |v| {np.min(np.abs(v)) * 1e3:.3g}-{np.max(np.abs(v)) * 1e3:.3g} mm/s")
    table = [[p, u, r, ("not identified" if c["identified"] is None else c["identified"]),
              ("-" if c["identified"] is None else se), c["written"]]
             for (p, u, r, _, se), c in zip(rows, coefficients.values())]
    print_table(["parameter", "unit", "rig", "identified", "std error", "written"], table)
    if not fit.static_identified:
        print(f"  {fit.static_note}.")
        print("  The rig file keeps the rig's static_up, static_down and stribeck_velocity; "
              "slow steady-velocity runs (below about twice C_s, both directions) pin them.")
        print(f"  (the fit's unreliable values: F_s up {fit.static_up:.4g} N, down "
              f"{fit.static_down:.4g} N, C_s {fit.stribeck_velocity * 1e3:.3g} mm/s)")
    print(f"  rms residual: up {fit.rms_up:.3g} N, down {fit.rms_down:.3g} N")
    print(f"  wrote {out / 'friction.png'}, {out / 'friction.json'}, {rig_file}")
    return 0
