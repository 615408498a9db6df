"""``hydroline sweep``: a parameter study of a rig, local processes or a Dask cluster."""
from __future__ import annotations

import argparse
import os
import signal
import sys
import time

import numpy as np

from ..rigs import load_rig
from ..scenarios.experiments import default_scenario
from ..studies.sweep import sweep
from .common import (add_solver_option, dump_json, note_cost, print_table, quantity,
                     run_network)

EPILOG = """\
values (after PATH=; PATH is a parameter's dotted path in the rig file, values carry units):
  150 MPa,178 MPa,220 MPa          levels of a full factorial (one value: constant override)
  linspace(150 MPa, 220 MPa, 8)    8 evenly spaced levels
with --samples N (random design; variant i drawn from numpy default_rng([seed, i])):
  uniform(LOW, HIGH)               e.g. 'uniform(150 MPa, 220 MPa)'
  loguniform(LOW, HIGH)            log-uniform, LOW > 0
  normal(MEAN, STD)                e.g. 'normal(178 MPa, 10 MPa)' (not truncated)
  lognormal(MEDIAN, SIGMA)         MEDIAN*exp(SIGMA*z), SIGMA a plain number
  triangular(LOW, MODE, HIGH)
  choice(V1, V2, ...)              a list of levels is a choice too; one value a constant
PATH1+PATH2=VALUES sets both paths to the same value, e.g.
  --set 'supply.section2.diameter+return.section2.diameter=12.7 mm,15.9 mm,19.05 mm'
On a circuit rig PATH is circuit.<component>.<parameter>, read in the unit the component
declares ('hydroline circuit --types'), e.g.
  hydroline sweep two_axis --set 'circuit.axis2.supply_hose.length=1.5 m,3.048 m'
and a rig with several servo axes gets its metrics per axis (<axis>.supply.amplitude_mpa,
<axis>.position_disturbance_mm, ...).

examples:
  hydroline sweep --set 'supply.section2.bulk_modulus=150 MPa,178 MPa,220 MPa' \\
                  --set 'supply.accumulator.precharge_pressure=10 MPa,14 MPa' --out bm
  hydroline sweep --samples 200 --set 'supply.section2.bulk_modulus=normal(178 MPa, 10 MPa)' \\
                  --set 'return.section2.bulk_modulus=uniform(140 MPa, 180 MPa)' --out mc
  hydroline sweep ... --out mc --resume          # continue after an interruption
  hydroline sweep ... --scheduler tcp://10.0.0.5:8786   # an existing Dask cluster
  hydroline sweep ... --scheduler local --workers 8     # a local Dask cluster

out/sweep.jsonl gets every row as it finishes (the record --resume continues from; on
Ctrl-C or SIGTERM the variants already running are finished and recorded too);
out/sweep.csv (and out/sweep.parquet where pyarrow is installed, else a note says so) the
table in variant order: variant, inputs in SI units (one column per path), supply/return
frequency_hz, amplitude_mpa, settling_time_s, wall_time_s, supply/return_settling_method
("measured" within the metrics window, "estimated" from the decay of the ringing at the
piston stop, as in 'hydroline layout'), warnings, error (the reason a variant failed, else
empty). A random design resumed with a smaller --samples keeps the extra rows in
sweep.jsonl, not in the table (a note says so).
"""


def register(sub):
    """Add the ``hydroline sweep`` subcommand and its options to the command's parser.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers object of the ``hydroline`` parser
        (from ``add_subparsers``); ``run`` is set as the
        subcommand's ``func``
    """
    p = sub.add_parser(
        "sweep", help="parameter study: full factorial or random samples over rig parameters, "
        "in parallel, resumable, on local processes or a Dask cluster",
        description="Run a scenario for every variant of a rig: a full factorial over the values\n"
        "given with --set, or --samples N random variants from distributions. Each variant:\n"
        "copy the rig, set the parameters, simulate, summarize. A failed variant is recorded\n"
        "with its reason and the sweep goes on.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("rig", nargs="?", help="base rig TOML file (default: the embedded Ayalew & Kulakowski 2005 rig)")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="PATH=VALUES",
                   help="a parameter and its values with units (repeat for more; syntax below)")
    p.add_argument("--samples", type=int, metavar="N", help="random design of N variants (default: full factorial)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="seed of the random design (default 0)")
    p.add_argument("--scenario", metavar="NAME",
                   help="the experiment each variant runs: open-loop-step, closed-loop-sine, "
                   "position-step or the rig's own [scenario.NAME] (default: the rig's "
                   "rig.scenario, else open-loop-step)")
    p.add_argument("--t-end", help="simulated time per variant with unit, e.g. '0.25 s' (scenario default)")
    add_solver_option(p)
    p.add_argument("--workers", type=int, metavar="W",
                   help="local worker processes, or workers of --scheduler local (default: CPU count)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on Dask: tcp://host:port of an existing scheduler (hydroline "
                   "installed on its workers), or 'local' for a local dask.distributed cluster")
    p.add_argument("--out", default="hydroline-sweep",
                   help="results folder: sweep.jsonl, sweep.csv, sweep.parquet (default: hydroline-sweep)")
    p.add_argument("--resume", action="store_true",
                   help="continue the sweep in --out: keep its finished rows, run the rest")
    p.add_argument("--json", action="store_true", help="print the table as a JSON list on stdout only")
    p.set_defaults(func=run)


class _Progress:
    """A progress bar on stderr (a TTY), or a line per 10 % (a log file); ``starting(n)`` is
    called once, when the sweep's inputs are checked and its ``n`` variants are about to run."""

    def __init__(self, enabled, starting=None):
        self.enabled = enabled
        self.starting = starting
        self.tty = sys.stderr.isatty()
        self.start = time.perf_counter()
        self.base = None
        self.first = None
        self.last_decile = -1

    def __call__(self, done, total, failed):
        if self.starting is not None:
            starting, self.starting = self.starting, None
            if total > done:
                starting(total - done)
        if not self.enabled or total == 0:
            return
        now = time.perf_counter()
        if self.base is None:
            self.base = done
        if self.first is None and done > self.base:     # rate from the first finished variant
            self.first = (done, now)                      # on (start-up excluded)
        d0, t0 = self.first or (done, now)
        rate = (done - d0) / (now - t0) if now > t0 and done > d0 else 0.0
        eta = f", ETA {(total - done) / rate:.0f} s" if rate > 0 and done < total else ""
        text = f"{done}/{total} variants, {failed} failed, {now - self.start:.0f} s{eta}"
        if self.tty:
            if getattr(self, "finished", False):
                return   # (the bar's last line is drawn once)
            self.finished = done >= total
            n = int(30 * done / total)
            sys.stderr.write(f"\rsweep [{'#' * n}{'.' * (30 - n)}] {text}   ")
            if done >= total:
                sys.stderr.write("\n")
            sys.stderr.flush()
        else:
            decile = int(10 * done / total)
            if decile > self.last_decile:
                self.last_decile = decile
                print(f"sweep: {text}", file=sys.stderr, flush=True)


def run(args) -> int:
    """Run ``hydroline sweep``: the parameter study's variants, in parallel and resumable, into results.csv and a summary.

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
    scenario = args.scenario or default_scenario(rig)
    t_end = quantity(args.t_end, "s", "--t-end") if args.t_end else None
    if t_end is not None and not t_end > 0:
        raise ValueError(f"--t-end must be > 0 s, got {args.t_end!r}")
    if not args.sets:
        raise ValueError("give at least one --set PATH=VALUES, e.g. "
                         "--set 'supply.section2.bulk_modulus=150 MPa,220 MPa'")

    def note_cost_of(variants):   # (once the design is known and checked)
        _note_sweep_cost(args, rig, scenario, t_end, variants)

    progress = _Progress(not args.json, note_cost_of)
    done = {"rows": 0}

    def count(row):
        done["rows"] += 1

    from . import Terminated, raise_terminated

    old = signal.signal(signal.SIGTERM, raise_terminated)    # a kill finishes cleanly, like Ctrl-C
    try:
        result = sweep(args.sets, rig, samples=args.samples, seed=args.seed,
                       scenario=scenario, t_end=t_end, solver=args.solver,
                       workers=args.workers, scheduler=args.scheduler, out=args.out,
                       resume=args.resume, progress=progress, callback=count)
    except KeyboardInterrupt as e:
        what = "terminated (SIGTERM)" if isinstance(e, Terminated) else "interrupted"
        print(f"\nhydroline sweep: {what} after {done['rows']} variants of this run; "
              f"every finished row is in {args.out}/sweep.jsonl: rerun the same command with "
              f"--resume to continue", file=sys.stderr)
        return 143 if isinstance(e, Terminated) else 130
    finally:
        signal.signal(signal.SIGTERM, old)
    table = result.table
    if args.json:
        for note in result.notes:   # stdout holds only the JSON
            print(f"hydroline sweep: note: {note}", file=sys.stderr)
        dump_json([{k: _plain(v) for k, v in r.items()} for r in table.to_dict("records")])
        return _failed_status(result, args)
    d = result.design
    if args.scheduler == "local":
        where = f"a local Dask cluster of {args.workers or 'CPU-count'} workers"
    elif args.scheduler:
        where = f"the Dask scheduler at {args.scheduler}"
    else:
        where = f"{args.workers or 'CPU-count'} local worker processes"
    print(f"hydroline sweep: {d.describe()}, {scenario} on {rig.get('rig.name', rig.source)}, "
          f"{where}")
    print("  parameters: " + "; ".join(f"{p.name} = {p.describe()}" for p in d.parameters))
    print(f"  {result.n_computed} variants run now, {len(table) - result.n_computed} from the "
          f"results file; {result.n_failed} failed; {result.wall_time:.1f} s")
    inputs = d.columns
    if len(table) <= 20:
        if len(result.axes) > 1:    # per axis: port amplitudes and the position disturbance
            shown = [(f"{a}.{side}.amplitude_mpa", f"{a} {side} [MPa]") for a in result.axes
                     for side in ("supply", "return")]
            shown += [(f"{a}.position_disturbance_mm", f"{a} disturbance [mm]")
                      for a in result.axes]
        else:
            shown = [("supply_frequency_hz", "supply [Hz]"), ("supply_amplitude_mpa", "supply [MPa]"),
                     ("return_frequency_hz", "return [Hz]"), ("return_amplitude_mpa", "return [MPa]")]
        shown.append(("wall_time_s", "wall [s]"))
        heads = ["variant", *inputs, *[h for _, h in shown], "error"]
        rows = [[r["variant"], *[r[c] for c in inputs], *[_opt(r[c]) for c, _ in shown],
                 _short(r["error"])] for r in table.to_dict("records")]
        print_table(heads, rows)
    else:
        rows = []
        for c in result.metrics:
            v = table[c].to_numpy(dtype=float)
            ok = v[np.isfinite(v)]
            rows.append([c, len(ok), *(np.percentile(ok, [0, 5, 50, 95, 100]) if len(ok) else [None] * 5)])
        print_table(["metric", "n", "min", "5 %", "median", "95 %", "max"], rows)
        fails = result.failed
        for r in fails.head(10).to_dict("records"):
            print(f"  failed variant {r['variant']}: {r['error']}")
        if len(fails) > 10:
            print(f"  ... and {len(fails) - 10} more failed variants (column 'error')")
    print(f"  wrote {', '.join(str(p) for p in result.files.values())}")
    for note in result.notes:       # parquet not written, rows beyond a smaller --samples
        print(f"  note: {note}")
    return _failed_status(result, args)


def _note_sweep_cost(args, rig, scenario, t_end, variants):
    """The cost note of :func:`hydroline.cli.common.note_cost` for a sweep of ``variants``
    runs of the base rig's model (on --workers processes, default the CPU count)."""
    from ..scenarios.experiments import build_scenario
    from .simulate import DT_OUT

    try:
        duration = t_end or build_scenario(rig, scenario).t_end
        _, network = run_network(rig, scenario, duration)
    except ValueError:   # the base rig alone does not build: each variant says why it fails
        return
    columns = 1 + len(network.signal_names) + len(network.state_names)
    note_cost("sweep", network, args.solver, duration, round(duration / DT_OUT) + 1, columns,
              variants=variants, workers=args.workers or os.cpu_count() or 1)


#: Exit status of a sweep in which at least one variant failed (2 stays "bad input").
EXIT_VARIANTS_FAILED = 1


def _failed_status(result, args) -> int:
    """0 when every variant ran; else one line on stderr with the count, and 1."""
    n = result.n_failed
    if not n:
        return 0
    first = result.failed.iloc[0]
    print(f"hydroline sweep: {n} of {len(result.table)} variants failed (reason in the 'error' "
          f"column of {args.out}/sweep.csv; the first, variant {first['variant']}: "
          f"{_short(str(first['error']), 120)})", file=sys.stderr)
    return EXIT_VARIANTS_FAILED


def _plain(v):
    if isinstance(v, float) and not np.isfinite(v):
        return None
    if isinstance(v, np.generic):
        return v.item()
    return v


def _opt(v):
    return None if v is None or (isinstance(v, float) and not np.isfinite(v)) else v


def _short(e, n=70):
    if not e:
        return ""
    return e if len(e) <= n else e[: n - 3] + "..."
