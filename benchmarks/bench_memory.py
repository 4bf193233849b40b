"""
Peak-memory benchmark: peak RSS of ``bearing-id identify`` against the number of speeds and the length.

Cases (two runs each, the default probes, ``bearing-id simulate``): 3, 9 and 27 speeds at the default dwell, and
9 speeds at half and double the dwell.  Each case is run as a fresh process per method (its own peak RSS, VmHWM).
Printed beside it: the samples per run, the recording's arrays in memory (both files), the import floor (a process
that imports what ``identify`` imports, reads nothing and exits), and the least-squares line RSS = a + b x samples
with its worst residual (linear when the residuals are small against the growth).

Target: peak RSS linear in the recording, <= 150 MiB at 27 speeds.  For the largest case the peak RSS
after each stage of one process is printed too (imports; the files read and fitted to 1X vectors, ``load_data``;
``identify()`` on those vectors), which shows which stage sets the peak.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_memory.py [--methods paper,direct] [--quick]
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
os.environ.setdefault('OMP_NUM_THREADS', '1')

import argparse  # noqa: E402, I100  (after the thread settings above)
from pathlib import Path  # noqa: E402
import sys  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import benchlib as bl  # noqa: E402, I100  (after the sys.path insert above)

TARGET_MIB_27 = 150.0


def speeds_list(n: int, lo: float = 600.0, hi: float = 3000.0) -> list:
    """``n`` speeds [rpm] evenly from ``lo`` to ``hi`` (whole rpm)."""
    return [float(round(v)) for v in np.linspace(lo, hi, n)] if n > 1 else [1500.0]


def array_mib(files) -> tuple[int, float]:
    """Return (samples per run, MiB of the arrays of all files once read) from the .npy headers (no data read)."""
    import zipfile
    total, n = 0, 0
    for f in files:
        with zipfile.ZipFile(f) as zf:
            for info in zf.infolist():
                total += info.file_size
                if info.filename == 'samples.npy':
                    with zf.open(info) as fh:
                        np.lib.format.read_magic(fh)
                        n = np.lib.format.read_array_header_1_0(fh)[0][0]
    return n, total / 2**20


def import_floor(method: str) -> float:
    """Peak RSS [MiB] of a process importing what ``identify --method`` imports, reading nothing."""
    code = ('import bearing_id.cli, bearing_id.commands.identify, bearing_id.identify.harmonics, '
            f'bearing_id.identify.{method}, bearing_id.identify.plausibility, bearing_id.rotor.assembly, '
            'bearing_id.bearings, bearing_id.simulation.rig')
    return bl.run_process([sys.executable, '-c', code])[2]


STAGES = r"""
import os, resource, sys
sys.path.insert(0, {root!r})
def rss():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
import bearing_id.cli, bearing_id.commands.identify, bearing_id.identify.harmonics, bearing_id.identify.plausibility
import bearing_id.identify.{method}, bearing_id.rotor.assembly, bearing_id.bearings, bearing_id.simulation.rig
from bearing_id.commands.identify import load_data
from bearing_id.identify import identify
from bearing_id.config.params import load_rig
from bearing_id.rotor.assembly import RotorModel
out = [rss()]
rig = load_rig()
data = load_data({files!r}, rig, stream={method!r} != 'paper')   # as the command: paper reads whole
out.append(rss())
identify({method!r}, RotorModel.from_params(rig), rig, data)
out.append(rss())
print('STAGES', *out)
"""


def stage_rss(files, method: str) -> tuple[float, float, float]:
    """
    Peak RSS [MiB] of one process after each stage: imports, files -> 1X vectors (``load_data``), ``identify()``.

    Shows where the peak comes from: the recording as read and fitted, or the identification on the 1X data.
    """
    import subprocess
    code = STAGES.format(root=str(bl.ROOT), method=method, files=[str(f) for f in files])
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, cwd=str(bl.ROOT), timeout=900)
    line = [x for x in out.stdout.splitlines() if x.startswith('STAGES ')]
    if out.returncode != 0 or not line:
        raise RuntimeError(f'stage child failed ({out.returncode}): {out.stderr[-2000:]}')
    a, b, c = (float(v) for v in line[-1].split()[1:])
    return a, b, c


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--methods', default='paper,direct', help='comma list of methods (default paper,direct)')
    ap.add_argument('--repeats', type=int, default=1, help='processes per case and method (max RSS reported)')
    ap.add_argument('--quick', action='store_true', help='smoke run: 1 and 3 speeds at a 1 s dwell, direct only')
    ap.add_argument('--fresh', action='store_true', help='simulate the inputs again (else cached in out/bench_data)')
    args = ap.parse_args(argv)
    from bearing_id.config.params import load_rig
    sim = load_rig().simulation
    dwell = float(sim.dwell)
    methods = ['direct'] if args.quick else [m for m in args.methods.split(',') if m]
    if args.quick:
        cases = [(f'{n} speeds, {1.0:g} s dwell', speeds_list(n), 1.0) for n in (1, 3)]
    else:
        cases = [(f'{n} speeds, {dwell:g} s dwell', speeds_list(n), dwell) for n in (3, 9, 27)]
        cases += [(f'9 speeds, {d:g} s dwell', speeds_list(9), d) for d in (dwell / 2, 2 * dwell)]
    print(f'# peak RSS of `bearing-id identify`, {bl.load_note()}')
    floors = {m: import_floor(m) for m in methods}
    rows, pts = [], {m: [] for m in methods}
    for name, speeds, dw in cases:
        files = bl.simulated(speeds, dwell=dw, fresh=args.fresh)
        n, mib = array_mib(files)
        cells = []
        for m in methods:
            argv = bl.cli('identify', *files, '--method', m, '--allow-undetermined')
            t = bl.time_process(argv, args.repeats)
            cells.append(f'{t.rss_max:.0f}')
            pts[m].append((n, t.rss_max, len(speeds), dw))
        target = TARGET_MIB_27 if len(speeds) == 27 and dw == dwell else None
        met = None if target is None else all(float(c) <= target for c in cells)
        rows.append([name, f'{n}', f'{mib:.1f}', *cells, '' if target is None else f'<= {target:.0f}', bl.yes(met)])
    print()
    heads = [f'peak RSS MiB, {m}' for m in methods]
    print(bl.table(['case', 'samples per run', 'arrays MiB (2 files)', *heads, 'target', 'met'], rows))
    print()
    print('import floor (imports only, no data) MiB: ' + ', '.join(f'{m} {v:.0f}' for m, v in floors.items()))
    big = max(cases, key=lambda c: (len(c[1]), c[2] == dwell))
    files = bl.simulated(big[1], dwell=big[2])
    print(f'\nwhere the peak comes from ({big[0]}, one process per method, peak RSS after each stage):')
    for m in methods:
        a, b, c = stage_rss(files, m)
        print(f'  {m}: imports {a:.0f} MiB; after reading the files and the 1X fits (load_data) {b:.0f} MiB '
              f'(+{b - a:.0f}); after identify() on the 1X data {c:.0f} MiB (+{c - b:.0f})')
    for m in methods:
        x = np.array([p[0] for p in pts[m]], dtype=float)
        y = np.array([p[1] for p in pts[m]], dtype=float)
        if x.size >= 2 and np.ptp(x) > 0:
            b, a = np.polyfit(x, y, 1)
            res = np.abs(y - (a + b * x)).max()
            print(f'{m}: least-squares line RSS = {a:.0f} MiB + {b * 1e6:.1f} MiB per million samples per run; '
                  f'worst residual {res:.1f} MiB over a growth of {np.ptp(y):.0f} MiB')
    return 0


if __name__ == '__main__':
    sys.exit(main())
