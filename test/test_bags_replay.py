"""
Bag-driven end-to-end: the nodes on a replayed bag equal the offline CLI and match the simulator's truth.

bags/ replayed by `bearing-id play` -> kf_estimator + identifier (separate processes, localhost-only DDS, own domain id,
kill timeouts) -> `bearing-id record` of the outputs -> the published coefficients equal the offline `bearing-id
identify` on the same bag (within 0.01 of the stated 1-sigma, test/agreement.py) and match the simulator's truth:
every coefficient within 3 of its stated 1-sigma (not only node == CLI, which would hide a defect both share).
"""
from __future__ import annotations

import json
import math
from pathlib import Path
import time

import agreement
from bearing_id.config.params import load_rig
from bearing_id.identify import eq38_error
from bearing_id.io import bags, messages
from bearing_id.io.record import Record
from bearing_id.simulation.rig import truth_bearing_fn
import numpy as np
import pytest
import rosutil

REPO = Path(__file__).resolve().parents[1]
BAGS = REPO / 'bags'

pytestmark = [pytest.mark.ros, pytest.mark.slow(reason='each replays a packaged bag through the nodes (10-20 s)')]


def _node(name, params, env, timeout=120.0):
    cmd = [rosutil.script(name), '--ros-args']
    for k, v in params.items():
        if isinstance(v, list):
            v = '[' + ','.join(str(x) for x in v) + ']'
        cmd += ['-p', f'{k}:={v}']
    return rosutil.RosProcess(cmd, env=env, hard_timeout=timeout)


def _coefficients_from_bag(path):
    """Latest BearingCoefficients per speed from a recorded bag (rosbags only, no rclpy in this process)."""
    out = {}
    for _, _, _, msg in bags.read_bag(path, ['/bearing_id/coefficients']):
        d = messages.coefficients_from_msg(msg)
        out[round(d['speed'], 6)] = d
    return out


def wait_for_results(record_dir: Path, n_speeds: int, timeout: float = 60.0, settle: float = 3.0) -> bool:
    """
    Poll the identifier's record until every speed has a result and the record has settled.

    Settled: a result at ``n_speeds`` distinct speeds and no new result for ``settle`` s.  The node solves as windows
    close, so a speed's first result may come from some of the runs only (its later solves, with every run, follow
    within a few solve durations: identifier.py SOLVE_BACKLOG); the settle period waits for those.
    """
    t_end = time.monotonic() + timeout
    last_n, last_change = -1, time.monotonic()
    while time.monotonic() < t_end:
        if (record_dir / 'record.jsonl').exists():
            entries = list(Record(record_dir, fsync=False).entries('result'))
            if len(entries) != last_n:
                last_n, last_change = len(entries), time.monotonic()
            speeds = {round(e['result']['speed_rad_s'], 6) for e in entries}
            if len(speeds) >= n_speeds and time.monotonic() - last_change >= settle:
                return True
        time.sleep(0.25)
    return False


def replay_through_nodes(bag: Path, method: str, speeds_rpm, runs, tmp_path: Path, rate: float = 4.0,
                         identifier_params: dict | None = None):
    """Play ``bag`` into kf_estimator + identifier, record their outputs; returns (coefficients, recorder output)."""
    env = rosutil.ros_env()
    out_bag = tmp_path / 'outputs'
    record_dir = tmp_path / 'record'
    procs = []
    try:
        procs.append(_node('kf_estimator', {'prebuild_speeds_rpm': [float(s) for s in speeds_rpm]}, env))
        procs.append(_node('identifier', {'method': method, 'record_dir': str(record_dir), 'runs': runs,
                                          **(identifier_params or {})}, env))
        rec = rosutil.RosProcess([rosutil.script('bearing-id'), 'record', str(out_bag), '--topics',
                                  '/bearing_id/coefficients', '/bearing_id/bearing_displacement'],
                                 env=env, hard_timeout=150)
        procs.append(rec)
        play = rosutil.run([rosutil.script('bearing-id'), 'play', str(bag), '--rate', str(rate), '--wait-for', '2',
                            '--timeout', '60'], timeout=150, env=env)
        assert play.returncode == 0, play.stdout + play.stderr
        assert wait_for_results(record_dir, len(speeds_rpm)), procs[1].output()
        time.sleep(1.5)                      # the last batch of coefficients reaches the recorder
        rc, _ = rec.interrupt(within=20.0)
        assert rc == 0, rec.output()
        for p in procs[:2]:
            assert p.alive(), p.output()
            rc, _ = p.interrupt()
            assert rc == 0, p.output()
    finally:
        for p in procs:
            p.close()
    return _coefficients_from_bag(out_bag), rec.stdout


def offline(bag: Path, method: str, tmp_path: Path, *extra) -> list[dict]:
    js = tmp_path / 'offline.json'
    r = rosutil.run([rosutil.script('bearing-id'), 'identify', str(bag), '--method', method, '--json', str(js),
                     *extra], timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    return json.loads(js.read_text())['results']


def test_unbalance_bag_physical_equals_offline_cli_and_truth(tmp_path):
    bag = BAGS / 'unbalance_ab_sweep'
    speeds = [600.0, 900.0, 1200.0, 1500.0, 1800.0, 2100.0, 2400.0, 2700.0, 3000.0]
    live, rec_out = replay_through_nodes(bag, 'physical', speeds, ['A', 'B'], tmp_path)
    ref = offline(bag, 'physical', tmp_path)
    assert len(ref) == len(speeds)
    truth = truth_bearing_fn(load_rig())
    for r, d in zip(ref, agreement.by_speed(live, [r['speed_rad_s'] for r in ref])):
        assert d['method'] == 'physical'
        _coefficients_agree(d, r)
    # the truth, as well as the offline method gets it: paper eq. 38 error per group, both routes; the physical
    # method's targets from one probe (issue 4): <= 2 % stiffness, <= 3 % damping
    speeds_rad = sorted(live)
    live_coeffs = [live[s]['coeffs'] for s in speeds_rad]
    truths = [truth(s) for s in speeds_rad]
    e_live = eq38_error(live_coeffs, truths)
    assert e_live['K'] <= 2.0 and e_live['C'] <= 3.0, e_live
    # and every published coefficient within 3 of its stated 1-sigma of the truth (the std is honest)
    for s, t in zip(speeds_rad, truths):
        d = live[s]
        for i, node in enumerate(d['nodes']):
            for j, sym in enumerate(('K', 'C')):
                err = np.abs(np.asarray(d[sym][i]) - t[node][j])
                assert np.all(err <= 3.0 * np.asarray(d[f'{sym}_std'][i])), (s, node, sym, err, d[f'{sym}_std'][i])
    assert all(math.isfinite(d['condition']) and d['rank'] == d['unknowns'] for d in live.values())


def _coefficients_agree(d, r):
    """Assert published coefficients ``d`` (a message) agree with the CLI's JSON result ``r`` (agreement.py)."""
    assert r['condition'] is not None and math.isfinite(r['condition']), r['condition']
    for i, b in enumerate(r['bearings']):
        for sym in ('K', 'C'):
            std = agreement.floats(b[f'{sym}_std'])
            what = f"{sym} of {b['name']} at {r['speed_rpm']:.0f} rpm"
            agreement.assert_coefficients_agree(d[sym][i], agreement.floats(b[sym]), std, r['condition'], what)
            agreement.assert_std_agree(d[f'{sym}_std'][i], std, what + ' (1-sigma)')
            assert np.array_equal(np.asarray(d[f'{sym}_determined'][i], dtype=bool),
                                  np.array(b['determined'][sym], dtype=bool)), what


def test_force_plan_bag_direct_equals_offline_cli_and_truth_within_its_std(tmp_path):
    """
    The directional-force plan (4 runs), direct fit: node == CLI within 0.01 sigma, truth within the stated 1-sigma.

    With ``segment_timeout`` at its floor (10 ms) and ``pause_blocks`` 0: the identifier sees a pause between most
    blocks, and its windows must still be the offline ones (a pause on a loaded CI machine once moved a live result
    0.3 %).
    A statistical check of the std the product prints: normalised error RMS below 2, no error beyond 4.5 sigma over the
    64 determined coefficients.
    """
    bag = BAGS / 'force_plan'
    speeds = [1200.0, 2400.0]
    live, rec_out = replay_through_nodes(bag, 'direct', speeds, ['F4x', 'F4y', 'F8x', 'F8y'], tmp_path,
                                         identifier_params={'segment_timeout': 0.01, 'pause_blocks': 0.0})
    ref = offline(bag, 'direct', tmp_path)
    truth = truth_bearing_fn(load_rig())
    z = []
    for r, d in zip(ref, agreement.by_speed(live, [r['speed_rad_s'] for r in ref])):
        _coefficients_agree(d, r)
        t = truth(r['speed_rad_s'])
        for i, b in enumerate(r['bearings']):
            for j, sym in enumerate(('K', 'C')):
                std = np.asarray(d[f'{sym}_std'][i], dtype=float)
                assert np.all(np.isfinite(std)), 'a published force-plan coefficient lacks its 1-sigma'
                true = t[d['nodes'][i]][j]
                z += list(((np.asarray(d[sym][i]) - true) / std).ravel())
    z = np.array(z)
    assert len(z) == 2 * 2 * 2 * 4
    assert np.sqrt(np.mean(z**2)) < 2.0 and np.max(np.abs(z)) < 4.5, z


def test_force_plan_bag_paper_method_equals_offline_cli(tmp_path):
    """
    The paper method through the nodes gives `bearing-id identify --method paper` on the same bag (agreement.py).

    Until 27 Nov the identifier's paper route took the kf_estimator's estimates, dropped every one, and published
    nothing -- and no test ran it.  The paper method determines nothing here (its filter runs on the nominal theory),
    so the node publishes with ``publish_undetermined`` and the CLI prints with ``--allow-undetermined`` (and
    ``--allow-misfit``: a speed whose eqs 33-37 residual misfits determines nothing, its values flagged): the values
    and the determined flags must agree all the same.
    """
    bag = BAGS / 'force_plan'
    speeds = [1200.0, 2400.0]
    live, rec_out = replay_through_nodes(bag, 'paper', speeds, ['F4x', 'F4y', 'F8x', 'F8y'], tmp_path,
                                         identifier_params={'publish_undetermined': True})
    ref = offline(bag, 'paper', tmp_path, '--allow-undetermined', '--allow-misfit')
    for r, d in zip(ref, agreement.by_speed(live, [r['speed_rad_s'] for r in ref])):
        assert d['method'] == 'paper'
        for i in range(len(r['bearings'])):
            for sym in ('K', 'C'):
                assert np.all(np.isfinite(d[sym][i])), (sym, i, d[sym][i])
        _coefficients_agree(d, r)
