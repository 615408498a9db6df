"""``hydroline circuit``: print a rig's circuit (components, connections, causality) and draw it."""
from __future__ import annotations

import json
from pathlib import Path

from ..circuit.drawing import component_rows, draw_circuit
from ..circuit.types import parameter_reference
from ..rigs import load_rig
from ..system import build_circuit
from .common import atomic_outputs, out_dir, print_table


def register(sub):
    """Add the ``hydroline circuit`` subcommand and its options to the command's parser.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers object of the ``hydroline`` parser
        (from ``add_subparsers``); ``run`` is set as the
        subcommand's ``func``
    """
    p = sub.add_parser("circuit", help="print a rig's circuit: components, connections, "
                       "causality; draw it as an ISO 1219 hydraulic schematic",
                       description="Print the components of a rig's circuit with the signal on "
                       "each port (inputs <- and outputs ->), the connections (each signal, the "
                       "port that outputs it and the ports that read it) and the servo axes; "
                       "--schematic draws the circuit as a hydraulic schematic with ISO 1219-1 "
                       "symbols (pump, tank, valves, accumulators, servovalve, cylinder, hoses "
                       "labelled with length and bore), --png the graph of its signals.")
    p.add_argument("rig", nargs="?", help="rig TOML file or shipped rig name, e.g. two_axis "
                   "(default: the embedded 2005 rig)")
    p.add_argument("--schematic", metavar="FILE",
                   help="draw the hydraulic schematic (ISO 1219-1 symbols) to FILE.svg or "
                   "FILE.png")
    p.add_argument("--png", help="draw the graph of the circuit's signals (which component "
                   "outputs what to which) to this PNG file")
    p.add_argument("--json", action="store_true", help="print components, connections and axes as JSON")
    p.add_argument("--types", action="store_true", help="list the component types a circuit file "
                   "may use, with every parameter's unit, bounds, default and description")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``hydroline circuit``: print a rig's circuit (components, connections, causality), optionally as JSON, drawn as an ISO 1219 schematic (SVG or PNG) or as a signal graph (PNG).

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
    if args.types:   # the reference of every type: nothing of a rig is read or drawn
        if args.rig is not None:
            raise ValueError(f"--types lists every component type and reads no rig; got the "
                             f"rig {args.rig!r} too (run 'hydroline circuit {args.rig}' for "
                             f"its circuit)")
        given = [o for o, v in (("--json", args.json), ("--png", args.png),
                                ("--schematic", getattr(args, "schematic", None))) if v]
        if given:
            raise ValueError(f"--types prints the reference as Markdown; {given[0]} is not "
                             f"taken with it")
        print(parameter_reference())
        return 0
    schematic = getattr(args, "schematic", None)
    if schematic is not None:
        suffix = Path(schematic).suffix.lower()
        if suffix not in (".svg", ".png"):
            raise ValueError(f"--schematic: {schematic!r} is written as SVG or PNG by its "
                             f"extension; give FILE.svg or FILE.png (got {suffix or 'none'!r})")
        out_dir(Path(schematic).parent if str(Path(schematic).parent) else ".",
                (Path(schematic).name,), option="--schematic")
    rig = load_rig(args.rig)
    circuit = build_circuit(rig)
    comps = component_rows(circuit)
    conns = circuit.connection_table()
    axes = {n: vars(a) for n, a in circuit.axes.items()}
    if args.png:
        draw_circuit(circuit, args.png, title=f"{rig.get('rig.name', rig.source)}")
    if schematic is not None:
        from ..circuit.schematic import draw_schematic

        folder = Path(schematic).parent
        with atomic_outputs(folder) as temp:   # the file replaced whole, or not at all
            draw_schematic(circuit, temp(Path(schematic).name),
                           title=f"{rig.get('rig.name', rig.source)}")
    if args.json:
        print(json.dumps({"components": comps, "connections": conns, "axes": axes}, indent=2))
        return 0
    print(f"hydroline circuit: {rig.get('rig.name', rig.source)} ({len(comps)} components, "
          f"{len(conns)} signals)")
    print("\ncomponents (causality: port <- signal it reads, port -> signal it outputs)")
    for c in comps:
        print(f"  {c['component']}  ({c['type']}, {c['states']} states"
              f"{'' if c['feedthrough'] else ', outputs from states only'})")
        for p, s in c["inputs"].items():
            print(f"      {p} <- {s}")
        for p, s in c["outputs"].items():
            print(f"      {p} -> {s}")
    print("\nconnections (signal [unit]: the port that outputs it -> the ports that read it)")
    for r in conns:
        print(f"  {r['signal']} [{r['unit']}]: {r['producer'] or '(from the experiment)'} -> "
              f"{', '.join(r['consumers']) or '(not read)'}")
    if axes:
        print("\nservo axes (handles)")
        print_table(["axis", "valve", "current", "supply port", "return port", "position", "controller"],
                    [[n, a["valve"], a["current"], a["supply_pressure"], a["return_pressure"],
                      a["position"], a["controller"] or "(experiment)"] for n, a in axes.items()])
    for path in (args.png, schematic):
        if path:
            print(f"\n  wrote {path}")
    return 0
