#!/usr/bin/env python
"""
Streaming benchmark: 10,240 Hz x 2 channels through sensor_driver -> kf_estimator -> identifier, three processes.

Reports (printed as a table):
* lost blocks: sent by the driver vs received (and sequence gaps) at kf_estimator and identifier, estimates published;
* real-time factor of each node = seconds of data streamed / CPU seconds the node used while streaming (from
  /proc/<pid>/stat; > 1 keeps up, and the machine has 2 cores shared by all three);
* latency from the arrival of the last block of a steady window at the identifier to the coefficients published
  (the identifier measures it; the window closes when the next block shows the speed change, or is used
  provisionally after ``segment_timeout`` without blocks), and how long after the driver's last block every speed
  is published;
* resident memory (VmRSS and peak VmHWM) of each node, target <= 300 MB.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_streaming.py [--rates 1,20] [--speeds ...] [--dwell 3]

Targets (issue 9): latency <= 0.5 s at 1x and <= 2 s at 20x, 0 blocks lost, bounded RSS.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import sys
import time

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from bearing_id.demo import Listener, ros_env, start_node, stop_processes  # noqa: E402

CLK = os.sysconf('SC_CLK_TCK')


def _domain_ids(n: int) -> list:
    """
    Return ``n`` ROS_DOMAIN_IDs reserved for this process (test/rosutil.py lock files).

    Without test/rosutil.py: [None] for one (ros_env's own), consecutive ids from 10 for more.
    """
    try:
        sys.path.insert(0, str(REPO / 'test'))
        from rosutil import domain_ids
        return domain_ids(n)
    except ImportError:
        return [None] if n == 1 else list(range(10, 10 + n))


def _domain_id() -> int | None:
    """Return a ROS_DOMAIN_ID reserved for this process (test/rosutil.py lock files), or None (ros_env's own)."""
    return _domain_ids(1)[0]


def stat_cpu_seconds(stat: Path) -> float:
    """Return the CPU seconds (utime + stime) of a /proc ``stat`` file: a process's, or one thread's (task/<tid>)."""
    f = stat.read_text().rsplit(')', 1)[1].split()
    return (int(f[11]) + int(f[12])) / CLK


def cpu_seconds(pid: int) -> float:
    return stat_cpu_seconds(Path(f'/proc/{pid}/stat'))


def memory_mb(pid: int) -> tuple[float, float]:
    rss = hwm = float('nan')
    for line in open(f'/proc/{pid}/status'):
        if line.startswith('VmRSS:'):
            rss = int(line.split()[1]) / 1024
        elif line.startswith('VmHWM:'):
            hwm = int(line.split()[1]) / 1024
    return rss, hwm


def run_once(rate: float, speeds, dwell: float, method: str, out: Path) -> dict:
    """One streaming run at ``rate`` x real time; returns the measured figures."""
    out.mkdir(parents=True, exist_ok=True)
    rec_dir = out / 'record'
    if rec_dir.exists():
        import shutil
        shutil.rmtree(rec_dir)
    env = ros_env(_domain_id())
    os.environ.update({k: env[k] for k in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_DOMAIN_ID',
                                           'FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')})
    from bearing_id.config.params import load_rig
    rig = load_rig()
    n_runs = len(rig.simulation.runs)
    data_s = n_runs * len(speeds) * dwell
    procs = {
        'identifier': start_node('identifier', {'method': method, 'record_dir': str(rec_dir),
                                                'runs': [r.id for r in rig.simulation.runs],
                                                'diagnostics_period': 0.5}, env, out),
        'kf_estimator': start_node('kf_estimator', {'prebuild_speeds_rpm': speeds, 'diagnostics_period': 0.5},
                                   env, out),
        'sensor_driver': start_node('sensor_driver', {'speeds_rpm': speeds, 'dwell': dwell,
                                                      'rate_factor': rate, 'wait_for_subscribers': 2,
                                                      'diagnostics_period': 0.5}, env, out),
    }
    listener = Listener()
    cpu0, mem0 = {}, {}
    t_pub = None
    res = {'rate': rate, 'data_s': data_s}
    try:
        t_end = time.monotonic() + 120 + data_s / rate
        while time.monotonic() < t_end:           # wait until the driver publishes, then snapshot CPU
            time.sleep(0.05)
            st = listener.diag.get('sensor_driver: source')
            if st and st[1].startswith('publishing'):
                cpu0 = {n: cpu_seconds(p.pid) for n, p in procs.items()}
                mem0 = {n: memory_mb(p.pid)[0] for n, p in procs.items()}
                t_pub = time.monotonic()
                break
        if t_pub is None:
            raise RuntimeError(f'driver never started publishing; see logs in {out}')
        sent = 0
        mem = {n: (0.0, 0.0) for n in procs}
        while time.monotonic() < t_end:
            time.sleep(0.25)
            mem = {n: tuple(max(a, b) for a, b in zip(mem[n], memory_mb(p.pid))) for n, p in procs.items()}
            v = listener.diag_values.get('sensor_driver: source', {})
            sent, total = int(v.get('blocks_sent', 0)), int(v.get('blocks_total', 1))
            if sent >= total:
                break
        t_sent = time.monotonic()
        while time.monotonic() < t_sent + 60 and len(listener.results) < len(speeds):
            time.sleep(0.1)                        # the identifier catches up: every speed published
        res['results_after_last_block_s'] = time.monotonic() - t_sent
        time.sleep(1.2)                            # fresh diagnostics after the last solve
        cpu1 = {n: cpu_seconds(p.pid) for n, p in procs.items()}
        mem = {n: tuple(max(a, b) for a, b in zip(mem[n], memory_mb(p.pid))) for n, p in procs.items()}
        res['wall_s'] = time.monotonic() - t_pub
        dv = dict(listener.diag_values)
        res['data_s'] = sent * 1024 / rig.simulation.sample_rate       # includes the speed ramps between steps
        res['sent'] = sent
        res['speeds_published'] = len(listener.results)
    finally:
        res['exits'] = stop_processes(procs)
        listener.close()
    res['kf_in'] = dv.get('kf_estimator: input /rotor/displacement', {})
    res['id_in'] = dv.get('identifier: input /rotor/displacement', {})
    res['acc'] = dv.get('identifier: accumulation', {})
    res['nodes'] = {n: {'cpu_s': cpu1[n] - cpu0[n], 'rss0': mem0[n], 'rss': mem[n][0], 'peak': mem[n][1]}
                    for n in procs}
    return res


def report(r: dict, n_speeds: int, method: str) -> None:
    print(f"\n== rate x{r['rate']:g}: {r['data_s']:.1f} s of data (2 runs x {n_speeds} speeds + ramps), 10,240 Hz x 2 "
          f"channels, 1024-sample blocks, method {method}; wall {r['wall_s']:.1f} s (2-core machine)")
    ki, ii = r['kf_in'], r['id_in']
    print(f"blocks: driver sent {r['sent']}; kf_estimator received {ki.get('blocks')} (lost {ki.get('lost_blocks')});"
          f" identifier received {ii.get('blocks')} (lost {ii.get('lost_blocks')})")
    print(f"{'node':<14} {'CPU s':>7} {'real-time factor':>17} {'RSS start MB':>13} {'RSS end MB':>11} "
          f"{'peak RSS MB':>12}")
    for n, v in r['nodes'].items():
        rtf = r['data_s'] / v['cpu_s'] if v['cpu_s'] > 0 else float('inf')
        print(f"{n:<14} {v['cpu_s']:7.2f} {rtf:17.1f} {v['rss0']:13.1f} {v['rss']:11.1f} {v['peak']:12.1f}")
    a = r['acc']
    print(f"identifier: {r['speeds_published']}/{n_speeds} speeds published, all of them "
          f"{r['results_after_last_block_s']:.2f} s after the driver's last block; latency last block of a window -> "
          f"its coefficients published: median {a.get('median_latency_s', '?')} s, max {a.get('max_latency_s', '?')} "
          f"s; last solve {a.get('last_solve_s', '?')} s")
    print(f"node exits: {r['exits']}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--speeds', default='600,1200,1800,2400,3000', help='speeds [rpm] (default 600..3000 by 600)')
    ap.add_argument('--dwell', type=float, default=3.0, help='seconds at each speed (default 3)')
    ap.add_argument('--rates', default='1,20', help='rate factors, one run each (default 1,20)')
    ap.add_argument('--method', default='physical')
    ap.add_argument('--out', default='out/bench_streaming')
    args = ap.parse_args(argv)
    speeds = [float(s) for s in args.speeds.split(',')]
    runs = [run_once(float(x), speeds, args.dwell, args.method, Path(args.out) / f'rate{x}')
            for x in args.rates.split(',')]
    for r in runs:
        report(r, len(speeds), args.method)
    return 0


if __name__ == '__main__':
    sys.exit(main())
