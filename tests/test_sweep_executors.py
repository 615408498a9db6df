"""The local worker processes of a sweep (hydroline.studies.executors.run_processes): variants
sent in chunks of neighbours, every row recorded once and in its chunk's order, a dying
worker's variants retried one by one, a row that cannot be sent back failing alone."""
import os
import time
from pathlib import Path

import pytest

from hydroline.studies import executors
from hydroline.studies.executors import CHUNK_SECONDS, CHUNKS_PER_WORKER, chunk_size


class Runner:
    """A picklable stand-in for the sweep's runner: a row per variant after ``seconds``; the
    variant ``dies`` ends its worker the first time it runs (a file under ``marks`` says it
    did), the variant ``unsendable`` returns a row that cannot be pickled."""

    def __init__(self, marks, seconds=0.004, dies=None, unsendable=None):
        self.marks, self.seconds, self.dies, self.unsendable = str(marks), seconds, dies, unsendable

    def __call__(self, index, values):
        time.sleep(self.seconds)
        if index == self.dies:
            mark = Path(self.marks) / f"died{index}"
            if not mark.exists():
                mark.touch()
                os._exit(1)
        row = {"variant": index, "x": values["x"], "pid": os.getpid()}
        if index == self.unsendable:
            row["x"] = lambda: None
        return row


def failed(index, values, reason):
    return {"variant": index, "x": values["x"], "error": reason}


def run(runner, n, monkeypatch):
    """Rows in the order recorded, and the chunk sizes sent."""
    sizes = []

    def counted(*args):
        sizes.append(chunk_size(*args))
        return sizes[-1]

    monkeypatch.setattr(executors, "chunk_size", counted)
    rows = []
    executors.run_processes([(i, {"x": 0.5 * i}) for i in range(n)], 2, runner, rows.append,
                            failed)
    return rows, sizes


def test_chunk_size_from_the_pace_and_what_is_left():
    assert chunk_size(None, 1000, 2) == 1                     # nothing timed yet
    assert chunk_size(0.01, 1000, 2) == round(CHUNK_SECONDS / 0.01)
    assert chunk_size(1e-4, 1000, 2) == 1000 // (CHUNKS_PER_WORKER * 2)
    assert chunk_size(0.01, 24, 2) == 24 // (CHUNKS_PER_WORKER * 2)
    assert chunk_size(0.01, 5, 2) == 1
    assert chunk_size(10.0, 1000, 2) == 1                     # slow variants: one by one


def test_chunks_record_every_row_once_and_a_dying_worker_is_retried(tmp_path, monkeypatch):
    n = 120
    rows, sizes = run(Runner(tmp_path, dies=70), n, monkeypatch)
    assert sorted(r["variant"] for r in rows) == list(range(n))
    assert all("error" not in r and r["x"] == 0.5 * r["variant"] for r in rows)
    assert (tmp_path / "died70").exists()                     # it did die, and ran again
    assert max(sizes) > 1 and sizes[:4] == [1, 1, 1, 1]      # chunks once a variant is timed


def test_a_row_that_cannot_be_sent_back_fails_alone(tmp_path, monkeypatch):
    n = 60
    rows, _ = run(Runner(tmp_path, unsendable=30), n, monkeypatch)
    assert sorted(r["variant"] for r in rows) == list(range(n))
    bad = [r for r in rows if "error" in r]
    assert [r["variant"] for r in bad] == [30]
    assert "pickle" in bad[0]["error"].lower()
