"""
``bearing-id diagnose``: locate where recordings and the model disagree, name the missing physics, model it.

Exit codes: 0 a verdict was reached ('none' included), 2 bad input.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from .inputs import attach_excitation, check_probe_nodes, check_probes_against_params, load_recordings
from .report import report_for_diagnosis
from ..config import defaults
from ..config.params import load_rig, ParamError
from ..diagnose import diagnose
from ..diagnose.reidentify import format_table, reidentify
from ..diagnose.report import augmented_rig, write_json, write_params, write_summary

EPILOG = """\
what is printed:
  verdict: NAME | [NAME, NAME] | none
      the effects selected (greedy, each lowering the BIC by more than 10 and validated on held-out data),
      then one sentence per effect: where it is, its key parameters +-1 sigma (or "not determined by these data"
      with what the data do fix), the share of the residual power explained (RMS in units of sigma before ->
      after), the noise-floor check (identify's MODEL MISFIT test on identify's 1X vectors: chi2/dof against the
      99.9 % limit), hypotheses that lowered the BIC but failed held-out validation, and the bearing viscosity /
      clearance factors refitted as nuisance.
  located mismatch (largest first):
      probe (node, direction), harmonic order (1X, 2X, 3X, sub-synchronous, slow roll), the largest residual
      |measured - model| [um], its significance [in sigma = sqrt(noise^2 + (rel-tol |X|)^2 + (0.003 |X_1X|)^2)]
      and the speeds [rpm] where it is significant (against the nominal model with refitted bearings).
  hypotheses (first step, best BIC first):
      every candidate effect fitted alone: effect, where, dBIC (BIC of "none" minus its BIC; > 10 counts),
      the share of the residual power it explains, and whether it passed held-out validation.
  with --identify: the bearing coefficients per speed identified on the nominal and on the augmented model
      (and the truth and the eq. 38 errors when the recordings are simulated).
  with --json / --report / --augmented: the paths written.
"""


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser('diagnose', help='find the physics the model leaves out (support flexibility, unbalance, bow, '
                                        'runout, misalignment, oil whirl, probe orientation, disc mass)',
                       description='Compare recordings with the model of --params (harmonic vectors per probe, '
                                   'order and speed, sub-synchronous lines, slow roll), fit candidate effects, rank '
                                   'them by BIC with held-out validation, check the result at the noise floor, and '
                                   'print the verdict; optionally write the JSON, the augmented params file and a '
                                   'report page with the before / after.',
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('recordings', nargs='+', help='recording files: .npz (bearing-id simulate / DAQ export), .csv '
                                                 '(DAQ export) or a bag directory (one run per /rotor/excitation)')
    p.add_argument('--params', help='nominal rig YAML (default: the packaged params/rig.yaml)')
    p.add_argument('--json', help='write the diagnosis JSON here')
    p.add_argument('--report', metavar='DIR',
                   help='write DIR/report.html (one self-contained page: the bearing-id report figures plus the '
                        'diagnosis before / after and its tables), every figure as a PNG next to it, '
                        'DIR/summary.txt and DIR/augmented_params.yaml')
    p.add_argument('--augmented', help='path of the augmented params YAML (default: REPORT/augmented_params.yaml, '
                                       'or next to --json)')
    p.add_argument('--held-out', choices=('speeds', 'runs'), default='speeds',
                   help='validation split: alternate speeds (default) or alternate recordings')
    p.add_argument('--rel-tol', type=float, default=0.02,
                   help='model tolerance as a fraction of the measured amplitude (default 0.02)')
    p.add_argument('--identify', metavar='METHOD', choices=('physical', 'direct'),
                   help='re-run identification with METHOD (physical or direct) on the nominal and on the augmented '
                        'model (measurement effects removed from the data, force effects added to the excitation, '
                        'flexible supports / disc corrections in the dynamic stiffness) and print both, with their '
                        'error vs truth when the recordings carry it')
    p.add_argument('--fixed-bearings', action='store_true',
                   help='trust the nominal bearing theory (do not refit viscosity/clearance factors as nuisance)')
    p.add_argument('--no-noise-floor', action='store_true',
                   help="skip the noise-floor check (identify's MODEL MISFIT test on identify's 1X vectors, and the "
                        'bearing model forms tried there when it trips): faster, but a model-form error below the '
                        '--rel-tol tolerance then goes unreported, and effect parameters are not refined on '
                        "identify's vectors")
    return p


def run(args) -> int:
    if not 0 <= args.rel_tol < 1:
        raise ParamError('--rel-tol must be in [0, 1)')
    rig = load_rig(args.params)
    recs = load_recordings(args.recordings)
    check_probes_against_params(recs, rig)
    recs = attach_excitation(recs, rig, required=False)   # checked before the heavy work
    check_probe_nodes(recs, rig.shaft.n_nodes)
    try:
        d = diagnose(recs, rig, held_out=args.held_out, rel_tol=args.rel_tol, nuisance=not args.fixed_bearings,
                     noise_floor=not args.no_noise_floor)
    except ValueError as exc:
        raise ParamError(f'cannot diagnose these recordings: {exc}') from None
    aug = args.augmented or (Path(args.report) / 'augmented_params.yaml' if args.report else
                             (Path(args.json).with_name(Path(args.json).stem + '_augmented_params.yaml')
                              if args.json else None))
    if aug is not None:
        write_params(d, rig, aug)
    out = [f'verdict: {d.verdict}']
    out += [f'  {s}' for s in d.sentences]
    if d.mismatch:
        out.append('located mismatch (largest first):')
        for m in d.mismatch[:8]:
            out.append(f'  {m.where:32s} {m.order:34s} {m.size * 1e6:9.3g} um {m.significance:7.1f} sigma  at '
                       + ', '.join(f'{s:.0f}' for s in m.speeds_rpm) + ' rpm')
    out.append('hypotheses (first step, best BIC first):')
    for h in [h for h in d.hypotheses if h['step'] == 0][:8]:
        out.append(f"  {h['effect']:20s} {h['where']:40s} dBIC {h['delta_bic']:10.1f}  explains "
                   f"{h['explained_fraction']:6.1%}  validated {h['validated']}")
    for line in out:
        print(line)
    if args.json:
        write_json(d, args.json)
        print(f'wrote {args.json}')
    ri = None
    if args.identify:
        try:
            ri = reidentify(recs, rig, augmented_rig(d, rig), args.identify, data=d.harmonic_data)
        except ValueError as exc:
            raise ParamError(f'cannot re-run identification: {exc}') from None
        table = format_table(ri)
        out += table
        for line in table:
            print(line)
        if args.json:
            j = json.loads(Path(args.json).read_text())
            j['identification'] = ri.as_json()
            Path(args.json).write_text(json.dumps(j, indent=2, default=float))
    if args.report:
        files = [write_summary(d, args.report)]
        info = report_for_diagnosis(d, recs, rig, args.report, reidentification=ri,
                                    method=args.identify or defaults.METHOD, cli_text='\n'.join(out),
                                    command='bearing-id diagnose ' + ' '.join(args.recordings), write_png=True,
                                    data=d.harmonic_data)
        for n in info.notes:
            print(f'note: {n}')
        print(f'wrote {len(files) + info.n_figures} report files to {args.report}')
        print(f'report page: {info.path} ({info.n_figures} figures, {info.seconds:.1f} s)')
    if aug is not None:
        print(f'augmented params: {aug}')
    return 0
