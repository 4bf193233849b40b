"""
Many machines on one DDS domain (issue 23 item 4) and parameters that do not exist (item 5).

Two namespaced identifiers with default parameters keep their records apart, each naming its machine; a second writer
on one record and another machine's record are refused with the reason; /diagnostics status names and hardware_id
carry the machine id.  A misspelled parameter (params file or ``-p``) and a missing params file end the node with
exit 2 and one line naming the key and the nearest known one.
"""
from __future__ import annotations

import fcntl
import os
from pathlib import Path
import tempfile
import time

from bearing_id.config.params import load_rig
from bearing_id.io.record import RecordInUse
from bearing_id.nodes import machine
from bearing_id.nodes.diagnostics import diagnostics_msg
from bearing_id.nodes.identifier_core import IdentifierCore
from bearing_id.nodes.status import DiagItem, OK
import pytest
import rosutil


def test_machine_id_and_record_dir_follow_the_namespace(tmp_path):
    assert machine.machine_id('', '/') == '' and machine.machine_id('', '/plant/c101') == 'plant/c101'
    assert machine.machine_id('k7', '/plant/c101') == 'k7'
    base = Path('~/.ros/bearing_id_record').expanduser()
    assert machine.record_dir('', '/', 'identifier') == base                    # where earlier versions kept it
    assert machine.record_dir('', '/machine2', 'identifier') == base / 'machine2' / 'identifier'
    assert machine.record_dir('', '/', 'identifier_b') == base / 'identifier_b'
    assert machine.record_dir(str(tmp_path), '/machine2', 'identifier') == tmp_path
    assert machine.status_name('machine1', 'identifier: accumulation') == 'machine1/identifier: accumulation'
    assert machine.status_name('', 'identifier: accumulation') == 'identifier: accumulation'


def test_diagnostics_carry_the_machine():
    arr = diagnostics_msg([DiagItem('identifier: accumulation', OK, 'ok', {})], None, 'machine1', 'machine1')
    assert [(s.name, s.hardware_id) for s in arr.status] == [('machine1/identifier: accumulation', 'machine1')]


def test_one_writer_per_record_and_never_another_machines(tmp_path):
    rig = load_rig()
    first = IdentifierCore(rig, 'physical', tmp_path, machine='machine1')
    with pytest.raises(RecordInUse, match=f'in use by another identifier \\(pid {os.getpid()}\\)'):
        IdentifierCore(rig, 'physical', tmp_path, machine='machine1')
    first.close()
    with pytest.raises(ValueError, match="belongs to machine 'machine1', this identifier serves 'machine2'"):
        IdentifierCore(rig, 'physical', tmp_path, machine='machine2')
    again = IdentifierCore(rig, 'physical', tmp_path, machine='machine1')        # the lock went with the first
    assert [e['type'] for e in again.record.entries()][:3] == ['machine', 'session', 'session']
    again.close()


@pytest.mark.ros
def test_two_namespaced_identifiers_with_default_parameters_keep_apart(tmp_path):
    """HOME is the test's directory: each default record lands under it, one per namespace, naming its machine."""
    env = rosutil.ros_env({'HOME': str(tmp_path)})
    procs = [rosutil.RosProcess([rosutil.script('identifier'), '--ros-args', '-r', f'__ns:=/machine{k}'], env=env,
                                hard_timeout=90) for k in (1, 2)]
    try:
        records = [tmp_path / '.ros' / 'bearing_id_record' / f'machine{k}' / 'identifier' / 'record.jsonl'
                   for k in (1, 2)]
        t_end = time.monotonic() + rosutil.STOP_WITHIN
        while not all(r.exists() and 'session' in r.read_text() for r in records) and time.monotonic() < t_end:
            time.sleep(0.2)
        assert all(p.alive() for p in procs), [p.output() for p in procs]
        for k, r in enumerate(records, start=1):
            assert f'"machine":"machine{k}"' in r.read_text(), r.read_text()
        assert not (tmp_path / '.ros' / 'bearing_id_record' / 'record.jsonl').exists()
    finally:
        for p in procs:
            p.interrupt()
            p.close()


@pytest.mark.ros
@pytest.mark.parametrize('node, args, key, near', [
    ('kf_estimator', ['-p', 'proces_noise:=1e-12'], 'proces_noise', 'process_noise'),
    ('identifier', 'file', 'methd', 'method'),
])
def test_a_misspelled_parameter_exits_2_naming_it_and_the_nearest(node, args, key, near, tmp_path):
    if args == 'file':
        f = tmp_path / 'p.yaml'
        f.write_text(f'/**:\n  ros__parameters:\n    {key}: direct\n')
        args = ['--params-file', str(f)]
    r = rosutil.run([rosutil.script(node), '--ros-args', *args], timeout=60)
    assert r.returncode == 2, r.stdout + r.stderr
    assert f"unknown parameter(s) '{key}' (did you mean '{near}'?)" in r.stderr and 'Traceback' not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr


@pytest.mark.ros
def test_a_missing_params_file_exits_2_in_one_line(tmp_path):
    r = rosutil.run([rosutil.script('identifier'), '--ros-args', '--params-file', str(tmp_path / 'nope.yaml')],
                    timeout=60)
    assert r.returncode == 2 and 'nope.yaml' in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


BEST_EFFORT_PEER = """
import sys, time
import rclpy
from rclpy.qos import qos_profile_sensor_data
from diagnostic_msgs.msg import DiagnosticArray
from bearing_id_msgs.msg import DisplacementBlock
rclpy.init()
node = rclpy.create_node('daq_sensor_qos')
node.create_publisher(DisplacementBlock, '/rotor/displacement', qos_profile_sensor_data)   # a SensorDataQoS DAQ
seen = {}
def on_diag(msg):
    for st in msg.status:
        if st.name == 'identifier: input /rotor/displacement':
            seen['message'] = st.message
node.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 10)
t_end = time.monotonic() + float(sys.argv[1])
while time.monotonic() < t_end and 'input_reliability' not in seen.get('message', ''):
    rclpy.spin_once(node, timeout_sec=0.1)
print('STATUS:', seen.get('message', '(none)'), flush=True)
"""


@pytest.mark.ros
@pytest.mark.parametrize('reliability', ['reliable', 'best_effort'])
def test_a_best_effort_publisher_that_cannot_connect_is_explained(tmp_path, reliability):
    """A SensorDataQoS (best-effort) DAQ publisher and a reliable input: /diagnostics names it and the parameter."""
    env = rosutil.ros_env()
    ident = rosutil.RosProcess([rosutil.script('identifier'), '--ros-args', '-p', f'record_dir:={tmp_path}',
                                '-p', 'diagnostics_period:=0.3', '-p', f'input_reliability:={reliability}'],
                               env=env, hard_timeout=90)
    try:
        r = rosutil.run_python(BEST_EFFORT_PEER, timeout=60, args=(20 if reliability == 'reliable' else 6,), env=env)
        assert r.returncode == 0, r.stdout + r.stderr
        status = r.stdout.split('STATUS:', 1)[1]
        if reliability == 'reliable':
            assert '1 best-effort publisher(s) on /rotor/displacement' in status, status
            assert 'input_reliability: best_effort' in status, status
        else:
            assert 'best-effort' not in status, status           # it connects: nothing to explain
    finally:
        ident.interrupt()
        ident.close()


def test_more_machines_than_a_domain_holds_get_distinct_reserved_domain_ids():
    """rosutil.domain_ids (benchmarks put machines beyond 39 on further domains): distinct ids, each locked."""
    ids = rosutil.domain_ids(3)
    assert ids[0] == rosutil.domain_id() and len(set(ids)) == 3 and rosutil.domain_ids(2) == ids[:2]
    for d in ids:
        assert d in rosutil.DOMAIN_RANGE
        with open(Path(tempfile.gettempdir()) / f'bearing_id_ros_domain_{d}.lock', 'a+') as f:
            with pytest.raises(OSError):                # held by this process's reservation
                fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
