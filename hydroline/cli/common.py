"""Helpers shared by the subcommands: units on the command line, output folders, tables."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from ..units import parse_quantity

__all__ = ["quantity", "out_dir", "print_table", "dump_json", "progress_printer"]


def quantity(text, unit, name):
    """A command-line quantity with units -> SI float (UnitError, one line, on misuse)."""
    return parse_quantity(text, unit, name)


def out_dir(path) -> Path:
    p = Path(path)
    p.mkdir(parents=True, exist_ok=True)
    return p


def print_table(headers, rows, file=None):
    """Plain aligned text table."""
    file = file or sys.stdout
    cells = [[str(h) for h in headers]] + [[_fmt(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    for k, r in enumerate(cells):
        print("  ".join(c.rjust(w) for c, w in zip(r, widths)), file=file)
        if k == 0:
            print("  ".join("-" * w for w in widths), file=file)


def _fmt(c):
    if c is None:
        return "-"
    if isinstance(c, float):
        return f"{c:.4g}"
    return str(c)


def dump_json(obj, file=None):
    """Strict JSON (RFC 8259) on stdout or ``file``: NaN and +-inf, which JSON has no word
    for, are written as null (a metric that does not exist)."""
    import math

    def clean(v):
        if isinstance(v, float):
            return v if math.isfinite(v) else None
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        return v

    json.dump(clean(obj), file or sys.stdout, indent=2, allow_nan=False)
    (file or sys.stdout).write("\n")


def progress_printer(label, enabled=True):
    """A callable(fraction) drawing a one-line progress bar on stderr (when it is a TTY)."""
    if not enabled or not sys.stderr.isatty():
        return None

    def show(frac):
        n = int(frac * 30)
        sys.stderr.write(f"\r{label} [{'#' * n}{'.' * (30 - n)}] {frac * 100:5.1f} %")
        if frac >= 1:
            sys.stderr.write("\n")
        sys.stderr.flush()

    return show
