"""`bearing-id identify` end to end on simulated .npz recordings: refusal (exit 1) and flagged output (exit 0)."""
import argparse
import json
from pathlib import Path

from bearing_id import plots
from bearing_id.cli import main
from bearing_id.commands import identify as cmd
from bearing_id.config import defaults
from bearing_id.config.params import load_rig
from bearing_id.io.recordings import load_npz, save_npz
from bearing_id.nodes import identifier_core, kf_estimator_core
from bearing_id.simulation import rig as rigmod
import numpy as np
import pytest


@pytest.fixture(scope='module')
def npz_runs(tmp_path_factory):
    d = tmp_path_factory.mktemp('ident')
    rig = load_rig()
    paths = []
    for run in rig.simulation.runs:       # unbalance A and B, node-6 probes: undetermined by design (rank 8 of 16)
        rec = rigmod.simulate_run(rig, run, speeds_rpm=[1200, 1800], dwell=0.6, noise=0.01)
        paths.append(str(save_npz(rec, d / f'run_{run.id}.npz')))
    return d, paths


def test_undetermined_plan_exits_1_and_prints_no_numbers(npz_runs, capsys):
    d, paths = npz_runs
    out_json = d / 'r.json'
    code = main(['identify', *paths, '--method', 'paper', '--json', str(out_json)])
    cap = capsys.readouterr()
    assert code == 1
    assert 'UNDETERMINED' in cap.err and 'rpm' in cap.err
    assert 'undetermined' in cap.out and '(prior)' not in cap.out
    assert 'N/m' in cap.out and 'N s/m' in cap.out
    res = json.loads(out_json.read_text())['results']
    assert [round(r['speed_rpm']) for r in res] == [1200, 1800]
    for r in res:
        assert r['unknowns'] == 16 and r['rank'] <= 8 and r['method'] == 'paper'
        # the paper method's honesty figures: how much of the answer is the KF's theory, per coefficient and overall
        assert 0.0 <= r['theory_fraction'] and any('theory fraction' in n for n in r['notes'])
        for b in r['bearings']:
            for sym in ('K', 'C'):
                sens = np.array(b['theory_sensitivity'][sym])
                assert sens.shape == (2, 2) and np.all(np.isfinite(sens))
                # a coefficient that follows the theory (d identified / d theory > 0.5) is never 'determined'
                assert not np.any(np.array(b['determined'][sym]) & (sens > 0.5))
            for sym in ('K', 'C'):
                for row, okr in zip(b[sym], b['determined'][sym]):
                    for v, ok in zip(row, okr):
                        assert (v is None) == (not ok)      # undetermined values are not published as numbers


def test_allow_undetermined_prints_flagged_values_and_exits_0(npz_runs, capsys):
    d, paths = npz_runs
    code = main(['identify', *paths, '--method', 'paper', '--allow-undetermined', '--plot', str(d / 'c.png')])
    cap = capsys.readouterr()
    assert code == 0
    flagged = [ln for ln in cap.out.splitlines() if ln.rstrip().endswith('(prior)')]
    assert len(flagged) >= 16                          # >= 8 per speed, 2 speeds
    assert all(np.isfinite(float(ln.split()[2])) for ln in flagged)
    assert (d / 'c.png').stat().st_size > 1000
    # the paper's Figs 5-6: KF bearing-node amplitude/phase vs speed, with the truth (the recordings carry it)
    png = d / 'c_bearing_vectors.png'
    assert png.stat().st_size > 1000
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert str(png) in cap.out


def test_bearing_vectors_plot_draws_estimate_and_truth(tmp_path):
    # plots.bearing_vectors_figure with runs x speeds x bearings x (x, y): one estimated and one true line per run in
    # every amplitude/phase panel; amplitudes in um, phases in degrees (checked on the drawn data).
    speeds = np.array([100.0, 200.0, 300.0])
    est = np.zeros((2, 3, 2, 2), complex)
    est[...] = 2e-6 * np.exp(1j * np.pi / 6)
    kw = {'true': 1.1 * est, 'nodes': (2, 10), 'run_labels': ['A', 'B']}
    fig = plots.bearing_vectors_figure(speeds, est, **kw)
    p = plots.plot_bearing_vectors(speeds, est, tmp_path / 'bv.png', **kw)
    assert p.stat().st_size > 1000
    ax_amp, ax_ph = fig.axes[0], fig.axes[4]
    assert len(ax_amp.lines) == 4                                 # 2 runs x (estimated, true)
    np.testing.assert_allclose(ax_amp.lines[0].get_ydata(), 2.0)  # 2e-6 m = 2 um
    np.testing.assert_allclose(ax_amp.lines[1].get_ydata(), 2.2)
    np.testing.assert_allclose(ax_ph.lines[0].get_ydata(), 30.0)  # pi/6 rad = 30 deg


def test_bad_inputs_exit_2(npz_runs, tmp_path):
    d, paths = npz_runs
    assert main(['identify', str(tmp_path / 'missing.npz')]) == 2
    bad = tmp_path / 'bad.npz'
    bad.write_bytes(b'not a zip')
    assert main(['identify', str(bad)]) == 2
    # conventional needs two probe nodes per bearing and direction: a named parameter error, not a traceback
    assert main(['identify', *paths, '--method', 'conventional']) == 2


def test_default_method_identifies_the_default_simulated_data(npz_runs, capsys):
    """
    `bearing-id identify` without --method on unbalance runs at one probe station (rank 8 of 16 per speed).

    The default, auto, runs physical and says why (the design check on these data); every coefficient is determined
    and within 3 of its stated 1-sigma of the simulator's truth, which the recordings carry.
    """
    d, paths = npz_runs
    out_json = d / 'auto.json'
    code = main(['identify', *paths, '--json', str(out_json)])
    out = capsys.readouterr().out
    assert code == 0
    assert out.startswith('method: physical (auto: ') and 'rank 8 of 16' in out.splitlines()[0]
    doc = json.loads(out_json.read_text())
    assert doc['method'] == 'physical' and doc['requested'] == 'auto'
    assert all(r['auto']['method'] == 'physical' and 'design check' in r['auto']['reason'] for r in doc['results'])
    truth = load_npz(paths[0]).truth['coefficients']
    for r in doc['results']:
        assert r['method'] == 'physical' and r['notes'][0].startswith('method auto chose physical: ')
        true = truth[min(truth, key=lambda s: abs(s - r['speed_rad_s']))]
        for b in r['bearings']:
            for sym, k in (('K', 0), ('C', 1)):
                assert np.all(b['determined'][sym])
                err = (np.array(b[sym]) - true[b['node']][k]) / np.array(b[sym + '_std'])
                assert np.all(np.abs(err) < 3.0), err


def test_default_method_is_direct_where_the_plan_determines_every_coefficient(capsys):
    """The packaged directional-force bag (4 shaker runs): the design check determines all 16, auto runs direct."""
    bag = Path(__file__).resolve().parent.parent / 'bags' / 'force_plan'
    code = main(['identify', str(bag)])
    out = capsys.readouterr().out
    assert code == 0
    assert out.startswith('method: direct (auto: the design check on these data (each speed at its measured noise) '
                          'determines all 16 coefficients at every speed')
    assert 'method direct  rank 16 of 16' in out


def test_method_options_need_their_method(npz_runs, capsys):
    """A method's own option with the default method is an error naming the method (exit 2), not ignored."""
    d, paths = npz_runs
    assert main(['identify', *paths, '--method', 'direct', '--bearing-model', 'finite']) == 2
    assert '--bearing-model applies to --method physical only' in capsys.readouterr().err
    assert main(['identify', *paths, '--Q', '1e-18']) == 2              # auto never runs the paper method
    assert '--Q applies to --method paper only' in capsys.readouterr().err


def test_the_cli_and_the_nodes_share_their_defaults():
    """One place for defaults (config/defaults.py): the identifier and kf_estimator specs and the CLI take them."""
    sub = argparse.ArgumentParser().add_subparsers()
    args = cmd.add_parser(sub).parse_args(['x.npz'])
    spec = {s.name: s.default for s in identifier_core.SPECS}
    assert args.method == spec['method'] == defaults.METHOD
    assert spec['kf_process_noise'] == defaults.KF_PROCESS_NOISE
    # the live filter fits its Q to the innovations (0) around the paper's value
    assert {s.name: s.default for s in kf_estimator_core.SPECS}['process_noise'] == 0.0
    assert (spec['speed_tolerance'], spec['settle_fraction'], spec['min_window'], spec['max_segment']) == \
        (defaults.SPEED_TOLERANCE, defaults.SETTLE_FRACTION, defaults.MIN_WINDOW, defaults.MAX_WINDOW)
