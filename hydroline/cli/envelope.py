"""``hydroline envelope``: the rig's performance envelope with its lines in the loop (issue 29)."""
from __future__ import annotations

import csv
import math
import re

import numpy as np

from ..rigs import load_rig
from .common import SCHEMA_VERSION, add_solver_option, atomic_outputs, dump_json, out_dir, \
    print_table, progress_printer, quantity

#: Files written by ``--out``.
FILES = ("envelope.csv", "envelope.json", "envelope.png")


def register(sub):
    """Add the ``hydroline envelope`` subcommand and its options to the command's parser.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers object of the ``hydroline`` parser;
        ``run`` is set as the subcommand's ``func``
    """
    p = sub.add_parser(
        "envelope", help="performance envelope: the largest sine amplitude the actuator holds "
        "at each frequency, with the supply and return lines in the loop, beside an ideal "
        "constant supply and the vendor's analytic curve",
        description="At each frequency, as a fatigue-test controller's amplitude control does "
        "(the reference's amplitude and phase adjusted until the piston reaches its target; the "
        "loop's linear roll-off is compensated, not a limit), find by bisection on closed-loop "
        "runs at their periodic state the largest sine displacement amplitude reached with the "
        "position's harmonic distortion within --distortion, and what stops a larger one: "
        "stroke, valve (spool or current at its limit for want of flow), supply_dip / "
        "return_rise (the line's pulsation at the valve's port: its loss of the valve's drop, "
        "or its troughs at the gas-release pressure), force (the actuator at its stall "
        "force), gas_release (in a chamber), distortion. The same with an ideal constant "
        "supply and tank (lines, "
        "manifolds and accumulators taken out, the valve's ports at their rest pressures) and "
        "the vendor's analytic envelope for it (stroke/2; Q(p_L)/A, its fundamental at the "
        "distortion allowed; (p_s - p_t) A/m). With --out DIR: envelope.csv, envelope.json and "
        "envelope.png (log-log displacement, velocity, acceleration and force against "
        "frequency, the limiting mechanism shaded).")
    p.add_argument("rig", nargs="?", help="rig TOML file or shipped rig name (default: the "
                   "embedded Ayalew & Kulakowski 2005 rig)")
    p.add_argument("--frequencies", default="0.5 Hz..200 Hz",
                   help="'LOW..HIGH' (log-spaced, --points of them) or a comma-separated list, "
                   "with units (default: '0.5 Hz..200 Hz')")
    p.add_argument("--points", type=int, default=20,
                   help="frequencies of a LOW..HIGH range (default 20)")
    p.add_argument("--distortion", default="5 %",
                   help="total harmonic distortion of the position allowed, e.g. '5 %%' or "
                   "'0.05' (default: 5 %%)")
    p.add_argument("--axis", help="multi-axis rig: the driven axis (the others hold), or 'all' "
                   "(every axis together, in phase); default: the first")
    p.add_argument("--no-constant-supply", dest="constant_supply", action="store_false",
                   help="skip the ideal constant supply's curve")
    p.add_argument("--workers", type=int, default=1,
                   help="local worker processes (default 1)")
    p.add_argument("--scheduler", metavar="ADDR",
                   help="a Dask scheduler ('tcp://host:port', or 'local' for a local cluster "
                   "of --workers processes)")
    add_solver_option(p)
    p.add_argument("--out", metavar="DIR", help="folder for envelope.csv, envelope.json and "
                   "envelope.png")
    p.add_argument("--json", action="store_true",
                   help="print only the JSON document on stdout: {schema_version, "
                   "frequency_hz, displacement_amplitude_m, velocity_amplitude_m_s, "
                   "acceleration_amplitude_m_s2, force_amplitude_n, limited_by, ..., "
                   "constant_supply: {...}, analytic: {...}}")
    p.set_defaults(func=run)


def frequencies(text: str, points: int) -> np.ndarray:
    """The test frequencies of ``--frequencies`` and ``--points``, [Hz].

    Parameters
    ----------
    text : str
        "LOW..HIGH" (``points`` log-spaced) or "f1, f2, ..." (units allowed)
    points : int
        Frequencies of a range, >= 1, [-]

    Returns
    -------
    ndarray
        Ascending, [Hz]
    """
    if ".." in text:
        low, _, high = text.partition("..")
        f0, f1 = quantity(low.strip(), "Hz", "--frequencies"), quantity(high.strip(), "Hz",
                                                                        "--frequencies")
        if not 0 < f0 <= f1:
            raise ValueError(f"--frequencies: must be 0 < LOW <= HIGH [Hz], got {text!r}")
        if points < 1:
            raise ValueError(f"--points: must be >= 1, got {points}")
        return np.geomspace(f0, f1, points) if points > 1 else np.array([f0])
    values = [quantity(v.strip(), "Hz", "--frequencies") for v in text.split(",") if v.strip()]
    if not values or not all(v > 0 for v in values):
        raise ValueError(f"--frequencies: must be > 0 [Hz], got {text!r}")
    return np.sort(np.array(values))


def distortion_value(text: str) -> float:
    """``--distortion`` as a fraction: "5 %" -> 0.05, "0.05" -> 0.05.

    Parameters
    ----------
    text : str
        As typed

    Returns
    -------
    float
        The fraction, [-].
    """
    m = re.fullmatch(r"\s*([0-9.eE+-]+)\s*(%?)\s*", text)
    try:
        value = float(m.group(1)) / (100.0 if m.group(2) else 1.0)
    except (AttributeError, ValueError):
        raise ValueError(f"--distortion: a fraction or a percentage, e.g. '5 %', got {text!r}") \
            from None
    if not 0 < value < 1:
        hint = (f" (a bare number is a fraction: did you mean '{text.strip()} %'?)"
                if not m.group(2) and 1 <= value < 100 else "")
        raise ValueError(f"--distortion: must lie between 0 and 100 %, got {text!r}{hint}")
    return value


def write_csv(result, path) -> None:
    """One row per frequency (:meth:`hydroline.studies.envelope.EnvelopeResult.rows`).

    Parameters
    ----------
    result : EnvelopeResult
        The study's outcome
    path : Path
        CSV file to write
    """
    rows = result.rows()
    columns = list(dict.fromkeys(k for r in rows for k in r))
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, columns)
        w.writeheader()
        w.writerows(rows)


def json_document(result) -> dict:
    """The ``--json`` document: ``schema_version`` and
    :meth:`hydroline.studies.envelope.EnvelopeResult.to_dict`.

    Parameters
    ----------
    result : EnvelopeResult
        The study's outcome

    Returns
    -------
    dict
        The document.
    """
    return {"schema_version": SCHEMA_VERSION, **result.to_dict()}


def run(args) -> int:
    """Run ``hydroline envelope``: the envelope, its table, files and figure.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line, with the options :func:`register` adds

    Returns
    -------
    int
        Exit code, 0 on success
    """
    from ..studies.envelope import envelope

    freqs = frequencies(args.frequencies, args.points)
    tolerance = distortion_value(args.distortion)
    if args.workers < 1:
        raise ValueError(f"--workers: must be >= 1, got {args.workers}")
    rig = load_rig(args.rig)
    out = out_dir(args.out, FILES) if args.out else None
    bar = progress_printer("envelope", not args.json)
    result = envelope(rig, freqs, axis=args.axis, distortion=tolerance,
                      constant_supply=args.constant_supply, workers=args.workers,
                      scheduler=args.scheduler, solver=args.solver,
                      progress=None if bar is None else (lambda d, n: bar(d / n)))
    if out is not None:
        from ..studies.envelope import envelope_figure

        with atomic_outputs(out) as temp:
            write_csv(result, temp("envelope.csv"))
            with open(temp("envelope.json"), "w") as fh:
                dump_json(json_document(result), fh)
            envelope_figure(result, temp("envelope.png"))
    if args.json:
        dump_json(json_document(result))
        return 0
    print(f"hydroline envelope: {result.rig}, axis {result.axis}, distortion <= "
          f"{tolerance * 100:g} % ({result.wall_time:.1f} s)")
    rows = []
    const = result.constant_supply
    for k, f in enumerate(result.frequency_hz):
        h = result.hoses[k] if k < len(result.hoses) else None
        c = const[k] if k < len(const) else None
        rows.append([f, None if h is None else h["displacement_amplitude_m"] * 1e3,
                     None if h is None else h["velocity_amplitude_m_s"],
                     None if h is None else h["limited_by"],
                     None if c is None else c["displacement_amplitude_m"] * 1e3,
                     None if c is None else c["limited_by"],
                     result.analytic["displacement_amplitude_m"][k] * 1e3,
                     result.analytic["limited_by"][k]])
    print_table(["f [Hz]", "x [mm]", "v [m/s]", "limited by", "const. x [mm]", "limited by",
                 "analytic x [mm]", "limited by"], rows)
    cut = [(f, 1 - h["displacement_amplitude_m"] / c["displacement_amplitude_m"])
           for f, h, c in zip(result.frequency_hz, result.hoses, const)
           if c["displacement_amplitude_m"] > 0]
    if cut:
        f, worst = max(cut, key=lambda fc: fc[1])
        if worst > 0.02:
            print(f"  the lines cut the envelope most at {f:.3g} Hz: {worst * 100:.0f} % below "
                  f"the constant supply's")
    for e in result.errors:
        print(f"  ERROR: {e}")
    if out is not None:
        print(f"  wrote {', '.join(str(out / n) for n in FILES)}")
    else:
        print("  (--out DIR writes envelope.csv, envelope.json and the figure envelope.png)")
    return 0 if not result.errors else 1
