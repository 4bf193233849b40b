"""
``bearing-id trend``: the history of each machine's bearings -- every fitted parameter against time, and its changes.

Reads a history database (``--history``: a SQLite file such as the identifier's ``history.db``, or a SQLAlchemy URL
for PostgreSQL), prints per machine and parameter the number of points, the reference (the first ``--reference``
points), the latest value with its 1-sigma, and the CUSUM alarms (onset, size with its 1-sigma, evidence) at the
false-alarm rate ``--arl0`` (average points to a false alarm per series); ``--html`` writes one page with each
parameter against time (1-sigma band, alarm markers) and a fleet overview.  Exit codes: 0 no alarm, 1 an alarm,
2 bad input (no database, a newer schema, a server that does not answer).
"""
from __future__ import annotations

import argparse
from datetime import datetime, timezone
from pathlib import Path

from sqlalchemy.exc import SQLAlchemyError

from .inputs import InputError
from ..config import defaults
from ..history import HistoryStore, SchemaVersionError, sqlite_url
from ..history.trend import changes, parameter_series
from ..plots.common import png_bytes
from ..plots.html import Page
from ..plots.trend import trend_figure


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser('trend', help="the history of each machine's bearing parameters and their changes",
                       description=__doc__.split('\n\n')[1].replace('\n', ' '))
    p.add_argument('history', help="history database: a SQLite file (e.g. the identifier's history.db) or a "
                                   'SQLAlchemy URL (postgresql+psycopg://user@host/db)')
    p.add_argument('--machine', action='append', help='machine id (repeatable; default: every machine)')
    p.add_argument('--arl0', type=float, default=defaults.ALARM_ARL0,
                   help=f'average number of points to a false alarm, per parameter series (default '
                        f'{defaults.ALARM_ARL0:g})')
    p.add_argument('--shift', type=float, default=defaults.ALARM_SHIFT,
                   help=f'the shift to detect fastest, in sigma (default {defaults.ALARM_SHIFT:g})')
    p.add_argument('--reference', type=int, default=defaults.ALARM_REFERENCE,
                   help=f'the first N points of each series are its in-control reference (default '
                        f'{defaults.ALARM_REFERENCE})')
    p.add_argument('--html', help='write the trend page here (one self-contained HTML file)')
    return p


def _utc(t: float) -> str:
    return datetime.fromtimestamp(float(t), timezone.utc).strftime('%Y-%m-%d %H:%M')


def run(args) -> int:
    url = args.history if '://' in args.history else sqlite_url(args.history)
    if '://' not in args.history and not Path(args.history).is_file():
        raise InputError(f'no history database at {args.history}')
    if not (args.arl0 > 1 and args.shift > 0 and args.reference >= 1):
        raise InputError('--arl0 must be > 1, --shift > 0 and --reference >= 1')
    try:
        store = HistoryStore(url)
    except (SchemaVersionError, SQLAlchemyError) as exc:
        raise InputError(f'history database {args.history}: {exc}') from exc
    try:
        machines = args.machine or [m.machine_id for m in store.machines()]
        page = Page('bearing-id trend')
        overview, n_alarms = [], 0
        for m in machines:
            series = parameter_series(store, m)
            found = changes(series, arl0=args.arl0, delta=args.shift, n_reference=args.reference)
            n_alarms += len(found)
            print(f'machine {m}: {len(series)} parameter series')
            for s in series:
                print(f'  {s.bearing} {s.name}: {s.t.size} point(s) {_utc(s.t[0])} .. {_utc(s.t[-1])} UTC, latest '
                      f'{s.value[-1]:.4g} ± {s.sigma[-1]:.2g}')
            for c in found:
                print(f'  ALARM {c.sentence()}')
            overview.append([m, str(len(series)), str(sum(s.t.size for s in series)), str(len(found)),
                             '; '.join(f'{c.bearing} {c.name} {"up" if c.alarm.direction > 0 else "down"} from '
                                       f'{_utc(c.alarm.onset_time)}' for c in found) or 'none'])
            if args.html and series:
                page.section(f'machine {m}')
                page.image(png_bytes(trend_figure(series, found)), f'machine {m}: every fitted parameter against '
                           f'time, 1-sigma band, alarms (CUSUM, ARL0 {args.arl0:g} points, shift {args.shift:g} '
                           f'sigma)', f'trend of {m}')
                if found:
                    page.bullets([c.sentence() for c in found])
        if args.html:
            page.section('fleet', 'fleet')
            page.table(['machine', 'series', 'points', 'alarms', 'changes'], overview, left_cols=5)
            print(f'wrote {page.write(args.html)}')
    finally:
        store.close()
    return 1 if n_alarms else 0
