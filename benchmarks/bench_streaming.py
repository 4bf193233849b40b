#!/usr/bin/env python
"""Streaming benchmark: 10,240 Hz x 2 channels through sensor_driver -> kf_estimator -> identifier, three processes.

Reports (printed as a table):
* lost blocks: sent by the driver vs received (and sequence gaps) at kf_estimator and identifier, estimates published;
* real-time factor of each node = seconds of data streamed / CPU seconds the node used while streaming (from
  /proc/<pid>/stat; > 1 keeps up, and the machine has 2 cores shared by all three);
* latency from the arrival of the last block of a steady window at the identifier to the coefficients published
  (the identifier measures it; the window closes when the next block shows the speed change or after
  ``segment_timeout``), target <= 0.5 s;
* resident memory (VmRSS and peak VmHWM) of each node, target <= 300 MB.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_streaming.py [--speeds 1200,2400] [--dwell 5]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from bearing_id.demo import Listener, ros_env, start_node, stop_processes  # noqa: E402

CLK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    f = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(f[11]) + int(f[12])) / CLK           # utime + stime


def memory_mb(pid: int) -> tuple[float, float]:
    rss = hwm = float("nan")
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmRSS:"):
            rss = int(line.split()[1]) / 1024
        elif line.startswith("VmHWM:"):
            hwm = int(line.split()[1]) / 1024
    return rss, hwm


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--speeds", default="1200,2400", help="speeds [rpm] (default 1200,2400)")
    ap.add_argument("--dwell", type=float, default=5.0, help="seconds at each speed (default 5)")
    ap.add_argument("--rate", type=float, default=1.0, help="rate factor (default 1 = real time)")
    ap.add_argument("--method", default="physical")
    ap.add_argument("--out", default="out/bench_streaming")
    args = ap.parse_args(argv)
    speeds = [float(s) for s in args.speeds.split(",")]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rec_dir = out / "record"
    if rec_dir.exists():
        import shutil
        shutil.rmtree(rec_dir)
    env = ros_env()
    os.environ.update({k: env[k] for k in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_DOMAIN_ID")})
    from bearing_id.params import load_rig
    rig = load_rig()
    n_runs = len(rig.simulation.runs)
    data_s = n_runs * len(speeds) * args.dwell
    procs = {
        "identifier": start_node("identifier", {"method": args.method, "record_dir": str(rec_dir),
                                                "runs": [r.id for r in rig.simulation.runs],
                                                "diagnostics_period": 0.5}, env, out),
        "kf_estimator": start_node("kf_estimator", {"prebuild_speeds_rpm": speeds, "diagnostics_period": 0.5},
                                   env, out),
        "sensor_driver": start_node("sensor_driver", {"speeds_rpm": speeds, "dwell": args.dwell,
                                                      "rate_factor": args.rate, "wait_for_subscribers": 2,
                                                      "diagnostics_period": 0.5}, env, out),
    }
    listener = Listener()
    cpu0 = {}
    t_pub = None
    try:
        t_end = time.monotonic() + 120 + data_s / args.rate
        while time.monotonic() < t_end:           # wait until the driver publishes, then snapshot CPU
            time.sleep(0.05)
            st = listener.diag.get("sensor_driver: source")
            if st and st[1].startswith("publishing"):
                cpu0 = {n: cpu_seconds(p.pid) for n, p in procs.items()}
                t_pub = time.monotonic()
                break
        if t_pub is None:
            print("driver never started publishing; see logs in", out)
            return 1
        sent = 0
        while time.monotonic() < t_end:
            time.sleep(0.25)
            v = listener.diag_values.get("sensor_driver: source", {})
            sent, total = int(v.get("blocks_sent", 0)), int(v.get("blocks_total", 1))
            if sent >= total:
                break
        mem = {n: memory_mb(p.pid) for n, p in procs.items()}
        time.sleep(1.5)                            # tail: last window closes, final solve, diagnostics
        cpu1 = {n: cpu_seconds(p.pid) for n, p in procs.items()}
        mem = {n: tuple(max(a, b) for a, b in zip(mem[n], memory_mb(p.pid))) for n, p in procs.items()}
        wall = time.monotonic() - t_pub
        dv = dict(listener.diag_values)
        data_s = sent * 1024 / rig.simulation.sample_rate       # includes the speed ramps between steps
    finally:
        codes = stop_processes(procs)
        listener.close()
    kf_in = dv.get("kf_estimator: input /rotor/displacement", {})
    id_in = dv.get("identifier: input /rotor/displacement", {})
    id_est = dv.get("identifier: input /bearing_id/bearing_displacement", {})
    acc = dv.get("identifier: accumulation", {})
    print(f"streaming benchmark: {n_runs} runs x {len(speeds)} speeds x {args.dwell:g} s (+ ramps) = {data_s:g} s of "
          f"data, "
          f"10,240 Hz x 2 channels, 1024-sample blocks, rate x{args.rate:g}, method {args.method}; "
          f"wall {wall:.1f} s (2-core machine)")
    print(f"blocks: driver sent {sent}; kf_estimator received {kf_in.get('blocks')} (gaps "
          f"{kf_in.get('sequence_gaps')}, lost {kf_in.get('lost_blocks')}); identifier received "
          f"{id_in.get('blocks')} measured (lost {id_in.get('lost_blocks')}) and {id_est.get('blocks')} estimated "
          f"(lost {id_est.get('lost_blocks')})")
    print(f"{'node':<14} {'CPU s':>7} {'real-time factor':>17} {'RSS MB':>8} {'peak RSS MB':>12}")
    for n in procs:
        c = cpu1[n] - cpu0[n]
        rtf = data_s / c if c > 0 else float("inf")
        print(f"{n:<14} {c:7.2f} {rtf:17.1f} {mem[n][0]:8.1f} {mem[n][1]:12.1f}")
    print(f"identifier: last solve {acc.get('last_solve_s', '?')} s; latency last block of a window -> coefficients "
          f"published: median {acc.get('median_latency_s', '?')} s, max {acc.get('max_latency_s', '?')} s over the "
          f"windows (target <= 0.5 s); published results "
          f"{acc.get('published_results')}")
    print(f"node exits: {codes}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
