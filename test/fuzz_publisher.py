"""
Publish randomly corrupted bearing_id messages to the nodes' input topics, for test_fuzz_nodes.py.

Every corruption makes the message unusable.  Run with the ROS python:  python fuzz_publisher.py SEED COUNT

Each message starts from a valid one (a short simulated recording as the sensor_driver sends it) and gets one to
three corruptions drawn from the lists below; every list entry alone makes the message invalid (NaN, lengths that
disagree, out-of-range numbers, unknown enums, samples in micrometres, ...).  Prints one JSON line with the counts.
"""
from __future__ import annotations

import array
import json
import math
import random
import sys
import time

from bearing_id.config.params import load_rig
from bearing_id.io import messages as M
from bearing_id.nodes.sensor_driver_core import stream_messages
from bearing_id.simulation import rig as R


def _block_mutations(rng):
    def nan(m):
        s = m.samples if len(m.samples) else array.array('d', [0.0, 0.0])
        s[rng.randrange(len(s))] = rng.choice([math.nan, math.inf, -math.inf])
        m.samples = s

    def units(m):
        m.samples = array.array('d', [x * 1e6 for x in m.samples])

    def odd_length(m):
        m.samples.append(0.0)

    def channels(m):
        m.channels = rng.choice([['p6x'], ['p6x', 'p6y', 'p7x'], ['p6z', 'p6y'], ['', '']])

    def nodes(m):
        m.nodes = array.array('I', rng.choice([[0, 6], [6], [6, 6, 6], [4000000000, 6]]))

    def directions(m):
        m.directions = rng.choice([['x'], ['z', 'y'], ['x', 'y', 'x'], ['X', 'Y']])

    def rate(m):
        m.sample_rate = rng.choice([0.0, -10240.0, math.nan, math.inf, 1e-300, 1e300])

    def _angles(m):
        a = list(m.sample_angles)
        return a if len(a) >= 3 else [0.0, 0.1, 0.2]         # (after another mutation emptied them)

    def angles_len(m):
        a = _angles(m)
        m.sample_angles = array.array('d', a[:rng.randrange(1, len(a) - 1)])

    def angles_nan(m):
        a = _angles(m)
        a[rng.randrange(len(a))] = math.nan
        m.sample_angles = array.array('d', a)

    def angles_back(m):
        m.sample_angles = array.array('d', _angles(m)[::-1])

    def angles_jump(m):
        a = _angles(m)
        k = rng.randrange(1, len(a))
        m.sample_angles = array.array('d', [x + (3.0 if i >= k else 0.0) for i, x in enumerate(a)])

    def empty(m):
        m.samples = array.array('d')
        m.sample_angles = array.array('d')

    def no_angle_no_speed(m):
        m.sample_angles = array.array('d')
        m.speed = rng.choice([math.nan, -1.0, 0.0, math.inf])

    return [nan, units, odd_length, channels, nodes, directions, rate, angles_len, angles_nan, angles_back,
            angles_jump, empty, no_angle_no_speed]


def _excitation_mutations(rng):
    def lengths(m):
        m.magnitude = array.array('d', list(m.magnitude) + [1.0])

    def kind(m):
        m.kind = [rng.choice(['bogus', '', 'UNBALANCE', 'force '])] * len(m.kind)

    def node(m):
        m.node = array.array('I', [rng.choice([0, 12, 4000000000])] * len(m.node))

    def magnitude(m):
        m.magnitude = array.array('d', [rng.choice([math.nan, -1.0, math.inf])] * len(m.magnitude))

    def phase(m):
        m.phase = array.array('d', [rng.choice([math.nan, math.inf])] * len(m.phase))

    def ratio(m):
        m.frequency_ratio = array.array('d', [rng.choice([0.0, -1.0, math.inf, math.nan, 1e9])] *
                                        len(m.frequency_ratio))

    def direction(m):
        m.direction = [rng.choice(['sideways', '', 'z'])] * len(m.direction)

    def run_id(m):
        m.run_id = rng.choice(['', 'A' * 1000])

    def empty(m):
        for f in ('kind', 'direction'):
            setattr(m, f, [])
        for f in ('magnitude', 'phase', 'frequency_ratio'):
            setattr(m, f, array.array('d'))
        m.node = array.array('I')

    return [lengths, kind, node, magnitude, phase, ratio, direction, run_id, empty]


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    seed, count = int(argv[0]), int(argv[1])
    rng = random.Random(seed)
    from bearing_id_msgs.msg import DisplacementBlock, Excitation, RotorSpeed
    import rclpy
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    rig = load_rig()
    recs = [R.simulate_run(rig, r, speeds_rpm=[1500.0], dwell=0.5, ramp=0.0) for r in rig.simulation.runs]
    valid = {'block': [], 'excitation': [], 'speed': []}
    for topic, _, msg, _ in stream_messages(recs, 1024, time.time_ns(), rig.name):
        valid[{'/rotor/displacement': 'block', '/rotor/excitation': 'excitation',
               '/rotor/speed': 'speed'}[topic]].append(msg)
    rclpy.init()
    node = rclpy.create_node('bearing_id_fuzzer')
    rel = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)
    pubs = {'block': node.create_publisher(DisplacementBlock, '/rotor/displacement', rel),
            'estimated': node.create_publisher(DisplacementBlock, '/bearing_id/bearing_displacement', rel),
            'excitation': node.create_publisher(Excitation, '/rotor/excitation', rel),
            'speed': node.create_publisher(RotorSpeed, '/rotor/speed', rel)}
    t_end = time.monotonic() + 20
    while time.monotonic() < t_end and (pubs['block'].get_subscription_count() < 2
                                        or pubs['excitation'].get_subscription_count() < 2):
        rclpy.spin_once(node, timeout_sec=0.1)
    muts = {'block': _block_mutations(rng), 'excitation': _excitation_mutations(rng)}
    sent = dict.fromkeys(pubs, 0)
    seq = 10_000
    for i in range(count):
        kind = rng.choice(['block', 'block', 'block', 'estimated', 'excitation', 'speed'])
        if kind == 'speed':
            m = M.speed_to_msg(rng.choice([math.nan, math.inf, -100.0, 1e300]), rng.choice([math.nan, 0.0]),
                               stamp=time.time_ns())
        else:
            src = rng.choice(valid['excitation' if kind == 'excitation' else 'block'])
            m = type(src)()
            for f in src.get_fields_and_field_types():
                v = getattr(src, f)
                setattr(m, f, array.array(v.typecode, v) if isinstance(v, array.array) else
                        (list(v) if isinstance(v, list) else v))
            if kind != 'excitation':
                seq += 1
                m.sequence = seq
            for mut in rng.sample(muts['excitation' if kind == 'excitation' else 'block'], rng.randint(1, 3)):
                mut(m)
        pubs[kind].publish(m)
        sent[kind] += 1
        rclpy.spin_once(node, timeout_sec=0.002)
    time.sleep(1.0)
    print(json.dumps(sent), flush=True)
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
