#!/usr/bin/env python
"""
Discovery time on this machine: a new node's time to match a node already up, with and without the shipped profile.

The profile is ``params/fastdds_localhost.xml``; issue 23 asks discovery with it within 0.5 s of the default.  Every
process runs with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (the project's rule) on this benchmark's own domain id,
one trial after the other.  A trial starts one process with a reliable ``std_msgs/String`` publisher, waits
``--lead`` s and starts a subscriber process, which measures the time from its node's creation to its first matched
publisher; then the same with the subscriber first (a publisher joining a subscriber already up: the sensor_driver
waiting for its subscribers).  Printed per variant and order: min / median / max over ``--trials``.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_discovery.py [--trials 8] [--lead 2]
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import statistics
import subprocess
import sys
import time

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / 'benchmarks'))

from bearing_id.demo import ros_env, stop_processes  # noqa: E402, I100
from bench_streaming import _domain_id  # noqa: E402

TOPIC = 'bench_discovery'
WAIT = 15.0          # [s] a trial that has not matched by then counts as this long
MATCH = 'matched after'  # the joining child's line: MATCH <seconds>


def child(role: str) -> int:
    """Run one side: ``pub`` publishes at 50 Hz; ``sub`` listens.  The joining side prints its time to a match [s]."""
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    rclpy.init()
    node = rclpy.create_node(f'bench_discovery_{role}')
    t0 = time.monotonic()
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    if role == 'pub':
        ep = node.create_publisher(String, TOPIC, qos)
        count = ep.get_subscription_count
        node.create_timer(0.02, lambda: ep.publish(String(data='x')))
    else:
        ep = node.create_subscription(String, TOPIC, lambda m: None, qos)
        count = ep.get_publisher_count
    joining = os.environ.get('BENCH_DISCOVERY_JOINING') == '1'
    try:
        while rclpy.ok():
            rclpy.spin_once(node, timeout_sec=0.005)
            waited = time.monotonic() - t0
            if joining and (count() > 0 or waited > WAIT):
                print(f'{MATCH} {min(waited, WAIT):.4f}', flush=True)
                return 0
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def trial(env: dict, first: str, lead: float) -> float:
    """Return the joining side's time to its first match [s] (``first``: the role started ``lead`` s before)."""
    second = 'sub' if first == 'pub' else 'pub'
    cmd = [sys.executable, str(Path(__file__).resolve()), '--child']
    up = subprocess.Popen(cmd + [first], env={**env, 'BENCH_DISCOVERY_JOINING': '0'}, stdout=subprocess.DEVNULL,
                          stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        time.sleep(lead)
        out = subprocess.run(cmd + [second], env={**env, 'BENCH_DISCOVERY_JOINING': '1'}, capture_output=True,
                             text=True, timeout=WAIT + 30)
    finally:
        stop_processes({first: up}, timeout=10.0)
    # Fast DDS prints its own errors on stdout too (e.g. a shared-memory port another process holds)
    lines = [ln[len(MATCH):] for ln in out.stdout.splitlines() if ln.startswith(MATCH + ' ')]
    if not lines:
        raise RuntimeError(f'the joining {second} printed no match time: {out.stdout[-500:]!r} {out.stderr[-500:]!r}')
    return float(lines[0])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--trials', type=int, default=8, help='trials per variant and order (default 8)')
    ap.add_argument('--lead', type=float, default=2.0, help='[s] the first process runs this long alone (default 2)')
    ap.add_argument('--profile', help="also time this Fast DDS profile (XML), e.g. a plant's own")
    ap.add_argument('--child', choices=('pub', 'sub'), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        return child(args.child)
    base = ros_env(_domain_id())
    variants = {'shipped profile': base,
                'no profile': {k: v for k, v in base.items()
                               if k not in ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')}}
    if args.profile:
        path = str(Path(args.profile).resolve())
        variants['--profile'] = {**base, 'FASTRTPS_DEFAULT_PROFILES_FILE': path, 'FASTDDS_DEFAULT_PROFILES_FILE': path}
    print(f'time to the first match of a joining node [s], {args.trials} trials, lead {args.lead:g} s, load '
          f'{os.getloadavg()[0]:.2f}')
    print(f"{'variant':<18} {'joining':<28} {'min':>7} {'median':>7} {'mean':>7} {'max':>7} {'> 1 s':>6}")
    medians, means = {}, {}
    for first in ('pub', 'sub'):
        for name, env in variants.items():
            t = [trial(env, first, args.lead) for _ in range(args.trials)]
            medians[name, first] = statistics.median(t)
            means[name, first] = statistics.fmean(t)
            joining = 'subscriber (publisher up)' if first == 'pub' else 'publisher (subscriber up)'
            print(f'{name:<18} {joining:<28} {min(t):7.3f} {statistics.median(t):7.3f} {statistics.fmean(t):7.3f} '
                  f'{max(t):7.3f} {sum(x > 1.0 for x in t):6d}', flush=True)
    for first in ('pub', 'sub'):
        gap = medians['shipped profile', first] - medians['no profile', first]
        mgap = means['shipped profile', first] - means['no profile', first]
        print(f'{first} first: median gap {gap:+.3f} s, mean gap {mgap:+.3f} s (issue 23: within 0.5 s)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
