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

from bearing_id.io.recordings import save_npz
import pytest


@pytest.fixture(scope='module')
def runout_npz(tmp_path_factory):
    from bearing_id.simulation import rig as rigmod
    from bearing_id.simulation import effects as te
    from bearing_id.config.params import load_rig
    from bearing_id.conventions import rpm_to_rad_s
    rig = rigmod.with_truth(load_rig(), viscosity_factor=(1.0, 1.0), clearance_factor=(1.0, 1.0))
    d = tmp_path_factory.mktemp('runout')
    sched = [rigmod.Segment(float(rpm_to_rad_s(200)), 1.5)] + rigmod.step_schedule((800, 1200, 1600, 2400, 2800), 1.0)
    rec = rigmod.simulate(rig, rig.simulation.runs[0], sched, effects=[te.ProbeRunout('p6x', 4e-6, 0.5)])
    return [str(save_npz(rec, d / 'run_A.npz'))]


def test_diagnose_report_writes_the_page(runout_npz, tmp_path, capsys):
    from bearing_id.cli import main
    from bearing_id.config.params import load_rig
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
    from bearing_id.plots.html import browser_check, find_chromium
    if find_chromium() is None:
        if os.environ.get('CI'):
            pytest.fail('CI: chromium is not installed (.ci/run installs it with apt-get install chromium)')
        return
    res = browser_check(rep / 'report.html')
    assert res['done'] and res['images'] == n_img and res['decoded'] == n_img, res
    assert res['errors'] == [] and res['console'] == [], res


def test_no_noise_floor_skips_the_check(runout_npz, tmp_path, capsys):
    from bearing_id.cli import main
    assert main(['diagnose', *runout_npz, '--no-noise-floor', '--json', str(tmp_path / 'd.json')]) == 0
    out = capsys.readouterr().out
    assert 'verdict: probe_runout' in out and 'noise floor' not in out.split('located mismatch')[0]
    j = json.loads((tmp_path / 'd.json').read_text())
    assert j['noise_floor'] is None and j['verdict'] == 'probe_runout'
    assert (tmp_path / 'd_augmented_params.yaml').exists()


def test_help_says_what_is_printed(capsys):
    from bearing_id.cli import main
    with pytest.raises(SystemExit) as e:
        main(['diagnose', '--help'])
    assert e.value.code == 0
    out = capsys.readouterr().out
    for text in ('what is printed:', 'verdict:', 'located mismatch', 'hypotheses', '--no-noise-floor', 'report.html'):
        assert text in out


KILLED_COMMAND = """
import os, signal, sys, time
sys.path.insert(0, sys.argv[1])
from bearing_id.commands.diagnose import _floor_pool
pool = _floor_pool()
if pool is None:
    print('NO POOL', flush=True)
    sys.exit(0)
pool.submit(time.sleep, 120)
print('WORKERS', *[p.pid for p in pool._processes.values()], flush=True)
os.kill(os.getpid(), signal.SIGKILL)
"""


def test_the_noise_floor_worker_ends_with_a_killed_command():
    """
    `diagnose` killed with SIGKILL in the middle of the noise-floor fit: its one worker process goes too (no orphan).

    The worker waits on its parent's sentinel (bearing_id.commands.diagnose._worker_init).  30 s is an upper bound for
    a loaded machine (the fit it was given takes 120 s), not a verdict on speed.
    """
    import subprocess
    import sys
    import time
    from pathlib import Path
    root = str(Path(__file__).resolve().parent.parent)
    env = {k: v for k, v in os.environ.items() if k != 'BEARING_ID_WORKERS'}
    r = subprocess.run([sys.executable, '-c', KILLED_COMMAND, root], capture_output=True, text=True, timeout=60,
                       env=env)
    if 'NO POOL' in r.stdout:
        pytest.skip('no spare core: diagnose runs without a worker here')
    pids = [int(x) for x in r.stdout.split()[1:]]
    assert r.stdout.startswith('WORKERS') and pids, r.stdout + r.stderr
    t_end = time.monotonic() + 30.0
    while any(_alive(p) for p in pids) and time.monotonic() < t_end:
        time.sleep(0.1)
    left = [p for p in pids if _alive(p)]
    for p in left:                      # (do not leave it behind when the test fails)
        os.kill(p, 9)
    assert not left, f'worker(s) {left} outlived their killed command'


def _alive(pid: int) -> bool:
    """Return True while ``pid`` runs (a zombie counts as gone)."""
    try:
        with open(f'/proc/{pid}/stat') as fh:
            return fh.read().split(') ')[-1].split()[0] != 'Z'
    except OSError:
        return False
