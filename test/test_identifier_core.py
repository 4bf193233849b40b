"""
The identifier's data path without ROS (issue 9 "nothing dropped that can be kept", issue 10 "kept apart").

Blocks that arrive before their run's excitation wait and are used; a dwell split by a lost block uses both halves; a
restarted identifier knows the runs from its record; probe sets are never stacked; a malformed record line is skipped.
References: the offline route on the same samples (harmonics.recording_vectors) and the simulator.
"""
from __future__ import annotations

from dataclasses import replace
import json
from pathlib import Path

import agreement
from bearing_id.config.params import load_rig, Probe
from bearing_id.identify import harmonics, identify, physical
from bearing_id.io.messages import Block
from bearing_id.io.recordings import from_bag, recordings_from_bag
from bearing_id.nodes.identifier_core import identifiability_item, IdentifierCore
from bearing_id.nodes.runs import RunResolver
from bearing_id.rotor.assembly import RotorModel
from bearing_id.simulation import rig as R
from bearing_id.simulation.rig import simulate_data
import numpy as np
import pytest


@pytest.fixture(scope='module')
def rig():
    return load_rig()


@pytest.fixture(scope='module')
def rec(rig):
    return R.simulate_run(rig, rig.simulation.runs[0], speeds_rpm=[1500.0], dwell=3.0, ramp=0.0)


def blocks(rec, block=1024, run_id=None, probes=None, t0=0.0):
    fs = rec.sample_rate
    probes = probes or rec.probes
    for k, i0 in enumerate(range(0, rec.samples.shape[0], block)):
        i1 = min(i0 + block, rec.samples.shape[0])
        yield Block(stamp_ns=int(round((t0 + i0 / fs) * 1e9)), sequence=k, sample_rate=fs, speed=float(rec.speed[i0]),
                    angle=float(rec.angle[i0]), channels=tuple(p.name for p in probes),
                    nodes=tuple(p.node for p in probes), directions=tuple(p.direction for p in probes),
                    samples=rec.samples[i0:i1], sample_angles=rec.angle[i0:i1],
                    run_id=rec.run.id if run_id is None else run_id)


def test_blocks_wait_for_their_run_and_are_released_in_order(rec):
    rs = RunResolver(max_waiting=5)
    bl = list(blocks(rec))[:4]
    assert [rs.resolve(b, k) for k, b in enumerate(bl)] == [None] * 4        # run A not announced yet
    new, released = rs.announce(0.0, rec.run)
    assert new and [t for _, _, t in released] == [0, 1, 2, 3] and all(r is rec.run for _, r, _ in released)
    assert rs.resolve(bl[0]) is rec.run and not rs.waiting
    for k, b in enumerate(blocks(rec, run_id='Z')):                           # a run never announced: bounded
        rs.resolve(b, k)
    assert len(rs.waiting) == 5 and rs.dropped > 0


def test_blocks_without_run_id_go_to_the_run_announced_before_their_stamp(rec, rig):
    rs = RunResolver()
    b0 = next(blocks(rec, run_id=''))
    assert rs.resolve(b0) is None
    _, rel = rs.announce(b0.stamp, rec.run)
    assert [r.id for _, r, _ in rel] == [rec.run.id]
    other = rig.simulation.runs[1]
    rs.announce(b0.stamp + 10.0, other)
    late = Block(**{**b0.__dict__, 'stamp_ns': b0.stamp_ns + 11_000_000_000})
    assert rs.resolve(late) is other and rs.resolve(b0) is rec.run


def _feed_all(core, bl, run, skip=()):
    wins = []
    prev_ok = True
    for k, b in enumerate(bl):
        if k in skip:
            prev_ok = False
            continue
        wins += core.feed(b, run, prev_ok, 0.0)
        prev_ok = True
    wins += core.flush(1e9, 0.0)
    return [w for w in wins if core.add_window(w)]


def test_a_dwell_split_by_a_lost_block_uses_both_halves(rec, rig, tmp_path):
    ref = harmonics.recording_vectors(rec)
    assert len(ref) == 1
    core = IdentifierCore(rig, 'physical', tmp_path)
    core.add_excitation(rec.run)
    bl = list(blocks(rec))
    used = _feed_all(core, bl, rec.run, skip={len(bl) // 2})
    assert len(used) == 2                                   # both halves were fitted and stored ...
    (speed, X, X_std, _, _), = core.vectors[rec.run.id]     # ... as one combined vector
    assert abs(speed - ref[0].speed) <= 1e-9 * speed
    assert np.all(np.abs(X - ref[0].X) <= 3 * np.hypot(X_std, ref[0].X_std))
    # said once, although the rest of the dwell was handed out provisionally (the end of the data) and cut again
    again = core.stream.stream.peek()
    assert again and all(core.add_window(w) for w in again)
    assert sum('combined with its first part' in n for n in core.notes) == 1, list(core.notes)
    core.close()
    # each half alone is less certain than the combination
    core2 = IdentifierCore(rig, 'physical', tmp_path / 'halves')
    first_half = _feed_all(core2, bl[:len(bl) // 2], rec.run)
    assert first_half and np.all(core2.vectors[rec.run.id][0][2] > X_std)
    core2.close()


def test_a_restarted_identifier_knows_its_runs_and_vectors_from_the_record(rec, rig, tmp_path):
    core = IdentifierCore(rig, 'physical', tmp_path)
    core.add_excitation(rec.run, stamp=12.5)
    _feed_all(core, list(blocks(rec)), rec.run)
    n = len(core.vectors[rec.run.id])
    core.close()
    again = IdentifierCore(rig, 'physical', tmp_path)
    assert again.resumed['vectors'] == n and list(again.runs) == [rec.run.id]
    assert again.run_starts == [(12.5, rec.run)]
    rs = RunResolver()
    for stamp, run in again.run_starts:
        rs.announce(stamp, run)
    b = next(blocks(rec, run_id='', t0=13.0))
    assert rs.resolve(b) == rec.run                        # a block without run id is not dropped after restart
    again.close()


def test_probe_sets_are_kept_apart(rec, rig, tmp_path):
    core = IdentifierCore(rig, 'physical', tmp_path)
    run_a, run_b = rig.simulation.runs
    core.add_excitation(run_a)
    core.add_excitation(run_b)
    _feed_all(core, list(blocks(rec)), run_a)
    moved = (Probe('p5x', 5, 'x'), Probe('p5y', 5, 'y'))      # the pair remounted at node 5 for run B
    _feed_all(core, list(blocks(rec, run_id=run_b.id, probes=moved)), run_b)
    assert core.assemble() is None                          # never stacked: run B's set has no run A vectors
    assert any('probe set changed' in n for n in core.notes)
    core.close()


def test_a_malformed_record_line_is_skipped_with_a_note(rec, rig, tmp_path):
    core = IdentifierCore(rig, 'physical', tmp_path)
    core.add_excitation(rec.run)
    _feed_all(core, list(blocks(rec)), rec.run)
    core.close()
    with open(tmp_path / 'record.jsonl', 'a') as fh:        # valid JSON, but a vector without "X"
        fh.write(json.dumps({'n': 99, 'type': 'vector', 'source': 'measured', 'run_id': 'A', 'speed': 157.0,
                             'probes': [['p6x', 6, 'x']]}) + '\n')
    again = IdentifierCore(rig, 'physical', tmp_path)
    assert again.resumed['malformed'] == 1 and again.resumed['vectors'] == 1
    assert any('malformed' in n for n in again.notes)
    again.close()


def test_estimated_vectors_of_an_old_record_are_not_resumed(rec, rig, tmp_path):
    """Records of older versions may hold the kf_estimator's 'estimated' vectors: skipped, never stacked."""
    core = IdentifierCore(rig, 'physical', tmp_path)
    core.add_excitation(rec.run)
    _feed_all(core, list(blocks(rec)), rec.run)
    ref = core.assemble()
    core.close()
    lines = (tmp_path / 'record.jsonl').read_text().splitlines()
    old = [json.loads(x) for x in lines]
    vec = next(e for e in old if e['type'] == 'vector')
    est = dict(vec, n=99, source='estimated', X=dict(vec['X'], re=[2.0 * v for v in vec['X']['re']]))   # other X
    wd = {'n': 100, 'type': 'withdrawn', 'source': 'estimated', 'run_id': vec['run_id'], 'window': vec['window']}
    with open(tmp_path / 'record.jsonl', 'a') as fh:
        fh.write(json.dumps(est) + '\n' + json.dumps(wd) + '\n')
    again = IdentifierCore(rig, 'physical', tmp_path)
    assert again.resumed['vectors'] == sum(e['type'] == 'vector' for e in old) and again.resumed['malformed'] == 0
    data = again.assemble()
    # the measured vectors only, the withdrawal ignored: the record's own numbers (floats stored by repr, which reads
    # back exactly -- one route, no arithmetic between the two)
    np.testing.assert_array_equal(data.X, ref.X)
    np.testing.assert_array_equal(data.X_std, ref.X_std)
    again.close()


def test_paper_does_not_use_resumed_vectors_without_their_plain_fit(rec, rig, tmp_path):
    """
    A record written before vectors carried their plain 1X fit: method paper leaves those out, with a note (no crash).

    Control: the same record with the fits resumes to data whose plain fit equals the offline route's.
    """
    core = IdentifierCore(rig, 'paper', tmp_path, required_runs=['A'])
    core.add_excitation(rec.run)
    _feed_all(core, list(blocks(rec)), rec.run)
    core.close()
    again = IdentifierCore(rig, 'paper', tmp_path, required_runs=['A'])
    data = again.assemble()
    ref = harmonics.from_recordings([rec])
    assert data is not None and data.sample_rate == rec.sample_rate
    agreement.assert_within_sigma(data.plain.X, ref.plain.X, np.sqrt(np.minimum(ref.plain.var_re, ref.plain.var_im)),
                                  'plain X')
    again.close()
    lines = [json.loads(x) for x in (tmp_path / 'record.jsonl').read_text().splitlines()]
    for e in lines:
        e.pop('plain_X', None)
        e.pop('plain_var', None)
    (tmp_path / 'record.jsonl').write_text(''.join(json.dumps(e) + '\n' for e in lines))
    old = IdentifierCore(rig, 'paper', tmp_path, required_runs=['A'])
    assert old.resumed['vectors'] >= 1 and old.assemble() is None
    assert sum('lack the plain 1X fit' in n for n in old.notes) == 1
    old.close()


def test_a_long_dwell_is_fitted_in_pieces_and_combined(rec):
    """
    Windows longer than max_window are fitted in pieces (bounded memory) and combined.

    The same vector as the whole window within the stated sigma, and a sigma no larger than 1.2 x the whole window's.
    """
    whole, = harmonics.recording_vectors(rec)
    pieces = harmonics.recording_vectors(rec, max_window=0.7)
    assert len(pieces) == 1                         # one vector per dwell, from several pieces
    v = pieces[0]
    assert np.all(np.abs(v.X - whole.X) <= 3 * np.hypot(v.X_std, whole.X_std))
    assert np.all(v.X_std <= 1.2 * whole.X_std)


def test_warm_started_solves_give_the_cold_answers(rig, tmp_path):
    """
    The node re-solves as speeds arrive, each physical fit starting from the previous one (warm start).

    Reference: a core that always starts from nominal (warm_start=False) on the same vectors.  Tolerance = the
    solver's: it stops when the cost changes by < 1e-12 relative (ftol, xtol), which on a chi-square of ~30 leaves
    each parameter within ~sqrt(2e-12 chi2) ~ 1e-5 of its 1-sigma of the minimum; both starts must agree within 1e-4
    sigma (parameters and coefficients) and 1e-9 relative in chi-square, with fewer solver evaluations warm.
    """
    speeds = (900, 1500, 2100, 2700)
    data = simulate_data(rig, rig.simulation.runs, speeds)
    rng = np.random.default_rng(3)
    std = 1e-3 * np.abs(data.X)
    X = data.X + std * (rng.standard_normal(data.X.shape) + 1j * rng.standard_normal(data.X.shape))
    warm = IdentifierCore(rig, 'physical', tmp_path / 'warm')
    cold = IdentifierCore(rig, 'physical', tmp_path / 'cold', warm_start=False)
    nfev = {'warm': 0, 'cold': 0}
    orig = physical.least_squares
    for k, w in enumerate(data.speeds):
        for core in (warm, cold):
            for r, run in enumerate(data.runs):
                if k == 0:
                    core.add_excitation(run)
                core._store(run.id, float(w), X[r, k], std[r, k], data.probes)
        out = {}
        for name, core in (('warm', warm), ('cold', cold)):
            def counting(*a, _name=name, **kw):
                sol = orig(*a, **kw)
                nfev[_name] += sol.nfev
                return sol
            physical.least_squares = counting
            try:
                out[name], _ = core.solve()
            finally:
                physical.least_squares = orig
        assert len(out['warm']) == len(out['cold']) == k + 1
        fw, fc = out['warm'][0].extra['fit'], out['cold'][0].extra['fit']
        sig = np.sqrt(np.diag(fc.cov_log))
        assert np.all(np.abs(np.log(fw.values / fc.values)) <= 1e-4 * sig), (k, fw.values / fc.values - 1, sig)
        assert fw.chi2 == pytest.approx(fc.chi2, rel=1e-9)
        for a, b in zip(out['warm'], out['cold']):
            cov = b.extra['cov_beta']
            # beta order of cov_beta: per bearing [K (4), C (4)]
            d = np.concatenate([(a.K - b.K).reshape(len(a.K), 4), (a.C - b.C).reshape(len(a.C), 4)], axis=1)
            d = d.reshape(-1)
            assert np.all(np.abs(d) <= 1e-4 * np.sqrt(np.diag(cov))), k
    assert nfev['warm'] < nfev['cold'], nfev
    warm.close()
    cold.close()


def test_a_provisional_window_is_replaced_by_its_final_cut_or_withdrawn(rec, rig, tmp_path):
    """
    A pause hands out the open window provisionally; its final cut replaces that vector.

    Replaced, not stored as a duplicate; and when the final cut gives no vector, the provisional one is withdrawn --
    also after a restart from the record.
    """
    core = IdentifierCore(rig, 'physical', tmp_path)
    core.add_excitation(rec.run)
    stream = harmonics.RunStream(rec.run, rec.probes, rec.sample_rate)
    half = rec.samples.shape[0] // 2
    assert not stream.feed(rec.samples[:half], rec.angle[:half])
    provisional, = stream.peek()
    assert provisional.provisional and not stream.feed(rec.samples[half:], rec.angle[half:])
    final, = stream.close()
    assert final.key == provisional.key and final.i1 > provisional.i1
    assert core.add_window(provisional)
    (_, X_prov, S_prov, _, _), = core.vectors[rec.run.id]
    assert core.add_window(final)
    (speed, X, S, _, _), = core.vectors[rec.run.id]       # replaced, not a second (duplicate) entry
    ref, = harmonics.recording_vectors(rec)
    agreement.assert_within_sigma(X, ref.X, ref.X_std, 'X')
    assert np.all(S < S_prov) and not np.array_equal(X, X_prov)
    short = replace(final, i1=final.i0 + 10, samples=final.samples[:10], angle=final.angle[:10],
                    speed=final.speed[:10])
    assert core.add_window(short) == []
    assert core.vectors[rec.run.id] == [None] and core.assemble() is None
    core.close()
    again = IdentifierCore(rig, 'physical', tmp_path)
    assert again.vector_counts() == {rec.run.id: 0} and again.assemble() is None
    again.close()


@pytest.mark.parametrize('method', ['paper', 'conventional', 'direct', 'physical'])
def test_every_method_through_the_core_equals_the_offline_route(rig, tmp_path, method):
    """
    IdentifierCore.solve (the node's route: blocks -> windows -> stored vectors -> assemble) == ``identify`` offline.

    Reference: ``identify(method, ...)`` on ``harmonics.from_recordings`` of the same recordings (what `bearing-id
    identify` runs), default options.  Probes at both bearings and midspan, so that every method runs.  The paper
    method's live route once produced nothing (no test drove it); this holds every method to the offline numbers:
    values, 1-sigma (NaN where undetermined, on both routes), determined flags, rank and flags.
    """
    probes = tuple(Probe(f'p{n}{d}', n, d) for n in (2, 6, 10) for d in 'xy')
    recs = [R.simulate_run(rig, run, speeds_rpm=[1200.0, 2400.0], dwell=1.5, ramp=0.2, probes=probes)
            for run in rig.simulation.runs]
    ref = identify(method, RotorModel.from_params(rig), rig, harmonics.from_recordings(recs))
    core = IdentifierCore(rig, method, tmp_path, options={'kf': {'Q': 1e-16, 'R': None}})
    for k, r in enumerate(recs):
        core.add_excitation(r.run, stamp=100.0 * k)
        wins = []
        for b in blocks(r, t0=100.0 * k):
            wins += core.feed(b, r.run, True, 0.0)
        wins += core.flush(1e9, 0.0)
        for w in wins:
            core.add_window(w)
    live, data = core.solve(record=False)
    core.close()
    assert data.plain is not None and not data.recordings
    assert len(ref) == 2
    agreement.assert_results_agree(live, ref, method)


@pytest.mark.parametrize('bag, chosen', [('unbalance_ab_sweep', 'physical'), ('force_plan', 'direct')])
def test_the_default_method_auto_chooses_by_the_data_and_says_so(tmp_path, bag, chosen):
    """
    The node's default, auto, chooses by the data, as `bearing-id identify` does.

    On the packaged bags: physical for unbalance runs at one probe station (rank 8 of 16), direct for the
    directional-force plan; the choice and its reason in every result and on /diagnostics, and the same results as
    `bearing-id identify` on the bag (within 0.01 of their 1-sigma).
    """
    path = Path(__file__).resolve().parent.parent / 'bags' / bag
    rig = load_rig()
    recs = recordings_from_bag(path)
    core = IdentifierCore(rig, 'auto', tmp_path / 'record')
    assert core.method == 'auto'
    for r in recs:
        core.add_excitation(r.run)
    for r in recs:
        _feed_all(core, list(blocks(r)), r.run)
    res, _ = core.solve()
    core.close()
    assert res and {r.method for r in res} == {chosen}
    assert all(r.extra['auto']['method'] == chosen and r.notes[0].startswith(f'method auto chose {chosen}: ')
               for r in res)
    item = identifiability_item(res)
    assert item.values['method'].startswith(f'{chosen} (auto: the design check on these data')
    ref = identify('auto', RotorModel.from_params(rig), rig, from_bag(path))
    agreement.assert_results_agree(res, ref, f'auto on {bag}')


@pytest.mark.parametrize('method', ['direct', 'conventional'])
def test_a_per_speed_method_solves_only_the_speeds_that_changed(rig, tmp_path, method):
    """
    A per-speed method re-solves only new or changed speeds: the cost does not grow with the history.

    Issue 23 item 6; the answers are those of one solve of everything.

    Reference: ``identify(method, ...)`` on all speeds at once.  Directional-force runs and probes at both bearings
    and midspan (every coefficient determined), 1e-3 relative noise.
    """
    probes = tuple(Probe(f'p{n}{d}', n, d) for n in (2, 6, 10) for d in 'xy')
    runs = R.scenario('force')
    data = simulate_data(rig, runs, (900, 1500, 2100, 2700), probes=probes)
    rng = np.random.default_rng(5)
    std = 1e-3 * np.abs(data.X)
    X = data.X + std * (rng.standard_normal(data.X.shape) + 1j * rng.standard_normal(data.X.shape))
    core = IdentifierCore(rig, method, tmp_path, options={'kf': {'Q': 1e-16, 'R': None}})
    for run in runs:
        core.add_excitation(run)
    latest = {}
    for k, w in enumerate(data.speeds):
        for r, run in enumerate(runs):
            core._store(run.id, float(w), X[r, k], std[r, k], probes)
        out, _ = core.solve(record=False)
        assert [o.speed for o in out] == [float(w)], (k, [o.speed_rpm for o in out])     # the new speed only
        latest.update({o.speed: o for o in out})
    assert core.solve(record=False)[0] == []                                            # nothing changed
    ref = identify(method, RotorModel.from_params(rig), rig, replace(data, X=X, X_std=std))
    agreement.assert_results_agree([latest[s] for s in sorted(latest)], ref, method)
    # a new dwell at 1500 rpm (its vectors change): that speed, and only it, is solved again
    core._store(runs[0].id, float(data.speeds[1]), X[0, 1] * 1.01, std[0, 1], probes)
    out, _ = core.solve(record=False)
    assert [o.speed for o in out] == [float(data.speeds[1])]
    core.close()


@pytest.mark.parametrize('block', [1024, 4096, 8192])
def test_a_gap_between_long_blocks_of_a_1x_stream_is_no_pause(rec, rig, tmp_path, block):
    """
    Blocks arriving once per block time (a 1x stream) are no pause, however long the blocks; a real pause is.

    With 4096-sample blocks at 10,240 Hz (0.4 s) and ``segment_timeout`` 0.3 s, every gap between two blocks was a
    pause: the open window was handed out, fitted and solved once per block (the identifier's CPU x6.7).  A pause is
    now also ``pause_blocks`` (3) blocks' time without a block.
    """
    core = IdentifierCore(rig, 'physical', tmp_path)
    core.add_excitation(rec.run)
    dt = block / rec.sample_rate
    now = 0.0
    for b in blocks(rec, block=block):
        if b.samples.shape[0] < block:
            break                                          # whole blocks only
        core.feed(b, core.runs[b.run_id], True, now)
        now += dt                                          # the next block arrives one block time later
        assert core.flush(now - 1e-3, 0.3, 3.0) == [], block
    last = now - dt                                        # the last block's arrival: the data end there
    assert core.flush(last + max(0.3, 3 * dt) - 1e-3, 0.3, 3.0) == []
    out = core.flush(last + max(0.3, 3 * dt) + 1e-3, 0.3, 3.0)
    assert out and all(w.provisional for w in out)
    core.close()
