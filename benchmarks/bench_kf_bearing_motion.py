"""
The Kalman-filter node's bearing-node 1X against the simulator's truth, per dwell (issue 23 item 1).

A run-up as the rig's simulation plans it (its speeds, dwells and ramps between them; 1 % noise, its probes).  First
pass: every excitation run, and the identifier's answer to it, ``identify('physical', ...)`` on all speeds at once (as
the node's identifier fits them, warm start aside; sent per speed as on bearing_id/coefficients).  Second pass: run A
again (new noise) through the estimator core (``nodes.kf_estimator_core.EstimatorCore``, the node's defaults: Q and
R from the data; one core per route for the whole stream, ramps included), once on the theory bearings and once on
the identified ones.  Reference: the same simulation's noise-free motion at the bearing nodes.  1X of both by a DFT
over whole revolutions of the last 3/4 of each dwell.  Printed per dwell: the largest amplitude error [%] and phase
error [deg] over the four bearing channels, the dwell's mean NIS against its 95 % band (the plain chi-square band,
and the node's: widened by the relative 1-sigma of the noise estimate it is normalised by), the innovation health at
the dwell's end, and (identified) the largest |1X error| in units of the 1X's stated 1-sigma (from the identified
coefficients' 1-sigma, as /diagnostics publishes it in ``kf_estimator: bearing motion``).  At the end: the largest
estimated and true bearing orbit against the orbit warning limit, and the largest |estimated - true| bearing motion
on the ramps (a block crossing speed bands is filtered piece by piece on each band's model).

Run:  python benchmarks/bench_kf_bearing_motion.py [--rig params.yaml] [--speeds 600,900,...] [--dwell 2.0]
      [--ramp 0.5] [--Q 1e-16 (fixed)]
"""
import argparse
import math
from pathlib import Path
import sys
import time

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bearing_id.config.params import load_rig, Probe  # noqa: E402, I100  (after the sys.path insert above)
from bearing_id.estimation.kalman import nis_band  # noqa: E402
from bearing_id.identify import harmonics, identify  # noqa: E402
from bearing_id.io.messages import Block  # noqa: E402
from bearing_id.nodes.kf_estimator_core import EstimatorCore, ORBIT_LIMIT  # noqa: E402
from bearing_id.rotor.assembly import RotorModel  # noqa: E402
from bearing_id.simulation import rig as R  # noqa: E402


def one_x(x, angle):
    """1X phasors (m,) of x (n, m) over the whole revolutions of ``angle`` (n,): 2 mean(x e^{-j angle})."""
    turns = (angle - angle[0]) / (2 * math.pi)
    n = int(np.searchsorted(turns, math.floor(turns[-1])))
    return 2 * np.mean(x[:n] * np.exp(-1j * angle[:n, None]), axis=0)


def dwells(rec, speeds_rpm):
    """Sample slices (the last 3/4 of each dwell) at each speed [rpm] of the recording's schedule."""
    out = []
    for rpm in speeds_rpm:
        idx = np.flatnonzero(np.abs(rec.speed - rpm * math.pi / 30) <= 1e-9 * rpm)
        out.append(slice(idx[0] + (idx[-1] + 1 - idx[0]) // 4, idx[-1] + 1))
    return out


class Route:
    """One estimator core through one recording, block by block as the node; its per-dwell figures."""

    def __init__(self, core, rec, truth, speeds_rpm, block_size: int):
        self.core, self.rec, self.truth = core, rec, truth
        self.windows = dwells(rec, speeds_rpm)
        self.block_size = int(block_size)
        self.orbit = 0.0          # largest bearing orbit radius so far / ORBIT_LIMIT x its clearance
        self.est = []             # the estimates (n, 2 nb) of every block so far

    def run(self):
        """Yield, per dwell, (amp err %, phase err deg, mean NIS, chi-square band, node's band, health, |err|/sigma)."""
        rec, core, fs = self.rec, self.core, self.rec.sample_rate
        est, nis, u, k = self.est, [], [], 0
        for w in self.windows:
            while sum(map(len, nis)) < w.stop:
                i0 = k * self.block_size
                i1 = min(i0 + self.block_size, rec.samples.shape[0])
                b = Block(stamp_ns=int(i0 / fs * 1e9), sequence=k, sample_rate=fs, speed=float(rec.speed[i0]),
                          angle=float(rec.angle[i0]), channels=tuple(p.name for p in rec.probes),
                          nodes=tuple(p.node for p in rec.probes), directions=tuple(p.direction for p in rec.probes),
                          samples=rec.samples[i0:i1], sample_angles=rec.angle[i0:i1], run_id=rec.run.id)
                core.submit(b, rec.run, float(np.mean(rec.speed[i0:i1])), k > 0)
                k += 1
                while core.pending:
                    got = core.drain()
                    if not got:         # its models are being built (a thread): do not spin against it
                        time.sleep(0.002)
                    for o in got:
                        for j, b in enumerate(core.rig.bearings):
                            r = np.hypot(o.estimates[:, 2 * j], o.estimates[:, 2 * j + 1])
                            self.orbit = max(self.orbit, float(np.max(r)) / (ORBIT_LIMIT * b.clearance))
                        est.append(o.estimates)
                        nis.append(o.nis)
                        u.append(np.full(o.nis.size, o.nis_rel_std))
            e, v, uu = np.concatenate(est), np.concatenate(nis), np.concatenate(u)
            got = one_x(e[w], rec.angle[w])
            ref = one_x(self.truth.samples[w], self.truth.angle[w])
            motion = core.motion_status()
            std = [motion.values.get(f'{p.name}_1x_std_coefficients_um') for p in core.outputs_probes]
            z = (np.max(np.abs(got - ref) / (1e-6 * np.array(std, float)))
                 if all(isinstance(x, float) for x in std) else math.nan)
            rel_u = float(np.sqrt(np.mean(uu[w] ** 2)))
            yield (100 * np.max(np.abs(np.abs(got) / np.abs(ref) - 1)), np.max(np.abs(np.degrees(np.angle(got / ref)))),
                   float(np.mean(v[w])), nis_band(v[w].size, core.n_meas),
                   nis_band(v[w].size, core.n_meas, rel_std=rel_u),
                   'white' if 'white' in core.health_status().message else 'MISMATCH', z)


def true_orbit(rig, truth) -> float:
    """Return the truth's largest bearing orbit radius / ORBIT_LIMIT x its clearance (x, y columns per bearing)."""
    x = truth.samples
    return max(float(np.max(np.hypot(x[:, 2 * j], x[:, 2 * j + 1]))) / (ORBIT_LIMIT * b.clearance)
               for j, b in enumerate(rig.bearings))


def ramp_error(rig, rec, truth, speeds_rpm, est) -> float:
    """
    Largest |estimated - true| bearing motion on the ramps (each with the 1024 samples after it) / the warning limit.

    The radius of the difference, per bearing over its x and y outputs, against ``ORBIT_LIMIT`` of its clearance;
    ``est`` (n, 2 nb) the route's estimates over the whole stream.
    """
    steady = np.zeros(rec.speed.size, bool)
    for rpm in speeds_rpm:
        steady |= np.abs(rec.speed - rpm * math.pi / 30) <= 1e-9 * rpm
    idx = np.flatnonzero(~steady)
    if idx.size == 0:
        return math.nan
    idx = np.unique(np.concatenate([np.arange(i, min(i + 1024, est.shape[0])) for i in idx]))
    idx = idx[idx < est.shape[0]]
    return max(float(np.max(np.hypot(*(est[idx, 2 * j + c] - truth.samples[idx, 2 * j + c] for c in (0, 1)))))
               / (ORBIT_LIMIT * b.clearance) for j, b in enumerate(rig.bearings))


def nis_cell(mean, band):
    return f"{mean:.3g} {'in' if band[0] <= mean <= band[1] else 'OUT of'} [{band[0]:.3g}, {band[1]:.3g}]"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--rig', default=None, help='rig params file (default: the packaged rig)')
    ap.add_argument('--speeds', default=None, help="rpm, comma separated (default: the rig simulation's)")
    ap.add_argument('--dwell', type=float, default=None, help="s at each speed (default: the rig simulation's)")
    ap.add_argument('--ramp', type=float, default=None, help="s between dwells (default: the rig simulation's)")
    ap.add_argument('--Q', type=float, default=0.0, help="the node's process_noise (0, its default: from the data)")
    args = ap.parse_args(argv)
    rig = load_rig(args.rig)
    sim = rig.simulation
    speeds = [float(v) for v in args.speeds.split(',')] if args.speeds else [float(v) for v in sim.speeds_rpm]
    plan = {'speeds_rpm': speeds, 'dwell': args.dwell, 'ramp': args.ramp}
    at = tuple(Probe(f'b{b.node}{d}', b.node, d) for b in rig.bearings for d in 'xy')
    print(f"command: python benchmarks/bench_kf_bearing_motion.py {' '.join(argv or sys.argv[1:])}\n")
    first = [R.simulate_run(rig, run, **plan) for run in sim.runs]
    results = identify('physical', RotorModel.from_params(rig), rig, harmonics.from_recordings(first))
    used = [r for r in results if r.fully_determined]          # what the node takes (kf_estimator: coefficients)
    left = ', '.join(f'{r.speed_rpm:.0f}' for r in results if not r.fully_determined)
    where = f' (not at {left} rpm: the filter interpolates there)' if left else ''
    misfit = ', MISFIT' if any(r.misfit for r in results) else ''
    print(f'identified (first pass): every coefficient determined at {len(used)} of {len(results)} speeds'
          f'{where}{misfit}\n')
    run = sim.runs[0]
    rec = R.simulate_run(rig, run, seed=R.run_seed(sim.seed, run.id, 1), **plan)      # the second pass
    truth = R.simulate_run(rig, run, probes=at, noise=0.0, **plan)
    theory_core, core = EstimatorCore(rig, args.Q, 0.0, 0.01), EstimatorCore(rig, args.Q, 0.0, 0.01)
    for r in used:
        core.set_coefficients(r.speed, {n: (r.K[i], r.C[i]) for i, n in enumerate(r.nodes)},
                              {n: (r.K_std[i], r.C_std[i]) for i, n in enumerate(r.nodes)})
    print("| rpm | theory: amp err % | phase err deg | dwell NIS, its 95 % band (node's) | innovations | "
          "identified: amp err % | phase err deg | dwell NIS, chi-square 95 % band | node's band | innovations | "
          '|1X error| / stated 1-sigma |\n|---|---|---|---|---|---|---|---|---|---|---|')
    block = sim.block_size
    ident_route = Route(core, rec, truth, speeds, block)
    for rpm, th, ident in zip(speeds, Route(theory_core, rec, truth, speeds, block).run(), ident_route.run()):
        cells = [f'{th[0]:.3g}', f'{th[1]:.2f}', nis_cell(th[2], th[4]), th[5], f'{ident[0]:.3g}', f'{ident[1]:.2f}',
                 nis_cell(ident[2], ident[3]), nis_cell(ident[2], ident[4]), ident[5], f'{ident[6]:.2f}']
        print(f"| {rpm:.0f} | {' | '.join(cells)} |", flush=True)
    print(f'\nprocess noise the innovations imply at the end: theory {theory_core.Q:.3g}, identified {core.Q:.3g} m^2 '
          f'({core.q_fits} gain re-solves for it); identified route: {core.resets} filter start(s), {core.switches} '
          f'model switches with the state kept; largest bearing orbit {100 * ident_route.orbit:.3g} % of the warning '
          f"limit ({ORBIT_LIMIT:.0%} of clearance), the truth's {100 * true_orbit(rig, truth):.3g} %; largest "
          f'|estimated - true| bearing motion on the ramps '
          f'{100 * ramp_error(rig, rec, truth, speeds, np.concatenate(ident_route.est)):.3g} % of the warning limit')
    theory_core.close()
    core.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
