"""
The Kalman-filter node's bearing-node estimates once the identifier has answered (issue 23 item 1).

With one probe station the bearing-node motion is the model's extrapolation.  On the theory bearings (25 % off the
simulator's truth in viscosity and clearance) the estimated 1X at the bearing nodes is tens of percent off; once the
identifier's fully determined coefficients at that speed are given (`physical` on the two unbalance runs, as the node
receives them on bearing_id/coefficients) it is within 1 % in amplitude and 1 degree in phase.  Reference: the
simulator's noise-free motion at the bearing nodes (the same simulation, probes there, no noise); the 1X of both by
a plain DFT over whole revolutions of the steady part (numpy here, not the package's harmonic fit).  The filter's noise
is each channel's own (from the data), its process noise the one the innovations imply, so every dwell's NIS is inside
its chi-square band once identified (and above it on the theory bearings); a probe gap offset never reaches it, and
on speed ramps its state carries over from band to band (no restart, orbits as the simulator's).
"""
from __future__ import annotations

from dataclasses import replace
import math
from pathlib import Path
import time

from bearing_id.config.params import load_rig, Probe
from bearing_id.estimation.kalman import nis_band
from bearing_id.identify import harmonics, identify
from bearing_id.io.messages import Block
from bearing_id.nodes import kf_estimator_core
from bearing_id.nodes.kf_estimator_core import EstimatorCore, IdentifiedBearings
from bearing_id.nodes.status import OK, WARN
from bearing_id.rotor.assembly import RotorModel
from bearing_id.simulation import rig as R
import numpy as np
import pytest
import yaml

RPM = 1500.0
REPO = Path(__file__).resolve().parents[1]


def one_x(x, angle):
    """1X phasors (m,) of x (n, m) over the whole revolutions of ``angle`` (n,): 2 mean(x e^{-j angle})."""
    turns = (angle - angle[0]) / (2 * math.pi)
    n = int(np.searchsorted(turns, math.floor(turns[-1])))
    return 2 * np.mean(x[:n] * np.exp(-1j * angle[:n, None]), axis=0)


def filtered(core, rec, run):
    return np.concatenate([o.estimates for o in filtered_outputs(core, rec, run)])


def filtered_outputs(core, rec, run):
    fs = rec.sample_rate
    out = []
    for k, i0 in enumerate(range(0, rec.samples.shape[0], 1024)):
        i1 = min(i0 + 1024, rec.samples.shape[0])
        b = Block(stamp_ns=int(i0 / fs * 1e9), sequence=k, sample_rate=fs, speed=float(rec.speed[i0]),
                  angle=float(rec.angle[i0]), channels=tuple(p.name for p in rec.probes),
                  nodes=tuple(p.node for p in rec.probes), directions=tuple(p.direction for p in rec.probes),
                  samples=rec.samples[i0:i1], sample_angles=rec.angle[i0:i1], run_id=run.id)
        core.submit(b, run, float(np.mean(rec.speed[i0:i1])), k > 0)
        while core.pending:
            got = core.drain()
            out += got
            if not got:                 # its models are being built (a thread): do not spin against it
                time.sleep(0.002)
    return out


@pytest.fixture(scope='module')
def case():
    rig = load_rig()
    recs = [R.simulate_run(rig, run, speeds_rpm=[RPM], dwell=2.0, ramp=0.0) for run in rig.simulation.runs]
    at_bearings = tuple(Probe(f'b{b.node}{d}', b.node, d) for b in rig.bearings for d in 'xy')
    truth = R.simulate_run(rig, rig.simulation.runs[0], speeds_rpm=[RPM], dwell=2.0, ramp=0.0, probes=at_bearings,
                           noise=0.0)
    return rig, recs, truth


def errors(rig, rec, truth, core):
    est = filtered(core, rec, rec.run)
    steady = slice(est.shape[0] // 4, None)              # the filter has settled from its steady-state start
    got, ref = one_x(est[steady], rec.angle[steady]), one_x(truth.samples[steady], truth.angle[steady])
    amp = np.abs(np.abs(got) / np.abs(ref) - 1)
    phase = np.abs(np.degrees(np.angle(got / ref)))
    return amp, phase


def test_bearing_node_estimates_follow_the_identified_bearings(case):
    rig, recs, truth = case
    theory = EstimatorCore(rig, 1e-16, 0.0, 0.01)
    amp0, _ = errors(rig, recs[0], truth, theory)
    health0 = theory.health_status()
    theory.close()
    assert np.mean(amp0) > 0.1                 # theory bearings: the extrapolation is far off (issue 23: 79 %) ...
    assert health0.level == WARN and 'coherent with 1X' in health0.message, health0.message   # ... and it says so
    res = identify('physical', RotorModel.from_params(rig), rig, harmonics.from_recordings(recs))
    (r,) = res
    assert r.fully_determined
    core = EstimatorCore(rig, 1e-16, 0.0, 0.01)
    core.set_coefficients(r.speed, {n: (r.K[i], r.C[i]) for i, n in enumerate(r.nodes)})
    assert core.bearings.source(r.speed) == 'identified' and core.bearings.source(2 * r.speed) == 'theory'
    amp, phase = errors(rig, recs[0], truth, core)
    health = core.health_status()
    core.close()
    assert np.all(amp <= 0.01) and np.all(phase <= 1.0), (amp, phase)
    assert health.level == OK and 'white' in health.message, health.message


def test_each_dwell_is_consistent_once_identified_and_the_theory_is_not(case):
    """
    Each dwell's mean NIS is in its 95 % band once identified, above it on the theory bearings.

    The node's default noise (R per channel, Q from the innovations); the theory bearings mispredict the 1X.

    One core per route through three speeds, as the node runs: what it learnt of the noise carries over.  Band: the
    chi-square of the dwell's samples times the two probes (kalman.nis_band), widened by the relative 1-sigma of the R
    the node estimated from the data and states with each block (Output.nis_rel_std: its median of at most 8 blocks
    is known to a few %, the chi-square band alone is +-1.4 % at 2 s), not a tuned number.
    """
    rig = case[0]
    ident, theory = EstimatorCore(rig, 0.0, 0.0, 0.01), EstimatorCore(rig, 0.0, 0.0, 0.01)
    for rpm in (900.0, 1500.0, 2400.0):
        recs = [R.simulate_run(rig, run, speeds_rpm=[rpm], dwell=2.0, ramp=0.0) for run in rig.simulation.runs]
        (r,) = identify('physical', RotorModel.from_params(rig), rig, harmonics.from_recordings(recs))
        assert r.fully_determined
        ident.set_coefficients(r.speed, {n: (r.K[i], r.C[i]) for i, n in enumerate(r.nodes)})
        for core, inside in ((ident, True), (theory, False)):
            out = filtered_outputs(core, recs[0], recs[0].run)
            nis = np.concatenate([o.nis for o in out])
            u = np.sqrt(np.mean(np.concatenate([np.full(o.nis.size, o.nis_rel_std ** 2) for o in out])))
            assert 0 < u < 0.1, u
            lo, hi = nis_band(nis.size, 2, rel_std=u)
            assert (lo <= np.mean(nis) <= hi) == inside and (inside or np.mean(nis) > hi), (rpm, inside, np.mean(nis))
    ident.close()
    theory.close()


def test_a_probe_gap_offset_never_reaches_the_filter(case):
    """A 30 um DC on every probe (a gap voltage not subtracted): the same estimates, within 1e-3 of the 1X."""
    rig, recs, truth = case
    plain, offset = EstimatorCore(rig, 1e-16, 0.0, 0.01), EstimatorCore(rig, 1e-16, 0.0, 0.01)
    a = filtered(plain, recs[0], recs[0].run)
    b = filtered(offset, replace(recs[0], samples=recs[0].samples + 30e-6), recs[0].run)
    nis = offset.nis_status().values['mean_nis'], plain.nis_status().values['mean_nis']
    plain.close()
    offset.close()
    steady = slice(a.shape[0] // 4, None)
    x1 = np.abs(one_x(a[steady], recs[0].angle[steady]))
    assert np.max(np.abs(a[steady] - b[steady])) <= 1e-3 * np.max(x1)
    assert abs(nis[0] / nis[1] - 1) <= 0.01, nis


def test_a_dc_step_at_a_steady_speed_is_followed_from_the_innovations(case):
    """
    The journal moves mid-dwell (a DC step of 20 noise sigma on both probes, 2 s into a 6 s dwell): the DC follows.

    The DC removed moves toward the step, never past it by more than 5 %, and is within 10 % of it at the end (it
    follows the innovations' own offset through the filter's bias gain: a small Q leaves the whole bias in them, one
    step; the fitted Q here takes most of it into the state first, so it takes a few seconds); the innovations' mean
    over the last second is within a tenth of the step.
    """
    rig = case[0]
    run = rig.simulation.runs[0]
    rec = R.simulate_run(rig, run, speeds_rpm=[RPM], dwell=6.0, ramp=0.0)
    sigma = rig.simulation.noise * np.sqrt(np.mean(rec.samples ** 2, axis=0))     # the simulator's noise std
    at = 20 * 1024
    step = np.zeros_like(rec.samples)
    step[at:] = 20 * sigma
    core = EstimatorCore(rig, 0.0, 0.0, 0.01)
    w = RPM * math.pi / 30
    core.set_coefficients(w, R.truth_bearing_fn(rig)(w))
    out = filtered_outputs(core, replace(rec, samples=rec.samples + step), run)
    core.close()
    moved = np.array([np.asarray(o.offset) - np.asarray(out[at // 1024 - 1].offset) for o in out[at // 1024:]])
    moved /= 20 * sigma
    assert np.all(moved <= 1.05) and np.all(np.diff(moved, axis=0) >= -0.05), moved
    assert np.all(moved[-1] >= 0.9), moved[-1]
    tail = np.concatenate([o.innovations for o in out[-10:]])
    assert np.all(np.abs(tail.mean(axis=0)) <= 2 * sigma), (tail.mean(axis=0), sigma)


def test_an_unequal_bearing_rig_through_fast_ramps_is_estimated_and_consistent_at_every_dwell(tmp_path):
    """
    An unequal-bearing rig through fast ramps: every dwell within 1 % and 1 degree, NIS in band; ramps followed.

    The variant: bearings of unequal length, clearance and oil, truth factors unequal, 0.3 s ramps between 2 s dwells
    (up to 8 % of speed per 1024-sample block, through the first critical speed).  Identified from a first pass over
    its speeds (`physical`, as the identifier fits them), a second pass (new noise) filtered by one core through the
    whole stream, ramps included.  At every dwell (last 3/4) the bearing-node 1X is within 1 % and 1 degree of the
    simulator's noise-free truth and the mean NIS inside its 95 % band (chi-square widened by the estimated R's stated
    1-sigma).  After each ramp the free vibration rings on: the R from a harmonic fit's residual counted it as noise
    (NIS 0.0004-1.4 at 1600-2500 rpm) and, with that mended, a DC fit of the samples took part of it (2500 rpm: 2.39).
    On the ramps (each with the block after it) the estimated bearing motion stays within a tenth of the orbit
    warning limit (``ORBIT_LIMIT`` of clearance) of the truth, sample by sample, so no orbit warning is raised that the
    truth is not within 10 % of: with one model per block (its mean speed) it was 29 % of the limit off through the
    critical speed.
    """
    d = yaml.safe_load((REPO / 'params' / 'rig.yaml').read_text())
    d['bearings'][0]['clearance'] = 4.5e-5
    d['bearings'][1].update(length=0.0095, clearance=6.0e-5, viscosity=0.025)
    sim = d['simulation']
    sim.update(speeds_rpm=[700, 1100, 1600, 2000, 2500, 2900], ramp=0.3, seed=11)
    sim['truth'].update(viscosity_factor=[1.15, 1.3], clearance_factor=[0.85, 0.9])
    for r in sim['runs']:
        for e in r['excitation']:
            e['magnitude'] *= 0.3
    path = tmp_path / 'variant.yaml'
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    rig = load_rig(path)
    res = identify('physical', RotorModel.from_params(rig), rig,
                   harmonics.from_recordings([R.simulate_run(rig, r) for r in rig.simulation.runs]))
    assert all(r.fully_determined for r in res)
    run = rig.simulation.runs[0]
    rec = R.simulate_run(rig, run, seed=R.run_seed(rig.simulation.seed, run.id, 1))
    at = tuple(Probe(f'b{b.node}{d}', b.node, d) for b in rig.bearings for d in 'xy')
    truth = R.simulate_run(rig, run, probes=at, noise=0.0)
    core = EstimatorCore(rig, 0.0, 0.0, 0.01)
    for r in res:
        core.set_coefficients(r.speed, {n: (r.K[i], r.C[i]) for i, n in enumerate(r.nodes)})
    out = filtered_outputs(core, rec, run)
    core.close()
    est = np.concatenate([o.estimates for o in out])
    nis = np.concatenate([o.nis for o in out])
    u2 = np.concatenate([np.full(o.nis.size, o.nis_rel_std ** 2) for o in out])
    steady = np.zeros(rec.speed.size, bool)
    for rpm in rig.simulation.speeds_rpm:
        idx = np.flatnonzero(np.abs(rec.speed - rpm * math.pi / 30) <= 1e-9 * rpm)
        steady[idx] = True
        w = slice(idx[0] + idx.size // 4, idx[-1] + 1)
        got, ref = one_x(est[w], rec.angle[w]), one_x(truth.samples[w], truth.angle[w])
        assert np.all(np.abs(np.abs(got) / np.abs(ref) - 1) <= 0.01), (rpm, got, ref)
        assert np.all(np.abs(np.degrees(np.angle(got / ref))) <= 1.0), (rpm, got, ref)
        lo, hi = nis_band(nis[w].size, 2, rel_std=float(np.sqrt(np.mean(u2[w]))))
        assert lo <= np.mean(nis[w]) <= hi, (rpm, np.mean(nis[w]), lo, hi)
    ramps = np.flatnonzero(~steady)
    ramps = np.unique(np.concatenate([np.arange(i, min(i + 1024, steady.size)) for i in ramps]))
    for j, b in enumerate(rig.bearings):
        err = np.hypot(*(est[ramps, 2 * j + k] - truth.samples[ramps, 2 * j + k] for k in (0, 1)))
        assert np.max(err) <= 0.1 * kf_estimator_core.ORBIT_LIMIT * b.clearance, (b.name, np.max(err))


def test_a_block_is_split_at_the_speed_bands_a_ramp_crosses_and_a_dwell_is_not():
    """
    speed_pieces against a constant-acceleration ramp's closed form, and a dwell with keyphasor jitter.

    Angle phi(t) = w0 t + a t^2 / 2: the pieces cover the block in order, each piece's speed is the mean of w over
    its samples (w0 + a (t_first + t_last) / 2), every sample's true speed is within the band width plus one
    ``SPEED_PIECE`` step of its piece's, and neighbouring pieces lie in different bands.  A steady block whose angles
    carry 1 mrad of jitter, and one whose angles run backwards, are one piece at the speed given.
    """
    fs, n, width = 10240.0, 1024, 0.01
    t = np.arange(n) / fs
    w0, a = 180.0, 600.0                      # rad/s, rad/s^2: 8 % of the speed within the block
    pieces = kf_estimator_core.speed_pieces(w0 * t + 0.5 * a * t ** 2, fs, w0 + a * t.mean(), width)
    assert pieces[0][0] == 0 and pieces[-1][1] == n and len(pieces) > 2
    step = a * kf_estimator_core.SPEED_PIECE / fs
    for (i0, i1, sp), nxt in zip(pieces, pieces[1:] + [None]):
        assert sp == pytest.approx(w0 + a * (t[i0] + t[i1 - 1]) / 2, rel=1e-9)
        assert np.all(np.abs(w0 + a * t[i0:i1] - sp) <= width * sp + step)
        if nxt is not None:
            assert nxt[0] == i1
            assert kf_estimator_core.band_key(nxt[2], width) != kf_estimator_core.band_key(sp, width)
    jitter = np.random.default_rng(3).normal(0.0, 1e-3, n)
    assert kf_estimator_core.speed_pieces(w0 * t + jitter, fs, w0, width) == [(0, n, w0)]
    assert kf_estimator_core.speed_pieces(-w0 * t, fs, w0, width) == [(0, n, w0)]


def test_speed_ramps_carry_the_state_over(case):
    """Through the critical speed on 0.5 s ramps: one start, no restart at the speed bands, orbits as the truth's."""
    rig = case[0]
    run = rig.simulation.runs[0]
    speeds = [1500.0, 2100.0, 2700.0]
    rec = R.simulate_run(rig, run, speeds_rpm=speeds, dwell=1.0, ramp=0.5)
    at = tuple(Probe(f'b{b.node}{d}', b.node, d) for b in rig.bearings for d in 'xy')
    truth = R.simulate_run(rig, run, speeds_rpm=speeds, dwell=1.0, ramp=0.5, probes=at, noise=0.0)
    core = EstimatorCore(rig, 1e-16, 0.0, 0.01)
    fn = R.truth_bearing_fn(rig)
    for rpm in speeds:                          # identified bearings at the dwells (here: the simulator's own)
        w = rpm * math.pi / 30
        core.set_coefficients(w, fn(w))
    est = filtered(core, rec, run)
    validity = core.validity_status(None)
    assert core.resets == 1 and core.switches > 10, (core.resets, core.switches)
    core.close()
    orbit = np.hypot(est[:, 0::2], est[:, 1::2]).max(axis=0)
    true_orbit = np.hypot(truth.samples[:, 0::2], truth.samples[:, 1::2]).max(axis=0)
    assert np.all(orbit <= 1.5 * true_orbit), (orbit, true_orbit)
    assert validity.level == OK, validity.message


def test_identified_bearings_interpolate_between_speeds_and_hold_theory_outside():
    theory = {2: (np.eye(2), np.eye(2))}
    ib = IdentifiedBearings(lambda w: theory, 0.01)
    ib.add(200.0, {2: (2 * np.eye(2), 3 * np.eye(2))})
    ib.add(100.0, {2: (4 * np.eye(2), 5 * np.eye(2))})
    K, C = ib(150.0)[2]
    assert np.allclose(K, 3 * np.eye(2)) and np.allclose(C, 4 * np.eye(2))
    assert ib(300.0) is theory and ib(50.0) is theory and ib.source(201.0) == 'identified'
    g = ib.generation
    ib.add(200.5, {2: (np.eye(2), np.eye(2))})           # within the band of 200: replaces it
    assert ib.generation == g + 1 and len(ib.speeds) == 2


def test_blocks_queued_before_new_coefficients_are_still_filtered(case):
    """
    A result arriving while blocks wait for their model: they keep that model and none is left waiting.

    A fixed measurement noise: the noise the first blocks give would re-solve the gain too (a switch each).
    """
    rig, recs, _ = case
    core = EstimatorCore(rig, 1e-16, 1e-7, 0.01)
    rec = recs[0]
    fs = rec.sample_rate
    blocks = [Block(stamp_ns=int(i0 / fs * 1e9), sequence=k, sample_rate=fs, speed=float(rec.speed[i0]),
                    angle=float(rec.angle[i0]), channels=tuple(p.name for p in rec.probes),
                    nodes=tuple(p.node for p in rec.probes), directions=tuple(p.direction for p in rec.probes),
                    samples=rec.samples[i0:i0 + 1024], sample_angles=rec.angle[i0:i0 + 1024], run_id=rec.run.id)
              for k, i0 in enumerate(range(0, 4 * 1024, 1024))]
    w = float(np.mean(rec.speed))
    for k, b in enumerate(blocks[:2]):
        core.submit(b, rec.run, w, k > 0)
    key, t_end = core.key(w, rec.probes, fs), time.monotonic() + 60
    while not core.ready(key) and time.monotonic() < t_end:       # their model is built, not yet used
        time.sleep(0.01)
    fn = R.truth_bearing_fn(rig)
    core.set_coefficients(w, fn(w))                       # while the first two wait
    for b in blocks[2:]:
        core.submit(b, rec.run, w, True)
    out, t_end = [], time.monotonic() + 60
    while len(out) < 4 and time.monotonic() < t_end:
        out += core.drain()
        time.sleep(0.01)
    core.close()
    assert [o.seq for o in out] == [0, 1, 2, 3] and core.resets == 1 and core.switches == 1


def test_a_result_within_a_quarter_sigma_or_a_percent_keeps_the_models():
    """
    A result within a quarter of its sigma or MODEL_TOL of the bearing's largest coefficient rebuilds no model.

    The identifier tracking a machine resends results that move within their sigma, or (oil temperature drift) by
    less than MODEL_TOL: the 1-sigma of the kept coefficients grows to cover how far the latest result is from them.
    """
    ib = IdentifiedBearings(lambda w: {}, 0.01)
    K, C = 1e8 * np.eye(2), 1e4 * np.eye(2)
    sig = {2: (1e5 * np.ones((2, 2)), 1.0 * np.ones((2, 2)))}         # 0.1 % and 0.01 %
    assert ib.add(100.0, {2: (K, C)}, sig)
    g, tag, rev = ib.generation, ib.tag(100.0), ib.revision
    eye = np.eye(2)
    assert not ib.add(100.0, {2: (K + 0.2e5 * eye, C - 0.2 * eye)}, sig)       # 0.2 sigma: the models stay
    assert not ib.add(100.0, {2: (K + 0.5e6 * eye, C - 50.0 * eye)}, sig)      # 5 and 50 sigma, 0.5 %: they stay
    assert ib.generation == g and ib.tag(100.0) == tag and np.array_equal(ib(100.0)[2][0], K)
    assert ib.revision == rev + 2          # kept results are counted: the motion's 1-sigma is recomputed
    K_std, C_std = ib.uncertainty(100.0)[2]
    assert np.allclose(np.diag(K_std), np.hypot(1e5, 0.5e6)) and np.allclose(np.diag(C_std), np.hypot(1.0, 50.0))
    assert np.allclose(K_std[0, 1], 1e5)                                  # an off-diagonal that did not move
    assert ib.add(100.0, {2: (K + 1.5e6, C)}, sig) and ib.generation == g + 1   # 15 sigma and 1.5 %: rebuilt
    assert ib.tag(100.0) != tag
    assert ib.add(100.0, {2: (K, C)}, None)                               # no sigma given: always taken


def test_a_changed_result_rebuilds_the_models_between_its_neighbours_only():
    """The cache key (tag) of a speed changes only when a result its coefficients are interpolated from changes."""
    ib = IdentifiedBearings(lambda w: {}, 0.01)
    K, C = 1e8 * np.eye(2), 1e4 * np.eye(2)
    for w in (100.0, 200.0, 300.0, 400.0):
        ib.add(w, {2: (K, C)})
    before = {w: ib.tag(w) for w in (50.0, 150.0, 250.0, 350.0, 450.0)}
    assert before[50.0] is None and before[450.0] is None                 # theory outside the identified range
    ib.add(400.0, {2: (2 * K, C)})
    after = {w: ib.tag(w) for w in before}
    assert [w for w in before if after[w] != before[w]] == [350.0]
    ib.add(500.0, {2: (K, C)})                                            # extends the range: 450 now identified
    assert ib.tag(450.0) is not None and ib.tag(150.0) == before[150.0]
    assert ib.tags() == {ib.tag(w) for w in (150.0, 250.0, 350.0, 450.0)}   # what the cache keeps models for


def test_the_reduced_filter_estimates_as_the_full_model(case):
    """
    The node's default Craig-Bampton model (every mode below Nyquist) against the full FE model, at 3000 rpm.

    Same data, same identified bearings: the bearing-node 1X of the two filters agree within 0.05 of the 1X's stated
    1-sigma (from the identified coefficients' 1-sigma, estimation.uncertainty.coefficient_sigma, which
    /diagnostics publishes), on fewer states.
    """
    rig, _, _ = case
    rpm = 3000.0
    recs = [R.simulate_run(rig, run, speeds_rpm=[rpm], dwell=1.0, ramp=0.0) for run in rig.simulation.runs]
    (r,) = identify('physical', RotorModel.from_params(rig), rig, harmonics.from_recordings(recs))
    assert r.fully_determined
    coeffs = {n: (r.K[i], r.C[i]) for i, n in enumerate(r.nodes)}
    stds = {n: (r.K_std[i], r.C_std[i]) for i, n in enumerate(r.nodes)}
    x1, sigma = [], None
    for cutoff in (0.0, kf_estimator_core.MODEL_CUTOFF):
        core = EstimatorCore(rig, 1e-16, 0.0, 0.01, cutoff=cutoff)
        core.set_coefficients(r.speed, coeffs, stds)
        est = filtered(core, recs[0], recs[0].run)
        steady = slice(est.shape[0] // 4, None)
        x1.append(one_x(est[steady], recs[0].angle[steady]))
        core.motion_status()
        sigma = core._coef_sigma[1]
        states = core.kf_rotor(recs[0].sample_rate)
        core.close()
    assert 2 * states.nr < 2 * RotorModel.from_params(rig).ndof
    assert np.all(np.abs(x1[1] - x1[0]) <= 0.05 * sigma), (np.abs(x1[1] - x1[0]) / sigma)
