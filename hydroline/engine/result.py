"""What a run returns: :class:`SimulationResult` (every signal and state against time), the
:class:`OutputSink` the integrator writes rows into (kept in memory, streamed to CSV with
per-column statistics, decimated preview), and the CSV writers.
"""
from __future__ import annotations

import numbers

import numpy as np

from .network import Network
from .steady_state import SteadyState

__all__ = ["SimulationResult", "OutputSink", "column_units", "column_indices", "write_csv_rows",
           "write_csv_table", "csv_cells", "matlab_names"]


class SimulationResult:
    """Time series of every named signal and state.

    Built from a DataFrame ``data`` (its index the time), or from ``times``, ``table`` and
    ``columns`` (no pandas needed).

    Parameters
    ----------
    data : pandas.DataFrame
        Index ``time`` [s]; one column per signal and per state, [SI]; None: built
        from ``times``, ``table`` and ``columns``
    steady_state : SteadyState
        The steady state the run started from
    wall_time : float
        Integration wall time, [s]
    stats : dict
        Solver statistics (function/Jacobian evaluations, steps)
    warnings : list[str]
        Validity warnings (e.g. pressure below zero absolute)
    metadata : dict
        Run description (rig, scenario, ``units``: column -> SI unit)
    times : array_like
        Output times, [s] (when ``data`` is None)
    table : array_like
        One row per time, one column per name in ``columns``, [SI]
    columns : list[str]
        Column names of ``table`` (when ``data`` is None), signals first

    Attributes
    ----------
    data : pandas.DataFrame
        Index ``time`` [s]; one column per signal and per state
        (``<component>.<state>``), SI units (made on first access;
        ``res[name]``, ``res.t`` and ``name in res`` need no pandas)
    columns : list[str]
        Column names of ``data``, signals first
    steady_state : SteadyState
        The steady state the run started from
    wall_time : float
        Integration wall time, [s]
    stats : dict
        Solver statistics (function/Jacobian evaluations, steps)
    warnings : list[str]
        Validity warnings (e.g. pressure below zero absolute)
    """

    #: ``summarizer(result) -> dict``: the summary its repr shows, registered by the module
    #: that defines the experiments' summaries (:func:`hydroline.summarize`, which sits above
    #: the engine); None: no summary shown
    summarizer = None

    def __init__(self, data=None, steady_state: SteadyState | None = None, wall_time: float = 0.0,
                 stats: dict | None = None, warnings: list | None = None,
                 metadata: dict | None = None, *, times=None, table=None, columns=None):
        if data is not None:   # a DataFrame given: its index is the time
            times, table, columns = data.index.to_numpy(), data.to_numpy(), list(data.columns)
        self._times = np.asarray(times, dtype=float)
        self._table = np.asarray(table, dtype=float).reshape(len(self._times), -1)
        self.columns = list(columns)
        self._column_index = {c: k for k, c in enumerate(self.columns)}
        self._data = data
        self.steady_state = steady_state
        self.wall_time = wall_time
        self.stats = {} if stats is None else stats
        self.warnings = [] if warnings is None else warnings
        self.metadata = {} if metadata is None else metadata

    @property
    def data(self):
        """The table as a DataFrame: index ``time`` [s], one column per name, [SI]."""
        if self._data is None:
            import pandas as pd

            self._data = pd.DataFrame(self._table, index=pd.Index(self._times, name="time"),
                                      columns=self.columns, copy=False)
        return self._data

    @property
    def t(self) -> np.ndarray:
        """Output times, [s]."""
        return self._times

    def __getitem__(self, key) -> np.ndarray:
        if self._data is not None:
            return self._data[key].to_numpy()
        try:
            return self._table[:, self._column_index[key]]
        except KeyError:
            raise KeyError(key) from None

    def __contains__(self, key) -> bool:
        return key in self._column_index if self._data is None else key in self._data

    def _summary_rows(self):
        """(label, value) rows describing the run, and the port-metric rows of its summary
        (:func:`hydroline.summarize`; none where the run has no experiment's metadata)."""
        meta = self.metadata
        t = self._times
        rows = [("scenario", meta.get("scenario", "-")),
                ("time [s]", f"{t[0]:.4g} to {t[-1]:.4g}, {len(t)} rows" if len(t) else "no rows"),
                ("columns", len(self.columns)), ("states", meta.get("n_states", "-")),
                ("wall time [s]", self.wall_time)]
        if self.steady_state is not None:
            rows.append(("steady-state residual [1/s]", getattr(self.steady_state, "residual", None)))
        rows += [("warning", w) for w in self.warnings]
        metrics = []
        if self.summarizer is None:
            return rows, metrics
        try:
            summary = self.summarizer(self)
        except Exception:                   # a result built by hand: no experiment to read
            return rows, metrics
        axes = summary.get("axes") or {"": summary}
        for name, entry in axes.items():
            for side in ("supply", "return"):
                m = entry.get(side, {})
                metrics.append([f"{name} {side}".strip(), m.get("frequency_hz"),
                                m.get("amplitude_mpa"), m.get("first_excursion_mpa"),
                                m.get("ripple_pp_mpa"),
                                None if m.get("settling_time_s") is None
                                else m["settling_time_s"] * 1e3])
        rows.append(("metrics window", summary.get("metrics_window_note", "-")))
        return rows, metrics

    #: Columns of the port-metric table of the summary shown by ``repr`` and in a notebook.
    METRIC_HEADER = ("port", "oscillation [Hz]", "amplitude [MPa]", "first excursion [MPa]",
                     "ripple p-p [MPa]", "settling [ms]")

    def __repr__(self) -> str:
        from .display import text_block

        rows, metrics = self._summary_rows()
        text = text_block("hydroline SimulationResult", rows)
        if metrics:
            text += "\n" + text_block("port pressures (hydroline.summarize):", metrics,
                                       self.METRIC_HEADER)
        return text

    def _repr_html_(self) -> str:
        from .display import html_block

        rows, metrics = self._summary_rows()
        out = html_block("hydroline SimulationResult", rows,
                         note="res['supply_port_pressure'] gives a column [SI]; res.data all "
                         "of them (pandas); res.plot() the figure")
        if metrics:
            out += html_block("port pressures (hydroline.summarize)", metrics, self.METRIC_HEADER)
        return out

    def csv_header(self) -> list[str]:
        """``time [s]``, then every column with its SI unit (``supply_port_pressure [Pa]``), as
        ``hydroline fit`` reads it.

        Returns
        -------
        list of str
            Column headings.
        """
        units = self.metadata.get("units", {})
        return ["time [s]"] + [f"{c} [{units[c]}]" if c in units else c for c in self.columns]

    def to_csv(self, path, every: int = 1):
        """Write all series to CSV: ``time [s]`` first, then every column with its SI unit in
        the header (``supply_port_pressure [Pa]``), as ``hydroline fit`` reads it; with
        ``every`` > 1 only every n-th row and the last.

        Parameters
        ----------
        path : str or Path
            The CSV file to write
        every : int
            Keep every n-th row (and the last), [-]
        """
        rows = slice(None)
        if every > 1:
            rows = np.unique(np.r_[np.arange(0, len(self._times), every), len(self._times) - 1])
        if self._data is not None:
            self._times, self._table = self._data.index.to_numpy(), self._data.to_numpy()
            self.columns = list(self._data.columns)
        with open(path, "w", buffering=1 << 20) as f:
            f.write(",".join(self.csv_header()) + "\n")
            write_csv_rows(f, self._times[rows], self._table[rows])

    def _rows(self, every: int):
        """(times [s], table [SI]) of every n-th row and the last."""
        if self._data is not None:
            self._times, self._table = self._data.index.to_numpy(), self._data.to_numpy()
            self.columns = list(self._data.columns)
        if every <= 1:
            return self._times, self._table
        rows = np.unique(np.r_[np.arange(0, len(self._times), every), len(self._times) - 1])
        return self._times[rows], self._table[rows]

    def to_parquet(self, path, every: int = 1):
        """Write all series to Parquet: a column ``time`` [s], then one per signal and state
        under its own name; the SI units in the file's metadata, as pandas reads them back
        (``pandas.read_parquet(path).attrs["units"]``: column -> unit). Needs pyarrow. Written
        in row groups of :data:`PARQUET_ROW_GROUP` rows, each converted on its own (a long
        run's table is not copied whole: a 10-minute run's ~80 MB of rows took ~450 MB
        resident through a DataFrame).

        Parameters
        ----------
        path : str or Path
            The file to write
        every : int
            Keep every n-th row (and the last), [-]

        Raises
        ------
        ValueError
            Where pyarrow is not installed (one line, naming the file).
        """
        import json

        pa, pq = parquet_writer(path)
        t, table = self._rows(every)
        units = self.metadata.get("units", {})
        names = ["time"] + list(self.columns)
        # (the key pandas keeps DataFrame.attrs under, and reads them back from)
        attrs = {"units": {"time": "s", **{c: units[c] for c in self.columns if c in units}}}
        schema = pa.schema([(n, pa.float64()) for n in names],
                           metadata={"PANDAS_ATTRS": json.dumps(attrs)})
        with pq.ParquetWriter(path, schema) as writer:
            for k in range(0, max(len(t), 1), PARQUET_ROW_GROUP):
                part = np.asarray(table[k:k + PARQUET_ROW_GROUP], dtype=float)
                writer.write_table(pa.Table.from_arrays(
                    [pa.array(np.asarray(t[k:k + PARQUET_ROW_GROUP], dtype=float))]
                    + [pa.array(np.ascontiguousarray(part[:, i])) for i in range(part.shape[1])],
                    schema=schema))

    def to_mat(self, path, every: int = 1):
        """Write all series to a MATLAB file (``scipy.io.savemat``, MAT 5): one variable per
        signal and state (a column vector), ``time`` [s] first; names made valid MATLAB
        names (:func:`matlab_names`: ``supply.section2.mode3.flow`` ->
        ``supply_section2_mode3_flow``); the struct ``units`` gives each variable's SI unit
        and the struct ``names`` its name in hydroline.

        Parameters
        ----------
        path : str or Path
            The file to write
        every : int
            Keep every n-th row (and the last), [-]
        """
        from scipy.io import savemat

        t, table = self._rows(every)
        units = self.metadata.get("units", {})
        columns = ["time"] + list(self.columns)
        names = matlab_names(columns)
        data = {"time": t[:, None]}
        for k, (c, v) in enumerate(zip(self.columns, names[1:])):
            data[v] = table[:, k][:, None]
        data["units"] = {v: ("s" if c == "time" else units.get(c, "")) for c, v in zip(columns, names)}
        data["names"] = dict(zip(names, columns))
        savemat(path, data, do_compression=True, oned_as="column", long_field_names=True)

    def plot(self, signals=None, path=None, title=None):
        """Plot signals (default: the paper's Figs. 10-12 set when present); the figure is
        drawn by :func:`hydroline.plotting.plot_result`, which this calls. Returns the figure.

        Parameters
        ----------
        signals : list
            Columns to plot (default: port and chamber pressures, velocity)
        path : str
            Write the figure there (PNG) when given
        title : str
            Figure title

        Returns
        -------
        matplotlib.figure.Figure
            The figure.
        """
        import importlib

        # the figure lives above the engine; loaded by name so the engine imports nothing above it
        return importlib.import_module("hydroline.plotting").plot_result(
            self, signals=signals, path=path, title=title)


def parquet_writer(path):
    """pyarrow and its Parquet module, for writing ``path``; a command that will write
    Parquet asks before its run (a long run's rows would otherwise find pyarrow missing only
    when the file is written, at the run's end).

    Parameters
    ----------
    path : str or Path
        The Parquet file to be written (named in the error).

    Returns
    -------
    pa : module
        ``pyarrow``.
    pq : module
        ``pyarrow.parquet``.

    Raises
    ------
    ValueError
        Where pyarrow is not installed (one line, naming the file).
    """
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise ValueError(f"{path}: writing Parquet needs pyarrow: pip install pyarrow, "
                         f"or write CSV or MAT") from None
    return pa, pq


#: Rows per row group of a Parquet file (:meth:`SimulationResult.to_parquet`: each group
#: converted on its own, ~10 MB at ~170 columns), [-].
PARQUET_ROW_GROUP = 8192
#: Longest variable name MATLAB accepts (``namelengthmax``).
MATLAB_NAME_LENGTH = 63
#: Names a MAT file of a run keeps for itself.
MATLAB_RESERVED = ("units", "names")


def matlab_names(columns) -> list[str]:
    """Valid, distinct MATLAB variable names for column names: every character other than a
    letter, digit or ``_`` becomes ``_``, a name not starting with a letter gets an ``x``
    prefix, names are cut to 63 characters and made distinct with a ``_<n>`` suffix.

    Parameters
    ----------
    columns : list of str
        Column names (e.g. ``supply.section2.mode3.flow``).

    Returns
    -------
    list of str
        One MATLAB name per column, in order.
    """
    import re

    out, seen = [], set(MATLAB_RESERVED)
    for c in columns:
        v = re.sub(r"[^A-Za-z0-9_]", "_", str(c))
        if not v or not v[0].isalpha() or not v.isascii():
            v = "x" + v
        v = v[:MATLAB_NAME_LENGTH]
        base, n = v, 1
        while v in seen:
            n += 1
            suffix = f"_{n}"
            v = base[:MATLAB_NAME_LENGTH - len(suffix)] + suffix
        seen.add(v)
        out.append(v)
    return out


def write_csv_rows(file, t, block):
    """Rows ``t, block[i, :]`` as CSV text, each number in Python's shortest round-trip form
    (what pandas writes; NaN as an empty field).

    Parameters
    ----------
    file : file object
        Open text file to append to
    t : ndarray
        Times, [s]
    block : ndarray
        One row per time, [SI]
    """
    data = np.column_stack([np.asarray(t, dtype=float), np.asarray(block, dtype=float)])
    line = ",".join(["%r"] * data.shape[1]) + "\n"   # (one % per piece: ~1/4 less time than
    step = max(1, 100_000 // max(data.shape[1], 1))  # a join of each row's reprs)
    for k in range(0, len(data), step):
        part = data[k:k + step]
        if np.isnan(part).any():
            text = "".join(",".join("" if v != v else repr(v) for v in r) + "\n"
                           for r in part.tolist())
        else:
            text = (line * len(part)) % tuple(part.ravel().tolist())
        file.write(text)


def csv_cells(values) -> list:
    """One column's values as the text of its CSV cells, as pandas writes the column of a
    DataFrame made of them (``DataFrame({name: values}).to_csv()``): a column of numbers
    with a float or a missing value among them is a float column (each value in Python's
    shortest round-trip form, ``1.0`` for 1), one of integers alone an integer column, any
    other ``str`` of each value; a missing value (None, NaN) an empty cell.

    Parameters
    ----------
    values : sequence
        The column: numbers, strings, None

    Returns
    -------
    list of str
        The cells' text, one per value.
    """
    if isinstance(values, np.ndarray) and values.dtype.kind == "f":
        return ["" if v != v else repr(v) for v in values.astype(float).tolist()]
    values = values.tolist() if isinstance(values, np.ndarray) else list(values)
    missing = [v is None or (isinstance(v, (float, np.floating)) and v != v) for v in values]
    present = [v for v, m in zip(values, missing) if not m]
    numeric = bool(present) and all(isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_))
                                    for v in present)
    if numeric and not any(missing) and all(isinstance(v, numbers.Integral) for v in present):
        return [str(int(v)) for v in values]
    if numeric:
        return ["" if m else repr(float(v)) for v, m in zip(values, missing)]
    return ["" if m else str(v) for v, m in zip(values, missing)]


def write_csv_table(path, columns: dict) -> None:
    """Write a table as CSV the way ``pandas.DataFrame(columns).to_csv(path, index=False)``
    does (the same text: the header row, then each row's cells by :func:`csv_cells`, quoted
    where a cell holds a comma, a quote or a line break), without importing pandas.

    Parameters
    ----------
    path : str or Path
        The CSV file to write
    columns : dict
        Column name -> its values (a sequence or 1-D array; all of one length)
    """
    import csv

    cells = [csv_cells(v) for v in columns.values()]
    with open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(list(columns))
        writer.writerows(zip(*cells))


def column_units(network: Network) -> dict:
    """Signal or state name -> its SI unit (``"-"`` for a pure number), from the ports and
    states the components declare.

    Parameters
    ----------
    network : Network
        The model

    Returns
    -------
    dict
        Name -> SI unit text.
    """
    units = network.__dict__.get("_column_units")   # made once per network
    if units is None:
        units = {}
        for c in network.components:
            for port, spec in c.outputs.items():
                units[c.signal(port)] = spec.unit
            for st in c.states:
                units[f"{c.name}.{st.name}"] = st.unit or "-"
        network.__dict__["_column_units"] = units
    return dict(units)


def column_indices(what, names, columns):
    """(names, their indices in ``columns``); ValueError naming ``what`` and unknown names.

    Parameters
    ----------
    what : str
        The option being checked (for the message)
    names : list
        Requested column names
    columns : list
        The available columns

    Returns
    -------
    names : list of str
        The names, as given.
    indices : ndarray of int
        Their indices in ``columns``, [-].

    Raises
    ------
    ValueError
        Naming ``what`` and the unknown names.
    """
    names = list(names)
    unknown = [k for k in names if k not in columns]
    if unknown:
        raise ValueError(f"{what}: unknown signal(s)/state(s) {', '.join(unknown)}")
    return names, np.array([columns.index(k) for k in names], dtype=int)


def csv_rows(rows) -> str:
    """Rows of numbers as CSV text, ``%.9g`` each, ``,`` between, one line per row: the text
    of ``np.savetxt(f, rows, fmt="%.9g", delimiter=",")``, formatted in one operation instead
    of one per row (a quarter less time on a long run's output).

    Parameters
    ----------
    rows : ndarray
        2-D array of values, [SI]

    Returns
    -------
    str
        The CSV text, one line per row.
    """
    rows = np.asarray(rows, dtype=float)
    line = ",".join(["%.9g"] * rows.shape[1]) + "\n"
    # in pieces of ~2000 numbers (~1 ms): one formatting operation holds Python's lock
    # throughout, which a thread waiting for it (the integration, between chunks) would wait for
    step = max(1, 2000 // max(rows.shape[1], 1))
    return "".join((line * len(part)) % tuple(part.ravel().tolist())
                   for part in (rows[k:k + step] for k in range(0, len(rows), step)))


def _same_place(a: np.ndarray, b: np.ndarray) -> bool:
    """True when two arrays are the same memory seen the same way (start, shape, strides)."""
    # (ctypes.data: the start's address without the interface dict made per call)
    return a.shape == b.shape and a.strides == b.strides and a.ctypes.data == b.ctypes.data


class OutputSink:
    """Where output rows go: kept in memory (all columns, or only ``keep``), streamed to CSV
    (every ``every``-th row of ``stream`` columns, the last row always) with per-column
    statistics, and a preview (``preview`` columns at most ``preview_rows`` rows, for a
    figure). Memory stays bounded by what is kept, whatever the run's length.

    Parameters
    ----------
    columns : list[str]
        Names of all output columns (signals, then states), in row order
    path : str
        CSV file to stream to; None: nothing written
    stream : list[str]
        Columns written to the CSV; None: all
    every : int
        Write every ``every``-th row (the last row always), [-]
    keep : list[str]
        Columns kept in memory; None: none kept
    n_total : int
        Rows the run will give, when known: what is kept (every row of every
        column when neither a file nor ``keep`` is given) is then one
        preallocated table, [-]
    preview : list[str]
        Columns of the preview (for a figure); None: no preview
    preview_rows : int
        Rows of the preview at most, [-]
    units : dict
        Column -> SI unit, written into the CSV header (``name [unit]``)
    observe : callable
        Called with ``(t [s], table [SI], columns)`` for every block of
        rows written (statistics of a long run chunk by chunk); None: none
    stats : list[str]
        Columns whose statistics are kept (streamed or ``keep``); None: every
        column
    """

    def __init__(self, columns, path, stream=None, every=1, keep=None, n_total=None,
                 preview=None, preview_rows=50_000, units=None, observe=None, stats=None):
        self.columns = columns
        self.observe = observe   # (issue 13: per-chunk statistics of a long run)
        self.path = path
        self.rows = 0
        self.parts = []
        self.last = None
        self.every = max(int(every), 1)
        self.n_total = n_total
        self.stats_index = None
        if path is not None:
            self.keep_file, self.index = column_indices(
                "stream_columns", columns if stream is None else stream, columns)
            self.file = open(path, "w", buffering=1 << 20)
            units = units or {}
            self.file.write(",".join(["time [s]"] + [f"{c} [{units[c]}]" if c in units else c
                                                    for c in self.keep_file]) + "\n")
            self.written = 0
        if path is not None or keep is not None:   # statistics of every column, or of ``stats``
            self.stats_names = list(columns)
            self.stats_index = True
            if stats is not None:
                self.stats_names, self.stats_index = column_indices("stats_columns", stats,
                                                                    columns)
            n = len(self.stats_names)
            self.mn, self.mx = np.full(n, np.inf), np.full(n, -np.inf)
            self.sum, self.sumsq = np.zeros(n), np.zeros(n)
        # rows kept in memory: the ``keep`` columns, or every column when nothing is streamed;
        # the count known, one preallocated table (no copy at the end), which a backend may
        # write into in place when it holds every column (:meth:`target`)
        self.keep = self.kept = None
        if keep is not None:
            self.keep, self.keep_index = column_indices("keep_columns", keep, columns)
        if (keep is not None or path is None) and n_total is not None:
            self.kept_t = np.empty(n_total)
            self.kept = np.empty((n_total, len(self.keep if keep is not None else columns)))
        self.preview = None
        if preview is not None:
            self.preview, self.preview_index = column_indices("preview_columns", preview, columns)
            self.preview_every = max(1, -(-int(n_total or 1) // max(int(preview_rows), 1)))
            self.preview_parts = []

    def target(self, n: int):
        """Where the next ``n`` rows (signals then states) may be written in place: a slice of
        the run's table, or None (the rows are then passed to :meth:`write` and copied).

        Parameters
        ----------
        n : int
            Rows, [-]

        Returns
        -------
        ndarray or None
            A view of ``n`` rows of the table, [SI], or None.
        """
        if self.keep is not None or self.kept is None or self.rows + n > len(self.kept):
            return None
        return self.kept[self.rows:self.rows + n]

    def write(self, t, X, Y, model, p):
        """Rows at times t: states X and signals Y (None: computed here), or with X None the
        table Y of signals and states side by side.

        Parameters
        ----------
        t : ndarray
            Output times, [s]
        X : ndarray
            States, one row per time, [SI] (None: ``Y`` is the whole table)
        Y : ndarray
            Signals, one row per time, [SI] (None: evaluated from ``X``)
        model : CompiledModel
            Evaluates the signals when ``Y`` is None
        p : ndarray
            Runtime parameters, [SI]
        """
        if X is None:
            block = Y
        else:
            if Y is None:
                # (one call with a column per row: CasADi evaluates it row by row, 5x faster
                # than making its map(n) first; the parameters given once, where a tiled copy
                # of them cost more to convert than the signals to evaluate)
                Y = np.asarray(model.signals(np.asarray(t, dtype=float)[None, :], X.T,
                                             p[:, None])).T
            block = np.hstack([np.asarray(Y).reshape(len(t), -1), X])
        t = np.asarray(t, dtype=float)
        if self.observe is not None:
            self.observe(t, block, self.columns)
        i0 = self.rows
        self.rows += len(t)
        if self.preview is not None:
            k = np.arange(i0, self.rows)
            sel = (k % self.preview_every == 0) | (k == (self.n_total or 0) - 1)
            if sel.any():
                self.preview_parts.append((t[sel], block[np.ix_(sel, self.preview_index)]))
        if self.stats_index is not None:
            part = block if self.stats_index is True else block[:, self.stats_index]
            self.mn = np.minimum(self.mn, part.min(axis=0))
            self.mx = np.maximum(self.mx, part.max(axis=0))
            self.sum += part.sum(axis=0)
            self.sumsq += np.einsum("ij,ij->j", part, part)   # (no temporary block)
        if self.keep is not None or self.path is None:     # rows kept in memory
            if self.kept is not None and self.rows <= len(self.kept_t):
                self.kept_t[i0:self.rows] = t
                place = self.kept[i0:self.rows]
                if self.keep is not None:
                    place[...] = block[:, self.keep_index]
                elif not _same_place(block, place):   # (rows the backend wrote here: as they are)
                    place[...] = block
            else:   # no count foreseen, or more rows than foreseen: go on in parts
                if self.kept is not None:
                    self.parts.append((self.kept_t[:i0], self.kept[:i0]))
                    self.kept = None
                self.parts.append((t.copy(), block[:, self.keep_index]) if self.keep is not None
                                  else (t, block))
        if self.path is not None:
            rows = np.arange(i0, self.rows)
            sel = (rows % self.every == 0)
            if self.n_total is not None:
                sel |= rows == self.n_total - 1   # the run's end is always written
            if sel.all():
                out_t, out = t, block[:, self.index]
            else:
                out_t, out = t[sel], block[np.ix_(sel, self.index)]
            if len(out_t):
                self.file.write(csv_rows(np.column_stack([out_t, out])))
                self.written += len(out_t)
        self.last = (t[-1:].copy(), block[-1:].copy())

    def rows_so_far(self):
        """(times [s], table [SI]) of the rows written so far where every column is kept in one
        table; None otherwise (streamed, ``keep``, or gone on in parts).

        Returns
        -------
        tuple or None
            ``(times [s], table [SI])``, or None.
        """
        if self.keep is not None or self.path is not None or self.kept is None:
            return None
        return self.kept_t[:self.rows], self.kept[:self.rows]

    def result(self):
        """(times, table, columns): the rows kept (all columns, or the ``keep`` columns), or the
        last row of every column when streaming without ``keep``.

        Returns
        -------
        tuple
            ``(times [s], table [SI], column names)``.
        """
        if self.path is not None:
            self.file.close()
        if self.keep is None and self.path is not None:
            return self.last[0], self.last[1], self.columns
        columns = self.keep if self.keep is not None else self.columns
        if self.kept is not None:
            return self.kept_t[:self.rows], self.kept[:self.rows], columns
        if len(self.parts) == 1:
            return self.parts[0][0], self.parts[0][1], columns
        return (np.concatenate([q[0] for q in self.parts]),
                np.vstack([q[1] for q in self.parts]), columns)

    def preview_result(self):
        """(times, table, columns) of the preview, or None.

        Returns
        -------
        tuple or None
            ``(times [s], table [SI], column names)``, or None without a preview.
        """
        if self.preview is None or not self.preview_parts:
            return None
        return (np.concatenate([q[0] for q in self.preview_parts]),
                np.vstack([q[1] for q in self.preview_parts]), self.preview)

    def stats_frame(self, names=None):
        """min, max, mean and rms of every column (rows: column names) as a DataFrame: of every
        column the sink keeps statistics of (its ``stats``).

        Parameters
        ----------
        names : list
            Only these columns, those of them with statistics (all when None)

        Returns
        -------
        pandas.DataFrame
            Columns ``min``, ``max``, ``mean``, ``rms``, [SI of each row].
        """
        import pandas as pd

        n = max(self.rows, 1)
        frame = pd.DataFrame({"min": self.mn, "max": self.mx, "mean": self.sum / n,
                              "rms": np.sqrt(self.sumsq / n)}, index=self.stats_names)
        return frame if names is None else frame.loc[[k for k in names if k in frame.index]]
