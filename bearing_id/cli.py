"""
``bearing-id``: the offline command line (no ROS needed for model, simulate, identify, diagnose).

Each subcommand lives in ``bearing_id/commands/<name>.py`` and exposes ``add_parser(subparsers)`` and
``run(args) -> int``.  Exit codes: 0 success, 1 a result that must not be trusted (e.g. undetermined
coefficients), 2 bad input (parameters, files), 3 an internal error (a bug), 130 interrupted.

Bad input never shows a traceback: the readers (:mod:`bearing_id.config.params`, :mod:`bearing_id.simulation.rig`,
:mod:`bearing_id.io.daq`, :mod:`bearing_id.io.bags`) turn every malformed file into an error naming the file and the
problem, printed here as one paragraph on stderr.  An unexpected exception is reported as an internal error with
where it happened; ``BEARING_ID_TRACEBACK=1`` prints the full traceback.
"""
from __future__ import annotations

import argparse
import importlib
import os
from pathlib import Path
import sys
import traceback

from . import blas_threads  # noqa: F401  (before numpy: one BLAS thread unless the user set one)
from .commands.inputs import InputError
from .config.params import ParamError
from .io.bags import BagError
from .io.daq import DaqError

COMMANDS = ('model', 'simulate', 'design', 'identify', 'diagnose', 'report', 'trend', 'record', 'play', 'import_ross')


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """
    Return the command-line parser: every subcommand, or only the subcommand ``only`` (what :func:`main` parses with).

    A command line that names its subcommand imports and builds that one alone (its options, ``--help`` and errors
    are the subparser's).
    """
    parser = argparse.ArgumentParser(
        prog='bearing-id',
        description='Identify journal-bearing stiffness and damping of a flexible rotor from shaft displacement '
                    '(SI units inside; rpm and micrometres in printed tables).')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    for name in COMMANDS if only is None else (only,):
        try:
            mod = importlib.import_module(f'bearing_id.commands.{name}')
        except ModuleNotFoundError as exc:
            if exc.name != f'bearing_id.commands.{name}':
                raise
            continue
        p = mod.add_parser(sub)
        p.set_defaults(_run=mod.run)
    return parser


def _say(command: str, text: str) -> None:
    """One paragraph on stderr (whitespace of a multi-line library message folded)."""
    text = ' '.join(str(text).split())
    if len(text) > 2000:
        text = text[:2000] + ' ...'
    try:
        print(f'bearing-id {command}: {text}', file=sys.stderr)
    except (BrokenPipeError, OSError):  # pragma: no cover - stderr gone
        pass


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    name = argv[0].replace('-', '_') if argv else None         # 'import-ross' is bearing_id.commands.import_ross
    parser = build_parser(name if name in COMMANDS else None)
    args = parser.parse_args(argv)
    if not getattr(args, '_run', None):
        parser.print_help()
        return 2
    cmd = args.command
    try:
        return int(args._run(args) or 0)
    except ParamError as exc:
        _say(cmd, exc if isinstance(exc, InputError) else f'parameter error: {exc}')
        return 2
    except (BagError, DaqError) as exc:
        _say(cmd, exc)
        return 2
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError, PermissionError) as exc:
        _say(cmd, exc)
        return 2
    except MemoryError:
        _say(cmd, 'out of memory: the input is too large for this machine')
        return 2
    except KeyboardInterrupt:
        _say(cmd, 'interrupted')
        return 130
    except BrokenPipeError:             # `bearing-id ... | head`
        return 0
    except Exception as exc:            # a bug: say where, without a wall of traceback (unless asked)
        if os.environ.get('BEARING_ID_TRACEBACK'):
            traceback.print_exc()
        tb = traceback.extract_tb(exc.__traceback__)
        where = f' at {Path(tb[-1].filename).name}:{tb[-1].lineno} in {tb[-1].name}' if tb else ''
        _say(cmd, f'internal error{where}: {type(exc).__name__}: {exc} -- this is a bug, not your input; please '
                  f'report it with the command line (BEARING_ID_TRACEBACK=1 prints the traceback)')
        return 3


if __name__ == '__main__':  # pragma: no cover
    sys.exit(main())
