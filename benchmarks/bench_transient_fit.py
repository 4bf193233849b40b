#!/usr/bin/env python
"""
In-process time of the 1X extraction of the demo recordings: the fast transient-aware fit against its reference.

The recordings are the packaged rig's plan (``rig.simulate_plan``: 2 runs x 9 speeds, what ``bearing-id simulate``
writes), 18 steady windows.  Timed, each min / median of ``--repeats`` (interleaved, so that load changes hit both):

* ``harmonics.from_recordings`` (windows, settling part dropped, transient-aware 1X fit, stationarity check): the
  whole 1X extraction, with ``signals._transient_fit`` (fast) and with ``signals._transient_fit_reference``;
* the transient-aware fits alone (``harmonic_vectors(..., transients=3)`` on the 18 fitted parts), both ways;
* the plain 1X fit of the same parts (the floor).

It also checks that both give the same vectors (max relative difference printed).

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

from bearing_id.config.params import load_rig  # noqa: E402
from bearing_id.identify import harmonics  # noqa: E402
from bearing_id.signals import harmonics as signals  # noqa: E402
from bearing_id.simulation.rig import simulate_plan  # noqa: E402
import numpy as np  # noqa: E402


def _parts(recordings):
    """Return the fitted part of every steady window (what window_vector passes to harmonic_vectors)."""
    out = []
    for rec in recordings:
        stream = harmonics.RunStream(rec.run, rec.probes, rec.sample_rate)
        for win in stream.feed(rec.samples, rec.angle) + stream.close():
            n = win.i1 - win.i0
            if win.duration < 0.2:
                continue
            j0 = 0 if win.continued else int(math.ceil(harmonics.DEFAULT_SETTLE * n))
            out.append((win.samples[j0:], win.angle[j0:], win.sample_rate))
    return out


def _time(fn):
    """Return (wall, CPU) seconds of fn()."""
    t0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t0, time.process_time() - c0


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
    fast_fit = signals._transient_fit

    def reference_fit(*args, coef0=None):
        return signals._transient_fit_reference(*args)

    def extraction(reference: bool):
        signals._transient_fit = reference_fit if reference else fast_fit
        try:
            return harmonics.from_recordings(recs)
        finally:
            signals._transient_fit = fast_fit

    def fits(method):
        return [signals.harmonic_vectors(x, a, transients=3, sample_rate=fs, transient_method=method)
                for x, a, fs in parts]

    a, b = extraction(False), extraction(True)
    rel = float(np.max(np.abs(a.X - b.X)) / np.max(np.abs(b.X)))
    rel_std = float(np.max(np.abs(a.X_std / b.X_std - 1)))
    fa, fb = fits('fast'), fits('reference')
    kept = sum(f.transient_rates.size for f in fb)
    times = {k: [] for k in ('extraction fast', 'extraction reference', 'fits fast', 'fits reference', 'plain fits')}
    for _ in range(args.repeats):
        times['extraction fast'].append(_time(lambda: extraction(False)))
        times['extraction reference'].append(_time(lambda: extraction(True)))
        times['fits fast'].append(_time(lambda: fits('fast')))
        times['fits reference'].append(_time(lambda: fits('reference')))
        times['plain fits'].append(_time(lambda: [signals.harmonic_vectors(x, a_) for x, a_, _ in parts]))
    print(f'{len(parts)} windows ({kept} decaying components kept by the reference); fast vs reference: max |dX| / max '
          f'|X| = {rel:.1e}, max |dstd / std| = {rel_std:.1e}, per-window fits max rel dX = '
          f'{max(float(np.max(np.abs(u.X - v.X) / np.abs(v.X))) for u, v in zip(fa, fb)):.1e}')
    print(f"{'in-process, s':<28} {'wall min':>9} {'median':>8} {'CPU min':>9} {'median':>8}   (of {args.repeats}; "
          f'load after: {os.getloadavg()})')
    for k, v in times.items():
        w, c = np.array(v).T
        print(f'{k:<28} {w.min():9.3f} {np.median(w):8.3f} {c.min():9.3f} {np.median(c):8.3f}')
    for what in ('extraction', 'fits'):
        r = [y[1] / x[1] for x, y in zip(times[f'{what} fast'], times[f'{what} reference'])]
        print(f'{what}: reference / fast (CPU) = {min(r):.1f} .. {max(r):.1f} (median {np.median(r):.1f})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
