"""How results show in a terminal and a notebook: a title and a table of labelled values, as text
(``__repr__``) or HTML (``_repr_html_``). Pure Python (no NumPy, no pandas): the objects that use
it import it at start-up."""
from __future__ import annotations

import html
import math

__all__ = ["format_value", "text_block", "html_block"]


def format_value(v, digits: int = 4) -> str:
    """A value as a short string: floats to ``digits`` significant digits, None and NaN as "-".

    Parameters
    ----------
    v : object
        The value (a number, text, None or a sequence of these).
    digits : int
        Significant digits of a float.

    Returns
    -------
    str
        The value as shown in a table cell.
    """
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, float) or type(v).__name__.startswith("float"):
        return f"{float(v):.{digits}g}"
    if isinstance(v, (list, tuple)):
        return ", ".join(format_value(x, digits) for x in v)
    return str(v)


def text_block(title: str, rows, header=None) -> str:
    """A title and rows of cells as plain text (``__repr__``).

    Parameters
    ----------
    title : str
        First line.
    rows : list of sequence
        Table rows (each cell formatted by :func:`format_value`); a two-cell row reads
        ``label: value``.
    header : sequence of str
        Column names of a table with more than two columns (None: a label/value list).

    Returns
    -------
    str
        The lines, joined.
    """
    cells = [[format_value(c) for c in r] for r in rows]
    if header is None:
        width = max((len(r[0]) for r in cells), default=0)
        return "\n".join([title] + [f"  {r[0]:<{width}}  {' '.join(r[1:])}" for r in cells])
    table = [list(header)] + cells
    widths = [max(len(r[k]) for r in table) for k in range(len(header))]
    lines = ["  " + "  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in table]
    return "\n".join([title] + lines)


def html_block(title: str, rows, header=None, note: str = "") -> str:
    """A title and rows of cells as an HTML table (``_repr_html_``), text escaped.

    Parameters
    ----------
    title : str
        Shown in bold above the table.
    rows : list of sequence
        Table rows (each cell formatted by :func:`format_value`).
    header : sequence of str
        Column names (None: none; the first column is then the label).
    note : str
        A line under the table (None or "": none).

    Returns
    -------
    str
        HTML.
    """
    esc = html.escape
    out = [f"<div><b>{esc(title)}</b>", "<table>"]
    if header is not None:
        out.append("<tr>" + "".join(f"<th>{esc(str(h))}</th>" for h in header) + "</tr>")
    for r in rows:
        cells = [format_value(c) for c in r]
        if header is None:
            out.append(f"<tr><th style=\"text-align:left\">{esc(cells[0])}</th>"
                       + "".join(f"<td style=\"text-align:left\">{esc(c)}</td>"
                                 for c in cells[1:]) + "</tr>")
        else:
            out.append("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in cells) + "</tr>")
    out.append("</table>")
    if note:
        out.append(f"<small>{esc(note)}</small>")
    out.append("</div>")
    return "\n".join(out)
