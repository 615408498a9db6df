"""The ``hydroline`` command: one subcommand per module in this package.

Every subcommand turns bad input into one clear line on stderr and exit code 2 (no
traceback); so do a model that cannot be started or run (no steady state, no C compiler
for ``--solver compiled``, integrator failure), an output that cannot be written (a full
disk, stdout on ``/dev/full``), input nested too deeply to read and a run too large for
memory; an option or argument given as an empty string is refused the same way (it does not
silently mean the default). A closed output pipe (``hydroline simulate | head``) or a closed
stdout (``hydroline simulate --json >&-``) ends the command quietly with exit code 141
(128 + SIGPIPE, as a shell reports it); Ctrl-C with 130 and SIGTERM with 143 (128 + the
signal). To add one, write a module with ``register(subparsers)`` (which sets
``func=run`` on its parser, ``run(args) -> int``) and list it in ``SUBCOMMANDS``.
"""
from __future__ import annotations

import argparse
import errno
import functools
import gc
import importlib
import io
import os
import re
import signal
import sys

from ..blas import single_threaded_blas
from ..cache import BACKGROUND_BUILD_ENV
from . import figure_process

__all__ = ["main", "UsageError", "Terminated", "version", "refuse_empty_values", "ClosedStdout"]

#: Subcommand modules, in help order.
SUBCOMMANDS = [
    "simulate",
    "line_response",
    "bode",
    "fit",
    "friction_id",
    "layout",
    "sweep",
    "envelope",
    "optimize",
    "circuit",
    "export_fmu",
]


class UsageError(ValueError):
    """Bad input from the user: printed as one line, exit code 2.

    Parameters
    ----------
    *args : str
        The message: one line naming the option.
    **kwargs : dict
        None taken (as ``ValueError``).
    """


class Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an exception so that a run stops as cleanly as on Ctrl-C (temporary
    files removed, finished sweep variants recorded); the command exits with 143.

    Parameters
    ----------
    *args : str
        The message.
    **kwargs : dict
        None taken (as ``KeyboardInterrupt``).
    """


def raise_terminated(signum, frame):
    """SIGTERM handler: raise :class:`Terminated` (a command then stops as on Ctrl-C).

    Parameters
    ----------
    signum : int
        The signal number
    frame : frame
        The interrupted stack frame (unused)
    """
    raise Terminated


class ClosedStdout(io.TextIOBase):
    """``sys.stdout`` of a command started with its stdout closed (``hydroline simulate --json
    >&-``: Python then sets ``sys.stdout`` to None): writing to it fails as writing to a pipe
    whose reader is gone does, so the command ends as ``hydroline simulate | head`` does, with
    exit code 141 and no traceback."""

    def writable(self) -> bool:
        """True: the command may try to write (and then learns that nobody reads).

        Returns
        -------
        bool
            Always True.
        """
        return True

    def write(self, text) -> int:
        """Refuse the text as a closed pipe would.

        Parameters
        ----------
        text : str
            What the command printed

        Raises
        ------
        BrokenPipeError
            Always (EPIPE)
        """
        raise BrokenPipeError(errno.EPIPE, "stdout is closed")


def version() -> str:
    """The installed version of hydroline (from the package metadata, without importing the
    model).

    Returns
    -------
    str
        The version, e.g. ``"0.9.0"``.
    """
    from importlib import metadata

    try:
        return metadata.version("hydroline")
    except metadata.PackageNotFoundError:     # run from a source tree that is not installed
        from .. import __version__

        return __version__


class _VersionAction(argparse.Action):
    """``--version``: the version looked up only when asked (importlib.metadata costs ~50 ms
    of every command's start-up otherwise)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help="show program's version number and exit"):
        super().__init__(option_strings, dest, nargs=0, default=default, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"hydroline {version()}")
        parser.exit()


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The argument parser; with ``only`` (a module name of ``SUBCOMMANDS``) just that
    subcommand is registered, so a command imports only its own module and what it uses.

    Parameters
    ----------
    only : str or None
        Module name of the one subcommand to register (``"line_response"``
        for ``line-response``); None registers all of them

    Returns
    -------
    argparse.ArgumentParser
    """
    parser = argparse.ArgumentParser(
        prog="hydroline",
        description="Electrohydraulic servo systems with supply and return hose dynamics.",
        epilog="Equations cited as (M#) are in the model reference, docs/model.md.")
    parser.add_argument("--version", action=_VersionAction)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMANDS if only is None else [only]:
        importlib.import_module(f"{__name__}.{name}").register(sub)
    return parser


def _requested_subcommand(argv) -> str | None:
    """The module of the subcommand named first on the command line (None: none or unknown,
    then every subcommand is registered for help and error messages)."""
    for arg in argv:
        if arg.startswith("-"):
            return None   # a global option (-h) before the command
        name = arg.replace("-", "_")
        return name if name in SUBCOMMANDS else None
    return None


def main(argv=None) -> int:
    """Run the ``hydroline`` command: parse the arguments and call the subcommand.

    A mistake the user can make (a bad unit, a missing file, a rig that does not solve) is
    printed as one line on stderr, without a traceback.

    Parameters
    ----------
    argv : list of str or None
        The arguments after ``hydroline`` (``sys.argv[1:]`` when None: the command's own
        process, the installed script's or ``python -m hydroline``'s, which ends when this
        returns: its objects are then frozen (``gc.freeze``), so that Python's shutdown does
        not collect over them)

    Returns
    -------
    int
        Exit code: 0 success, 2 bad input (or no subcommand), 130 interrupted, 141 closed
        stdout, 143 terminated, or the subcommand's own
    """
    process = argv is None           # the command's own process (the script, python -m)
    argv = sys.argv[1:] if argv is None else list(argv)
    if "numpy" not in sys.modules:   # a fresh process: one BLAS thread (the user's setting wins)
        single_threaded_blas()
    # a run whose compiled library is not built yet uses CVODES while it is built in the
    # background (the user's setting wins; restored after: main() may run in-process)
    background = BACKGROUND_BUILD_ENV not in os.environ
    if background:
        os.environ[BACKGROUND_BUILD_ENV] = "1"
    streams = sys.stdout, sys.stderr
    _closed_streams_replaced()       # (before the fork: the figure process inherits them)
    if draws_a_figure(argv):   # the figure's branch is the longer one: forked before parsing
        figure_process.start_early()
    try:
        return _parse_and_run(argv)
    finally:
        figure_process.cancel_unclaimed()
        if streams[0] is None or streams[1] is None:   # (main() may run in-process)
            sys.stdout, sys.stderr = streams
        if background:
            os.environ.pop(BACKGROUND_BUILD_ENV, None)
        if process:   # the process ends now: Python's shutdown skips the garbage collections
            gc.freeze()   # over every object left (~17 ms of a warm simulate --json's ~0.17 s)


def _closed_streams_replaced() -> None:
    """A command started with stdout or stderr closed (``>&-``, ``2>&-``; Python sets the
    stream to None): stdout becomes a :class:`ClosedStdout` (the command ends with 141, as
    on a closed pipe), stderr a sink (the command's messages are dropped, not sent to stdout
    by ``print(file=None)``). The closed descriptor is held on /dev/null, so that a file the
    run opens (a CSV, a pipe to the figure process) does not become fd 1 or 2."""
    for fd, name in ((1, "stdout"), (2, "stderr")):
        if getattr(sys, name) is not None:
            continue
        try:
            os.fstat(fd)
        except OSError:              # closed: keep the number taken
            try:
                null = os.open(os.devnull, os.O_WRONLY)
                if null != fd:
                    os.dup2(null, fd)
                    os.close(null)
            except OSError:
                pass
        setattr(sys, name, ClosedStdout() if name == "stdout" else open(os.devnull, "w"))


def draws_a_figure(argv) -> bool:
    """Whether a command line will (most likely) draw a figure (``hydroline simulate``'s,
    ``hydroline bode``'s, ``hydroline fit``'s, ``hydroline layout --out``'s): the figure
    process is started for it before the arguments are parsed. A wrong guess costs little: a
    process not claimed is stopped, and one missing is started when needed.

    Parameters
    ----------
    argv : list of str
        The arguments after ``hydroline``

    Returns
    -------
    bool
        True when a figure is likely drawn.
    """
    if not argv or argv[0] not in ("simulate", "bode", "fit", "layout"):
        return False
    options = {a.split("=", 1)[0] for a in argv[1:] if a.startswith("-")}
    if options & {"-h", "--help"}:
        return False
    if argv[0] == "layout":
        return "--out" in options
    return argv[0] in ("bode", "fit") or "--json" not in options or "--out" in options


def _parse_and_run(argv) -> int:
    parser = build_parser(_requested_subcommand(argv))
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    import warnings

    shown_before = warnings.showwarning   # restored after the command (main() may run in-process)
    warnings.showwarning = functools.partial(_show_warning, args.command, set())
    try:
        old_term = signal.signal(signal.SIGTERM, raise_terminated)
    except ValueError:          # not the main thread (e.g. called from a worker thread)
        old_term = None
    try:
        refuse_empty_values(args)
        rc = int(args.func(args) or 0)
        sys.stdout.flush()      # a full or closed stdout is found here, not at exit
        return rc
    except (ValueError, FileNotFoundError, KeyError) as e:   # UnitError, RigError, NetworkError
        return _one_line(args, e)
    except _model_errors() as e:   # (evaluated only when an exception is being matched)
        return _one_line(args, e)
    except BrokenPipeError:
        _silence_stdout()
        return 141
    except OSError as e:        # disk full, stdout on /dev/full, a folder that went away
        if _is_stdout_error():
            _silence_stdout()
            return _one_line(args, e, "cannot write to stdout: ")
        return _one_line(args, e, _os_prefix(e))
    except RecursionError:
        return _one_line(args, "input nested too deeply to process (lists or tables inside "
                         "each other hundreds of levels deep)")
    except MemoryError:
        return _one_line(args, "out of memory: the run is too large for this machine (fewer "
                         "modes, a shorter --t-end or a coarser output step)")
    except RuntimeError as e:   # the integrator gave up (step size, non-finite states)
        return _one_line(args, e, "model error: ")
    except Terminated:
        _say(f"hydroline {args.command}: terminated (SIGTERM)")
        return 143
    except KeyboardInterrupt:
        _say(f"hydroline {args.command}: interrupted")
        return 130
    finally:
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
        warnings.showwarning = shown_before


#: How the messages name a parsed value whose option is not ``--`` and its name (as the
#: usage line does).
ARGUMENT_NAMES = {"rig": "RIG", "files": "FILE", "sets": "--set"}


def refuse_empty_values(args) -> None:
    """Refuse an option or argument given as an empty or blank string: it would otherwise be
    taken as not given (``--t-end ""`` the scenario's own end time, ``--out ""`` the current
    folder, ``hydroline simulate ""`` the embedded rig).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line

    Raises
    ------
    UsageError
        One line naming the option
    """
    for dest, value in vars(args).items():
        values = value if isinstance(value, (list, tuple)) else (value,)
        if any(isinstance(v, str) and not v.strip() for v in values):
            name = ARGUMENT_NAMES.get(dest, "--" + dest.replace("_", "-"))
            raise UsageError(f"{name}: empty value; give one, or leave it out for the default")


def _model_errors() -> tuple:
    """The model's own errors that are printed as one line: imported only when an exception is
    being matched, so that a command's start-up (and the figure process it forks) does not
    import the model."""
    from ..compiled import CompilerUnavailable
    from ..compiled.codegen import UnsupportedOperation
    from ..engine import SteadyStateError

    return SteadyStateError, CompilerUnavailable, UnsupportedOperation


#: Matplotlib's warning, one per character, for text its font cannot draw (a rig or component
#: name in another script): said once, as :data:`MISSING_GLYPHS`.
_MISSING_GLYPH = re.compile(r"Glyph \d+ .*missing from font")
MISSING_GLYPHS = ("the figure's font cannot draw some characters of its text (a rig or "
                  "component name): they show as empty boxes")


def _show_warning(command, said, message, category, filename, lineno, file=None, line=None):
    """A Python warning as one line: ``hydroline <command>: warning: <message>`` (each once;
    Matplotlib's missing-glyph warnings, one per character, as one)."""
    text = (str(message).strip() or category.__name__).splitlines()[0]
    if _MISSING_GLYPH.match(text):
        text = MISSING_GLYPHS
    text = f"hydroline {command}: warning: {text}"
    if text not in said:   # each warning once per command
        said.add(text)
        _say(text)


def _say(text):
    try:
        print(text, file=sys.stderr)
    except (OSError, ValueError):
        pass


def _is_stdout_error() -> bool:
    """True when stdout cannot take what is buffered (a full device, a closed pipe)."""
    try:
        sys.stdout.flush()
        return False
    except (OSError, ValueError):
        return True


def _os_prefix(e: OSError) -> str:
    if e.errno == errno.ENOSPC and not e.filename:
        return "cannot write the output: "
    return f"cannot write {e.filename}: " if e.filename else ""


def _one_line(args, e, prefix="") -> int:
    """Print an exception as one line on stderr; exit code 2."""
    if isinstance(e, OSError) and not isinstance(e, FileNotFoundError) and e.strerror:
        msg = e.strerror
    else:
        msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
    if len(msg) > 500:         # one line, not a page (a huge value quoted back)
        msg = msg[:497] + "..."
    _say(f"hydroline {args.command}: error: {prefix}{msg}")
    return 2


def _silence_stdout():
    """After EPIPE on stdout: point it at /dev/null so the interpreter's final flush is quiet
    (https://docs.python.org/3/library/signal.html#note-on-sigpipe)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):   # no real file descriptor (captured stdout)
        pass


if __name__ == "__main__":
    sys.exit(main())
