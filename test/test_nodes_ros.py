"""
The three nodes as processes.

Parameter rejection at start-up, the params/*.yaml files, SIGTERM, and the whole chain sensor_driver -> kf_estimator ->
identifier against the offline route on the same simulated data.
"""
from __future__ import annotations

import os
import signal
import time

import agreement
from bearing_id.config.params import load_rig
from bearing_id.identify import harmonics, identify
from bearing_id.io.record import Record
from bearing_id.rotor.assembly import RotorModel
from bearing_id.simulation import rig as R
import pytest
import rosutil

pytestmark = pytest.mark.ros
REPO = rosutil.REPO


@pytest.mark.parametrize('node, param, value', [
    ('sensor_driver', 'block_size', '8'),
    ('sensor_driver', 'source', 'tcp'),
    ('kf_estimator', 'measurement_noise', '-1.0'),
    ('kf_estimator', 'speed_band', '0.5'),
    ('identifier', 'method', 'magic'),
    ('identifier', 'settle_fraction', '1.5'),
])
def test_out_of_range_parameter_is_rejected_naming_it(node, param, value):
    r = rosutil.run([rosutil.script(node), '--ros-args', '-p', f'{param}:={value}'], timeout=60)
    assert r.returncode == 2, r.stdout + r.stderr
    assert f"parameter '{param}'" in r.stderr and 'Traceback' not in r.stderr, r.stderr


def test_wrong_parameter_type_is_rejected_naming_it():
    r = rosutil.run([rosutil.script('kf_estimator'), '--ros-args', '-p', 'process_noise:=abc'], timeout=60)
    assert r.returncode == 2 and "parameter 'process_noise'" in r.stderr and 'Traceback' not in r.stderr, r.stderr


@pytest.mark.parametrize('node', ['sensor_driver', 'kf_estimator', 'identifier'])
def test_params_file_starts_and_sigterm_stops_cleanly(node, tmp_path):
    cmd = [rosutil.script(node), '--ros-args', '--params-file', str(REPO / 'params' / f'{node}.yaml')]
    if node == 'identifier':
        cmd += ['-p', f"record_dir:={tmp_path / 'rec'}"]
    with rosutil.RosProcess(cmd, hard_timeout=90) as p:
        time.sleep(3.0)
        assert p.alive(), p.output()
        os.kill(p.pid, signal.SIGTERM)
        rc = p.wait(rosutil.STOP_WITHIN)               # a generous upper bound, not a timing verdict
        assert rc == 0, p.output()
        assert 'SIGTERM: shutting down' in p.stderr + p.stdout and 'Traceback' not in p.stderr, p.output()
    if node == 'identifier':
        assert [e['type'] for e in Record(tmp_path / 'rec', fsync=False).entries()] == ['machine', 'session']


@pytest.mark.slow(reason='simulation, three node processes and the offline route (~5-10 s)')
@pytest.mark.parametrize('executor', ['events', 'single_threaded'])
def test_driver_estimator_identifier_chain_equals_offline(tmp_path, executor):
    """
    Simulate -> three processes -> coefficients; the same simulation offline agrees within 0.01 sigma.

    With either executor the nodes can run (``executor``): the default events executor and the stock one.
    """
    env = rosutil.ros_env()
    speeds = [1200.0, 2400.0]
    rec_dir = tmp_path / 'rec'
    ex = ['-p', f'executor:={executor}']
    procs = []
    try:
        procs.append(rosutil.RosProcess([rosutil.script('identifier'), '--ros-args', '-p', 'method:=physical',
                                         '-p', f'record_dir:={rec_dir}', '-p', 'runs:=[A,B]', *ex], env=env,
                                        hard_timeout=120))
        procs.append(rosutil.RosProcess([rosutil.script('kf_estimator'), '--ros-args', '-p',
                                         'prebuild_speeds_rpm:=[1200.0,2400.0]', *ex], env=env, hard_timeout=120))
        drv = rosutil.RosProcess([rosutil.script('sensor_driver'), '--ros-args', '-p', 'speeds_rpm:=[1200.0,2400.0]',
                                  '-p', 'dwell:=1.5', '-p', 'rate_factor:=4.0', '-p', 'wait_for_subscribers:=2',
                                  '-p', 'exit_when_done:=true', *ex], env=env, hard_timeout=120)
        procs.append(drv)
        assert drv.wait(90) == 0, drv.output()
        t_end = time.monotonic() + 30
        res = []
        while time.monotonic() < t_end:
            res = [e['result'] for e in Record(rec_dir, fsync=False).entries('result')]
            if len({round(r['speed_rad_s'], 6) for r in res}) == 2:
                break
            time.sleep(0.25)
        for p in procs[:2]:
            assert p.alive(), p.output()
            rc, _ = p.interrupt()
            assert rc == 0, p.output()
        for p in procs:             # no callback failed along the way (the node would log it and go on)
            assert 'callback failed' not in p.stderr and 'Traceback' not in p.stderr, p.output()
    finally:
        for p in procs:
            p.close()
    rig = load_rig()
    recs = [R.simulate_run(rig, r, speeds_rpm=speeds, dwell=1.5) for r in rig.simulation.runs]
    ref = identify('physical', RotorModel.from_params(rig), rig, harmonics.from_recordings(recs))
    last = {r['speed_rad_s']: r for r in res}                 # the latest result per speed
    for r, d in zip(ref, agreement.by_speed(last, [r.speed for r in ref])):
        for i, b in enumerate(d['bearings']):
            for sym in ('K', 'C'):
                std = getattr(r, sym + '_std')[i]
                agreement.assert_coefficients_agree(agreement.floats(b[sym]), getattr(r, sym)[i], std, r.condition,
                                                    f'{sym} of bearing {i} at {r.speed_rpm:.0f} rpm')
                agreement.assert_std_agree(agreement.floats(b[sym + '_std']), std, f'{sym}_std of bearing {i}')


RAISING_NODE = """
import sys
from bearing_id.nodes.process import run_node
from rclpy.node import Node


def make():
    node = Node('raiser')
    node.declare_parameter('executor', 'EXECUTOR')
    ticks = []

    def tick():
        ticks.append(1)
        if len(ticks) in (2, 3):
            {}.pop('bug')               # a KeyError in a timer callback, twice
        if len(ticks) >= 8:
            node.finished = True
            print('ticks', len(ticks), flush=True)
    node.create_timer(0.02, tick)
    return node


sys.exit(run_node('raiser', 'test node', [], make, ['raiser']))
"""


@pytest.mark.parametrize('executor', ['events', 'single_threaded'])
def test_a_failing_callback_is_logged_with_its_traceback_and_the_node_goes_on(executor):
    r = rosutil.run_python(RAISING_NODE.replace('EXECUTOR', executor), timeout=60)
    assert r.returncode == 0, r.stdout + r.stderr
    assert 'ticks 8' in r.stdout, r.stdout + r.stderr      # the timer kept firing after both failures
    assert r.stderr.count('callback failed') == 2 and "KeyError: 'bug'" in r.stderr, r.stderr
    assert '2 so far' in r.stderr and 'Traceback' in r.stderr, r.stderr


HANGING_TEARDOWN_NODE = """
import ctypes
import sys
import time
import rclpy
from bearing_id.nodes import process
from rclpy.node import Node

process.TEARDOWN_LIMIT, process.TEARDOWN_HARD_LIMIT = 1.0, 3.0
HANGS = {'none': lambda: None,
         'sleeping': lambda: time.sleep(60),                     # a teardown that hangs, the GIL released
         'holding the GIL': lambda: ctypes.PyDLL(None).sleep(60)}   # libc sleep(60) with the GIL held
rclpy.try_shutdown = HANGS[sys.argv[1]]


class Closing(Node):
    def close(self):
        print('closed', flush=True)


def make():
    node = Closing('hanger')
    node.finished = True
    return node


sys.exit(process.run_node('hanger', 'test node', [], make, ['hanger']))
"""


@pytest.mark.parametrize('hang', ['none', 'sleeping', 'holding the GIL'])
def test_a_hanging_middleware_teardown_is_abandoned_after_the_node_closed(hang):
    t0 = time.monotonic()
    r = rosutil.run_python(HANGING_TEARDOWN_NODE, timeout=60, args=[hang])
    took = time.monotonic() - t0
    out = r.stdout + r.stderr
    assert 'closed' in r.stdout, out                  # close() (records) ran before the teardown
    if hang == 'none':
        assert r.returncode == 0 and 'teardown' not in out and 'Timeout' not in out, out
    elif hang == 'sleeping':                           # the watchdog thread: the node's own exit code
        assert r.returncode == 0 and took < 20, out    # after TEARDOWN_LIMIT, not after the 60 s hang
        assert 'middleware teardown still running after 1 s' in r.stderr, out
        assert 'most recent call first' in r.stderr and '_middleware_teardown' in r.stderr, out   # the stacks
    else:                                              # no Python thread runs: faulthandler ends it (exit 1)
        assert r.returncode == 1 and took < 20, out
        assert 'Timeout (0:00:03)' in r.stderr and '_middleware_teardown' in r.stderr, out
