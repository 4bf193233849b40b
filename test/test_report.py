"""
`bearing-id report` and the figure modules.

The data behind every figure checked against the model, the page self-contained, and (with Chromium installed, or always
on CI) rendered in a real headless browser.

Independent checks: the Campbell diagram's 1X crossing of a forward branch (read back from the drawn points) equals
the critical speed `bearing-id model` reports; the Bode / polar model curves pass through the FE model's 1X
response with the identified coefficients at every test speed (computed here with harmonic_response); the measured
points are the 1X vectors identification used; orbit keyphasor dots, spectrum amplitudes and journal positions
against closed forms.
"""
from __future__ import annotations

import base64
import math
import os
from pathlib import Path
import re
from types import SimpleNamespace

import agreement
from bearing_id.cli import main
from bearing_id.commands.inputs import attach_excitation, load_recordings
from bearing_id.commands.model import analyse, campbell_from_report
from bearing_id.commands.report import build_report
from bearing_id.config.params import load_rig, Probe, Run
from bearing_id.conventions import probe_row, RPM_PER_RAD_S, rpm_to_rad_s
from bearing_id.excitation import harmonic_forces
from bearing_id.identify import harmonics, identify
from bearing_id.identify.result import IdentResult
from bearing_id.io.recordings import save_npz
from bearing_id.plots.campbell import campbell_figure
from bearing_id.plots.coefficients import theory_coefficients_figure
from bearing_id.plots.data import (amplitude_spectrum, critical_mode_index, diagnosis_curves, identified_bearing_fn,
                                   InterpolatedBearings, journal_positions, mode_shapes, orbit_data, probe_stations,
                                   response_curves, response_curves_adaptive)
from bearing_id.plots.diagnosis import diagnosis_bode_figure, residual_orders_figure
from bearing_id.plots.html import browser_check, find_chromium, Page
from bearing_id.rotor import supports
from bearing_id.rotor.assembly import harmonic_response, probe_matrix, RotorModel
from bearing_id.rotor.modal import damped_modes
from bearing_id.simulation.rig import simulate_run
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
BAG = ROOT / 'bags' / 'unbalance_ab_sweep'


# ------------------------------------------------------------------------------------------------ fixtures
@pytest.fixture(scope='module')
def demo(tmp_path_factory):
    """Return the report of the demo-like recording (bags/unbalance_ab_sweep, method physical), figures kept."""
    rig = load_rig()
    recs = attach_excitation(load_recordings([str(BAG)]), rig, required=False)
    out = tmp_path_factory.mktemp('report')
    info = build_report(rig, recs, out, keep_figures=True, command='test')
    return rig, recs, info


def _by_gid(fig, gid):
    return [a for ax in fig.axes for a in ax.get_children() if a.get_gid() == gid]


# ------------------------------------------------------------------------------------------------ Campbell
def test_campbell_1x_crossing_equals_the_reported_critical_speed(tmp_path):
    r = analyse(load_rig(), [600.0, 3000.0], max_rpm=6000.0, update=False)
    crit = r['critical_speeds_rpm']
    assert len(crit) == 1 and 1800 < crit[0] < 2200
    fig = campbell_figure(campbell_from_report(r), measured_rpm=[600, 3000])
    # the forward-whirl points as drawn: per speed, the sorted forward frequencies; crossing of a branch with 1X
    pts = np.vstack([c.get_offsets() for c in _by_gid(fig, 'campbell:forward')])
    rpm = np.unique(pts[:, 0])
    fw = [np.sort(pts[pts[:, 0] == s, 1]) for s in rpm]
    found = []
    for k in range(min(len(f) for f in fw)):
        g = np.array([f[k] for f in fw]) - rpm / 60.0
        for i in np.nonzero(np.sign(g[:-1]) * np.sign(g[1:]) < 0)[0]:
            found.append(rpm[i] - g[i] * (rpm[i + 1] - rpm[i]) / (g[i + 1] - g[i]))
    assert len(found) == 1
    assert found[0] == pytest.approx(crit[0], rel=0.01)          # linear interpolation on a 150 rpm grid
    (marker,) = _by_gid(fig, 'critical:0')
    assert marker.get_xdata()[0] == pytest.approx(crit[0], rel=1e-12)
    assert marker.get_ydata()[0] == pytest.approx(crit[0] / 60.0, rel=1e-12)   # on the 1X line
    # order lines 0.5X, 1X, 2X through the origin with the right slope; threshold drawn where reported
    for name, k in (('0.5X', 0.5), ('1X', 1.0), ('2X', 2.0)):
        (ln,) = _by_gid(fig, f'order:{name}')
        x, y = ln.get_xdata(), ln.get_ydata()
        assert y[-1] == pytest.approx(k * x[-1] / 60.0) and y[0] == 0
    (thr,) = _by_gid(fig, 'threshold')
    assert thr.get_xdata()[0] == pytest.approx(r['stability_threshold_rpm'])
    # log-decrement colouring: every point's colour value is the mode's log decrement
    sc = _by_gid(fig, 'campbell:forward')[0]
    assert np.all(np.isfinite(sc.get_array()))


def test_model_command_plots_each_bearing_visibly(tmp_path, capsys):
    assert main(['model', '--out', str(tmp_path), '--speeds', '600,1800,3000', '--no-update']) == 0
    for name in ('campbell.png', 'coefficients.png', 'mode_shapes.png'):
        assert (tmp_path / name).read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    K = np.ones((3, 2, 2))
    fig = theory_coefficients_figure([600, 1800, 3000], {2: (K, K), 10: (K, 2 * K)})
    a, b = _by_gid(fig, 'theory:2:Cxy')[0], _by_gid(fig, 'theory:10:Cxy')[0]
    assert (a.get_color(), a.get_marker(), a.get_linestyle()) != (b.get_color(), b.get_marker(), b.get_linestyle())
    assert len(_by_gid(fig, 'theory:2:Cyx')) == 1       # Cxy and Cyx in their own panels


def test_mode_shapes_are_the_damped_modes(rig, model):
    bfn = supports.bearing_fn(rig)
    w = rpm_to_rad_s(1964.0)
    shapes = mode_shapes(model, bfn, w, 4)
    m = damped_modes(model, w, bfn(w), 4)
    np.testing.assert_allclose([s.frequency for s in shapes], m.frequency)
    assert [s.whirl for s in shapes] == list(m.whirl)
    k = critical_mode_index(shapes, w)
    assert shapes[k].whirl == 'forward' and abs(shapes[k].frequency - w) / w < 0.05
    for s in shapes:
        assert max(np.max(np.abs(s.x)), np.max(np.abs(s.y))) == pytest.approx(1.0)
        assert np.all(s.envelope >= np.maximum(np.abs(s.x_plane), np.abs(s.y_plane)) * (1 - 1e-9))


# ------------------------------------------------------------------------------------------------ response
def test_model_curves_pass_through_the_model_response_at_the_test_speeds(demo):
    rig, recs, info = demo
    model = RotorModel.from_params(rig)
    data = harmonics.from_recordings(recs)
    results = identify('physical', model, rig, data)
    S = probe_matrix(model, data.probes)
    curves = info.data['curves_by_probe']
    assert [c.kind for c in curves[0]] == ['identified', 'theory']
    for c, p in enumerate(data.probes):
        polar = info.figures[f'polar_{p.name}']
        bode = info.figures[f'bode_{p.name}']
        for r, run in enumerate(data.runs):
            (line,) = _by_gid(polar, f'polar:{curves[c][0].label}:{run.id}')
            (amp,) = _by_gid(bode, f'model:{curves[c][0].label}:{run.id}')
            z = (line.get_xdata() + 1j * line.get_ydata()) * 1e-6         # drawn in µm
            rpm = curves[c][0].rpm
            for s, res in enumerate(results):      # within 0.01 of the 1-sigma of the measured point there
                k = int(np.argmin(np.abs(rpm - res.speed_rpm)))
                agreement.assert_speeds_agree(rpm[k], res.speed_rpm, 'the test speed is on the grid')
                F = harmonic_forces(run.excitation, res.speed, model.n_nodes)[1.0]
                want = (S @ harmonic_response(model, res.speed, res.speed, F, res.coeffs()))[c]
                sigma = data.X_std[r, s, c]
                agreement.assert_within_sigma(z[k], want, sigma, 'polar curve')
                agreement.assert_within_sigma(amp.get_ydata()[k], abs(want) * 1e6, sigma * 1e6, 'Bode amplitude')
            # measured points = the identification's 1X vectors
            (pts,) = _by_gid(polar, f'polar-measured:{run.id}')
            agreement.assert_within_sigma(pts.get_xdata() + 1j * pts.get_ydata(), data.X[r, :, c] * 1e6,
                                          data.X_std[r, :, c] * 1e6, 'measured points')


def test_identified_physical_model_reproduces_the_results(demo):
    rig, recs, _ = demo
    data = harmonics.from_recordings(recs)
    results = identify('physical', RotorModel.from_params(rig), rig, data)
    im, why = identified_bearing_fn(results, rig)
    assert im is not None and im.kind == 'physical', why
    for res in results:                 # the fitted model's coefficients: within 0.01 of the results' 1-sigma
        for b, (node, (K, C)) in enumerate(res.coeffs().items()):
            Kf, Cf = im.fn(res.speed)[node]
            agreement.assert_within_sigma(Kf, K, res.K_std[b], f'K at node {node}')
            agreement.assert_within_sigma(Cf, C, res.C_std[b], f'C at node {node}')


def test_interpolated_bearings_are_exact_at_the_speeds_and_refuse_to_extrapolate():
    def res(w, scale, det=True):
        K = np.array([[[1e6, 2e5], [-3e5, 8e5]]]) * scale
        C = np.array([[[1e3, -1e2], [-1e2, 2e3]]]) * scale
        ones = np.ones((1, 2, 2), bool) & det
        return IdentResult(w, 'direct', ('b1',), (2,), K, C, np.abs(K) * 0.01, np.abs(C) * 0.01, ones, ones.copy(),
                           16, 16, 1.0, 0.0)
    rs = [res(100.0, 1.0), res(200.0, 2.0), res(300.0, 3.0)]
    ib = InterpolatedBearings(rs)
    for r in rs:                        # through the identified points, within 0.01 of their 1-sigma
        agreement.assert_within_sigma(ib(r.speed)[2][0], r.K[0], r.K_std[0])
    np.testing.assert_allclose(ib(150.0)[2][0], rs[0].K[0] * 1.5)     # linear data: PCHIP is linear
    with pytest.raises(ValueError):
        ib(350.0)
    im, _ = identified_bearing_fn(rs, None)
    assert im.kind == 'interpolated' and im.speed_range == (100.0, 300.0)
    im, why = identified_bearing_fn([res(100.0, 1.0), res(200.0, 2.0, det=False)], None)
    assert im is None and 'not determined' in why


def test_adaptive_curve_resolves_the_resonance(rig, model):
    bfn = supports.bearing_fn(rig)
    runs = rig.simulation.runs
    test = rpm_to_rad_s(np.array([600.0, 1800.0, 3000.0]))
    g, Y = response_curves_adaptive(model, bfn, runs, rig.probes, test, test[0], test[-1])
    for w in test:
        assert np.min(np.abs(g - w)) == 0.0
    # the curve is drawn to 2 % of its peak (the refinement's step): the adaptive grid's values agree with the plain
    # route's within 0.01 of that resolution
    peak = np.max(np.abs(Y), axis=1, keepdims=True)
    assert np.all(np.abs(Y - response_curves(model, bfn, runs, rig.probes, g)) <= 0.01 * 0.02 * peak)
    step = np.max(np.abs(np.diff(Y, axis=1)) / peak)
    assert step <= 0.02 + 1e-12                     # no polygon through the resonance loop


# ------------------------------------------------------------------------------------------------ signals
def test_orbit_keyphasor_and_whirl_on_a_synthetic_orbit():
    fs, w = 2048.0, 2 * math.pi * 20.0
    t = np.arange(int(fs)) / fs
    ang = w * t + 0.3
    X, Y = 3e-6 * np.exp(1j * 0.4), 2e-6 * np.exp(1j * (0.4 - math.pi / 2))    # forward ellipse
    smp = np.column_stack([np.real(X * np.exp(1j * ang)), np.real(Y * np.exp(1j * ang))]) + 5e-6
    rec = SimpleNamespace(angle=ang, samples=smp)
    o = orbit_data(rec, 0, t.size, 0, 1, X, Y, w, n_rev=3)
    assert o.whirl == 'forward'
    assert len(o.raw_key) == 3
    np.testing.assert_allclose(o.raw_key, np.tile([np.real(X), np.real(Y)], (3, 1)), atol=2e-8)  # DC removed
    np.testing.assert_allclose(o.filt_key, [np.real(X), np.real(Y)])
    np.testing.assert_allclose(o.pk_pk, [6e-6, 4e-6])


def test_orbit_from_probes_at_plus_minus_45_degrees_is_the_xy_orbit():
    """API 670 pairs (45 and 135 deg from +x, one with a 2 % gain error): the station's x, y are the true x, y."""
    probes = (Probe('a', 7, '45.0deg*1.02'), Probe('m', 4, 'x'), Probe('b', 7, '135.0deg'), Probe('c', 9, '45.0deg'),
              Probe('d', 9, '60.0deg'))
    st = probe_stations(probes)
    assert [(i, j) for i, j, _ in st] == [(0, 2)]        # node 4 has one probe; node 9's two are 15 deg apart
    fs, w = 2048.0, 2 * math.pi * 20.0
    t = np.arange(int(fs)) / fs
    ang = w * t + 0.3
    X, Y = 3e-6 * np.exp(1j * 0.4), 2e-6 * np.exp(1j * (0.4 + math.pi / 2))    # a backward ellipse
    x, y = np.real(X * np.exp(1j * ang)), np.real(Y * np.exp(1j * ang))
    rows = [probe_row(probes[k].direction) for k in (0, 2)]
    smp = np.column_stack([r[0] * x + r[1] * y for r in rows]) + 4e-6
    Xa, Xb = (r[0] * X + r[1] * Y for r in rows)
    o = orbit_data(SimpleNamespace(angle=ang, samples=smp), 0, t.size, 0, 1, Xa, Xb, w, to_xy=st[0][2])
    ref = orbit_data(SimpleNamespace(angle=ang, samples=np.column_stack([x, y])), 0, t.size, 0, 1, X, Y, w)
    assert o.whirl == ref.whirl == 'backward'
    np.testing.assert_allclose(o.filt, ref.filt, atol=1e-15)
    np.testing.assert_allclose(o.raw, ref.raw, atol=1e-15)
    np.testing.assert_allclose(o.pk_pk, [6e-6, 4e-6], rtol=1e-12)
    assert probe_stations((Probe('x1', 3, 'x'), Probe('y1', 3, 'y')))[0][2] is None   # x and y: used as they are


def test_spectrum_amplitude_of_a_sinusoid():
    fs = 1024.0
    t = np.arange(4096) / fs
    f, a = amplitude_spectrum(7e-6 * np.cos(2 * math.pi * 32.0 * t) + 1e-3, fs, fmax=100.0)
    k = int(np.argmax(a))
    assert f[k] == pytest.approx(32.0) and a[k] == pytest.approx(7e-6, rel=1e-6)
    assert f[-1] <= 100.0


def test_journal_positions_are_the_bearing_equilibrium(rig):
    bfn = supports.bearing_fn(rig)
    w = np.array([50.0, 200.0, 300.0])
    jp = journal_positions(bfn, w)
    for node, d in jp.items():
        c = d['clearance']
        np.testing.assert_allclose(np.hypot(*d['xy'].T), d['eps'] * c, rtol=1e-9)
        assert np.all(d['xy'][:, 1] < 0)                 # below the bearing centre: load along -y
        assert np.all(np.diff(d['eps']) < 0)             # the journal rises towards the centre with speed
        sol = bfn.solutions(200.0)[node]
        np.testing.assert_allclose(d['xy'][1], sol.journal_position)


# ------------------------------------------------------------------------------------------------ the page
def test_report_page_is_self_contained(demo):
    rig, recs, info = demo
    html = info.path.read_text(encoding='utf-8')
    assert 'Content-Security-Policy' in html and "default-src 'none'" in html
    assert not re.search(r"(src|href)\s*=\s*[\"'](?!data:|#)", html)           # nothing fetched, only anchors
    imgs = re.findall(r'<img alt="([^"]+)" src="data:image/png;base64,([^"]+)"', html)
    assert len(imgs) == info.n_figures
    names = [a for a, _ in imgs]
    for want in ('campbell_theory', 'campbell_identified', 'mode_shapes', 'bode_p6x', 'polar_p6y', 'orbits_node6',
                 'spectrum_node6', 'centreline', 'coefficients'):
        assert want in names
    for _, b64 in imgs:
        assert base64.b64decode(b64)[:8] == b'\x89PNG\r\n\x1a\n'
    for text in ('Machine summary', 'critical speeds, theory', 'stability threshold, identified', '1964 rpm',
                 '144 of 144 coefficients determined', 'units: speed rpm'):
        assert text in html
    assert not info.notes


def test_report_in_a_headless_browser(demo, tmp_path):
    if find_chromium() is None:
        if os.environ.get('CI'):
            pytest.fail('CI: chromium is not installed (.ci/run installs it with apt-get install chromium)')
        pytest.skip('chromium not installed (apt-get install chromium); CI runs this check')
    rig, recs, info = demo
    res = browser_check(info.path, screenshot=tmp_path / 'shot.png', window=(1400, 1200))
    assert res['done'], res
    assert res['images'] == info.n_figures and res['decoded'] == res['images'], res
    assert res['errors'] == [] and res['console'] == [], res
    assert (tmp_path / 'shot.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_browser_check_catches_broken_pages(tmp_path):
    if find_chromium() is None:
        if os.environ.get('CI'):
            pytest.fail('CI: chromium is not installed')
        pytest.skip('chromium not installed')
    page = Page('broken')
    page.raw('<img alt="corrupt" src="data:image/png;base64,iVBORw0KGgoAAAA="><script>noSuchFunction();</script>')
    res = browser_check(page.write(tmp_path / 'bad.html'))
    assert res['done'] and res['decoded'] == 0 and res['bad'] == ['corrupt']
    assert any('noSuchFunction' in e for e in res['errors']) and res['console']


def test_diagnosis_section_from_a_diagnosis_like_object(tmp_path):
    """The before/after section draws what the diagnosis predicts (here a stand-in with the same interface)."""
    probes = (Probe('p6x', 6, 'x'), Probe('p6y', 6, 'y'))
    rec = SimpleNamespace(probes=probes, run=Run('A', ()))
    wins = [SimpleNamespace(rec=0, speed=s, X=np.array([[1e-6 * (k + 1), 2e-6j]]), std=np.full((1, 2), 1e-8))
            for k, s in enumerate([100.0, 200.0, 300.0])]

    class Prob:
        n_nuis = 4
        windows = wins
        obs = SimpleNamespace(recordings=[rec], orders=(1.0,))

        def prediction_by_window(self, theta, effects, nls, lin):
            f = 1.0 + 0.1 * len(effects) + (0.05 if np.any(theta) else 0.0)
            return [w.X * f for w in wins]
    fit = SimpleNamespace(theta=np.ones(4), effects=[1], nls=[], lin=np.zeros(0))
    diag = SimpleNamespace(problem=Prob(), selection=SimpleNamespace(base=SimpleNamespace(theta=np.ones(4)),
                                                                     final=fit))
    dc = diagnosis_curves(diag)
    assert len(dc['panels']) == 2
    p = dc['panels'][0]
    np.testing.assert_allclose(p['rpm'], np.array([100.0, 200.0, 300.0]) * RPM_PER_RAD_S)
    np.testing.assert_allclose(p['augmented'], p['measured'] * 1.15)
    np.testing.assert_allclose(p['nominal'], p['measured'])
    fig = diagnosis_bode_figure(p)
    (ln,) = _by_gid(fig, 'diag:augmented')
    np.testing.assert_allclose(ln.get_ydata(), np.abs(p['augmented']) * 1e6)
    residual_orders_figure(dc)


# ------------------------------------------------------------------------------------------------ CLI
@pytest.fixture(scope='module')
def small_npz(tmp_path_factory):
    """Two simulated runs (truth != theory) at 3 speeds, as .npz files."""
    rig = load_rig()
    d = tmp_path_factory.mktemp('small')
    return [str(save_npz(simulate_run(rig, run, speeds_rpm=[900.0, 1500.0, 2400.0], dwell=0.8, ramp=0.2, seed=3),
                         d / f'run_{run.id}.npz')) for run in rig.simulation.runs]


def test_cli_report(small_npz, tmp_path, capsys):
    """`bearing-id report`: exit 0 and the page with its figures; bad input exit 2."""
    assert main(['report', *small_npz, '--out', str(tmp_path / 'r'), '--png']) == 0
    out = capsys.readouterr().out
    html = (tmp_path / 'r' / 'report.html').read_text(encoding='utf-8')
    assert 'report.html' in out and html.count('<img ') == 11
    assert len(list((tmp_path / 'r').glob('*.png'))) == 11
    assert main(['report', str(tmp_path / 'missing.npz'), '--out', str(tmp_path / 'x')]) == 2
    assert main(['report', *small_npz, '--out', str(tmp_path / 'y'), '--max-rpm', '-1']) == 2


def test_identify_report(small_npz, tmp_path, capsys):
    rc = main(['identify', *small_npz, '--method', 'physical', '--plot', str(tmp_path / 'c.png'),
               '--report', str(tmp_path / 'rep')])
    assert rc == 0
    html = (tmp_path / 'rep' / 'report.html').read_text(encoding='utf-8')
    assert 'Bearing coefficients vs speed' in html and 'truth' in html and 'bearing-id identify' in html
    assert (tmp_path / 'c.png').stat().st_size > 10_000
