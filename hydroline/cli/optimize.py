"""``hydroline optimize``: constrained design optimisation with the hose dynamics in the loop."""
from __future__ import annotations

import argparse
import signal
import sys

from ..rigs import load_rig
from .common import (add_solver_option, dump_json, out_dir, print_table, progress_printer,
                     quantity)

#: Files written in ``--out`` besides the results file optimize.jsonl.
FILES = ("optimum.toml", "optimize.json", "optimize.png")

EPILOG = """\
variables (values with units, read as 'hydroline sweep --set' reads them):
  --vary PATH=LOW..HIGH            a continuous variable, e.g. 'supply.section2.length=0.5 m..4 m'
  --choose PATH=V1,V2,...          discrete values, e.g. 'supply.section2.diameter=12.7 mm,19.05 mm'
  PATH1+PATH2=...                  both paths take the same value
metrics (--minimize, --subject-to): the sweep's metrics with a dot after the side
  supply.amplitude_mpa, supply.frequency_hz, supply.settling_time_s,
  return.first_excursion_mpa, ..., tracking_error_rms_mm (closed-loop-sine); per axis
  of a multi-axis rig axis2.supply.amplitude_mpa, axis2.position_disturbance_mm; the
  linearised model's closed position loop bandwidth position_bandwidth_hz (-3 dB, at rest
  at mid-stroke; per axis axis2.position_bandwidth_hz); cost proxies total_hose_length_m,
  accumulator_volume_l. A constraint is 'METRIC<=VALUE' or 'METRIC>=VALUE', VALUE in the
  unit the metric's name ends with.

methods: continuous variables: SLSQP (finite-difference gradients, each gradient's points
run as one batch) from the best of a few Latin-hypercube starting points and the base rig;
where SLSQP fails or ends where it started (a zero or noisy gradient: a rough or stepped
metric) COBYQA (derivative-free) goes on from the best point; --method derivative-free
uses COBYQA alone. With --choose (or --method global): every combination of the choices,
or differential evolution, then SLSQP on the continuous variables at the best choice.

examples:
  hydroline optimize --vary 'supply.section2.length=0.5 m..6 m' --minimize supply.amplitude_mpa
  hydroline optimize --vary 'supply.section2.length=0.5 m..6 m' \\
      --vary 'supply.accumulator.capacity=0.2 L..4 L' --minimize supply.amplitude_mpa \\
      --subject-to 'supply.frequency_hz>=30' --workers 4 --out opt
  hydroline optimize ... --out opt --resume          # continue after an interruption

--out DIR: optimize.jsonl (every evaluation's row as it finishes, what --resume reads),
optimum.toml (the rig with each changed value commented 'optimised for ...'),
optimize.json (the result) and optimize.png (baseline and optimum port pressures, the
objective per evaluation, the Pareto front with several --minimize); with several
--minimize also front_01.toml, front_02.toml, ... (one rig per point of the front).

several --minimize: a Pareto front by the epsilon-constraint method: each metric's minimum,
then the first metric minimised with the others <= levels spread between those ends
(--front-points); the front is in optimize.json ("front") and the figure.
"""


def register(sub):
    """Add the ``hydroline optimize`` subcommand and its options to the command's parser.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers object of the ``hydroline`` parser;
        ``run`` is set as the subcommand's ``func``
    """
    p = sub.add_parser(
        "optimize", help="constrained design optimisation: which hose lengths, bores, "
        "accumulators or gains minimise a port-pressure metric, with the hose dynamics in the loop",
        description="Minimise a metric of the rig's response over rig parameters (--vary "
        "ranges, --choose discrete values) subject to constraints on other metrics; every "
        "evaluation runs the scenario on the model shared by all of them (numbers are runtime "
        "parameters: nothing is recompiled).",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("rig", nargs="?", help="base rig TOML file or shipped rig name (default: "
                   "the embedded Ayalew & Kulakowski 2005 rig)")
    p.add_argument("--vary", action="append", default=[], metavar="PATH=LOW..HIGH",
                   help="a continuous variable and its range with units (repeat for more)")
    p.add_argument("--choose", action="append", default=[], metavar="PATH=V1,V2,...",
                   help="a discrete variable and its values with units (repeat for more)")
    p.add_argument("--minimize", action="append", default=[], metavar="METRIC",
                   help="the metric to minimise, e.g. supply.amplitude_mpa; several give a "
                   "Pareto front (epsilon-constraint)")
    p.add_argument("--front-points", type=int, default=5, metavar="N",
                   help="with several --minimize: levels of each further metric on the Pareto "
                   "front, its ends included (default 5)")
    p.add_argument("--subject-to", dest="subject_to", action="append", default=[],
                   metavar="'METRIC<=VALUE'", help="a constraint (repeat for more)")
    p.add_argument("--scenario", metavar="NAME", help="the experiment each evaluation runs "
                   "(default: the rig's rig.scenario, else open-loop-step)")
    p.add_argument("--t-end", help="simulated time per evaluation with unit, e.g. '0.25 s'")
    add_solver_option(p)
    p.add_argument("--method", default="auto",
                   choices=("auto", "local", "derivative-free", "global"),
                   help="local: SLSQP from space-filling starts, COBYQA where it stalls "
                   "(continuous only); derivative-free: COBYQA from those starts (rough "
                   "metrics); global: differential evolution (or every combination of "
                   "--choose), then SLSQP; auto: global where there are --choose variables, "
                   "else local (default)")
    p.add_argument("--max-evaluations", type=int, metavar="N",
                   help="evaluations allowed (default 40 + 30 per variable)")
    p.add_argument("--starts", type=int, metavar="N",
                   help="space-filling starting points (default 3 + 2 per continuous variable)")
    p.add_argument("--seed", type=int, default=0, help="seed of the starting points and of "
                   "differential evolution (default 0)")
    p.add_argument("--workers", type=int, default=1, metavar="W",
                   help="local worker processes, or workers of --scheduler local (default 1)")
    p.add_argument("--scheduler", metavar="ADDR", help="run on Dask: tcp://host:port or 'local'")
    p.add_argument("--out", metavar="DIR", help="folder for optimize.jsonl, optimum.toml, "
                   "optimize.json and optimize.png")
    p.add_argument("--resume", action="store_true",
                   help="continue from --out's optimize.jsonl (its evaluations are not rerun)")
    p.add_argument("--no-figure", dest="figure", action="store_false",
                   help="skip optimize.png (two more runs)")
    p.add_argument("--json", action="store_true", help="print the result as JSON on stdout only")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``hydroline optimize``: the optimisation, its summary and files.

    Bad input raises a ``ValueError`` whose one-line message :func:`hydroline.cli.main` prints.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line, with the options :func:`register` adds

    Returns
    -------
    int
        Exit code: 0, or 1 where the optimum found breaks a constraint
    """
    from ..studies.optimize import optimize, shown_value

    if not args.minimize:
        raise ValueError("--minimize METRIC is required, e.g. --minimize supply.amplitude_mpa")
    if not args.vary and not args.choose:
        raise ValueError("give at least one --vary PATH=LOW..HIGH or --choose PATH=V1,V2,..., "
                         "e.g. --vary 'supply.section2.length=0.5 m..4 m'")
    t_end = quantity(args.t_end, "s", "--t-end") if args.t_end else None
    if t_end is not None and not t_end > 0:
        raise ValueError(f"--t-end must be > 0 s, got {args.t_end!r}")
    rig = load_rig(args.rig)
    out = out_dir(args.out, FILES) if args.out else None
    bar = progress_printer("optimize", not args.json)
    from . import Terminated, raise_terminated

    old = signal.signal(signal.SIGTERM, raise_terminated)
    try:
        result = optimize(args.vary, rig, choose=args.choose, minimize=args.minimize,
                          front_points=args.front_points,
                          subject_to=args.subject_to, scenario=args.scenario, t_end=t_end,
                          solver=args.solver, method=args.method,
                          max_evaluations=args.max_evaluations, starts=args.starts,
                          seed=args.seed, workers=args.workers, scheduler=args.scheduler,
                          out=out, resume=args.resume, figure=args.figure,
                          progress=None if bar is None else (lambda d, n: bar(d / n)))
    except KeyboardInterrupt as e:
        what = "terminated (SIGTERM)" if isinstance(e, Terminated) else "interrupted"
        where = (f"every finished evaluation is in {out}/optimize.jsonl: rerun the same "
                 f"command with --resume to continue" if out else
                 "nothing kept (give --out DIR to keep every evaluation)")
        print(f"\nhydroline optimize: {what}; {where}", file=sys.stderr)
        return 143 if isinstance(e, Terminated) else 130
    finally:
        signal.signal(signal.SIGTERM, old)
    if args.json:
        dump_json(result.to_dict())
        return 0 if result.feasible else 1
    print(f"hydroline optimize: minimise {result.objective_name} on "
          f"{rig.get('rig.name', rig.source)}, {result.scenario}, {result.method} method "
          f"({result.evaluations} evaluations, {result.n_computed} run now, "
          f"{result.wall_time:.1f} s)")
    for v in result.variables:
        print(f"  variable {v}")
    for c in result.constraints:
        print(f"  subject to {c}")
    rows = []
    for p in result.optimum:
        (base, unit), (best, _) = (shown_value(result.baseline[p], result.units.get(p)),
                                   shown_value(result.optimum[p], result.units.get(p)))
        rows.append([p, unit or "-", base, best])
    print_table(["parameter", "unit", "baseline", "optimum"], rows)
    shown = [result.objective_name] + [c.split("<")[0].split(">")[0] for c in result.constraints]
    print_table(["metric", "baseline", "optimum"],
                [[m, result.baseline_metrics.get(m), result.metrics.get(m)]
                 for m in dict.fromkeys(shown)])
    print(f"  feasible: {result.feasible}; converged: {result.converged} ({result.message})")
    if result.front is not None:
        print(f"  Pareto front ({len(result.front)} points; the optimum above is "
              f"{result.objective_name}'s minimum):")
        print_table(list(result.front[0]["variables"]) + list(result.objectives),
                    [list(p["variables"].values()) + list(p["objectives"].values())
                     for p in result.front])
    if result.active_constraints:
        print(f"  active constraints: {', '.join(result.active_constraints)}")
    if result.at_bounds:
        print(f"  at a bound of its range: {', '.join(result.at_bounds)}")
    if result.files:
        print(f"  wrote {', '.join(str(p) for p in result.files.values())}")
    if not result.feasible:
        print("hydroline optimize: no evaluated point meets every constraint (the optimum "
              "shown violates least)", file=sys.stderr)
        return 1
    return 0
