"""``bearing-id record``: record ROS 2 topics into a rosbag2 bag (mcap or sqlite3), since ``ros2 bag`` is not on PyPI.

Subscribes to each topic with the nodes' QoS (:mod:`bearing_id.nodes.common`), takes the raw serialized bytes (no
decode, no re-encode) and writes them with :func:`bearing_id.io.bags.write_bag` when it stops: on SIGINT/SIGTERM,
after ``--duration`` seconds, or after ``--idle`` seconds without a message (once something arrived).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

DEFAULT_TOPICS = {
    "/rotor/displacement": "bearing_id_msgs/msg/DisplacementBlock",
    "/rotor/speed": "bearing_id_msgs/msg/RotorSpeed",
    "/rotor/excitation": "bearing_id_msgs/msg/Excitation",
    "/bearing_id/bearing_displacement": "bearing_id_msgs/msg/DisplacementBlock",
    "/bearing_id/innovation": "bearing_id_msgs/msg/DisplacementBlock",
    "/bearing_id/coefficients": "bearing_id_msgs/msg/BearingCoefficients",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
}


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("record", help="record ROS 2 topics into a bag (raw bytes; mcap or sqlite3)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("bag", help="output bag directory (must not exist unless --overwrite)")
    p.add_argument("--topics", nargs="+", metavar="TOPIC[:TYPE]",
                   help="topics to record (default: all bearing_id topics); TYPE like pkg/msg/Name for others")
    p.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    p.add_argument("--duration", type=float, help="stop after this many seconds")
    p.add_argument("--idle", type=float, help="stop after this many seconds without a message (once one arrived)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing bag directory")
    return p


def parse_topics(items) -> dict:
    if not items:
        return dict(DEFAULT_TOPICS)
    out = {}
    for it in items:
        topic, _, typ = it.partition(":")
        typ = typ or DEFAULT_TOPICS.get(topic)
        if not typ:
            raise ValueError(f"--topics: give the type of {topic} as {topic}:pkg/msg/Name")
        out[topic] = typ
    return out


def run(args) -> int:
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from ..io.bags import BagError, write_bag
    from ..nodes.common import StopFlag, qos_latched, qos_stream
    from .play import LATCHED, msg_class
    try:
        topics = parse_topics(args.topics)
    except ValueError as exc:
        print(f"bearing-id record: {exc}", file=sys.stderr)
        return 2
    path = Path(args.bag)
    if path.exists() and not args.overwrite:
        print(f"bearing-id record: {path} exists (use --overwrite)", file=sys.stderr)
        return 2
    stop = StopFlag().install()
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bearing_id_record")
    got = []
    last = [None]

    def cb_for(topic, typ):
        def cb(data):
            now = node.get_clock().now().nanoseconds
            got.append((topic, typ, now, bytes(data)))
            last[0] = time.monotonic()
        return cb

    for topic, typ in topics.items():
        qos = qos_latched() if topic in LATCHED else (10 if topic == "/diagnostics" else qos_stream())
        node.create_subscription(msg_class(typ), topic, cb_for(topic, typ), qos, raw=True)
    t0 = time.monotonic()
    from rclpy.executors import SingleThreadedExecutor
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    try:
        while not stop.event.is_set():
            ex.spin_once(timeout_sec=0.05)
            now = time.monotonic()
            if args.duration is not None and now - t0 >= args.duration:
                break
            if args.idle is not None and last[0] is not None and now - last[0] >= args.idle:
                break
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    got.sort(key=lambda m: m[2])
    try:
        write_bag(path, got, storage=args.storage, overwrite=args.overwrite)
    except BagError as exc:
        print(f"bearing-id record: {exc}", file=sys.stderr)
        return 2
    counts = {}
    for t, *_ in got:
        counts[t] = counts.get(t, 0) + 1
    print(f"bearing-id record: wrote {len(got)} message(s) to {path} ({args.storage}): {counts}")
    return 0
