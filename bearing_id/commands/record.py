"""
``bearing-id record``: record ROS 2 topics into a rosbag2 bag (mcap or sqlite3), since ``ros2 bag`` is not on PyPI.

Subscribes to each topic with the nodes' QoS (:mod:`bearing_id.nodes.qos`; latched topics as transient-local, so a
message published before the recorder started is still recorded), takes the raw serialized bytes (no decode, no
re-encode) and writes each message as it arrives (:class:`bearing_id.io.bags.BagWriter`).  It stops on SIGINT/SIGTERM,
after ``--duration`` seconds, or after ``--idle`` seconds without a message (once something arrived), and then
finishes the bag (index and ``metadata.yaml``).

Surviving a kill: everything received is made durable at least every ``--flush`` seconds (default 1: the mcap chunk is
closed and written followed by a footer, sqlite3 commits, and ``metadata.yaml`` is replaced by one describing what is
now on disk, all fsync'ed), so ``kill -9`` or a power cut loses at most the last second.  The bag a ``kill -9`` leaves
opens as it is in stock readers (rosbags' ``Reader``, :func:`bearing_id.io.bags.read_bag`): its ``metadata.yaml`` is
marked unfinished in ``custom_data``, and its mcap file has no summary, so readers scan it.  Only a kill while a flush
is writing (microseconds for mcap, the milliseconds of a sqlite3 commit) leaves a bag they refuse or whose metadata.yaml
is one flush behind.  ``bearing-id record --recover BAG`` turns any unfinished bag (also one without ``metadata.yaml``,
or one a power cut left) into a complete one in place: every complete message, an mcap summary, the metadata of a
finished bag (the unfinished original is kept as ``BAG.unfinished``).

QoS: each topic's ``offered_qos_profiles`` are the QoS its publishers really offer (``get_publishers_info_by_topic``
when its first message arrives), as ``ros2 bag record`` stores them, so ``ros2 bag play`` (and ``bearing-id play``)
replays a latched topic (``/rotor/excitation``: RELIABLE + TRANSIENT_LOCAL) as latched; when no publisher can be
asked, the bearing_id nodes' QoS for that topic (:func:`bearing_id.io.bags.default_qos`).
"""
from __future__ import annotations

import argparse
import collections
import hashlib
from pathlib import Path
import sys
import time

from ..io.bags import BagError, BagWriter, default_qos, LATCHED_TOPICS, qos_from_rclpy, recover_bag, typestore
from ..io.messages import msg_class

DEFAULT_TOPICS = {
    '/rotor/displacement': 'bearing_id_msgs/msg/DisplacementBlock',
    '/rotor/speed': 'bearing_id_msgs/msg/RotorSpeed',
    '/rotor/excitation': 'bearing_id_msgs/msg/Excitation',
    '/bearing_id/bearing_displacement': 'bearing_id_msgs/msg/DisplacementBlock',
    '/bearing_id/innovation': 'bearing_id_msgs/msg/DisplacementBlock',
    '/bearing_id/coefficients': 'bearing_id_msgs/msg/BearingCoefficients',
    '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
}


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser('record', help='record ROS 2 topics into a bag (raw bytes; mcap or sqlite3; survives kill -9)',
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('bag', help='output bag directory (must not exist unless --overwrite); with --recover the '
                               'unfinished bag to repair')
    p.add_argument('--topics', nargs='+', metavar='TOPIC[:TYPE]',
                   help='topics to record (default: all bearing_id topics); TYPE like pkg/msg/Name for others')
    p.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap')
    p.add_argument('--duration', type=float, help='stop after this many seconds')
    p.add_argument('--idle', type=float, help='stop after this many seconds without a message (once one arrived)')
    p.add_argument('--flush', type=float, default=1.0, metavar='SECONDS',
                   help='make what was received durable at least this often (default 1 s: a kill -9 loses at most '
                        'that much)')
    p.add_argument('--overwrite', action='store_true', help='replace an existing bag directory')
    p.add_argument('--recover', action='store_true',
                   help='do not record: turn the unfinished bag BAG (recorder killed) into a complete one, keeping '
                        'the original as BAG.unfinished')
    return p


def parse_topics(items) -> dict:
    if not items:
        return dict(DEFAULT_TOPICS)
    out = {}
    for it in items:
        topic, _, typ = it.partition(':')
        typ = typ or DEFAULT_TOPICS.get(topic)
        if not typ:
            raise ValueError(f'--topics: give the type of {topic} as {topic}:pkg/msg/Name')
        out[topic] = typ
    return out


def recover(path: Path) -> int:
    try:
        out, sv, backup = recover_bag(path)
    except BagError as exc:
        print(f'bearing-id record --recover: {exc}', file=sys.stderr)
        return 2
    counts = {t.topic: t.count for t in sv.topics.values()}
    print(f'bearing-id record --recover: wrote {sv.message_count} message(s) to {out} ({sv.storage}): {counts}; '
          f'read {sv.valid_bytes} of {sv.total_bytes} bytes of {sv.storage_file.name} ({sv.stopped}); the unfinished '
          f'original is kept as {backup}')
    return 0


def publisher_qos(node, topic: str) -> list:
    """Return the QoS every publisher of ``topic`` offers, as rosbags ``Qos`` (empty when none is known)."""
    try:
        return [qos_from_rclpy(i.qos_profile) for i in node.get_publishers_info_by_topic(topic)]
    except Exception:  # pragma: no cover - graph query failed; the caller falls back to the nodes' QoS
        return []


def run(args) -> int:
    path = Path(args.bag)
    if args.recover:
        return recover(path)
    # ROS only here: `--recover` and `--help` work without it (rclpy is the optional 'ros' dependency)
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from ..nodes.process import StopFlag
    from ..nodes.qos import qos_stream, subscribe_latched

    try:
        topics = parse_topics(args.topics)
    except ValueError as exc:
        print(f'bearing-id record: {exc}', file=sys.stderr)
        return 2
    if not args.flush > 0:
        print('bearing-id record: --flush must be > 0 s', file=sys.stderr)
        return 2
    if path.exists() and not args.overwrite:
        print(f'bearing-id record: {path} exists (use --overwrite)', file=sys.stderr)
        return 2
    unknown = [f'{t} ({ty})' for t, ty in topics.items() if ty not in typestore().types]
    if unknown:
        print(f"bearing-id record: unknown message type(s): {', '.join(unknown)}", file=sys.stderr)
        return 2
    classes = {}
    for topic, typ in topics.items():
        try:
            classes[topic] = msg_class(typ)
        except (ImportError, AttributeError, ValueError) as exc:
            print(f'bearing-id record: no rclpy class for {typ} ({exc})', file=sys.stderr)
            return 2
    try:
        writer = BagWriter(path, args.storage, overwrite=args.overwrite, flush_period=args.flush)
    except BagError as exc:
        print(f'bearing-id record: {exc}', file=sys.stderr)
        return 2
    stop = StopFlag().install()
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bearing_id_record')
    last = [None]
    failure = []

    seen = {t: collections.deque(maxlen=64) for t in topics if t in LATCHED_TOPICS}   # latched: heard twice (below)

    def cb_for(topic, typ):
        def cb(data):
            if topic in seen:
                key = hashlib.sha1(bytes(data)).digest()
                if key in seen[topic]:
                    return                     # the second copy of a transient-local publisher's message
                seen[topic].append(key)
            try:
                if topic not in writer.counts:
                    writer.add_connection(topic, typ, publisher_qos(node, topic) or default_qos(topic))
                writer.write(topic, typ, node.get_clock().now().nanoseconds, bytes(data))
            except (BagError, OSError) as exc:      # disk full, ...: stop, keep what is on disk
                failure.append(exc)
                stop.event.set()
            last[0] = time.monotonic()
        return cb

    for topic, typ in topics.items():
        if topic in LATCHED_TOPICS:    # transient-local AND volatile subscriptions: a plain `ros2 bag play` is heard
            subscribe_latched(node, classes[topic], topic, cb_for(topic, typ), raw=True)
            continue
        qos = 10 if topic == '/diagnostics' else qos_stream()
        node.create_subscription(classes[topic], topic, cb_for(topic, typ), qos, raw=True)
    t0 = time.monotonic()
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    try:
        while not stop.event.is_set():
            ex.spin_once(timeout_sec=0.05)
            writer.maybe_flush()
            now = time.monotonic()
            if args.duration is not None and now - t0 >= args.duration:
                break
            if args.idle is not None and last[0] is not None and now - last[0] >= args.idle:
                break
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    if failure:
        writer.abort()
        print(f'bearing-id record: stopped: {failure[0]}; {writer.message_count} message(s) are in {path}, '
              f'`bearing-id record --recover {path}` finishes it', file=sys.stderr)
        return 2
    try:
        writer.close()
    except BagError as exc:
        print(f'bearing-id record: {exc}', file=sys.stderr)
        return 2
    print(f'bearing-id record: wrote {writer.message_count} message(s) to {path} ({args.storage}): '
          f'{dict(writer.counts)}')
    return 0
