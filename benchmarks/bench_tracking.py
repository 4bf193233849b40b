"""
A machine that wears while the three nodes watch it (issue 23: the identified coefficients follow a change).

sensor_driver streams the packaged rig's plan ``--passes`` times (each pass its own noise) with the true bearing
clearances x``--clearance`` from the middle of the stream on (``truth_change_after``); kf_estimator and the identifier
(default method) run beside it, three processes on localhost-only DDS.  Every result the identifier recorded is then
compared with both machines: the largest |error| / stated 1-sigma over its determined coefficients against the
original and against the worn one, and whether it was a misfit (nothing determined).  Printed per result, then the
summary: before the change every determined result should be within ~3 sigma of the original, after it within
~3 sigma of the worn machine, and results whose data straddle the change are misfits (not determined).

The record is read every 20 s while the stream runs, so results a long run's compaction drops are still counted.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_tracking.py [--passes 6] [--speeds 1500,2400] [--dwell 2]
      [--rate 2] [--clearance 1.1]          (2 hours: --passes 164 with the packaged speeds and --rate 1)
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

import argparse  # noqa: E402, I100  (after the thread setting above)
import json  # noqa: E402
from pathlib import Path  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / 'benchmarks'))

from bearing_id.config.params import load_rig  # noqa: E402, I100
from bearing_id.demo import ros_env, stop_processes  # noqa: E402
from bearing_id.io.record import decode, RECORD_NAME  # noqa: E402
from bearing_id.nodes import sensor_driver_core  # noqa: E402
from bearing_id.simulation import rig as R  # noqa: E402
from bench_streaming import _domain_id  # noqa: E402


def start(name: str, args: list, env: dict, out: Path) -> subprocess.Popen:
    """Start ``bearing_id.nodes.<name>`` with ``--ros-args`` ``args``, its log in ``out``."""
    return subprocess.Popen([sys.executable, '-m', f'bearing_id.nodes.{name}', '--ros-args', *args], env=env,
                            stdout=open(out / f'{name}.log', 'w'), stderr=subprocess.STDOUT, start_new_session=True)


def collect(record_dir: Path, seen: dict) -> None:
    """
    Add the record's results to ``seen`` (keyed by speed, data span and values): compaction drops old ones later.

    Read-only while the identifier writes (a ``Record`` would repair a line being written): a line that does not
    parse (the one being written) is skipped and read on the next pass.
    """
    path = record_dir / RECORD_NAME
    if not path.exists():
        return
    with open(path, encoding='utf-8', errors='replace') as fh:
        for line in fh:
            try:
                d = json.loads(line)
            except json.JSONDecodeError:
                continue
            if isinstance(d, dict) and d.get('type') == 'result':
                r = decode(d)['result']      # a global fit re-solves a speed on the same data: each result kept
                seen.setdefault((r['speed_rpm'], tuple(r['data_span']), json.dumps(r['bearings'], sort_keys=True)), r)


def max_z(result: dict, truth) -> float:
    """Largest |value - truth| / 1-sigma over a recorded result's determined coefficients (NaN: none determined)."""
    z = []
    for b in result['bearings']:
        t = truth(result['speed_rad_s'])[b['node']]
        for k, sym in ((0, 'K'), (1, 'C')):
            det = np.array(b['determined'][sym], bool)
            v, s = (np.array([[np.nan if x is None else x for x in row] for row in b[key]], float)
                    for key in (sym, sym + '_std'))
            z += list(np.abs((v - t[k]) / s)[det])
    return max(z) if z else float('nan')


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--passes', type=int, default=6)
    ap.add_argument('--speeds', default='1500,2400', help='rpm, comma-separated (default 1500,2400)')
    ap.add_argument('--dwell', type=float, default=2.0, help='s at each speed (default 2)')
    ap.add_argument('--rate', type=float, default=2.0, help='rate factor (default 2)')
    ap.add_argument('--clearance', type=float, default=1.1, help='true clearance factor after the change (1.1)')
    args = ap.parse_args(argv)
    speeds = [float(s) for s in args.speeds.split(',')]
    rig = load_rig()
    values = {s.name: s.default for s in sensor_driver_core.SPECS}
    values.update(speeds_rpm=speeds, dwell=args.dwell, passes=args.passes)
    sources = sensor_driver_core.load_sources(values)
    change = sources.start(len(rig.simulation.runs) * (args.passes // 2))
    total = sources.start(len(sources))
    env = ros_env(_domain_id())
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        speeds_arg = '[' + ','.join(f'{s:g}.0' if float(s).is_integer() else f'{s:g}' for s in speeds) + ']'
        procs = {'identifier': start('identifier', ['-p', f'record_dir:={out / "record"}'], env, out),
                 'kf_estimator': start('kf_estimator', [], env, out),
                 'sensor_driver': start('sensor_driver', [
                     '-p', f'speeds_rpm:={speeds_arg}', '-p', f'dwell:={args.dwell}', '-p', f'passes:={args.passes}',
                     '-p', f'truth_change_after:={change}', '-p', f'truth_change_clearance:={args.clearance}',
                     '-p', f'rate_factor:={args.rate}', '-p', 'wait_for_subscribers:=2',
                     '-p', 'exit_when_done:=true'], env, out)}
        t0 = time.monotonic()
        seen: dict = {}          # every result the record held at some time (the identifier compacts it on long runs)
        try:
            t_end = t0 + 120 + 2 * total / args.rate
            while procs['sensor_driver'].poll() is None and time.monotonic() < t_end:
                time.sleep(20.0)
                collect(out / 'record', seen)
            time.sleep(8.0)                     # the identifier's last solves
        finally:
            codes = stop_processes(procs)
        wall = time.monotonic() - t0
        collect(out / 'record', seen)
        results = sorted(seen.values(), key=lambda r: (r['data_span'][1], r['speed_rpm']))
    old, worn = R.truth_bearing_fn(rig), R.changed_truth(rig, clearance=args.clearance)
    t_start = min(r['data_span'][0] for r in results) if results else 0.0
    print(f'{total:.1f} s of stream in {wall:.1f} s; the clearance x{args.clearance:g} from {change:.1f} s of stream; '
          f'node exits {codes}')
    print(' speed [rpm]   data [s of stream]   max|z| original   max|z| worn   misfit')
    rows = []
    for r in results:
        a, b = (t - t_start for t in r['data_span'])
        zo, zw = max_z(r, old), max_z(r, worn)
        rows.append((b <= change, a >= change, zo, zw, bool(r['misfit'])))
        print(f"{r['speed_rpm']:11.0f}   {a:7.1f} - {b:7.1f}   {zo:15.1f}   {zw:11.1f}   {r['misfit']}")
    before = [zo for end, _, zo, _, m in rows if end and not m]
    after = [zw for _, start_, _, zw, m in rows if start_ and not m]
    mixed = [m for end, start_, _, _, m in rows if not end and not start_]
    print(f'before the change: {len(before)} determined result(s), max|z| against the original machine '
          f'{max(before, default=float("nan")):.1f}')
    print(f'after the change:  {len(after)} determined result(s), max|z| against the worn machine '
          f'{max(after, default=float("nan")):.1f}')
    print(f'data across the change: {len(mixed)} result(s), {sum(mixed)} of them misfits (nothing determined)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
