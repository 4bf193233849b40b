"""
``bearing-id report``: one self-contained HTML page per run of the machine -- the pictures a rotordynamicist reads.

The page (``report.html`` in ``--out``; images embedded as base64 PNG, no network) holds the machine summary and
every figure the data support: Campbell diagram (0.5X / 1X / 2X, log decrement, critical speeds, stability
threshold), mode shapes at the critical speeds, 1X Bode and polar plots per probe (measured +- 1 sigma, the model as
a continuous curve, rpm labels), orbits (unfiltered and 1X, keyphasor), spectrum cascades, the shaft centreline in
the clearance circle, the identified coefficients vs speed with 1-sigma bands next to the theory, a diagnosis
before / after (``diagnose --report``), and the tables the CLI prints.

:func:`build_report` is the library entry; ``identify --report`` and ``diagnose --report`` call it with what they
already computed.  Exit codes: 0 page written, 2 bad input.
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass, field
import math
from pathlib import Path
import time

import numpy as np

from .inputs import attach_excitation, check_probe_nodes, check_probes_against_params, load_recordings
from .model import machine_modes
from ..config import defaults
from ..config.params import load_rig, ParamError
from ..conventions import COEFF_ORDER, RPM_PER_RAD_S, rpm_to_rad_s
from ..diagnose.reidentify import format_table
from ..excitation import harmonic_forces
from ..identify import harmonics, identify, METHODS
from ..identify.result import format_results, undetermined_label
from ..plots import data as fd
from ..plots.campbell import campbell_figure, mode_shapes_figure
from ..plots.centreline import centreline_figure
from ..plots.coefficients import coefficients_figure
from ..plots.common import png_bytes, probe_text
from ..plots.diagnosis import diagnosis_bode_figure, residual_orders_figure
from ..plots.html import esc, Page
from ..plots.orbits import orbits_figure
from ..plots.response import bode_figure, Curve, polar_figure
from ..plots.spectrum import waterfall_figure
from ..rotor import supports
from ..rotor.assembly import RotorModel
from ..rotor.modal import modes_solver

REPORT_NAME = 'report.html'
METHOD_CHOICES = METHODS + ('none',)


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser('report', help='write one self-contained HTML report (Campbell, mode shapes, Bode, polar, '
                                      'orbits, spectra, centreline, coefficients) for recordings',
                       description='Analyse recordings (.npz / .csv per run, or a bag) against the model of --params '
                                   'and write DIR/report.html: the machine summary, every figure the data support '
                                   'and the tables the CLI prints, images embedded (the page needs no network).')
    p.add_argument('inputs', nargs='+', help='.npz or .csv recordings (one per run) or bag directories')
    p.add_argument('--out', default='out/report', help='output directory (default out/report)')
    p.add_argument('--params', help='rig YAML (default: the packaged params/rig.yaml)')
    p.add_argument('--method', default=defaults.METHOD, choices=METHOD_CHOICES,
                   help=f'identification method for the coefficients and the identified model curves (default '
                        f'{defaults.METHOD}, as bearing-id identify; none = theory only)')
    p.add_argument('--max-rpm', type=float, default=None,
                   help='upper end of the Campbell diagram [rpm] (default: max(6000, 1.5 x the highest test speed))')
    p.add_argument('--png', action='store_true', help='also write every figure as a PNG file next to the page')
    return p


def run(args) -> int:
    rig = load_rig(args.params)
    if args.max_rpm is not None and not args.max_rpm > 0:
        raise ParamError('--max-rpm must be > 0')
    recs = load_recordings(args.inputs)
    check_probes_against_params(recs, rig)
    recs = attach_excitation(recs, rig, required=False)
    check_probe_nodes(recs, rig.shaft.n_nodes)
    info = build_report(rig, recs, args.out, method=args.method, max_rpm=args.max_rpm, write_png=args.png,
                        command='bearing-id report ' + ' '.join(args.inputs)
                                + (f' --method {args.method}' if args.method != defaults.METHOD else ''))
    if info.method:
        print(f'identification method: {info.method}')
    for n in info.notes:
        print(f'note: {n}')
    print(f'wrote {info.path} ({info.n_figures} figures, {info.seconds:.1f} s)')
    return 0


# ------------------------------------------------------------------------------------------------ helpers
@dataclass
class ReportInfo:
    """
    What :func:`build_report` wrote.

    ``path`` of the page, figure count, wall time [s], notes (what the data did not support), ``method`` (the
    identification method that ran, with auto's reason), the figures
    (``figures``: name -> Figure, with ``keep_figures``) and the numbers drawn (``data``), for tests.
    """

    path: Path
    n_figures: int
    seconds: float
    notes: list = field(default_factory=list)
    method: str = ''
    figures: dict = field(default_factory=dict, repr=False)
    data: dict = field(default_factory=dict, repr=False)


def _rpm(w):
    return np.asarray(w, float) * RPM_PER_RAD_S


def _excitation_text(run) -> str:
    parts = []
    for e in run.excitation:
        if e.kind == 'unbalance':
            parts.append(f'unbalance {e.magnitude * 1e6:.3g} g·mm at node {e.node}, {math.degrees(e.phase):.0f}°')
        else:
            parts.append(f'{e.magnitude:.3g} N force ({e.direction}) at node {e.node}, {math.degrees(e.phase):.0f}°'
                         + (f', {e.frequency_ratio:g}X' if e.frequency_ratio != 1.0 else ''))
    return '; '.join(parts) or 'none known'


def _fmt(v, digits=4) -> str:
    return 'nan' if v is None or not np.isfinite(v) else f'{v:.{digits}g}'


def _has_forcing(run, n_nodes) -> bool:
    try:
        return 1.0 in harmonic_forces(run.excitation, 100.0, n_nodes)
    except ValueError:
        return False


def _bearing_text(b, load) -> str:
    """One bearing for the machine summary: a film's geometry, oil and static load [N], or a table's speed range."""
    if b.model == 'table':
        w = np.asarray(b.table.speeds, float) * RPM_PER_RAD_S
        return (f'{b.name} at node {b.node}: table, {w.size} rows {w.min():.0f}-{w.max():.0f} rpm'
                + (f', c {b.clearance * 1e6:.1f} µm' if np.isfinite(b.clearance) else ''))
    text = (f'{b.name} at node {b.node}: D {b.diameter * 1e3:.2f} mm, L {b.length * 1e3:.2f} mm, '
            f'c {b.clearance * 1e6:.1f} µm, µ {b.viscosity:.4g} Pa s, {b.model} model')
    return text + (f', load {load:.2f} N' if load is not None and np.isfinite(load) else '')


def coefficient_rows(results, allow_undetermined: bool = False) -> tuple[list, list]:
    """
    Return (header, rows) of the identified coefficients: one row per speed and bearing, 'value ± 1σ' per coefficient.

    A coefficient the data do not determine is shown as 'undetermined' (never as a plain number).
    """
    header = ['rpm', 'bearing'] + [f'K{c} [N/m]' for c in COEFF_ORDER] + [f'C{c} [N s/m]' for c in COEFF_ORDER] \
        + ['rank', 'condition', 'flags']
    rows = []
    for r in sorted(results, key=lambda r: r.speed):
        for b, name in enumerate(r.bearings):
            row = [f'{r.speed_rpm:.0f}', name]
            for sym in ('K', 'C'):
                v, s, d = getattr(r, sym)[b], getattr(r, sym + '_std')[b], getattr(r, sym + '_determined')[b]
                for k in range(4):
                    i, j = divmod(k, 2)
                    if d[i, j]:
                        row.append(f'{v[i, j]:.4g} ± {_fmt(s[i, j], 2)}')
                    elif allow_undetermined and np.isfinite(v[i, j]):
                        row.append((f'{v[i, j]:.4g} ({undetermined_label(r)})', 'undet'))
                    else:
                        row.append(('undetermined', 'undet'))
            flags = ', '.join(r.flags) or ('' if r.fully_determined else 'not all determined')
            row += [f'{r.rank} of {r.unknowns}', _fmt(r.condition, 3), (flags or 'ok', 'warn' if flags else 'ok')]
            rows.append(row)
    return header, rows


def modes_rows(model, bearing_fn, speeds, n_modes: int = 6) -> tuple[list, list]:
    """
    Return (header, rows): damped natural frequencies [Hz] with whirl (F/B) and log decrement at each speed.

    This is the table ``bearing-id model`` prints; the modes by :func:`bearing_id.rotor.modal.modes_solver`.
    """
    rows = []
    speeds = np.asarray(speeds, float)
    modes = modes_solver(model, float(np.max(speeds)), bearing_fn, n_modes) if speeds.size else None
    for w in speeds:
        m = modes(w, bearing_fn(w), n_modes)
        rows.append([f'{_rpm(w):.0f}'] + [f'{f / (2 * math.pi):.2f} {wh[0].upper()} ({d:+.2f})'
                                          for f, wh, d in zip(m.frequency, m.whirl, m.log_dec)])
    n = max((len(r) for r in rows), default=1) - 1
    return ['rpm'] + [f'mode {k + 1}: Hz F/B (log dec)' for k in range(n)], rows


# ------------------------------------------------------------------------------------------------ rendering
class _Figures:
    """Figures -> PNG bytes; ``keep``: also keep the Figure objects (tests read the drawn data back)."""

    def __init__(self, keep: bool = False):
        self.keep = keep
        self.figures: dict = {}

    def figure(self, name: str, fn, *args, **kw) -> bytes:
        """Return the PNG of ``fn(*args, **kw)``."""
        fig = fn(*args, **kw)
        if self.keep:
            self.figures[name] = fig
        return png_bytes(fig)


# ------------------------------------------------------------------------------------------------ the page
CAPTIONS = {
    'campbell': 'Damped natural frequencies vs speed (▲ forward, ▼ backward whirl), coloured by logarithmic decrement '
                '(red: unstable). Lines 0.5X (oil whirl / whip), 1X (unbalance: a critical speed where a forward mode '
                'crosses it, circled) and 2X. Red line: the stability threshold; star: the mode that goes unstable '
                'there. Green ticks: the steady speeds of these recordings.',
    'modes': 'The four lowest damped modes at each critical speed. Blue: x plane, orange: y plane, each drawn against '
             'its largest node with the sign of its phase; grey: orbit semi-major axis; ▲ bearings, grey bands discs. '
             'F/B: forward / backward whirl; δ: logarithmic decrement. The framed panel is the mode the critical '
             'speed excites.',
    'bode': '1X amplitude and phase vs speed, one colour per run: measured vectors ±1σ (dots), the identified model '
            "(solid) and the theory (dashed) as continuous curves; dotted: the model's critical speed. Phase = arg X "
            'of x(t) = Re{X e^{jφ}}, φ the keyphasor angle.',
    'polar': '1X polar plot, one panel per run: measured vectors with 1σ circles and rpm labels, the model curves '
             '(arrow: increasing speed); the frame fits the measured points. Angles counter-clockwise from +Re.',
    'orbits': 'Orbits at one probe station per speed, one colour per run: thin the last 3 revolutions unfiltered '
              '(window mean removed), thick the 1X orbit with its keyphasor dot and the direction of travel; hollow '
              'dots: keyphasor on the unfiltered signal. Each panel has its own scale (equal axes); F/B = forward / '
              'backward 1X whirl. A station is an x and a y probe at one node, or two probes there at least 30° from '
              'parallel (e.g. API 670 pairs at ±45°) whose readings are transformed to x and y.',
    'spectrum': 'The amplitude spectrum (Hann window) of each steady window on a baseline at its speed, with the '
                "0.5X, 1X and 2X lines (a probe pair at one node: the first run's cascades; sub-synchronous whirl "
                'does not depend on the unbalance); below, the highest speed of every run on a log scale '
                '(sub-synchronous lines and the noise floor).',
    'centreline': 'Journal centre inside the clearance circle vs speed (computed from the bearing model at the static '
                  'load: eccentricity and attitude angle; labels: test speeds in rpm), and the eccentricity ratio. Not '
                  'measured: that needs DC-coupled probes at the bearings.',
    'coefficients': 'Identified K [N/m] and C [N s/m] of each bearing vs speed: determined values with ±1σ error bars '
                    'and band; hollow grey markers are coefficients the data do NOT determine (prior values, not '
                    'results); dashed: the theory (nominal params); green: the truth when the recordings carry it '
                    '(simulated rig).',
}


def build_report(rig, recordings, outdir, *, data=None, results=None, method: str = defaults.METHOD,
                 options=None, diagnosis=None, reidentification=None, cli_text: str | None = None,
                 command: str | None = None, max_rpm: float | None = None, write_png: bool = False,
                 allow_undetermined: bool = False, keep_figures: bool = False) -> ReportInfo:
    """
    Write ``outdir/report.html`` for ``recordings`` (rig.Recording list) on ``rig``.

    data : the HarmonicData of the recordings when already computed (else :func:`harmonics.from_recordings`).
    results : identification results when already computed (else ``method`` is run; 'none' = no identification).
    diagnosis : a :class:`bearing_id.diagnose.Diagnosis` (adds the before / after section and its tables);
    reidentification : its :class:`bearing_id.diagnose.reidentify.Reidentification` (table).
    cli_text : text the calling command printed (shown verbatim).  keep_figures : keep the Figure objects in the
    returned info (tests).
    Anything the data do not support is left out with a note, never drawn.
    """
    t0 = time.perf_counter()
    R = _Figures(keep_figures)
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    notes: list[str] = []
    fdata: dict = {}
    figs: list = []                       # (name, PNG bytes), in page order within each section
    model = RotorModel.from_params(rig)
    theory = supports.bearing_fn(rig)
    recordings = list(recordings or [])
    if rig.extra and rig.extra.get('effects'):
        notes.append('the params carry extra.effects (an augmented model): the model curves here use the rotor and '
                     'bearings only, without those effects')
    # the Campbell range, known before the 1X vectors: from the recorded speeds
    top_rec = max((float(np.nanmax(np.abs(r.speed))) for r in recordings if r.speed.size), default=0.0)
    hi_rpm = max_rpm or max(6000.0, 1.5 * _rpm(top_rec))
    hi = float(rpm_to_rad_s(hi_rpm))
    # ---------------------------------------------------------------- measured 1X
    if data is None and recordings:
        try:
            data = harmonics.from_recordings(recordings)
        except ValueError as exc:
            notes.append(f'no 1X vectors from these recordings: {exc}')
    test_speeds = np.asarray(data.speeds, float) if data is not None else np.zeros(0)
    test_rpm = _rpm(test_speeds)
    probes = tuple(data.probes) if data is not None else (tuple(recordings[0].probes) if recordings else ())
    runs = tuple(data.runs) if data is not None else tuple(r.run for r in recordings)
    run_labels = [str(r.id) for r in runs]
    # ---------------------------------------------------------------- orbits
    sec_orbits = []
    stations = fd.probe_stations(probes) if probes else []
    pairs = [(ix, iy) for ix, iy, _ in stations]
    if data is not None and data.windows and stations:
        ns = test_speeds.size
        most = 9 if len(stations) == 1 else 6
        pick = list(range(ns)) if ns <= most else sorted(set(np.linspace(0, ns - 1, most).round().astype(int)))
        for ix, iy, to_xy in stations:
            panels = []
            for s in pick:
                row = [fd.orbit_data(rec, *data.windows[r][s], ix, iy, data.X[r, s, ix], data.X[r, s, iy],
                                     test_speeds[s], to_xy=to_xy) if data.windows[r][s] is not None else None
                       for r, rec in enumerate(data.recordings)]
                panels.append(row)
            fdata.setdefault('orbits', []).append(panels)
            px, py = probes[ix], probes[iy]
            name = f'orbits_node{px.node}'
            how = '' if to_xy is None else f'x, y from the probes at {px.direction} and {py.direction}; '
            sec_orbits.append((name, R.figure(name, orbits_figure, panels, run_labels,
                                              title=f'orbits at node {px.node} ({px.name}, {py.name}); {how}x right, '
                                                    'y up, rotation counter-clockwise'),
                               f'Node {px.node}. ' + CAPTIONS['orbits']))
    elif probes:
        notes.append('no orbit plots: orbits need two probes at one node at least 30° from parallel (x and y, or '
                     'e.g. ±45°)')
    # ---------------------------------------------------------------- spectra
    sec_spectra = []
    if data is not None and data.windows:
        fmax = 2.6 * float(test_speeds.max()) / (2 * math.pi)
        spec = {c: [fd.waterfall_data(data, r, c, fmax) for r in range(len(data.recordings))]
                for c in range(len(probes))}
        fdata['spectra'] = {p.name: [(run_labels[r], spec[c][r]) for r in range(len(runs))]
                            for c, p in enumerate(probes)}
        paired = {i for pr in pairs for i in pr}
        groups = [list(pr) for pr in pairs] + [[c] for c in range(len(probes)) if c not in paired]
        for grp in groups:
            if len(grp) == 2:         # a probe pair at one node: each one's first-run cascade, every run's top speed
                casc = [(f'{probes[c].name}, run {run_labels[0]}', 0, spec[c][0]) for c in grp]
                name = f'spectrum_node{probes[grp[0]].node}'
                head = (f'spectrum cascade at node {probes[grp[0]].node} ({probes[grp[0]].name}, '
                        f'{probes[grp[1]].name})')
            else:                     # a single probe: one cascade per run
                casc = [(f'run {run_labels[r]}', r, spec[grp[0]][r]) for r in range(len(runs))]
                name = f'spectrum_{probes[grp[0]].name}'
                head = f'spectrum cascade, probe {probe_text(probes[grp[0]])}'
            logs = [(f'{probes[c].name} run {run_labels[r]}', r, i, spec[c][r][-1])
                    for i, c in enumerate(grp) for r in range(len(runs)) if spec[c][r]]
            sec_spectra.append((name, R.figure(name, waterfall_figure, casc, logs, fmax=fmax, title=head),
                                head + '. ' + CAPTIONS['spectrum']))
    forced = [_has_forcing(r, model.n_nodes) for r in runs]
    if results is None and data is not None and method not in (None, 'none'):
        if not all(forced):
            notes.append(f'identification ({method}) skipped: run(s) '
                         f"{', '.join(str(r.id) for r, f in zip(runs, forced) if not f)} carry no known excitation")
        else:
            try:
                results = identify(method, model, rig, data, options=options)
            except ValueError as exc:
                notes.append(f'identification ({method}) not possible on these data: {exc}')
    results = list(results or [])
    ident, why = fd.identified_bearing_fn(results, rig) if results else (None, 'no identification')
    if results and ident is None:
        notes.append(f'no identified model curve: {why}')
    # ---------------------------------------------------------------- 1X response (continuous model curves)
    sec_response = []
    if data is not None:
        lo_c, hi_c = 0.8 * float(test_speeds.min()), 1.1 * float(test_speeds.max())
        curves = []
        if any(forced):
            gt, Yt = fd.response_curves_adaptive(model, theory, runs, probes, test_speeds, lo_c, hi_c)
            curves.append(('theory (nominal bearings)', gt, Yt, 'theory'))
            if ident is not None:
                a, b = ident.speed_range or (lo_c, hi_c)
                gi, Yi = fd.response_curves_adaptive(model, ident.fn, runs, probes, test_speeds, max(a, lo_c),
                                                     min(b, hi_c))
                curves.insert(0, (ident.label, gi, Yi, 'identified'))
        else:
            notes.append('no run carries a known synchronous excitation: Bode / polar plots show the measurement only')
        fdata['response_curves'] = curves
        fdata['curves_by_probe'] = []
        for c, p in enumerate(probes):
            cl = [Curve(lab, _rpm(g), Y[:, :, c], kind) for lab, g, Y, kind in curves]
            fdata['curves_by_probe'].append(cl)
            sec_response.append((f'bode_{p.name}', None, f'Probe {p.name}. ' + CAPTIONS['bode']))  # after Campbell
            sec_response.append((f'polar_{p.name}', R.figure(f'polar_{p.name}', polar_figure, p, test_rpm,
                                                             data.X[:, :, c], data.X_std[:, :, c], run_labels, cl),
                                 f'Probe {p.name}. ' + CAPTIONS['polar']))
    # ---------------------------------------------------------------- coefficients
    sec_coeff = []
    if results:
        truth = data.truth if data is not None and data.truth else None
        sec_coeff.append(('coefficients', R.figure('coefficients', coefficients_figure, results, truth_fn=truth,
                                                   theory_fn=theory, title='identified bearing coefficients, method '
                                                                           f'{results[0].method}'),
                          CAPTIONS['coefficients']))
    # ---------------------------------------------------------------- centreline
    sec_centre = []
    if test_speeds.size:
        g = fd.curve_speeds(test_speeds, max(0.5 * test_speeds.min(), 5.0), 1.2 * test_speeds.max(), 40)
        cl = [('theory', 'theory', _rpm(g), fd.journal_positions(theory, g))]
        if ident is not None and ident.kind == 'physical':
            cl.insert(0, ('identified', 'identified', _rpm(g), fd.journal_positions(ident.fn, g)))
        cl = [c for c in cl if c[3]]
        fdata['centreline'] = cl
        if cl:
            sec_centre.append(('centreline', R.figure('centreline', centreline_figure, cl, label_rpm=test_rpm),
                               CAPTIONS['centreline']))
    # ---------------------------------------------------------------- diagnosis
    sec_diag, dc = [], None
    if diagnosis is not None:
        try:
            dc = fd.diagnosis_curves(diagnosis)
        except (AttributeError, IndexError, KeyError, TypeError, ValueError) as exc:
            notes.append(f'diagnosis before/after curves not available: {type(exc).__name__}: {exc}')
        if dc is not None:
            fdata['diagnosis'] = dc
            for pnl in dc['panels']:
                name = f"diagnosis_{pnl['run']}_{pnl['probe'].name}"
                sec_diag.append((name, R.figure(name, diagnosis_bode_figure, pnl),
                                 f"Run {pnl['run']}, probe {pnl['probe'].name}: measured 1X ±1σ against the nominal "
                                 'model, the model with refitted bearings and no effect, and the augmented model '
                                 'with the effects found (the diagnosis predicts at the test speeds: markers, joined '
                                 'by thin lines that are not a model curve).'))
            sec_diag.append(('diagnosis_residual', R.figure('diagnosis_residual', residual_orders_figure, dc),
                             'RMS residual (measured minus model) per harmonic order, all probes and speeds, before '
                             'and after.'))
    # ---------------------------------------------------------------- Campbell, critical speeds, mode shapes
    cd_ident = None
    n_modes = machine_modes(rig, hi_rpm)           # as `bearing-id model`: every mode that can reach 1X in the range
    if ident is not None and ident.speed_range is None:
        cd_ident = fd.campbell_data(model, ident.fn, hi, label=ident.label, n_modes=n_modes)
    cd_theory = fd.campbell_data(model, theory, hi, label='theory (nominal params)', n_modes=n_modes)
    cd = cd_ident or cd_theory
    fdata['campbell'], fdata['campbell_theory'] = cd, cd_theory
    sec_campbell = []
    for c_, tag in ((cd_theory, 'theory'), (cd_ident, 'identified')):
        if c_ is not None:
            sec_campbell.append((f'campbell_{tag}', R.figure(f'campbell_{tag}', campbell_figure, c_,
                                                             measured_rpm=test_rpm,
                                                             title=f'Campbell diagram - {c_.label}'),
                                 f'Bearings: {c_.label}. ' + CAPTIONS['campbell']))
    crit_speeds = list(cd.critical) or ([float(test_speeds.max())] if test_speeds.size else [])
    rows = []
    shape_fn = ident.fn if cd_ident is not None else theory
    modes = modes_solver(model, max(crit_speeds[:3]), shape_fn, 4) if crit_speeds else None
    for w in crit_speeds[:3]:
        shapes = fd.mode_shapes(model, shape_fn, w, 4, solver=modes)
        lab = f'{_rpm(w):.0f} rpm' + (' (critical)' if cd.critical.size else ' (highest test speed)')
        rows.append((lab, shapes, fd.critical_mode_index(shapes, w) if cd.critical.size else None))
    fdata['mode_shapes'] = rows
    if rows:
        sec_campbell.append(('mode_shapes', R.figure('mode_shapes', mode_shapes_figure, rows,
                                                     bearing_nodes=model.bearing_nodes,
                                                     disc_nodes=[d.node for d in rig.discs]),
                             f'Bearings: {cd.label}. ' + CAPTIONS['modes']))
    # the Bode plots mark the critical speeds of the model drawn (identified when there is one)
    for k, (name, png, cap) in enumerate(sec_response):
        if png is None:
            c = [p.name for p in probes].index(name[5:])
            sec_response[k] = (name, R.figure(name, bode_figure, probes[c], test_rpm, data.X[:, :, c],
                                              data.X_std[:, :, c], run_labels, fdata['curves_by_probe'][c],
                                              critical_rpm=list(cd.critical_rpm)), cap)

    # ================================================================ assemble the page (in order)
    page = Page(f'bearing_id report - {rig.name}')
    page.section('Machine summary', 'summary')
    kv = [('rig', rig.name), ('rotor', f'{model.mass:.3f} kg, {model.n_nodes} nodes, shaft '
                                       f'{rig.shaft.diameter * 1e3:.2f} mm x {rig.shaft.length:.3f} m')]
    kv.append(('bearings', '; '.join(_bearing_text(b, theory.loads.get(b.node)) for b in rig.bearings)))
    kv.append(('discs', '; '.join(f'node {d.node}: {d.outer_diameter * 1e3:.0f} x {d.thickness * 1e3:.0f} mm'
                                  for d in rig.discs) or 'none'))
    if recordings:
        kv.append(('probes', ', '.join(f'{p.name} (node {p.node} {p.direction})' for p in recordings[0].probes)))
        for rec in recordings:
            dur = rec.samples.shape[0] / rec.sample_rate
            kv.append((f'run {rec.run.id}', f'{_excitation_text(rec.run)}; {dur:.1f} s at {rec.sample_rate:.0f} Hz'))
    if test_rpm.size:
        kv.append(('steady test speeds [rpm]', ', '.join(f'{v:.0f}' for v in test_rpm)))

    def crit_text(c):
        s = ('; '.join(f'{v:.0f} rpm (ζ {z:.3f}, amplification ≈ {1 / (2 * z) if z > 0 else np.inf:.0f})'
                       for v, z in zip(c.critical_rpm, c.critical_zeta)) or f'none below {hi_rpm:.0f} rpm')
        if c.damped_crossings.size:
            pairs = zip(c.damped_crossings_rpm, c.damped_crossings_zeta)
            s += (f'; critically damped 1X crossings (ζ > {fd.CRITICALLY_DAMPED:g}, not critical speeds): '
                  + ', '.join(f'{v:.0f} rpm (ζ {z:.2f})' for v, z in pairs))
        return s

    def thr_text(c):
        if c.threshold_rpm is None:
            return (f'stable up to {hi_rpm:.0f} rpm' if c.threshold is not None else
                    '; '.join(c.notes) or 'not computed')
        s = f'{c.threshold_rpm:.0f} rpm (the unstable mode whirls at {c.threshold_ratio:.2f}X)'
        if test_rpm.size:
            s += f'; highest test speed {test_rpm.max():.0f} rpm = {100 * test_rpm.max() / c.threshold_rpm:.0f} % of it'
        return s

    kv.append(('critical speeds, theory', crit_text(cd_theory)))
    kv.append(('stability threshold, theory', thr_text(cd_theory)))
    if cd_ident is not None:
        kv.append(('critical speeds, identified', crit_text(cd_ident)))
        kv.append(('stability threshold, identified', thr_text(cd_ident)))
    if results:
        nd = sum(int(np.sum(r.K_determined) + np.sum(r.C_determined)) for r in results)
        ntot = sum(r.K.size + r.C.size for r in results)
        mis = [f'{r.speed_rpm:.0f}' for r in results if r.misfit]
        kv.append((f'identification ({results[0].method})',
                   f'{nd} of {ntot} coefficients determined by the data over {len(results)} speeds'
                   + (f"; MISFIT at {', '.join(mis)} rpm (1σ is a lower bound)" if mis else '')))
        fit = results[0].extra.get('fit') if isinstance(results[0].extra, dict) else None
        if fit is not None and hasattr(fit, 'note'):
            kv.append(('fitted bearing parameters', fit.note()))
    if diagnosis is not None:
        kv.append(('diagnosis verdict', str(diagnosis.verdict)))
    page.table(None, [[k, v] for k, v in kv], cls='kv')
    for n in notes:
        page.paragraph('note: ' + n, cls='muted')

    def put(items):
        for name, png, cap in items:
            page.image(png, cap, alt=name)
            figs.append((name, png))

    page.section('Campbell diagram and mode shapes', 'campbell')
    camp = [x for x in sec_campbell if x[0].startswith('campbell_')]
    if len(camp) > 1:
        page.row_start()
        put(camp)
        page.row_end()
    else:
        put(camp)
    put([x for x in sec_campbell if not x[0].startswith('campbell_')])
    if not cd.critical.size:
        page.paragraph(f'No synchronous critical speed below {hi_rpm:.0f} rpm; mode shapes at the highest test speed.',
                       cls='muted')
    if sec_response:
        page.section('1X response: Bode and polar plots', 'response')
        put(sec_response)
    if sec_orbits:
        page.section('Orbits', 'orbits')
        put(sec_orbits)
    if sec_spectra:
        page.section('Spectra', 'spectra')
        put(sec_spectra)
    if sec_centre:
        page.section('Shaft centreline', 'centreline')
        put(sec_centre)
    if results:
        page.section('Bearing coefficients vs speed', 'coefficients')
        put(sec_coeff)
        h, rws = coefficient_rows(results, allow_undetermined)
        page.table(h, rws, left_cols=2)
        if cli_text is None:
            cli_text = 'units: speed rpm, K N/m, C N s/m\n' + format_results(results, allow_undetermined)
    if diagnosis is not None:
        page.section('Diagnosis: before / after', 'diagnosis')
        page.paragraph(f'verdict: {diagnosis.verdict}')
        page.bullets(diagnosis.sentences)
        put(sec_diag)
        if diagnosis.mismatch:
            page.table(['where', 'order', 'size [µm]', 'significance [σ]', 'speeds [rpm]'],
                       [[m.where, m.order, f'{m.size * 1e6:.3g}', f'{m.significance:.1f}',
                         ', '.join(f'{s:.0f}' for s in m.speeds_rpm)] for m in diagnosis.mismatch[:12]],
                       caption='located mismatch (largest first)', left_cols=2)
        hyp = [h for h in diagnosis.hypotheses if h.get('step') == 0][:10]
        if hyp:
            page.table(['effect', 'where', 'ΔBIC', 'explains', 'validated'],
                       [[h['effect'], h['where'], f"{h['delta_bic']:.1f}", f"{h['explained_fraction']:.1%}",
                         str(h['validated'])] for h in hyp], caption='hypotheses (first step, best BIC first)',
                       left_cols=2)
        if reidentification is not None:
            try:
                page.pre('\n'.join(format_table(reidentification)))
            except Exception as exc:   # noqa: BLE001 - a table we cannot format is left out, not fatal
                page.paragraph(f're-identification table not available: {exc}', cls='muted')
    page.section('Tables', 'tables')
    if test_speeds.size:
        page.subsection('natural frequencies on the bearings at the test speeds (theory, as `bearing-id model`)')
        h, rws = modes_rows(model, theory, test_speeds)
        page.table(h, rws)
        if ident is not None:
            page.subsection(f'natural frequencies at the test speeds ({ident.label})')
            h, rws = modes_rows(model, ident.fn, test_speeds)
            page.table(h, rws)
    if data is not None:
        page.subsection('measured 1X vectors (amplitude [µm] ± 1σ, phase [deg])')
        hdr = ['run', 'rpm'] + [p.name for p in probes]
        rws = []
        for r, run in enumerate(runs):
            for s in range(test_speeds.size):
                rws.append([str(run.id), f'{test_rpm[s]:.0f}'] + [
                    f'{abs(data.X[r, s, c]) * 1e6:.4g} ± {data.X_std[r, s, c] * 1e6:.2g} ∠ '
                    f'{math.degrees(np.angle(data.X[r, s, c])):.1f}°' for c in range(len(probes))])
        page.table(hdr, rws, left_cols=2)
    if cli_text:
        page.pre(cli_text, summary="the command's printed output")
    if write_png:
        for name, png in figs:
            (out / f'{name}.png').write_bytes(png)
    seconds = time.perf_counter() - t0
    footer = (f'written by bearing_id in {seconds:.1f} s'
              + (f'; command: {command}' if command else '')
              + '; SI inside, rpm / µm / degrees for people; conventions: bearing_id/conventions.py')
    header_html = f'<p class="muted">{esc(command)}</p>' if command else ''
    path = page.write(out / REPORT_NAME, header_html=header_html, footer_text=footer)
    auto = results[0].extra.get('auto') if results else None
    ran = (f"{auto['method']} (auto: {auto['reason']})" if auto else results[0].method) if results else ''
    return ReportInfo(path=path, n_figures=page.n_images, seconds=seconds, notes=notes, method=ran,
                      figures=dict(R.figures), data=fdata)


def report_for_diagnosis(diagnosis, recordings, rig, outdir, *, reidentification=None,
                         method: str = defaults.METHOD, cli_text: str | None = None, command: str | None = None,
                         write_png: bool = False, data=None) -> ReportInfo:
    """
    Return the page for ``bearing-id diagnose --report DIR``.

    It is :func:`build_report` with the diagnosis' before / after.  ``data`` : the recordings' HarmonicData when the
    diagnosis already built it (:attr:`bearing_id.diagnose.Diagnosis.harmonic_data`; default: that attribute, else
    computed here).
    """
    if data is None:
        data = getattr(diagnosis, 'harmonic_data', None)
    return build_report(rig, recordings, outdir, data=data, method=method, diagnosis=diagnosis,
                        reidentification=reidentification, cli_text=cli_text, command=command, write_png=write_png)


__all__ = ['add_parser', 'run', 'build_report', 'report_for_diagnosis', 'ReportInfo', 'coefficient_rows',
           'modes_rows', 'REPORT_NAME']
