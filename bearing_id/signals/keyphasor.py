"""
Key marks from a sampled once-per-revolution keyphasor pulse, and the rotor angle and speed rebuilt from them.

Convention (:data:`KEY_MARK_CONVENTION`)
    The rotor angle is 0 (mod 2 pi) at the instant the keyphasor pulse's rising edge crosses 50 % of the way from
    its low to its high level.  A sampled square (TTL) pulse is high while the angle mod 2 pi is in [0, width):
    sample k (time k / fs) is high iff it is at or after the mark, so the mark tau of an edge whose first high sample
    is k lies in (k - 1, k] [samples].  ``edge='falling'`` reads an inverted pulse (the falling edge is the mark).

Estimating the mark of each edge (``KeyMarks.kind``)
    ``'ramp'``  the edge rises over several samples (at least half the edges have both samples around the 50 % level
        strictly between the two levels): the 50 % crossing is interpolated linearly between those two samples, exact
        for a linear rise of >= 2 samples; 1-sigma from the level noise (0 for a noise-free pulse).
    ``'sharp'`` (one sample low, the next high; also a rise shorter than ~2 samples) each edge only says tau is in
        (k - 1, k], k its first sample at or above the 50 % level.  Consecutive marks are grouped into the longest
        runs consistent with one constant speed (a straight line tau_m = a + b m through all their intervals; greedy,
        with the convex hull of the points (m, k_m)).  Over all such lines each mark has a feasible range; sigma =
        that range / sqrt 12 (the true mark is always inside it when the speed is constant over the run).  Per run:
        * locked: the first-high samples repeat with a period of Q revolutions (b = P/Q exactly; Q = 1 is a whole
          number of samples per revolution, Q = 5 the simulator's 204.8 samples/rev at 3000 rpm and 10240 Hz) over
          >= 5 periods and >= 8 marks.  No data can place the marks within the 1/Q sample they share.  With
          ``synchronous=True`` (default) they are taken ON the samples of the line (tau = a_max + b m): exact when
          the DAQ clock is locked to the rotor (order-tracking DAQs, a simulator starting at angle 0 on a sample).
          With an asynchronous clock the estimate is then up to 1/Q sample late, the same at every mark of the run:
          an unavoidable phase error of up to 2 pi / (Q N) rad (N samples per revolution) that does not average out;
          ``synchronous=False`` centres the marks instead (error within +-1/(2Q) sample, never exact).
          ``locked`` = True, sigma >= 1 / (Q sqrt 12).
        * dithering (any other run): the sub-sample position of the edge moves from revolution to revolution; each
          mark is the middle of its feasible range (a vernier: a long steady run pins the marks to a small fraction
          of a sample).  A run of 1-2 marks gives k - 0.5 +- 0.5 (the mid-sample estimate, unbiased on average).
        For comparison, k - 0.5 at every edge (a mid-level crossing) is half a sample early at a whole number of
        samples per revolution with marks on samples, and k is +0.5 sample late on average when edges dither.
    ``sigma`` is per mark, in samples: fold it into a 1X phase uncertainty as 2 pi sigma / N rad (N samples/rev);
    the errors of locked marks are one offset per run (they do not average out), the others vary mark to mark.

Angle and speed (:func:`angle_from_marks`, :func:`speed_from_marks`)
    2 pi per mark interval, linear in time between marks (for a speed ramp with angular acceleration alpha the
    interpolation error is <= alpha T^2 / 8 for a revolution of duration T), extrapolated before the first and after
    the last mark with the nearest revolution's mean speed; the angle is unwrapped and 0 at the first mark.
    Speed: each revolution's mean speed 2 pi / T at the revolution's middle, linear between.

Errors (:class:`KeyphasorError`, a ValueError): NaN in the pulse, a constant pulse, fewer than 2 marks, or a
revolution whose duration differs from the previous one by more than ``max_jump`` (default 20 %): a missing or an
extra pulse; the message names the sample index.

numpy only, no ROS.  Times in samples (``index``) or seconds (``times``), angles in rad, speeds in rad/s.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

TWO_PI = 2.0 * math.pi

KEY_MARK_CONVENTION = ("rotor angle = 0 (mod 2 pi) when the keyphasor pulse's rising edge crosses 50 % of its "
                       'low-to-high swing; a square keyphasor pulse is high while the angle mod 2 pi is in [0, width)')
DEFAULT_WIDTH = 0.2 * math.pi  # rad, pulse width written by :func:`pulse_from_angle`
MAX_JUMP = 0.2             # relative change of the revolution duration between consecutive revolutions refused
LEVEL_TOL = 0.1            # fraction of the swing: a sample closer than this to a level is 'on' that level
HYSTERESIS = 0.25          # an edge goes from below 25 % to above 75 % of the swing (noise near 50 % is no edge)
LOCK_MIN_MARKS = 8         # a locked (periodic) run needs at least this many marks ...
LOCK_MIN_PERIODS = 5       # ... and at least this many periods of its first-high pattern
ON_MARK_REV = 1e-9         # rev: an angle this close below a multiple of 2 pi counts as on the mark (rounding)
_FEASIBLE = 1.0 - 1e-9     # a run is consistent with a constant speed when its minimal vertical width is below this
SIGMA_UNIFORM_1 = 1.0 / math.sqrt(12.0)   # 1-sigma of a mark known only to lie within one sample [samples]


class KeyphasorError(ValueError):
    """The keyphasor signal or key-mark times cannot give a rotor angle; the message says why and where."""


@dataclass(frozen=True)
class KeyMarks:
    """
    Key marks of a pulse train.

    index : (m,) sub-sample position of each mark [samples], 0 = the first sample (time index / sample_rate).
    sigma : (m,) 1-sigma of ``index`` [samples] (see the module docstring).
    locked : (m,) bool, the mark is taken to fall on a sample (periodic run of sharp edges); its error, if the
        clock was not locked to the rotor, is the same offset at every mark of its run.
    kind : 'sharp' or 'ramp' (how the edges were read).
    sample_rate : Hz.
    """

    index: np.ndarray
    sigma: np.ndarray
    locked: np.ndarray
    kind: str
    sample_rate: float

    @property
    def times(self) -> np.ndarray:
        """(m,) mark times [s] from the first sample."""
        return self.index / self.sample_rate

    def __len__(self) -> int:
        return int(self.index.size)


# ------------------------------------------------------------------------------------------------ public API
def key_marks(pulse, sample_rate: float, *, edge: str = 'rising', max_jump: float = MAX_JUMP,
              synchronous: bool = True) -> KeyMarks:
    """
    Key marks of a sampled once-per-revolution pulse ``pulse`` (N,) [any unit] at ``sample_rate`` [Hz].

    ``edge``: 'rising' (the convention) or 'falling' (an inverted pulse).  ``max_jump``: largest relative change of
    the revolution duration between consecutive revolutions.  ``synchronous``: a periodic run of sharp edges puts
    its marks on samples (the DAQ clock is locked to the rotor; default) or, False, in the middle of their common
    1/Q-sample ambiguity (an asynchronous clock at a speed that happens to be rational: error within +-1/(2Q)
    sample instead of 0 or up to 1/Q).  Raises :class:`KeyphasorError`.
    """
    fs = _check_rate(sample_rate)
    p = _check_pulse(pulse)
    if edge not in ('rising', 'falling'):
        raise KeyphasorError(f"keyphasor: edge must be 'rising' or 'falling', got {edge!r}")
    if edge == 'falling':
        p = -p
    lo, hi, noise = _levels(p)
    k = _edges(p, lo, hi)
    if k.size < 2:
        raise KeyphasorError(f'keyphasor: found {k.size} key mark(s) in {p.size} samples, need at least 2 '
                             '(is the column a once-per-revolution pulse train, and the record >= 1 revolution?)')
    _check_spacing(k.astype(float), max_jump, slack=1.0)
    before, after = p[k - 1], p[k]
    tol = LEVEL_TOL * (hi - lo)
    resolved = (np.minimum(before, after) > lo + tol) & (np.maximum(before, after) < hi - tol)   # both on the edge
    if np.mean(resolved) >= 0.5:
        mid = 0.5 * (lo + hi)
        index = k - (after - mid) / (after - before)
        sigma = np.where(resolved, math.sqrt(2.0) * noise / np.abs(after - before), SIGMA_UNIFORM_1)
        return KeyMarks(index, sigma, np.zeros(k.size, bool), 'ramp', fs)
    index, sigma, locked = _sharp_marks(k, synchronous)
    return KeyMarks(index, sigma, locked, 'sharp', fs)


def continued_angle(angle, stamp, prev_angle: float, prev_stamp, speed: float, sample_rate: float) -> np.ndarray:
    """
    Return a block's angles ``angle`` (n,) [rad] moved by the whole number of turns that continues ``prev_angle``.

    ``prev_angle`` [rad] is the previous block's last sample, taken at ``prev_stamp`` [s]; ``stamp`` [s] is this
    block's first sample; ``speed`` [rad/s] the speed between them.  The first sample is put nearest to
    ``prev_angle + speed * dt`` (dt from the stamps; one sample period when a stamp is missing or implausible --
    not in [1 / sample_rate, 1000 s]).  A whole number of turns changes no phase; an angle already continuous
    moves by none.  Right while the speed error times dt stays below half a turn.  One rule for every route that
    joins blocks (a bag read offline, the identifier node's stream).
    """
    a = np.asarray(angle, dtype=float)
    if not a.size or not math.isfinite(prev_angle):
        return a
    dt = math.nan if stamp is None or prev_stamp is None else float(stamp) - float(prev_stamp)
    dt = dt if math.isfinite(dt) and 1.0 / sample_rate <= dt <= 1e3 else 1.0 / sample_rate
    w = speed if math.isfinite(speed) else 0.0
    return a + 2 * np.pi * np.round((prev_angle + w * dt - a[0]) / (2 * np.pi))


def angle_from_marks(mark_times, n_samples: int, sample_rate: float, *, max_jump: float = MAX_JUMP) -> np.ndarray:
    """
    Rotor angle (n_samples,) [rad] at t = i / sample_rate from key-mark times (m,) [s] (0 = first sample).

    2 pi per mark interval, linear between marks, extrapolated at both ends with the nearest revolution's speed;
    unwrapped, 0 at the first mark.
    """
    e, n = _check_marks(mark_times, n_samples, sample_rate, max_jump)
    idx = np.arange(n, dtype=float)
    angle = TWO_PI * np.interp(idx, e, np.arange(e.size, dtype=float))
    before, after = idx < e[0], idx > e[-1]
    angle[before] = TWO_PI * (idx[before] - e[0]) / (e[1] - e[0])
    angle[after] = TWO_PI * ((e.size - 1) + (idx[after] - e[-1]) / (e[-1] - e[-2]))
    return angle


def speed_from_marks(mark_times, n_samples: int, sample_rate: float, *, max_jump: float = MAX_JUMP) -> np.ndarray:
    """
    Return the rotor speed (n_samples,) [rad/s].

    Each revolution's mean speed at its middle, linear between, constant beyond the first and last middles.
    """
    e, n = _check_marks(mark_times, n_samples, sample_rate, max_jump)
    per_rev = TWO_PI * float(sample_rate) / np.diff(e)
    mids = 0.5 * (e[:-1] + e[1:])
    return np.interp(np.arange(n, dtype=float), mids, per_rev)


def angle_from_keyphasor(pulses, sample_rate: float, *, edge: str = 'rising', max_jump: float = MAX_JUMP,
                         synchronous: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """
    Rotor angle [rad] and speed [rad/s] per sample (N,) from a once-per-revolution pulse train (N,).

    The key marks (:func:`key_marks`, same keywords) are angle 2 pi m; :func:`angle_from_marks` and
    :func:`speed_from_marks`.
    """
    marks = key_marks(pulses, sample_rate, edge=edge, max_jump=max_jump, synchronous=synchronous)
    n = np.asarray(pulses).size
    return (angle_from_marks(marks.times, n, sample_rate, max_jump=math.inf),
            speed_from_marks(marks.times, n, sample_rate, max_jump=math.inf))


def pulse_from_angle(angle, speed=None, *, width: float = DEFAULT_WIDTH, rise_time: float = 0.0) -> np.ndarray:
    """
    Return the keyphasor pulse (N,) in [0, 1] of the convention for the rotor angle (N,) [rad] of each sample.

    ``rise_time`` = 0: high (1.0) while angle mod 2 pi is in [0, width) (an angle within ``ON_MARK_REV`` revolution
    below a multiple of 2 pi, float rounding, counts as on the mark).  ``rise_time`` > 0 [s]: linear edges of that
    duration centred on the mark and on the end of the pulse (``speed`` (N,) [rad/s] > 0 converts to time).
    """
    a = np.asarray(angle, dtype=float)
    if not 0.0 < width < math.pi:
        raise ValueError(f'pulse width must be in (0, pi) rad, got {width}')
    rev = a / TWO_PI
    f = rev - np.floor(rev + ON_MARK_REV)          # in [-ON_MARK_REV, 1): revolutions since the last mark
    w = width / TWO_PI
    if rise_time <= 0.0:
        return (f < w).astype(float)
    s = np.broadcast_to(np.asarray(speed, dtype=float), a.shape)
    if not np.all(s > 0):
        raise ValueError('pulse_from_angle: a finite rise_time needs a positive speed at every sample')
    d = np.where(f >= 0.5, f - 1.0, f) * TWO_PI / s  # s from the nearest mark (negative before it)
    level = np.minimum(0.5 + d / rise_time, 0.5 - (d - width / s) / rise_time)
    return np.clip(level, 0.0, 1.0)


# ------------------------------------------------------------------------------------------------ input checks
def _check_rate(sample_rate) -> float:
    fs = float(sample_rate)
    if not (math.isfinite(fs) and fs > 0):
        raise KeyphasorError(f'keyphasor: sample_rate must be a positive number [Hz], got {sample_rate!r}')
    return fs


def _check_pulse(pulse) -> np.ndarray:
    p = np.asarray(pulse, dtype=float)
    if p.ndim != 1:
        raise KeyphasorError(f'keyphasor: the pulse must be one column (N,), got shape {p.shape}')
    bad = np.flatnonzero(~np.isfinite(p))
    if bad.size:
        raise KeyphasorError(f'keyphasor: {bad.size} non-finite value(s) (NaN/inf), the first at sample {bad[0]}')
    if p.size == 0 or np.ptp(p) == 0:
        raise KeyphasorError(f'keyphasor: the column is constant ({p.size} samples'
                             f"{', all ' + format(p[0], 'g') if p.size else ''}): no pulses")
    return p


def _check_marks(mark_times, n_samples, sample_rate, max_jump) -> tuple[np.ndarray, int]:
    fs = _check_rate(sample_rate)
    e = np.asarray(mark_times, dtype=float).reshape(-1) * fs
    n = int(n_samples)
    if n < 1:
        raise KeyphasorError(f'keyphasor: n_samples must be >= 1, got {n_samples}')
    if e.size < 2:
        raise KeyphasorError(f'keyphasor: {e.size} key mark(s), need at least 2')
    bad = np.flatnonzero(~np.isfinite(e))
    if bad.size:
        raise KeyphasorError(f'keyphasor: key-mark time {bad[0]} is not finite')
    _check_spacing(e, max_jump, slack=0.0)
    return e, n


def _check_spacing(e: np.ndarray, max_jump: float, slack: float) -> None:
    """Check that marks (m,) [samples] increase and consecutive revolutions differ by <= max_jump (+ slack samples)."""
    d = np.diff(e)
    bad = np.flatnonzero(d <= 0)
    if bad.size:
        i = bad[0]
        raise KeyphasorError(f'keyphasor: key marks must increase; mark {i + 1} (sample {e[i + 1]:.1f}) is not '
                             f'after mark {i} (sample {e[i]:.1f})')
    jump = np.flatnonzero(np.abs(d[1:] - d[:-1]) > max_jump * d[:-1] + slack)
    if jump.size:
        i = jump[0]
        raise KeyphasorError(
            f'keyphasor: the revolution from sample {e[i + 1]:.0f} to {e[i + 2]:.0f} lasts {d[i + 1]:.1f} samples, '
            f'the one before {d[i]:.1f} ({100 * (d[i + 1] / d[i] - 1):+.0f} %, limit {100 * max_jump:.0f} %): '
            f"a key-mark pulse {'missing' if d[i + 1] > d[i] else 'too many'} "
            f'around samples {e[i + 1]:.0f}-{e[i + 2]:.0f}?')


# ------------------------------------------------------------------------------------------------ edges
def _levels(p: np.ndarray) -> tuple[float, float, float]:
    """
    Return the low and high level of the pulse and the level noise.

    The levels are the medians of the samples below / above the mid range; the noise is a 1-sigma, the pooled robust
    spread of the samples near each level.
    """
    mid0 = 0.5 * (p.min() + p.max())
    low, high = p[p <= mid0], p[p > mid0]
    lo, hi = float(np.median(low)), float(np.median(high))
    tol = LEVEL_TOL * (hi - lo)
    dev = np.concatenate([low[low < lo + tol] - lo, high[high > hi - tol] - hi])
    noise = 1.4826 * float(np.median(np.abs(dev))) if dev.size else 0.0
    return lo, hi, noise


def _edges(p: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """
    Return the first sample at or above the mid level of each rising edge (int (m,)).

    An edge must go from below 25 % to above 75 % of the swing, and the last crossing of the mid level before it reaches
    75 % is taken.  A sample exactly at the mid level is on the mark (a linear edge centred on a mark that falls on a
    sample).
    """
    sw = hi - lo
    state = np.where(p < lo + HYSTERESIS * sw, -1, np.where(p > hi - HYSTERESIS * sw, 1, 0))
    nz = np.flatnonzero(state)
    s = state[nz]
    j = nz[1:][(s[:-1] == -1) & (s[1:] == 1)]
    below = np.flatnonzero(p < lo + 0.5 * sw)
    return below[np.searchsorted(below, j) - 1] + 1


# ------------------------------------------------------------------------------------------------ sharp edges
def _sharp_marks(k: np.ndarray, synchronous: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Find marks, sigma, locked for first-high samples k (int (m,)): greedy constant-speed runs (module docstring)."""
    index, sigma, locked = np.empty(k.size), np.empty(k.size), np.zeros(k.size, bool)
    s = 0
    while s < k.size:
        e = _longest_run(k, s)
        index[s:e], sigma[s:e], locked[s:e] = _run_marks(k[s:e], synchronous)
        s = e
    return index, sigma, locked


def _longest_run(k: np.ndarray, s: int) -> int:
    """Largest e such that marks s..e-1 are consistent with one constant speed (>= s + 1)."""
    n = k.size
    good, size = min(s + 2, n), 4
    while s + size < n and _feasible(k[s:s + size]):
        good, size = s + size, 2 * size
    if s + size >= n and _feasible(k[s:]):
        return n
    bad = min(s + size, n)
    while bad - good > 1:
        mid = (good + bad) // 2
        good, bad = (mid, bad) if _feasible(k[s:mid]) else (good, mid)
    return good


def _feasible(k: np.ndarray) -> bool:
    return k.size <= 2 or _min_width(k - k[0])[0] < _FEASIBLE


def _hull_slopes(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the slopes dy/dx of the edges of the convex hull of the points (i, y_i), i = 0..L-1.

    Reduced integer numerators, denominators; sorted by value, unique (Andrew's monotone chain).
    """
    lower: list[tuple[int, int]] = []
    upper: list[tuple[int, int]] = []
    for x, v in enumerate(y.tolist()):
        for hull, sign in ((lower, 1), (upper, -1)):
            while len(hull) >= 2:
                (x0, y0), (x1, y1) = hull[-2], hull[-1]
                if sign * ((x1 - x0) * (v - y0) - (y1 - y0) * (x - x0)) > 0:
                    break
                hull.pop()
            hull.append((x, v))
    pairs = set()
    for hull in (lower, upper):
        for (x0, y0), (x1, y1) in zip(hull[:-1], hull[1:]):
            g = math.gcd(y1 - y0, x1 - x0)
            pairs.add(((y1 - y0) // g, (x1 - x0) // g))
    num, den = (np.array(v, dtype=np.int64) for v in zip(*sorted(pairs, key=lambda q: q[0] / q[1])))
    return num, den


def _width(y: np.ndarray, x: np.ndarray, b) -> np.ndarray:
    """Vertical width max(y - b x) - min(y - b x) for each slope in b."""
    r = y[None, :] - np.atleast_1d(b)[:, None] * x[None, :]
    return r.max(axis=1) - r.min(axis=1)


def _min_width(y: np.ndarray):
    """
    (minimal vertical width, index of its slope, slopes (float), numerators, denominators) for points (i, y_i).

    The width is convex and piecewise linear in the slope with its breakpoints at the hull-edge slopes: binary
    search over them.
    """
    num, den = _hull_slopes(y)
    slopes = num / den
    x = np.arange(y.size, dtype=float)
    yf = y.astype(float)
    lo, hi = 0, slopes.size - 1
    while lo < hi:
        m = (lo + hi) // 2
        w = _width(yf, x, slopes[m:m + 2])
        lo, hi = (m + 1, hi) if w[1] < w[0] else (lo, m)
    return float(_width(yf, x, slopes[lo])[0]), lo, slopes, num, den


def _crossing(yf, x, slopes, best: int, side: int) -> float:
    """Slope beyond slopes[best] on ``side`` (-1 left, +1 right) where the vertical width reaches 1."""
    order = slopes[:best][::-1] if side < 0 else slopes[best + 1:]
    b0, w0 = slopes[best], float(_width(yf, x, slopes[best])[0])
    for b in order:
        w = float(_width(yf, x, b)[0])
        if w >= 1.0:
            return b0 + (1.0 - w0) * (b - b0) / (w - w0)
        b0, w0 = b, w
    b = b0 + side * 1.0                            # beyond the last breakpoint the width is linear
    w = float(_width(yf, x, b)[0])
    return b0 + (1.0 - w0) * (b - b0) / (w - w0)


def _run_marks(k: np.ndarray, synchronous: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return marks, sigma, locked of one constant-speed run of first-high samples k (int (L,))."""
    L = k.size
    if L <= 2:
        return k - 0.5, np.full(L, SIGMA_UNIFORM_1), np.zeros(L, bool)
    y = (k - k[0]).astype(np.int64)
    x = np.arange(L, dtype=np.int64)
    width, best, slopes, num, den = _min_width(y)
    bottom, top = _feasible_range(y.astype(float), x.astype(float), slopes, best)
    sigma = (top - bottom) * SIGMA_UNIFORM_1
    P, Q = int(num[best]), int(den[best])
    r = y * Q - P * x                              # exact residues, Q (y - b x) at b = P / Q
    if int(np.ptp(r)) == Q - 1 and L >= max(LOCK_MIN_MARKS, LOCK_MIN_PERIODS * Q):
        offset = r.min() if synchronous else r.min() - 0.5      # on the samples, or the middle of the 1/Q cell
        return k[0] + (offset + P * x) / Q, sigma, np.ones(L, bool)
    return k[0] + 0.5 * (top + bottom), sigma, np.zeros(L, bool)


def _feasible_range(yf: np.ndarray, xf: np.ndarray, slopes: np.ndarray, best: int) -> tuple[np.ndarray, np.ndarray]:
    """
    Earliest and latest position (L,) of each mark over all lines through every interval (y_i - 1, y_i].

    The feasible lines (slope b, offset a) form a polygon between a_hi(b) = min(y - b x) and a_lo(b) =
    max(y - b x) - 1, over the slopes where the vertical width is <= 1; a mark's extremes are at its vertices.
    """
    b_lo, b_hi = _crossing(yf, xf, slopes, best, -1), _crossing(yf, xf, slopes, best, +1)
    cand = np.concatenate([[b_lo], slopes[(slopes > b_lo) & (slopes < b_hi)], [b_hi]])
    res = yf[None, :] - cand[:, None] * xf[None, :]
    line = cand[:, None] * xf[None, :]
    top = (res.min(axis=1)[:, None] + line).max(axis=0)
    bottom = (res.max(axis=1)[:, None] - 1.0 + line).min(axis=0)
    return np.maximum(bottom, yf - 1.0), np.minimum(top, yf)
