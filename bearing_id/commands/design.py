"""``bearing-id design``: before measuring, what a probe set and an excitation plan can determine, and what to add."""
from __future__ import annotations

import argparse

from ..config.params import load_rig, ParamError, parse_probes
from ..conventions import rpm_to_rad_s
from ..identify.design import check_design
from ..rotor.assembly import RotorModel
from ..rotor.supports import bearing_fn
from ..simulation import rig as rigmod


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser('design', help='experiment-design check: rank per speed of a probe set and excitation plan, '
                                      'and what to add to determine all 16 coefficients',
                       description='For a probe set and an excitation plan, print per speed the rank and condition '
                                   'of the identification (the 16 coefficients from the measured 1X vectors, '
                                   'linearised at the theory), the coefficient combinations the data cannot fix, '
                                   'and the probes or directional forces that would fix them.')
    p.add_argument('--params', help='rig YAML (default: the packaged params/rig.yaml)')
    p.add_argument('--probes', help="probe list like 6x,6y (default: the params' probes)")
    p.add_argument('--scenario', default='default',
                   help='default (the runs in the params file), paper_table3, paper_table4 or force')
    p.add_argument('--speeds', help='comma-separated speeds in rpm (default: simulation.speeds_rpm)')
    p.add_argument('--noise', type=float, default=0.01,
                   help='probe noise as a fraction of the signal RMS (default 0.01)')
    p.add_argument('--samples', type=int, default=20480, help='samples per 1X vector (default 20480 = 2 s)')
    return p


def run(args) -> int:
    rig = load_rig(args.params)
    probes = parse_probes(args.probes) if args.probes else rig.probes
    if not probes:
        raise ParamError('no probes: give --probes or list probes in the params file')
    runs = (rig.simulation.runs if args.scenario == 'default' and rig.simulation else rigmod.scenario(args.scenario))
    if args.speeds:
        try:
            rpm = [float(s) for s in args.speeds.split(',')]
        except ValueError:
            raise ParamError(f'--speeds must be comma-separated rpm values, got {args.speeds!r}') from None
    elif rig.simulation:
        rpm = list(rig.simulation.speeds_rpm)
    else:
        raise ParamError('give --speeds (the params file has no simulation.speeds_rpm)')
    if any(s <= 0 for s in rpm):
        raise ParamError('--speeds: every speed must be > 0 rpm')
    if not 0 < args.noise < 1 or args.samples < 16:
        raise ParamError('--noise must be in (0, 1) and --samples >= 16')
    model = RotorModel.from_params(rig)
    reports = check_design(model, probes, runs, [float(rpm_to_rad_s(s)) for s in rpm], bearing_fn(rig),
                           sample_noise=args.noise, n_samples=args.samples)
    print(f"probes {', '.join(p.name for p in probes)}; runs {', '.join(r.id for r in runs)}; "
          f'noise {args.noise:g} x RMS over {args.samples} samples; linearised at the nominal bearing theory')
    for r in reports:
        print(r.summary())
    full = all(r.data.rank == r.data.unknowns for r in reports)
    print('the plan determines all 16 coefficients at every speed' if full else
          'the plan does NOT determine all 16 coefficients at every speed (see the advice above; the physical '
          'method needs only the 4 bearing parameters and is determined by far less)')
    return 0 if full else 1
