"""
Foundation, message conversions (bearing_id.io.messages).

Inverse pairs, validation of a DisplacementBlock, and the rclpy and rosbags flavours serialising to identical CDR bytes
(two independent serialisers).
"""
from __future__ import annotations

import json
import math
import subprocess
import sys

from bearing_id.config.params import ExcitationEntry, Probe, Run
from bearing_id.io import bags, messages as M
import numpy as np
import pytest
import rosutil

TS = bags.typestore()
PROBES = (Probe('px', 3, 'x'), Probe('py', 3, 'y'))


def _block(samples=None, **kw):
    x = np.array([[1e-5, -2e-5], [3e-6, 4e-6], [0.0, 1e-4]]) if samples is None else samples
    args = {'sequence': 12, 'sample_rate': 5000.0, 'speed': 300.0, 'angle': 1.25, 'probes': PROBES, 'stamp': 2.5,
            'frame_id': 'rig', 'types': TS}
    args.update(kw)
    return M.block_to_msg(x, **args)


def test_block_round_trip():
    x = np.random.default_rng(1).normal(scale=1e-5, size=(257, 2))
    b = M.block_from_msg(_block(x))
    assert b.samples.shape == (257, 2) and np.array_equal(b.samples, x)
    assert (b.stamp_ns, b.sequence, b.sample_rate, b.speed, b.angle, b.frame_id) == \
        (2_500_000_000, 12, 5000.0, 300.0, 1.25, 'rig')
    assert b.probes == PROBES and b.channels == ('px', 'py') and b.nodes == (3, 3) and b.directions == ('x', 'y')
    assert b.stamp == pytest.approx(2.5, abs=1e-12)
    # row-major (sample, channel) on the wire
    assert np.array_equal(_block(x).samples[:4], [x[0, 0], x[0, 1], x[1, 0], x[1, 1]])


def test_block_from_inconsistent_message_raises_value_error():
    m = _block()
    m.samples = m.samples[:-1]
    with pytest.raises(ValueError, match='not a multiple of 2 channels'):
        M.block_from_msg(m)
    m = _block()
    m.nodes = m.nodes[:1]
    with pytest.raises(ValueError, match='2 channels but 1 nodes'):
        M.block_from_msg(m)


def test_validate_block_reports_problems_without_raising():
    assert M.validate_block(_block()) == []
    mm = M.validate_block(_block(np.array([[0.05, 0.01], [0.02, 0.0]])))       # millimetres sent as metres
    assert len(mm) == 1 and 'wrong units' in mm[0] and '0.05' in mm[0]
    x = np.full((4, 2), 1e-6)
    x[0, 0], x[1, 1], x[2, 0] = np.nan, np.nan, np.inf
    p = M.validate_block(_block(x))
    assert '2 NaN sample(s)' in p and '1 infinite sample(s)' in p and len(p) == 2
    p = M.validate_block(_block(speed=math.nan, sample_rate=0.0))
    assert any('sample_rate' in s for s in p) and any('unknown rotor speed' in s for s in p)
    p = M.validate_block(_block(probes=None, channels=['a', 'b'], nodes=[0, 2], directions=['x', 'z']))
    assert any('1-based' in s for s in p) and any("'x' or 'y'" in s for s in p)
    bad = _block()
    bad.samples = bad.samples[:-1]
    p = M.validate_block(bad)
    assert len(p) == 1 and p[0].startswith('malformed')


def test_excitation_round_trip():
    run = Run(id='r1', excitation=(ExcitationEntry('unbalance', 2, 1e-5, 0.3, 'forward', 1.0),
                                   ExcitationEntry('force', 5, 2.5, -1.0, 'x', 0.5)))
    m = M.excitation_to_msg(run, stamp=7, types=TS)
    assert M.excitation_from_msg(m) == run
    assert M.excitation_entries_from_msg(m) == list(run.excitation)
    m.phase = m.phase[:1]
    with pytest.raises(ValueError, match='differ in length'):
        M.excitation_from_msg(m)


def test_coefficients_round_trip_and_undetermined_nan():
    rng = np.random.default_rng(2)
    K, C = rng.normal(size=(2, 2, 2)) * 1e7, rng.normal(size=(2, 2, 2)) * 1e4
    K_std = np.abs(K) * 0.01
    K_std[1, 0, 1] = np.nan
    r = {'speed': 200.0, 'method': 'paper', 'bearings': ('b1', 'b2'), 'nodes': (1, 9), 'K': K, 'C': C, 'K_std': K_std,
         'rank': 15, 'unknowns': 16, 'condition': float('inf'), 'residual': 0.01, 'notes': ['x']}
    d = M.coefficients_from_msg(M.coefficients_to_msg(r, stamp=1.0, types=TS))
    assert np.array_equal(d['K'], K) and np.array_equal(d['C'], C)
    assert np.array_equal(d['K_std'], K_std, equal_nan=True) and np.all(np.isnan(d['C_std']))
    assert d['K_determined'].sum() == 7 and not d['K_determined'][1, 0, 1] and not d['C_determined'].any()
    assert (d['rank'], d['unknowns'], d['condition'], d['residual']) == (15, 16, math.inf, 0.01)
    assert d['bearings'] == ('b1', 'b2') and d['nodes'] == (1, 9) and d['notes'] == ['x']
    assert set(d['coeffs']) == {1, 9} and np.array_equal(d['coeffs'][9][0], K[1])
    # the flat layout on the wire is xx, xy, yx, yy per bearing
    m = M.coefficients_to_msg(r, types=TS)
    assert np.array_equal(m.stiffness[4:8], [K[1, 0, 0], K[1, 0, 1], K[1, 1, 0], K[1, 1, 1]])


def test_stamp_conversions():
    assert M.stamp_to_ns(1.5) == 1_500_000_000 and M.stamp_to_ns(7) == 7
    t = TS.types['builtin_interfaces/msg/Time'](sec=3, nanosec=5)
    assert M.stamp_to_ns(t) == 3_000_000_005
    with pytest.raises(ValueError):
        M.stamp_to_ns(float('nan'))
    with pytest.raises(TypeError):
        M.stamp_to_ns('now')


def test_no_ros_import_at_module_import():
    """The message converters and the bag reader work without a ROS environment: no rclpy, no built interfaces."""
    code = ('import sys; import bearing_id.io.messages, bearing_id.io.bags; '
            "print(sorted(m for m in ('rclpy', 'bearing_id_msgs') if m in sys.modules))")
    r = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=60,
                       cwd=str(rosutil.REPO))
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == '[]'


def test_rclpy_and_rosbags_flavours_agree_on_the_wire():
    """
    The converters build rclpy messages and rosbags messages that agree on the wire.

    rclpy messages are serialised by rclpy/Fast CDR in a subprocess, rosbags messages by rosbags in pure Python: same
    length, and rclpy's bytes deserialised by rosbags give the sample values.  (Not byte-equal: Fast CDR leaves
    alignment padding uninitialised.)
    """
    rosutil.require_ros()
    code = f"""
import sys, json
sys.path.insert(0, {str(rosutil.REPO / 'test')!r})
import rosutil
from rclpy.serialization import serialize_message
print(json.dumps([serialize_message(rosutil.build_with_converters(s)).hex() for s in rosutil.sample_messages()]))
"""
    r = rosutil.run_python(code, timeout=90)
    assert r.returncode == 0, r.stderr
    from_rclpy = json.loads(r.stdout.strip().splitlines()[-1])
    for s, hx in zip(rosutil.sample_messages(), from_rclpy):
        theirs = bytes.fromhex(hx)
        ours = bytes(TS.serialize_cdr(rosutil.build_with_converters(s, TS), s['type']))
        assert len(ours) == len(theirs), s['type']
        back = TS.deserialize_cdr(theirs, s['type'])
        assert rosutil.normalise(rosutil.msg_to_dict(back)) == rosutil.normalise(s['fields']), s['type']
