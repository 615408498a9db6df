"""Where a sweep's variants run: in this process, in local worker processes, or on Dask.

Every executor takes the variants as ``(index, values)`` tasks, a *runner* -- a picklable
callable ``runner(index, values) -> row`` that never raises for a bad variant (the sweep's
:class:`hydroline.studies.sweep.VariantRunner`) -- and ``record(row)``, called in this
process once per finished variant, in completion order. A variant whose worker fails in a
way the runner cannot report (a worker process that dies, a row that cannot be sent back)
gets the row ``failed_row(index, values, reason)``.

* :func:`run_serial` -- one variant after the other, here;
* :func:`run_processes` -- W local worker processes (``concurrent.futures``, forkserver where
  there is one): the runner is sent once per worker and kept there, so whatever it builds
  for the first variant (the compiled model of the rig's structure) serves every later one;
  neighbouring variants are sent together, as many as run in about :data:`CHUNK_SECONDS`
  (:func:`chunk_size`); a pool broken by a dying worker is restarted and its variants
  retried, one by one (:data:`MAX_ATTEMPTS`); the workers end with this process even when
  it is killed with SIGKILL (:func:`die_with_parent`); on an interruption (Ctrl-C, SIGTERM,
  an exception from ``record``) the variants already running are waited for and recorded;
* :func:`run_dask` -- a ``dask.distributed`` cluster (:func:`dask_client`), a bounded window
  of variants in flight (four per worker thread), the runner scattered once.
"""
from __future__ import annotations

import contextlib
import os
import signal
import sys
import time
from collections import deque

from ..blas import blas_thread_variables_set
from ..rigs import RigError

__all__ = ["run_serial", "run_processes", "run_dask", "worker_pool", "dask_client", "die_with_parent",
           "quiet_resource_tracker", "failure_reason", "chunk_size", "MAX_ATTEMPTS", "MAX_WORKERS",
           "WINDOW_PER_WORKER", "CHUNK_SECONDS", "CHUNKS_PER_WORKER"]

#: Times a variant may be in flight when a worker process dies before it is recorded failed.
MAX_ATTEMPTS = 2
#: Most local worker processes (or local Dask workers) a sweep starts, [-].
MAX_WORKERS = 512
#: Variants in flight per worker (process or Dask thread), [-]: enough to keep every worker
#: busy, few enough that 10^5 variants need no more memory than 100.
WINDOW_PER_WORKER = 4
#: Local worker processes: the variants sent to a worker at once (neighbours in the
#: design) take about this long together, [s]. A task costs this process ~0.5 ms of
#: bookkeeping and its worker ~0.1 ms (pipes, pickles, futures): on W workers on W cores
#: (1000 variants of ~10 ms) that is time taken from the variants; a chunk's rows reach
#: ``record`` (the journal, the progress) when the whole chunk is done.
CHUNK_SECONDS = 0.2
#: ... and at most the remaining variants over this many chunks per worker, so that the
#: last chunks are short and the workers finish together, [-].
CHUNKS_PER_WORKER = 4


def failure_reason(e: BaseException) -> str:
    """The ``error`` text of a failed variant: ``"Type: first line of the message"``.

    Parameters
    ----------
    e : BaseException
        What the variant raised

    Returns
    -------
    str
    """
    msg = str(e).strip().splitlines()[0] if str(e).strip() else ""
    return f"{type(e).__name__}: {msg}" if msg else type(e).__name__


# --------------------------------------------------------------------------- in this process

def run_serial(tasks, runner, record) -> None:
    """Run every task here, one after the other, recording each row as it finishes.

    Parameters
    ----------
    tasks : iterable
        ``(index, values)`` pairs
    runner : callable
        ``runner(index, values) -> row``
    record : callable
        ``record(row)``
    """
    for index, values in tasks:
        record(runner(index, values))


# --------------------------------------------------------------------------- local processes

#: The runner of this worker process (set by its initializer).
_WORKER: dict = {}


def die_with_parent(parent_pid: int) -> None:
    """End this worker as soon as the process that started the sweep is gone, even when it
    was killed with SIGKILL and could not stop its pool.

    A daemon thread waits on a pidfd of that process (Linux >= 5.3: readable when it exits,
    immune to pid reuse) or, where there is none, checks once every 0.5 s that it is still
    alive; then it ends the worker with ``os._exit``. (``prctl(PR_SET_PDEATHSIG)`` would not
    do: the workers' parent is the forkserver, which itself stays up while any worker holds
    its "alive" pipe.) No-op on Windows, where the pool's own pipes end the workers.

    Parameters
    ----------
    parent_pid : int
        Process id of the sweep's process, [-]
    """
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
            while process_alive(parent_pid):
                time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="hydroline-parent-watch", daemon=True).start()


def process_alive(pid: int) -> bool:
    """True while a process of this id exists (ours or another user's).

    Parameters
    ----------
    pid : int
        Process id, [-]

    Returns
    -------
    bool
    """
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:             # exists, owned by someone else
        return True
    return True


def _init_worker(runner, parent_pid=None):
    signal.signal(signal.SIGINT, signal.SIG_IGN)    # the parent decides when to stop
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if parent_pid is not None:
        die_with_parent(parent_pid)
    _WORKER["runner"] = runner


def _pool_task(index, values):
    return _WORKER["runner"](index, values)


def _pool_chunk(chunk):
    """The rows of a chunk of ``(index, values)`` tasks, in order, and the seconds taken."""
    tic = time.perf_counter()
    rows = [_WORKER["runner"](index, values) for index, values in chunk]
    return rows, time.perf_counter() - tic


def chunk_size(seconds_per_variant, remaining: int, workers: int) -> int:
    """How many neighbouring variants a local worker gets at once: as many as take
    :data:`CHUNK_SECONDS`, at most ``remaining / (CHUNKS_PER_WORKER workers)``, at least one
    (one while no variant has been timed: the first builds the models).

    Parameters
    ----------
    seconds_per_variant : float or None
        Wall time of a variant on a worker, the latest measured, [s]
    remaining : int
        Variants not yet sent, [-]
    workers : int
        Worker processes, [-]

    Returns
    -------
    int
        Variants in the next chunk, [-]
    """
    if seconds_per_variant is None:
        return 1
    by_time = int(CHUNK_SECONDS / max(seconds_per_variant, 1e-9))
    return max(1, min(by_time, remaining // (CHUNKS_PER_WORKER * workers)))


#: The resource tracker's warning when the process that started the workers was killed
#: (SIGKILL) before it could release their semaphores: the tracker releases them, and says so
#: in two lines of a Python warning that tell the user nothing to do.
_LEAK_WARNING = "ignore:resource_tracker:UserWarning"


def quiet_resource_tracker() -> None:
    """Start multiprocessing's resource tracker (as the first pool would) with its warning
    about semaphores "leaked" by a killed sweep turned off; it still releases them. A tracker
    already running is left as it is."""
    from multiprocessing import resource_tracker

    added = _LEAK_WARNING not in sys.warnoptions
    if added:   # the tracker is a new interpreter started with this process's -W options
        sys.warnoptions.append(_LEAK_WARNING)
    try:
        resource_tracker.ensure_running()
    finally:
        if added:
            sys.warnoptions.remove(_LEAK_WARNING)


def _mp_context():
    import multiprocessing as mp

    methods = mp.get_all_start_methods()
    if "forkserver" in methods:      # fresh, thread-free parent for workers; fast after the first
        ctx = mp.get_context("forkserver")
        # scipy.fft: the metrics' spectra, hydroline.compiled.codegen: CasADi and the C
        # writer (a new structure's graph; a single run of a known model needs neither);
        # imported once in the server instead of in every worker's first variant (a new hose
        # length's line needs no scipy.special: hydroline.lines.bessel)
        ctx.set_forkserver_preload(["hydroline.studies.sweep", "scipy.fft",
                                    "hydroline.compiled.codegen"])
        return ctx
    return mp.get_context("spawn")


@contextlib.contextmanager
def _main_module_hidden():
    """Keep worker processes from re-running the caller's script.

    The spawn and forkserver start methods import the parent's ``__main__`` (by path or by
    module name) in every new worker, as ``__mp_main__``; a script that calls
    :func:`hydroline.studies.sweep` at its top level without an ``if __name__ ==
    "__main__":`` guard would then start the sweep again inside each worker. The workers need
    nothing from ``__main__`` (the task, the rig and the results are hydroline objects), so
    while the pool starts workers ``__main__`` shows neither its ``__spec__`` nor its
    ``__file__``."""
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


def run_processes(tasks, workers: int, runner, record, failed_row) -> None:
    """Run the tasks on ``workers`` local worker processes.

    Neighbouring tasks go to a worker together (:func:`chunk_size`); ``record`` gets a
    chunk's rows when it is done, in the tasks' order. A pool broken by a dying worker is
    restarted and the variants in flight retried, one by one, up to :data:`MAX_ATTEMPTS`
    times each. On an interruption (Ctrl-C, SIGTERM, an exception from
    ``record``) the variants already running are waited for and every one that finished is
    recorded before the exception goes on.

    Parameters
    ----------
    tasks : iterable
        ``(index, values)`` pairs
    workers : int
        Worker processes, [-]
    runner : callable
        Picklable ``runner(index, values) -> row``, sent once per worker
    record : callable
        ``record(row)``, in this process
    failed_row : callable
        ``failed_row(index, values, reason) -> row``
    """
    # (the workers, and a forkserver started now, run one BLAS thread each: the models'
    # matrices are small, and W workers on W cores leave no core to extra threads)
    with _main_module_hidden(), blas_thread_variables_set():
        _run_process_pool(tasks, workers, runner, record, failed_row)


def _run_process_pool(tasks, workers, runner, record, failed_row):
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    pending = deque(tasks)
    attempts: dict = {}
    alone: set = set()        # sent one by one: retried after a dying worker or a lost chunk
    window = 2 * workers      # chunks in flight: one running and one queued per worker
    pace = None               # seconds a variant, the latest chunk's
    ctx = _mp_context()
    if os.name == "posix":
        quiet_resource_tracker()
    init_args = (runner, os.getpid())

    def next_chunk():
        size = chunk_size(pace, len(pending), workers)
        chunk = [pending.popleft()]
        while pending and len(chunk) < size and chunk[0][0] not in alone and \
                pending[0][0] not in alone:
            chunk.append(pending.popleft())
        return chunk

    while pending:
        inflight = {}
        unrecorded = deque()    # rows of a finished chunk not yet recorded
        pool = ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init_worker,
                                   initargs=init_args)
        try:
            while pending or inflight:
                while pending and len(inflight) < window:
                    chunk = next_chunk()
                    inflight[pool.submit(_pool_chunk, chunk)] = chunk
                done, _ = wait(inflight, return_when=FIRST_COMPLETED)
                for fut in done:
                    chunk = inflight[fut]
                    try:
                        rows, seconds = fut.result()
                        pace = seconds / len(chunk)
                    except BrokenProcessPool:
                        raise
                    except Exception as e:      # e.g. a result that could not be sent back
                        if len(chunk) > 1:      # whose? each again, alone
                            alone.update(index for index, _ in chunk)
                            pending.extendleft(reversed(chunk))
                            del inflight[fut]
                            continue
                        rows = [failed_row(*chunk[0], failure_reason(e))]
                    del inflight[fut]           # until recorded, an interruption leaves
                    unrecorded.extend(rows)     # them to the handler below
                    while unrecorded:
                        record(unrecorded.popleft())
        except BaseException as e:
            if not isinstance(e, BrokenProcessPool):    # interrupted: let the running ones
                record_all(record, unrecorded)           # finish, keep what they computed
                _finish_interrupted(pool, inflight, record)
                raise
            record_all(record, unrecorded)
            # a worker died: keep what finished, retry the rest, one by one
            for fut, chunk in inflight.items():
                if fut.done() and not fut.cancelled() and fut.exception() is None:
                    for row in fut.result()[0]:
                        record(row)
                    continue
                for index, values in reversed(chunk):
                    attempts[index] = attempts.get(index, 0) + 1
                    alone.add(index)
                    if attempts[index] >= MAX_ATTEMPTS:
                        record(failed_row(index, values, "WorkerDied: the worker process died "
                                          "while running this variant (crash or out of memory)"))
                    else:
                        pending.appendleft((index, values))
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


@contextlib.contextmanager
def worker_pool(workers: int, runner):
    """W local worker processes that keep ``runner`` (and the models it builds) for as long as
    the pool is open: for a study that sends its variants in rounds, each decided by the
    last (an optimiser's batches), where :func:`run_processes` would start new workers (and
    build the models anew) per round. The workers end with this process (as in
    :func:`run_processes`); a dying worker is not retried: its variant's future raises.

    Parameters
    ----------
    workers : int
        Worker processes, [-]
    runner : callable
        Picklable ``runner(index, values) -> row``, sent once per worker

    Yields
    ------
    callable
        ``submit(index, values) -> concurrent.futures.Future`` of the variant's row
    """
    from concurrent.futures import ProcessPoolExecutor

    ctx = _mp_context()
    if os.name == "posix":
        quiet_resource_tracker()
    with _main_module_hidden():
        pool = ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init_worker,
                                   initargs=(runner, os.getpid()))
        try:
            yield lambda index, values: pool.submit(_pool_task, index, values)
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


def _finish_interrupted(pool, inflight: dict, record):
    """After an interruption: cancel the variants not started, wait for the running ones
    and record every one that finished without an exception (in variant order)."""
    try:
        pool.shutdown(wait=True, cancel_futures=True)
    except BaseException:       # a second Ctrl-C: record what is done now, then stop
        pass
    finished = [(chunk[0][0], fut) for fut, chunk in inflight.items()
                if fut.done() and not fut.cancelled() and fut.exception() is None]
    inflight.clear()
    record_all(record, [row for _, fut in sorted(finished, key=lambda item: item[0])
                        for row in fut.result()[0]])


def record_all(record, rows) -> None:
    """Record rows while an interruption is being handled: an exception from the user's
    callback (raised after the row is written) does not keep the others from the file.

    Parameters
    ----------
    record : callable
        ``record(row)``
    rows : iterable
        Rows to record
    """
    for row in rows:
        try:
            record(row)
        except Exception:
            pass


# --------------------------------------------------------------------------- Dask

def dask_client(scheduler, workers: int):
    """Connect to (or start) a Dask cluster.

    Parameters
    ----------
    scheduler : str or Client
        "local" (a local cluster of ``workers`` single-threaded
        processes on 127.0.0.1), "tcp://host:port", or a
        ``distributed.Client`` used as is
    workers : int
        Workers of a "local" cluster, [-]

    Returns
    -------
    (client, cluster or None, owned)  ``owned``: the caller closes the client

    Raises
    ------
    RigError  dask.distributed missing, a bad address, an unreachable scheduler (one line).
    """
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


def call_runner(runner, index, values):
    """``runner(index, values)``: the task a Dask worker runs (the runner scattered once).

    Parameters
    ----------
    runner : callable
        The sweep's variant runner
    index : int
        Variant number, [-]
    values : dict
        Rig path -> SI value

    Returns
    -------
    dict
        The variant's row
    """
    return runner(index, values)


def run_dask(tasks, client, runner, record, failed_row) -> None:
    """Run the tasks on a Dask cluster, at most :data:`WINDOW_PER_WORKER` per worker thread
    (at least 8) in flight; on an interruption the finished ones are recorded and the rest
    cancelled.

    Parameters
    ----------
    tasks : iterable
        ``(index, values)`` pairs
    client : Client
        A ``distributed.Client`` (:func:`dask_client`)
    runner : callable
        Picklable ``runner(index, values) -> row``
    record : callable
        ``record(row)``, in this process
    failed_row : callable
        ``failed_row(index, values, reason) -> row``
    """
    from distributed import as_completed

    runner_f = client.scatter(runner, broadcast=True)
    threads = sum(client.nthreads().values()) or 1
    window = max(8, WINDOW_PER_WORKER * threads)
    pending = deque(tasks)
    meta = {}
    ac = as_completed()

    def submit():
        index, values = pending.popleft()
        fut = client.submit(call_runner, runner_f, index, values, pure=False,
                            key=f"hydroline-variant-{index}-{os.urandom(4).hex()}")
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
                row = failed_row(index, values, failure_reason(e))
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
            record_all(record, rows)
