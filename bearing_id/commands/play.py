"""
``bearing-id play``: replay a rosbag2 bag (mcap or sqlite3) onto ROS 2 topics, since ``ros2 bag`` is not on PyPI.

The bag's raw CDR bytes are published unchanged (rclpy accepts serialized messages), paced by the bag timestamps in
real time or ``--rate`` times faster, after every stream topic has at least ``--wait-for`` subscribers.  QoS matches
the nodes (:mod:`bearing_id.nodes.qos`): reliable, deep queue for streams; reliable + transient-local (latched)
for a topic whose recorded ``offered_qos_profiles`` are all transient-local, and -- when the bag stores none -- for
``/rotor/excitation`` and ``/bearing_id/coefficients``.  A truncated or corrupt bag is played up to the damage, then
the command says where it stopped and exits 2.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys
import time

from ..io.bags import bag_topics, BagError, LATCHED_TOPICS, offered_qos, read_bag
from ..io.messages import msg_class


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser('play', help='replay a bag onto ROS 2 topics (raw bytes, real time or a rate factor)',
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('bag', help='rosbag2 directory (mcap or sqlite3)')
    p.add_argument('--rate', type=float, default=1.0, help='playback speed relative to real time (default 1)')
    p.add_argument('--topics', nargs='+', help='only these topics (default: all)')
    p.add_argument('--wait-for', type=int, default=1, metavar='N',
                   help='wait until each stream topic has N subscribers (default 1; 0 = do not wait)')
    p.add_argument('--wait-topics', nargs='+', default=['/rotor/displacement'],
                   help='topics whose subscribers are awaited (default /rotor/displacement)')
    p.add_argument('--timeout', type=float, default=30.0, help='give up waiting for subscribers after this [s]')
    p.add_argument('--linger', type=float, default=1.0, help='stay up this long after the last message [s]')
    return p


def latched(topic: str, profiles) -> bool:
    """
    Tell whether to replay ``topic`` latched.

    Latched when its recorded publishers all offered TRANSIENT_LOCAL (the bag's ``offered_qos_profiles``), or -- none
    recorded -- when it is one of bearing_id's latched topics.
    """
    if profiles:
        return all(getattr(q.durability, 'name', '') == 'TRANSIENT_LOCAL' for q in profiles)
    return topic in LATCHED_TOPICS


def run(args) -> int:
    # ROS only here: `bearing-id --help` works without it (rclpy is the optional 'ros' dependency)
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from ..nodes.process import StopFlag
    from ..nodes.qos import qos_latched, qos_stream

    if not args.rate > 0:
        print('bearing-id play: --rate must be > 0', file=sys.stderr)
        return 2
    path = Path(args.bag)
    try:
        topics = bag_topics(path)
        offered = offered_qos(path)
    except BagError as exc:
        print(f'bearing-id play: {exc}', file=sys.stderr)
        return 2
    if args.topics:
        missing = [t for t in args.topics if t not in topics]
        if missing:
            print(f'bearing-id play: {path}: topic(s) {missing} not in the bag; it has {sorted(topics)}',
                  file=sys.stderr)
            return 2
        topics = {t: topics[t] for t in args.topics}
    stop = StopFlag().install()
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bearing_id_play')
    pubs = {}
    for t, (mt, _) in topics.items():
        try:
            cls = msg_class(mt)
        except (ImportError, AttributeError, ValueError) as exc:
            print(f'bearing-id play: topic {t}: no rclpy class for {mt} ({exc}); skipped', file=sys.stderr)
            continue
        pubs[t] = node.create_publisher(cls, t, qos_latched() if latched(t, offered.get(t)) else qos_stream())
    code = 0
    n = 0
    try:
        if args.wait_for > 0:
            t_end = time.monotonic() + args.timeout
            waits = [t for t in args.wait_topics if t in pubs]
            while (any(pubs[t].get_subscription_count() < args.wait_for for t in waits)
                   and time.monotonic() < t_end and not stop.event.is_set()):
                time.sleep(0.05)
            short = [t for t in waits if pubs[t].get_subscription_count() < args.wait_for]
            if short:
                print(f'bearing-id play: waited {args.timeout:g} s, topic(s) {short} still have fewer than '
                      f'{args.wait_for} subscriber(s); playing anyway', file=sys.stderr)
        t0_wall = None
        t0_bag = None
        try:
            for topic, _, stamp, data in read_bag(path, list(pubs), raw=True):
                if stop.event.is_set():
                    break
                if t0_wall is None:
                    t0_wall, t0_bag = time.monotonic(), stamp
                due = t0_wall + (stamp - t0_bag) * 1e-9 / args.rate
                delay = due - time.monotonic()
                if delay > 0 and stop.event.wait(delay):
                    break
                pubs[topic].publish(data)
                n += 1
        except BagError as exc:
            print(f'bearing-id play: stopped after {n} message(s): {exc}', file=sys.stderr)
            code = 2
        if not stop.event.is_set():
            stop.event.wait(args.linger)
        print(f'bearing-id play: published {n} message(s) from {path}')
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return code
