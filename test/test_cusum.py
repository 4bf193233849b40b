"""
The two-sided CUSUM (bearing_id/monitor/cusum.py): false-alarm rate, detection delay, onset and size of a shift.

Oracles: the ARL integral equation (test/cusum_oracle.py, independent of the module's Siegmund approximation), checked
first against the published table of Montgomery, *Introduction to Statistical Quality Control* (6th ed., Table 9.3:
two-sided tabular CUSUM, k = 1/2: h = 4 gives ARL 168 / 8.38 / 3.34 at shifts 0 / 1 / 2 sigma, h = 5 gives 465 /
10.4 / 4.01); Monte Carlo (seeded) of the module's own recursion; closed forms for a noise-free step.

Tolerances: a Monte-Carlo mean is within 3 of its standard errors of the truth; the module's ARL (Siegmund) differs
from the integral equation's by what is measured and printed here (relative to the integral equation: k = 0.5,
ARL0 500: 0.8 %; k = 1: 5.9 % in control, 2.4 % for the 2-sigma delay), which is added where the Monte Carlo is
compared with the requested value.
"""
from __future__ import annotations

import math

from bearing_id.monitor.cusum import design, detect, level_at_end, siegmund_arl, statistics, threshold, two_sided_arl
import cusum_oracle
import numpy as np
import pytest
from scipy.stats import norm

MONTGOMERY = [    # (h, shift [sigma], ARL, half unit of the last printed digit) for k = 1/2, two-sided
    (4.0, 0.0, 168.0, 0.5), (4.0, 1.0, 8.38, 0.005), (4.0, 2.0, 3.34, 0.005),
    (5.0, 0.0, 465.0, 0.5), (5.0, 1.0, 10.4, 0.05), (5.0, 2.0, 4.01, 0.005),
]


def mc_run_lengths(rng, runs: int, mu: float, k: float, h: float, chunk: int = 1000) -> np.ndarray:
    """Return the zero-state run lengths (runs,) of the module's two-sided recursion for z ~ N(mu, 1)."""
    rl = np.zeros(runs, dtype=int)
    active = np.arange(runs)
    p = np.zeros(runs)
    m = np.zeros(runs)
    done_before = 0
    while active.size:
        z = rng.standard_normal((chunk, active.size)) + mu
        sp, sm = statistics(z, k, start=(p, m))
        hit = (sp > h) | (sm > h)
        done = hit.any(axis=0)
        rl[active[done]] = done_before + np.argmax(hit[:, done], axis=0) + 1
        p, m = sp[-1, ~done], sm[-1, ~done]
        active = active[~done]
        done_before += chunk
    return rl


@pytest.mark.parametrize('h, shift, published, half_unit', MONTGOMERY)
def test_oracle_reproduces_the_published_table(h, shift, published, half_unit):
    got, err = cusum_oracle.two_sided_arl(shift, 0.5, h)
    assert abs(got - published) <= half_unit + err, (h, shift, got, published)


def test_siegmund_limits_and_threshold_inverse():
    # Delta = 0 (mu = k): ARL = b^2, the limit of the closed form from both sides
    b = 5.0 + 1.166
    assert siegmund_arl(0.5, 0.5, 5.0) == pytest.approx(b * b, rel=1e-12)
    for eps in (1e-5, -1e-5):
        assert siegmund_arl(0.5 + eps, 0.5, 5.0) == pytest.approx(b * b, rel=1e-4)
    # the in-control one-sided ARL in closed form (exp(2kb) - 2kb - 1) / (2k^2), written out here
    k = 0.5
    assert siegmund_arl(0.0, k, 5.0) == pytest.approx((np.exp(2 * k * b) - 2 * k * b - 1) / (2 * k * k), rel=1e-12)
    for arl0, kk in ((100.0, 0.25), (500.0, 0.5), (10000.0, 1.5)):
        assert two_sided_arl(0.0, kk, threshold(arl0, kk)) == pytest.approx(arl0, rel=1e-10)
    with pytest.raises(ValueError, match='ARL0 must lie'):
        threshold(1.0, 0.5)


@pytest.mark.parametrize('delta', [1.0, 2.0])
def test_in_control_arl_is_the_requested_one(delta):
    arl0 = 500.0
    des = design(arl0, delta)
    exact, qerr = cusum_oracle.two_sided_arl(0.0, des.k, des.h)
    siegmund_err = abs(exact - arl0)
    rl = mc_run_lengths(np.random.default_rng(20250 + int(delta)), 6000, 0.0, des.k, des.h)
    mean, se = rl.mean(), rl.std(ddof=1) / np.sqrt(rl.size)
    print(f'k = {des.k}, h = {des.h:.4f}: MC ARL0 {mean:.1f} +- {se:.1f} (6000 runs), requested {arl0:.0f}, '
          f'integral equation {exact:.1f} (Siegmund error {100 * siegmund_err / exact:.2f} %)')
    assert abs(mean - exact) <= 3 * se + qerr          # the recursion is the CUSUM the oracle describes
    assert abs(mean - arl0) <= 3 * se + siegmund_err + qerr
    assert siegmund_err / exact < 0.07                 # the approximation error stated in the module (6 %)


def test_delay_for_a_two_sigma_shift():
    des = design(500.0, 2.0)
    exact, qerr = cusum_oracle.two_sided_arl(2.0, des.k, des.h)
    siegmund = float(des.arl(2.0))
    rl = mc_run_lengths(np.random.default_rng(7), 20000, 2.0, des.k, des.h)
    mean, se = rl.mean(), rl.std(ddof=1) / np.sqrt(rl.size)
    print(f'2-sigma shift: MC delay {mean:.3f} +- {se:.3f} samples, integral equation {exact:.3f}, Siegmund '
          f'{siegmund:.3f} ({100 * abs(siegmund - exact) / exact:.1f} % off)')
    assert abs(mean - exact) <= 3 * se + qerr
    assert abs(mean - siegmund) <= 3 * se + abs(siegmund - exact) + qerr


def test_noise_free_step_closed_form():
    """Noise-free step: z = 0 before sample 50, delta after; S+ grows by (delta - k) a sample, alarm at S+ > h."""
    sigma, ref, delta = 2e-6, 1e-4, 2.0
    des = design(500.0, delta)
    x = np.full(120, ref)
    x[50:] += delta * sigma
    times = 1000.0 + 60.0 * np.arange(x.size)
    alarms = detect(x, sigma, arl0=500.0, delta=delta, reference=ref, times=times)
    n_alarm = int(np.floor(des.h / (delta - des.k))) + 1          # samples since the step at the first S+ > h
    a = alarms[0]
    assert (a.onset, a.index, a.direction, a.n) == (50, 50 + n_alarm - 1, 1, n_alarm)
    assert a.onset_time == 1000.0 + 60.0 * 50 and a.time == 1000.0 + 60.0 * a.index
    assert a.size == pytest.approx(delta * sigma, rel=1e-12)
    assert a.size_sigma == pytest.approx(sigma / np.sqrt(n_alarm), rel=1e-12)
    assert a.statistic == pytest.approx(n_alarm * (delta - des.k), rel=1e-12) and a.statistic > a.h
    # after the alarm the statistic restarts: the persisting step raises the next alarm n_alarm samples later
    assert alarms[1].index == a.index + n_alarm and alarms[1].onset == a.index + 1
    down = detect(2 * ref - x, sigma, arl0=500.0, delta=delta, reference=ref)[0]
    assert (down.direction, down.onset, down.index) == (-1, 50, a.index)
    assert down.size == pytest.approx(-delta * sigma, rel=1e-12)


def test_reference_from_the_first_samples():
    sigma = np.full(100, 2e-6)
    x = np.full(100, 1e-4)
    x[60:] += 3 * 2e-6
    a = detect(x, sigma, arl0=500.0, delta=2.0, n_reference=40)[0]
    assert a.reference == pytest.approx(1e-4, rel=1e-14) and a.reference_sigma == pytest.approx(2e-6 / np.sqrt(40))
    assert a.onset == 60
    assert a.size_sigma == pytest.approx(np.sqrt(2e-6 ** 2 / a.n + 2e-6 ** 2 / 40), rel=1e-12)
    assert detect(x[:40], sigma[:40], arl0=500.0, delta=2.0, n_reference=40) == []
    with pytest.raises(ValueError, match='reference'):
        detect(x, sigma, arl0=500.0)


def _late_or_early_bound(m: int, drift_after: float, drift_before: float, terms: int = 10000) -> float:
    """
    Union bound on P(|onset estimate - true onset| > m) (derivation in the test below).

    Late: S_{t0+j-1} = 0 needs sum_{i=t0}^{t0+j-1} (z_i - k) <= 0, probability Phi(-drift_after sqrt(j)), for some
    j > m.  Early: a positive stretch of more than m in-control samples ending at t0 - 1, probability at most
    Phi(-drift_before sqrt(j)) for some length j > m, on either side (factor 2).
    """
    j = np.arange(m + 1, m + 1 + terms)
    return float(np.sum(norm.cdf(-drift_after * np.sqrt(j))) + 2 * np.sum(norm.cdf(-drift_before * np.sqrt(j))))


def test_onset_and_size_of_a_two_sigma_shift():
    """
    Monte Carlo: 3000 sequences, 30 in-control samples, then a 2-sigma shift (designed for it: k = 1, ARL0 500).

    Onset: the estimate is the sample after the alarming side's S was last zero.  S_n >= sum_{i=a}^{n} (z_i - k) for
    any a after the last restart, so a late estimate (S zero at t0 + j - 1, j > m) needs a post-shift partial sum of
    j terms of mean delta - k = 1 to be <= 0 (probability Phi(-sqrt(j))), and an early one a positive in-control
    partial sum of more than m terms of mean -k (Phi(-k sqrt(j))): the union bound of :func:`_late_or_early_bound`.
    Size: the inverse-variance mean since the onset, with its 1-sigma.  The alarm selects samples that happened to
    be high, so the estimate is biased up (measured: +0.32 of its sigma) and its stated sigma covers less than a
    normal one would: required are the mean of (size - delta) / size_sigma in [0, 0.5] and at least 95 % of the true
    shifts within 3 stated sigma (a normal estimate: 99.7 %).
    """
    rng = np.random.default_rng(11)
    sigma, ref, delta, t0 = 2e-6, 1e-4, 2.0, 30
    onset_err, t_size = [], []
    for _ in range(3000):
        x = ref + sigma * rng.standard_normal(t0 + 40)
        x[t0:] += delta * sigma
        after = [a for a in detect(x, sigma, arl0=500.0, delta=delta, reference=ref) if a.index >= t0]
        a = after[0]
        onset_err.append(a.onset - t0)
        t_size.append((a.size - delta * sigma) / a.size_sigma)
    onset_err, t_size = np.array(onset_err), np.array(t_size)
    n = onset_err.size
    for m in (2, 4, 6):
        frac = float(np.mean(np.abs(onset_err) > m))
        bound = _late_or_early_bound(m, delta / 2, delta / 2)
        print(f'|onset error| > {m}: {100 * frac:.2f} % of {n} alarms, bound {100 * bound:.1f} %')
        assert frac <= bound + 3 * np.sqrt(bound * (1 - bound) / n)
    cover3 = float(np.mean(np.abs(t_size) <= 3))
    print(f'onset exact in {100 * np.mean(onset_err == 0):.1f} %; size: mean (size - delta)/sigma '
          f'{t_size.mean():+.3f}, within 2 sigma {100 * np.mean(np.abs(t_size) <= 2):.1f} %, within 3 sigma '
          f'{100 * cover3:.1f} %')
    assert 0.0 <= t_size.mean() <= 0.5
    assert cover3 >= 0.95


def test_level_at_end_is_the_weighted_line_numpy_fits():
    # oracle: numpy.polyfit (weights 1/sigma on the residuals, unscaled covariance) evaluated at the last time
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0.0, 50.0, 9))
    sigma = rng.uniform(0.5, 2.0, 9)
    x = 3.0 + 0.2 * t + sigma * rng.standard_normal(9)
    p, cov = np.polyfit(t - t[-1], x, 1, w=1.0 / sigma, cov='unscaled')
    level, level_sigma = level_at_end(t, x, sigma)
    assert level == pytest.approx(p[1], rel=1e-9)
    assert level_sigma == pytest.approx(math.sqrt(cov[1, 1]), rel=1e-9)
    assert level_at_end(t[:2], x[:2], sigma[:2]) == (x[1], sigma[1])      # two points: the last one as it is


def test_a_ramp_is_sized_at_the_alarm_by_the_line_since_its_onset():
    # a drift (wear): 40 in-control samples, then x grows by 0.5 sigma per sample.  The mean since the onset lags the
    # ramp; the alarm sample's own deviation is biased up (the alarm fires on a high sample: +0.57 sigma on average
    # over these 300 series); the line through the onset..alarm samples removes most of that bias and its stated
    # 1-sigma covers its error
    rng = np.random.default_rng(11)
    n, sigma, trials = 80, 1.0, 300
    truth = np.where(np.arange(n) < 40, 0.0, 0.5 * (np.arange(n) - 39))
    z_line, z_point, lag = [], [], []
    for _ in range(trials):
        x = 100.0 + truth + sigma * rng.standard_normal(n)
        a = [a for a in detect(x, sigma, arl0=1e4, delta=2.0, n_reference=20) if a.index >= 40][0]
        assert a.direction == 1
        z_line.append((a.latest - truth[a.index]) / a.latest_sigma)
        z_point.append((x[a.index] - a.reference - truth[a.index]) / math.hypot(sigma, a.reference_sigma))
        lag.append((a.size - truth[a.index]) / a.size_sigma)
    z_line, z_point, lag = np.array(z_line), np.array(z_point), np.array(lag)
    cover = float(np.mean(np.abs(z_line) <= 2.0))
    p2 = 2 * norm.cdf(2.0) - 1
    print(f'(size at the alarm - truth) / sigma: line mean {z_line.mean():+.3f} (2-sigma cover {100 * cover:.1f} %), '
          f'alarm sample {z_point.mean():+.3f}, mean since the onset {lag.mean():+.3f}')
    assert z_point.mean() > 3 * z_point.std() / math.sqrt(trials)       # the selection bias is there
    assert z_line.mean() < 0.5 * z_point.mean()                          # the line removes at least half of it
    assert cover >= p2 - 3 * math.sqrt(p2 * (1 - p2) / trials)
    assert lag.mean() < -3 * lag.std() / math.sqrt(trials)              # the mean since the onset lags
