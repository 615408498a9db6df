"""Limits on what one run may produce, estimated before it starts.

A run keeps its time series in memory (one float per column and output sample) unless it
streams them to a file; a long ``t_end`` at a fine output step would otherwise integrate for
hours and end in a MemoryError. :func:`output_estimate` gives the rows and bytes of a run
from ``t_end``, the output step and the number of columns; :func:`check_output_size` refuses
a run beyond :data:`MAX_TABLE_BYTES` in memory, or one whose CSV would not fit on the disk,
with one line saying how large it would be and what to change.
"""
from __future__ import annotations

import math
import shutil
from dataclasses import dataclass
from pathlib import Path

__all__ = ["MAX_TABLE_BYTES", "CSV_BYTES_PER_VALUE", "OutputEstimate", "output_estimate",
           "check_output_size"]

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
    rows : int          Output samples (a float when beyond 1e15), t_end / dt_out + 1, [-]
    columns : int       Signals and states (plus time), [-]
    memory_bytes : int  The table in memory (float64; the result frame doubles it briefly), [B]
    csv_bytes : int     The table as CSV, [B]
    """

    rows: int
    columns: int
    memory_bytes: int
    csv_bytes: int

    def describe(self) -> str:
        """One line for messages, e.g. ``"1e+06 rows x 40 columns = 320 MB in memory, ..."``.

        Returns
        -------
        str  Rows, columns, the size in memory and as CSV (B, kB, MB, ...)
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
    t_end : float     Simulated time, [s]
    dt_out : float    Output step, [s] (<= 0: unbounded rows)
    n_columns : int   Signals and states, without time, [-]

    Returns
    -------
    OutputEstimate  Rows, columns and bytes in memory [B] and as CSV [B]
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
    t_end : float        Simulated time, [s]
    dt_out : float       Output step, [s]
    n_columns : int      Signals and states, [-]
    stream_to : path     The CSV the run streams to (memory is then constant; only the disk
                         is checked), or None (the table is kept in memory)
    csv_folder : path    Where the run's CSV will be written (its free space is checked)
    name : str           The option or key that set ``t_end``, for the message

    Returns
    -------
    OutputEstimate
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
