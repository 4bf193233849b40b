"""
The Kalman-filter node's bearing-node 1X against the simulator's truth, per speed (issue 23 item 1).

Packaged rig, its unbalance runs A and B simulated at each speed (2 s dwell, 1 % noise, midspan probes).  The
estimator core (``nodes.kf_estimator_core.EstimatorCore``, the node's defaults: Q and R from the data; one core per
route for all speeds, as the node) filters run A twice: on the theory bearings, and on the identifier's result at that
speed (``identify('physical', ...)`` on both runs, as the node receives it on bearing_id/coefficients).  Reference:
the same simulation's noise-free motion at the bearing nodes.  1X of both by a DFT over whole revolutions of the last
3/4 of the dwell.  Printed per speed: the largest amplitude error [%] and phase error [deg] over the four bearing
channels, the dwell's mean NIS against its 95 % chi-square band, the innovation health, and (identified) the largest
|1X error| in units of the 1X's stated 1-sigma (from the identified coefficients' 1-sigma, as /diagnostics publishes
it in ``kf_estimator: bearing motion``).

Run:  python benchmarks/bench_kf_bearing_motion.py [--speeds 600,900,...] [--dwell 2.0] [--Q 1e-16 (fixed)]
"""
import argparse
import math
from pathlib import Path
import sys

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bearing_id.config.params import load_rig, Probe  # noqa: E402, I100  (after the sys.path insert above)
from bearing_id.estimation.kalman import nis_band  # noqa: E402
from bearing_id.identify import harmonics, identify  # noqa: E402
from bearing_id.io.messages import Block  # noqa: E402
from bearing_id.nodes.kf_estimator_core import EstimatorCore  # noqa: E402
from bearing_id.rotor.assembly import RotorModel  # noqa: E402
from bearing_id.simulation import rig as R  # noqa: E402


def one_x(x, angle):
    turns = (angle - angle[0]) / (2 * math.pi)
    n = int(np.searchsorted(turns, math.floor(turns[-1])))
    return 2 * np.mean(x[:n] * np.exp(-1j * angle[:n, None]), axis=0)


def run_filter(core, rec):
    fs, out = rec.sample_rate, []
    for k, i0 in enumerate(range(0, rec.samples.shape[0], 1024)):
        i1 = min(i0 + 1024, rec.samples.shape[0])
        b = Block(stamp_ns=int(i0 / fs * 1e9), sequence=k, sample_rate=fs, speed=float(rec.speed[i0]),
                  angle=float(rec.angle[i0]), channels=tuple(p.name for p in rec.probes),
                  nodes=tuple(p.node for p in rec.probes), directions=tuple(p.direction for p in rec.probes),
                  samples=rec.samples[i0:i1], sample_angles=rec.angle[i0:i1], run_id=rec.run.id)
        core.submit(b, rec.run, float(np.mean(rec.speed[i0:i1])), k > 0)
        while core.pending:
            out += core.drain()
    return np.concatenate([o.estimates for o in out]), np.concatenate([o.nis for o in out])


def errors(core, rec, truth):
    """
    Return the channels' errors and the filter's consistency over one dwell.

    (amp err %, phase err deg, the dwell's mean NIS, its 95 % band, innovations, largest |1X error| / its stated
    1-sigma or NaN).
    """
    est, nis = run_filter(core, rec)
    s = slice(est.shape[0] // 4, None)
    got, ref = one_x(est[s], rec.angle[s]), one_x(truth.samples[s], truth.angle[s])
    health, motion = core.health_status(), core.motion_status()
    std = [motion.values.get(f'{p.name}_1x_std_coefficients_um') for p in core.outputs_probes]
    z = (np.max(np.abs(got - ref) / (1e-6 * np.array(std, float))) if all(isinstance(v, float) for v in std)
         else math.nan)
    return (100 * np.max(np.abs(np.abs(got) / np.abs(ref) - 1)), np.max(np.abs(np.degrees(np.angle(got / ref)))),
            float(np.mean(nis)), nis_band(nis.size, core.n_meas), 'white' if 'white' in health.message else 'MISMATCH',
            z)


def nis_cell(mean, band):
    return f"{mean:.3g} {'in' if band[0] <= mean <= band[1] else 'OUT of'} [{band[0]:.3g}, {band[1]:.3g}]"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--speeds', default='600,900,1200,1500,1800,2100,2400,2700,3000')
    ap.add_argument('--dwell', type=float, default=2.0)
    ap.add_argument('--Q', type=float, default=0.0, help="the node's process_noise (0, its default: from the data)")
    args = ap.parse_args(argv)
    rig = load_rig()
    at = tuple(Probe(f'b{b.node}{d}', b.node, d) for b in rig.bearings for d in 'xy')
    print(f"command: python benchmarks/bench_kf_bearing_motion.py {' '.join(argv or sys.argv[1:])}\n")
    print('| rpm | theory: amp err % | phase err deg | dwell NIS, 95 % band | innovations | identified: amp err % | '
          'phase err deg | dwell NIS, 95 % band | innovations | |1X error| / stated 1-sigma |\n'
          '|---|---|---|---|---|---|---|---|---|---|')
    # one core per route for the whole run, as the node: what it learnt of the noise carries from dwell to dwell
    theory_core, core = EstimatorCore(rig, args.Q, 0.0, 0.01), EstimatorCore(rig, args.Q, 0.0, 0.01)
    for rpm in (float(v) for v in args.speeds.split(',')):
        recs = [R.simulate_run(rig, run, speeds_rpm=[rpm], dwell=args.dwell, ramp=0.0) for run in rig.simulation.runs]
        truth = R.simulate_run(rig, rig.simulation.runs[0], speeds_rpm=[rpm], dwell=args.dwell, ramp=0.0, probes=at,
                               noise=0.0)
        theory = errors(theory_core, recs[0], truth)
        (r,) = identify('physical', RotorModel.from_params(rig), rig, harmonics.from_recordings(recs))
        core.set_coefficients(r.speed, {n: (r.K[i], r.C[i]) for i, n in enumerate(r.nodes)},
                              {n: (r.K_std[i], r.C_std[i]) for i, n in enumerate(r.nodes)})
        ident = errors(core, recs[0], truth)
        cells = [f'{theory[0]:.3g}', f'{theory[1]:.2f}', nis_cell(theory[2], theory[3]), theory[4],
                 f'{ident[0]:.3g}', f'{ident[1]:.2f}', nis_cell(ident[2], ident[3]), ident[4], f'{ident[5]:.2f}']
        print(f"| {rpm:.0f} | {' | '.join(cells)} |", flush=True)
    print(f'\nprocess noise the innovations imply at the end: theory {theory_core.Q:.3g}, identified {core.Q:.3g} m^2 '
          f'({core.q_fits} gain re-solves for it)')
    theory_core.close()
    core.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
