"""Parameter sweeps: many variants of a rig through one scenario, in parallel, resumable.

Each variant is ``rig.copy()``, ``rig.set(path, value)`` for every varied path, then
:func:`hydroline.scenarios.simulate` and :func:`hydroline.scenarios.summarize`; its row holds
the inputs (SI units, one column per rig path), the port metrics and an ``error`` column. A
variant that fails (a negative bore, a steady state that does not converge, a worker process
that dies twice on it) gets its reason in ``error`` and the sweep goes on.

Where it runs
-------------
* ``workers=1``: in this process, one variant after the other;
* ``workers=W``: W local worker processes (``concurrent.futures``);
* ``scheduler="tcp://host:port"``: an existing Dask cluster (``dask.distributed``); hydroline
  must be installed on its workers. ``scheduler="local"`` starts a local Dask cluster of W
  single-threaded worker processes on 127.0.0.1, and a ``distributed.Client`` may be passed
  as is. Only a bounded window of variants is in flight at any time (four per worker
  thread), so 10^5 variants need no more memory than 100.

Results file and resume
-----------------------
With ``out=DIR`` every finished row is appended to ``DIR/sweep.jsonl`` the moment it
arrives (one JSON object per line, after a header line that identifies the sweep: rig hash,
scenario, end time, solver and the design). ``resume=True`` reads that file, checks that it
belongs to the same sweep, keeps every row already there (failed ones included: a failure is
a result) and runs only the missing variants; a line cut short by a kill is dropped and its
variant run again. On an interruption (Ctrl-C, SIGTERM to the CLI, an exception from the
callback) the variants already running are waited for and recorded too. At the end (or on
interruption) the table of every finished variant of the design, in variant order, is
written to ``DIR/sweep.csv`` and, where pyarrow is installed, to ``DIR/sweep.parquet``
(otherwise :attr:`SweepResult.notes` says so). Rows of a random design resumed with a smaller
``samples`` stay in the results file, out of the table (a note says so).

Worker processes end with the process that started the sweep, even when it is killed with
SIGKILL (a thread in each worker watches it: a pidfd on Linux, else a poll every 0.5 s).

Per-variant time limits are not offered: the compiled integrator runs a whole variant in one
C call, which a Python-level timer cannot interrupt, and ending a worker process from the
parent breaks the pool for the other variants in flight.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import signal
import sys
import time as _time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from ..rigs import Rig, RigError, load_rig
from ..scenarios import SCENARIOS, simulate
from .design import Design, parse_parameters
from .settling import port_summary

__all__ = ["sweep", "run_variant", "SweepResult", "SweepFileError", "METRIC_COLUMNS",
           "JOURNAL_NAME", "read_journal"]

#: Metric columns of every row (then ``warnings`` and ``error``); the closed-loop scenario adds
#: ``tracking_error_rms_mm`` and ``tracking_error_max_mm``.
METRIC_COLUMNS = ["supply_frequency_hz", "supply_amplitude_mpa", "supply_settling_time_s",
                  "return_frequency_hz", "return_amplitude_mpa", "return_settling_time_s",
                  "supply_first_excursion_mpa", "supply_steady_change_mpa",
                  "supply_peak_to_peak_mpa", "return_first_excursion_mpa",
                  "return_steady_change_mpa", "return_peak_to_peak_mpa", "wall_time_s"]
#: Port metrics taken from :func:`hydroline.scenarios.summarize` into each row (one definition
#: for simulate, layout and sweep, :func:`hydroline.analysis.pressure_metrics`).
_PORT_METRICS = ("frequency_hz", "amplitude_mpa", "settling_time_s", "first_excursion_mpa",
                 "steady_change_mpa", "peak_to_peak_mpa")
TRACKING_COLUMNS = ["tracking_error_rms_mm", "tracking_error_max_mm"]
#: How each settling time was obtained: "measured", "estimated" or "" (none), see
#: :func:`hydroline.studies.settling.port_settling`.
SETTLING_COLUMNS = ["supply_settling_method", "return_settling_method"]
JOURNAL_NAME = "sweep.jsonl"
FORMAT_VERSION = 1
#: Times a variant may be in flight when a worker process dies before it is recorded failed.
MAX_ATTEMPTS = 2
#: Most local worker processes (or local Dask workers) a sweep starts, [-].
MAX_WORKERS = 512


class SweepFileError(ValueError):
    """A results file that cannot be used (another sweep's, or one that exists without resume)."""


# --------------------------------------------------------------------------- one variant

def _set_si(rig: Rig, path: str, value, unit: str):
    """Set a rig parameter from an SI value through :meth:`Rig.set` (so it is validated)."""
    if unit in ("-", "str"):
        rig.set(path, value)
    else:
        rig.set(path, f"{value!r} {unit}")


def run_variant(rig: Rig, index: int, values: dict, scenario: str = "open-loop-step",
                t_end: float | None = None, solver: str = "auto", units: dict | None = None) -> dict:
    """Run one variant and return its row; never raises for a bad variant.

    Parameters
    ----------
    rig : Rig          The base rig (not modified)
    index : int        Variant number, [-]
    values : dict      Rig path -> value in SI units (text for text parameters)
    scenario : str     "open-loop-step" or "closed-loop-sine"
    t_end : float      Simulated time, [s]; the scenario's default when None
    solver : str       See :func:`hydroline.engine.integrate`
    units : dict       Rig path -> SI unit (looked up in the rig schema when None)

    Returns
    -------
    dict  ``variant``, the inputs, :data:`METRIC_COLUMNS` (frequencies [Hz], amplitudes,
          first excursions, steady changes and peak-to-peak [MPa], settling times [s], wall
          time [s]; None where a metric does not exist),
          :data:`SETTLING_COLUMNS` (how each settling time was obtained, as in the layout
          study: :func:`hydroline.studies.settling.port_settling`), ``warnings`` (text, ""
          when none) and ``error`` (None, or "Type: reason").
    """
    from .design import parameter_unit

    tic = _time.perf_counter()
    row = {"variant": int(index), **values}
    for k in METRIC_COLUMNS:
        row[k] = None
    if scenario == "closed-loop-sine":
        for k in TRACKING_COLUMNS:
            row[k] = None
    for k in SETTLING_COLUMNS:
        row[k] = ""
    row["warnings"], row["error"] = "", None
    try:
        r = rig.copy()
        for path, v in values.items():
            _set_si(r, path, v, (units or {}).get(path) or parameter_unit(path))
        res = simulate(r, scenario, t_end, solver=solver)
        s = port_summary(res)
        for side in ("supply", "return"):
            for k in _PORT_METRICS:
                row[f"{side}_{k}"] = _finite_or_none(s[side].get(k))
            row[f"{side}_settling_method"] = s[side].get("settling_method") or ""
        for k in TRACKING_COLUMNS:
            if k in s:
                row[k] = _finite_or_none(s[k])
        row["warnings"] = "; ".join(s["warnings"])
    except Exception as e:   # a failed variant is recorded, never sinks the sweep
        row["error"] = _reason(e)
    row["wall_time_s"] = _time.perf_counter() - tic
    return row


def _finite_or_none(v):
    """None for a metric that does not exist (None or NaN/inf): rows are strict JSON."""
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def _json_line(row: dict) -> str:
    """One results-file line; NaN/inf (never valid JSON) become null."""
    return json.dumps({k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                       for k, v in row.items()}, allow_nan=False)


def _reason(e: BaseException) -> str:
    msg = str(e).strip().splitlines()[0] if str(e).strip() else ""
    return f"{type(e).__name__}: {msg}" if msg else type(e).__name__


def _failed_row(index, values, reason, scenario) -> dict:
    row = {"variant": int(index), **values, **{k: None for k in METRIC_COLUMNS}}
    if scenario == "closed-loop-sine":
        row.update({k: None for k in TRACKING_COLUMNS})
    row.update({k: "" for k in SETTLING_COLUMNS})
    row["warnings"], row["error"] = "", reason
    return row


# --------------------------------------------------------------------------- results file

def _rig_hash(rig: Rig) -> str:
    text = json.dumps(sorted((k, repr(v)) for k, v in rig.values.items()))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _header(rig, design, scenario, t_end, solver) -> dict:
    head = {"hydroline_sweep": FORMAT_VERSION, "rig": rig.source, "rig_sha256": _rig_hash(rig),
            "scenario": scenario, "t_end_s": t_end, "solver": solver, "design": design.header()}
    return json.loads(json.dumps(head))     # as it reads back from the file


def read_journal(path) -> tuple[dict | None, dict]:
    """The header and rows (variant -> row) of a results file; a last line cut short by a
    kill is ignored. Returns (None, {}) for a missing or empty file."""
    path = Path(path)
    if not path.exists():
        return None, {}
    header, rows = None, {}
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    for k, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            obj = json.loads(line)
        except json.JSONDecodeError:
            if k >= len(lines) - 2:      # the last line, cut short by a kill
                continue
            raise SweepFileError(f"{path}: line {k + 1} is not valid JSON; "
                                 f"the file is damaged (start a new --out)") from None
        if header is None:
            if obj.get("hydroline_sweep") != FORMAT_VERSION:
                raise SweepFileError(f"{path}: not a hydroline sweep results file")
            header = obj
        else:
            rows[int(obj["variant"])] = obj
    return header, rows


def _trim_partial_line(path: Path):
    """Cut a last line left half-written by a kill, so appends start on a fresh line."""
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        path.write_bytes(data[: data.rfind(b"\n") + 1])


def _same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, (int, float)):
        return a == b or (math.isnan(a) and math.isnan(b))
    return a == b


@dataclass
class SweepResult:
    """The outcome of :func:`sweep`.

    Attributes
    ----------
    table : pandas.DataFrame  One row per finished variant, in variant order: ``variant``,
                              the inputs (one column per rig path, SI units), the metrics
                              (:data:`METRIC_COLUMNS`), ``warnings`` and ``error``
    design : Design           The variants
    n_computed : int          Variants run by this call (the rest came from the results file)
    wall_time : float         Wall time of this call, [s]
    files : dict              "journal", "csv", "parquet" -> Path of the files written
    complete : bool           Every variant of the design is in the table
    notes : list[str]         What the user should know about the files: sweep.parquet not
                              written (pyarrow missing), rows of the results file beyond
                              this design left out of the table (a larger --samples earlier)
    """

    table: pd.DataFrame
    design: Design
    n_computed: int = 0
    wall_time: float = 0.0
    files: dict = field(default_factory=dict)
    complete: bool = True
    notes: list = field(default_factory=list)

    @property
    def failed(self) -> pd.DataFrame:
        """The rows of failed variants (``error`` set)."""
        return self.table[self.table["error"].notna()]

    @property
    def n_failed(self) -> int:
        return int(self.table["error"].notna().sum())


def _table(rows: dict, design: Design, scenario: str) -> pd.DataFrame:
    cols = ["variant", *design.columns, *METRIC_COLUMNS]
    if scenario == "closed-loop-sine":
        cols += TRACKING_COLUMNS
    cols += [*SETTLING_COLUMNS, "warnings", "error"]
    data = [rows[i] for i in sorted(rows) if i < len(design)]
    df = pd.DataFrame(data, columns=cols)
    for c in cols:
        if c in METRIC_COLUMNS or c in TRACKING_COLUMNS:
            df[c] = pd.to_numeric(df[c], errors="coerce").astype(float)
    df["variant"] = df["variant"].astype(int)
    for c in SETTLING_COLUMNS:          # rows of an older results file lack them
        df[c] = df[c].fillna("").astype(str)
    df["error"] = df["error"].astype(object).where(df["error"].notna(), None)
    return df.reset_index(drop=True)


def _write_tables(df: pd.DataFrame, out: Path, files: dict, notes: list):
    """sweep.csv, and sweep.parquet where pyarrow is installed (a note says why not)."""
    df.to_csv(out / "sweep.csv", index=False)
    files["csv"] = out / "sweep.csv"
    try:
        import pyarrow  # noqa: F401  (optional)
    except ImportError:
        notes.append("sweep.parquet not written: pip install pyarrow (sweep.csv holds the "
                     "same table)")
        return
    try:
        df.to_parquet(out / "sweep.parquet", index=False)
    except Exception as e:      # e.g. a column pyarrow cannot type; the CSV stands
        notes.append(f"sweep.parquet not written: {_reason(e)} (sweep.csv holds the table)")
        return
    files["parquet"] = out / "sweep.parquet"


# --------------------------------------------------------------------------- backends

_WORKER: dict = {}


def _die_with_parent(parent_pid: int):
    """End this worker as soon as the process that started the sweep is gone, even when it
    was killed with SIGKILL and could not stop its pool.

    A daemon thread waits on a pidfd of that process (Linux >= 5.3: readable when it exits,
    immune to pid reuse) or, where there is none, checks once every 0.5 s that it is still
    alive; then it ends the worker with ``os._exit``. (``prctl(PR_SET_PDEATHSIG)`` would not
    do: the workers' parent is the forkserver, which itself stays up while any worker holds
    its "alive" pipe.) No-op on Windows, where the pool's own pipes end the workers."""
    if os.name != "posix":
        return
    import threading

    try:
        fd = os.pidfd_open(parent_pid)
    except ProcessLookupError:      # gone already
        os._exit(1)
    except (AttributeError, OSError):   # no pidfd (not Linux, old kernel, seccomp): poll
        fd = None

    def watch():
        if fd is not None:
            import select

            select.select([fd], [], [])
        else:
            while _alive(parent_pid):
                _time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="hydroline-parent-watch", daemon=True).start()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:             # exists, owned by someone else
        return True
    return True


def _init_worker(rig, scenario, t_end, solver, units, parent_pid=None):
    signal.signal(signal.SIGINT, signal.SIG_IGN)    # the parent decides when to stop
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if parent_pid is not None:
        _die_with_parent(parent_pid)
    _WORKER.update(rig=rig, scenario=scenario, t_end=t_end, solver=solver, units=units)


def _pool_task(index, values):
    w = _WORKER
    return run_variant(w["rig"], index, values, w["scenario"], w["t_end"], w["solver"], w["units"])


def _mp_context():
    import multiprocessing as mp

    methods = mp.get_all_start_methods()
    if "forkserver" in methods:      # fresh, thread-free parent for workers; fast after the first
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(["hydroline.studies.sweep"])
        return ctx
    return mp.get_context("spawn")


def _run_serial(tasks, run, record):
    for index, values in tasks:
        record(run(index, values))


@contextlib.contextmanager
def _main_module_hidden():
    """Keep worker processes from re-running the caller's script.

    The spawn and forkserver start methods import the parent's ``__main__`` (by path or by
    module name) in every new worker, as ``__mp_main__``; a script that calls
    :func:`sweep` at its top level without an ``if __name__ == "__main__":`` guard would then
    start the sweep again inside each worker. The workers need nothing from ``__main__``
    (the task, the rig and the results are hydroline objects), so while the pool starts
    workers ``__main__`` shows neither its ``__spec__`` nor its ``__file__``."""
    main = sys.modules.get("__main__")
    saved = {}
    if main is not None:
        for attr in ("__spec__", "__file__"):
            if attr in vars(main):
                saved[attr] = vars(main)[attr]
        if "__spec__" in saved:
            main.__spec__ = None
        if "__file__" in saved:
            del main.__file__
    try:
        yield
    finally:
        for attr, value in saved.items():
            setattr(main, attr, value)


def _run_processes(tasks, workers, init_args, record, scenario):
    with _main_module_hidden():
        _run_process_pool(tasks, workers, init_args, record, scenario)


def _run_process_pool(tasks, workers, init_args, record, scenario):
    """Local worker processes; a pool broken by a dying worker is restarted and the variants
    in flight retried, up to :data:`MAX_ATTEMPTS` times each. On an interruption (Ctrl-C,
    SIGTERM, an exception from ``record``) the variants already running are waited for and
    every one that finished is recorded before the exception goes on."""
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    pending = deque(tasks)
    attempts: dict = {}
    window = 4 * workers
    ctx = _mp_context()
    init_args = (*init_args, os.getpid())
    while pending:
        inflight = {}
        pool = ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init_worker,
                                   initargs=init_args)
        try:
            while pending or inflight:
                while pending and len(inflight) < window:
                    index, values = pending.popleft()
                    inflight[pool.submit(_pool_task, index, values)] = (index, values)
                done, _ = wait(inflight, return_when=FIRST_COMPLETED)
                for fut in done:
                    index, values = inflight[fut]
                    try:
                        row = fut.result()
                    except BrokenProcessPool:
                        raise
                    except Exception as e:      # e.g. a result that could not be sent back
                        row = _failed_row(index, values, _reason(e), scenario)
                    try:
                        record(row)
                    finally:                    # until recorded, an interruption leaves it
                        inflight.pop(fut, None)  # to the handler below
        except BaseException as e:
            if not isinstance(e, BrokenProcessPool):    # interrupted: let the running ones
                _finish_interrupted(pool, inflight, record)   # finish, keep what they computed
                raise
            # a worker died: keep what finished, retry the rest
            for fut, (index, values) in inflight.items():
                if fut.done() and not fut.cancelled() and fut.exception() is None:
                    record(fut.result())
                    continue
                attempts[index] = attempts.get(index, 0) + 1
                if attempts[index] >= MAX_ATTEMPTS:
                    record(_failed_row(index, values, "WorkerDied: the worker process died while "
                                       "running this variant (crash or out of memory)", scenario))
                else:
                    pending.appendleft((index, values))
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


def _finish_interrupted(pool, inflight: dict, record):
    """After an interruption: cancel the variants not started, wait for the running ones
    and record every one that finished without an exception (in variant order)."""
    try:
        pool.shutdown(wait=True, cancel_futures=True)
    except BaseException:       # a second Ctrl-C: record what is done now, then stop
        pass
    finished = [(index, fut) for fut, (index, _) in inflight.items()
                if fut.done() and not fut.cancelled() and fut.exception() is None]
    inflight.clear()
    _record_all(record, [fut.result() for _, fut in sorted(finished, key=lambda item: item[0])])


def _record_all(record, rows):
    """Record rows while an interruption is being handled: an exception from the user's
    callback (raised after the row is written) does not keep the others from the file."""
    for row in rows:
        try:
            record(row)
        except Exception:
            pass


def _dask_client(scheduler, workers):
    """(client, cluster-or-None) for "local", an address, or a Client passed as is."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:    # pragma: no cover - dask[distributed] is a dependency
        raise RigError("--scheduler needs dask.distributed: pip install 'dask[distributed]'") from None
    if isinstance(scheduler, Client):
        return scheduler, None, False
    if scheduler == "local":
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None)
        return Client(cluster), cluster, True
    if not isinstance(scheduler, str) or "://" not in scheduler:
        raise RigError(f"--scheduler: expected 'local' or an address like tcp://host:8786, "
                       f"got {scheduler!r}")
    try:
        return Client(scheduler, timeout="30s"), None, True
    except (OSError, TimeoutError) as e:
        raise RigError(f"--scheduler {scheduler}: cannot reach the Dask scheduler ({e})") from None


def _run_dask(tasks, client, init_args, record, scenario):
    from distributed import as_completed

    rig, scen, t_end, solver, units = init_args
    rig_f = client.scatter(rig, broadcast=True)
    threads = sum(client.nthreads().values()) or 1
    window = max(8, 4 * threads)
    pending = deque(tasks)
    meta = {}
    ac = as_completed()

    def submit():
        index, values = pending.popleft()
        fut = client.submit(run_variant, rig_f, index, values, scen, t_end, solver, units,
                            pure=False, key=f"hydroline-variant-{index}-{os.urandom(4).hex()}")
        meta[fut.key] = (index, values, fut)
        ac.add(fut)

    while pending and len(meta) < window:
        submit()
    try:
        for fut in ac:
            index, values, _ = meta[fut.key]
            try:
                row = fut.result()
            except Exception as e:      # KilledWorker and the like: recorded, sweep goes on
                row = _failed_row(index, values, _reason(e), scenario)
            try:
                record(row)
            finally:                    # until recorded, an interruption leaves it to the
                meta.pop(fut.key, None)  # clean-up below
                fut.release()
            while pending and len(meta) < window:
                submit()
    finally:
        if meta:        # interrupted: keep what finished, drop what is still queued
            done = sorted((i, f) for i, _, f in meta.values() if f.status == "finished")
            rows = []
            for _, f in done:
                try:
                    rows.append(f.result(timeout=10))
                except Exception:
                    pass
            client.cancel([f for _, _, f in meta.values()])
            _record_all(record, rows)


# --------------------------------------------------------------------------- the sweep

def sweep(parameters, rig=None, *, samples: int | None = None, seed: int = 0,
          scenario: str = "open-loop-step", t_end: float | None = None, solver: str = "auto",
          workers: int | None = None, scheduler=None, out=None, resume: bool = False,
          progress=None, callback=None) -> SweepResult:
    """Run a parameter study of a rig: a full factorial or random samples, in parallel.

    Parameters
    ----------
    parameters : list or dict   What varies: ``["PATH=VALUES", ...]`` as on the command line
                                (``"supply.section2.bulk_modulus=150 MPa,220 MPa"``), or
                                ``{PATH: VALUES}`` with VALUES text, a list of quantities or a
                                :class:`~hydroline.studies.Distribution`; the syntax (levels,
                                ``linspace``, ``uniform``, ``normal``, ...) is in
                                :mod:`hydroline.studies.design`
    rig : Rig, str or None      The base rig (None: the embedded 2005 paper's rig)
    samples : int               Random design of this many variants; None: full factorial
    seed : int                  Seed of the random design, [-]
    scenario : str              "open-loop-step" or "closed-loop-sine"
    t_end : float               Simulated time per variant, [s]; the scenario's when None
    solver : str                See :func:`hydroline.engine.integrate`
    workers : int               Local worker processes (default: the CPU count), or the
                                number of workers of a ``scheduler="local"`` Dask cluster
    scheduler : str or Client   None: local processes; "local": a local Dask cluster;
                                "tcp://host:port": an existing Dask scheduler
    out : path                  Folder for ``sweep.jsonl`` (every row as it finishes),
                                ``sweep.csv`` and ``sweep.parquet``; None keeps it in memory
    resume : bool               Continue the sweep in ``out``: keep its rows, run the rest
    progress : callable         ``progress(done, total, failed)`` after each variant
    callback : callable         ``callback(row)`` after each variant is recorded (an
                                exception raised there stops the sweep; what is recorded
                                stays recorded)

    Returns
    -------
    SweepResult

    Raises
    ------
    ValueError (RigError, UnitError, SweepFileError) on bad input, one line naming it.
    """
    tic = _time.perf_counter()
    if scenario not in SCENARIOS:
        raise RigError(f"--scenario: unknown scenario {scenario!r} (known: {', '.join(SCENARIOS)})")
    if t_end is not None and not t_end > 0:
        raise RigError(f"--t-end must be > 0 s, got {t_end!r}")
    if not isinstance(rig, Rig):
        rig = load_rig(rig)
    params = parse_parameters(parameters)
    design = Design(params, samples, seed)
    workers = (os.cpu_count() or 1) if workers is None else int(workers)
    if not 1 <= workers <= MAX_WORKERS:
        raise RigError(f"--workers must be within 1 ... {MAX_WORKERS} [-] (processes on this "
                       f"machine or Dask workers), got {workers}")
    units = {path: p.unit for p in params for path in p.paths}
    header = _header(rig, design, scenario, t_end, solver)

    client = cluster = None
    owned = False
    if scheduler is not None:      # connect first: an unreachable cluster leaves no files
        client, cluster, owned = _dask_client(scheduler, workers)
    try:
        return _sweep(rig, design, header, scenario, t_end, solver, workers, client, out, resume,
                      progress, callback, units, tic)
    finally:
        if owned:
            client.close()
        if cluster is not None:
            cluster.close()


def _sweep(rig, design, header, scenario, t_end, solver, workers, client, out, resume,
           progress, callback, units, tic) -> SweepResult:
    rows: dict = {}
    files: dict = {}
    journal = None
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        jpath = out / JOURNAL_NAME
        files["journal"] = jpath
        old_header, old_rows = read_journal(jpath)
        if old_header is not None and not resume:
            raise SweepFileError(f"{jpath} exists: pass --resume to continue that sweep, or "
                                 f"choose another --out")
        if old_header is not None:
            _check_same_sweep(jpath, old_header, header)
            for i, row in old_rows.items():
                if i < len(design):
                    want = design.variant(i)
                    if any(not _same(row.get(k), v) for k, v in want.items()):
                        raise SweepFileError(f"{jpath}: variant {i} has other inputs than this "
                                             f"sweep's; it belongs to another sweep (start a new --out)")
                rows[i] = row
            _trim_partial_line(jpath)
            journal = open(jpath, "a", encoding="utf-8")
        else:
            journal = open(jpath, "w", encoding="utf-8")
            journal.write(json.dumps(header) + "\n")
            journal.flush()
    elif resume:
        raise RigError("--resume needs --out DIR (the folder of the sweep to continue)")

    total = len(design)
    tasks = [(i, design.variant(i)) for i in range(total) if i not in rows]
    done = [sum(1 for i in rows if i < total)]
    failed = [sum(1 for i, r in rows.items() if i < total and r.get("error"))]
    computed = [0]

    def record(row):
        i = row["variant"]
        rows[i] = row
        if journal is not None:
            journal.write(_json_line(row) + "\n")
            journal.flush()
        computed[0] += 1
        done[0] += 1
        failed[0] += bool(row.get("error"))
        if progress is not None:
            progress(done[0], total, failed[0])
        if callback is not None:
            callback(row)

    if progress is not None:
        progress(done[0], total, failed[0])
    init_args = (rig, scenario, t_end, solver, units)
    try:
        if not tasks:
            pass
        elif client is not None:
            _run_dask(tasks, client, init_args, record, scenario)
        elif workers == 1 or len(tasks) == 1:
            _run_serial(tasks, lambda i, v: run_variant(rig, i, v, scenario, t_end, solver, units),
                        record)
        else:
            _run_processes(tasks, min(workers, len(tasks)), init_args, record, scenario)
    finally:
        if journal is not None:
            journal.close()
        table = _table(rows, design, scenario)
        notes = []
        extra = sorted(i for i in rows if i >= total)
        if extra:           # a random design resumed with a smaller --samples: kept in the file
            notes.append(f"{len(extra)} variants of an earlier, larger run ({total}..{extra[-1]}) "
                         f"stay in {JOURNAL_NAME} but not in the table, which holds the "
                         f"{total} of this design; resume with --samples {extra[-1] + 1} to "
                         f"include them")
        if out is not None:
            _write_tables(table, out, files, notes)
    return SweepResult(table, design, computed[0], _time.perf_counter() - tic, files,
                       complete=len(table) == total, notes=notes)


def _check_same_sweep(path, old: dict, new: dict):
    for key, what in (("rig_sha256", "rig"), ("scenario", "scenario"), ("t_end_s", "--t-end"),
                      ("solver", "--solver")):
        if old.get(key) != new.get(key):
            raise SweepFileError(f"{path}: written by a sweep with another {what} "
                                 f"({old.get(key)!r}, now {new.get(key)!r}); start a new --out")
    if old.get("design") != new.get("design"):
        o, n = old.get("design") or {}, new["design"]
        what = ("design kind" if o.get("kind") != n["kind"] else
                "--seed" if o.get("seed") != n["seed"] else "parameters")
        raise SweepFileError(f"{path}: written by a sweep with other {what}; resume with the "
                             f"same --set/--samples/--seed, or start a new --out")
