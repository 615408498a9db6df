"""``hydroline export-fmu``: the rig's plant as an FMI 2.0 or 3.0 FMU for co-simulation."""
from __future__ import annotations

from ..rigs import load_rig
from ..scenarios.experiments import SCENARIOS


def register(sub):
    """Add the ``hydroline export-fmu`` subcommand and its options to the command's parser.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers object of the ``hydroline`` parser
        (from ``add_subparsers``); ``run`` is set as the
        subcommand's ``func``
    """
    p = sub.add_parser(
        "export-fmu", help="export the rig's plant as an FMU (FMI 2.0 or 3.0, co-simulation or model "
        "exchange)",
        description="Write the rig's plant (hoses, HSM, accumulators, servovalve, actuator, "
        "friction, load) as an FMI 2.0 or 3.0 FMU: inputs valve_current [A], external_force [N], "
        "pump_pressure and tank_pressure [Pa]; outputs the valve port and chamber pressures "
        "[Pa] and the piston position [m] and velocity [m/s]; tunable parameters for the values "
        "that do not change the model's structure. The FMU starts at the solved rest state of "
        "--start. Built with the system C compiler for this platform; the C sources are in the "
        "FMU too. See docs/fmu.md.")
    p.add_argument("rig", nargs="?", help="rig TOML file (default: the embedded Ayalew & Kulakowski 2005 rig)")
    p.add_argument("--out", default="hydroline.fmu",
                   help="FMU file to write (default hydroline.fmu; its stem is the modelIdentifier)")
    p.add_argument("--fmi", default="2", help="FMI version: 2 (FMI 2.0, default) or 3 (FMI 3.0)")
    p.add_argument("--kind", default="cs",
                   help="cs (co-simulation, hydroline's BDF integrator inside; default), me (model "
                   "exchange: the importer integrates the ODE) or both")
    p.add_argument("--start", default="open-loop-step",
                   help=f"scenario whose rest state the FMU starts from: {' or '.join(SCENARIOS)} "
                   "(default open-loop-step: valve at its initial current, piston where the load "
                   "puts it; closed-loop-sine: piston held by the rig's controller, whose current "
                   "becomes valve_current's start value)")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``hydroline export-fmu``: write the rig's plant as an FMI 2.0 or 3.0 FMU.

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
    from ..fmu import FMI_VERSIONS, KINDS, export_fmu

    fmi = {"2": 2, "2.0": 2, "3": 3, "3.0": 3}.get(str(args.fmi).strip())
    if fmi not in FMI_VERSIONS:
        raise ValueError(f"--fmi: must be 2 (FMI 2.0) or 3 (FMI 3.0), got {args.fmi!r}")
    kind = str(args.kind).strip().lower()
    if kind not in KINDS:
        raise ValueError(f"--kind: must be one of {', '.join(KINDS)}, got {args.kind!r}")
    if args.start not in SCENARIOS:
        raise ValueError(f"--start: must be one of {', '.join(SCENARIOS)}, got {args.start!r}")
    rig = load_rig(args.rig)
    path = export_fmu(rig, args.out, fmi=fmi, kind=kind, start=args.start)
    print(f"wrote {path} (FMI {fmi}.0, {'co-simulation and model exchange' if kind == 'both' else {'cs': 'co-simulation', 'me': 'model exchange'}[kind]})")
    return 0
