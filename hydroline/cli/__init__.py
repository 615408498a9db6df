"""The ``hydroline`` command: one subcommand per module in this package.

Every subcommand turns bad input into one clear line on stderr and exit code 2 (no
traceback); so do a model that cannot be started or run (no steady state, no C compiler
for ``--solver compiled``, integrator failure). A closed output pipe (``hydroline simulate
| head``) ends the command quietly with exit code 141 (128 + SIGPIPE, as a shell reports it). To add one, write a module with ``register(subparsers)`` (which sets
``func=run`` on its parser, ``run(args) -> int``) and list it in ``SUBCOMMANDS``.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

__all__ = ["main", "UsageError"]

#: Subcommand modules, in help order.
SUBCOMMANDS = [
    "simulate",
    "line_response",
    "bode",
    "fit",
    "friction_id",
    "layout",
    "sweep",
    "circuit",
]


class UsageError(ValueError):
    """Bad input from the user: printed as one line, exit code 2."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hydroline",
        description="Electrohydraulic servo systems with supply and return hose dynamics.",
        epilog="Equations cited as (M#) are in the model reference, docs/model.md.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMANDS:
        importlib.import_module(f"{__name__}.{name}").register(sub)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    from ..compiled import CompilerUnavailable
    from ..compiled.codegen import UnsupportedOperation
    from ..simulation import SteadyStateError

    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError, KeyError) as e:   # UnitError, RigError, NetworkError
        return _one_line(args, e)
    except (SteadyStateError, CompilerUnavailable, UnsupportedOperation) as e:
        return _one_line(args, e)
    except BrokenPipeError:
        _silence_stdout()
        return 141
    except RecursionError:
        raise
    except RuntimeError as e:   # the integrator gave up (step size, non-finite states)
        return _one_line(args, e, "model error: ")
    except KeyboardInterrupt:
        print(f"hydroline {args.command}: interrupted", file=sys.stderr)
        return 130


def _one_line(args, e, prefix="") -> int:
    """Print an exception as one line on stderr; exit code 2."""
    msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
    try:
        print(f"hydroline {args.command}: error: {prefix}{msg}", file=sys.stderr)
    except BrokenPipeError:
        pass
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
