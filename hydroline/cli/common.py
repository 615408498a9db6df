"""Helpers shared by the subcommands: units on the command line, output folders, tables.

Output files are checked before a run (:func:`out_dir`) and written atomically
(:func:`atomic_outputs`): each to a temporary file in the output folder, renamed over the old
one only when all of them are written, so a run that fails (an error, a full disk, Ctrl-C)
leaves the previous results as they were and no partial file behind.
"""
from __future__ import annotations

import contextlib
import errno
import json
import os
import sys
import tempfile
from pathlib import Path

from ..units import parse_quantity

__all__ = ["SCHEMA_VERSION", "quantity", "out_dir", "atomic_outputs", "OutputError",
           "print_table", "dump_json", "progress_printer", "settling_cell", "settling_legend",
           "add_settling_band_option", "amplitude_cell", "run_network", "note_cost"]


class OutputError(ValueError):
    """An output path that cannot be written; the message is one line naming it.

    Parameters
    ----------
    *args : str
        The message: one line naming the path.
    **kwargs : dict
        None taken (as ``ValueError``).
    """


def quantity(text, unit, name):
    """A command-line quantity with units -> SI float (UnitError, one line, on misuse).

    Parameters
    ----------
    text : str
        The option's value as typed, e.g. ``"3000 psi"`` or ``"12.7mm"``
    unit : str
        The SI unit wanted, e.g. ``"Pa"``, ``"m"`` (see
        :func:`hydroline.units.parse_quantity`)
    name : str
        The option's name, for the message, e.g. ``"--position"``

    Returns
    -------
    float
        The value in ``unit``, [unit]
    """
    return parse_quantity(text, unit, name)


def out_dir(path, files=(), option: str = "--out") -> Path:
    """The output folder, created and checked writable before any work is done.

    Parameters
    ----------
    path : str or Path
        The folder (created with its parents when missing)
    files : iterable
        Names of the files the command will write there; each must not be
        a folder
    option : str
        The option that named it, for the messages

    Returns
    -------
    Path

    Raises
    ------
    OutputError
        One line: an existing file (not a folder) at or above ``path``, a folder that
        cannot be created or written, or a file name taken by a folder
    """
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise OutputError(f"{option}: {path} exists and is not a folder; give a folder")
    for parent in p.parents:
        if parent.exists():
            if not parent.is_dir():
                raise OutputError(f"{option}: {path} lies under {parent}, which is a file, "
                                  f"not a folder")
            break
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputError(f"{option}: cannot create the folder {path} "
                          f"({e.strerror or e})") from None
    try:   # writable? (os.access is wrong for root and some file systems: try it)
        fd, probe = tempfile.mkstemp(prefix=".hydroline-probe-", dir=p)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise OutputError(f"{option}: cannot write in the folder {path} "
                          f"({e.strerror or e})") from None
    for name in files:
        target = p / name
        if target.is_dir():
            raise OutputError(f"{option}: {target} is a folder; the command writes a file "
                              f"of that name there (move the folder or choose another {option})")
    return p


@contextlib.contextmanager
def atomic_outputs(folder):
    """Write several files so that either all of them are replaced or none is.

    ``with atomic_outputs(out) as temp: df.to_csv(temp("results.csv"))`` -- ``temp(name)``
    gives a temporary path in ``folder`` (hidden, same extension, so writers that look at the
    extension still work); when the block ends without an exception every temporary file is
    renamed (``os.replace``, atomic on one file system) to its name, otherwise all of them are
    removed. A full disk gives one line (:class:`OutputError`) naming the file.

    Parameters
    ----------
    folder : str or Path
        The output folder (checked by :func:`out_dir`); the temporary
        files are made there, on the same file system as their targets

    Yields
    ------
    callable
        ``temp(name) -> Path``: the temporary path to write for the file ``name``
    """
    folder = Path(folder)
    pending = {}

    def temp(name):
        target = folder / name
        fd, tmp = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=f".tmp{target.suffix}",
                                   dir=folder)
        os.close(fd)
        pending[target] = Path(tmp)
        return Path(tmp)

    try:
        yield temp
        mode = 0o666 & ~_umask()         # what a plain open() would have given
        for target, tmp in pending.items():
            os.chmod(tmp, mode)
            os.replace(tmp, target)
        pending.clear()
    except OSError as e:
        raise OutputError(_os_message(e, folder)) from None
    finally:
        for tmp in pending.values():
            with contextlib.suppress(OSError):
                tmp.unlink()


def _umask() -> int:
    mask = os.umask(0o22)
    os.umask(mask)
    return mask


def _os_message(e: OSError, folder) -> str:
    where = e.filename or folder
    if e.errno == errno.ENOSPC:
        return f"no space left on the device writing {where}; the previous results are unchanged"
    if e.errno == errno.EDQUOT:
        return f"disk quota exceeded writing {where}; the previous results are unchanged"
    return f"cannot write {where} ({e.strerror or e}); the previous results are unchanged"


def print_table(headers, rows, file=None):
    """Plain aligned text table.

    Parameters
    ----------
    headers : sequence of str
        Column headings
    rows : iterable
        Rows, each a sequence of cells (a float is printed with four
        significant digits, None as "-")
    file : file-like
        Where to print (stdout when None)
    """
    file = file or sys.stdout
    cells = [[str(h) for h in headers]] + [[_fmt(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    for k, r in enumerate(cells):
        print("  ".join(c.rjust(w) for c, w in zip(r, widths)), file=file)
        if k == 0:
            print("  ".join("-" * w for w in widths), file=file)


def _fmt(c):
    if c is None:
        return "-"
    if isinstance(c, float):
        return f"{c:.4g}"
    return str(c)


#: Version of the ``--json`` documents of ``simulate`` and ``layout`` (docs/summary.schema.json,
#: docs/layout.schema.json): raised when a documented key is renamed, removed or changes its
#: meaning, not when one is added.
SCHEMA_VERSION = 1


def dump_json(obj, file=None):
    """Strict JSON (RFC 8259) on stdout or ``file``: NaN and +-inf, which JSON has no word
    for, are written as null (a metric that does not exist).

    Parameters
    ----------
    obj : dict, list or scalar
        The data (nested dicts, lists and tuples of numbers, strings,
        booleans and None)
    file : file-like
        Where to write (stdout when None)
    """
    import math

    def clean(v):
        if isinstance(v, float):
            return v if math.isfinite(v) else None
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        return v

    json.dump(clean(obj), file or sys.stdout, indent=2, allow_nan=False)
    (file or sys.stdout).write("\n")


def progress_printer(label, enabled=True):
    """A callable(fraction) drawing a one-line progress bar on stderr (when it is a TTY).

    Parameters
    ----------
    label : str
        Text before the bar
    enabled : bool
        False: no bar (e.g. under ``--json``)

    Returns
    -------
    callable or None
        ``show(fraction)``, fraction done in 0..1 [-]; None when disabled or
        stderr is no terminal
    """
    if not enabled or not sys.stderr.isatty():
        return None
    drawn = [None]   # the line last drawn: a repeated one (100 % twice) is not drawn again

    def show(frac):
        frac = min(max(float(frac), 0.0), 1.0)
        n = int(frac * 30)
        line = f"{label} [{'#' * n}{'.' * (30 - n)}] {frac * 100:5.1f} %"
        if line == drawn[0] or (drawn[0] is not None and drawn[0].endswith("100.0 %")):
            return   # (the bar is finished: its line ended)
        drawn[0] = line
        sys.stderr.write(f"\r{line}" + ("\n" if frac >= 1 else ""))
        sys.stderr.flush()

    return show


def settling_cell(metrics: dict):
    """A port's settling time for a table: [ms], "~..." when estimated, "...*" where a crest
    lies at the band's edge (the time may jump by half a period), None when there is none.

    Parameters
    ----------
    metrics : dict
        A port's metrics, holding ``settling_time_s`` [s] (or None),
        ``settling_method`` and ``settling_jump_s``

    Returns
    -------
    float, str or None
        Settling time, [ms]
    """
    v = metrics["settling_time_s"]
    if v is None:
        return None
    estimated = metrics.get("settling_method") == "estimated"
    if not estimated and not metrics.get("settling_jump_s"):
        return v * 1e3
    return f"{'~' if estimated else ''}{v * 1e3:.4g}{'*' if metrics.get('settling_jump_s') else ''}"


def run_network(rig, scenario: str, duration: float):
    """A run's circuit and network, built before it starts: the model's size for the output
    and cost estimates.

    Parameters
    ----------
    rig : Rig
        The rig
    scenario : str
        The experiment's name
    duration : float
        Simulated time, [s]

    Returns
    -------
    tuple
        (Circuit, Network)
    """
    from ..scenarios.experiments import build_scenario
    from ..system import build_circuit

    circuit = build_circuit(rig)
    sc = build_scenario(rig, scenario, duration, axes=circuit.axes)
    return circuit, circuit.network(sc.commands)


def note_cost(command, network, solver, duration, rows, columns, *, streamed=False, write=False,
              dt_out=None, variants=1, workers=1, file="results.csv") -> None:
    """One note on stderr before a run estimated (:func:`hydroline.limits.run_cost`) to take
    more than a few seconds or a few hundred MB: the model's size, the output and the
    estimate, so that a long run is not taken for a hang.

    Parameters
    ----------
    command : str
        The subcommand, for the note
    network : Network
        The run's model (:func:`run_network`)
    solver : str
        --solver: "auto" and "compiled" build the compiled core if needed
    duration : float
        Simulated time of one run, [s]
    rows : int
        Output rows of one run, [-]
    columns : int
        Output columns (time, signals, states), [-]
    streamed : bool
        The table is streamed to results.csv, not kept in memory
    write : bool
        results.csv is written
    dt_out : float
        --dt-out [s], or None (for the hint)
    variants : int
        Runs of the model (a sweep's variants), [-]
    workers : int
        Processes running them side by side, [-]
    file : str
        The file the rows are written to, for the note
    """
    from .. import compiled
    from ..limits import run_cost

    n = len(network.state_names)
    compiles = solver in ("auto", "compiled") and compiled.available()

    def cost(build):
        return run_cost(n, duration, rows, columns, build=build, in_memory=not streamed,
                        csv=write, variants=variants, workers=workers)

    estimate = cost(compiles)
    if not estimate.notable:
        return
    if compiles:   # (looked up only for a large run)
        try:
            builds = compiled.needs_build(network)
        except (compiled.CompilerUnavailable, compiled.UnsupportedOperation):
            builds = False   # the run goes to CVODES instead
        if not builds:
            estimate = cost(False)
            if not estimate.notable:
                return
    what = f"{n} states, {duration:g} s simulated"
    if variants > 1:
        what += f" per variant, {variants} variants"
    else:
        what += f", {rows:,} rows x {columns} columns" + (f" to {file}" if write else "")
    hint = ""
    if estimate.write_seconds > 0.5 * estimate.seconds:
        hint = ("; --dt-out 10 ms would write 1/100 of it" if dt_out is None
                else "; a larger --dt-out writes less")
    print(f"hydroline {command}: note: a large run: {what}: {estimate.describe()}{hint}",
          file=sys.stderr, flush=True)


def add_solver_option(parser):
    """Add ``--solver`` (the integrator, one of :data:`hydroline.engine.backends.SOLVERS`) to a
    subcommand's parser.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser
    """
    parser.add_argument("--solver", default="auto",
                        choices=("auto", "compiled", "radau", "cvodes", "scipy"),
                        help="auto (default: the compiled C core where a C compiler exists, else "
                        "CVODES; its BDF, or its Radau IIA at 100x the tolerances where the "
                        "model's lightly damped upper modes cap the BDF's orders: short hoses, "
                        "many modes), compiled (its variable-order BDF), radau (the compiled "
                        "core's Radau IIA, order 5, at the tolerances given; docs/engine.md), "
                        "cvodes (CasADi + SUNDIALS) or the reference SciPy path")


def add_settling_band_option(parser):
    """Add ``--settling-band`` (the port pressures' settling band) to a subcommand's parser.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser
    """
    parser.add_argument("--settling-band", default="2%", metavar="BAND",
                        help="band the port pressures' settling time is read against: '2%%' "
                        "(default: +-2 %% of the final absolute pressure, the operating "
                        "pressure a fluid-power engineer reads a trace against) or e.g. "
                        "'5%% of change' (+-5 %% of the steady pressure change, the control "
                        "engineer's step-response band)")


def amplitude_cell(metrics: dict):
    """A port's amplitude for a table: [MPa], "...^" where the ringing lasts fewer than
    :data:`hydroline.traces.metrics.VERDICT_MARGIN` periods above 1 % of the excursion (near
    the 'no oscillation' verdict, where the amplitude is a share of the swing that fades to 0
    at the verdict), None when there is none.

    Parameters
    ----------
    metrics : dict
        A port's metrics, holding ``amplitude_mpa`` [MPa] (or None) and
        ``ringing_periods`` [-]

    Returns
    -------
    float, str or None
        Amplitude, [MPa]
    """
    from ..traces.metrics import VERDICT_MARGIN

    a, periods = metrics["amplitude_mpa"], metrics.get("ringing_periods")
    if a is None or periods is None or periods >= VERDICT_MARGIN:
        return a
    return f"{a:.4g}^"


def settling_legend(summaries) -> str:
    """One line saying what the settling column means: the band in words and its half-width
    per port, and the marks of :func:`settling_cell`.

    Parameters
    ----------
    summaries : list of tuple
        Port metrics (``settling_band``, ``settling_band_mpa``),
        labelled: ``[(label, metrics), ...]``; the half-widths of one
        label are given as their range

    Returns
    -------
    str
    """
    bands = [(label, m) for label, m in summaries if m.get("settling_band")]
    if not bands:
        return ""
    by_label = {}
    for label, m in bands:
        if m.get("settling_band_mpa") is not None:
            by_label.setdefault(label, []).append(m["settling_band_mpa"])
    widths = ", ".join(f"{label} +-{min(v):.3g}" + (f"-{max(v):.3g}" if f"{max(v):.3g}" !=
                                                     f"{min(v):.3g}" else "") + " MPa"
                       for label, v in by_label.items())
    return (f"settling: within {bands[0][1]['settling_band']}" + (f" ({widths})" if widths else "")
            + " about the pressure's one-period mean; '~' estimated from the decay of the "
            "oscillation; '*' a crest at the band's edge: the time may jump by half a period")
