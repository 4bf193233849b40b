"""
Days of operation compressed, watched by the nodes (issue 25's "done when"): the wear alarm against the temperature.

sensor_driver streams the packaged rig's plan (unbalance runs A and B, probes 6x and 6y) for ``--hours`` of stream time
at ``--rate`` times real time, with an operating profile: the oil inlet at ``--mean`` K cycling by ``--amplitude`` K
daily (ISO VG 46, so the true viscosity moves about +-15 % for 3.5 K), and bearing2's clearance growing linearly from
``--onset`` to the end to ``--wear`` times its start (1.0: no wear, the control).  The identifier (default method,
the same oil law) writes its history; kf_estimator runs beside them unless ``--no-kf``.

Afterwards, from the history (the detection the identifier ran live is the same code, `history/trend.py`; the
identifier's log lines ``bearing change:`` are its published alarms): every alarm with its bearing, parameter, onset,
size and 1-sigma; the moment the true clearance change passed twice the fit's clearance 1-sigma; the delay from there
to the wear alarm (issue 25: within 6 hours), the size against the true mean change from the alarm's onset to the
alarm (within 20 %); the viscosity's swing and the compensated ratio's; the wall time and so the rate achieved.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_monitoring.py [--hours 72] [--rate 50] [--onset 36]
      [--wear 1.08] [--dwell S] [--block-size N] [--no-kf]          (the control: --wear 1.0)
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

import argparse  # noqa: E402, I100  (after the thread setting above)
import contextlib  # noqa: E402
import math  # noqa: E402
from pathlib import Path  # noqa: E402
import re  # noqa: E402
import sqlite3  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / 'benchmarks'))

from bearing_id.demo import ros_env, stop_processes  # noqa: E402, I100
from bearing_id.history import HistoryStore, sqlite_url  # noqa: E402
from bearing_id.history.trend import changes, parameter_series  # noqa: E402
from bearing_id.nodes import sensor_driver_core  # noqa: E402
from bench_streaming import _domain_id, cpu_seconds  # noqa: E402
from bench_tracking import start  # noqa: E402

OIL = ['-p', 'oil_viscosities:=[4.6e-05,6.8e-06]', '-p', 'oil_density:=870.0']


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--hours', type=float, default=72.0, help='stream time [h] (default 72)')
    ap.add_argument('--rate', type=float, default=50.0, help='rate factor (default 50)')
    ap.add_argument('--onset', type=float, default=None, help='wear onset [h] (default: half of --hours)')
    ap.add_argument('--wear', type=float, default=1.08, help="bearing2's clearance at the end (default 1.08)")
    ap.add_argument('--mean', type=float, default=318.15, help='oil inlet mean [K] (default 318.15)')
    ap.add_argument('--amplitude', type=float, default=3.5, help='its daily cycle [K] (default 3.5)')
    ap.add_argument('--dwell', type=float, default=None,
                    help="[s] time at each speed of the plan (default: the rig's, 2 s); a plant dwells far longer")
    ap.add_argument('--block-size', type=int, default=None,
                    help="samples per published block (default: sensor_driver's, 1024); the nodes' CPU goes mostly "
                         'per message')
    ap.add_argument('--no-kf', action='store_true', help='without kf_estimator')
    ap.add_argument('--keep', help="keep the nodes' logs, record and history in this directory")
    args = ap.parse_args(argv)
    values = {s.name: s.default for s in sensor_driver_core.SPECS}
    values['dwell'] = args.dwell
    one_pass = sensor_driver_core.load_sources(values)
    plan = one_pass.start(len(one_pass))          # [s] of stream per pass of the plan
    passes = max(1, math.ceil(args.hours * 3600.0 / plan))
    total = passes * plan
    onset = 3600.0 * (args.hours / 2 if args.onset is None else args.onset)
    env = ros_env(_domain_id())
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.keep or tmp)
        out.mkdir(parents=True, exist_ok=True)
        db = out / 'history.db'
        driver = ['-p', f'passes:={passes}', '-p', f'rate_factor:={args.rate}', '-p', 'exit_when_done:=true',
                  '-p', f'oil_temperature_mean:={args.mean}', '-p', f'oil_temperature_amplitude:={args.amplitude}',
                  '-p', 'wait_for_subscribers:=' + ('1' if args.no_kf else '2'), *OIL]
        if args.dwell is not None:
            driver += ['-p', f'dwell:={args.dwell}']
        if args.block_size is not None:
            driver += ['-p', f'block_size:={args.block_size}']
        if args.wear != 1.0:
            driver += ['-p', 'wear_bearing:=bearing2', '-p', f'wear_onset:={onset}', '-p', f'wear_end:={total}',
                       '-p', f'wear_clearance:={args.wear}']
        procs = {'identifier': start('identifier', ['-p', f'record_dir:={out / "record"}', '-p', f'history:={db}',
                                                    *OIL], env, out)}
        if not args.no_kf:
            procs['kf_estimator'] = start('kf_estimator', [], env, out)
        procs['sensor_driver'] = start('sensor_driver', driver, env, out)
        t0 = time.monotonic()
        cpu: dict = {}
        try:
            t_end = t0 + 300 + 3 * total / args.rate
            while procs['sensor_driver'].poll() is None and time.monotonic() < t_end:
                _sample_cpu(procs, cpu)
                time.sleep(5.0)
            streamed = time.monotonic() - t0
            # the run ends when the identifier has solved on the last pass's data (or has stopped progressing for a
            # minute): what it had not processed by then is not counted as achieved
            last, still = -1.0, time.monotonic()
            while time.monotonic() - still < 60.0:
                covered = _data_covered(db)
                if covered >= total - plan:
                    break
                if covered > last:
                    last, still = covered, time.monotonic()
                _sample_cpu(procs, cpu)
                time.sleep(2.0)
        finally:
            _sample_cpu(procs, cpu)
            codes = stop_processes(procs)
        wall = time.monotonic() - t0
        covered = _data_covered(db)
        published = [ln.split('bearing change: ', 1)[1].strip() for ln in
                     (out / 'identifier.log').read_text(errors='replace').splitlines() if 'bearing change: ' in ln]
        late = [ln for ln in (out / 'sensor_driver.log').read_text(errors='replace').splitlines() if 'late' in ln]
        gaps = {node: _gaps_logged(out / f'{node}.log') for node in ('identifier', 'kf_estimator')}
        with HistoryStore(sqlite_url(db)) as store:
            machines = store.machines()
            series = parameter_series(store, machines[0].machine_id) if machines else []
    found = changes(series, arl0=1e4, delta=2.0, n_reference=10)
    t_first = min((s.t[0] for s in series), default=0.0)
    print(f'{total / 3600:.1f} h of stream ({passes} passes of {plan:.1f} s) published in {streamed / 60:.1f} min '
          f'({total / streamed:.1f}x, asked {args.rate:g}x); the identifier had solved on {covered / 3600:.2f} h of '
          f'it after {wall / 60:.1f} min: {covered / wall:.1f}x real time end to end; node exits {codes}')
    print(f"sensor_driver: {late[-1] if late else 'no report'}; sequence gaps on /rotor/displacement logged by "
          + ', '.join(f'{node} {n} ({lost} blocks)' for node, (n, lost) in gaps.items())
          + ' (at most one line per 2 s: lower bounds; a gap restarts the windows there)')
    print('CPU per hour of stream (user + system, sampled every 2-5 s): '
          + ', '.join(f'{name} {3600.0 * sec / total:.1f} s' for name, sec in cpu.items()))
    by = {(s.bearing, s.name): s for s in series}
    for key in sorted(by):
        s = by[key]
        ok = s.sigma <= 100.0 * np.median(s.sigma)     # a first solve before every speed is in: prior-dominated
        v = s.value[ok]
        print(f'  {key[0]}.{key[1]}: {s.t.size} independent points, value {np.min(v):.4g}..{np.max(v):.4g}'
              f' (swing {100 * np.ptp(v) / np.mean(v):.2f} %), median 1-sigma {np.median(s.sigma):.3g}'
              + (f'; {np.sum(~ok)} point(s) with a 1-sigma over 100x the median left out of the range'
                 if not ok.all() else ''))
    print(f'alarms (history, ARL0 1e4 points per series): {len(found)}; published by the node: {len(published)}')
    for c in found:
        print(f'  {c.sentence()}  [onset {(c.alarm.onset_time - t_first) / 3600:.2f} h, alarm '
              f'{(c.alarm.time - t_first) / 3600:.2f} h of stream]')
    clear = by.get(('bearing2', 'clearance'))
    if args.wear != 1.0 and clear is not None:
        c0 = float(np.mean(clear.value[:10]))
        sig = float(np.median(clear.sigma))
        slope = c0 * (args.wear - 1.0) / (total - onset)          # m per s of stream
        t2 = onset + 2 * sig / slope
        wear = [c for c in found if (c.bearing, c.name) == ('bearing2', 'clearance')]
        print(f'true change passes 2 sigma ({2 * sig:.3g} m) at {t2 / 3600:.2f} h of stream')
        if wear:
            a = wear[0].alarm
            ta, to = a.time - t_first, a.onset_time - t_first
            true_mean = slope * (0.5 * (max(to, onset) + ta) - onset) if ta > onset else 0.0
            # the alarm point's data end at ta and span about one pass: the truth's mean change over that pass
            true_now = slope * max(0.0, ta - 0.5 * plan - onset)
            print(f'wear alarm: bearing2 clearance {(ta - t2) / 3600:+.2f} h after that (target <= 6 h); mean size '
                  f'{a.size:.3g} +- {a.size_sigma:.2g} m against the true mean change {true_mean:.3g} m over its '
                  f'onset..alarm ({100 * (a.size / true_mean - 1) if true_mean else math.nan:+.0f} %); the change '
                  f"at the alarm {a.latest:.3g} +- {a.latest_sigma:.2g} m against the truth over that point's data "
                  f'{true_now:.3g} m ({100 * (a.latest / true_now - 1) if true_now else math.nan:+.0f} %; '
                  'target 20 %)')
        else:
            print('wear alarm: none on bearing2 clearance')
    return 0


def _data_covered(db: Path) -> float:
    """Return [s] how much of the stream the history's solves cover: the latest data end after the first start."""
    if not db.exists():
        return 0.0
    try:
        with contextlib.closing(sqlite3.connect(f'file:{db}?mode=ro', uri=True, timeout=5.0)) as con:
            t0, t1 = con.execute('SELECT MIN(t_start), MAX(t_end) FROM identifications').fetchone()
    except sqlite3.Error:            # not created yet, or busy: no progress seen this time
        return 0.0
    return 0.0 if t0 is None else float(t1 - t0)


def _sample_cpu(procs: dict, cpu: dict) -> None:
    """Update ``cpu`` [s] (user + system) of each running process in ``procs`` from /proc (Linux; else nothing)."""
    for name, p in procs.items():
        try:
            cpu[name] = cpu_seconds(p.pid)
        except (OSError, IndexError):            # exited (or not Linux): its last sample stands
            continue


def _gaps_logged(log: Path) -> tuple[int, int]:
    """Return (sequence-gap lines, blocks they report lost) in a node's log (its problem lines are throttled)."""
    text = log.read_text(errors='replace') if log.exists() else ''
    lost = [int(m) for m in re.findall(r'sequence gap: (\d+) block\(s\) lost', text)]
    return len(lost), sum(lost)


if __name__ == '__main__':
    sys.exit(main())
