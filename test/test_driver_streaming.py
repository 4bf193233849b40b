"""
The sensor_driver streams (issue 23 item 5).

Its first block goes out at once and memory stays bounded for any stream length (a run already streamed is not kept),
and DAQ files are read one at a time when their turn comes.

Oracle for the pieces: the whole-run arrays of :func:`bearing_id.simulation.rig.simulate` are not an independent
physics oracle, so the sim's steady state is checked against the frequency response of the nominal model written
elsewhere (:func:`bearing_id.rotor.assembly.harmonic_response`, a different code path: one complex solve per speed),
and the stream's blocks against the collected Recording sample by sample within round-off.
"""
from __future__ import annotations

import dataclasses
import gc
import time
import tracemalloc

from bearing_id.config.params import load_rig
from bearing_id.excitation import harmonic_forces
from bearing_id.io import recordings
from bearing_id.io.messages import block_from_msg
from bearing_id.nodes import sensor_driver_core as core
from bearing_id.nodes.topics import TOPIC_DISPLACEMENT, TOPIC_EXCITATION
from bearing_id.rotor.assembly import harmonic_response, probe_matrix, RotorModel
from bearing_id.simulation import rig as rigmod
import numpy as np
import pytest

BLOCK = 1024


def _values(**kw):
    v = {s.name: s.default for s in core.SPECS}
    v.update(kw)
    return v


def test_a_nine_hour_sim_stream_sends_its_first_block_at_once_in_bounded_memory():
    """Nine speeds x 1 hour (332 M samples per run, 5.3 GB as one array): first block in < 2 s, < 60 MB traced."""
    tracemalloc.start()
    try:
        t0 = time.perf_counter()
        sources = core.load_sources(_values(dwell=3600.0))
        assert sources[0].n_samples > 3e8
        stream = core.stream_messages(sources, BLOCK, 0, 'rig')
        first = None
        n = 0
        for topic, _, msg, _ in stream:
            if topic == TOPIC_DISPLACEMENT:
                first = first or time.perf_counter() - t0
                n += 1
                if n == 200:            # past the first 65,536-sample piece: a second piece was computed
                    break
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    # the first block needs the model, one solve per harmonic and one piece (65,536 samples): well under a second
    assert first < 2.0, first
    # one piece: samples, speed, angle (65,536 x 4 x 8 B = 2 MB) + one transient block (4096 x 2 ndof x 16 B) + model
    assert peak < 60e6, peak / 1e6


def test_the_streamed_blocks_are_the_collected_recording_and_its_steady_state_is_the_model_response():
    rig = load_rig()
    run = rig.simulation.runs[0]
    sched = rigmod.step_schedule([900.0, 2100.0], dwell=7.0, ramp=0.3)   # dwells longer than one piece
    rec = rigmod.simulate(rig, run, sched, noise=0.0)
    blocks = [block_from_msg(m) for t, _, m, _ in
              core.stream_messages([rigmod.simulate_stream(rig, run, sched, noise=0.0)], BLOCK, 0, 'rig')
              if t == TOPIC_DISPLACEMENT]
    assert [b.sequence for b in blocks] == list(range(len(blocks)))
    # stamps: the time of each block's first sample, in order (pieces end on block boundaries here: 65,536 samples)
    stamps = np.array([b.stamp_ns for b in blocks])
    np.testing.assert_allclose(stamps, np.arange(len(blocks)) * BLOCK / rec.sample_rate * 1e9, rtol=0, atol=1)
    streamed = np.concatenate([b.samples for b in blocks])
    scale = np.abs(rec.samples).max()
    # the same arithmetic on the same rows: equal within a few round-offs of the largest sample
    np.testing.assert_allclose(streamed, rec.samples, rtol=0, atol=1e-12 * scale)
    assert all(b.samples.shape[0] == BLOCK for b in blocks[:-1])
    # the end of each dwell is steady: 1X of the probes = the nominal model's harmonic response with truth bearings
    bfn = rigmod.truth_bearing_fn(rig)
    model = RotorModel.from_params(rig)
    S = probe_matrix(model, rig.probes)
    for i0, i1, W, steady in rec.segments:
        if not steady:
            continue
        n = int(round(rec.sample_rate * 2 * np.pi / W * 10))       # the last 10 revolutions
        sl = slice(i1 - n, i1)
        ph = np.exp(-1j * rec.angle[sl])
        meas = 2 * (rec.samples[sl] * ph[:, None]).mean(axis=0)
        q = harmonic_response(model, W, W, harmonic_forces(run.excitation, W, model.n_nodes)[1.0], bfn(W))
        want = S @ q[:S.shape[1]]
        # residual transient of the 0.3 s ramp after 7 s at zeta >= 0.005: below 1e-3 of the response
        np.testing.assert_allclose(meas, want, rtol=2e-3, atol=0)


def test_a_sim_plan_keeps_no_streamed_run_and_times_and_seeds_every_run_as_a_list_would():
    """
    The plan builds run i when asked for, and after streaming no SimulatedRun is alive.

    The 72-hour bench's driver grew ~220 MB holding 478 streamed runs and their truths.  Oracle: the runs listed one
    by one as ``simulate_stream`` documents them (each run's start the sum of the durations before it, the seed of
    ``run_seed``), and the blocks counted off the stream.
    """
    rig = load_rig()
    runs, speeds = rig.simulation.runs, [900.0, 1500.0]
    plan = core.load_sources(_values(speeds_rpm=speeds, dwell=0.05, passes=3))
    assert len(plan) == 3 * len(runs)
    t0 = 0.0
    for i in range(len(plan)):
        k, r = divmod(i, len(runs))
        src = plan[i]
        twin = rigmod.simulate_stream(rig, runs[r], rigmod.run_schedule(rig, speeds, 0.05),
                                      seed=rigmod.run_seed(rig.simulation.seed, runs[r].id, k))
        first, want = next(src.pieces())[3], next(twin.pieces())[3]
        assert src.run.id == runs[r].id
        np.testing.assert_allclose(first, want, rtol=0, atol=1e-12 * np.abs(want).max())
        assert plan.start(i) == pytest.approx(t0, rel=1e-12, abs=0)
        t0 += src.n_samples / src.sample_rate
    assert plan.start(len(plan)) == pytest.approx(t0, rel=1e-12)
    assert plan[-1].run.id == runs[-1].id
    assert [s.run.id for s in plan[1:3]] == [runs[1 % len(runs)].id, runs[2 % len(runs)].id]
    with pytest.raises(IndexError):
        plan[len(plan)]
    # the machine changed from the start of run 2: its first segment is changed, run 1's last is not
    changed = core.load_sources(_values(speeds_rpm=speeds, dwell=0.05, passes=3, truth_change_after=plan.start(2),
                                        truth_change_clearance=1.2))
    before, after = changed[1], changed[2]
    for src in (before, after):
        for _ in src.pieces():
            pass
    ref = rigmod.changed_truth(rig, clearance=1.2)(after.segments[0][2])
    node = sorted(ref)[0]
    np.testing.assert_allclose(after.truth_coefficients[after.segments[0][2]][node][0], ref[node][0], rtol=1e-12)
    assert not np.allclose(before.truth_coefficients[before.segments[-1][2]][node][0],
                           rigmod.changed_truth(rig, clearance=1.2)(before.segments[-1][2])[node][0], rtol=1e-3)
    del src, twin, before, after
    gc.collect()
    blocks = 0
    for topic, *_ in core.stream_messages(plan, BLOCK, 0, 'rig'):
        blocks += topic == TOPIC_DISPLACEMENT
    gc.collect()
    assert sum(isinstance(o, rigmod.SimulatedRun) for o in gc.get_objects()) == 0
    assert core.blocks_total(plan, BLOCK) == blocks


def test_files_are_read_one_at_a_time_and_a_bad_one_is_skipped_and_named(tmp_path, monkeypatch):
    rig = load_rig()
    recs = [rigmod.simulate_run(rig, r, speeds_rpm=[1200.0], dwell=0.5) for r in rig.simulation.runs]
    paths = [recordings.save_npz(recs[0], tmp_path / 'a.npz'), tmp_path / 'broken.npz',
             recordings.save_npz(recs[1], tmp_path / 'b.npz')]
    paths[1].write_bytes(b'not a zip')
    sources = core.load_sources(_values(source='file', files=[str(p) for p in paths]))
    read = []
    real = core.read_daq
    monkeypatch.setattr(core, 'read_daq', lambda p, **kw: read.append(str(p)) or real(p, **kw))
    skipped = []
    runs_seen = []
    for topic, _, msg, _ in core.stream_messages(sources, BLOCK, 0, 'rig', on_skip=lambda s, why: skipped.append(
            (s.path, why))):
        if topic == TOPIC_EXCITATION:
            runs_seen.append((msg.run_id, list(read)))
    # run A streamed before the next file was read; the broken file named with its reason; run B streamed after
    assert runs_seen[0] == ('A', [str(paths[0])]), runs_seen
    assert [p for p, _ in skipped] == [str(paths[1])] and 'zip' in skipped[0][1], skipped
    assert runs_seen[1][0] == 'B' and len(runs_seen) == 2


def test_a_missing_file_is_refused_at_start_naming_it(tmp_path):
    with pytest.raises(core.ParamError, match='nope.npz'):
        core.load_sources(_values(source='file', files=[str(tmp_path / 'nope.npz')]))


def test_a_npz_file_streams_piece_by_piece_as_the_whole_file_would_and_bad_values_stop_it_named(
        tmp_path, monkeypatch):
    # never whole in memory: load_npz (the whole-file reader) must not be called; the blocks are the whole
    # recording's, cut the same way (the pieces are 4 MB: the 1.5 s run below is one piece, so a smaller piece size
    # is set to cross piece boundaries inside blocks)
    rig = load_rig()
    rec = rigmod.simulate_run(rig, rig.simulation.runs[0], speeds_rpm=[900.0, 1500.0], dwell=0.6)
    good = recordings.save_npz(rec, tmp_path / 'a.npz')
    bad = rec.samples.copy()
    bad[bad.shape[0] * 2 // 3, 0] = np.nan
    broken = recordings.save_npz(dataclasses.replace(rec, samples=bad), tmp_path / 'nan.npz')
    monkeypatch.setattr(recordings, 'NPZ_PIECE_BYTES', 8 * 2 * 777)
    monkeypatch.setattr(recordings, 'load_npz', lambda *a, **k: pytest.fail('a streamed file was read whole'))
    skipped = []
    sent = {}
    for name in ('a', 'nan'):
        src = core.load_sources(_values(source='file', files=[str(good if name == 'a' else broken)]))
        sent[name] = [block_from_msg(m) for topic, _, m, _ in core.stream_messages(
            src, BLOCK, 0, 'rig', on_skip=lambda s, why: skipped.append((s.path, why))) if topic == TOPIC_DISPLACEMENT]
    whole = list(core.run_blocks(core.RecordingRun(rec), BLOCK))
    assert len(sent['a']) == len(whole)
    for b, (i0, w, a, y) in zip(sent['a'], whole):
        assert np.array_equal(b.samples, y) and np.array_equal(b.angles(), a) and b.speed == float(w[0])
    # the NaN file: the blocks before the bad piece went out, then the file is named with its reason
    assert 0 < len(sent['nan']) < len(whole)
    assert [p for p, _ in skipped] == [str(broken)] and 'its rest not streamed' in skipped[0][1], skipped
