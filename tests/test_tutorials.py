"""The tutorials of the documentation (docs/tutorials/tutorial_*.py) run to the end.

The documentation build runs them (sphinx-gallery executes each script in ``docs/tutorials``
and embeds its printed output and figures; a tutorial that raises fails the build), so CI
runs them once, there, and this file checks the built site: with
``HYDROLINE_DOCS_BUILT=docs/_build/html`` (``.ci/run`` sets it after ``sphinx-build``) every
tutorial's page holds its output, no traceback, and the figures it draws; the model reference
loads its maths from the site itself, not from the network.

``HYDROLINE_RUN_TUTORIALS=1`` instead runs each script as a user would (``python
docs/tutorials/tutorial_x.py`` in a scratch directory, Agg backend; each must exit 0 within a
minute), without building the documentation. Together they take about a minute of two cores,
more than the unit-test budget, so neither runs by default; the numbers each tutorial prints
are checked by the unit tests that the verification page lists.
"""
import os
import re
import subprocess
import sys
from html import unescape
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("tutorial_*.py"))
RUN = os.environ.get("HYDROLINE_RUN_TUTORIALS") == "1"
BUILT = os.environ.get("HYDROLINE_DOCS_BUILT")


def test_every_issue_topic_has_a_tutorial():
    """(a) paper study ... (f) line models, (g) own component: one script each, each with a sphinx-gallery title."""
    letters = sorted(p.name.split("_")[1] for p in TUTORIALS)
    assert letters == ["a", "b", "c", "d", "e", "f", "g"]
    for p in TUTORIALS:
        head = p.read_text().split('"""')[1].strip().splitlines()
        assert len(head) >= 2 and set(head[1]) == {"="} and len(head[1]) >= len(head[0]), p.name


@pytest.mark.skipif(not RUN, reason="set HYDROLINE_RUN_TUTORIALS=1 (the docs build runs them)")
@pytest.mark.parametrize("script", TUTORIALS, ids=lambda p: p.stem)
def test_tutorial_runs(script, tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-4000:]


def _draws_figures(script: Path) -> bool:
    """The script saves or plots a figure (hydroline's ``plot(path=...)``, ``save(folder)``
    of a layout study, or matplotlib directly)."""
    text = script.read_text()
    return bool(re.search(r"\.plot\(|savefig\(|plt\.subplots\(|\.save\(", text))


def _outputs(page: str) -> list[str]:
    """The printed output blocks of a sphinx-gallery page, as text."""
    blocks = re.findall(r'<div class="sphx-glr-script-out[^"]*">.*?<pre>(.*?)</pre>', page, re.S)
    return [unescape(re.sub(r"<[^>]+>", "", b)) for b in blocks]


@pytest.mark.skipif(not BUILT, reason="set HYDROLINE_DOCS_BUILT to a built site (CI does)")
@pytest.mark.parametrize("script", TUTORIALS, ids=lambda p: p.stem)
def test_built_tutorial_ran(script):
    """Its page has the script's printed output, no traceback, and its figures."""
    page_path = Path(BUILT) / "auto_tutorials" / f"{script.stem}.html"
    assert page_path.is_file(), f"{page_path}: not built"
    page = page_path.read_text()
    outputs = _outputs(page)
    assert outputs and all(o.strip() for o in outputs), \
        f"{script.name}: no printed output on its page (built with HYDROLINE_DOCS_EXECUTE=0?)"
    assert not any("Traceback (most recent call last)" in o for o in outputs), script.name
    images = re.findall(rf'<img[^>]+src="[^"]*sphx_glr_{script.stem}_\d+\.png"', page)
    if _draws_figures(script):
        assert images, f"{script.name} draws a figure but its page shows none"
        for src in re.findall(r'src="([^"]*sphx_glr_[^"]+\.png)"', page):
            assert (page_path.parent / src).is_file(), src


@pytest.mark.skipif(not BUILT, reason="set HYDROLINE_DOCS_BUILT to a built site (CI does)")
def test_built_site_renders_maths_offline():
    """The model reference loads MathJax from the site (sphinx-mathjax-offline), no CDN."""
    site = Path(BUILT)
    page = (site / "model.html").read_text()
    scripts = re.findall(r'<script[^>]*src="([^"]+)"', page)
    assert not [s for s in scripts if re.match(r"(https?:)?//", s)], scripts
    mathjax = [s for s in scripts if "mathjax" in s.lower()]
    assert mathjax and all((site / s.split("?")[0]).is_file() for s in mathjax), mathjax
    assert r"\tag{M5}" in page                  # the maths is there for it to typeset


@pytest.mark.skipif(not hasattr(__import__("signal"), "SIGALRM"), reason="no SIGALRM (Windows)")
def test_a_tutorial_past_the_time_limit_fails_naming_itself(monkeypatch):
    """The docs build's limit per tutorial (docs/gallery_timeout.py, sphinx-gallery's
    ``reset_modules`` hook): a tutorial still running at the limit raises an error naming it
    and the limit, which sphinx-gallery reports as that tutorial's failure; one that ends in
    time is not stopped; a bad setting is refused naming the variable."""
    import time

    sys.path.insert(0, str(ROOT / "docs"))
    try:
        import gallery_timeout as gt
    finally:
        sys.path.remove(str(ROOT / "docs"))
    monkeypatch.setenv(gt.ENVIRONMENT, "0.2")
    script = str(ROOT / "docs" / "tutorials" / "tutorial_x_hangs.py")
    gt.limit_time({}, script, "before")
    try:
        with pytest.raises(gt.TutorialTimeout, match=r"tutorial_x_hangs\.py: ran past .* 0\.2 s"):
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline:      # a hung tutorial (interruptible)
                time.sleep(0.01)
    finally:
        gt.limit_time({}, script, "after")
    gt.limit_time({}, script, "before")
    gt.limit_time({}, script, "after")              # ended in time: disarmed
    time.sleep(0.4)
    monkeypatch.setenv(gt.ENVIRONMENT, "soon")
    with pytest.raises(ValueError, match=gt.ENVIRONMENT):
        gt.time_limit()
    monkeypatch.setenv(gt.ENVIRONMENT, "0")
    assert gt.time_limit() == 0
