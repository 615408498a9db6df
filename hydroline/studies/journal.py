"""The sweep's results file (journal): one JSON object per line, appended as rows finish.

The first line is a header that identifies the sweep (rig hash, scenario, end time, solver,
design); every further line is one variant's row (``variant``, the inputs in SI units, the
metrics, ``warnings``, ``error``). :func:`hydroline.studies.sweep` appends a row the moment a
variant finishes, so a sweep interrupted by Ctrl-C, SIGTERM or SIGKILL loses at most the line
being written; ``resume=True`` reads the file back (:func:`read_journal`), checks that it
belongs to the same sweep (:func:`check_same_sweep`, :func:`check_same_inputs`), cuts a line
left half-written by a kill (:func:`trim_partial_line`) and appends the missing variants.
"""
from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

__all__ = ["JOURNAL_NAME", "FORMAT_VERSION", "SweepFileError", "rig_hash", "journal_header",
           "read_journal", "trim_partial_line", "json_line", "same_value", "check_same_sweep",
           "check_same_inputs", "Journal"]

#: File name of the journal inside the sweep's ``out`` folder.
JOURNAL_NAME = "sweep.jsonl"
#: Version of the journal format, written in the header (``hydroline_sweep``), [-].
FORMAT_VERSION = 1


class SweepFileError(ValueError):
    """A results file that cannot be used (another sweep's, or one that exists without resume).

    Parameters
    ----------
    *args : str
        The message: one line naming the file and what is wrong with it
    **kwargs : dict
        None taken (as ``ValueError``)
    """


def rig_hash(rig) -> str:
    """First 16 hex digits of the SHA-256 of a rig's values (path -> SI value), [-].

    Parameters
    ----------
    rig : Rig
        The base rig of the sweep

    Returns
    -------
    str
        16 hex digits
    """
    text = json.dumps(sorted((k, repr(v)) for k, v in rig.values.items()))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def journal_header(rig, design, scenario: str, t_end, solver: str) -> dict:
    """The header line of a sweep's journal, as it reads back from the file.

    Parameters
    ----------
    rig : Rig
        The base rig
    design : Design
        The variants (:meth:`hydroline.studies.Design.header`)
    scenario : str
        Scenario name
    t_end : float
        Simulated time per variant, [s] (None: the scenario's)
    solver : str
        Solver name

    Returns
    -------
    dict  ``hydroline_sweep`` (format version), ``rig``, ``rig_sha256``, ``scenario``,
          ``t_end_s`` [s], ``solver``, ``design``
    """
    head = {"hydroline_sweep": FORMAT_VERSION, "rig": rig.source, "rig_sha256": rig_hash(rig),
            "scenario": scenario, "t_end_s": t_end, "solver": solver, "design": design.header()}
    return json.loads(json.dumps(head))     # as it reads back from the file


def read_journal(path) -> tuple[dict | None, dict]:
    """The header and rows (variant -> row) of a results file; a last line cut short by a
    kill is ignored. Returns (None, {}) for a missing or empty file.

    Parameters
    ----------
    path : path
        The ``sweep.jsonl`` file

    Returns
    -------
    (dict or None, dict)
        The header, and variant -> row

    Raises
    ------
    SweepFileError  A damaged file (a line that is not JSON before the last) or another
                    program's file, one line naming it.
    """
    path = Path(path)
    if not path.exists():
        return None, {}
    header, rows = None, {}
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    for k, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            obj = json.loads(line)
        except json.JSONDecodeError:
            if k >= len(lines) - 2:      # the last line, cut short by a kill
                continue
            raise SweepFileError(f"{path}: line {k + 1} is not valid JSON; "
                                 f"the file is damaged (start a new --out)") from None
        if header is None:
            if obj.get("hydroline_sweep") != FORMAT_VERSION:
                raise SweepFileError(f"{path}: not a hydroline sweep results file")
            header = obj
        else:
            rows[int(obj["variant"])] = obj
    return header, rows


def trim_partial_line(path) -> None:
    """Cut a last line left half-written by a kill, so appends start on a fresh line.

    Parameters
    ----------
    path : path
        The ``sweep.jsonl`` file
    """
    path = Path(path)
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        path.write_bytes(data[: data.rfind(b"\n") + 1])


def json_line(row: dict) -> str:
    """One results-file line of a row; NaN/inf (never valid JSON) become null.

    Parameters
    ----------
    row : dict
        Column -> value (SI units)

    Returns
    -------
    str
        One line of strict JSON (no newline)
    """
    return json.dumps({k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                       for k, v in row.items()}, allow_nan=False)


def same_value(a, b) -> bool:
    """True when an input read back from the journal equals this design's (NaN equals NaN).

    Parameters
    ----------
    a, b : object
        Two input values (SI numbers or text)

    Returns
    -------
    bool
    """
    if isinstance(a, float) and isinstance(b, (int, float)):
        return a == b or (math.isnan(a) and math.isnan(b))
    return a == b


def check_same_sweep(path, old: dict, new: dict) -> None:
    """Refuse (one line) a journal whose header belongs to another sweep.

    Parameters
    ----------
    path : path
        The journal (named in the message)
    old : dict
        Its header (:func:`read_journal`)
    new : dict
        This sweep's header (:func:`journal_header`)

    Raises
    ------
    SweepFileError  Naming what differs: rig, scenario, --t-end, --solver, design kind,
                    --seed or parameters.
    """
    for key, what in (("rig_sha256", "rig"), ("scenario", "scenario"), ("t_end_s", "--t-end"),
                      ("solver", "--solver")):
        if old.get(key) != new.get(key):
            raise SweepFileError(f"{path}: written by a sweep with another {what} "
                                 f"({old.get(key)!r}, now {new.get(key)!r}); start a new --out")
    if old.get("design") != new.get("design"):
        o, n = old.get("design") or {}, new["design"]
        what = ("design kind" if o.get("kind") != n["kind"] else
                "--seed" if o.get("seed") != n["seed"] else "parameters")
        raise SweepFileError(f"{path}: written by a sweep with other {what}; resume with the "
                             f"same --set/--samples/--seed, or start a new --out")


def check_same_inputs(path, rows: dict, design) -> None:
    """Refuse (one line) journal rows whose inputs differ from this design's variants.

    Parameters
    ----------
    path : path
        The journal (named in the message)
    rows : dict
        variant -> row read back from it
    design : Design
        This sweep's variants
    """
    for i, row in rows.items():
        if i < len(design):
            want = design.variant(i)
            if any(not same_value(row.get(k), v) for k, v in want.items()):
                raise SweepFileError(f"{path}: variant {i} has other inputs than this "
                                     f"sweep's; it belongs to another sweep (start a new --out)")


class Journal:
    """An open journal to append rows to (a new file with its header, or one resumed).

    Parameters
    ----------
    path : path
        The ``sweep.jsonl`` file
    header : dict
        The header to write when the file is new (None: resume, append)
    """

    def __init__(self, path, header: dict | None = None):
        self.path = Path(path)
        if header is None:
            trim_partial_line(self.path)
            self.file = open(self.path, "a", encoding="utf-8")
        else:
            self.file = open(self.path, "w", encoding="utf-8")
            self.file.write(json.dumps(header) + "\n")
            self.file.flush()

    def append(self, row: dict) -> None:
        """Write one row as a line and flush it (it survives a kill of this process).

        Parameters
        ----------
        row : dict
            Column -> value (SI units)
        """
        self.file.write(json_line(row) + "\n")
        self.file.flush()

    def close(self) -> None:
        """Close the file (every row written so far is on disk)."""
        self.file.close()
