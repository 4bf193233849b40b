"""
`bearing-id diagnose` as a command: what it prints, --report (the page with the before / after), --no-noise-floor.

A recording made here by the simulated rig with 4 um of probe runout hidden on p6x (simulator side,
bearing_id.simulation.effects; parameters chosen in this file), run A, a 1.5 s slow roll and 1 s dwells at 5 speeds (the
schedule of test/test_diagnose.py): small enough for a command-level test.  The diagnosis itself is proven in
test/test_diagnose*.py; here the command's wiring: the verdict printed, the page written with the diagnosis section,
its figures as PNG, the augmented params, the noise-floor check run or skipped on request, and the help text.
"""
from __future__ import annotations

import json
import os

from bearing_id.cli import main
from bearing_id.config.params import load_rig
from bearing_id.conventions import rpm_to_rad_s
from bearing_id.io.recordings import save_npz
from bearing_id.plots.html import browser_check, find_chromium
from bearing_id.simulation import effects as te, rig as rigmod
import pytest


@pytest.fixture(scope='module')
def runout_npz(tmp_path_factory):
    rig = rigmod.with_truth(load_rig(), viscosity_factor=(1.0, 1.0), clearance_factor=(1.0, 1.0))
    d = tmp_path_factory.mktemp('runout')
    sched = [rigmod.Segment(float(rpm_to_rad_s(200)), 1.5)] + rigmod.step_schedule((800, 1200, 1600, 2400, 2800), 1.0)
    rec = rigmod.simulate(rig, rig.simulation.runs[0], sched, effects=[te.ProbeRunout('p6x', 4e-6, 0.5)])
    return [str(save_npz(rec, d / 'run_A.npz'))]


def test_diagnose_report_writes_the_page(runout_npz, tmp_path, capsys):
    rep = tmp_path / 'rep'
    assert main(['diagnose', *runout_npz, '--report', str(rep), '--json', str(tmp_path / 'd.json')]) == 0
    out = capsys.readouterr().out
    assert 'verdict: probe_runout' in out, out
    assert f"report page: {rep / 'report.html'}" in out
    html = (rep / 'report.html').read_text(encoding='utf-8')
    assert 'Diagnosis: before / after' in html and 'verdict: probe_runout' in html
    assert 'bearing-id diagnose ' in html                    # the command and its printed output on the page
    n_img = html.count('<img ')
    pngs = sorted(p.name for p in rep.glob('*.png'))
    assert n_img == len(pngs) >= 10
    assert {'diagnosis_A_p6x.png', 'diagnosis_A_p6y.png', 'diagnosis_residual.png', 'campbell_theory.png'} <= set(pngs)
    assert 'verdict: probe_runout' in (rep / 'summary.txt').read_text()
    aug = load_rig(rep / 'augmented_params.yaml')
    assert aug.extra['effects'][0]['effect'] == 'probe_runout'
    assert json.loads((tmp_path / 'd.json').read_text())['noise_floor'] is not None
    if find_chromium() is None:
        if os.environ.get('CI'):
            pytest.fail('CI: chromium is not installed (.ci/run installs it with apt-get install chromium)')
        return
    res = browser_check(rep / 'report.html')
    assert res['done'] and res['images'] == n_img and res['decoded'] == n_img, res
    assert res['errors'] == [] and res['console'] == [], res


def test_no_noise_floor_skips_the_check(runout_npz, tmp_path, capsys):
    assert main(['diagnose', *runout_npz, '--no-noise-floor', '--json', str(tmp_path / 'd.json')]) == 0
    out = capsys.readouterr().out
    assert 'verdict: probe_runout' in out and 'noise floor' not in out.split('located mismatch')[0]
    j = json.loads((tmp_path / 'd.json').read_text())
    assert j['noise_floor'] is None and j['verdict'] == 'probe_runout'
    assert (tmp_path / 'd_augmented_params.yaml').exists()


def test_help_says_what_is_printed(capsys):
    with pytest.raises(SystemExit) as e:
        main(['diagnose', '--help'])
    assert e.value.code == 0
    out = capsys.readouterr().out
    for text in ('what is printed:', 'verdict:', 'located mismatch', 'hypotheses', '--no-noise-floor', 'report.html'):
        assert text in out
