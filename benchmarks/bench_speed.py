"""
Speed benchmark of the Kalman-filter estimation step (issue 4 item 6): the paper's job on the simulated rig.

Job (Kang et al. 2020, 4.4 s in the paper): two unbalance runs (A and B of params/rig.yaml), 20,480 samples each at
10,240 Hz from the midspan probe pair (node 6, x and y), the FE model at one speed with the theoretical (nominal)
bearing coefficients, estimating x and y at both bearing nodes (4 outputs).

    fast path : model build (state space, expm, steady-state gain from the DARE, chunk operators) + the vectorised
                steady-state filter for both runs
    reference : filterpy KalmanFilter, one predict/update per sample, both runs (same model, started from P_ss)
    streaming : StreamingKF.step_block on 1024-sample blocks; real-time factor = block duration / time per block

Targets: fast <= 0.05 s, fast >= 100x the reference loop, streaming real-time factor >= 50 on one core.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_speed.py [--rpm 1500] [--repeats 5]
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')       # before numpy: threaded BLAS slows these small loops
os.environ.setdefault('OMP_NUM_THREADS', '1')
os.environ.setdefault('MKL_NUM_THREADS', '1')

import argparse  # noqa: E402, I100  (after the thread settings above)
from pathlib import Path  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bearing_id import kalman  # noqa: E402, I100  (after the sys.path insert above)
from bearing_id import rig as rigmod  # noqa: E402
from bearing_id.conventions import rpm_to_rad_s  # noqa: E402
from bearing_id.excitation import harmonic_forces  # noqa: E402
from bearing_id.params import load_rig  # noqa: E402
from bearing_id.rotor.assembly import RotorModel  # noqa: E402

SAMPLE_RATE = 10240.0
N_SAMPLES = 20480
BLOCK = 1024


def simulate_runs(rig, model, rpm):
    """Two recordings (runs A and B) of N_SAMPLES at one speed, node-6 probes, default truth bearings and noise."""
    recs = []
    for run in rig.simulation.runs[:2]:
        recs.append(rigmod.simulate(rig, run, rigmod.step_schedule([rpm], N_SAMPLES / SAMPLE_RATE), model=model,
                                    sample_rate=SAMPLE_RATE))
    return recs


def build_models(rig, model, speed, recs, q):
    """One KalmanModel per run (same matrices and gain, each run's own known excitation) from nominal theory."""
    coeffs = rigmod.nominal_bearing_fn(rig)(speed)
    sigma2 = [float(np.mean(np.var(r.samples, axis=0)) * rig.simulation.noise**2) for r in recs]
    km = kalman.rotor_kalman_model(model, speed, coeffs, recs[0].probes, SAMPLE_RATE,
                                   forces=harmonic_forces(recs[0].run.excitation, speed, model.n_nodes), Q=q,
                                   R=max(sigma2))
    km.steady_state()
    kms = [km] + [km.with_forces(harmonic_forces(r.run.excitation, speed, model.n_nodes)) for r in recs[1:]]
    return kms


def fast_job(rig, model, speed, recs, q):
    kms = build_models(rig, model, speed, recs, q)
    return [kalman.fast_filter(km, r.samples, r.angle) for km, r in zip(kms, recs)]


def best_of(fn, repeats):
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--rpm', type=float, default=1500.0, help='rotor speed [rpm] (default 1500)')
    ap.add_argument('--q', type=float, default=1e-16, help='process noise Q = q I (paper: 1e-16 ... 1e-18)')
    ap.add_argument('--repeats', type=int, default=5, help='repeats of the fast path (best is reported)')
    ap.add_argument('--ref-repeats', type=int, default=1, help='repeats of the filterpy reference loop')
    args = ap.parse_args(argv)

    rig = load_rig()
    model = RotorModel.from_params(rig)
    speed = float(rpm_to_rad_s(args.rpm))
    recs = simulate_runs(rig, model, args.rpm)

    # fast path, model build included (fresh model each repeat)
    t_fast, fast = best_of(lambda: fast_job(rig, model, speed, recs, args.q), args.repeats)
    kms = build_models(rig, model, speed, recs, args.q)
    kalman.fast_filter(kms[0], recs[0].samples, recs[0].angle)                   # warm the operator cache
    t_filter, _ = best_of(lambda: [kalman.fast_filter(km, r.samples, r.angle) for km, r in zip(kms, recs)],
                          args.repeats)
    # filterpy reference loop on the same models (started from the steady-state covariance)
    t_ref, ref = best_of(lambda: [kalman.reference_filter(km, r.samples, r.angle) for km, r in zip(kms, recs)],
                         args.ref_repeats)
    diff = max(np.abs(f.estimates - r.estimates).max() / np.abs(r.estimates).max() for f, r in zip(fast, ref))

    # streaming: blocks of 1024 samples through one StreamingKF
    s = kalman.StreamingKF(kms[0])
    r0 = recs[0]
    nb = N_SAMPLES // BLOCK
    s.step_block(r0.samples[:BLOCK], r0.angle[:BLOCK], speed)                     # warm-up
    s.reset()
    per = []
    for rep in range(3):
        s.reset()
        t0 = time.perf_counter()
        for b in range(nb):
            sl = slice(b * BLOCK, (b + 1) * BLOCK)
            s.step_block(r0.samples[sl], r0.angle[sl], speed)
        per.append((time.perf_counter() - t0) / nb)
    t_block = min(per)
    rtf = (BLOCK / SAMPLE_RATE) / t_block

    n = kms[0].n
    print(f"# Speed benchmark: paper's KF job at {args.rpm:.0f} rpm, Q = {args.q:g} I, {n} states, "
          f'2 runs x {N_SAMPLES} samples at {SAMPLE_RATE:.0f} Hz, probes node 6 x/y, 4 bearing-node outputs')
    print(f"# OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}, numpy {np.__version__}")
    print()
    print('| quantity | measured | target |')
    print('|---|---|---|')
    print(f'| fast path, model build + both runs [s] | {t_fast:.4f} | <= 0.05 |')
    print(f'| fast path, filtering only, both runs [s] | {t_filter:.4f} | |')
    print(f'| filterpy reference loop, both runs [s] | {t_ref:.2f} | (paper: 4.4) |')
    print(f'| speed-up (reference / fast incl. build) | {t_ref / t_fast:.0f}x | >= 100x |')
    print(f'| max relative difference fast vs reference | {diff:.1e} | <= 1e-9 |')
    print(f'| streaming, time per {BLOCK}-sample block [ms] | {1e3 * t_block:.3f} | |')
    print(f'| streaming real-time factor (one core) | {rtf:.0f} | >= 50 |')
    ok = t_fast <= 0.05 and t_ref / t_fast >= 100 and rtf >= 50 and diff <= 1e-9
    print()
    print('all targets met' if ok else 'TARGET MISSED')
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
