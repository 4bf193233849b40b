"""
Issue 10: hostile input never kills a node, never yields a number, and leaves no state behind.

kf_estimator and identifier (separate processes, loopback DDS, own domain id, kill timeouts) receive 600 randomly
corrupted messages of every input type (test/fuzz_publisher.py: NaN/inf, lengths that disagree, out-of-range rates
and nodes, unknown enums, micrometres as metres, broken keyphasor angles, far sequence numbers...).  Then:
both nodes are alive, nothing was accumulated or published, and the recorded unbalance bag played afterwards is
identified exactly as `bearing-id identify` identifies it offline (so no corrupted message left a trace: a poisoned
sequence counter, a bogus run, a stuck window).
"""
from __future__ import annotations

import json
import time

import agreement
from bearing_id.io.record import Record
import pytest
import rosutil
from test_bags_replay import _node, BAGS, offline, wait_for_results

pytestmark = [pytest.mark.ros,
              pytest.mark.slow(reason='600 corrupted messages, then a whole bag through two nodes (~20 s)')]


def test_nodes_survive_corrupted_messages_then_identify_a_valid_bag_exactly(tmp_path):
    env = rosutil.ros_env()
    record_dir = tmp_path / 'record'
    speeds = [600.0, 900.0, 1200.0, 1500.0, 1800.0, 2100.0, 2400.0, 2700.0, 3000.0]
    procs = [_node('kf_estimator', {'prebuild_speeds_rpm': speeds}, env, timeout=240),
             _node('identifier', {'method': 'physical', 'record_dir': str(record_dir), 'runs': ['A', 'B']}, env,
                   timeout=240)]
    try:
        fz = rosutil.run([rosutil.require_ros(), str(rosutil.REPO / 'test' / 'fuzz_publisher.py'), '7', '600'],
                         timeout=150, env=env)
        assert fz.returncode == 0, fz.stdout + fz.stderr
        sent = json.loads(fz.stdout.strip().splitlines()[-1])
        assert sum(sent.values()) == 600 and min(sent.values()) > 20, sent
        time.sleep(1.0)
        for p in procs:
            assert p.alive(), p.output()
        rec = Record(record_dir, fsync=False)
        kinds = {e['type'] for e in rec.entries()}
        assert kinds <= {'machine', 'session'}, kinds       # nothing accumulated, no run, no result
        play = rosutil.run([rosutil.script('bearing-id'), 'play', str(BAGS / 'unbalance_ab_sweep'), '--rate', '4',
                            '--wait-for', '2', '--timeout', '60'], timeout=150, env=env)
        assert play.returncode == 0, play.stdout + play.stderr
        assert wait_for_results(record_dir, len(speeds)), procs[1].output()
        for p in procs:
            assert p.alive(), p.output()
            rc, _ = p.interrupt()
            assert rc == 0, p.output()
            assert 'Traceback' not in p.stderr, p.stderr
    finally:
        for p in procs:
            p.close()
    res = [e['result'] for e in Record(record_dir, fsync=False).entries('result')]
    live = {r['speed_rad_s']: r for r in res}
    ref = offline(BAGS / 'unbalance_ab_sweep', 'physical', tmp_path)
    for r, d in zip(ref, agreement.by_speed(live, [r['speed_rad_s'] for r in ref])):
        for b_live, b_ref in zip(d['bearings'], r['bearings']):
            for sym in ('K', 'C'):
                std = agreement.floats(b_ref[f'{sym}_std'])
                agreement.assert_coefficients_agree(agreement.floats(b_live[sym]), agreement.floats(b_ref[sym]), std,
                                                    r['condition'], f"{sym} of {b_ref['name']}")
                agreement.assert_std_agree(agreement.floats(b_live[f'{sym}_std']), std, f"{sym}_std of {b_ref['name']}")
