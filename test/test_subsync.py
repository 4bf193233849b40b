"""
Sub-synchronous lines (:mod:`bearing_id.signals.subsync`) against truth and against least squares written here.

Oracles, none of them the package's own code:

* ``np.linalg.lstsq`` of [1, cos 2 pi f t, sin 2 pi f t] per channel (the definition of the cost the search
  minimises): the series-based cost and phasors at a given f within 0.01 of their 1-sigma (the phasors' from the
  least-squares covariance, the cost's sigma^2 sqrt(2 dof) per channel).
* ``scipy.optimize.minimize_scalar`` (bounded Brent) on that direct cost, after the synchronous orders were removed
  and the peak bin found here (lstsq and a Hann-windowed FFT): the frequency within 0.01 of its 1-sigma.
* The Cramer-Rao bound of a sinusoid's frequency in white noise (Kay, Fundamentals of Statistical Signal
  Processing I, eq. 3.41: var(f) = 12 / ((2 pi)^2 eta N (N^2 - 1)) cycles^2 / sample^2, eta = A^2 / (2 sigma^2),
  summed information over channels): Monte-Carlo frequency errors / that 1-sigma inside a chi-square band.
* Closed-form whirl orbits (x = a cos, y = +-a sin) for the whirl direction.
"""
import math

from bearing_id.conventions import phasor_to_time
from bearing_id.signals.harmonics import harmonic_vectors
from bearing_id.signals.subsync import _subsync_peak, _subsync_spectrum, SinusoidCost, subsynchronous, \
    subsynchronous_bands
import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from scipy.special import chdtri

FS = 10240.0
EPS = np.finfo(float).eps
ALPHA = 1e-3                # false-alarm probability of the statistical band


def _whirl_signal(n, nch, amp, noise, ratio=0.437, speed_hz=31.7, sense=1.0, seed=0):
    """Return (x (n, nch), angle (n,)): 1X + 2X + offsets + a whirl of amplitude ``amp`` at ``ratio`` + noise."""
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


def _crb_sigma_f(sigma2, amplitudes, n) -> float:
    """
    Return the Cramer-Rao 1-sigma [Hz] of one frequency shared by channels of ``amplitudes`` [m] in white noise.

    Kay eq. 3.41: var(f) = 12 / ((2 pi)^2 eta N (N^2 - 1)) [cycles / sample]^2 with eta = A^2 / (2 sigma^2) for one
    channel; independent channels add their information (sum of A_c^2); times FS for Hz.
    """
    return FS / (2 * math.pi) * math.sqrt(24 * sigma2 / (np.sum(np.square(amplitudes)) * n * (n * n - 1.0)))


def _sinusoid_lstsq(r, f):
    """Return (X (nch,), std_re (nch,), std_im (nch,), rss (nch,)): lstsq of r (N, nch) on [1, cos, sin] at f [Hz]."""
    t = np.arange(r.shape[0]) / FS
    D = np.column_stack([np.ones(t.size), np.cos(2 * math.pi * f * t), np.sin(2 * math.pi * f * t)])
    coef = np.linalg.lstsq(D, r, rcond=None)[0]
    rss = np.sum((r - D @ coef) ** 2, axis=0)
    cov = np.linalg.inv(D.T @ D)
    s2 = rss / (t.size - 3)
    return coef[1] - 1j * coef[2], np.sqrt(cov[1, 1] * s2), np.sqrt(cov[2, 2] * s2), rss


def _without_sync(x, ang, orders=(1, 2, 3)):
    """Return x (N, nch) minus its least-squares offset and harmonics of the rotor angle (lstsq here)."""
    D = np.column_stack([np.ones(ang.size)] + [f(k * ang) for k in orders for f in (np.cos, np.sin)])
    return x - D @ np.linalg.lstsq(D, x, rcond=None)[0]


@pytest.mark.parametrize('n, nch, amp, noise, sense', CASES)
def test_series_cost_and_phasors_equal_direct_least_squares(n, nch, amp, noise, sense):
    x, ang = _whirl_signal(n, nch, amp, noise, sense=sense)
    sp = _subsync_spectrum(x, ang, FS, (1, 2, 3))
    k, _ = _subsync_peak(sp, (0.05, 0.95))
    df = FS / n
    f0 = sp['freqs'][k]
    cost = SinusoidCost(sp['resid'], FS, f0, df)
    for f in f0 + df * np.linspace(-1.0, 1.0, 9):
        X, s_re, s_im, rss = _sinusoid_lstsq(sp['resid'], f)
        rss_std = np.sqrt(np.sum(2 * (n - 3) * (rss / (n - 3)) ** 2))         # 1-sigma of the summed RSS
        assert abs(cost(f) - np.sum(rss)) <= 0.01 * rss_std, (cost(f) - np.sum(rss)) / rss_std
        d = cost.phasors(f) - X
        assert np.all(np.abs(d.real) <= 0.01 * s_re) and np.all(np.abs(d.imag) <= 0.01 * s_im)


def _brent_min(cost, f0, df):
    """
    Return the minimum of ``cost`` within f0 +- df [Hz] by scipy's bounded Brent search, in two stages.

    Its tolerance is sqrt(eps) |u| + xatol / 3 of its variable u: first u = (f - f0) / df in [-1, 1] (to ~1.5e-8 df),
    then v = (f - f1) / (1e-5 df) in [-1, 1] around that first minimum f1 (to ~1e-13 df).
    """
    u = minimize_scalar(lambda u: cost(f0 + u * df), bounds=(-1.0, 1.0), method='bounded',
                        options={'xatol': 1e-12}).x
    f1 = f0 + u * df
    v = minimize_scalar(lambda v: cost(f1 + v * 1e-5 * df), bounds=(-1.0, 1.0), method='bounded',
                        options={'xatol': 1e-8}).x
    return f1 + v * 1e-5 * df


@pytest.mark.parametrize('n, nch, amp, noise, sense', CASES)
def test_search_finds_the_minimum_of_the_direct_cost(n, nch, amp, noise, sense):
    """The golden search ends where Brent's bounded search of the direct lstsq cost does (0.01 sigma_f)."""
    x, ang = _whirl_signal(n, nch, amp, noise, sense=sense)
    xy = (0, 1) if nch > 1 else None
    r = _without_sync(x, ang)
    win = np.hanning(n)
    power = np.sum(np.abs(np.fft.rfft(r * win[:, None], axis=0)) ** 2, axis=1)
    freqs = np.fft.rfftfreq(n, 1 / FS)
    speed_hz = (ang[-1] - ang[0]) / (2 * math.pi) / ((n - 1) / FS)
    df = FS / n
    for band in ((0.05, 0.95), (0.3, 0.6)):
        got = subsynchronous(x, ang, FS, ratio_range=band, xy=xy)
        idx = np.nonzero((freqs >= band[0] * speed_hz) & (freqs <= band[1] * speed_hz))[0]
        k = idx[np.argmax(power[idx])]
        f_min = _brent_min(lambda f: float(np.sum(_sinusoid_lstsq(r, f)[3])), freqs[k], df)
        X, s_re, s_im, rss = _sinusoid_lstsq(r, f_min)
        sigma2 = np.sum(rss) / (nch * (n - 3))
        sigma_f = _crb_sigma_f(sigma2, np.abs(X), n)
        assert abs(got.frequency - f_min) <= 0.01 * sigma_f, (got.frequency - f_min) / sigma_f
        assert got.ratio * speed_hz == pytest.approx(got.frequency, rel=4 * EPS)     # two roundings
        # the phasors: the least-squares fit at the frequency found (0.01 of their 1-sigma)
        X, s_re, s_im, _ = _sinusoid_lstsq(r, got.frequency)
        d = got.X - X
        assert np.all(np.abs(d.real) <= 0.01 * s_re) and np.all(np.abs(d.imag) <= 0.01 * s_im)
        assert got.whirl == (None if xy is None else ('forward' if sense > 0 else 'backward'))


def test_frequency_errors_match_the_cramer_rao_bound():
    """
    40 noise draws of a forward whirl (2 channels, 1.5 s): the frequency errors / CRB 1-sigma have mean square ~ 1.

    Least squares is the maximum-likelihood estimator here, efficient at this SNR (amplitude / noise = 10), so the
    mean square of 40 independent normalised errors lies in the chi-square(40) / 40 band at ALPHA.
    """
    n, amp, noise, ratio, speed_hz, draws = 15360, 2e-6, 2e-7, 0.437, 31.7, 40
    f_true = ratio * speed_hz
    sigma_f = _crb_sigma_f(noise ** 2, np.array([amp, amp]), n)
    z = []
    for seed in range(draws):
        x, ang = _whirl_signal(n, 2, amp, noise, ratio=ratio, speed_hz=speed_hz, seed=seed)
        z.append((subsynchronous(x, ang, FS).frequency - f_true) / sigma_f)
    ms = float(np.mean(np.square(z)))
    assert chdtri(draws, 1 - ALPHA / 2) / draws < ms < chdtri(draws, ALPHA / 2) / draws, ms


@pytest.mark.parametrize('sense', ['forward', 'backward'])
def test_subsynchronous_whirl(sense):
    rng = np.random.default_rng(3)
    W = 2 * math.pi * 40.0
    t = np.arange(int(2.0 * FS)) / FS
    angle = W * t
    ratio = 0.437
    f = ratio * W / (2 * math.pi)
    a = 4e-6
    sgn = 1.0 if sense == 'forward' else -1.0
    x = np.column_stack([phasor_to_time(2e-5, angle) + a * np.cos(2 * math.pi * f * t + 0.3),
                         phasor_to_time(-2e-5j, angle) + sgn * a * np.sin(2 * math.pi * f * t + 0.3)])
    x += 2e-7 * rng.standard_normal(x.shape)
    sub = subsynchronous(x, angle, FS)
    # coarse bounds (this test is about the whirl direction): the Cramer-Rao bounds of the frequency and amplitude
    # here are ~4e-6 and ~5e-4 relative; test_frequency_errors_match_the_cramer_rao_bound checks those
    assert sub.ratio == pytest.approx(ratio, rel=1e-3)
    np.testing.assert_allclose(sub.amplitude, [a, a], rtol=0.02)
    assert sub.whirl == sense
    assert sub.snr > 20
    # the same component fitted inside harmonic_vectors does not leak into 1X
    fit = harmonic_vectors(x, angle, subsync=sub.ratio)
    np.testing.assert_allclose(fit.X[0], [2e-5, -2e-5j], atol=3e-8)
    np.testing.assert_allclose(np.abs(fit.X_sub[0]), [a, a], rtol=0.02)


def test_bands_share_one_fit_and_give_the_single_calls_components():
    n = 12001
    x, ang = _whirl_signal(n, 2, 2e-6, 1e-7)
    bands = [(0.05, 0.95), (0.3, 0.6), (0.7, 0.95), (0.05, 0.0501)]
    got = subsynchronous_bands(x, ang, FS, bands)
    assert got[3] is None                                     # narrower than 3 FFT bins
    r = _without_sync(x, ang)
    for band, g in zip(bands[:3], got):
        one = subsynchronous(x, ang, FS, ratio_range=band)
        X, s_re, s_im, rss = _sinusoid_lstsq(r, one.frequency)
        sigma2 = np.sum(rss) / (2 * (n - 3))
        sigma_f = _crb_sigma_f(sigma2, np.abs(X), n)
        assert abs(g.frequency - one.frequency) <= 0.01 * sigma_f
        assert np.all(np.abs((g.X - one.X).real) <= 0.01 * s_re) and np.all(np.abs((g.X - one.X).imag) <= 0.01 * s_im)
        assert g.whirl == one.whirl
    with pytest.raises(ValueError, match='too short'):
        subsynchronous(x, ang, FS, ratio_range=bands[3])
    with pytest.raises(ValueError, match='does not turn'):
        subsynchronous_bands(x, np.zeros(x.shape[0]), FS, bands)
    bad = x.copy()
    bad[7, 1] = np.nan
    with pytest.raises(ValueError, match='1 non-finite'):
        subsynchronous(bad, ang, FS)
