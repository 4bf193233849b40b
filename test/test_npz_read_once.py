"""
``io.recordings.load_npz`` reads every array of a recording once, and its result equals a plain ``np.load`` reading.

References: ``numpy.load`` of the same file (the library's own reader, independent of the checked reader in
``bearing_id.io.recordings``) and the Recording that was written; the count of ``numpy.lib.format.read_array`` calls
against the number of members of the archive.
"""
from __future__ import annotations

import zipfile
import zlib

from bearing_id.config.params import ExcitationEntry, Probe, Run
from bearing_id.io import recordings
from bearing_id.io.recordings import save_npz
from bearing_id.signals.recording import Recording
import numpy as np
import pytest

N_TRUTH_SPEEDS = 60          # a ramp stores truth at every step: many speeds (409 in the default 9-speed plan)


def _recording(n=5000, seed=3):
    """Return a synthetic Recording with every optional member: excitation, segments, truth at many speeds, gaps."""
    rng = np.random.default_rng(seed)
    fs = 10240.0
    t = np.arange(n) / fs
    speed = np.full(n, 150.0)
    angle = np.cumsum(speed) / fs
    samples = 1e-5 * rng.standard_normal((n, 2))
    probes = (Probe('p6x', 6, 'x'), Probe('p6y', 6, 'y'))
    run = Run('A', (ExcitationEntry('unbalance', 4, 1e-4, 0.3, 'forward', 1.0),
                    ExcitationEntry('force', 7, 2.0, -1.0, 'x', 0.5)))
    truth = {'coefficients': {float(s): {node: (rng.standard_normal((2, 2)) * 1e7, rng.standard_normal((2, 2)) * 1e4)
                                         for node in (2, 10)}
                              for s in np.linspace(60.0, 320.0, N_TRUTH_SPEEDS)}}
    segments = [(0, n // 2, 150.0, True), (n // 2, n, 150.0, False)]
    rec = Recording(sample_rate=fs, t=t, speed=speed, angle=angle, probes=probes, samples=samples, run=run,
                    segments=segments, truth=truth, rig_name='test rig')
    return rec


@pytest.fixture(scope='module')
def written(tmp_path_factory):
    rec = _recording()
    path = save_npz(rec, tmp_path_factory.mktemp('npz') / 'run_A.npz')
    return rec, path


def test_every_member_is_read_at_most_once(written, monkeypatch):
    _, path = written
    calls, opens = [], []
    orig, orig_open = np.lib.format.read_array, zipfile.ZipFile.open

    def counting(fp, *a, **k):
        calls.append(getattr(fp, 'name', '?'))
        return orig(fp, *a, **k)

    def counting_open(self, name, *a, **k):
        opens.append(getattr(name, 'filename', name))
        return orig_open(self, name, *a, **k)

    monkeypatch.setattr(np.lib.format, 'read_array', counting)
    monkeypatch.setattr(zipfile.ZipFile, 'open', counting_open)
    recordings.load_npz(path)
    with zipfile.ZipFile(path) as zf:
        members = {i.filename: i.file_size for i in zf.infolist() if i.filename.endswith('.npy')}
    assert len(calls) == len(set(calls)), 'a member was read twice'
    # each member opened once (header and data), a large one twice (header first, data after every check)
    for m, size in members.items():
        assert opens.count(m) == (1 if size <= recordings.NPZ_SMALL_BYTES else 2), (m, size, opens.count(m))
    assert len(opens) < 2 * len(members)


def test_result_equals_a_plain_np_load_reading(written):
    rec, path = written
    got = recordings.load_npz(path)
    with np.load(path, allow_pickle=False) as z:
        ref = {k: z[k] for k in z.files}
    for name in ('t', 'speed', 'angle', 'samples'):
        a, b = getattr(got, name), ref[name]
        assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b), name
        assert np.array_equal(a, getattr(rec, name)), name
    assert got.sample_rate == float(ref['sample_rate'])
    assert [(p.name, p.node, p.direction) for p in got.probes] == \
        [(str(c), int(n), str(d)) for c, n, d in zip(ref['channels'], ref['nodes'], ref['directions'])]
    assert got.run == rec.run
    assert got.segments == rec.segments
    assert got.rig_name == 'test rig'
    # truth: every speed, node and coefficient, bit for bit, against the arrays np.load reads and the dict written
    tc = got.truth['coefficients']
    assert list(tc) == [float(s) for s in ref['truth_speeds']]
    for i, s in enumerate(ref['truth_speeds']):
        assert list(tc[float(s)]) == [int(n) for n in ref['truth_nodes']]
        for j, node in enumerate(ref['truth_nodes']):
            K, C = tc[float(s)][int(node)]
            assert np.array_equal(K, ref['truth_K'][i, j]) and np.array_equal(C, ref['truth_C'][i, j])
            K0, C0 = rec.truth['coefficients'][float(s)][int(node)]
            assert np.array_equal(K, K0) and np.array_equal(C, C0)
    assert len(tc) == N_TRUTH_SPEEDS


def test_only_members_that_shrink_are_deflated(written):
    """
    The noisy samples are stored as they are (they shrink by a few % at most), the rest is deflated.

    Reference: zlib on each array's bytes as ``np.load`` reads them (deflated size vs raw size), and the zip
    directory's compression method of that member; a plain ``np.savez_compressed`` file of the same arrays reads equal.
    """
    _, path = written
    with zipfile.ZipFile(path) as zf, np.load(path, allow_pickle=False) as z:
        infos = {i.filename[:-4]: i for i in zf.infolist()}
        assert set(infos) == set(z.files)
        for key, info in infos.items():
            data = z[key].tobytes()                    # the array's bytes, without the .npy header
            if len(data) < recordings.NPZ_DEFLATE_ALWAYS_BELOW:
                assert info.compress_type == zipfile.ZIP_DEFLATED, key
                continue
            saving = 1.0 - len(zlib.compress(data[:1 << 20], 1)) / len(data[:1 << 20])
            if saving < 0.05 or saving > 0.2:          # clear cases only (the rule's threshold is 10 %)
                want = zipfile.ZIP_DEFLATED if saving > 0.2 else zipfile.ZIP_STORED
                assert info.compress_type == want, (key, saving, info.compress_type)
        assert infos['samples'].compress_type == zipfile.ZIP_STORED
        assert infos['speed'].compress_type == zipfile.ZIP_DEFLATED         # constant: shrinks to almost nothing
        arrays = {k: z[k] for k in z.files}
    plain = path.with_name('plain.npz')
    np.savez_compressed(plain, **arrays)
    a, b = recordings.load_npz(path), recordings.load_npz(plain)
    for name in ('t', 'speed', 'angle', 'samples'):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.run == b.run and a.segments == b.segments and a.truth.keys() == b.truth.keys()
