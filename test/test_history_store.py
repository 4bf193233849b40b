"""
The history store (bearing_id/history) on SQLite, and on PostgreSQL when a server is named.

Round trip, idempotent writes, concurrent writers, one writer per machine, schema migration and a newer schema
refused -- on SQLite always, and on PostgreSQL when BEARING_ID_TEST_PG_URL names a server (a SQLAlchemy URL of a
superuser's database, e.g. what ``scripts/pg_test_server.sh start`` prints; each test creates and drops a database
of its own there).
"""
from __future__ import annotations

import contextlib
import math
import multiprocessing
import os
import time
import uuid

from bearing_id.history import (coefficients_from_arrays, HistoryStore, IdentificationRecord, Parameter,
                                SCHEMA_VERSION, SchemaVersionError, sqlite_url, WriterConflict)
import numpy as np
import pytest
import sqlalchemy as sa

PG_URL = os.environ.get('BEARING_ID_TEST_PG_URL', '')
# on CI (.ci/run starts a server) the PostgreSQL cases run or fail; elsewhere they are skipped without a server
_PG_SKIP = pytest.mark.skipif(not PG_URL and not os.environ.get('CI'),
                              reason='no PostgreSQL server: set BEARING_ID_TEST_PG_URL (scripts/pg_test_server.sh '
                                     'start prints one) to run the history tests on PostgreSQL too')
BACKENDS = ['sqlite', pytest.param('postgresql', marks=_PG_SKIP)]
T0 = 1.7e9          # s, UNIX


@pytest.fixture(params=BACKENDS)
def url(request, tmp_path):
    """Return the URL of an empty history database: a SQLite file in tmp_path, or a new PostgreSQL database."""
    if request.param == 'sqlite':
        yield sqlite_url(tmp_path / 'fleet.db')
        return
    with pg_database() as u:
        yield u


@contextlib.contextmanager
def pg_database():
    """Yield the URL of a new, empty PostgreSQL database on the test server; drop it afterwards."""
    assert PG_URL, 'CI is set but BEARING_ID_TEST_PG_URL is not: .ci/run should have started PostgreSQL'
    base = sa.make_url(PG_URL)
    name = 'bearing_id_test_' + uuid.uuid4().hex[:12]
    admin = sa.create_engine(base, isolation_level='AUTOCOMMIT')
    with admin.connect() as c:
        c.execute(sa.text(f'CREATE DATABASE {name}'))
    try:
        yield base.set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect() as c:
            c.execute(sa.text(f'DROP DATABASE IF EXISTS {name} WITH (FORCE)'))
        admin.dispose()


def _record(machine: str, i: int, *, clearance: float = 100e-6) -> IdentificationRecord:
    """Identification i of ``machine``: two bearings, an undetermined (NaN) coefficient, parameters, provenance."""
    K = np.array([[1.0e6, 2.0e5], [-1.5e5, 8.0e5]]) * (1 + 0.01 * i)
    C = np.array([[3.0e3, 1.0e2], [1.0e2, 2.5e3]])
    coef = (coefficients_from_arrays('bearing1', K, C, 0.01 * K, 0.02 * C, np.ones((2, 2), bool))
            + coefficients_from_arrays('bearing2', K, np.full((2, 2), np.nan), 0.01 * K, np.full((2, 2), np.nan),
                                       np.array([np.ones((2, 2), bool), np.zeros((2, 2), bool)])))
    par = (Parameter('bearing1', 'clearance', clearance * (1 + 1e-3 * i), 1e-6),
           Parameter('bearing1', 'viscosity', 0.018, 4e-4), Parameter('bearing2', 'clearance', 120e-6, float('nan')))
    return IdentificationRecord(machine=machine, t_start=T0 + 600.0 * i, t_end=T0 + 600.0 * i + 20.0,
                                speed=2 * math.pi * (10 + i), method='physical', coefficients=coef, parameters=par,
                                misfit=(i % 5 == 4), provenance={'recordings': [f'run_{i}.npz'], 'node': machine},
                                rig_name='test rig')


def _same(a: IdentificationRecord, b: IdentificationRecord) -> bool:
    """Return whether the records are equal field by field (NaN = NaN), coefficients and parameters in any order."""
    def num(x, y):
        return (math.isnan(x) and math.isnan(y)) or x == y
    ca = sorted(a.coefficients, key=lambda c: (c.bearing, c.name))
    cb = sorted(b.coefficients, key=lambda c: (c.bearing, c.name))
    pa = sorted(a.parameters, key=lambda p: (p.bearing, p.name))
    pb = sorted(b.parameters, key=lambda p: (p.bearing, p.name))
    return ((a.machine, a.t_start, a.t_end, a.speed, a.method, a.misfit, a.provenance, a.rig_name)
            == (b.machine, b.t_start, b.t_end, b.speed, b.method, b.misfit, b.provenance, b.rig_name)
            and len(ca) == len(cb) and len(pa) == len(pb)
            and all((x.bearing, x.name, x.determined) == (y.bearing, y.name, y.determined)
                    and num(x.value, y.value) and num(x.sigma, y.sigma) for x, y in zip(ca, cb))
            and all((x.bearing, x.name) == (y.bearing, y.name) and num(x.value, y.value) and num(x.sigma, y.sigma)
                    for x, y in zip(pa, pb)))


def _count(url: str, table: str) -> int:
    eng = sa.create_engine(url)
    try:
        with eng.connect() as c:
            return int(c.execute(sa.text(f'SELECT COUNT(*) FROM {table}')).scalar_one())
    finally:
        eng.dispose()


def test_round_trip(url):
    written = [_record('plant/c101', i) for i in range(4)] + [_record('plant/c102', 0, clearance=90e-6)]
    with HistoryStore(url) as store:
        assert store.migrated_from == 0
        for r in written:
            assert store.write(r).inserted
        assert [m.machine_id for m in store.machines()] == ['plant/c101', 'plant/c102']
        assert {m.rig_name for m in store.machines()} == {'test rig'}
        back = store.records('plant/c101')
        assert len(back) == 4 and all(_same(a, b) for a, b in zip(written[:4], back))
        assert all(a.key() == b.key() for a, b in zip(written[:4], back))
        q = store.query('plant/c101', bearing='bearing1', parameter='clearance')
        assert list(q['value']) == [100e-6 * (1 + 1e-3 * i) for i in range(4)]
        assert set(q['kind']) == {'parameter'} and np.all(q['determined']) and np.all(q['sigma'] == 1e-6)
        assert list(q['t_start']) == [T0 + 600.0 * i for i in range(4)] and q['misfit'].tolist() == [False] * 4
        q = store.query('plant/c101', bearing='bearing2', since=T0 + 1200.0)     # identifications 2 and 3
        assert q['identification'].size == 2 * (8 + 1)
        cxx = q['name'] == 'Cxx'
        assert np.all(np.isnan(q['value'][cxx])) and not np.any(q['determined'][cxx])
        assert np.all(np.isnan(q['sigma'][(q['kind'] == 'parameter')]))
        assert store.query('plant/c101', parameter='Kxx')['value'].tolist() == [1.0e6 * (1 + 0.01 * i)
                                                                                for i in range(4) for _ in (1, 2)]
        empty = store.query('nobody')
        assert all(v.size == 0 for v in empty.values())
        assert store.records('plant/c102')[0].parameters[0].value == 90e-6


def test_the_same_result_twice_is_one_row(url):
    r = _record('m1', 0)
    with HistoryStore(url) as store:
        first = store.write(r)
        again = store.write(_record('m1', 0))         # an equal record built anew
        assert first.inserted and not again.inserted and first.identification == again.identification
        changed = store.write(IdentificationRecord(**{**r.__dict__, 'misfit': True}))
        assert changed.inserted and changed.identification != first.identification
    assert _count(url, 'identifications') == 2
    assert _count(url, 'coefficients') == 2 * 16 and _count(url, 'parameters') == 2 * 3


def test_many_records_are_one_transaction_all_or_none(url):
    with HistoryStore(url) as first, HistoryStore(url) as second:
        first.write(_record('m1', 0))                                  # m1's writer is `first`
        with pytest.raises(WriterConflict):                            # m2 is free, m1 is not: nothing is written
            second.write_many([_record('m2', 0), _record('m1', 1), _record('m2', 1)])
        assert _count(url, 'identifications') == 1
        done = first.write_many([_record('m1', 1), _record('m1', 0), _record('m1', 2)])
        assert [w.inserted for w in done] == [True, False, True]
        assert done[1].identification == first.write(_record('m1', 0)).identification
    assert _count(url, 'identifications') == 3 and _count(url, 'coefficients') == 3 * 16


def _write_machine(url: str, machine: str, n: int, barrier, queue) -> None:
    """Child process: open the (new) database when both children are ready, write n records of ``machine``."""
    try:
        barrier.wait(timeout=60)
        with HistoryStore(url) as store:
            for i in range(n):
                store.write(_record(machine, i))
        queue.put(('ok', machine))
    except Exception as e:            # reported to the parent, which fails the test with it
        queue.put(('error', f'{machine}: {e!r}'))


def test_two_processes_writing_two_machines_lose_nothing(url):
    ctx = multiprocessing.get_context('spawn')
    barrier, queue = ctx.Barrier(2), ctx.Queue()
    n = 40
    procs = [ctx.Process(target=_write_machine, args=(url, m, n, barrier, queue)) for m in ('m1', 'm2')]
    for p in procs:
        p.start()
    results = [queue.get(timeout=180) for _ in procs]
    for p in procs:
        p.join(timeout=60)
    assert all(r[0] == 'ok' for r in results), results
    with HistoryStore(url) as store:
        for m in ('m1', 'm2'):
            back = store.records(m)
            assert len(back) == n and sorted(b.key() for b in back) == sorted(_record(m, i).key() for i in range(n))
    assert _count(url, 'coefficients') == 2 * n * 16


def _try_write(url: str, machine: str, queue, hold: bool = False) -> None:
    """Child process: write one record of ``machine``; report the outcome; with ``hold``, exit without closing."""
    try:
        store = HistoryStore(url)
        store.write(_record(machine, 0))
        queue.put(('ok', ''))
        if not hold:                  # held: the process ends without close(), as a killed node would
            store.close()
    except WriterConflict as e:
        queue.put(('refused', str(e)))
    except Exception as e:
        queue.put(('error', repr(e)))


def _in_child(url: str, machine: str, hold: bool = False) -> tuple[str, str]:
    ctx = multiprocessing.get_context('spawn')
    queue = ctx.Queue()
    p = ctx.Process(target=_try_write, args=(url, machine, queue, hold))
    p.start()
    out = queue.get(timeout=120)
    p.join(timeout=60)
    return out


def test_one_writer_per_machine(url):
    with HistoryStore(url) as first:
        first.write(_record('m1', 0))
        status, message = _in_child(url, 'm1')                        # another process, same machine
        assert status == 'refused', message
        assert "machine 'm1' already has a writer" in message and f'process {os.getpid()}' in message
        assert _in_child(url, 'm2')[0] == 'ok'                        # another machine is fine
        with HistoryStore(url) as second:                              # another store in this process
            with pytest.raises(WriterConflict, match='one writer per machine'):
                second.write(_record('m1', 1))
        first.write(_record('m1', 1))                                  # the holder goes on
    assert _in_child(url, 'm1')[0] == 'ok'                             # released by close()


def test_a_dead_or_silent_writer_is_taken_over(url):
    HistoryStore(url).close()
    assert _in_child(url, 'm1', hold=True)[0] == 'ok'                  # it exits holding the lease
    with HistoryStore(url) as store:                                   # its process is gone: taken over at once
        store.write(_record('m1', 1))
    silent = HistoryStore(url, lease_timeout=0.2)
    silent.write(_record('m3', 0))
    time.sleep(0.3)
    with HistoryStore(url, lease_timeout=0.2) as successor:
        successor.write(_record('m3', 1))                              # the lease was stale
        with pytest.raises(WriterConflict, match='taken over'):
            silent.write(_record('m3', 2))                             # the silent one learns it lost the lease
    silent.close()


V1_DDL = [   # the version-1 layout as an older bearing_id created it ({serial}: the dialect's auto-increment key)
    'CREATE TABLE schema_version (version INTEGER NOT NULL)',
    "CREATE TABLE machines (machine_id VARCHAR(200) PRIMARY KEY, rig_name VARCHAR(200) NOT NULL DEFAULT '', "
    'created DOUBLE PRECISION NOT NULL)',
    'CREATE TABLE identifications (id {serial}, machine_id VARCHAR(200) NOT NULL REFERENCES machines (machine_id), '
    'result_key VARCHAR(64) NOT NULL, t_start DOUBLE PRECISION NOT NULL, t_end DOUBLE PRECISION NOT NULL, '
    'speed DOUBLE PRECISION NOT NULL, method VARCHAR(40) NOT NULL, misfit BOOLEAN NOT NULL, '
    'written DOUBLE PRECISION NOT NULL, '
    'CONSTRAINT uq_identifications_machine_key UNIQUE (machine_id, result_key))',
    'CREATE INDEX ix_identifications_machine_time ON identifications (machine_id, t_end)',
    'CREATE TABLE coefficients (identification_id INTEGER NOT NULL REFERENCES identifications (id), '
    'bearing VARCHAR(200) NOT NULL, name VARCHAR(8) NOT NULL, value DOUBLE PRECISION, sigma DOUBLE PRECISION, '
    'determined BOOLEAN NOT NULL, PRIMARY KEY (identification_id, bearing, name))',
    'INSERT INTO schema_version (version) VALUES (1)',
    "INSERT INTO machines VALUES ('old', 'old rig', 1600000000.0)",
    'INSERT INTO identifications (machine_id, result_key, t_start, t_end, speed, method, misfit, written) '
    "VALUES ('old', 'k1', 1600000000.0, 1600000020.0, 314.0, 'direct', FALSE, 1600000030.0)",
    "INSERT INTO coefficients VALUES (1, 'bearing1', 'Kxx', 1000000.0, 5000.0, TRUE)",
]
SERIAL = {'sqlite': 'INTEGER PRIMARY KEY AUTOINCREMENT', 'postgresql': 'SERIAL PRIMARY KEY'}


def _layout(url: str) -> dict:
    eng = sa.create_engine(url)
    try:
        insp = sa.inspect(eng)
        return {t: sorted(c['name'] for c in insp.get_columns(t)) for t in sorted(insp.get_table_names())}
    finally:
        eng.dispose()


def test_migration_from_version_1(url, tmp_path):
    eng = sa.create_engine(url)
    with eng.begin() as c:
        for stmt in V1_DDL:
            c.execute(sa.text(stmt.format(serial=SERIAL[eng.dialect.name])))
    eng.dispose()
    with HistoryStore(url) as store:
        assert store.migrated_from == 1
        old = store.records('old')
        assert len(old) == 1 and old[0].provenance == {} and old[0].rig_name == 'old rig'
        assert old[0].coefficients[0].value == 1e6 and old[0].parameters == ()
        assert store.write(_record('old', 1)).inserted                  # the new tables take rows
        assert len(store.records('old')) == 2
    with HistoryStore(url) as again:
        assert again.migrated_from == SCHEMA_VERSION                    # nothing left to do
    fresh = sqlite_url(tmp_path / 'fresh.db') if url.startswith('sqlite') else None
    if fresh:
        HistoryStore(fresh).close()
        assert _layout(url) == _layout(fresh)                           # migrated = created new
    assert 'parameters' in _layout(url) and 'provenance' in _layout(url)['identifications']


def test_a_newer_schema_is_refused(url):
    with HistoryStore(url) as store:
        store.write(_record('m1', 0))
    eng = sa.create_engine(url)
    with eng.begin() as c:
        c.execute(sa.text('UPDATE schema_version SET version = :v'), {'v': SCHEMA_VERSION + 1})
    with pytest.raises(SchemaVersionError, match=f'schema version {SCHEMA_VERSION + 1}, newer than this bearing_id '
                                                 f'understands \\({SCHEMA_VERSION}\\)'):
        HistoryStore(url)
    with eng.connect() as c:
        assert c.execute(sa.text('SELECT version FROM schema_version')).scalar_one() == SCHEMA_VERSION + 1
    eng.dispose()


@_PG_SKIP
def test_a_fleet_on_postgresql_and_on_sqlite_holds_the_same_content(tmp_path):
    # three machines (namespaced ids) written alike to both databases, in another order on each: the same records
    machines = ['/plant/c101', '/plant/c102', '/plant/p201']
    recs = [_record(m, i, clearance=(100 + j) * 1e-6) for j, m in enumerate(machines) for i in range(6)]
    with pg_database() as pg_url, HistoryStore(pg_url) as pg, HistoryStore(sqlite_url(tmp_path / 'fleet.db')) as lite:
        for r in recs:
            pg.write(r)
        for r in reversed(recs):
            lite.write(r)
        assert [m.machine_id for m in pg.machines()] == [m.machine_id for m in lite.machines()] == sorted(machines)
        for m in machines:
            a, b = pg.records(m), lite.records(m)
            assert [r.key() for r in a] == [r.key() for r in b] == [r.key() for r in sorted(
                (r for r in recs if r.machine == m), key=lambda r: r.t_end)]
