"""The ``hydroline`` command: one subcommand per module in this package.

Every subcommand turns bad input into one clear line on stderr and exit code 2 (no
traceback). To add one, write a module with ``register(subparsers)`` (which sets
``func=run`` on its parser, ``run(args) -> int``) and list it in ``SUBCOMMANDS``.
"""
from __future__ import annotations

import argparse
import importlib
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
]


class UsageError(ValueError):
    """Bad input from the user: printed as one line, exit code 2."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hydroline",
        description="Electrohydraulic servo systems with supply and return hose dynamics.")
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
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError, KeyError) as e:   # UnitError, RigError, NetworkError
        msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        print(f"hydroline {args.command}: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"hydroline {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
