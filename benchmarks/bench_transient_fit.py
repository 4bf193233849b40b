#!/usr/bin/env python
"""
In-process time of the 1X extraction of the demo recordings and of its transient-aware fits.

The recordings are the packaged rig's plan (``rig.simulate_plan``: 2 runs x 9 speeds, what ``bearing-id simulate``
writes), 18 steady windows.  Timed, each min / median of ``--repeats``:

* ``harmonics.from_recordings`` (windows, settling part dropped, transient-aware 1X fit, stationarity check): the
  whole 1X extraction;
* the transient-aware fits alone (``harmonic_vectors(..., transients=3)`` on the 18 fitted parts);
* the plain 1X fit of the same parts (the floor).

It also reports the time spent inside ``scipy.optimize.least_squares`` outside the variable-projection evaluations
(its per-call overhead, what a purpose-built Levenberg-Marquardt could save).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_transient_fit.py [--repeats 5]
"""
from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
import sys
import time

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from bearing_id.config import defaults  # noqa: E402
from bearing_id.config.params import load_rig  # noqa: E402
from bearing_id.identify import harmonics  # noqa: E402
from bearing_id.signals.harmonics import harmonic_vectors  # noqa: E402
from bearing_id.signals.transient import VariableProjection  # noqa: E402
from bearing_id.simulation.rig import simulate_plan  # noqa: E402
import numpy as np  # noqa: E402


def _parts(recordings):
    """Return the fitted part of every steady window (what window_vector passes to harmonic_vectors)."""
    out = []
    for rec in recordings:
        for win in harmonics.recording_windows(rec):
            n = win.i1 - win.i0
            if win.duration < 0.2:
                continue
            j0 = 0 if win.continued else int(math.ceil(defaults.SETTLE_FRACTION * n))
            out.append((win.samples[j0:], win.angle[j0:], win.sample_rate))
    return out


def _time(fn):
    """Return (wall, CPU) seconds of fn()."""
    t0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t0, time.process_time() - c0


def _solver_overhead(parts) -> tuple[float, float, int]:
    """Return (s in least_squares, s of it in evaluations, calls) over one pass of the transient-aware fits."""
    acc = {'solve': 0.0, 'eval': 0.0, 'calls': 0, 'inside': False}
    evaluate, solve = VariableProjection.evaluate, VariableProjection.solve

    def timed_evaluate(self, p, jac=True):
        t0 = time.perf_counter()
        try:
            return evaluate(self, p, jac)
        finally:
            if acc['inside']:
                acc['eval'] += time.perf_counter() - t0

    def timed_solve(self, *args, **kw):
        acc['inside'], t0 = True, time.perf_counter()
        try:
            return solve(self, *args, **kw)
        finally:
            acc['solve'] += time.perf_counter() - t0
            acc['calls'] += 1
            acc['inside'] = False

    VariableProjection.evaluate, VariableProjection.solve = timed_evaluate, timed_solve
    try:
        for x, a, fs in parts:
            harmonic_vectors(x, a, transients=3, sample_rate=fs)
    finally:
        VariableProjection.evaluate, VariableProjection.solve = evaluate, solve
    return acc['solve'], acc['eval'], acc['calls']


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--repeats', type=int, default=5)
    args = ap.parse_args(argv)
    rig = load_rig()
    t0 = time.perf_counter()
    recs = simulate_plan(rig)
    print(f'simulated {len(recs)} recordings in {time.perf_counter() - t0:.1f} s; '
          f'OPENBLAS_NUM_THREADS={os.environ.get("OPENBLAS_NUM_THREADS", "unset")}; load {os.getloadavg()}')
    parts = _parts(recs)
    kept = sum(harmonic_vectors(x, a, transients=3, sample_rate=fs).transient_rates.size for x, a, fs in parts)
    times = {k: [] for k in ('extraction', 'transient-aware fits', 'plain fits')}
    for _ in range(args.repeats):
        times['extraction'].append(_time(lambda: harmonics.from_recordings(recs)))
        times['transient-aware fits'].append(_time(lambda: [harmonic_vectors(x, a, transients=3, sample_rate=fs)
                                                            for x, a, fs in parts]))
        times['plain fits'].append(_time(lambda: [harmonic_vectors(x, a) for x, a, _ in parts]))
    print(f'{len(parts)} windows, {kept} decaying components kept')
    print(f"{'in-process, s':<28} {'wall min':>9} {'median':>8} {'CPU min':>9} {'median':>8}   (of {args.repeats}; "
          f'load after: {os.getloadavg()})')
    for k, v in times.items():
        w, c = np.array(v).T
        print(f'{k:<28} {w.min():9.3f} {np.median(w):8.3f} {c.min():9.3f} {np.median(c):8.3f}')
    solve, evaluations, calls = _solver_overhead(parts)
    print(f'least_squares: {solve:.3f} s in {calls} calls, of which evaluations {evaluations:.3f} s: overhead '
          f'{solve - evaluations:.3f} s ({1e3 * (solve - evaluations) / max(calls, 1):.2f} ms per call)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
