"""``bearing-id simulate``: record the simulated rig to .npz files (one per excitation run)."""
from __future__ import annotations

import argparse
from pathlib import Path

from ..config.params import load_rig, ParamError, parse_probes
from ..io.recordings import save_npz
from ..simulation import rig as rigmod


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser('simulate', help='record the simulated rig (truth bearings != theory) to .npz files',
                       description='Simulate the rig described by --params and write one .npz per excitation run '
                                   '(samples in metres, speed in rad/s, keyphasor angle in rad).')
    p.add_argument('--params', help='rig YAML (default: the packaged params/rig.yaml)')
    p.add_argument('--scenario', default='default',
                   help='default (the runs in the params file), paper_table3, paper_table4 or force')
    p.add_argument('--speeds', help='comma-separated speeds in rpm (default: simulation.speeds_rpm)')
    p.add_argument('--dwell', type=float, help='seconds at each speed (default: simulation.dwell)')
    p.add_argument('--noise', type=float, help='noise std as a fraction of channel RMS (default: simulation.noise)')
    p.add_argument('--probes', help='probe list like 6x,6y or 17@45,17@135 (NODE@degrees from +x towards +y; '
                                    "default: the params' probes)")
    p.add_argument('--truth-model', choices=('short', 'finite'), help='bearing model of the truth bearings')
    p.add_argument('--out', default='out/sim', help='output directory (default out/sim)')
    return p


def run(args) -> int:
    rig = load_rig(args.params)
    if rig.simulation is None:
        raise ParamError('the params file has no simulation section')
    if args.truth_model:
        rig = rigmod.with_truth(rig, bearing_model=args.truth_model)
    runs = rig.simulation.runs if args.scenario == 'default' else rigmod.scenario(args.scenario)
    speeds = None
    if args.speeds:
        try:
            speeds = [float(s) for s in args.speeds.split(',')]
        except ValueError:
            raise ParamError(f'--speeds must be comma-separated rpm values, got {args.speeds!r}') from None
        if any(s <= 0 for s in speeds):
            raise ParamError('--speeds: every speed must be > 0 rpm (no hydrodynamic film at standstill)')
    if args.dwell is not None and args.dwell <= 0:
        raise ParamError('--dwell must be > 0 s')
    if args.noise is not None and not 0 <= args.noise <= 1:
        raise ParamError('--noise is a fraction of the RMS signal, 0..1')
    probes = parse_probes(args.probes) if args.probes else None
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for r in runs:
        rec = rigmod.simulate_run(rig, r, speeds_rpm=speeds, dwell=args.dwell, noise=args.noise, probes=probes)
        path = save_npz(rec, out / f'run_{r.id}.npz')
        print(f'wrote {path}  ({rec.samples.shape[0]} samples x {rec.samples.shape[1]} channels at '
              f'{rec.sample_rate:.0f} Hz, run {r.id})')
    return 0
