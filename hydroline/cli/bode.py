"""``hydroline bode``: frequency response of the linearised test system, hoses vs ideal supply."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ..analysis.figures import plot_bode
from ..analysis.frequency import MODAL, bode_analysis, rated_velocity
from ..analysis.linearize import INPUTS, OperatingPoint
from ..engine.result import write_csv_table
from ..rigs import load_rig
from .common import atomic_outputs, dump_json, out_dir, print_table, quantity
from .figure_process import claim_figure_process

DEFAULT_OUTPUTS = "piston_velocity,supply_port_pressure,return_port_pressure"


def register(sub):
    """Add the ``hydroline bode`` subcommand and its options to the command's parser.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers object of the ``hydroline`` parser
        (from ``add_subparsers``); ``run`` is set as the
        subcommand's ``func``
    """
    p = sub.add_parser(
        "bode", help="frequency response of the linearised system: with the hoses and with an "
        "ideal constant supply",
        description="Linearise the test system about an operating point (piston at --position, "
        "moving at --velocity, under --force; the valve current that holds it there is solved "
        "for) and plot magnitude and phase of OUTPUT/INPUT with the hoses as modal lines, with "
        "the hoses as exact dissipative lines (M6), and with ideal constant supply and return "
        "pressures. Prints the -3 dB bandwidths read two ways -- the first -3 dB crossing (marked "
        "when it lies in a notch the gain climbs out of) and the frequency up to which the gain "
        "stays within 3 dB, notches aside -- and the resonances (frequency, damping); writes "
        "bode.png, bode.json and bode.csv to --out.")
    p.add_argument("rig", nargs="?", help="rig TOML file (default: the embedded Ayalew & Kulakowski 2005 rig)")
    p.add_argument("--axis", default=None, help="servo axis whose valve drives (default: the "
                   "first; `hydroline circuit RIG` lists them); generic outputs such as "
                   "piston_velocity are that axis's, its position loop is opened, other axes hold")
    p.add_argument("--input", default="valve_current", choices=tuple(INPUTS),
                   help="input channel (default valve_current)")
    p.add_argument("--output", default=DEFAULT_OUTPUTS,
                   help=f"comma-separated output signals (default {DEFAULT_OUTPUTS})")
    p.add_argument("--compare", default="constant-supply", choices=("constant-supply", "none"),
                   help="also show the ideal constant-supply model (default)")
    p.add_argument("--position", default="0 mm", help="piston position from mid-stroke (default '0 mm')")
    p.add_argument("--velocity", default="rated",
                   help="steady piston velocity, e.g. '0 m/s' (at rest: an underlapped valve at "
                   "null hardly couples to the hoses) or 'rated' (default: the valve's rated flow "
                   "over the bottom area, up)")
    p.add_argument("--force", help="external force on the rod, positive down, e.g. '2 kN' "
                   "(default: the rig's load.applied_force)")
    p.add_argument("--f-min", default="1 Hz", help="lowest frequency (default 1 Hz)")
    p.add_argument("--f-max", default="500 Hz", help="highest frequency (default 500 Hz)")
    p.add_argument("--points", type=int, default=1200, help="log-spaced frequencies (default 1200)")
    p.add_argument("--friction", default="viscous", choices=("viscous", "model"),
                   help="friction slope in the linear model: viscous coefficient (default) or the "
                   "literal Jacobian of the regularised (M24)")
    p.add_argument("--no-exact", action="store_true", help="skip the exact-line response")
    p.add_argument("--out", default="hydroline-out", help="output folder (default hydroline-out)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout only")
    p.set_defaults(func=run)


def _operating_point(args, rig):
    x = quantity(args.position, "m", "--position")
    if str(args.velocity).strip().lower() == "rated":
        v = rated_velocity(rig, args.axis)
    else:
        v = quantity(args.velocity, "m/s", "--velocity")
    force = quantity(args.force, "N", "--force") if args.force else None
    return OperatingPoint(piston_position=x, piston_velocity=v, external_force=force)


def _frequencies(args):
    f0 = quantity(args.f_min, "Hz", "--f-min")
    f1 = quantity(args.f_max, "Hz", "--f-max")
    if not 0 < f0 < f1:
        raise ValueError(f"--f-min and --f-max must satisfy 0 < f-min < f-max [Hz], got "
                         f"{args.f_min!r}, {args.f_max!r}")
    if args.points < 10:
        raise ValueError(f"--points must be >= 10, got {args.points}")
    return np.logspace(np.log10(f0), np.log10(f1), args.points)


def summary_dict(res, op) -> dict:
    """The JSON summary of a :class:`~hydroline.analysis.frequency.BodeResult`.

    Parameters
    ----------
    res : BodeResult
        The frequency responses, bandwidths and resonances of the variants
    op : OperatingPoint
        Where the model was linearised (piston position [m] and velocity
        [m/s], :class:`~hydroline.analysis.linearize.OperatingPoint`)

    Returns
    -------
    dict
        Keys name their unit (``_hz``, ``_pa``, ``_m``, ...); ready for :func:`dump_json`
    """
    solved = res.operating_points[MODAL]
    out = {
        "input": res.input, "outputs": res.outputs,
        "operating_point": {
            "piston_position_m": op.piston_position, "piston_velocity_m_s": op.piston_velocity,
            "external_force_n": solved.signals.get(
                solved.network.component(solved.axis.actuator).signal("load_force")),
            "valve_current_a": {k: v.valve_current for k, v in res.operating_points.items()},
            "supply_port_pressure_pa": solved.signals[solved.axis.supply_pressure],
            "return_port_pressure_pa": solved.signals[solved.axis.return_pressure]},
        "frequency_range_hz": [float(res.f[0]), float(res.f[-1])],
        "bandwidth_hz": res.bandwidths, "bandwidth_notes": res.notes,
        "passband": {label: {o: {"first_crossing_hz": b.first_crossing_hz,
                                 "within_3db_up_to_hz": b.within_3db_up_to_hz,
                                 "first_crossing_in_notch": None if b.notch is None else
                                 {"frequency_hz": b.notch[0], "depth_db": b.notch[1]},
                                 "note": b.note}
                             for o, b in bands.items()}
                     for label, bands in res.passbands.items()},
        "highest_retained_mode_hz": res.highest_mode_hz,
        "resonances": {},
    }
    for label, rows in res.resonances.items():
        out["resonances"][label] = []
        for r in rows:
            entry = {"frequency_hz": r.frequency_hz, "damping_ratio": r.damping_ratio,
                     "strongest_in": r.strongest_in}
            if label == MODAL and r.eigenvalue in res.exact_poles:
                ex = res.exact_poles[r.eigenvalue]
                entry["exact_lines"] = None if ex is None else {"frequency_hz": ex[0], "damping_ratio": ex[1]}
            out["resonances"][label].append(entry)
    return out


def figure_passbands(res) -> dict:
    """The passbands as the figure reads them (whether the first -3 dB crossing lies in a
    notch, and up to where the gain stays within 3 dB), in plain objects: unpickling the
    analysis' own would import the model into the figure process.

    Parameters
    ----------
    res : BodeResult
        The frequency responses and their passbands

    Returns
    -------
    dict
        Label -> {output: ``types.SimpleNamespace(in_notch, within_3db_up_to_hz)``}
    """
    return {label: {o: SimpleNamespace(in_notch=b.in_notch, within_3db_up_to_hz=b.within_3db_up_to_hz)
                    for o, b in bands.items()}
            for label, bands in res.passbands.items()}


def run(args) -> int:
    """Run ``hydroline bode``: the frequency response of the linearised test system, with the hoses and with an ideal supply: a Bode plot, bandwidths and resonances.

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
    # Matplotlib imports in a second process while this one solves (started with the command:
    # hydroline.cli.main); the figure is drawn there
    with claim_figure_process() as figures:
        return _run(args, figures)


def _run(args, figures) -> int:
    rig = load_rig(args.rig)
    out = out_dir(args.out)       # checked before the analysis, not after it
    outputs = [o.strip() for o in args.output.split(",") if o.strip()]
    if not outputs:
        raise ValueError("--output: give at least one signal, e.g. piston_velocity")
    op = _operating_point(args, rig)
    f = _frequencies(args)
    res = bode_analysis(rig, op, args.input, outputs, f, compare=args.compare != "none", axis=args.axis,
                        exact=not args.no_exact, friction=args.friction)
    summary = summary_dict(res, op)
    cols = {"frequency [Hz]": res.f}
    for label, H in res.curves.items():
        for j, o in enumerate(outputs):
            cols[f"{o}/{args.input} |H| [SI] ({label})"] = np.abs(H[:, j])
            cols[f"{o}/{args.input} phase [deg] ({label})"] = np.degrees(np.angle(H[:, j]))
    name = rig.get("rig.name", rig.source)
    title = (f"{name}: x_p = {op.piston_position * 1e3:g} mm, v_p = {op.piston_velocity:.3g} m/s, "
             f"i = {res.operating_points[MODAL].valve_current * 1e3:.3g} mA")
    with atomic_outputs(out) as temp:   # the three files replaced together, or none
        with open(temp("bode.json"), "w") as fh:     # strict JSON: NaN/inf as null
            dump_json(summary, fh)
        figures.submit(plot_bode, res.f, res.curves, args.input, outputs, res.bandwidths,
                       path=str(temp("bode.png")), title=title,
                       highest_mode_hz=res.highest_mode_hz, passbands=figure_passbands(res))
        write_csv_table(temp("bode.csv"), cols)   # (pandas' text, without its import)
        figures.wait()
    if args.json:
        dump_json(summary)
        return 0
    print(f"hydroline bode: {args.input} -> {', '.join(outputs)} on {name}")
    print(f"  operating point: piston at {op.piston_position * 1e3:g} mm moving at "
          f"{op.piston_velocity:.3g} m/s, holding current "
          f"{res.operating_points[MODAL].valve_current * 1e3:.4g} mA")
    rows, notes = [], []
    for label in res.curves:
        for o in outputs:
            band = res.passbands[label].get(o)
            if band is None:       # no low-pass: resonant, integrating, held constant
                rows.append([label, o, "-", "-"])
                notes.append(f"  {label}, {o}: no -3 dB reading: {res.notes[label].get(o, '-')}")
                continue
            first = "-" if band.first_crossing_hz is None else f"{band.first_crossing_hz:.4g}"
            rows.append([label, o, first + (" (in a notch)" if band.in_notch else ""),
                         band.within_3db_up_to_hz if band.within_3db_up_to_hz is not None
                         else f"above {res.f[-1]:.4g}"])
            if band.note:
                notes.append(f"  {label}, {o}: {band.note}")
    print_table(["model", "output", "first -3 dB crossing [Hz]", "gain within 3 dB up to [Hz]"], rows)
    print("  first -3 dB crossing: where the gain first falls 3 dB below its low-frequency gain, "
          "'(in a notch)' when it climbs back above -3 dB after (a line mode's anti-resonance); "
          "gain within 3 dB up to: where it falls below -3 dB for good, notches aside")
    for line in notes:
        print(line)
    print("  resonances (lightly damped poles that show in these outputs):")
    rows = []
    for label, rs in res.resonances.items():
        for r in rs:
            ex = res.exact_poles.get(r.eigenvalue) if label == MODAL else None
            rows.append([label, r.frequency_hz, r.damping_ratio,
                         None if ex is None else ex[0], None if ex is None else ex[1], r.strongest_in])
    print_table(["model", "f_n [Hz]", "damping [-]", "exact lines f_n [Hz]", "exact damping [-]",
                 "strongest in"], rows)
    if np.isfinite(res.highest_mode_hz):
        print(f"  modal lines follow the exact lines up to their highest retained mode, "
              f"{res.highest_mode_hz:.0f} Hz (dash-dot line on the figure): resonance frequencies "
              "within 1 %, peak heights within the line library's own per-mode peak error "
              "compounded over the hose sections in series (a few % at the low modes, up to "
              "~20 % near the highest); above it, only the exact lines hold")
    if any("resonant" in n for notes in res.notes.values() for n in notes.values()):
        print("  no -3 dB bandwidth for resonant channels (|H| rises > 3 dB above its "
              "low-frequency gain): the -3 dB point of such a response is not a bandwidth")
    print(f"  wrote {out / 'bode.png'}, {out / 'bode.json'}, {out / 'bode.csv'}")
    return 0
