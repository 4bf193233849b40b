"""
Bad input, one test each: the node stays up and /diagnostics says what and where.

No coefficients come from bad windows, and nothing already accumulated is lost.

Each test starts one node (identifier or kf_estimator) and a publisher peer -- this file run as a script under the ROS
python (``python test_bad_input.py peer SPEC.json OUT.json``) -- that sends the simulated rig's messages with one
fault injected, then collects /diagnostics, /bearing_id/coefficients and /bearing_id/bearing_displacement.  Every ROS
process goes through test/rosutil.py (localhost-only DDS, own domain id, kill timeouts).
"""
from __future__ import annotations

import array
import json
import math
from pathlib import Path
import shutil
import sys
import time

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
SPEEDS_RPM = [1200.0, 2400.0]
DWELL = 1.0
BLOCK = 1024
BLOCKS_PER_SPEED = int(DWELL * 10240 / BLOCK)      # 10


# ------------------------------------------------------------------------------------------------ peer process
def _inject(msgs, fault: str, arg):
    """Apply ``fault`` to the (topic, t_ns, msg, end_ns) list; returns the new list."""
    def disp(seq):
        return next(i for i, m in enumerate(msgs) if m[0] == '/rotor/displacement' and m[2].sequence == seq)

    if fault in ('nan', 'inf'):
        m = msgs[disp(arg)][2]
        m.samples[2 * 17 + 1] = float('nan') if fault == 'nan' else float('inf')
    elif fault == 'gap':
        del msgs[disp(arg)]
    elif fault == 'reorder':
        i, j = disp(arg), disp(arg + 1)
        msgs[i], msgs[j] = msgs[j], msgs[i]
    elif fault == 'channels':                   # run B's blocks come with other channel names
        for t, _, m, _ in msgs:
            if t == '/rotor/displacement' and m.sequence >= arg:
                m.channels = ['ch0', 'ch1']
    elif fault == 'units':                      # micrometres sent as metres
        for t, _, m, _ in msgs:
            if t == '/rotor/displacement':
                m.samples = array.array('d', [v * 1e6 for v in m.samples])
    elif fault == 'no_speed':                   # a DAQ without keyphasor angles and without speed
        msgs = [x for x in msgs if x[0] != '/rotor/speed']
        for t, _, m, _ in msgs:
            if t == '/rotor/displacement':
                m.speed = float('nan')
                m.sample_angles = array.array('d')
    elif fault == 'no_excitation':
        msgs = [x for x in msgs if x[0] != '/rotor/excitation']
    elif fault == 'unsteady':                   # the keyphasor says the speed wanders by 1 % steps block to block
        a_end = None
        for t, _, m, _ in msgs:
            if t == '/rotor/displacement':
                a = list(m.sample_angles)
                f = 1.0 + 0.01 * (m.sequence % 7)
                a0 = a[0] if a_end is None else a_end
                new = [a0 + f * (v - a[0]) for v in a]
                a_end = new[-1] + f * (a[-1] - a[-2])
                m.sample_angles = array.array('d', new)
                m.speed = m.speed * f
    elif fault == 'runs':                       # only some runs (arg = list of run ids)
        keep, cur = [], None
        for x in msgs:
            if x[0] == '/rotor/excitation':
                cur = x[2].run_id
            if cur in arg:
                keep.append(x)
        msgs = keep
    elif fault != 'none':
        raise ValueError(fault)
    return msgs


def peer(spec_path: str, out_path: str) -> int:
    from diagnostic_msgs.msg import DiagnosticArray
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    sys.path.insert(0, str(REPO))
    from bearing_id.io import messages as M
    from bearing_id.nodes.qos import qos_latched, qos_stream
    from bearing_id.nodes.sensor_driver_core import stream_messages
    from bearing_id.io.recordings import load_npz

    spec = json.loads(Path(spec_path).read_text())
    recs = [load_npz(p) for p in spec['recordings']]
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bad_input_peer')
    pubs = {'/rotor/displacement': node.create_publisher(M.DisplacementBlock, '/rotor/displacement', qos_stream()),
            '/rotor/speed': node.create_publisher(M.RotorSpeed, '/rotor/speed', qos_stream(50)),
            '/rotor/excitation': node.create_publisher(M.Excitation, '/rotor/excitation', qos_latched())}
    got = {'diagnostics': [], 'coefficients': [], 'bearing_blocks': 0}
    node.create_subscription(DiagnosticArray, '/diagnostics', lambda m: got['diagnostics'].extend(
        {'name': s.name, 'level': int.from_bytes(s.level, 'little') if isinstance(s.level, bytes) else int(s.level),
         'message': s.message, 'values': {kv.key: kv.value for kv in s.values}} for s in m.status), 50)
    node.create_subscription(M.BearingCoefficients, '/bearing_id/coefficients',
                             lambda m: got['coefficients'].append(round(float(m.speed), 6)), qos_latched(100))

    def on_est(m):
        got['bearing_blocks'] += 1
    node.create_subscription(M.DisplacementBlock, '/bearing_id/bearing_displacement', on_est, qos_stream())
    t_end = time.monotonic() + 30
    while pubs['/rotor/displacement'].get_subscription_count() < 1 and time.monotonic() < t_end:
        rclpy.spin_once(node, timeout_sec=0.05)
    time.sleep(0.3)
    msgs = _inject(list(stream_messages(recs, BLOCK, 1_000_000_000_000, 'rig')), spec['fault'], spec.get('arg'))
    for topic, _, msg, _ in msgs:
        pubs[topic].publish(msg)
        if topic == '/rotor/displacement':
            rclpy.spin_once(node, timeout_sec=0.0)
            time.sleep(0.004)
    # listen for `listen` s, and on until coefficients at `until_speeds` speeds came (at most 45 s more: an upper
    # bound for a loaded machine, so that no verdict depends on how fast the nodes are)
    need, need_blocks = int(spec.get('until_speeds', 0)), int(spec.get('until_bearing_blocks', 0))
    t_end, t_hard = time.monotonic() + spec.get('listen', 3.0), time.monotonic() + 45.0
    while time.monotonic() < t_end or ((len(set(got['coefficients'])) < need or got['bearing_blocks'] < need_blocks)
                                       and time.monotonic() < t_hard):
        rclpy.spin_once(node, timeout_sec=0.05)
    Path(out_path).write_text(json.dumps(got))
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    if len(sys.argv) == 4 and sys.argv[1] == 'peer':
        sys.exit(peer(sys.argv[2], sys.argv[3]))
    sys.exit('usage: test_bad_input.py peer SPEC.json OUT.json')


# ------------------------------------------------------------------------------------------------ tests
import agreement  # noqa: E402
from bearing_id.config.params import load_rig  # noqa: E402
from bearing_id.identify import harmonics, identify  # noqa: E402
from bearing_id.io.record import Record  # noqa: E402
from bearing_id.io.recordings import load_npz, save_npz  # noqa: E402
from bearing_id.rotor.assembly import RotorModel  # noqa: E402
from bearing_id.simulation import rig as R  # noqa: E402
import pytest  # noqa: E402
import rosutil  # noqa: E402

pytestmark = pytest.mark.ros


@pytest.fixture(scope='module')
def recordings(tmp_path_factory):
    """Write runs A and B of the rig, 1200 and 2400 rpm, 1 s each (npz, written once)."""
    rig = load_rig()
    d = tmp_path_factory.mktemp('recs')
    return [str(save_npz(R.simulate_run(rig, r, speeds_rpm=SPEEDS_RPM, dwell=DWELL), d / f'run_{r.id}.npz'))
            for r in rig.simulation.runs]


def start(name, params, env):
    cmd = [rosutil.script(name), '--ros-args', '-p', 'diagnostics_period:=0.2']
    for k, v in params.items():
        if isinstance(v, list):
            v = '[' + ','.join(str(x) for x in v) + ']'
        cmd += ['-p', f'{k}:={v}']
    return rosutil.RosProcess(cmd, env=env, hard_timeout=90)


def identifier(tmp_path, env, **kw):
    return start('identifier', {'method': 'physical', 'record_dir': str(tmp_path / 'record'), 'runs': ['A', 'B'],
                                **kw}, env)


def drive(recordings, tmp_path, fault, arg=None, listen=4.0, env=None, until_speeds=0, until_bearing_blocks=0):
    """
    Publish the recordings with ``fault`` injected; listen, and on until enough results and estimates came.

    Listens ``listen`` s, and on (45 s at most) until ``until_speeds`` speeds' coefficients and
    ``until_bearing_blocks`` bearing-displacement blocks came.
    """
    spec = tmp_path / f'spec_{fault}.json'
    out = tmp_path / f'out_{fault}.json'
    spec.write_text(json.dumps({'recordings': recordings, 'fault': fault, 'arg': arg, 'listen': listen,
                                'until_speeds': until_speeds, 'until_bearing_blocks': until_bearing_blocks}))
    r = rosutil.run([rosutil.require_ros(), str(Path(__file__)), 'peer', str(spec), str(out)], timeout=150, env=env)
    assert r.returncode == 0, r.stdout + r.stderr
    return json.loads(out.read_text())


def diag_text(got, name_part=''):
    seen = dict.fromkeys(f"[{d['level']}] {d['name']}: {d['message']} {d['values'].get('problems', '')}"
                         for d in got['diagnostics'] if name_part in d['name'])     # unique, in order
    return ' || '.join(seen)


def vectors(tmp_path):
    return [v for v in Record(tmp_path / 'record', fsync=False).entries('vector') if v['used']]


def finish(proc):
    assert proc.alive(), proc.output()                 # the node stayed up
    rc, dt = proc.interrupt()
    assert rc == 0, proc.output()
    assert 'Traceback' not in proc.stderr, proc.output()


def _no_vector_spans(vecs, bad_seq):
    for v in vecs:
        a, b = v['seqs']
        assert not (a <= bad_seq <= b), f"vector {v['run_id']} {v['speed']:.1f} rad/s uses blocks {a}..{b}"


@pytest.mark.parametrize('fault', ['nan', 'inf'])
def test_nonfinite_samples(recordings, tmp_path, fault):
    env = rosutil.ros_env()
    bad = 5                                          # run A, 1200 rpm, inside the steady part
    with identifier(tmp_path, env) as node:
        got = drive(recordings, tmp_path, fault, bad, env=env, until_speeds=2)
        finish(node)
    text = diag_text(got, 'identifier')
    assert 'non-finite sample(s)' in text and f'seq {bad}' in text and 'p6y' in text, text
    vecs = vectors(tmp_path)
    _no_vector_spans(vecs, bad)
    # the good data still give every speed (nothing lost): 2 runs x 2 speeds of vectors (the dwell with the bad
    # block contributes both of its halves), coefficients at both speeds
    assert {(v['run_id'], round(v['speed'])) for v in vecs} == {(r, round(w)) for r in 'AB' for w in (
        1200 * math.pi / 30, 2400 * math.pi / 30)}, vecs
    assert any(v.get('after_gap') for v in vecs), vecs
    assert len(set(got['coefficients'])) == 2, got['coefficients']


def test_sequence_gap(recordings, tmp_path):
    env = rosutil.ros_env()
    lost = 6
    with identifier(tmp_path, env) as node:
        got = drive(recordings, tmp_path, 'gap', lost, env=env, until_speeds=2)
        finish(node)
    text = diag_text(got, 'identifier')
    assert f'1 block(s) lost between seq {lost - 1} and {lost + 1}' in text, text
    for v in vectors(tmp_path):                      # no window straddles the gap
        a, b = v['seqs']
        assert not (a <= lost - 1 and b >= lost + 1), v['seqs']
    assert len(set(got['coefficients'])) == 2


def test_out_of_order_stamps(recordings, tmp_path):
    env = rosutil.ros_env()
    k = 4
    with identifier(tmp_path, env) as node:
        got = drive(recordings, tmp_path, 'reorder', k, env=env, until_speeds=2)
        finish(node)
    text = diag_text(got, 'identifier')
    assert f'sequence went back from {k + 1} to {k}' in text and 'rejected' in text, text
    for v in vectors(tmp_path):
        a, b = v['seqs']
        assert not (a <= k <= b), v['seqs']
    assert len(set(got['coefficients'])) == 2


def test_wrong_channel_names(recordings, tmp_path):
    env = rosutil.ros_env()
    first_b = 2 * BLOCKS_PER_SPEED                   # run B starts here
    with identifier(tmp_path, env) as node:
        got = drive(recordings, tmp_path, 'channels', first_b, env=env)
        finish(node)
    text = diag_text(got, 'identifier')
    assert "wrong channels ['ch0', 'ch1']" in text and "expected ['p6x', 'p6y']" in text, text
    vecs = vectors(tmp_path)
    assert {v['run_id'] for v in vecs} == {'A'} and len(vecs) == 2       # run A kept, nothing of B
    assert got['coefficients'] == []                 # run B missing: no coefficients


def test_wrong_units(recordings, tmp_path):
    env = rosutil.ros_env()
    with identifier(tmp_path, env) as node:
        got = drive(recordings, tmp_path, 'units', env=env)
        finish(node)
    text = diag_text(got, 'identifier')
    assert 'implausible amplitude' in text and 'micrometres sent?' in text, text
    assert vectors(tmp_path) == [] and got['coefficients'] == []


def test_no_speed_topic_kf_estimator(recordings, tmp_path):
    env = rosutil.ros_env()
    with start('kf_estimator', {'prebuild_speeds_rpm': SPEEDS_RPM}, env) as node:
        got = drive(recordings, tmp_path, 'no_speed', env=env)
        finish(node)
    text = diag_text(got, 'kf_estimator')
    assert 'rejected' in text and 'no sample_angles (unknown rotor speed)' in text, text
    assert any(d['level'] == 3 and '/rotor/speed' in d['message'] for d in got['diagnostics']), text
    assert got['bearing_blocks'] == 0                 # nothing estimated without a speed


def test_no_excitation(recordings, tmp_path):
    env = rosutil.ros_env()
    with identifier(tmp_path, env) as node:
        got = drive(recordings, tmp_path, 'no_excitation', env=env)
        finish(node)
    errs = [d for d in got['diagnostics'] if d['level'] == 2 and 'identifier' in d['name']]
    assert errs and 'no excitation received on /rotor/excitation' in errs[-1]['message'], diag_text(got)
    assert vectors(tmp_path) == [] and got['coefficients'] == []


def test_speed_not_steady(recordings, tmp_path):
    env = rosutil.ros_env()
    with identifier(tmp_path, env) as node:
        got = drive(recordings, tmp_path, 'unsteady', env=env)
        finish(node)
    text = diag_text(got, 'identifier')
    assert 'too short for a 1X vector' in text, text
    # the speed was never steady for long enough: no vector, no coefficients
    assert len(vectors(tmp_path)) == 0 and got['coefficients'] == []


def test_truncated_and_corrupt_bag(recordings, tmp_path):
    env = rosutil.ros_env()
    src = REPO / 'bags' / 'slow_roll'
    trunc = tmp_path / 'truncated'
    shutil.copytree(src, trunc)
    mcap = next(trunc.glob('*.mcap'))
    mcap.write_bytes(mcap.read_bytes()[: mcap.stat().st_size // 2])
    corrupt = tmp_path / 'corrupt'
    shutil.copytree(src, corrupt)
    m2 = next(corrupt.glob('*.mcap'))
    data = bytearray(m2.read_bytes())
    data[-200:] = b'\xff' * 200                       # summary section and footer destroyed
    m2.write_bytes(bytes(data))
    with identifier(tmp_path, env) as node:
        for bag in (trunc, corrupt):
            r = rosutil.run([rosutil.script('bearing-id'), 'play', str(bag), '--rate', '20', '--timeout', '20'],
                            timeout=60, env=env)
            assert r.returncode == 2, r.stdout + r.stderr
            assert str(bag) in r.stderr and 'Traceback' not in r.stderr, r.stderr
            assert node.alive(), node.output()
        finish(node)


@pytest.mark.slow(reason='an identifier is run, stopped and restarted on its record (~10 s)')
def test_identifier_restart_resumes_from_its_record(recordings, tmp_path):
    env = rosutil.ros_env()
    with identifier(tmp_path, env) as node:
        got = drive(recordings, tmp_path, 'runs', ['A'], env=env, listen=1.5)
        assert got['coefficients'] == []              # run B still missing
        rc, _ = node.interrupt()           # (SIGINT; SIGTERM is tested in test_nodes_ros)
        assert rc == 0, node.output()
    before = vectors(tmp_path)
    assert {v['run_id'] for v in before} == {'A'} and len(before) == 2
    with identifier(tmp_path, env) as node:
        got = drive(recordings, tmp_path, 'runs', ['B'], env=env, until_speeds=2)
        finish(node)
    entries = Record(tmp_path / 'record', fsync=False).entries()
    sessions = [e for e in entries if e['type'] == 'session']
    assert sessions[-1]['resumed_vectors'] == 2
    assert len(set(got['coefficients'])) == 2         # A (from the record) + B (new) solved at both speeds
    # the resumed result equals an uninterrupted run on the same data (offline route on the same windows)
    rig = load_rig()
    ref = identify('physical', RotorModel.from_params(rig), rig, harmonics.from_recordings(
        [load_npz(p) for p in recordings]))
    res = [e['result'] for e in entries if e['type'] == 'result'][-len(ref):]
    for r, d in zip(ref, agreement.by_speed({x['speed_rad_s']: x for x in res}, [r.speed for r in ref])):
        for i, b in enumerate(d['bearings']):
            for sym in ('K', 'C'):
                agreement.assert_coefficients_agree(agreement.floats(b[sym]), getattr(r, sym)[i],
                                                    getattr(r, sym + '_std')[i], r.condition, f'{sym} of bearing {i}')


@pytest.mark.parametrize('executor', ['events', 'single_threaded'])
def test_blocks_waiting_for_their_model_are_estimated_when_it_is_built(recordings, tmp_path, executor):
    """
    Every block is estimated, also those still queued for their model when the stream has ended.

    No model is built before the stream (the prebuilt speed is another), and the peer publishes the blocks within
    a fraction of a second, far faster than a model is built: the last blocks are drained only when the model
    builder's thread wakes the node, with either executor (the events executor has no guard conditions).
    """
    env = rosutil.ros_env()
    total = -(-load_npz(recordings[0]).samples.shape[0] // BLOCK)      # run A's dwells and ramps
    with start('kf_estimator', {'prebuild_speeds_rpm': [600.0], 'executor': executor}, env) as node:
        got = drive(recordings, tmp_path, 'runs', ['A'], listen=1.0, env=env, until_bearing_blocks=total)
        finish(node)
    assert got['bearing_blocks'] == total, (got['bearing_blocks'], diag_text(got, 'kf_estimator'))
