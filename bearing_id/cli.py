"""``bearing-id``: the offline command line (no ROS needed for model, simulate, identify, diagnose).

Each subcommand lives in ``bearing_id/commands/<name>.py`` and exposes ``add_parser(subparsers)`` and
``run(args) -> int``.  Exit codes: 0 success, 1 a result that must not be trusted (e.g. undetermined
coefficients), 2 bad input (parameters, files).
"""
from __future__ import annotations

import argparse
import importlib
import sys

from .params import ParamError

COMMANDS = ("model", "simulate", "design", "identify", "diagnose", "record", "play")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bearing-id",
        description="Identify journal-bearing stiffness and damping of a flexible rotor from shaft displacement "
                    "(SI units inside; rpm and micrometres in printed tables).")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            mod = importlib.import_module(f"bearing_id.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"bearing_id.commands.{name}":
                raise
            continue
        p = mod.add_parser(sub)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    try:
        return int(args._run(args) or 0)
    except ParamError as exc:
        print(f"bearing-id {args.command}: parameter error: {exc}", file=sys.stderr)
        return 2
    except (FileNotFoundError, IsADirectoryError, PermissionError) as exc:
        print(f"bearing-id {args.command}: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
