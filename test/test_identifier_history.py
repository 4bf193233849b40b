"""
The identifier writes every result it records to the history database (issue 25 item 1), and loses none.

The machine of ``test_identifier_tracking`` (two speeds, two unbalance runs, three probe stations, method physical):
each recorded result is one identification in the history, with its data span, the coefficients, their 1-sigma and
determined flags as published, and the fitted viscosity and clearance with their 1-sigma.  A write that fails (the
database down) is an ERROR on /diagnostics while the record keeps the result; the next start writes what the history
lacks, once (a second restart adds nothing).  A second identifier writing the same machine is refused (ERROR), not
crashed.  The change detection runs on the machine's history and queues each alarm once.
"""
from __future__ import annotations

from bearing_id.history import HistoryStore, sqlite_url
from bearing_id.history.trend import changes, parameter_series
from bearing_id.nodes.identifier_core import alarm_items, history_url, IdentifierCore
from bearing_id.nodes.status import ERROR, OK, WARN
import numpy as np
from sqlalchemy.exc import OperationalError
from test_identifier_tracking import feed, passes  # noqa: F401  (the fixture)
from test_trend import write_history


class DownStore:
    """A history database that is down: every write fails as SQLAlchemy reports a lost server."""

    url = 'postgresql+psycopg://user:secret@db.example/history'

    def write_many(self, records):
        raise OperationalError('INSERT ...', {}, Exception('server closed the connection unexpectedly'))


def test_every_recorded_result_is_in_the_history_as_published(passes, tmp_path):  # noqa: F811
    rig, _, first, _ = passes
    with HistoryStore(sqlite_url(tmp_path / 'h.db')) as store:
        core = IdentifierCore(rig, 'physical', tmp_path / 'rec', machine='plant/c101', history=store)
        feed(core, first, 0.0)
        results, _ = core.solve()
        core.close()
        assert core.history_item().level == OK and core.history_rows == len(results)
        recs = store.records('plant/c101')
        assert len(recs) == len(results)
        for r in results:
            (h,) = [x for x in recs if x.speed == r.speed]
            assert (h.t_start, h.t_end) == tuple(r.extra['data_span'])
            assert h.method == r.method and h.misfit == r.misfit
            by = {(c.bearing, c.name): c for c in h.coefficients}
            for i, b in enumerate(r.bearings):
                for sym in 'KC':
                    for a in range(2):
                        for c in range(2):
                            row = by[(b, f"{sym}{'xy'[a]}{'xy'[c]}")]
                            # JSON floats round-trip exactly (repr); NaN stays NaN
                            assert np.array_equal([row.value, row.sigma],
                                                  [getattr(r, sym)[i][a, c], getattr(r, sym + '_std')[i][a, c]],
                                                  equal_nan=True)
                            assert row.determined == bool(getattr(r, sym + '_determined')[i][a, c])
            pars = {(p.bearing + '.' + p.name): p for p in h.parameters}
            assert pars.keys() == r.extra['parameters'].keys()
            for name, p in r.extra['parameters'].items():
                assert pars[name].value == p['value'] and pars[name].sigma == p['std']


def test_a_failed_write_is_an_error_and_the_next_start_writes_it_once(passes, tmp_path):  # noqa: F811
    rig, _, first, _ = passes
    core = IdentifierCore(rig, 'physical', tmp_path / 'rec', machine='m1', history=DownStore())
    feed(core, first, 0.0)
    results, _ = core.solve()
    item = core.history_item()
    core.close()
    assert item.level == ERROR and 'server closed the connection' in item.message, item
    assert 'secret' not in str(item.values), item.values                       # no password on /diagnostics
    for attempt in range(2):
        with HistoryStore(sqlite_url(tmp_path / 'h.db')) as store:
            again = IdentifierCore(rig, 'physical', tmp_path / 'rec', machine='m1', history=store)
            again.close()
            assert again.resumed['history_backfilled'] == (len(results) if attempt == 0 else 0)
            assert sorted(x.speed for x in store.records('m1')) == sorted(r.speed for r in results)


def test_a_second_writer_of_the_machine_is_an_error_not_a_crash(passes, tmp_path):  # noqa: F811
    rig, _, first, _ = passes
    url = sqlite_url(tmp_path / 'fleet.db')
    with HistoryStore(url) as one, HistoryStore(url) as two:
        a = IdentifierCore(rig, 'physical', tmp_path / 'a', machine='m1', history=one)
        b = IdentifierCore(rig, 'physical', tmp_path / 'b', machine='m1', history=two)
        feed(a, first, 0.0)
        feed(b, first, 0.0)
        ra, _ = a.solve()
        rb, _ = b.solve()
        a.close()
        b.close()
        assert a.history_item().level == OK
        item = b.history_item()
        assert item.level == ERROR and 'writer' in item.message, item
        assert len(one.records('m1')) == len(ra)
    assert rb and all(r.speed for r in rb)         # the second identifier still identified (and recorded) its data


def test_the_history_parameter_names_a_database(tmp_path):
    assert history_url('record', tmp_path) == sqlite_url(tmp_path / 'history.db')
    assert history_url(str(tmp_path / 'fleet.db'), tmp_path / 'x') == sqlite_url(tmp_path / 'fleet.db')
    assert history_url('postgresql+psycopg://u@h/db', tmp_path) == 'postgresql+psycopg://u@h/db'


def test_a_change_in_the_history_is_an_alarm_once_with_its_evidence(passes, tmp_path):  # noqa: F811
    """
    The identifier's change detection is bearing-id trend's, on the machine's own history (issue 25 item 3).

    A history with bearing 1's clearance stepped by 8 sigma (test_trend's, written there): at start the identifier
    queues that one alarm for bearing_id/alarms (bearing, parameter, direction, size, onset, evidence as values) and
    /diagnostics names it (WARN); a machine whose history holds only its own fresh solve has none (OK).
    """
    rig, _, first, _ = passes
    db = tmp_path / 'fleet.db'
    write_history(db, 'worn', step=True, seed=1)
    with HistoryStore(sqlite_url(db)) as store:
        core = IdentifierCore(rig, 'physical', tmp_path / 'rec', machine='worn', history=store,
                              alarms={'arl0': 1e5})
        core.close()
        expected = changes(parameter_series(store, 'worn'), arl0=1e5, delta=2.0, n_reference=10)
        (alarm,) = core.new_alarms
        (c,) = expected
        assert (alarm.bearing, alarm.name, alarm.alarm.onset_time) == (c.bearing, c.name, c.alarm.onset_time)
        (item,) = alarm_items(list(core.new_alarms))
        assert item.level == WARN and item.values['bearing'] == 'bearing1' and item.values['parameter'] == 'clearance'
        assert item.values['direction'] == 'up' and abs(float(item.values['onset_stamp']) - c.alarm.onset_time) <= 1e-3
        assert item.values['size'] == c.alarm.size and item.values['threshold_sigma'] == c.alarm.h
        diag = core.alarm_item()
        assert diag.level == WARN and 'bearing1 clearance: up' in diag.message, diag.message

        fresh = IdentifierCore(rig, 'physical', tmp_path / 'rec2', machine='new', history=store)
        feed(fresh, first, 0.0)
        fresh.solve()
        fresh.close()
        assert not fresh.new_alarms and fresh.alarm_item().level == OK, fresh.alarm_item().message
        assert fresh.watch.points == 1 and fresh.watch.series > 0
