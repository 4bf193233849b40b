"""
Time ``bearing-id diagnose`` and ``bearing-id report`` as processes: min / median wall and CPU time over repeats.

Cases (each a fresh process, as a user runs it):

* ``diagnose``: the demo recordings (``bearing-id simulate`` of params/rig.yaml: runs A and B, 9 speeds, 2 s dwells,
  ramps; written to ``--data`` once), with the noise-floor check (default) and with ``--no-noise-floor``;
* ``diagnose --report DIR`` on the same recordings (the page with the before / after, every figure as PNG);
* ``report``: ``bearing-id report bags/unbalance_ab_sweep`` (the demo recording's page), and the plant-like example
  (``bearing-id simulate --params params/examples/plant_like.yaml``: 33 elements, a pedestal, a seal, +-45 deg probe
  pairs at three stations, runs A, F13x, F13y, F21x, F21y x 6 speeds; written to ``--plant-data`` once).

CPU time is the process' own plus its children's (the report renders figures in worker processes).  The machine
is shared: the load average before and after is printed beside the numbers; compare cases within one run.
Targets (issues 13, 14): diagnose <= 1.5 s without the report, the report page <= 10 s.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_diagnose_report.py [--repeats 5] [--cases diagnose,report]
"""
import argparse
import os
from pathlib import Path
import resource
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).with_name('bearing-id')


def _cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_timed(argv) -> tuple[float, float]:
    """Return (wall s, CPU s) of one process (CPU: its own and its waited-for children's)."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS='1')
    c0, t0 = _cpu_children(), time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, env=env, cwd=ROOT)
    return time.perf_counter() - t0, _cpu_children() - c0


def demo_recordings(data: Path) -> list[str]:
    files = [data / 'run_A.npz', data / 'run_B.npz']
    if not all(f.exists() for f in files):
        subprocess.run([str(BIN), 'simulate', '--out', str(data)], check=True, stdout=subprocess.DEVNULL,
                       env=dict(os.environ, OPENBLAS_NUM_THREADS='1'), cwd=ROOT)
    return [str(f) for f in files]


def plant_recordings(data: Path) -> list[str]:
    runs = ('A', 'F13x', 'F13y', 'F21x', 'F21y')
    files = [data / f'run_{r}.npz' for r in runs]
    if not all(f.exists() for f in files):
        subprocess.run([str(BIN), 'simulate', '--params', str(PLANT), '--out', str(data)], check=True,
                       stdout=subprocess.DEVNULL, env=dict(os.environ, OPENBLAS_NUM_THREADS='1'), cwd=ROOT)
    return [str(f) for f in files]


PLANT = ROOT / 'params' / 'examples' / 'plant_like.yaml'
TARGETS = {'diagnose (demo, 2 runs x 9 speeds)': 1.5, 'report bags/unbalance_ab_sweep': 10.0,
           'report plant-like example': 10.0}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--repeats', type=int, default=5)
    ap.add_argument('--data', default=str(ROOT / 'out' / 'bench_data' / 'demo_sim'),
                    help='where the demo recordings are (simulated once if missing)')
    ap.add_argument('--plant-data', default=str(ROOT / 'out' / 'bench_data' / 'plant_like'),
                    help='where the plant-like recordings are (simulated once if missing)')
    ap.add_argument('--cases', default='diagnose,report', help='comma list of: diagnose, report')
    args = ap.parse_args(argv)
    subprocess.run([sys.executable, '-m', 'compileall', '-q', str(ROOT / 'bearing_id')], check=False,
                   stdout=subprocess.DEVNULL)        # bytecode as an installed package has it (see benchlib)
    cases = set(args.cases.split(','))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        jobs = []
        if 'diagnose' in cases:
            files = demo_recordings(Path(args.data))
            jobs += [('diagnose (demo, 2 runs x 9 speeds)', [str(BIN), 'diagnose', *files]),
                     ('diagnose --no-noise-floor', [str(BIN), 'diagnose', *files, '--no-noise-floor']),
                     ('diagnose --report', [str(BIN), 'diagnose', *files, '--report', f'{tmp}/diag'])]
        if 'report' in cases:
            jobs.append(('report bags/unbalance_ab_sweep', [str(BIN), 'report', 'bags/unbalance_ab_sweep', '--out',
                                                            f'{tmp}/report']))
            jobs.append(('report plant-like example', [str(BIN), 'report', *plant_recordings(Path(args.plant_data)),
                                                       '--params', str(PLANT), '--out', f'{tmp}/plant']))
        load0 = os.getloadavg()
        times = {name: [] for name, _ in jobs}
        for _ in range(args.repeats):            # interleaved, so that a change of load hits every case alike
            for name, cmd in jobs:
                times[name].append(run_timed(cmd))
        load1 = os.getloadavg()
        for name, _ in jobs:
            w = [t[0] for t in times[name]]
            c = [t[1] for t in times[name]]
            rows.append((name, min(w), statistics.median(w), min(c), statistics.median(c)))
    print(f'load average before {load0[0]:.2f}, after {load1[0]:.2f} (2 cores shared); {args.repeats} repeats')
    print(f"{'case':40s} {'wall min':>9s} {'wall med':>9s} {'CPU min':>9s} {'CPU med':>9s}   [s]  target (wall min)")
    missed = []
    for name, a, b, c, d in rows:
        t = TARGETS.get(name)
        verdict = '' if t is None else f'<= {t:g} s: ' + ('met' if a <= t else 'NO')
        if t is not None and a > t:
            missed.append(name)
        print(f'{name:40s} {a:9.2f} {b:9.2f} {c:9.2f} {d:9.2f}   {verdict}')
    print('TARGETS MISSED: ' + '; '.join(missed) if missed else 'all targets met')
    return 0


if __name__ == '__main__':
    sys.exit(main())
