"""Limits on what one run may produce, estimated before it starts.

A run keeps its time series in memory (one float per column and output sample) unless it
streams them to a file; a long ``t_end`` at a fine output step would otherwise integrate for
hours and end in a MemoryError. :func:`output_estimate` gives the rows and bytes of a run
from ``t_end``, the output step and the number of columns; :func:`check_output_size` refuses
a run beyond :data:`MAX_TABLE_BYTES` in memory, or one whose CSV would not fit on the disk,
with one line saying how large it would be and what to change. :func:`run_cost` estimates
the wall time and memory of a run that is allowed (its model's size, the compiled core's
first build, the output rows), for the note a command prints before an expensive one.
"""
from __future__ import annotations

import math
import shutil
from dataclasses import dataclass
from pathlib import Path

__all__ = ["MAX_TABLE_BYTES", "CSV_BYTES_PER_VALUE", "OutputEstimate", "output_estimate",
           "check_output_size", "RunCost", "run_cost", "NOTE_SECONDS", "NOTE_BYTES"]

#: Largest time-series table a run keeps in memory, [bytes] (2 GiB: 86 columns of the default
#: rig at the default 0.1 ms output step are about 80 s of simulated time).
MAX_TABLE_BYTES = 2 * 1024**3

#: Bytes per value in a results CSV (``%.9g`` numbers and a separator, up to ~17), [bytes]
CSV_BYTES_PER_VALUE = 17


@dataclass(frozen=True)
class OutputEstimate:
    """Size of a run's output.

    Attributes
    ----------
    rows : int
        Output samples (a float when beyond 1e15), t_end / dt_out + 1, [-]
    columns : int
        Signals and states (plus time), [-]
    memory_bytes : int
        The table in memory (float64; the result frame doubles it briefly), [B]
    csv_bytes : int
        The table as CSV, [B]
    """

    rows: int
    columns: int
    memory_bytes: int
    csv_bytes: int

    def describe(self) -> str:
        """One line for messages, e.g. ``"1e+06 rows x 40 columns = 320 MB in memory, ..."``.

        Returns
        -------
        str
            Rows, columns, the size in memory and as CSV (B, kB, MB, ...)
        """
        return (f"{self.rows:.3g} rows x {self.columns} columns = {_size(self.memory_bytes)} in "
                f"memory, {_size(self.csv_bytes)} as CSV")


def _size(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if n < 1000 or unit == "PB":
            return f"{n:.3g} {unit}"
        n /= 1000
    return f"{n:.3g} EB"


def output_estimate(t_end: float, dt_out: float, n_columns: int) -> OutputEstimate:
    """Rows and bytes of a run of ``t_end`` [s] sampled every ``dt_out`` [s] with
    ``n_columns`` signals and states (time added).

    Parameters
    ----------
    t_end : float
        Simulated time, [s]
    dt_out : float
        Output step, [s] (<= 0: unbounded rows)
    n_columns : int
        Signals and states, without time, [-]

    Returns
    -------
    OutputEstimate
        Rows, columns and bytes in memory [B] and as CSV [B]
    """
    rows = t_end / dt_out + 1 if dt_out > 0 else math.inf
    rows = int(rows) if rows < 1e15 else rows      # huge: a float, for the message
    cols = int(n_columns) + 1
    return OutputEstimate(rows, cols, 8 * rows * cols, CSV_BYTES_PER_VALUE * rows * cols)


def check_output_size(t_end: float, dt_out: float, n_columns: int, *, stream_to=None,
                      csv_folder=None, name: str = "t_end") -> OutputEstimate:
    """Refuse, before it starts, a run whose output would not fit (one line, ValueError).

    Parameters
    ----------
    t_end : float
        Simulated time, [s]
    dt_out : float
        Output step, [s]
    n_columns : int
        Signals and states, [-]
    stream_to : path
        The CSV the run streams to (memory is then constant; only the disk
        is checked), or None (the table is kept in memory)
    csv_folder : path
        Where the run's CSV will be written (its free space is checked)
    name : str
        The option or key that set ``t_end``, for the message

    Returns
    -------
    OutputEstimate
        Rows, columns and bytes in memory [B] and as CSV [B]
    """
    est = output_estimate(t_end, dt_out, n_columns)
    if stream_to is None and est.memory_bytes > MAX_TABLE_BYTES:
        longest = MAX_TABLE_BYTES / (8 * est.columns) * dt_out
        raise ValueError(f"{name}: {t_end:g} s at a {dt_out:g} s output step is {est.describe()}, "
                         f"over the {_size(MAX_TABLE_BYTES)} a run keeps in memory; give at most "
                         f"about {longest:.3g} s, a coarser output step, or stream to a file")
    folder = Path(stream_to).parent if stream_to is not None else csv_folder
    if folder is not None:
        try:
            free = shutil.disk_usage(Path(folder) if Path(folder).exists() else Path.cwd()).free
        except OSError:
            free = None
        if free is not None and est.csv_bytes > free:
            raise ValueError(f"{name}: {t_end:g} s at a {dt_out:g} s output step is "
                             f"{est.describe()}; only {_size(free)} are free in {folder}")
    return est


# The cost model of a run: an estimate for a note, not a limit. Hand-fitted on the 2-core
# development machine (under a load of 2-3), with n the model's states:
#
#   build [s]        = BUILD_SECONDS + n / BUILD_STATES       (a model structure new to the cache)
#   build [B]        = BUILD_BYTES + BUILD_BYTES_PER_STATE * n   (the C compiler's memory)
#   integrate [s]    = t_end / INTEGRATION_SPEED * (n / REFERENCE_STATES)^1.5
#   write [s]        = CSV bytes / CSV_RATE
#   table [B]        = 2 * 8 * rows * columns   (kept in memory, doubled while it becomes the
#                                                result, one per variant running; 0 when
#                                                streamed to a file)
#   wall time        = build + integrate + write;  memory = the larger of build and table
#
# The compiled core's C source grows with the states (hydroline.compiled.codegen: the bordered
# Jacobian and its sparse LU; before it, the LU of the full Jacobian grew as ~n^3 and 330
# states took 95 s and 550 MB to compile): writing and compiling took 1.4, 2.2, 4.7 and 8.5 s
# of CPU for 138, 330, 570 and 890 states (6, 30, 60, 100 modes per section), the compiler
# 72-246 MB. Integration: 45 simulated seconds per second for a 58-state rig (600 s of
# closed-loop sine in 11-14 s, benchmarks/README.md); on the open-loop step 53x real time
# at the default rig's 138 states, 11x at 330 (n^1.75 between them).

#: Fixed part of a first build (compiler start-up, the BDF integrator's code), [s].
BUILD_SECONDS = 1.0
#: States written and compiled per second beyond it, [1/s].
BUILD_STATES = 90.0
#: Memory of the C compiler on a small model, [B], and its part per state, [B].
BUILD_BYTES = 40e6
BUILD_BYTES_PER_STATE = 0.23e6
#: Simulated seconds per wall second of the compiled integrator on REFERENCE_STATES states.
INTEGRATION_SPEED = 45.0
REFERENCE_STATES = 58
#: Bytes of CSV written per second, [B/s].
CSV_RATE = 15e6
#: A run estimated above these gets a note before it starts: wall time [s], memory [B].
NOTE_SECONDS = 10.0
NOTE_BYTES = 300e6


@dataclass(frozen=True)
class RunCost:
    """A run's estimated cost (the model in the comment above :data:`BUILD_SECONDS`).

    Attributes
    ----------
    build_seconds : float
        Writing and compiling the model's C core (0 when cached), [s]
    integrate_seconds : float
        Integration of all variants, [s]
    write_seconds : float
        Writing the CSV, [s]
    memory_bytes : float
        Peak memory: the compiler's or the table's, [B]
    """

    build_seconds: float
    integrate_seconds: float
    write_seconds: float
    memory_bytes: float

    @property
    def seconds(self) -> float:
        """Estimated wall time, [s]."""
        return self.build_seconds + self.integrate_seconds + self.write_seconds

    @property
    def notable(self) -> bool:
        """True when the run is worth a note: beyond :data:`NOTE_SECONDS` or
        :data:`NOTE_BYTES`."""
        return self.seconds > NOTE_SECONDS or self.memory_bytes > NOTE_BYTES

    def describe(self) -> str:
        """One line, e.g. ``"about 25 s and 130 MB (...)"``.

        Returns
        -------
        str
            Wall time and memory, and the part the compiled core's first build takes
        """
        text = f"about {_duration(self.seconds)}" + (
            f" and {_size(self.memory_bytes)}" if self.memory_bytes > 0 else "")
        if self.build_seconds > 0.5 * self.seconds:
            text += (f" ({_duration(self.build_seconds)} of it compiling the model's C core, "
                     f"once: later runs of this model structure reuse it)")
        return text


def _duration(s: float) -> str:
    return f"{s / 60:.0f} min" if s >= 120 else f"{s:.0f} s"


def run_cost(n_states: int, t_end: float, rows: float = 0, columns: int = 0, *,
             build: bool = False, in_memory: bool = True, csv: bool = False,
             variants: int = 1, workers: int = 1) -> RunCost:
    """Estimate a run's wall time and memory before it starts (the cost model above
    :data:`BUILD_SECONDS`).

    Parameters
    ----------
    n_states : int
        States of the model, [-]
    t_end : float
        Simulated time of one variant, [s]
    rows : float
        Output rows of one variant, [-]
    columns : int
        Output columns (time, signals and states), [-]
    build : bool
        The compiled core is built first (:func:`hydroline.compiled.needs_build`)
    in_memory : bool
        The table is kept in memory (False: streamed to a file)
    csv : bool
        The table is written as CSV
    variants : int
        Runs of the same model (a sweep), [-]
    workers : int
        Processes running them side by side, [-]

    Returns
    -------
    RunCost
        Build, integration and writing time [s] and peak memory [B].
    """
    n = float(n_states)
    build_s = BUILD_SECONDS + n / BUILD_STATES if build else 0.0
    build_b = BUILD_BYTES + BUILD_BYTES_PER_STATE * n if build else 0.0
    rounds = math.ceil(max(variants, 1) / max(workers, 1))
    integrate = rounds * t_end / INTEGRATION_SPEED * (n / REFERENCE_STATES) ** 1.5
    write = rounds * CSV_BYTES_PER_VALUE * rows * columns / CSV_RATE if csv else 0.0
    side_by_side = min(max(workers, 1), max(variants, 1))   # a table per running variant
    table = 2 * 8 * rows * columns * side_by_side if in_memory else 0.0
    return RunCost(build_s, integrate, write, max(build_b, table))
