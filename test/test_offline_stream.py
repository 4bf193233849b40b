"""
Offline recordings are read piece by piece (issue 23 item 6): same vectors, same refusals, bounded memory.

References: the whole-array route on the same file (``load_npz`` -> ``from_recordings``, which feeds the whole
arrays to the same RunStream) for the vectors; ``load_npz``'s message (``check_recording`` on the whole arrays) for
every refusal; for the memory, the bytes the arrays would take whole against a bound derived from the window length
and the piece size.
"""
from __future__ import annotations

from dataclasses import replace
import math
import tracemalloc

from bearing_id.config.params import load_rig
from bearing_id.identify import harmonics
from bearing_id.io import recordings
from bearing_id.io.recordings import load_npz, open_npz, save_npz
from bearing_id.signals import recording as SR
from bearing_id.simulation import rig as R
import numpy as np
import pytest

SMALL_PIECE = 3000 * 8 * 2      # bytes: pieces of 3000 rows of 2 channels, so windows and checks span pieces


@pytest.fixture(scope='module')
def recs():
    rig = load_rig()
    return [R.simulate_run(rig, run, speeds_rpm=[900.0, 1500.0, 2100.0], dwell=1.0, ramp=0.3)
            for run in rig.simulation.runs]


@pytest.fixture
def small_pieces(monkeypatch):
    monkeypatch.setattr(recordings, 'NPZ_PIECE_BYTES', SMALL_PIECE)


def _files(recs, tmp_path, tag='ok'):
    return [save_npz(r, tmp_path / f'{tag}_{r.run.id}.npz') for r in recs]


@pytest.mark.parametrize('gaps', [(), (7000,)])
def test_streamed_vectors_equal_the_whole_array_ones(recs, tmp_path, small_pieces, gaps):
    recs = [replace(r, gaps=gaps) for r in recs]
    files = _files(recs, tmp_path)
    whole = harmonics.from_recordings([load_npz(f) for f in files])
    streamed = harmonics.from_recordings([open_npz(f) for f in files])
    assert open_npz(files[0]).n_samples > 10 * (SMALL_PIECE // 16)
    np.testing.assert_allclose(streamed.speeds, whole.speeds, rtol=1e-12)
    assert np.all(np.abs(streamed.X - whole.X) <= 0.01 * whole.X_std)
    np.testing.assert_allclose(streamed.X_std, whole.X_std, rtol=0.01)
    assert streamed.windows == whole.windows
    assert streamed.truth.keys() == whole.truth.keys()
    for a, b in zip(streamed.plain.arrays(), whole.plain.arrays()):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-30)


def _faults(rec):
    """(name, faulty recording) pairs: each value check, some at a piece boundary (pieces of 3000 rows)."""
    n = rec.samples.shape[0]
    out = []
    x = rec.samples.copy()
    x[3000, 1] = np.nan
    x[n - 5, 0] = np.inf
    out.append(('nan samples', replace(rec, samples=x)))
    w = rec.speed.copy()
    w[5999] = np.nan
    out.append(('nan speed', replace(rec, speed=w)))
    x = rec.samples.copy()
    x[4500, 0] = 0.5
    out.append(('peak', replace(rec, samples=x)))
    for i in (2999, 3000, 3001, 3064, 6000 - 65, n - 2):
        a = rec.angle.copy()
        a[i:] += 2.5
        out.append((f'slip at {i}', replace(rec, angle=a)))
    out.append(('speed in rpm', replace(rec, speed=rec.speed * 60 / (2 * math.pi))))
    return out


def test_every_refusal_is_the_whole_array_one(recs, tmp_path, small_pieces):
    rec = recs[0]
    assert rec.samples.shape[0] > 7000
    for name, bad in _faults(rec):
        f = save_npz(bad, tmp_path / 'bad.npz')
        with pytest.raises(ValueError) as whole:
            load_npz(f)
        with pytest.raises(ValueError) as streamed:
            harmonics.recording_vectors(open_npz(f))
        assert str(streamed.value) == str(whole.value), name
        assert str(f) in str(streamed.value), name


def test_a_corrupt_member_is_named(recs, tmp_path, small_pieces):
    f = save_npz(recs[0], tmp_path / 'run.npz')
    data = bytearray(f.read_bytes())
    i = data.find(b'samples.npy')
    k = i + 4000                              # inside the stored samples member's data
    data[k:k + 8] = bytes(8 * [0x7f])
    f.write_bytes(bytes(data))
    with pytest.raises(ValueError, match='member samples.npy is corrupt'):
        harmonics.recording_vectors(open_npz(f))


def test_memory_is_bounded_by_the_window_and_the_piece(tmp_path, monkeypatch):
    """
    A 40 s run streamed with 0.5 s windows peaks within a bound set by the window and the piece.

    The peak of traced allocations; the bound is less than half of what the arrays take whole.
    """
    monkeypatch.setattr(recordings, 'NPZ_PIECE_BYTES', 1 << 16)
    monkeypatch.setattr(SR, 'RATIO_SUBSAMPLE', 1 << 14)
    rig = load_rig()
    rec = R.simulate_run(rig, rig.simulation.runs[0], speeds_rpm=[1200.0, 2400.0], dwell=20.0, ramp=0.3)
    f = save_npz(rec, tmp_path / 'long.npz')
    n, nch = rec.samples.shape
    whole_bytes = n * (nch + 3) * 8                   # samples, t, speed, angle as read whole
    del rec
    max_window = 0.5
    win = int(max_window * rig.simulation.sample_rate)
    # the window's fit: its samples, angle and speed (buffered and cut out), the design matrices and the decaying
    # components' search: ~60 doubles per sample of the window measured (2 channels, 3 components), 96 allowed; one
    # piece of each member read (and its float copy); the speed check's three subsamples (twice, while thinned); 1 MB
    # of anything else
    bound = 96 * 8 * win + 2 * 4 * recordings.NPZ_PIECE_BYTES + 3 * 2 * SR.RATIO_SUBSAMPLE * 8 + (1 << 20)
    assert whole_bytes > 2 * bound
    src = open_npz(f)
    tracemalloc.start()
    try:
        vecs = harmonics.recording_vectors(src, max_window=max_window)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert len(vecs) == 2
    assert peak <= bound, (peak, bound, whole_bytes)


def test_a_long_window_is_fitted_in_row_blocks_to_the_same_numbers(monkeypatch):
    """The transient-aware fit triangularised QR_BLOCK_ROWS rows at a time equals the one-block fit (rounding)."""
    from bearing_id.signals import transient
    from bearing_id.signals.harmonics import harmonic_vectors
    fs, n = 10240.0, 40000
    t = np.arange(n) / fs
    angle = 2 * math.pi * 25.0 * t
    rng = np.random.default_rng(5)
    ring = np.exp(-3.0 * t) * np.cos(2 * math.pi * 120.0 * t + 0.4)
    x = np.stack([2e-6 * np.cos(angle + 0.3) + 5e-7 * ring, 1.5e-6 * np.sin(angle - 0.2) - 3e-7 * ring], axis=1)
    x += 2e-8 * rng.standard_normal(x.shape)
    one = harmonic_vectors(x, angle, transients=3, sample_rate=fs)
    assert one.transient_rates.size >= 1                      # the ringing mode is found and fitted
    monkeypatch.setattr(transient, 'QR_BLOCK_ROWS', 4096)    # ~10 blocks
    blocks = harmonic_vectors(x, angle, transients=3, sample_rate=fs)
    np.testing.assert_allclose(blocks.transient_rates, one.transient_rates, rtol=1e-7)
    assert np.all(np.abs(blocks.X - one.X) <= 1e-6 * one.std_re)
    np.testing.assert_allclose(blocks.std_re, one.std_re, rtol=1e-7)
    A = rng.standard_normal((10000, 7))
    R1 = np.linalg.qr(A, mode='r')
    R2 = transient.stacked_r(A.shape[0], lambda i, j: A[i:j])
    np.testing.assert_allclose(np.abs(R2), np.abs(R1), rtol=1e-9, atol=1e-9 * np.abs(R1).max())
