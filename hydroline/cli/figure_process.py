"""Draw a command's figure in a second process while the first one simulates.

Matplotlib's import and one figure's drawing take about as long as the rest of a
``hydroline simulate`` run. A forked child imports Matplotlib while the parent builds the model,
simulates and writes the CSV; the parent then hands it the columns the figure needs and waits
for the PNG. On a machine with two cores the whole process ends when the longer of the two
branches does, not after their sum. Where ``os.fork`` does not exist (Windows), or with
``HYDROLINE_FIGURE_PROCESS=0``, the figure is drawn in the parent as before.

The figure's branch (Matplotlib's import, then one figure drawn) is the longer one, so it
starts as early as it can: :func:`start_early` forks at the very start of ``hydroline.cli.main``
when the command line asks for a figure, before the arguments are parsed or the command's
module is imported, and the command takes that process with :func:`claim_figure_process`
(an unclaimed one is let go by :func:`cancel_unclaimed`). The child imports only the Agg
canvas and ``matplotlib.figure``, without the 3-D projection, with Python's cyclic garbage
collector off (it draws one figure and exits).
"""
from __future__ import annotations

import gc
import os
import pickle
import signal
import sys
import threading
import warnings

__all__ = ["FigureProcess", "start_early", "claim_figure_process", "cancel_unclaimed"]

#: The process forked by :func:`start_early` and not claimed yet.
_early = None


def start_early() -> None:
    """Fork the figure process now (at a command's start), for :func:`claim_figure_process`."""
    global _early
    if _early is None:
        _early = FigureProcess()


def claim_figure_process() -> "FigureProcess":
    """The figure process started by :func:`start_early`, or a new one when none was."""
    global _early
    figures, _early = _early, None
    return figures if figures is not None else FigureProcess()


def cancel_unclaimed() -> None:
    """Let go of a process :func:`start_early` forked that no command claimed (the command
    line turned out to ask for no figure, or was refused)."""
    global _early
    figures, _early = _early, None
    if figures is not None:
        figures.cancel()


def import_matplotlib() -> None:
    """Import what a figure on the Agg canvas needs, and no more: ``matplotlib.figure``
    registers the 3-D projection (``mpl_toolkits.mplot3d``, ~10 % of the import) unless it
    cannot be imported; the figure process draws 2-D figures only, so it is marked absent
    (Matplotlib then goes on without it; its warning about that is not shown)."""
    if "matplotlib.figure" in sys.modules:
        return
    sys.modules.setdefault("mpl_toolkits.mplot3d", None)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Unable to import Axes3D")
        import matplotlib.backends.backend_agg  # noqa: F401
        import matplotlib.figure  # noqa: F401


def _read_all(fd: int) -> bytes:
    chunks = []
    while True:
        b = os.read(fd, 1 << 20)
        if not b:
            return b"".join(chunks)
        chunks.append(b)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


class FigureProcess:
    """A forked process that imports Matplotlib now and draws one figure later.

    Use :meth:`draw` once with a module-level drawing function and its arguments (all
    picklable: arrays, not open files), or :meth:`cancel`. :meth:`draw` returns when the
    figure is written; an error in the child is raised again in the parent (the same exception
    where it can be pickled, else ``RuntimeError`` with its text).
    """

    def __init__(self):
        self.pid = None
        self._job_w = self._done_r = None
        if not hasattr(os, "fork") or os.environ.get("HYDROLINE_FIGURE_PROCESS", "1") == "0":
            return
        import numpy  # noqa: F401  (both processes need it: imported once, before the fork)

        job_r, self._job_w = os.pipe()
        self._done_r, done_w = os.pipe()
        pid = os.fork()
        if pid == 0:   # the child: never returns
            os.close(self._job_w)
            os.close(self._done_r)
            self._child(job_r, done_w)
        os.close(job_r)
        os.close(done_w)
        self.pid = pid

    @staticmethod
    def _child(job_r: int, done_w: int):
        status = 1
        try:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            signal.signal(signal.SIGINT, signal.SIG_DFL)
            # one figure, then os._exit: the cyclic collector would only walk the objects
            # (and copy the parent's pages it touches): ~3 % of the import
            gc.disable()
            import_matplotlib()   # (the import being overlapped)

            job = _read_all(job_r)
            if job:
                function, args, kwargs = pickle.loads(job)
                function(*args, **kwargs)
            _write_all(done_w, b"ok")
            status = 0
        except BaseException as e:   # reported to the parent, which raises it
            try:
                try:
                    report = b"E" + pickle.dumps(e)
                    pickle.loads(report[1:])
                except Exception:   # an exception that does not travel: its text
                    report = b"T" + f"{type(e).__name__}: {e}".encode(errors="replace")
                _write_all(done_w, report)
            except OSError:
                pass
        finally:
            os._exit(status)

    def submit(self, function, *args, **kwargs) -> None:
        """Hand the child ``function(*args, **kwargs)`` to draw now, and return at once (in
        this process, where there is no child, it is drawn by :meth:`wait`).

        Parameters
        ----------
        function : callable   A module-level function that writes the figure
        args, kwargs          Its arguments (picklable)
        """
        self._job = (function, args, kwargs)
        if self.pid is None:
            return
        data, fd = pickle.dumps(self._job, protocol=5), self._job_w
        self._job_w = None   # (its number may be reused by a file opened later)

        def send():   # the job is larger than a pipe holds: written while this process goes on
            try:
                _write_all(fd, data)
            except OSError:   # the child is gone: wait() reports it
                pass
            finally:
                os.close(fd)

        self._sender = threading.Thread(target=send, name="figure-job", daemon=True)
        self._sender.start()

    def wait(self) -> None:
        """Wait for the figure handed over by :meth:`submit`; raise the child's error here."""
        if self.pid is None:
            job, self._job = getattr(self, "_job", None), None
            if job is not None:
                function, args, kwargs = job
                function(*args, **kwargs)
            return
        answer = _read_all(self._done_r)
        self._join_sender()
        os.close(self._done_r)
        self._done_r = None
        os.waitpid(self.pid, 0)
        self.pid = None
        if answer == b"ok":
            return
        if answer.startswith(b"E"):   # the child's exception, raised here (a full disk: OSError)
            raise pickle.loads(answer[1:])
        text = answer[1:].decode(errors="replace") if answer else "the process died"
        raise RuntimeError(f"drawing the figure failed: {text}")

    def _join_sender(self) -> None:
        sender, self._sender = getattr(self, "_sender", None), None
        if sender is not None:
            sender.join()

    def draw(self, function, *args, **kwargs) -> None:
        """:meth:`submit` then :meth:`wait`: draw and return when the figure is written.

        Parameters
        ----------
        function : callable   A module-level function that writes the figure
        args, kwargs          Its arguments (picklable)
        """
        self.submit(function, *args, **kwargs)
        self.wait()

    def cancel(self) -> None:
        """Let the child go without drawing (an error in the parent, nothing to draw): stopped
        at once when it has no job yet (it may still be importing Matplotlib)."""
        if self.pid is None:
            return
        if self._job_w is not None:   # nothing submitted: no figure is being written
            try:
                os.kill(self.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        for fd in (self._job_w, self._done_r):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._job_w = self._done_r = None
        try:
            os.waitpid(self.pid, 0)
        except ChildProcessError:
            pass
        self._join_sender()
        self.pid = None
