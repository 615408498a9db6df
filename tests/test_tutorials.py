"""The tutorials of the documentation (docs/tutorials/tutorial_*.py) run to the end.

Each script is run as a user would run it (``python docs/tutorials/tutorial_x.py``, in a
scratch directory, Agg backend) and must exit 0 within a minute. Together they take about
1.5 minutes of two cores, more than the unit-test budget, so they run only when
``HYDROLINE_RUN_TUTORIALS=1`` (the CI does: ``.ci/run``); the numbers each tutorial prints
are checked by the unit tests that the verification page lists.
"""
import os
import subprocess
import sys
from pathlib import Path

import pytest

TUTORIALS = sorted((Path(__file__).resolve().parents[1] / "docs" / "tutorials").glob("tutorial_*.py"))
RUN = os.environ.get("HYDROLINE_RUN_TUTORIALS") == "1"


def test_every_issue_topic_has_a_tutorial():
    """(a) paper study ... (f) line models, (g) own component: one script each, each with a sphinx-gallery title."""
    letters = sorted(p.name.split("_")[1] for p in TUTORIALS)
    assert letters == ["a", "b", "c", "d", "e", "f", "g"]
    for p in TUTORIALS:
        head = p.read_text().split('"""')[1].strip().splitlines()
        assert len(head) >= 2 and set(head[1]) == {"="} and len(head[1]) >= len(head[0]), p.name


@pytest.mark.skipif(not RUN, reason="set HYDROLINE_RUN_TUTORIALS=1 (CI runs them)")
@pytest.mark.parametrize("script", TUTORIALS, ids=lambda p: p.stem)
def test_tutorial_runs(script, tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-4000:]
