"""
Fast paths of the diagnosis' signal side against their references.

* ``signals.subsynchronous`` (default, the golden search on :class:`signals._SinusoidCost`, moments computed once)
  against ``method='reference'`` (the first implementation, a least-squares fit per channel and step, kept
  unchanged).  The cost and the phasors at a given frequency agree to 1e-9 relative (measured ~1e-13).  The two
  golden searches take the same steps until the two costs' rounding decides a comparison differently, so the found
  frequencies agree to the search's own tolerance: its final bracket, 2 df g^40 = 8.8e-9 df (df = fs / N the FFT
  bin, g the golden ratio), allowed twice; both minima have the same cost to 1e-12 relative; the phasors agree to
  1e-9 relative at the same frequency.  Components with an SNR above 10 (what the diagnosis uses) on 1 to 4
  channels, odd lengths, both whirl senses, offsets.
* ``signals.SteadyWindowTracker.feed`` (a bounded scan per window) against the rule written out sample by sample in
  plain Python here (the sum sequential, as documented): the same windows, in any chunking.
"""
import math

from bearing_id.signals import harmonics as signals
import numpy as np
import pytest

FS = 10240.0
G40 = ((math.sqrt(5) - 1) / 2) ** 40


def _whirl_signal(n, nch, amp, noise, ratio=0.437, speed_hz=31.7, sense=1.0, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    ang = 2 * math.pi * speed_hz * t + 0.3
    fw = ratio * speed_hz
    x = np.empty((n, nch))
    for c in range(nch):
        ph = 2 * math.pi * fw * t + 0.7 * (c // 2)
        whirl = np.cos(ph) if c % 2 == 0 else sense * np.sin(ph)
        x[:, c] = (20e-6 * np.cos(ang + c) + 3e-6 * np.cos(2 * ang - c) + amp * whirl + 1e-5 * (c - 1)
                   + noise * rng.standard_normal(n))
    return x, ang


CASES = [(15437, 2, 5e-6, 1e-7, 1.0), (20480, 4, 2e-6, 2e-7, -1.0), (4099, 1, 1e-6, 1e-7, 1.0),
         (15513, 2, 1e-6, 1e-9, -1.0), (8191, 3, 3e-7, 1e-7, 1.0)]


@pytest.mark.parametrize('n, nch, amp, noise, sense', CASES)
def test_fast_cost_and_phasors_equal_the_reference_fit(n, nch, amp, noise, sense):
    x, ang = _whirl_signal(n, nch, amp, noise, sense=sense)
    sp = signals._subsync_spectrum(x, ang, FS, (1, 2, 3))
    k, _ = signals._subsync_peak(sp, (0.05, 0.95))
    df = FS / n
    f0 = sp['freqs'][k]
    cost = signals._SinusoidCost(sp['resid'], FS, f0, df)
    for f in f0 + df * np.linspace(-1.0, 1.0, 9):
        ref = [signals._fit_sinusoid(sp['resid'][:, c], sp['tt'], f) for c in range(nch)]
        assert cost(f) == pytest.approx(sum(r[1] for r in ref), rel=1e-9)
        X_ref = np.array([r[0] for r in ref])
        assert np.max(np.abs(cost.phasors(f) - X_ref)) <= 1e-9 * np.max(np.abs(X_ref))


@pytest.mark.parametrize('n, nch, amp, noise, sense', CASES)
def test_fast_search_equals_the_reference(n, nch, amp, noise, sense):
    x, ang = _whirl_signal(n, nch, amp, noise, sense=sense)
    xy = (0, 1) if nch > 1 else None
    for band in ((0.05, 0.95), (0.3, 0.6)):
        ref = signals.subsynchronous(x, ang, FS, ratio_range=band, xy=xy, method='reference')
        new = signals.subsynchronous(x, ang, FS, ratio_range=band, xy=xy)
        assert ref.snr > 10.0 or band != (0.05, 0.95)       # a clear line (the narrow band's median holds it)
        df = FS / n
        assert abs(new.frequency - ref.frequency) <= 2 * (2 * df * G40), (new.frequency - ref.frequency) / df
        assert abs(new.ratio - ref.ratio) * ref.frequency / ref.ratio <= 2 * (2 * df * G40)
        assert new.snr == ref.snr and new.whirl == ref.whirl
        assert new.whirl == (None if xy is None else ('forward' if sense > 0 else 'backward'))
        # both found the minimum of the reference's own cost, to rounding
        tt = np.arange(n) / FS
        sp = signals._subsync_spectrum(x, ang, FS, (1, 2, 3))

        def ref_cost(f):
            return sum(signals._fit_sinusoid(sp['resid'][:, c], tt, f)[1] for c in range(nch))

        assert ref_cost(new.frequency) == pytest.approx(ref_cost(ref.frequency), rel=1e-12)
        # the phasors: equal to the reference's fit at the frequency found
        X_at = np.array([signals._fit_sinusoid(sp['resid'][:, c], tt, new.frequency)[0] for c in range(nch)])
        assert np.max(np.abs(new.X - X_at)) <= 1e-9 * np.max(np.abs(X_at))
        np.testing.assert_allclose(new.amplitude, ref.amplitude, rtol=1e-6)


def test_bands_share_one_fit_and_equal_single_calls():
    x, ang = _whirl_signal(12001, 2, 2e-6, 1e-7)
    bands = [(0.05, 0.95), (0.3, 0.6), (0.7, 0.95), (0.05, 0.0501)]
    got = signals.subsynchronous_bands(x, ang, FS, bands)
    assert got[3] is None                                     # narrower than 3 FFT bins
    for band, g in zip(bands[:3], got):
        one = signals.subsynchronous(x, ang, FS, ratio_range=band)
        assert (g.frequency, g.snr, g.whirl) == (one.frequency, one.snr, one.whirl)
        np.testing.assert_array_equal(g.X, one.X)
    ref = signals.subsynchronous_bands(x, ang, FS, bands, method='reference')
    assert ref[3] is None and ref[2].snr == got[2].snr
    with pytest.raises(ValueError, match='too short'):
        signals.subsynchronous(x, ang, FS, ratio_range=bands[3])
    with pytest.raises(ValueError, match='method'):
        signals.subsynchronous(x, ang, FS, method='golden')
    with pytest.raises(ValueError, match='does not turn'):
        signals.subsynchronous_bands(x, np.zeros(x.shape[0]), FS, bands)


# ------------------------------------------------------------------------------------------------ steady windows
def _windows_by_the_rule(speed, tol_rel):
    """Return the steady windows of the documented rule, sample by sample (plain Python floats)."""
    out, i0 = [], None
    hi = lo = s = 0.0
    count = 0
    for i, v in enumerate(speed):
        v = float(v)
        if not math.isfinite(v):
            if i0 is not None:
                out.append((i0, i))
                i0 = None
            continue
        if i0 is not None:
            h, lw, ss = max(hi, v), min(lo, v), s + v
            if h - lw > tol_rel * max(abs(ss / (count + 1)), 1e-300):
                out.append((i0, i))
                i0 = None
            else:
                hi, lo, s, count = h, lw, ss, count + 1
                continue
        i0, hi, lo, s, count = i, v, v, v, 1
    if i0 is not None:
        out.append((i0, i0 + count))
    return out


def test_tracker_equals_the_rule_in_any_chunking():
    rng = np.random.default_rng(5)
    parts = []
    for level in (50.0, 80.0, 120.0):                    # dwells, ramps, noise, gaps
        parts += [level * (1 + 1e-3 * rng.standard_normal(6000)), np.linspace(level, level + 30.0, 2500)]
    speed = np.concatenate(parts)
    speed[[100, 7000, 7001, 15000]] = np.nan
    speed[9000:9010] = np.inf
    want = _windows_by_the_rule(speed, 0.005)
    assert len(want) > 100
    for chunks in ([speed.size], [1, 7, 1000, 5, 33000], list(rng.integers(1, 3000, 60))):
        tr = signals.SteadyWindowTracker(0.005)
        got, o = [], 0
        for c in chunks:
            got += tr.feed(speed[o:o + c])
            o += c
        got += tr.feed(speed[o:]) + tr.close()
        assert got == want
