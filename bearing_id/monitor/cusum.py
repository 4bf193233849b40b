"""
Two-sided tabular CUSUM on a standardised sequence, with the threshold chosen for a stated false-alarm rate.

The monitored quantity x_k (e.g. a bearing's clearance [m], one value per identification) has a stated 1-sigma
sigma_k (same unit) and an in-control reference; the test runs on z_k = (x_k - reference) / sigma_k, which is N(0, 1)
while nothing changes.  For a shift of ``delta`` sigmas to be detected fastest the reference value (allowance) is
k = delta / 2, and (Page 1954; Montgomery, *Introduction to Statistical Quality Control*, ch. 9)

    S+_n = max(0, S+_{n-1} + z_n - k),   S-_n = max(0, S-_{n-1} - z_n - k),   S_0 = 0,

with an alarm when S+_n > h or S-_n > h.  The threshold h is the user's average run length to a false alarm ARL0
turned into a number by Siegmund's approximation (Siegmund 1985, *Sequential Analysis*, eq. 2.55) of the one-sided
zero-state ARL for z ~ N(mu, 1): with Delta = mu - k and b = h + 1.166,

    ARL(mu) = (exp(-2 Delta b) + 2 Delta b - 1) / (2 Delta^2)      (b^2 at Delta = 0),

and the two sides combined as 1 / ARL = 1 / ARL+ + 1 / ARL- (ARL- is ARL+ of -mu).  In control (mu = 0, Delta = -k)
each side runs ARL = (exp(2 k b) - 2 k b - 1) / (2 k^2), so the two-sided scheme's ARL0 is half of it.  The
approximation's error is measured in test/test_cusum.py against the integral-equation solution (a few tenths of a
percent for k = 0.5 to 6 % for k = 1 at ARL0 = 500).

An alarm reports its onset (the sample after the statistic was last zero), the shift's size in the unit of x with
its 1-sigma (the inverse-variance weighted mean of x - reference from the onset to the alarm: the mean of z since the
onset, k + S / N, converted back), and its evidence (the statistic and h).  After an alarm both sides restart at 0.
The size estimate is biased away from zero (the alarm fires when the z happened to be high) by a fraction of its
sigma; the test states how much.

A reference estimated from the first N samples (``n_reference``) is their weighted mean; its own error is correlated
across every later z, which shortens the in-control ARL for small N (the stated ARL0 holds for a known reference).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
import math

import numpy as np
from scipy.optimize import brentq
from scipy.stats import chi2 as chi2_dist

SIEGMUND_OFFSET = 1.166     # b = h + 1.166: Siegmund's correction for the overshoot of a normal random walk
H_MAX = 200.0               # largest threshold searched [sigma]
SCALE_QUANTILE = 0.16       # scatter_scale: the chi^2 quantile of its one-sided 1-sigma (84 %) upper bound


def siegmund_arl(mu, k: float, h: float):
    """
    Return Siegmund's approximate zero-state ARL [samples] of the one-sided upper CUSUM (k, h) for z ~ N(mu, 1).

    ``mu`` [sigma] any shape; ``k``, ``h`` [sigma].  Delta = mu - k, b = h + 1.166.
    """
    d = np.asarray(mu, dtype=float) - float(k)
    b = float(h) + SIEGMUND_OFFSET
    x = 2.0 * d * b
    small = np.abs(x) < 1e-6
    d_safe = np.where(small, 1.0, d)
    with np.errstate(over='ignore'):
        arl = (np.expm1(-x) + x) / (2.0 * d_safe * d_safe)
    # at small |x| the series (exp(-x) + x - 1 = x^2/2 - x^3/6 + x^4/24 - ...) avoids the cancellation
    return np.where(small, b * b * (1.0 - x / 3.0 + x * x / 12.0), arl)


def two_sided_arl(mu, k: float, h: float):
    """Return the two-sided scheme's ARL [samples] for z ~ N(mu, 1): 1 / (1 / ARL+(mu) + 1 / ARL+(-mu))."""
    return 1.0 / (1.0 / siegmund_arl(mu, k, h) + 1.0 / siegmund_arl(-np.asarray(mu, dtype=float), k, h))


def threshold(arl0: float, k: float) -> float:
    """
    Return the threshold h [sigma] of the two-sided CUSUM with allowance ``k`` [sigma] and in-control ARL ``arl0``.

    ``arl0`` [samples], by Siegmund's approximation.  Raises ValueError when ``arl0`` is below what h = 0 already
    gives (or above what H_MAX gives).
    """
    arl0, k = float(arl0), float(k)
    if not (k > 0 and math.isfinite(k)):
        raise ValueError(f'the allowance k must be > 0 sigma, got {k}')
    lo, hi = float(two_sided_arl(0.0, k, 0.0)), float(two_sided_arl(0.0, k, H_MAX))
    if not (lo < arl0 < hi):
        raise ValueError(f'ARL0 must lie between {lo:.3g} (h = 0) and {hi:.3g} samples (h = {H_MAX}) for k = {k}, '
                         f'got {arl0}')
    return float(brentq(lambda h: math.log(float(two_sided_arl(0.0, k, h))) - math.log(arl0), 0.0, H_MAX,
                        xtol=1e-12, rtol=1e-14))


@dataclass(frozen=True)
class Design:
    """A CUSUM design: allowance k and threshold h [sigma], the shift delta [sigma] it targets and its ARL0."""

    k: float
    h: float
    delta: float
    arl0: float

    def arl(self, mu) -> np.ndarray:
        """Return Siegmund's two-sided ARL [samples] for a shift ``mu`` [sigma] (any shape)."""
        return two_sided_arl(mu, self.k, self.h)


@lru_cache(maxsize=64)
def design(arl0: float, delta: float = 1.0) -> Design:
    """Return the design for the in-control ARL ``arl0`` [samples] tuned to a shift ``delta`` [sigma] (k = delta/2)."""
    delta = float(delta)
    if not (delta > 0 and math.isfinite(delta)):
        raise ValueError(f'the shift to detect must be > 0 sigma, got {delta}')
    return Design(k=delta / 2.0, h=threshold(arl0, delta / 2.0), delta=delta, arl0=float(arl0))


def statistics(z, k: float, start=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """
    Return (S+, S-) of the two-sided CUSUM over ``z`` (n,) or (n, m) (time first; m independent sequences) [sigma].

    ``start``: the statistics before the first sample (scalars or (m,)).  No restart at a threshold.
    """
    z = np.asarray(z, dtype=float)
    if z.ndim == 1:                 # one sequence: the recursion in plain floats (10x faster than 0-d arrays)
        return _statistics_1d(z, float(k), float(start[0]), float(start[1]))
    sp = np.empty_like(z)
    sm = np.empty_like(z)
    p = np.broadcast_to(np.asarray(start[0], dtype=float), z.shape[1:]).copy()
    m = np.broadcast_to(np.asarray(start[1], dtype=float), z.shape[1:]).copy()
    for i in range(z.shape[0]):
        p = np.maximum(0.0, p + z[i] - k)
        m = np.maximum(0.0, m - z[i] - k)
        sp[i] = p
        sm[i] = m
    return sp, sm


def _statistics_1d(z: np.ndarray, k: float, p: float, m: float) -> tuple[np.ndarray, np.ndarray]:
    sp, sm = [], []
    for zi in z.tolist():
        p = max(0.0, p + zi - k)
        m = max(0.0, m - zi - k)
        sp.append(p)
        sm.append(m)
    return np.array(sp), np.array(sm)


def run_lengths(z, k: float, h: float) -> np.ndarray:
    """
    Return the sample number (1-based) of the first alarm of each column of ``z`` (n, m) [sigma], 0 where none.

    An alarm: S+ > h or S- > h (:func:`statistics` from 0).
    """
    sp, sm = statistics(z, k)
    hit = (sp > h) | (sm > h)
    first = np.argmax(hit, axis=0) + 1
    return np.where(hit.any(axis=0), first, 0)


@dataclass(frozen=True)
class Alarm:
    """
    One alarm of :func:`detect`.

    index: the sample that raised it (0-based in the input); onset: the first sample of the shift (the one after the
    statistic was last zero); time / onset_time: the same in the unit of ``times`` (or the index); direction: +1 up,
    -1 down; size, size_sigma: the shift and its 1-sigma in the unit of x; statistic, h [sigma]: the evidence (the
    side's S at the alarm, the threshold); k [sigma]; reference, reference_sigma: the in-control value and its
    1-sigma (0 when given) in the unit of x; n: samples from the onset to the alarm; latest, latest_sigma: the shift
    at the alarm and its 1-sigma: the value at the alarm's time of a weighted straight line through the onset..alarm
    samples less the reference (:func:`level_at_end`; a drift's size when it is alarmed, a step's too: ``size``
    averages since the onset, right for a step, behind for a ramp).
    """

    index: int
    onset: int
    time: float
    onset_time: float
    direction: int
    size: float
    size_sigma: float
    statistic: float
    h: float
    k: float
    reference: float
    reference_sigma: float
    n: int
    latest: float = math.nan
    latest_sigma: float = math.nan


def reference_from(x, sigma) -> tuple[float, float]:
    """Return the inverse-variance weighted mean of ``x`` (n,) with 1-sigma ``sigma`` (n,) and its 1-sigma."""
    x, sigma = _checked(x, sigma)
    w = 1.0 / sigma ** 2
    return float(np.sum(w * x) / np.sum(w)), float(1.0 / math.sqrt(np.sum(w)))


def level_at_end(t, x, sigma) -> tuple[float, float]:
    """
    Return the value at ``t[-1]`` of the weighted least-squares line through ``x`` (n,) at ``t`` (n,), and its 1-sigma.

    ``sigma`` (n,): the samples' 1-sigma (unit of x).  With fewer than 3 samples, the last sample and its sigma (a
    line through two points has no scatter to check).  The level of a drift where it was last seen: unbiased for a
    ramp and a step alike, where the last sample alone is biased up by the selection an alarm makes (it is the one
    that crossed the threshold), and the mean since the onset lags a ramp.
    """
    t = np.asarray(t, dtype=float).reshape(-1)
    x, sigma = _checked(x, sigma)
    if x.size < 3 or np.ptp(t) == 0.0:
        return float(x[-1]), float(sigma[-1])
    w = 1.0 / sigma ** 2
    a = np.column_stack([np.ones_like(t), t - t[-1]])
    cov = np.linalg.inv(a.T @ (w[:, None] * a))
    beta = cov @ (a.T @ (w * x))
    return float(beta[0]), float(math.sqrt(cov[0, 0]))


def scatter_scale(x, sigma, reference: float) -> float:
    """
    Return how much wider than their stated 1-sigma the in-control samples may scatter: an upper bound, at least 1.

    chi^2 = sum(((x - reference) / sigma)^2) over ``x`` (n,) with 1-sigma ``sigma`` (n,) about their weighted mean
    ``reference`` has n - 1 degrees of freedom; the scale is sqrt(chi^2 / q), q its ``SCALE_QUANTILE`` quantile: the
    one-sided 1-sigma upper confidence bound of the scatter's ratio to the stated sigma (1 for n < 2).  Never below 1:
    a scatter smaller than stated is taken as chance.  The bound, not the estimate: a CUSUM standardised by an
    estimated scale alarms falsely far more often when the estimate happens to be low than it gains when high (20
    reference points, scatter 1.5x the stated sigma: with the estimate the false-alarm rate was 2.4x the design's,
    measured once in a Monte Carlo like test/test_trend.py's, which checks that the bound's is within it).  A series
    standardised by scale * sigma keeps the stated false-alarm rate when the fits' sigma is understated by a constant
    factor, as a fit that leaves out a slowly varying effect (a temperature the viscosity law does not follow
    exactly) does.
    """
    x, sigma = _checked(x, sigma)
    if x.size < 2:
        return 1.0
    chi2 = float(np.sum(((x - float(reference)) / sigma) ** 2))
    return max(1.0, math.sqrt(chi2 / float(chi2_dist.ppf(SCALE_QUANTILE, x.size - 1))))


def detect(x, sigma, *, arl0: float, delta: float = 1.0, reference: float | None = None,
           n_reference: int | None = None, times=None, reference_sigma: float = 0.0) -> list[Alarm]:
    """
    Return the alarms of the two-sided CUSUM on ``x`` (n,) with 1-sigma ``sigma`` (n,) or scalar (unit of x).

    ``arl0`` [samples]: the average run length to a false alarm; ``delta`` [sigma]: the shift to detect fastest.
    The in-control value is ``reference`` (unit of x; its 1-sigma ``reference_sigma`` enters the sizes' 1-sigma),
    or else the weighted mean of the first ``n_reference`` samples, which are then not monitored.  ``times`` (n,)
    label the samples (e.g. UNIX s), default their index.  After an alarm both sides restart from 0 at the next
    sample.
    """
    x, sigma = _checked(x, sigma)
    n = x.size
    t = np.arange(n, dtype=float) if times is None else np.asarray(times, dtype=float).reshape(-1)
    if t.size != n:
        raise ValueError(f'times must have one entry per sample ({n}), got {t.size}')
    first = 0
    ref_sigma = float(reference_sigma)
    if reference is None:
        if n_reference is None or not (1 <= int(n_reference) <= n):
            raise ValueError(f'give a reference, or n_reference between 1 and the number of samples ({n}), '
                             f'got {n_reference}')
        first = int(n_reference)
        reference, ref_sigma = reference_from(x[:first], sigma[:first])
    elif n_reference is not None:
        raise ValueError('give either a reference or n_reference, not both')
    des = design(arl0, delta)
    z = (x - float(reference)) / sigma
    alarms: list[Alarm] = []
    start = first
    while start < n:
        sp, sm = statistics(z[start:], des.k)
        hit = np.flatnonzero((sp > des.h) | (sm > des.h))
        if hit.size == 0:
            break
        i = int(hit[0])
        up = sp[i] > des.h and (sp[i] >= sm[i])
        s = sp if up else sm
        zeros = np.flatnonzero(s[:i] == 0.0)
        onset = int(zeros[-1]) + 1 if zeros.size else 0
        sl = slice(start + onset, start + i + 1)
        w = 1.0 / sigma[sl] ** 2
        size = float(np.sum(w * (x[sl] - float(reference))) / np.sum(w))
        size_sigma = math.sqrt(1.0 / float(np.sum(w)) + ref_sigma ** 2)
        level, level_sigma = level_at_end(t[sl], x[sl] - float(reference), sigma[sl])
        alarms.append(Alarm(index=start + i, onset=start + onset, time=float(t[start + i]),
                            onset_time=float(t[start + onset]), direction=1 if up else -1, size=size,
                            size_sigma=size_sigma, statistic=float(s[i]), h=des.h, k=des.k,
                            reference=float(reference), reference_sigma=ref_sigma, n=i - onset + 1,
                            latest=level, latest_sigma=math.hypot(level_sigma, ref_sigma)))
        start += i + 1
    return alarms


def _checked(x, sigma) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(x, dtype=float).reshape(-1)
    sigma = np.broadcast_to(np.asarray(sigma, dtype=float), x.shape).astype(float)
    if not np.all(np.isfinite(x)):
        raise ValueError('x must be finite')
    if not np.all(np.isfinite(sigma) & (sigma > 0)):
        raise ValueError('sigma must be finite and > 0')
    return x, sigma


__all__ = ['Alarm', 'Design', 'design', 'detect', 'level_at_end', 'reference_from', 'run_lengths', 'scatter_scale',
           'siegmund_arl', 'statistics', 'threshold', 'two_sided_arl']
