"""
Killing a node mid-run loses no published history row (issue 25's "done when").

The three nodes stream the packaged plan several times over; a listener writes every BearingCoefficients message the
identifier publishes to a file as it arrives.  Mid-run kf_estimator is killed (SIGKILL) and restarted, then the
identifier, then sensor_driver (the stream stops: its restart streams the plan again).  Afterwards every message heard
-- from both lives of the identifier -- is a row of the history: same speed, method and coefficients (the values the
identifier wrote and sent, compared within 1e-12 relative: one number stored and transported, not two computations),
because the identifier writes a solve's rows before it publishes them.  The identifier's second life resumed its
record's vectors rather than starting empty, and solved on the restarted stream.
"""
from __future__ import annotations

import json
import math
import time

from bearing_id.history import HistoryStore, sqlite_url
import pytest
import rosutil

LISTENER = """
import json, sys, time
import rclpy
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from bearing_id_msgs.msg import BearingCoefficients
rclpy.init()
node = rclpy.create_node('coefficient_listener')
qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.VOLATILE)
out = open(sys.argv[2], 'a')
def on_msg(m):
    out.write(json.dumps({'speed': m.speed, 'method': m.method, 'bearings': list(m.bearings),
                          'K': list(m.stiffness), 'C': list(m.damping)}) + '\\n')
    out.flush()
node.create_subscription(BearingCoefficients, '/bearing_id/coefficients', on_msg, qos)
t_end = time.monotonic() + float(sys.argv[1])
while time.monotonic() < t_end:
    rclpy.spin_once(node, timeout_sec=0.1)
"""
NAMES = ('xx', 'xy', 'yx', 'yy')


def _heard(path) -> list:
    """Return the messages the listener wrote so far (a line still being written is not one yet)."""
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().split('\n')[:-1] if line.strip()]


def _wait(cond, timeout: float, what: str) -> None:
    t_end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < t_end, f'timed out waiting for {what}'
        time.sleep(0.2)


def _row_values(r) -> dict:
    return {(c.bearing, c.name): c.value for c in r.coefficients}


def _same(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or abs(a - b) <= 1e-12 * max(abs(a), abs(b), 1e-300)


@pytest.mark.ros
def test_killing_any_node_mid_run_loses_no_published_history_row(tmp_path):
    env = rosutil.ros_env()
    db, heard_file = tmp_path / 'history.db', tmp_path / 'heard.jsonl'
    ident_cmd = [rosutil.script('identifier'), '--ros-args', '-p', f'record_dir:={tmp_path / "record"}',
                 '-p', f'history:={db}']
    kf_cmd = [rosutil.script('kf_estimator'), '--ros-args']
    driver_cmd = [rosutil.script('sensor_driver'), '--ros-args', '-p', 'passes:=3', '-p', 'rate_factor:=3.0',
                  '-p', 'wait_for_subscribers:=2', '-p', 'exit_when_done:=true']
    listener = rosutil.RosProcess([rosutil.ros_python(), '-c', LISTENER, '400', str(heard_file)], env=env,
                                  hard_timeout=420)
    procs = {'identifier': rosutil.RosProcess(ident_cmd, env=env, hard_timeout=400),
             'kf_estimator': rosutil.RosProcess(kf_cmd, env=env, hard_timeout=400),
             'sensor_driver': rosutil.RosProcess(driver_cmd, env=env, hard_timeout=400)}
    lives = []
    try:
        for name, after in (('kf_estimator', 3), ('identifier', 12), ('sensor_driver', 20)):
            _wait(lambda: len(_heard(heard_file)) >= after, 240, f'{after} coefficient messages before killing {name}')
            procs[name].kill()
            lives.append(procs[name])
            time.sleep(1.0)
            cmd = {'identifier': ident_cmd, 'kf_estimator': kf_cmd, 'sensor_driver': driver_cmd}[name]
            n_restart = len(_heard(heard_file))
            procs[name] = rosutil.RosProcess(cmd, env=env, hard_timeout=400)
        assert procs['sensor_driver'].wait(300) == 0, procs['sensor_driver'].output()
        _wait(lambda: len(_heard(heard_file)) > n_restart, 120, 'the identifier to solve the restarted stream')
        last, since = None, time.monotonic()
        while time.monotonic() - since < 10.0:         # until nothing new was heard for 10 s
            n = len(_heard(heard_file))
            if n != last:
                last, since = n, time.monotonic()
            time.sleep(0.5)
    finally:
        log = procs['identifier'].stdout + procs['identifier'].stderr
        for p in list(procs.values()) + [listener]:
            p.interrupt()
            p.close()
        for p in lives:
            p.close()
    heard = _heard(heard_file)
    with HistoryStore(sqlite_url(db)) as store:
        rows = [r for m in store.machines() for r in store.records(m.machine_id)]
    missing = []
    for h in heard:
        want = {(b, f'{kc}{n}'): v for kc in ('K', 'C')
                for i, b in enumerate(h['bearings']) for n, v in zip(NAMES, h[kc][4 * i:4 * i + 4])}
        if not any(r.speed == h['speed'] and r.method == h['method']
                   and all(_same(v, _row_values(r).get(k, math.nan)) for k, v in want.items()) for r in rows):
            missing.append((h['speed'], h['method']))
    assert len(heard) >= 20, len(heard)
    assert not missing, f'{len(missing)} of {len(heard)} published results not in the history: {missing[:5]}'
    resumed = [int(x.split()[0]) for x in log.split('(resumed ')[1:]]
    assert resumed and resumed[0] > 0, log[-3000:]
