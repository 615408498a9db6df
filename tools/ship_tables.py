"""Write the tables shipped with the package (``hydroline/shipped_tables``, read by
:func:`hydroline.cache.load_table` where the cache has no entry): the line realisations the
default rig's first commands compute (``hydroline simulate``, ``bode``, ``layout`` at its
default lengths), so that a first run after installing skips them (issue 25: ~0.15 s CPU of
a first ``simulate``, and SciPy's Bessel functions), and the nodes over the dissipation
number a fit of the default record's section-II bulk moduli interpolates its lines from
(:mod:`hydroline.lines.residue_table`: ~0.3 s CPU of a first ``fit``).

Run by hand after a change of the line code (their keys name its source: the old entries are
then simply not found; ``tests/test_cache.py`` says when they are out of date):
``python tools/ship_tables.py`` (about 10 s).
"""
from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

#: The cache's kinds that are shipped: the lines' realisations, correction factors and the
#: nodes of interpolated lines
KINDS = ("residue_lines", "correction_factors", "residue_line_nodes")
#: The fit whose nodes are shipped (the first fit `benchmarks/bench_user.py` times)
FIT = ("--params", "supply.section2.bulk_modulus,return.section2.bulk_modulus")


def main() -> int:
    """Compute the tables in an empty cache and copy them into the package.

    Returns
    -------
    int
        Exit code, 0 on success
    """
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["HYDROLINE_CACHE_DIR"] = tmp
        os.environ["HYDROLINE_BACKGROUND_BUILD"] = "0"
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        from hydroline.cache import SHIPPED_TABLES
        from hydroline.cli import main as hydroline

        for command in ("simulate", "bode", "layout"):   # as a user's first commands
            if hydroline([command, "--out", str(Path(tmp) / command)]) != 0:
                return 1
        record = str(Path(tmp) / "simulate" / "results.csv")
        if hydroline(["fit", record, *FIT, "--out", str(Path(tmp) / "fit")]) != 0:
            return 1
        if SHIPPED_TABLES.exists():
            shutil.rmtree(SHIPPED_TABLES)
        count = 0
        for kind in KINDS:
            for entry in sorted((Path(tmp) / kind).glob("*.json")):
                (SHIPPED_TABLES / kind).mkdir(parents=True, exist_ok=True)
                shutil.copyfile(entry, SHIPPED_TABLES / kind / entry.name)
                count += 1
    print(f"{count} tables written to {SHIPPED_TABLES}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
