"""
Identifier solve cost over a run (issue 23 item 6): does the cost of a new speed grow with the speeds before it.

The live identifier solves when a speed completes.  A per-speed method (``direct``, ``conventional``, ``paper``) now
solves only the speeds whose vectors are new or changed; before, every solve re-solved every speed (an N-speed run
cost ~N^2/2 single-speed solves).  This feeds N speeds one by one into :class:`IdentifierCore` (directional-force
runs, probes at both bearings and midspan, 1e-3 relative noise on simulated 1X vectors) and prints, as CPU seconds:

* the run as the identifier does it now (one solve per new speed);
* the same run re-solving every speed at each arrival (what it did before; the same code asked to solve all);
* the ratio, and the CPU of the last arrival in both.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_identifier_solves.py [--speeds 81] [--method direct]
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

import argparse  # noqa: E402, I100  (after the thread setting above)
from pathlib import Path  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bearing_id.config.params import load_rig, Probe  # noqa: E402, I100
from bearing_id.nodes.identifier_core import IdentifierCore  # noqa: E402
from bearing_id.simulation.rig import scenario, simulate_data  # noqa: E402


def run(rig, method, data, X, std, resolve_all: bool) -> tuple[float, float, int]:
    """Feed the speeds one by one; return (total CPU [s], CPU of the last arrival [s], results returned)."""
    with tempfile.TemporaryDirectory() as tmp:
        core = IdentifierCore(rig, method, Path(tmp))
        if resolve_all:                       # the former behaviour: every speed at every solve
            core._changed_speeds = lambda d: list(range(len(d.speeds)))
        for run_ in data.runs:
            core.add_excitation(run_)
        total, last, n = 0.0, 0.0, 0
        for k, w in enumerate(data.speeds):
            for r, run_ in enumerate(data.runs):
                core._store(run_.id, float(w), X[r, k], std[r, k], data.probes)
            t0 = time.process_time()
            out, _ = core.solve(record=True)
            last = time.process_time() - t0
            total += last
            n += len(out)
        core.close()
    return total, last, n


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--speeds', type=int, default=81, help='speeds from 600 to 3000 rpm (default 81)')
    ap.add_argument('--method', default='direct', choices=('direct', 'conventional'))
    args = ap.parse_args(argv)
    rig = load_rig()
    probes = tuple(Probe(f'p{n}{d}', n, d) for n in (2, 6, 10) for d in 'xy')
    data = simulate_data(rig, scenario('force'), np.linspace(600.0, 3000.0, args.speeds), probes=probes)
    rng = np.random.default_rng(1)
    std = 1e-3 * np.abs(data.X)
    X = data.X + std * (rng.standard_normal(data.X.shape) + 1j * rng.standard_normal(data.X.shape))
    now = run(rig, args.method, data, X, std, resolve_all=False)
    before = run(rig, args.method, data, X, std, resolve_all=True)
    print(f'{args.method}, {args.speeds} speeds fed one by one (CPU seconds, this machine):')
    print(f'  {"":24s} {"whole run":>10s} {"last arrival":>13s} {"results returned":>17s}')
    for name, (tot, last, n) in (('new/changed speeds only', now), ('every speed every time', before)):
        print(f'  {name:24s} {tot:10.2f} {last:13.3f} {n:17d}')
    print(f'  ratio (every time / changed only): whole run {before[0] / now[0]:.1f}x, last arrival '
          f'{before[1] / max(now[1], 1e-9):.1f}x')
    return 0


if __name__ == '__main__':
    sys.exit(main())
