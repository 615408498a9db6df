"""Plain-text tables for the benchmark scripts (right-aligned columns under a dashed rule)."""
from __future__ import annotations


def text_table(head, rows) -> str:
    """A table as text: the header, a rule of dashes, one line per row.

    Parameters
    ----------
    head : sequence   Column titles
    rows : sequence   Rows (sequences of values, printed with ``str``)
    """
    widths = [max(len(str(r[i])) for r in [*rows, head]) for i in range(len(head))]
    lines = ["  ".join(str(h).rjust(w) for h, w in zip(head, widths)),
             "  ".join("-" * w for w in widths)]
    lines += ["  ".join(str(c).rjust(w) for c, w in zip(r, widths)) for r in rows]
    return "\n".join(lines)
