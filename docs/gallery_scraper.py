"""sphinx-gallery image scraper for the figures a tutorial writes to files.

hydroline's own plots (``SimulationResult.plot(path=...)``, ``LayoutStudy.save``) draw on
figures that pyplot does not hold, so sphinx-gallery's matplotlib scraper does not see them.
This scraper shows, after each code block, the PNG files the block wrote under the
tutorials' ``tutorial-out/`` folder. A block that leaves pyplot figures open is left to the
matplotlib scraper (it would otherwise show a figure it also saved twice).

Named in ``docs/conf.py`` as ``"gallery_scraper.written_figures"`` (a dotted name keeps the
Sphinx configuration picklable).
"""
from __future__ import annotations

import shutil
from pathlib import Path

#: Where the tutorials write their files (they run in ``docs/tutorials``)
FOLDER = Path(__file__).resolve().parent / "tutorials" / "tutorial-out"


def _snapshot() -> dict:
    if not FOLDER.is_dir():
        return {}
    return {p: p.stat().st_mtime_ns for p in FOLDER.rglob("*.png")}


_seen = _snapshot()


def written_figures(block, block_vars, gallery_conf) -> str:
    """reST for the PNG files written or rewritten since the previous code block."""
    global _seen
    import matplotlib.pyplot as plt
    from sphinx_gallery.scrapers import figure_rst

    now = _snapshot()
    new = sorted(p for p, t in now.items() if _seen.get(p) != t)
    _seen = now
    if plt.get_fignums():
        return ""
    names = []
    for path in new:
        target = next(block_vars["image_path_iterator"])
        shutil.copyfile(path, target)
        names.append(target)
    return figure_rst(names, gallery_conf["src_dir"])
