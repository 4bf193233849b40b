"""
``bearing-id identify``: bearing coefficients per speed from recordings (.npz per run, or a bag), offline.

Exit codes: 0 every printed coefficient is determined by the data (or --allow-undetermined / --allow-misfit was
given); 1 some coefficient is not determined by the data, or the model misfits the data (they are named, never printed
as numbers); 2 bad input.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import sys

import numpy as np

from .inputs import attach_excitation, check_probe_nodes, check_probes_against_params, InputError, load_recordings
from .report import build_report
from ..config import defaults
from ..config.params import load_rig, ParamError
from ..identify import harmonics, identify, METHODS
from ..identify.paper import bearing_dofs, forces_at
from ..identify.result import format_results
from ..plots import plot_bearing_vectors, plot_coefficients
from ..rotor.assembly import harmonic_response, RotorModel
from ..rotor.supports import bearing_fn
from ..signals.recording import RecordingError


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser('identify', help='identify the bearing stiffness and damping coefficients per speed',
                       description='Identify K [N/m] and C [N s/m] of each bearing per steady speed from .npz '
                                   'recordings (one file per excitation run) or a bag. Coefficients the data do '
                                   'not determine are named and the command exits 1 unless --allow-undetermined; '
                                   'a model that misfits the data determines nothing (exit 1 unless --allow-misfit).')
    p.add_argument('inputs', nargs='+', help='.npz or .csv recordings (one per run) or one bag directory')
    p.add_argument('--params', help='rig YAML (default: the packaged params/rig.yaml)')
    p.add_argument('--method', default=defaults.METHOD, choices=METHODS,
                   help='auto (default): direct where the data determine every coefficient at every speed (the '
                        'design check on these data), else physical; the method that ran and why lead the notes')
    p.add_argument('--json', help='write the results to this JSON file')
    p.add_argument('--plot', help='write the coefficients-vs-speed plot (PNG); with --method paper also '
                                  '<name>_bearing_vectors.png: KF bearing-node amplitude/phase vs speed (and the '
                                  'truth when the recordings carry it)')
    p.add_argument('--report', metavar='DIR', help='also write DIR/report.html: one self-contained page with the '
                                                   'Campbell diagram, mode shapes, Bode / polar / orbit / spectrum '
                                                   'plots, the coefficients vs speed and these tables')
    p.add_argument('--allow-undetermined', action='store_true',
                   help="print prior-dominated (undetermined) values, flagged '(prior)', and exit 0")
    p.add_argument('--allow-misfit', action='store_true',
                   help='where the model misfits the data, print the values the fit would determine, flagged '
                        "'(misfit)' with their Birge-scaled 1-sigma (a lower bound), and exit 0")
    p.add_argument('--Q', type=float, default=None,
                   help=f'paper method: KF process noise (default {defaults.KF_PROCESS_NOISE:g})')
    p.add_argument('--R', type=float, default=None, metavar='STD_M',
                   help="paper method: the KF's probe noise std in metres, R = value^2 for every probe (default: "
                        "each window's residual around its plain 1X fit; the identifier node's "
                        'kf_measurement_noise)')
    red = p.add_mutually_exclusive_group()
    red.add_argument('--reduce', action='store_true',
                     help='paper method: Kalman filter on a Craig-Bampton reduced model (bearing, probe and force '
                          'DOFs kept; its 1X receptance error per speed in the notes); the default for models of '
                          'more than 88 states')
    red.add_argument('--no-reduce', action='store_true', help='paper method: the Kalman filter on the full model')
    p.add_argument('--bearing-model', choices=('short', 'finite'), default=None,
                   help="physical method: the estimator's bearing model, short (Ocvirk) or finite (finite-length "
                        "Reynolds); default: each bearing's model in the params file")
    return p


def load_data(inputs, rig=None, *, stream: bool = True):
    """
    Load HarmonicData from .npz / .csv recordings (one per run) or one bag; ParamError (exit 2) for any bad input.

    With ``rig``, a recording without excitation (a CSV export) takes that of the params' run of the same id.  The
    windows' 1X fits run in this process (a worker pool saved 0.25 s of 1.75 s on the 2-core machine: not worth one).
    ``stream`` (default): .npz recordings are read piece by piece into the 1X fits, window by window (a recording of
    any length in bounded memory; its values checked as they are read); else each is read whole first (what needs
    the time series afterwards: the paper method's filter, the report).  CSV files and bags are read whole.
    """
    recs = load_recordings(inputs, one_bag_only=True, stream=stream)
    if rig is not None:
        check_probes_against_params(recs, rig)
        recs = attach_excitation(recs, rig, required=True)
    try:
        return harmonics.from_recordings(recs)
    except RecordingError as exc:       # a value of a recording read piece by piece (the message names the file)
        raise InputError(str(exc)) from None
    except ValueError as exc:
        raise InputError(f"{', '.join(map(str, inputs))}: {exc}") from None


def _add_honesty(d: dict, r) -> None:
    """Per-bearing theory sensitivity / interpolation bias (2x2 per K and C) and the theory fraction, into ``d``."""
    nb = len(r.nodes)
    for key, name in (('theory_sensitivity', 'theory_sensitivity'), ('interpolation_bias', 'interpolation_bias')):
        v = r.extra.get(key)
        if v is None:
            continue
        v = np.asarray(v, dtype=float)
        for i, b in enumerate(d['bearings']):
            b[name] = {'K': v[4 * i:4 * i + 4].reshape(2, 2).tolist(),
                       'C': v[4 * nb + 4 * i:4 * nb + 4 * i + 4].reshape(2, 2).tolist()}
    if 'theory_fraction' in r.extra:
        d['theory_fraction'] = float(r.extra['theory_fraction'])


def bearing_vectors_plot(model, data, results, plot_path):
    """Plot the paper's Figs 5-6: KF bearing-node 1X vectors per run vs speed, the truth's when known -> PNG path."""
    if not results or any('z_B' not in r.extra for r in results):
        return None
    est = np.stack([np.asarray(r.extra['z_B']) for r in results], axis=1)          # (nr, ns, nb, 2)
    true = None
    if all(data.truth_at(r.speed) is not None for r in results):
        true = np.zeros_like(est)
        b = bearing_dofs(model)
        for s, r in enumerate(results):
            for k, F in enumerate(forces_at(model, data.runs, r.speed)):
                true[k, s] = harmonic_response(model, r.speed, r.speed, F, data.truth_at(r.speed))[b].reshape(-1, 2)
    p = Path(plot_path)
    out = p.with_name(p.stem + '_bearing_vectors' + (p.suffix or '.png'))
    return plot_bearing_vectors([r.speed for r in results], est, out, true=true, nodes=tuple(results[0].nodes),
                                labels=('KF estimate', 'true'), run_labels=[str(run.id) for run in data.runs],
                                title='bearing-node 1X displacement: Kalman filter (theory model) vs true')


def _only(flag: str, method: str) -> ParamError:
    return ParamError(f'{flag} applies to --method {method} only (name it: the default, auto, chooses between direct '
                      'and physical)')


def run(args) -> int:
    rig = load_rig(args.params)
    # every input checked before the heavy imports; read whole only for what needs the time series afterwards
    data = load_data(args.inputs, rig, stream=not (args.report or args.method == 'paper'))
    model = RotorModel.from_params(rig)
    check_probe_nodes(data.recordings, model.n_nodes)
    opts = {}
    if args.Q is not None:
        if args.method != 'paper':
            raise _only('--Q', 'paper')
        opts['Q'] = args.Q
    if args.R is not None:
        if args.method != 'paper':
            raise _only('--R', 'paper')
        if not (math.isfinite(args.R) and args.R ** 2 > 0):
            raise ParamError(f'--R must be a probe noise std > 0 in metres, got {args.R!r}')
        opts['R'] = args.R ** 2
    if args.reduce or args.no_reduce:
        if args.method != 'paper':
            raise _only('--reduce' if args.reduce else '--no-reduce', 'paper')
        opts['reduce'] = bool(args.reduce)
    if args.bearing_model is not None:
        if args.method not in ('physical', 'auto'):
            raise _only('--bearing-model', 'physical')
        opts['bearing_model'] = args.bearing_model
    if args.method == 'auto':               # auto's options are per method: a bearing model is physical's
        opts = {'physical': opts} if opts else {}
    try:
        results = identify(args.method, model, rig, data, options=opts or None)
    except ValueError as exc:   # the data cannot feed this method (e.g. conventional without two probes per bearing)
        raise ParamError(f'--method {args.method}: {exc}') from exc
    ran = results[0].method if results else args.method
    if args.method == 'auto' and results:
        print(f"method: {ran} (auto: {results[0].extra['auto']['reason']})")
    print('units: speed rpm, K N/m, C N s/m')
    print(format_results(results, args.allow_undetermined, args.allow_misfit))
    undet = [(r.speed_rpm, r.undetermined_names()) for r in results if not r.fully_determined and not r.misfit]
    misfit = [r.speed_rpm for r in results if r.misfit]
    if args.json:
        out = []
        for r in results:
            d = r.to_dict()
            if not (args.allow_misfit if r.misfit else args.allow_undetermined):  # undetermined: never a number
                for b in d['bearings']:
                    for sym in ('K', 'C'):
                        b[sym] = [[v if ok else None for v, ok in zip(row, okr)]
                                  for row, okr in zip(b[sym], b['determined'][sym])]
            _add_honesty(d, r)
            out.append(d)
        Path(args.json).write_text(json.dumps({'method': ran, 'requested': args.method, 'results': out}, indent=1))
    if args.plot:
        plot_coefficients(results, args.plot, truth_fn=data.truth or None, theory_fn=bearing_fn(rig),
                          title=f'method {ran}')
        if ran == 'paper':
            p = bearing_vectors_plot(model, data, results, args.plot)
            if p is not None:
                print(f'bearing-node vectors plot: {p}')
    if args.report:
        info = build_report(rig, data.recordings, args.report, data=data, results=results,
                            allow_undetermined=args.allow_undetermined,
                            command='bearing-id identify ' + ' '.join(args.inputs) + f' --method {args.method}')
        print(f'report: {info.path}')
    rc = 0
    if misfit:
        print('\nMODEL MISFIT (the model does not reproduce the data within their noise: nothing determined'
              + (", values printed flagged '(misfit)'" if args.allow_misfit else ', not printed') + '): '
              f"{', '.join(f'{rpm:.0f}' for rpm in misfit)} rpm", file=sys.stderr)
        if not args.allow_misfit:
            print('exit 1: see the MODEL MISFIT note for the likely cause; `bearing-id diagnose` looks for the missing '
                  'physics; --allow-misfit prints the values flagged', file=sys.stderr)
            rc = 1
    if undet:
        print('\nUNDETERMINED by the data (prior/theory-dominated'
              + (", printed flagged '(prior)'" if args.allow_undetermined else ', not printed') + '):',
              file=sys.stderr)
        for rpm, names in undet:
            print(f"  {rpm:.0f} rpm: {', '.join(names)}", file=sys.stderr)
        if not args.allow_undetermined:
            hint = ('' if ran == 'physical' else
                    '--method physical (a bearing model fitted across all speeds, which unbalance runs at one probe '
                    'station determine), ')
            print(f'exit 1: try {hint}add probes or directional-force runs (`bearing-id design` says which), or pass '
                  '--allow-undetermined to print prior-dominated values flagged', file=sys.stderr)
            rc = 1
    return rc
