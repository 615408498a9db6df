"""Draw a command's figure in a second process while the first one simulates.

Matplotlib's import and one figure's drawing take about as long as the rest of a
``hydroline simulate`` run. A forked child imports Matplotlib while the parent builds the model,
simulates and writes the CSV; the parent then hands it the columns the figure needs and waits
for the PNG. On a machine with two cores the whole process ends when the longer of the two
branches does, not after their sum. Where ``os.fork`` does not exist (Windows), or with
``HYDROLINE_FIGURE_PROCESS=0``, the figure is drawn in the parent as before.
"""
from __future__ import annotations

import os
import pickle
import signal
import threading

__all__ = ["FigureProcess"]


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
            import matplotlib.backends.backend_agg  # noqa: F401  (the import being overlapped)
            import matplotlib.figure  # noqa: F401

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
