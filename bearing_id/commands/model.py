"""
``bearing-id model``: the rotor-bearing model of a params file.

Natural frequencies, critical speeds, stability threshold, bearing coefficients vs speed, Campbell diagram, and the
Table-2 model-updating table.

Prints tables (rpm, Hz, N/m, N s/m) and writes ``campbell.png`` (0.5X / 1X / 2X lines, log-decrement colour,
labelled critical speeds and stability threshold), ``coefficients.png`` (one panel per coefficient, each bearing in
its own style), ``mode_shapes.png`` (at the critical speeds) and ``model.json`` (SI units:
rad/s, N/m, N s/m, plus rpm/Hz copies for people) into ``--out``.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from ..config.params import load_rig, ParamError
from ..conventions import COEFF_ORDER, RPM_PER_RAD_S, rpm_to_rad_s
from ..plots.campbell import campbell_figure, mode_shapes_figure
from ..plots.coefficients import theory_coefficients_figure
from ..plots.common import save_png
from ..plots.data import campbell_data, CampbellData, critical_mode_index, CRITICALLY_DAMPED, mode_shapes
from ..rotor import supports
from ..rotor.assembly import RotorModel, static_bearing_loads
from ..rotor.modal import free_free_frequencies, modes_below, modes_solver
from ..rotor.updating import update_model

TWO_PI = 2.0 * math.pi


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser('model', help='natural frequencies, critical speeds, stability, bearing coefficients, '
                                     'Campbell diagram and model updating of a rig',
                       description='Analyse the FE rotor-bearing model described by --params: free-free and '
                                   'on-bearing natural frequencies, critical speeds, the stability threshold (oil '
                                   "whip), bearing coefficients vs speed, a Campbell diagram, and the paper's "
                                   'Table-2 model updating against modal_test.measured_hz.')
    p.add_argument('--params', help='rig YAML (default: the packaged params/rig.yaml)')
    p.add_argument('--out', default='out/model', help='directory for campbell.png, coefficients.png, '
                                                      'mode_shapes.png, model.json (default out/model)')
    p.add_argument('--max-rpm', type=float, default=None,
                   help='upper end of the speed range for Campbell, critical speeds and stability [rpm] '
                        "(default: the machine's -- twice its top simulation speed or the last row of its bearing "
                        'and seal tables, whichever is higher; 6000 when it has neither)')
    p.add_argument('--speeds', help='comma-separated speeds [rpm] for the coefficient and mode tables '
                                    '(default: simulation.speeds_rpm)')
    p.add_argument('--modes', type=int, default=None,
                   help="number of modes to report and search for critical speeds (default: the machine's -- every "
                        'mode below 1.25 x the top speed at either end of the range, plus 2; at least 6)')
    p.add_argument('--no-update', action='store_true', help='skip the model updating (Table 2)')
    return p


def _speeds(args, rig):
    if args.speeds:
        try:
            v = [float(s) for s in args.speeds.split(',') if s.strip()]
        except ValueError:
            raise ParamError(f'--speeds must be comma-separated rpm values, got {args.speeds!r}') from None
    elif rig.simulation is not None:
        v = list(rig.simulation.speeds_rpm)
    else:
        v = list(np.linspace(args.max_rpm / 10, args.max_rpm, 10))
        tables = [b.table.speeds for b in _tables(rig)]
        if tables:       # where the tables say something: from the first row of any to the last of any
            lo, hi = min(t[0] for t in tables) * RPM_PER_RAD_S, max(t[-1] for t in tables) * RPM_PER_RAD_S
            v = list(np.linspace(lo, min(hi, args.max_rpm), 10))
    if not v or any(s <= 0 for s in v):
        raise ParamError('--speeds: every speed must be > 0 rpm (no hydrodynamic film at standstill)')
    return v


def _tables(rig) -> list:
    """Return the bearings and seals (identified or known) that are tables of more than one row."""
    return [b for b in tuple(rig.bearings) + tuple(rig.known_elements())
            if b.model == 'table' and b.table is not None and len(b.table.speeds) > 1]


def machine_max_rpm(rig) -> float:
    """
    Return the machine's speed range top [rpm]: twice its top simulation speed or its tables' last row, the higher.

    6000 rpm (the paper rig's range) when the params give neither.
    """
    cand = [2.0 * max(rig.simulation.speeds_rpm)] if rig.simulation is not None and rig.simulation.speeds_rpm else []
    cand += [b.table.speeds[-1] * RPM_PER_RAD_S for b in _tables(rig)]
    return float(max(cand)) if cand else 6000.0


MODES_ABOVE_TOP = 1.25     # modes below this x the top speed can reach the 1X line within the range: all searched
MODES_MIN, MODES_MAX = 6, 24


def machine_modes(rig, max_rpm: float) -> int:
    """
    Return the number of modes ``model`` needs on this machine: every mode below 1.25 x the top speed, plus 2.

    Counted on the bearings at the two ends of the range (the film or table stiffens or softens the modes with speed);
    at least 6 (the lowest bending pairs), at most 24.
    """
    model, bfn = RotorModel.from_params(rig), supports.bearing_fn(rig)
    lo, hi = float(rpm_to_rad_s(max(50.0, max_rpm / 60))), float(rpm_to_rad_s(max_rpm))
    count = max(modes_below(model, bfn, w, MODES_ABOVE_TOP * hi) for w in (lo, hi))
    return int(min(MODES_MAX, max(MODES_MIN, count + 2)))


def analyse(rig, speeds_rpm, max_rpm=6000.0, n_modes=6, update=True) -> dict:
    """Everything the command prints, as a dict (SI, with rpm/Hz copies)."""
    model = RotorModel.from_params(rig)
    bfn = supports.bearing_fn(rig)
    out: dict = {'rig': rig.name, 'mass_kg': model.mass, 'n_nodes': model.n_nodes, 'n_elements': len(model.elements),
                 'ndof': model.ndof,
                 'static_loads_N': {str(k): v for k, v in static_bearing_loads(model).items()},
                 'known_elements': [{'name': b.name, 'node': b.node, 'kind': b.model} for b in model.known]}
    ff = free_free_frequencies(model, 4)
    out['free_free_hz'] = (ff / TWO_PI).tolist()
    lo, hi = float(rpm_to_rad_s(max(50.0, max_rpm / 60))), float(rpm_to_rad_s(max_rpm))
    modes = modes_solver(model, max([hi, *rpm_to_rad_s(np.asarray(speeds_rpm, float))]), bfn, n_modes)
    rows = []
    for rpm in speeds_rpm:
        W = float(rpm_to_rad_s(rpm))
        co = bfn(W)
        m = modes(W, co, n_modes)
        rows.append({'speed_rpm': rpm, 'speed': W,
                     'bearings': {str(n): {'K': np.asarray(k).tolist(), 'C': np.asarray(c).tolist()}
                                  for n, (k, c) in co.items()},
                     'modes_hz': (m.frequency / TWO_PI).tolist(), 'log_dec': m.log_dec.tolist(),
                     'whirl': list(m.whirl)})
    out['speeds'] = rows
    cd = campbell_data(model, bfn, hi, min_speed=lo, n_modes=n_modes, n_grid=40, solver=modes)
    out['campbell'] = {'speeds_rpm': cd.speeds_rpm.tolist(), 'frequency_hz': cd.frequency_hz.tolist(),
                       'log_dec': cd.log_dec.tolist(), 'whirl': cd.whirl.tolist()}
    out['critical_speeds_rpm'] = cd.critical_rpm.tolist()
    out['critical_damping_ratio'] = cd.critical_zeta.tolist()     # of the forward mode crossing 1X (AF ~ 1/2 zeta)
    out['critically_damped_crossings_rpm'] = cd.damped_crossings_rpm.tolist()
    out['critically_damped_zeta'] = cd.damped_crossings_zeta.tolist()
    out['stability_threshold_rpm'] = cd.threshold_rpm
    out['stability_whirl_ratio'] = cd.threshold_ratio            # whirl frequency / speed of the mode going unstable
    out['notes'] = list(cd.notes)
    for b in _tables(rig):
        t = b.table
        if lo < t.speeds[0] or hi > t.speeds[-1]:
            out['notes'].append(f'{b.name}: its table covers {t.speeds[0] * RPM_PER_RAD_S:.0f}-'
                                f'{t.speeds[-1] * RPM_PER_RAD_S:.0f} rpm; outside, its first / last row is held')
    if update and rig.modal_test is not None and rig.modal_test.measured_hz:
        res = update_model(rig, rig.modal_test.measured_hz, maxiter=1500)
        out['updating'] = {'table': res.table(), 'factors': res.factors, 'initial_hz': res.initial_hz.tolist(),
                           'measured_hz': res.measured_hz.tolist(), 'updated_hz': res.updated_hz.tolist(),
                           'condition': res.condition,
                           'paper_initial_hz': list(rig.modal_test.paper_initial_hz),
                           'paper_updated_hz': list(rig.modal_test.paper_updated_hz)}
    return out


def _print_report(r: dict) -> None:
    print(f"rig {r['rig']}: rotor mass {r['mass_kg']:.3f} kg; static bearing loads "
          + ', '.join(f'node {k}: {v:.2f} N' for k, v in r['static_loads_N'].items()))
    print('free-free bending frequencies [Hz]: ' + ', '.join(f'{f:.2f}' for f in r['free_free_hz']))
    print('\nnatural frequencies on the bearings [Hz] (damped; F forward, B backward whirl; log dec):')
    for row in r['speeds']:
        modes = '  '.join(f'{f:7.2f}{w[0].upper()}({d:+.2f})' for f, w, d in
                          zip(row['modes_hz'], row['whirl'], row['log_dec']))
        print(f"  {row['speed_rpm']:7.0f} rpm  {modes}")
    crit = r['critical_speeds_rpm']
    print(f'\ncritical speeds (forward whirl = 1X, damping ratio <= {CRITICALLY_DAMPED:g}) [rpm] (damping ratio): '
          + (', '.join(f'{c:.0f} ({z:.2f})' for c, z in zip(crit, r['critical_damping_ratio'])) or 'none in range'))
    if r.get('critically_damped_crossings_rpm'):
        pairs = zip(r['critically_damped_crossings_rpm'], r['critically_damped_zeta'])
        print(f'critically damped 1X crossings (damping ratio > {CRITICALLY_DAMPED:g}, API 684: not critical speeds) '
              '[rpm]: ' + ', '.join(f'{c:.0f} ({z:.2f})' for c, z in pairs))
    thr = r['stability_threshold_rpm']
    wr = r.get('stability_whirl_ratio')
    print('stability threshold (onset of oil whip) [rpm]: ' + (f'{thr:.0f}' + (f' (the unstable mode whirls at '
                                                                               f'{wr:.2f}X)' if wr else '')
                                                               if thr is not None else 'none in range'))
    for n in r.get('notes', []):
        print(f'  note: {n}')
    print('\nbearing coefficients vs speed (K [N/m], C [N s/m], order ' + ' '.join(COEFF_ORDER) + '):')
    hdr = f"{'rpm':>7} {'node':>4} " + ' '.join(f"{'K' + c:>11}" for c in COEFF_ORDER) + ' ' + \
        ' '.join(f"{'C' + c:>10}" for c in COEFF_ORDER)
    print(hdr)
    for row in r['speeds']:
        for node, kc in row['bearings'].items():
            K = np.asarray(kc['K']).ravel()
            C = np.asarray(kc['C']).ravel()
            print(f"{row['speed_rpm']:7.0f} {node:>4} " + ' '.join(f'{v:11.4g}' for v in K) + ' '
                  + ' '.join(f'{v:10.4g}' for v in C))
    if 'updating' in r:
        u = r['updating']
        print('\nmodel updating against the measured free-free frequencies (paper Table 2 layout):')
        print(u['table'])
        if u['paper_initial_hz']:
            print("paper's own initial / updated model [Hz]: "
                  + ', '.join(f'{a:.2f}' for a in u['paper_initial_hz']) + ' / '
                  + ', '.join(f'{a:.2f}' for a in u['paper_updated_hz'])
                  + "  (Table 1 geometry gives the 'initial' column above: the paper's rig differs from its table)")


def campbell_from_report(r: dict):
    """Return the :class:`bearing_id.plots.data.CampbellData` of an :func:`analyse` dict (what campbell.png draws)."""
    cb = r['campbell']
    rpm = np.array(cb['speeds_rpm'], float)
    thr = r['stability_threshold_rpm']
    return CampbellData(speeds=rpm_to_rad_s(rpm), frequency=np.array(cb['frequency_hz'], float) * TWO_PI,
                        log_dec=np.array(cb['log_dec'], float), damping_ratio=np.full(np.shape(cb['log_dec']), np.nan),
                        whirl=np.array(cb['whirl'], dtype=object),
                        critical=rpm_to_rad_s(np.array(r['critical_speeds_rpm'], float)),
                        critical_zeta=np.array(r['critical_damping_ratio'], float),
                        threshold=(float(rpm_to_rad_s(thr)) if thr is not None else
                                   (None if r.get('notes') else math.inf)),
                        threshold_ratio=r.get('stability_whirl_ratio'), label='theory (nominal params)',
                        damped_crossings=rpm_to_rad_s(np.array(r.get('critically_damped_crossings_rpm', []), float)),
                        damped_crossings_zeta=np.array(r.get('critically_damped_zeta', []), float))


def _plots(r: dict, out: Path, rig=None) -> list[Path]:
    """campbell.png, coefficients.png and (with ``rig``) mode_shapes.png at the critical speeds."""
    cd = campbell_from_report(r)
    rows = r['speeds']
    paths = [save_png(campbell_figure(cd, measured_rpm=[row['speed_rpm'] for row in rows],
                                      speeds_label='table speeds (--speeds)',
                                      title=f"Campbell diagram - {r['rig']} (theory, nominal params)"),
                      out / 'campbell.png', dpi=110)]
    nodes = list(rows[0]['bearings'])
    coeffs = {int(n): (np.array([row['bearings'][n]['K'] for row in rows], float),
                       np.array([row['bearings'][n]['C'] for row in rows], float)) for n in nodes}
    names = {b.node: b.name for b in rig.bearings} if rig is not None else None
    paths.append(save_png(theory_coefficients_figure([row['speed_rpm'] for row in rows], coeffs, names),
                          out / 'coefficients.png', dpi=110))
    if rig is not None and cd.critical.size:
        model = RotorModel.from_params(rig)
        bfn = supports.bearing_fn(rig)
        sh = []
        modes = modes_solver(model, float(np.max(cd.critical[:3])), bfn, 4)
        for w in cd.critical[:3]:
            m = mode_shapes(model, bfn, w, 4, solver=modes)
            sh.append((f'{w * 60 / TWO_PI:.0f} rpm (critical)', m, critical_mode_index(m, w)))
        paths.append(save_png(mode_shapes_figure(sh, bearing_nodes=model.bearing_nodes,
                                                 disc_nodes=[d.node for d in rig.discs]),
                              out / 'mode_shapes.png', dpi=110))
    return paths


def run(args) -> int:
    rig = load_rig(args.params)
    if args.max_rpm is None:
        args.max_rpm = machine_max_rpm(rig)
        print(f"speed range: up to {args.max_rpm:.0f} rpm (the machine's; --max-rpm sets another)")
    if args.max_rpm <= 0:
        raise ParamError('--max-rpm must be > 0')
    if args.modes is None:
        args.modes = machine_modes(rig, args.max_rpm)
        print(f'modes: {args.modes} (every mode below {MODES_ABOVE_TOP:g} x the top speed, plus 2; --modes sets '
              'another)')
    if args.modes < 1:
        raise ParamError('--modes must be >= 1')
    r = analyse(rig, _speeds(args, rig), max_rpm=args.max_rpm, n_modes=args.modes, update=not args.no_update)
    _print_report(r)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'model.json').write_text(json.dumps(r, indent=1, default=float) + '\n')
    paths = _plots(r, out, rig)
    print('\nwrote ' + ', '.join(str(p) for p in paths + [out / 'model.json']))
    return 0
