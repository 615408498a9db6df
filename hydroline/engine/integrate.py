"""Time integration of an assembled network (docs/model.md section 6).

:func:`integrate` splits ``[0, t_end]`` at the components' breakpoints (a step command's jump)
and sampling instants (a sampled controller's zero-order hold), runs a solver backend
(:mod:`hydroline.engine.backends`) over each segment, and writes the output rows into an
:class:`~hydroline.engine.result.OutputSink` (in memory, or streamed to CSV in constant memory).
"""
from __future__ import annotations

import sys
import time as _time

import numpy as np

from .backends import SOLVERS, make_backend
from .network import Network
from .result import OutputSink, SimulationResult, column_units

__all__ = ["integrate", "segments", "apply_samples", "RowWriter"]


def segments(t_end: float, breakpoints, sample_time: float | None = None) -> list[float]:
    """Segment edges of a run: 0, the breakpoints inside (0, t_end), the sampling instants
    k * sample_time, and t_end, sorted, [s].

    Parameters
    ----------
    t_end : float
        End of the run, [s]
    breakpoints : list
        Times where inputs jump, [s]
    sample_time : float
        Zero-order-hold period of a sampled component, [s] (None: none)

    Returns
    -------
    list of float
        The edges, [s].
    """
    edges = {0.0, float(t_end)}
    edges.update(b for b in breakpoints if 0 < b < t_end)
    if sample_time:
        n = int(np.floor(t_end / sample_time + 1e-9))
        edges.update(k * sample_time for k in range(1, n + 1) if k * sample_time < t_end)
    return sorted(edges)


def apply_samples(network: Network, sampled: list, t: float, x, p, signals=None) -> None:
    """At a sampling instant, let each sampled component (:meth:`Component.sample`) set its
    held runtime parameters from the signals at (t, x); ``p`` is changed in place.

    Parameters
    ----------
    network : Network
        The model
    sampled : list
        Components with a ``sample_time``
    t : float
        Sampling instant, [s]
    x : ndarray
        States there, [SI]
    p : ndarray
        Runtime parameters, [SI]; changed in place
    signals : ndarray
        Every signal at (t, x) in ``network.signal_names`` order, [SI], where
        known (the compiled core's last output row of the segment before);
        None: evaluated here by the components' Python code (~1 ms)
    """
    if signals is None:
        sig = network.signals_at(t, x, p)
    else:
        sig = dict(zip(network.signal_names, map(float, signals)))
    for c in sampled:
        xs, _ = network.component_values(c, x, p)
        u = {port: sig[c.signal(port)] for port in c.inputs}
        for k, v in c.sample(xs, u).items():
            p[network.parameter_names.index(f"{c.name}.{k}")] = v


#: Output rows per chunk of a run whose rows stay in memory (one call into the compiled core
#: each: fewer calls, less Python between them), [-].
IN_MEMORY_CHUNK_ROWS = 20_000
#: Output rows per chunk of a run whose rows a second thread takes in (:class:`RowWriter`:
#: statistics, CSV text, ``observe``): a block of ~7 MB (~170 columns) is mostly still in the
#: processor's cache when that thread reads it. On the 10-minute closed-loop sine (two cores
#: under load 3) 20 000-row blocks (27 MB) took ~12 % more CPU; 2 000-row blocks as little
#: CPU as 5 000 but more wall time (two blocks waiting hold less: the integrating thread
#: waited for the other more often), [-].
HANDED_CHUNK_ROWS = 5_000


class RowWriter:
    """Hands blocks of output rows to an :class:`~hydroline.engine.result.OutputSink` in a
    second thread, in order, at most ``depth`` blocks behind: the sink's NumPy statistics,
    CSV text and ``observe`` run while the caller integrates the next block (the compiled core
    releases Python's lock; on two cores the wall time is the longer of the two, not the sum).
    An exception in the sink is raised again from the next :meth:`write` or :meth:`close`.
    While it runs, Python's thread switch interval is 0.2 ms instead of 5 ms: the integrating
    thread, back from C between chunks, waits that long at most for Python's lock (300 chunks
    of a 10-minute run waited ~1 s at 5 ms); restored by :meth:`close`.

    Parameters
    ----------
    sink : OutputSink
        Where the rows go
    depth : int
        Blocks waiting at most (memory: each is one chunk of rows), [-]
    """

    def __init__(self, sink, depth: int = 2):
        import queue       # (only a streamed run's writer: not at every command's start)
        import threading

        self.sink = sink
        self.blocks = queue.Queue(maxsize=max(int(depth), 1))
        self.error = None        # the sink's exception: no block is written after it
        self.raised = False
        self.switch_interval = sys.getswitchinterval()
        self.own_interval = min(self.switch_interval, 2e-4)
        sys.setswitchinterval(self.own_interval)
        self.thread = threading.Thread(target=self._run, name="hydroline-rows", daemon=True)
        self.thread.start()

    def _run(self):
        while True:
            job = self.blocks.get()
            if job is None:
                return
            if self.error is None:
                try:
                    self.sink.write(*job)
                except BaseException as e:   # (re-raised in the caller's thread)
                    self.error = e

    def _raise(self):
        if self.error is not None and not self.raised:
            self.raised = True
            raise self.error

    def write(self, t, X, Y, model, p):
        """Queue one block of rows, as :meth:`OutputSink.write` takes it.

        Parameters
        ----------
        t : ndarray
            Output times, [s]
        X : ndarray
            States, one row per time, [SI] (None: ``Y`` is the whole table)
        Y : ndarray
            Signals (or the whole table), one row per time, [SI]
        model : CompiledModel
            Evaluates the signals when ``Y`` is None
        p : ndarray
            Runtime parameters, [SI] (copied: a sampled component changes
            them in place)
        """
        self._raise()
        if self.error is None:
            self.blocks.put((t, X, Y, model, None if p is None else np.array(p)))

    def close(self, raise_error: bool = True):
        """Wait until every queued block is written; raise a sink's error, if any.

        Parameters
        ----------
        raise_error : bool
            Raise the sink's exception (False: only wait)
        """
        if self.thread.is_alive():
            self.blocks.put(None)
            self.thread.join()
            if sys.getswitchinterval() == self.own_interval:   # (unless changed meanwhile)
                sys.setswitchinterval(self.switch_interval)
        if raise_error:
            self._raise()


def integrate(network: Network, x0, t_end: float, dt_out: float = 1e-4, p=None,
              solver: str = "auto", rtol: float = 1e-7, atol_scale: float = 1e-8,
              progress=None, stream_to=None, chunk_rows: int | None = None,
              stream_columns=None, stream_every: int = 1, keep_columns=None,
              preview_columns=None, preview_rows: int = 50_000,
              observe=None, until=None, until_rows: int = 200,
              relax=None, relax_rows: int = 1000, stats_columns=None) -> SimulationResult:
    """Integrate the network from x0 over [0, t_end], sampled every dt_out.

    Parameters
    ----------
    network : Network
        The model
    x0 : array
        Initial state (e.g. ``solve_steady_state(...).x``), [SI]
    t_end : float
        End time, [s]
    dt_out : float
        Output interval, [s]
    p : array
        Runtime parameters, [SI] (network defaults when None)
    solver : str
        "auto" (default: the compiled core where a C compiler is available,
        else "cvodes"; its BDF, or its Radau IIA at 100x ``rtol`` and
        ``atol_scale`` where the model's lightly damped fast modes hold the
        BDF's order 3 to steps below 40 us, docs/engine.md; the metadata's
        "solver" says which), "compiled" (the network as C code with a
        sparse-Jacobian BDF integrator, :mod:`hydroline.compiled`; library
        cached on disk),
        "cvodes" (CasADi + SUNDIALS CVODES, exact sparse Jacobian), "scipy"
        (reference: per-component Python right-hand side, SciPy BDF) or
        "radau" (the compiled C core with Radau IIA of order 5 instead of its
        BDF: docs/engine.md says when it pays)
    rtol : float
        Relative tolerance, [-]
    atol_scale : float
        Absolute tolerance as a fraction of each state's typical magnitude, [-]
    progress : callable
        Called with the fraction done (0..1) after each segment or chunk
    stream_to : path
        Write the time series to this CSV file chunk by chunk as the run
        goes, keeping only per-column summary statistics in memory (constant
        memory for long runs); ``data`` then holds the last row only and
        ``metadata["stream_stats"]`` the min/max/mean/rms of every column
    chunk_rows : int
        Output rows per chunk (streaming and the compiled path); None:
        :data:`IN_MEMORY_CHUNK_ROWS`, or :data:`HANDED_CHUNK_ROWS` where a second thread takes
        the rows in (``stream_to`` or ``keep_columns`` on the compiled core), [-]
    stream_columns : list
        Columns to write when streaming (all signals and states if None)
    stream_every : int
        Write every n-th output row to ``stream_to`` (decimation; the last row
        always), [-]
    keep_columns : list
        Keep only these columns in memory (every output row): ``data`` then
        holds them, and ``metadata["stream_stats"]`` has the statistics of
        every column (bounded memory for long runs without a file)
    preview_columns : list
        Also keep these columns at every k-th row, at most
        ``preview_rows`` rows (``metadata["preview"]``, a SimulationResult:
        a figure of a long run)
    preview_rows : int
        Most rows of the preview, [-]
    observe : callable
        Called with ``(t, table, columns)`` for every block of output rows as
        the run goes (times [s], rows of signals and states [SI], their names):
        statistics of a long run computed chunk by chunk, in constant memory.
        With ``stream_to`` or ``keep_columns`` on the compiled core it is
        called from a second thread (:class:`RowWriter`), block after block in
        order, while the next block is integrated; ``progress`` stays in the
        caller's thread
    until : callable
        Called with ``(t, table, columns)`` of every row so far (times [s],
        signals and states [SI], their names) after each block of at most
        ``until_rows`` rows (each segment on CVODES and SciPy); True ends the
        run there: the result holds the rows up to that block's end (a run
        whose metrics are all it is for, :class:`~hydroline.scenarios.
        summaries.WindowEnd`). Where it has a ``time_ahead()`` method (how soon
        it may say True, [s], from the rows it last saw; inf: unknown), the
        compiled core's blocks shrink toward that estimate (:data:`AHEAD_SHARE`,
        :data:`NEAR_ROWS`): the run ends within a few rows of where it first holds.
        Rows kept in memory only (no ``stream_to``, ``keep_columns``)
    until_rows : int
        Rows per block checked by ``until`` at most, [-]
    relax : tuple
        ``(test, rtol, atol_scale)``: once ``test``, asked as ``until`` after each block of
        at most ``relax_rows`` rows (shorter near its ``time_ahead()``, as for ``until``),
        says True, the compiled core goes on at these looser tolerances
        (history kept): e.g. after the piston's stop, where no metric looks
        (:func:`hydroline.scenarios.simulate`'s ``after_stop_rtol``). Rows in memory only;
        ignored by the other backends and where rows are streamed
    relax_rows : int
        Rows per block checked by the ``relax`` test at most, [-]: long (0.1 s at the
        default output step), as a later switch loses only steps saved, never accuracy;
        each block costs a call and a check (~30 us on the 2-core test machine: 100-row
        blocks cost a closed-loop run that never reaches a stop ~15 %)
    stats_columns : list
        Columns whose min/max/mean/rms ``metadata["stream_stats"]`` holds, from every row, with
        ``stream_to`` or ``keep_columns``; None: every column (a 10-minute run's statistics of
        ~170 columns at every 0.1 ms row cost ~1.5 s)

    Returns
    -------
    SimulationResult
        Times [s], signals and states [SI], solver statistics and metadata.
    """
    if not t_end > 0:
        raise ValueError(f"t_end must be > 0 [s], got {t_end!r}")
    if solver not in SOLVERS:
        raise ValueError(f"solver must be one of {', '.join(SOLVERS)}, got {solver!r}")
    if not (rtol > 0 and atol_scale > 0):
        raise ValueError(f"rtol and atol_scale must be > 0 [-], got {rtol!r} and {atol_scale!r}")
    bounded_rows = stream_to is not None or keep_columns is not None
    if relax is not None and not (relax[1] > 0 and relax[2] > 0):
        raise ValueError(f"relax's rtol and atol_scale must be > 0 [-], got {relax[1:]!r}")
    if until is not None and bounded_rows:
        raise ValueError("until needs every row in memory: give it without stream_to and "
                         "keep_columns")
    p = network.parameter_values.copy() if p is None else np.asarray(p, dtype=float).copy()
    n_out = int(round(t_end / dt_out))
    t_last = n_out * dt_out
    h_out = t_last / n_out

    def t_out(i0, i1):   # output times i0..i1-1 (made per chunk: constant memory)
        return np.arange(i0, i1) * h_out

    sampled = [c for c in network.components if c.sample_time]
    sample_time = sampled[0].sample_time if sampled else None
    edges = segments(t_last, network.breakpoints(t_last), sample_time)
    x = np.asarray(x0, dtype=float).copy()
    backend, solver_note, build_time = make_backend(network, solver, p, rtol, atol_scale)
    columns = list(network.signal_names) + list(network.state_names)
    sink = OutputSink(columns, stream_to, stream_columns, stream_every, keep_columns, n_out + 1,
                      preview_columns, preview_rows, column_units(network) if stream_to else None,
                      observe, stats_columns)
    first = backend.signals_at(0.0, x, p)   # the compiled core's; else from the graph:
    model = network.compile() if first is None else None   # (a backend without signals)
    if first is None:
        sink.write(t_out(0, 1), x[None, :], None, model, p)
    else:
        sink.write(t_out(0, 1), None, np.concatenate([first, x])[None, :], None, p)
    bounded = stream_to is not None or keep_columns is not None
    if chunk_rows is None:
        chunk_rows = HANDED_CHUNK_ROWS if bounded and backend.chunked else IN_MEMORY_CHUNK_ROWS
    chunk_rows = max(int(chunk_rows), 1)
    # a long run's rows are taken in (statistics, CSV text, observe) by a second thread while
    # the compiled core, which holds no Python lock, integrates the next chunk
    rows_in = RowWriter(sink) if bounded and backend.chunked else sink
    tic = _time.perf_counter()
    try:
        relaxing = None
        if relax is not None and backend.chunked and not bounded_rows:
            relaxing = (_Until(relax[0], max(int(relax_rows), 1), sink, columns),
                        float(relax[1]), float(relax[2]))
        _segments(network, sampled, edges, h_out, n_out, t_last, t_out, chunk_rows, bounded,
                  backend, rows_in, model, x, p, progress,
                  None if until is None else _Until(until, max(int(until_rows), 1), sink,
                                                    columns), relaxing)
    except BaseException:
        if rows_in is not sink:
            rows_in.close(raise_error=False)   # the integration's own error is the one to see
        raise
    if rows_in is not sink:
        rows_in.close()
    wall = _time.perf_counter() - tic
    stats = backend.stats()
    stats["build_time"] = build_time
    if relaxing is not None and relaxing[0].when is not None:
        stats["relaxed_at"] = relaxing[0].when
    t_rows, table, kept = sink.result()
    res = SimulationResult(times=t_rows, table=table, columns=kept, wall_time=wall,
                           stats=stats, warnings=[])
    res.metadata.update(solver=backend.name, rtol=rtol, atol_scale=atol_scale,
                        units=column_units(network))
    if solver_note:
        res.metadata["solver_note"] = solver_note
    if stream_to is not None:
        res.metadata.update(stream_to=str(stream_to), stream_rows=sink.written,
                            stream_stats=sink.stats_frame(sink.keep_file))
    elif keep_columns is not None:
        res.metadata.update(stream_stats=sink.stats_frame())
    preview = sink.preview_result()
    if preview is not None:
        res.metadata["preview"] = SimulationResult(times=preview[0], table=preview[1],
                                                   columns=preview[2])
    return res


#: Fewest rows in a block that :func:`integrate` checks with ``until`` or ``relax`` while their
#: test's ``time_ahead()`` says it is near: the run ends (or relaxes) within about this many
#: rows of where the test first holds. Each block costs a call into the compiled core and a
#: check, ~20-40 us on the 2-core test machine; 2 and 10 rows measured alike, [-].
NEAR_ROWS = 5
#: Part of the test's estimate (``time_ahead()``) that the next block covers: below 1, as a
#: piston that speeds up arrives sooner than at its last speed; 0.5-0.95 measured alike, [-].
AHEAD_SHARE = 0.8


class _Until:
    """:func:`integrate`'s ``until``, asked with every row so far (from the sink's table)."""

    def __init__(self, ask, rows: int, sink, columns):
        self.ask, self.rows, self.sink, self.columns = ask, rows, sink, columns
        self.when = None   # the last row's time [s] when first reached
        self.ahead = getattr(ask, "time_ahead", None)

    def next_rows(self, h_out: float) -> int:
        """Rows of the next block: ``rows``, or :data:`AHEAD_SHARE` of the test's own estimate
        of how soon it may hold (its ``time_ahead()``, [s]) where it has one, at least
        :data:`NEAR_ROWS`."""
        ahead = self.ahead() if self.ahead is not None else np.inf
        if not np.isfinite(ahead):
            return self.rows
        return int(min(self.rows, max(NEAR_ROWS, np.ceil(AHEAD_SHARE * ahead / h_out))))

    def reached(self) -> bool:
        """True when the run may end after the rows written so far."""
        so_far = self.sink.rows_so_far()
        done = so_far is not None and bool(self.ask(so_far[0], so_far[1], self.columns))
        if done and self.when is None:
            self.when = float(so_far[0][-1])
        return done


def _segments(network, sampled, edges, h_out, n_out, t_last, t_out, chunk_rows, bounded,
              backend, rows_in, model, x, p, progress, until=None, relaxing=None) -> None:
    """The segment loop of :func:`integrate`: each segment between breakpoints and sampling
    instants started on the backend, its output rows handed to ``rows_in`` chunk by chunk;
    it ends early where ``until`` (:class:`_Until`) is reached; the backend's tolerances are
    relaxed where ``relaxing`` (its :class:`_Until`, rtol, atol_scale) is."""
    n_signals = len(network.signal_names)
    target = getattr(rows_in, "target", None)
    at_edge = None   # the signals at the segment's start, where the backend gave them
    for a, b in zip(edges[:-1], edges[1:]):
        if sampled:
            apply_samples(network, sampled, a, x, p, at_edge)
        # output indices i0..i1-1 lie in (a, b]
        i0 = int(np.floor((a + 1e-12) / h_out)) + 1
        i1 = min(int(np.floor((b + 1e-12) / h_out)) + 1, n_out + 1)
        n_in = max(i1 - i0, 0)
        ends_on_grid = n_in > 0 and abs(t_out(i1 - 1, i1)[0] - b) <= 1e-12
        n_grid = n_in if ends_on_grid else n_in + 1   # the segment end b is always reached
        step = chunk_rows if (backend.chunked or bounded) else n_grid
        watched = until is not None and backend.chunked
        backend.start(a, x, b, p)
        k = 0
        while k < n_grid:
            # a watched run goes in blocks, shorter as its test's estimate nears (_Until)
            if watched or relaxing is not None:
                step = chunk_rows
                if watched:
                    step = min(step, until.next_rows(h_out))
                if relaxing is not None:
                    step = min(step, relaxing[0].next_rows(h_out))
            g = t_out(i0 + k, i0 + min(k + step, n_in))
            if k + step >= n_grid and not ends_on_grid:
                g = np.append(g, b)
            # rows written straight into the run's table where the sink keeps one (the extra
            # row at a segment end off the grid is overwritten by the next segment's first)
            X, table = backend.advance(g, out=target(len(g)) if target else None)
            m = min(n_in - k, len(g))
            if m > 0:
                if table is not None:
                    rows_in.write(g[:m], None, table[:m], model, p)
                else:
                    rows_in.write(g[:m], X[:m], None, model, p)
            x = X[-1].copy()
            at_edge = None if table is None else table[-1, :n_signals].copy()
            if progress and n_grid > step:
                progress(g[-1] / t_last)
            if until is not None and m > 0 and until.reached():
                if progress:
                    progress(1.0)
                return
            k += step
            if relaxing is not None and m > 0 and relaxing[0].reached():
                backend.relax(relaxing[1], relaxing[2])
                relaxing = None
                step = chunk_rows
        if progress:
            progress(b / t_last)
