"""
The history store: every identification of every machine, in SQLite (default) or PostgreSQL, through SQLAlchemy Core.

``HistoryStore('sqlite:////var/lib/bearing_id/fleet.db')`` or ``HistoryStore('postgresql+psycopg://u@host/db')``:
the same tables (:mod:`.schema`), the same code.  :meth:`HistoryStore.write` stores an :class:`IdentificationRecord`
once (its content key is unique per machine: a second write of the same result is a no-op, insert-or-ignore);
:meth:`HistoryStore.query` returns the rows of one machine as numpy arrays; :meth:`HistoryStore.machines` lists
the machines.

SQLite: each connection sets WAL journal mode (readers never block the writer nor it them), a busy timeout (a writer
waits for another's transaction instead of failing) and foreign keys; write transactions begin IMMEDIATE (the write
lock is taken at BEGIN, so two writers queue instead of deadlocking on a lock upgrade).  The file must be on a local
filesystem (WAL needs shared memory): every writer of one file runs on one host.  For a fleet on several hosts, use
PostgreSQL.

**One writer per machine.**  The first write for a machine takes its lease, a row of ``writers`` (machine id, a
random token, host, pid, heartbeat [s, UNIX]); every write renews the heartbeat, :meth:`HistoryStore.heartbeat`
renews it between writes, :meth:`HistoryStore.close` gives it back.  Another store (another process, or another
object in this one) that writes the same machine is refused with :class:`WriterConflict`, naming the holder, while
the lease is live.  A lease is stale, and is taken over, when its heartbeat is older than ``lease_timeout`` or when
its holder ran on this host and its process is gone (a killed node's successor need not wait).  The lease is a row
in the database itself, so it works the same on SQLite and PostgreSQL and for writers on different hosts (a lock
file would not reach PostgreSQL, an advisory lock would not exist on SQLite); the check and the take-over happen in
one transaction (SQLite: the IMMEDIATE write lock; PostgreSQL: SELECT ... FOR UPDATE, the primary key for two
first-timers).  A writer whose lease was taken over (it stalled for longer than ``lease_timeout``) is refused at its
next write: two writers never interleave rows of one machine unknowingly.  Heartbeats are wall-clock times: hosts
that share a PostgreSQL history need clocks synchronised (NTP) well within ``lease_timeout``.
"""
from __future__ import annotations

from dataclasses import dataclass
import json
import math
import os
from pathlib import Path
import socket
import sqlite3
import time
import uuid

import numpy as np
import sqlalchemy as sa
from sqlalchemy.dialects import postgresql, sqlite

from . import schema
from .records import Coefficient, IdentificationRecord, Parameter
from .schema import coefficients, identifications, machines, parameters, SchemaVersionError, writers

LEASE_TIMEOUT = 300.0       # s without a heartbeat after which a machine's writer lease may be taken over
BUSY_TIMEOUT = 30.0         # s a SQLite connection waits for another's write transaction
PG_SCHEMA_LOCK = 0x62656172  # the PostgreSQL advisory-lock key held while the schema is created or migrated

QUERY_COLUMNS = ('identification', 't_start', 't_end', 'speed', 'method', 'misfit', 'kind', 'bearing', 'name',
                 'value', 'sigma', 'determined')


class WriterConflict(RuntimeError):
    """Another live writer holds the machine's lease (or took it over from this one)."""


@dataclass(frozen=True)
class Machine:
    """A machine of the history: id, rig name and when it was first written [s, UNIX]."""

    machine_id: str
    rig_name: str
    created: float


@dataclass(frozen=True)
class WriteResult:
    """Outcome of :meth:`HistoryStore.write`: the identification's row id and whether this call inserted it."""

    identification: int
    inserted: bool


def sqlite_url(path) -> str:
    """Return the SQLAlchemy URL of the SQLite file ``path`` (made absolute)."""
    return 'sqlite:///' + str(Path(path).expanduser().resolve())


def redacted_url(url: str) -> str:
    """Return the database URL ``url`` without its password (for logs and /diagnostics)."""
    try:
        return sa.make_url(url).render_as_string(hide_password=True)
    except Exception:      # not a URL SQLAlchemy reads: say so rather than echo it
        return '(unparsable URL)'


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return False
    except PermissionError:          # exists, another user's
        return True
    return True


def _db(x) -> float | None:
    """Return None for NaN (NULL: SQLite has no NaN), other floats as they are."""
    x = float(x)
    return None if math.isnan(x) else x


def _nan(x) -> float:
    return float('nan') if x is None else float(x)


class HistoryStore:
    """
    The history database at ``url`` (a SQLAlchemy URL; :func:`sqlite_url` for a file), created or migrated on open.

    ``lease_timeout`` [s]: a writer lease without heartbeat for longer is stale; ``busy_timeout`` [s]: SQLite's wait
    for another writer.  Raises :class:`~.schema.SchemaVersionError` for a database of a newer schema version.
    Use as a context manager, or call :meth:`close` (which releases this store's leases).
    """

    def __init__(self, url: str, *, lease_timeout: float = LEASE_TIMEOUT, busy_timeout: float = BUSY_TIMEOUT):
        self.url = str(url)
        self.lease_timeout = float(lease_timeout)
        self.token = uuid.uuid4().hex
        self.host = socket.gethostname()
        self._leases: set[str] = set()
        self.engine = _engine(self.url, float(busy_timeout))
        self.dialect = self.engine.dialect.name
        if self.dialect not in ('sqlite', 'postgresql'):
            self.engine.dispose()
            raise ValueError(f'history database must be SQLite or PostgreSQL, got {self.dialect!r} ({self.url})')
        try:
            with self.engine.begin() as conn:
                if self.dialect == 'postgresql':
                    conn.execute(sa.select(sa.func.pg_advisory_xact_lock(PG_SCHEMA_LOCK)))
                self.migrated_from = schema.migrate(conn, self.url)
        except Exception:
            self.engine.dispose()
            raise

    # ----------------------------------------------------------------------------------------------- lifecycle
    def __enter__(self) -> HistoryStore:
        """Return the store."""
        return self

    def __exit__(self, *exc) -> None:
        """Close the store (release the leases)."""
        self.close()

    def close(self) -> None:
        """Release this store's writer leases and close its connections."""
        if self._leases:
            with self.engine.begin() as conn:
                conn.execute(writers.delete().where(writers.c.token == self.token))
            self._leases.clear()
        self.engine.dispose()

    # ---------------------------------------------------------------------------------------------------- write
    def acquire(self, machine: str, rig_name: str = '') -> None:
        """Take (or renew) the writer lease of ``machine``; raises :class:`WriterConflict` if another holds it."""
        with self.engine.begin() as conn:
            self._ensure_machine(conn, machine, rig_name)
            self._lease(conn, machine)

    def heartbeat(self) -> None:
        """Renew the heartbeat of every lease this store holds (call it more often than ``lease_timeout``)."""
        with self.engine.begin() as conn:
            for machine in sorted(self._leases):
                self._lease(conn, machine)

    def write(self, record: IdentificationRecord) -> WriteResult:
        """
        Store ``record`` (one transaction: the identification, its coefficients and parameters, or nothing).

        Takes or renews the machine's lease first; a record already stored (same content key) is not written again
        (``inserted`` False, the existing row's id).
        """
        return self.write_many([record])[0]

    def write_many(self, records: list[IdentificationRecord]) -> list[WriteResult]:
        """Store ``records`` as :meth:`write` does each, all in one transaction (one commit: all of them or none)."""
        now = time.time()
        out = []
        with self.engine.begin() as conn:
            for machine in dict.fromkeys(r.machine for r in records):
                rig_name = next(r.rig_name for r in records if r.machine == machine)
                self._ensure_machine(conn, machine, rig_name)
                self._lease(conn, machine)
            for record in records:
                out.append(self._write_one(conn, record, now))
        return out

    def _write_one(self, conn: sa.Connection, record: IdentificationRecord, now: float) -> WriteResult:
        key = record.key()
        ins = self._insert(identifications).values(
            machine_id=record.machine, result_key=key, t_start=float(record.t_start), t_end=float(record.t_end),
            speed=float(record.speed), method=str(record.method), misfit=bool(record.misfit), written=now,
            provenance=json.dumps(record.provenance, sort_keys=True))
        ident = conn.execute(ins.on_conflict_do_nothing(index_elements=['machine_id', 'result_key'])
                             .returning(identifications.c.id)).scalar()
        inserted = ident is not None
        if not inserted:
            ident = conn.execute(sa.select(identifications.c.id).where(
                identifications.c.machine_id == record.machine, identifications.c.result_key == key)).scalar_one()
        if inserted and record.coefficients:
            conn.execute(coefficients.insert(), [
                {'identification_id': ident, 'bearing': c.bearing, 'name': c.name, 'value': _db(c.value),
                 'sigma': _db(c.sigma), 'determined': bool(c.determined)} for c in record.coefficients])
        if inserted and record.parameters:
            conn.execute(parameters.insert(), [
                {'identification_id': ident, 'bearing': p.bearing, 'name': p.name, 'value': _db(p.value),
                 'sigma': _db(p.sigma)} for p in record.parameters])
        return WriteResult(int(ident), inserted)

    def _insert(self, table: sa.Table):
        return (postgresql.insert(table) if self.dialect == 'postgresql' else sqlite.insert(table))

    def _ensure_machine(self, conn: sa.Connection, machine: str, rig_name: str) -> None:
        conn.execute(self._insert(machines).values(machine_id=str(machine), rig_name=str(rig_name or ''),
                                                   created=time.time()).on_conflict_do_nothing())

    def _lease(self, conn: sa.Connection, machine: str) -> None:
        """Take or renew ``machine``'s lease inside ``conn``'s transaction, or raise WriterConflict."""
        now = time.time()
        row = conn.execute(sa.select(writers).where(writers.c.machine_id == machine).with_for_update()).first()
        mine = {'token': self.token, 'host': self.host, 'pid': os.getpid(), 'heartbeat': now}
        if row is not None and row.token == self.token:
            conn.execute(writers.update().where(writers.c.machine_id == machine).values(heartbeat=now))
            return
        if machine in self._leases:
            self._leases.discard(machine)
            raise WriterConflict(f'the writer lease of machine {machine!r} was taken over by '
                                 f'{_holder(row)} after this writer was silent for longer than '
                                 f'{self.lease_timeout:g} s: stop writing it')
        if row is None:
            conn.execute(writers.insert().values(machine_id=machine, acquired=now, **mine))
        elif now - row.heartbeat > self.lease_timeout or (row.host == self.host and not _pid_alive(row.pid)):
            conn.execute(writers.update().where(writers.c.machine_id == machine, writers.c.token == row.token)
                         .values(acquired=now, **mine))
        else:
            raise WriterConflict(f'machine {machine!r} already has a writer in {self.url}: {_holder(row)}, last '
                                 f'heartbeat {now - row.heartbeat:.1f} s ago (its lease is taken over after '
                                 f'{self.lease_timeout:g} s without one, or at once when that process is gone); '
                                 f'one writer per machine')
        self._leases.add(machine)

    # ----------------------------------------------------------------------------------------------------- read
    def machines(self) -> list[Machine]:
        """Return the machines in the history, by id."""
        with self._read() as conn:
            rows = conn.execute(sa.select(machines).order_by(machines.c.machine_id)).all()
        return [Machine(r.machine_id, r.rig_name, float(r.created)) for r in rows]

    def query(self, machine: str, bearing: str | None = None, parameter: str | None = None,
              since: float | None = None, after_id: int | None = None) -> dict[str, np.ndarray]:
        """
        Return the coefficient and parameter rows of ``machine`` as columns (QUERY_COLUMNS -> arrays (n,)).

        Optional filters: ``bearing``; ``parameter`` (a parameter or coefficient name, e.g. 'clearance', 'Kxx');
        ``since`` [s, UNIX]: identifications whose data end at or after it; ``after_id``: identifications written
        after the one with this id (``identification`` column; ids grow with every write).  Ordered by t_end,
        identification, kind ('coefficient' before 'parameter'), bearing, name.  value and sigma are float (NaN where
        not stored), determined bool (True for parameters), t_* and speed float, the rest str (identification int).
        """
        i = identifications
        parts = []
        for kind, table, det in (('coefficient', coefficients, coefficients.c.determined),
                                 ('parameter', parameters, sa.true())):
            sel = (sa.select(i.c.id.label('identification'), i.c.t_start, i.c.t_end, i.c.speed, i.c.method,
                             i.c.misfit, sa.literal(kind).label('kind'), table.c.bearing, table.c.name,
                             table.c.value, table.c.sigma, det.label('determined'))
                   .join_from(i, table, table.c.identification_id == i.c.id).where(i.c.machine_id == machine))
            if bearing is not None:
                sel = sel.where(table.c.bearing == bearing)
            if parameter is not None:
                sel = sel.where(table.c.name == parameter)
            if since is not None:
                sel = sel.where(i.c.t_end >= float(since))
            if after_id is not None:
                sel = sel.where(i.c.id > int(after_id))
            parts.append(sel)
        u = sa.union_all(*parts).subquery()
        stmt = sa.select(u).order_by(u.c.t_end, u.c.identification, u.c.kind, u.c.bearing, u.c.name)
        with self._read() as conn:
            rows = conn.execute(stmt).all()
        cols = list(zip(*rows)) if rows else [()] * len(QUERY_COLUMNS)
        out = {}
        for name, col in zip(QUERY_COLUMNS, cols):
            if name in ('value', 'sigma'):
                out[name] = np.array([_nan(v) for v in col], dtype=float)
            elif name in ('t_start', 't_end', 'speed'):
                out[name] = np.array(col, dtype=float)
            elif name in ('misfit', 'determined'):
                out[name] = np.array([bool(v) for v in col], dtype=bool)
            elif name == 'identification':
                out[name] = np.array(col, dtype=np.int64)
            else:
                out[name] = np.array(col, dtype=str)
        return out

    def records(self, machine: str, since: float | None = None) -> list[IdentificationRecord]:
        """Return the identifications of ``machine`` (by t_end, then row id) from ``since`` [s, UNIX] on, rebuilt."""
        i = identifications
        sel = sa.select(i, machines.c.rig_name).join_from(i, machines).where(i.c.machine_id == machine)
        if since is not None:
            sel = sel.where(i.c.t_end >= float(since))
        with self._read() as conn:
            rows = conn.execute(sel.order_by(i.c.t_end, i.c.id)).all()
            ids = [r.id for r in rows]
            coef = conn.execute(sa.select(coefficients).where(coefficients.c.identification_id.in_(ids))
                                .order_by(coefficients.c.bearing, coefficients.c.name)).all() if ids else []
            par = conn.execute(sa.select(parameters).where(parameters.c.identification_id.in_(ids))
                               .order_by(parameters.c.bearing, parameters.c.name)).all() if ids else []
        by_c: dict[int, list] = {}
        by_p: dict[int, list] = {}
        for c in coef:
            by_c.setdefault(c.identification_id, []).append(
                Coefficient(c.bearing, c.name, _nan(c.value), _nan(c.sigma), bool(c.determined)))
        for p in par:
            by_p.setdefault(p.identification_id, []).append(Parameter(p.bearing, p.name, _nan(p.value),
                                                                      _nan(p.sigma)))
        return [IdentificationRecord(machine=r.machine_id, t_start=float(r.t_start), t_end=float(r.t_end),
                                     speed=float(r.speed), method=r.method, misfit=bool(r.misfit),
                                     provenance=json.loads(r.provenance), rig_name=r.rig_name,
                                     coefficients=tuple(by_c.get(r.id, ())), parameters=tuple(by_p.get(r.id, ())))
                for r in rows]

    def _read(self):
        """Return a connection whose transactions start deferred (SQLite: a reader takes no write lock)."""
        return self.engine.connect().execution_options(history_read=True)


def _holder(row) -> str:
    return 'nobody' if row is None else f'process {row.pid} on host {row.host!r}'


def _wal(cur, busy_timeout: float) -> None:
    """
    Put the database into WAL journal mode (persistent in the file), waiting up to ``busy_timeout`` [s].

    Switching needs the file to itself and SQLite answers "database is locked" at once instead of calling the busy
    handler (seen when two processes open a new file together), so the switch is retried until the mode is WAL.
    """
    deadline = time.monotonic() + busy_timeout
    while True:
        try:
            mode = cur.execute('PRAGMA journal_mode').fetchone()[0]
            if str(mode).lower() in ('wal', 'memory'):
                return
            cur.execute('PRAGMA journal_mode=WAL')
        except sqlite3.OperationalError as e:
            if 'locked' not in str(e) or time.monotonic() > deadline:
                raise
            time.sleep(0.01)


def _engine(url: str, busy_timeout: float) -> sa.Engine:
    """Return the engine for ``url``: SQLite with WAL, busy timeout, foreign keys and IMMEDIATE write transactions."""
    u = sa.make_url(url)
    if u.get_backend_name() != 'sqlite':
        return sa.create_engine(u, pool_pre_ping=True)
    if u.database and u.database != ':memory:':
        Path(u.database).parent.mkdir(parents=True, exist_ok=True)
    engine = sa.create_engine(u, connect_args={'timeout': busy_timeout})

    @sa.event.listens_for(engine, 'connect')
    def _on_connect(dbapi_conn, _record):
        dbapi_conn.isolation_level = None          # pysqlite issues no BEGIN of its own: _on_begin does
        cur = dbapi_conn.cursor()
        cur.execute(f'PRAGMA busy_timeout={int(busy_timeout * 1000)}')
        _wal(cur, busy_timeout)
        cur.execute('PRAGMA foreign_keys=ON')
        cur.close()

    @sa.event.listens_for(engine, 'begin')
    def _on_begin(conn):
        conn.exec_driver_sql('BEGIN' if conn.get_execution_options().get('history_read') else 'BEGIN IMMEDIATE')

    return engine


__all__ = ['HistoryStore', 'IdentificationRecord', 'Coefficient', 'Parameter', 'Machine', 'WriteResult',
           'WriterConflict', 'SchemaVersionError', 'sqlite_url', 'redacted_url', 'LEASE_TIMEOUT', 'QUERY_COLUMNS']
