"""The nodes' ROS-free parts: parameter validation, input-stream checks, the identifier's record, the DAQ reader."""
from __future__ import annotations

import json
import math
import threading
import time
from types import SimpleNamespace

import agreement
from bearing_id.config.params import load_rig, PACKAGE_PARAMS, ParamError, Probe, Run
from bearing_id.conventions import rpm_to_rad_s
from bearing_id.estimation.kalman import fast_filter, rotor_kalman_model
from bearing_id.excitation import harmonic_forces
from bearing_id.identify import identify
from bearing_id.io import bags, messages, recordings
from bearing_id.io.daq import angle_from_keyphasor, DaqError, read_csv, read_daq, write_csv
from bearing_id.io.record import Record
from bearing_id.nodes import kf_estimator_core
from bearing_id.nodes.identifier_core import IdentifierCore
from bearing_id.nodes.kf_estimator_core import EstimatorCore
from bearing_id.nodes.monitor import StreamMonitor
from bearing_id.nodes.specs import ParamSpec, validate_values, yaml_block
from bearing_id.nodes.status import Throttle
from bearing_id.rotor.assembly import RotorModel
from bearing_id.signals.recording import Recording
from bearing_id.simulation import rig as rigmod
import numpy as np
import pytest
import yaml

SPECS = [
    ParamSpec('block_size', 1024, 'samples per block', 'samples', lo=16, hi=65536),
    ParamSpec('rate_factor', 1.0, 'playback speed relative to real time', '-', lo=0.0, hi=1000.0),
    ParamSpec('source', 'sim', 'data source', choices=('sim', 'file')),
    ParamSpec('speeds_rpm', [600.0, 900.0], 'speed steps', 'rpm', lo=1.0, hi=1e5),
    ParamSpec('channels', ['p6x', 'p6y'], 'expected channel names'),
]


def test_defaults_validate_and_bad_values_name_the_parameter():
    v = validate_values(SPECS, {})
    assert v['block_size'] == 1024 and v['source'] == 'sim'
    for bad, name in [({'block_size': 8}, 'block_size'), ({'rate_factor': -1.0}, 'rate_factor'),
                      ({'rate_factor': float('nan')}, 'rate_factor'), ({'source': 'tcp'}, 'source'),
                      ({'speeds_rpm': [600.0, 0.0]}, 'speeds_rpm[1]'), ({'block_size': 1.5}, 'block_size'),
                      ({'channels': ['p6x', 3]}, 'channels[1]'), ({'blocksize': 3}, 'blocksize')]:
        with pytest.raises(ParamError, match=rf"{name.replace('[', '.').replace(']', '.')}"):
            validate_values(SPECS, bad)


def test_yaml_block_round_trips_defaults():
    text = yaml_block('sensor_driver', SPECS)
    d = yaml.safe_load(text)['/**']['ros__parameters']
    assert d == {s.name: s.default for s in SPECS}
    assert text.count('#') >= len(SPECS)   # every default commented


def _block(n=1024, nch=2, amp=1e-5, seed=0):
    return np.random.default_rng(seed).standard_normal((n, nch)) * amp


def test_stream_monitor_resynchronises_after_restarts_jumps_and_hostile_blocks():
    """
    Issue 10: one bad block never blocks the stream for good.

    A far-future stamp, an absurd sample rate, a sequence reset when the DAQ restarts, a renumbered source.
    """
    fs, n = 10240.0, 1024
    ch = ['p6x', 'p6y']
    m = StreamMonitor('/rotor/displacement', expected_channels=ch)
    for k in range(3):
        assert m.check(k, k * n / fs, fs, ch, _block()).usable
    r = m.check(3, 1e6, fs, ch, _block())                 # stamped a million seconds ahead
    assert r.usable and not r.contiguous and 'time gap' in r.problems[0]
    r = m.check(4, 4 * n / fs, fs, ch, _block())          # the next one is on time again: accepted, new segment
    assert r.usable and not r.contiguous and 'stamp went back' in r.problems[0]
    r = m.check(5, 5 * n / fs, fs, ch, _block())
    assert r.usable and r.contiguous and not r.problems
    r = m.check(6, 6 * n / fs, 1e-300, ch, _block())      # absurd rate: rejected, no state change
    assert not r.usable
    r = m.check(6, 6 * n / fs, fs, ch, _block())
    assert r.usable and r.contiguous, r.problems
    r = m.check(0, 100.0, fs, ch, _block())               # the driver restarted: sequence back to 0
    assert r.usable and not r.contiguous and 'restarted' in r.problems[0]
    r = m.check(1, 100.0 + n / fs, fs, ch, _block())
    assert r.usable and r.contiguous
    r = m.check(4_000_000_000, 100.0 + 2 * n / fs, fs, ch, _block())   # renumbered: not 4e9 lost blocks
    assert r.usable and not r.contiguous and 'jumped' in r.problems[0]
    st = m.status('x')
    assert st.values['source_restarts'] == 1 and st.values['sequence_jumps'] == 1 and st.values['lost_blocks'] == 0


def test_stream_monitor_flags_each_fault_where_it_happens():
    fs, n = 10240.0, 1024
    m = StreamMonitor('/rotor/displacement', expected_channels=['p6x', 'p6y'])
    ch = ['p6x', 'p6y']
    r = m.check(0, 0.0, fs, ch, _block(), now=0.0)
    assert r.usable and r.contiguous and not r.problems
    r = m.check(1, n / fs, fs, ch, _block(), now=0.1)
    assert r.usable and r.contiguous
    # gap: seq 2, 3 lost
    r = m.check(4, 4 * n / fs, fs, ch, _block(), now=0.2)
    assert r.usable and not r.contiguous and '2 block(s) lost' in r.problems[0] and 'seq 4' in r.problems[0]
    # NaN
    bad = _block()
    bad[17, 1] = np.nan
    r = m.check(5, 5 * n / fs, fs, ch, bad, now=0.3)
    assert not r.usable and 'sample 17' in r.problems[0] and 'p6y' in r.problems[0]
    # stamp goes back one block on a contiguous sequence number: the clock jumped -- a new segment, not a loss
    r = m.check(6, 4 * n / fs, fs, ch, _block(), now=0.4)
    assert r.usable and not r.contiguous and 'stamp went back' in r.problems[0]
    # repeated sequence
    r = m.check(6, 7 * n / fs, fs, ch, _block(), now=0.5)
    assert not r.usable and 'went back' in r.problems[0]
    # a late block (sequence behind, stamp behind)
    r = m.check(5, 3 * n / fs, fs, ch, _block(), now=0.55)
    assert not r.usable and 'went back' in r.problems[0]
    # wrong channel names
    r = m.check(7, 7 * n / fs, fs, ['a', 'b'], _block(), now=0.6)
    assert not r.usable and any('wrong channels' in p for p in r.problems)
    # micrometres sent as metres
    r = m.check(8, 8 * n / fs, fs, ch, _block() * 1e6, now=0.7)
    assert not r.usable and any('micrometres' in p for p in r.problems)
    st = m.status('x', now=0.8)
    assert st.level == 1
    assert st.values['sequence_gaps'] == 1 and st.values['lost_blocks'] == 2
    assert st.values['nonfinite_samples'] == 1 and st.values['out_of_order'] == 2 and st.values['stamp_jumps'] == 1
    assert st.values['wrong_channels'] == 1 and st.values['implausible_amplitude'] == 1
    # nothing new for a while -> stale
    assert m.status('x', stale_after=5.0, now=10.0).level == 3


def test_record_appends_resumes_and_survives_a_torn_line(tmp_path):
    X = np.array([1e-6 + 2e-6j, -3e-7j])
    with Record(tmp_path) as r:
        assert r.append('vector', run='A', speed=62.8, X=X, std=np.array([1e-9, np.nan])) == 0
        assert r.append('result', speed=62.8, K=np.eye(2)) == 1
    # a crash mid-write leaves a torn last line
    with open(tmp_path / 'record.jsonl', 'a') as fh:
        fh.write('{"n": 2, "type": "vec')
    r2 = Record(tmp_path)
    e = r2.entries()
    assert r2.torn_lines == 1 and [x['n'] for x in e] == [0, 1]
    np.testing.assert_array_equal(e[0]['X'], X)
    assert math.isnan(e[0]['std'][1])
    assert r2.append('vector', run='B', X=X) == 2          # numbering continues, nothing overwritten
    r2.close()
    lines = (tmp_path / 'record.jsonl').read_text().splitlines()
    assert json.loads(lines[0])['n'] == 0 and json.loads(lines[-1])['run'] == 'B'
    assert [x['type'] for x in Record(tmp_path).entries()] == ['vector', 'result', 'vector']


def test_keyphasor_angle_matches_the_true_angle_within_one_sample():
    fs = 10240.0
    t = np.arange(int(fs)) / fs
    w = 2 * math.pi * 1500 / 60 * (1 + 0.02 * t)             # slowly accelerating
    phi = np.cumsum(w) / fs + 0.3
    pulses = (np.mod(phi, 2 * math.pi) < 0.5).astype(float)
    angle, speed = angle_from_keyphasor(pulses, fs)
    k = (angle - np.mod(angle[2000], 2 * math.pi)) - (phi - np.mod(phi[2000], 2 * math.pi))
    # compare away from the ends, up to the constant multiple of 2 pi offset
    err = np.mod(angle - phi + math.pi, 2 * math.pi) - math.pi
    core = slice(1000, -1000)
    assert np.max(np.abs(err[core])) < 1.5 * w.max() / fs
    assert np.max(np.abs(speed[core] / w[core] - 1)) < 5e-3
    del k


def test_csv_round_trip_with_units_and_bad_headers(tmp_path):
    fs = 10240.0
    n = 2048
    t = np.arange(n) / fs
    ang = 100.0 * t
    samples = np.column_stack([1e-5 * np.cos(ang), 1e-5 * np.sin(ang)])
    rec = Recording(fs, t, np.full(n, 100.0), ang, (Probe('p6x', 6, 'x'), Probe('p6y', 6, 'y')), samples,
                    Run('A', ()))
    p = write_csv(rec, tmp_path / 'daq.csv', units='um')
    back = read_daq(p)
    assert back.sample_rate == fs and back.channels == ['p6x', 'p6y'] and back.probes[0].node == 6
    np.testing.assert_allclose(back.samples, samples, rtol=1e-10, atol=1e-17)
    np.testing.assert_allclose(back.angle, ang, rtol=1e-10)
    bad = tmp_path / 'bad.csv'
    bad.write_text('# units: um\n# channels: p6x@6x\nt,angle,p6x\n0,0,1\n')
    with pytest.raises(DaqError, match='sample_rate'):
        read_csv(bad)
    bad.write_text('# sample_rate: 100\n# channels: p6x@6q\nt,angle,p6x\n0,0,1\n')
    with pytest.raises(DaqError, match='p6x@6q'):
        read_csv(bad)
    bad.write_text('# sample_rate: 100\n# channels: p9a@9:45dg\nt,angle,p9a\n0,0,1\n')
    with pytest.raises(DaqError, match='p9a@9:45dg'):
        read_csv(bad)


def test_csv_probes_at_any_angle_round_trip(tmp_path):
    """+-45 deg probe pairs (API 670) in a CSV export: name@node:<angle>deg[*gain] written and read back."""
    n, fs = 256, 1024.0
    t = np.arange(n) / fs
    probes = (Probe('p9a', 9, '45.0deg'), Probe('p9b', 9, '135.0deg*1.02'), Probe('p6x', 6, 'x'))
    rec = Recording(fs, t, np.full(n, 50.0), 50.0 * t, probes, np.zeros((n, 3)) + 1e-6, Run('A', ()))
    p = write_csv(rec, tmp_path / 'daq.csv')
    assert '# channels: p9a@9:45.0deg, p9b@9:135.0deg*1.02, p6x@6x' in p.read_text()
    back = read_daq(p)
    assert [(q.name, q.node, q.angle_deg, q.gain) for q in back.probes] == \
        [('p9a', 9, 45.0, 1.0), ('p9b', 9, 135.0, 1.02), ('p6x', 6, 0.0, 1.0)]


@pytest.mark.parametrize('pauses', ['none', 'after every block', 'after every 7th block'])
def test_identifier_windows_equal_the_offline_route_on_a_bag(tmp_path, pauses):
    """
    The identifier's block-by-block windows + vectors == harmonics.from_bag (what `bearing-id identify` uses).

    Within 0.01 of each vector's stated 1-sigma (test/agreement.py), on the bag with speed ramps between the dwells
    (ramp steps inside blocks), whatever pauses the blocks' arrival has: a pause (``flush`` after ``segment_timeout``)
    hands out the open windows provisionally, and the final cut of each replaces them -- the wall clock never cuts
    the data (a loaded CI machine once split a dwell that way and the live result moved 0.3 %).
    """
    bag = PACKAGE_PARAMS.parent / 'bags' / 'unbalance_ab_sweep'
    ref = recordings.from_bag(bag)
    core = IdentifierCore(load_rig(), 'physical', tmp_path)
    wins, n = [], 0
    for topic, _, _, msg in bags.read_bag(bag, ['/rotor/excitation', '/rotor/displacement']):
        if topic == '/rotor/excitation':
            core.add_excitation(messages.excitation_from_msg(msg))
            continue
        b = messages.block_from_msg(msg)
        assert b.has_sample_angles and b.run_id in core.runs
        wins += core.feed(b, core.runs[b.run_id], True, float(n))
        n += 1
        if pauses == 'after every block' or (pauses == 'after every 7th block' and n % 7 == 0):
            wins += core.flush(n + 1.0, 0.3)
            assert not core.flush(n + 2.0, 0.3)         # once per pause
    wins += core.flush(1e9, 0.0)
    for w in wins:
        core.add_window(w)
    if pauses != 'none':
        assert sum(w.provisional for w in wins) > 2
    data = core.assemble()
    _vectors_agree(data, ref)
    core.close()
    again = IdentifierCore(load_rig(), 'physical', tmp_path)      # a restart resumes the record: the same vectors
    resumed = again.assemble()
    _vectors_agree(resumed, ref)
    again.close()


def _vectors_agree(data, ref):
    """1X vectors (and the plain fits the paper method's filter takes) of two routes, test/agreement.py."""
    agreement.assert_speeds_agree(data.speeds, ref.speeds)
    agreement.assert_within_sigma(data.X, ref.X, ref.X_std, 'X')
    agreement.assert_std_agree(data.X_std, ref.X_std, 'X_std')
    g, w = data.plain, ref.plain
    agreement.assert_within_sigma(g.X, w.X, np.sqrt(np.minimum(w.var_re, w.var_im)), 'plain X')
    for name in ('var_re', 'var_im', 'noise_var'):                  # variances: twice a std's relative error
        np.testing.assert_allclose(getattr(g, name), getattr(w, name), rtol=2 * agreement.STD_RTOL, err_msg=name)
    assert data.sample_rate == ref.sample_rate                       # a parameter of the recording, not computed


@pytest.mark.parametrize('R_std', [0.0, 1e-7])
def test_identifier_paper_method_equals_the_offline_route(tmp_path, R_std):
    """
    The identifier with method paper gives `bearing-id identify --method paper`'s coefficients (and R) on a bag.

    Reference: ``identify('paper', ...)`` on ``harmonics.from_bag`` (the offline route), default options or the same
    fixed R (the node's ``kf_measurement_noise`` = the CLI's ``--R``).  The node holds no time series, so only the
    NIS (offline: from the samples) is missing there.  (Until 27 Nov the node used the kf_estimator's time-domain
    estimates and dropped every one of them -- no result at all.)
    """
    bag = PACKAGE_PARAMS.parent / 'bags' / 'unbalance_ab_sweep'
    rig = load_rig()
    ref_data = recordings.from_bag(bag).select([0, 4, 8])          # three speeds: the test's time
    R = R_std ** 2 or None
    ref = identify('paper', RotorModel.from_params(rig), rig, ref_data, options=None if R is None else {'R': R})
    core = IdentifierCore(rig, 'paper', tmp_path, options={'kf': {'Q': 1e-16, 'R': R}})
    wins = []
    for topic, _, _, msg in bags.read_bag(bag, ['/rotor/excitation', '/rotor/displacement']):
        if topic == '/rotor/excitation':
            core.add_excitation(messages.excitation_from_msg(msg))
        else:
            b = messages.block_from_msg(msg)
            wins += core.feed(b, core.runs[b.run_id], True, 0.0)
    wins += core.flush(1e9, 0.0)
    for w in wins:
        core.add_window(w)
    data = core.assemble()
    assert data.recordings == [] and data.plain is not None
    live, _ = core.solve(data.select([0, 4, 8]), record=False)
    core.close()
    agreement.assert_results_agree(live, ref, 'paper')
    for a, b in zip(live, ref):
        assert a.extra['nis'] is None and b.extra['nis'] is not None     # the NIS needs the samples


def test_estimator_core_builds_models_off_the_data_path_and_matches_the_batch_filter(monkeypatch):
    """
    submit() returns before the model exists (the build runs in the worker; held here until the blocks are queued).

    Once built, the queued blocks are filtered in order and agree with kalman.fast_filter over the same samples (the
    batch route) within 0.01 of each output's stated 1-sigma.
    """
    gate = threading.Event()

    def held(*a, **kw):                 # the model build waits for the gate (at most 60 s)
        gate.wait(60.0)
        return rotor_kalman_model(*a, **kw)
    monkeypatch.setattr(kf_estimator_core, 'rotor_kalman_model', held)
    rig = load_rig()
    rec = rigmod.simulate_run(rig, rig.simulation.runs[0], speeds_rpm=[1500.0], dwell=0.5)
    core = EstimatorCore(rig, 1e-16, 1e-7, 0.01)
    fs, n = rec.sample_rate, 1024
    w = float(rec.speed[0])
    blocks = [SimpleNamespace(seq=k, stamp=i0 / fs, samples=rec.samples[i0:i0 + n], angles=lambda i0=i0: (
                              rec.angle[i0:i0 + n]), sample_rate=fs, probes=rec.probes, frame_id='rig')
              for k, i0 in enumerate(range(0, 4 * n, n))]
    for b in blocks:
        assert core.submit(b, rec.run, w, True) is None
    assert not core.ready(core.key(w, rec.probes, fs))   # every submit returned while the build was held
    assert core.drain() == [] and core.pending == 4     # queued, in order, until the model exists
    gate.set()
    out = []
    t_end = time.monotonic() + 30
    while len(out) < 4 and time.monotonic() < t_end:
        out += core.drain()
        time.sleep(0.01)
    core.close()
    assert [o.seq for o in out] == [0, 1, 2, 3]
    km = rotor_kalman_model(core.kf_rotor(fs), w, core.bearing_fn(w), rec.probes, fs, Q=1e-16, R=1e-14,
                            forces=harmonic_forces(rec.run.excitation, w, core.rotor.n_nodes),
                            outputs=[(p.node, p.direction) for p in core.outputs_probes])
    dc = np.concatenate([np.broadcast_to(o.offset, o.innovations.shape) for o in out])   # each block's DC removed
    ref = fast_filter(km, rec.samples[:4 * n] - dc, w * np.arange(4 * n) / fs + rec.angle[0])
    # within 0.01 of each quantity's stated 1-sigma (test/agreement.py): the innovations of sqrt(diag S), the
    # estimates of the steady-state posterior std of the outputs, sqrt(diag E (P - K S K^T) E^T), and the NIS (a
    # chi-square variable with m degrees of freedom) of sqrt(2 m)
    P, K, S = km.steady_state()
    post_std = np.sqrt(np.diag(km.E @ (P - K @ S @ K.T) @ km.E.T))
    agreement.assert_within_sigma(np.concatenate([o.estimates for o in out]), ref.estimates, post_std, 'estimates')
    agreement.assert_within_sigma(np.concatenate([o.innovations for o in out]), ref.innovations,
                                  np.sqrt(np.diag(S)), 'innovations')
    agreement.assert_within_sigma(np.concatenate([o.nis for o in out]), ref.nis, np.sqrt(2 * km.m), 'NIS')


def test_estimator_validity_flags_the_papers_unbalance_orbit_like_the_rig_check():
    """
    The paper's 4 g x 63 mm unbalance drives orbits past 30 % of the clearance at 2400 rpm.

    The unbalance: rig.scenario('paper_table3').  rig.check_validity (steady-state response) is the independent
    reference.
    """
    rig = load_rig()
    run = rigmod.scenario('paper_table3')[0]
    ref = rigmod.check_validity(rig, [run], [rpm_to_rad_s(600.0), rpm_to_rad_s(2400.0)])
    assert {round(i.speed) for i in ref if i.kind == 'orbit'} == {round(rpm_to_rad_s(2400.0))}
    core = EstimatorCore(rig, 1e-16, 1e-7, 0.01)
    for rpm, expect_warn in ((600.0, False), (2400.0, True)):
        rec = rigmod.simulate_run(rig, run, speeds_rpm=[rpm], dwell=0.3, noise=0.0)
        w = float(rec.speed[0])
        core.last_orbit.clear()
        b = SimpleNamespace(seq=0, stamp=0.0, samples=rec.samples[:2048], angles=lambda rec=rec: rec.angle[:2048],
                            sample_rate=rec.sample_rate, probes=rec.probes, frame_id='rig')
        core.submit(b, run, w, False)
        t_end = time.monotonic() + 30
        while core.pending and time.monotonic() < t_end:
            core.drain()
            time.sleep(0.01)
        st = core.validity_status(w)
        assert (st.level == 1 and 'orbit' in st.message and 'clearance' in st.message) == expect_warn, st
    core.close()


def test_a_throttle_lets_one_event_through_per_period_and_counts_the_rest():
    gate = Throttle(2.0)
    assert gate.due(100.0) == 0
    assert [gate.due(t) for t in (100.5, 101.0, 101.99)] == [None, None, None]
    assert gate.due(102.0) == 3 and gate.due(103.0) is None and gate.due(104.5) == 1
    assert gate.line('gap', 107.0) == 'gap' and gate.line('gap', 108.0) is None
    assert gate.line('gap', 109.5) == 'gap (1 more problem(s) not logged since the last line)'
