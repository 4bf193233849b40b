"""
The identifier publishes the history's bearing changes on a topic of their own and on /diagnostics (issue 25 item 3).

A machine's history with bearing 1's clearance stepped by 8 sigma (test_trend's) is the identifier's history
database; started in the machine's namespace, the node publishes that alarm on ``<ns>/bearing_id/alarms`` (latched:
a subscriber that comes later gets it) with bearing, parameter, direction, size and onset as values and the machine
as hardware_id, and its /diagnostics item names the change (WARN).  The same detection as ``bearing-id trend`` (one
implementation: history/trend.py), here through the node.
"""
from __future__ import annotations

import json

from bearing_id.history import HistoryStore, sqlite_url
from bearing_id.history.trend import changes, parameter_series
import pytest
import rosutil
from test_trend import write_history

PEER = """
import json, sys, time
import rclpy
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from diagnostic_msgs.msg import DiagnosticArray
rclpy.init()
node = rclpy.create_node('alarm_listener')
latched = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
seen = {'alarms': [], 'diag': None}
def on_alarm(msg):
    for st in msg.status:
        seen['alarms'].append({'name': st.name, 'level': st.level[0], 'message': st.message,
                               'hardware_id': st.hardware_id, 'values': {kv.key: kv.value for kv in st.values}})
def on_diag(msg):
    for st in msg.status:
        if st.name == 'worn/identifier: bearing change alarms':
            seen['diag'] = {'level': st.level[0], 'message': st.message}
node.create_subscription(DiagnosticArray, '/worn/bearing_id/alarms', on_alarm, latched)
node.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 10)
t_end = time.monotonic() + float(sys.argv[1])
while time.monotonic() < t_end and not (seen['alarms'] and seen['diag']):
    rclpy.spin_once(node, timeout_sec=0.1)
print('SEEN:' + json.dumps(seen), flush=True)
"""


@pytest.mark.ros
def test_the_history_s_change_is_published_as_an_alarm(tmp_path):
    db = tmp_path / 'history.db'
    write_history(db, 'worn', step=True, seed=1)
    with HistoryStore(sqlite_url(db)) as store:
        (c,) = changes(parameter_series(store, 'worn'), arl0=1e5, delta=2.0, n_reference=10)
    env = rosutil.ros_env()
    ident = rosutil.RosProcess([rosutil.script('identifier'), '--ros-args', '-r', '__ns:=/worn',
                                '-p', f'record_dir:={tmp_path / "rec"}', '-p', f'history:={db}',
                                '-p', 'alarm_arl0:=1e5', '-p', 'diagnostics_period:=0.3'], env=env, hard_timeout=90)
    try:
        r = rosutil.run_python(PEER, timeout=60, args=(30,), env=env)
        assert r.returncode == 0, r.stdout + r.stderr + ident.output()
        seen = json.loads(r.stdout.split('SEEN:', 1)[1])
    finally:
        ident.interrupt()
        ident.close()
    (alarm,) = seen['alarms']
    assert alarm['name'] == 'worn/identifier: alarm: bearing1 clearance' and alarm['hardware_id'] == 'worn', alarm
    v = alarm['values']
    assert (v['bearing'], v['parameter'], v['direction']) == ('bearing1', 'clearance', 'up'), v
    assert abs(float(v['onset_stamp']) - c.alarm.onset_time) <= 1e-3
    assert float(v['size']) == pytest.approx(c.alarm.size, rel=1e-5)
    assert seen['diag']['level'] == 1 and 'bearing1 clearance: up' in seen['diag']['message'], seen['diag']
