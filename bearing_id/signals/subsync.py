"""
The strongest sub-synchronous line of a window (oil whirl, rub, a mode excited below running speed).

The synchronous orders are fitted and removed (:func:`bearing_id.signals.harmonics.harmonic_vectors`), the residual
is Hann-windowed and Fourier transformed, the channel-summed power peak inside a band of frequency ratios
(f / mean speed) is found and refined by a least-squares sinusoid fit whose frequency is found by golden-section
search (:class:`SinusoidCost`, moments computed once per window).  The component is not locked to the rotor: its
phasors are relative to the window start.  Samples in m (any unit: X comes back in it), angle rad, rates Hz.
"""
from __future__ import annotations

import cmath
from dataclasses import dataclass
import math

import numpy as np

from .harmonics import as_2d, check_angle, finite_rows, harmonic_vectors
from ..conventions import whirl_direction

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class SubsyncComponent:
    """
    The strongest sub-synchronous component of a window.

    ratio : frequency / mean running speed.  frequency : Hz.  X : complex (nch,) phasors at that frequency,
    x = Re{X exp(j 2 pi f (t - t0))} (phase relative to the window start, not to the keyphasor: the component is not
    locked to the rotor).  amplitude : |X| (nch,).  whirl : 'forward' / 'backward' from the (x, y) pair, or None.
    snr : peak amplitude / median amplitude of the residual spectrum in the searched band (amplitude ratio).
    """

    ratio: float
    frequency: float
    X: np.ndarray
    amplitude: np.ndarray
    whirl: str | None
    snr: float


SUBSYNC_GOLDEN_STEPS = 40       # golden-section steps refining the peak frequency within +-1 FFT bin
SUBSYNC_TAYLOR_TERMS = 32       # terms of the series in the frequency offset (truncation < 1e-19 of sum |x|)


def _subsync_spectrum(samples, angle, sample_rate: float, sync_orders):
    """
    Return the first step of the sub-synchronous search: the window without its synchronous orders and its spectrum.

    The samples with the synchronous orders fitted and removed (:func:`harmonic_vectors` over the whole window),
    Hann-windowed and Fourier transformed: dict with ``x`` (N, nch) [m], ``resid`` (N, nch) [m], ``fs`` [Hz],
    ``speed_hz`` (mean running speed [Hz]), ``freqs`` (N // 2 + 1,) [Hz], ``power`` (N // 2 + 1,) channel-summed
    squared amplitude spectrum [m^2].
    """
    x = as_2d(samples)
    a = check_angle(angle, x.shape[0])
    finite_rows(x, 'raise')
    fs = float(sample_rate)
    n = x.shape[0]
    speed_hz = (a[-1] - a[0]) / TWO_PI / ((n - 1) / fs if n > 1 else 1.0)
    if speed_hz <= 0:
        raise ValueError('the rotor does not turn in this window')
    fit = harmonic_vectors(x, a, sync_orders, whole_revs=False)
    ph = np.outer(a, np.asarray(fit.orders, dtype=float))
    resid = x - fit.offset - np.real(np.exp(1j * ph) @ fit.X)
    win = np.hanning(n)
    spec = np.abs(np.fft.rfft(resid * win[:, None], axis=0)) / (np.sum(win) / 2)      # amplitude spectrum
    return {'x': x, 'resid': resid, 'fs': fs, 'speed_hz': speed_hz,
            'freqs': np.fft.rfftfreq(n, 1 / fs), 'power': np.sum(spec**2, axis=1)}


def _subsync_peak(sp, ratio_range):
    """Return (k, idx): the FFT bin of the channel-summed power peak within ``ratio_range`` and the band's bins."""
    freqs, power, speed_hz = sp['freqs'], sp['power'], sp['speed_hz']
    band = (freqs >= ratio_range[0] * speed_hz) & (freqs <= ratio_range[1] * speed_hz)
    if np.count_nonzero(band) < 3:
        raise ValueError('the window is too short to resolve sub-synchronous frequencies; use more revolutions')
    idx = np.nonzero(band)[0]
    return idx[int(np.argmax(power[idx]))], idx


def _golden_min(cost, lo, hi) -> float:
    """Return the midpoint of [lo, hi] after ``SUBSYNC_GOLDEN_STEPS`` golden-section steps on the unimodal ``cost``."""
    g = (math.sqrt(5) - 1) / 2
    c1, c2 = hi - g * (hi - lo), lo + g * (hi - lo)
    f1, f2 = cost(c1), cost(c2)
    for _ in range(SUBSYNC_GOLDEN_STEPS):
        if f1 < f2:
            hi, c2, f2 = c2, c1, f1
            c1 = hi - g * (hi - lo)
            f1 = cost(c1)
        else:
            lo, c1, f1 = c1, c2, f2
            c2 = lo + g * (hi - lo)
            f2 = cost(c2)
    return 0.5 * (lo + hi)


def _geometric_sum(theta: float, n: int) -> complex:
    """Return sum_{k=0}^{n-1} exp(j theta k) in closed form (exp(j theta (n-1)/2) sin(n theta/2) / sin(theta/2))."""
    s = math.sin(0.5 * theta)
    if abs(s) < 1e-300:
        return complex(n)
    return cmath.exp(0.5j * theta * (n - 1)) * (math.sin(0.5 * n * theta) / s)


class SinusoidCost:
    """
    The sinusoid-fit cost, all channels at once: sum_c min ||x_c - d_c - a_c cos(2 pi f t) - b_c sin(2 pi f t)||^2.

    For f = f0 + delta with |delta| <= max_offset (the search's bracket: one FFT bin each side of f0).  The normal
    equations of the 3-column fit need, per channel, sum x_c, sum x_c^2 (constants) and S_c(f) = sum_k x_c[k]
    exp(-j 2 pi f t_k); the Gram matrix of [1, cos, sin] needs sum exp(j 2 pi f t_k) and sum exp(j 4 pi f t_k), both
    geometric series (closed form, the samples are evenly spaced).  S_c is a power series in delta:
    S_c(f) = exp(-j 2 pi f t_c) sum_m (-j a)^m / m! M_mc with u_k = (t_k - t_c) / h in [-1, 1] (t_c, h the centre
    and half-length of the window), a = 2 pi delta h (|a| <= pi) and the moments M_mc = sum_k x_c[k]
    exp(-j 2 pi f0 (t_k - t_c)) u_k^m, computed once (O(N) work once; each cost evaluation is O(nch)).
    ``SUBSYNC_TAYLOR_TERMS`` terms: the series is truncated below pi^32 / 32! ~ 3e-20 of sum |x_c|.
    """

    def __init__(self, x, fs: float, f0: float, max_offset: float):
        n, nch = x.shape
        self.n, self.fs, self.f0 = n, float(fs), float(f0)
        self.tc = 0.5 * (n - 1) / self.fs
        self.h = max(self.tc, 0.5 / self.fs)
        if TWO_PI * abs(max_offset) * self.h > math.pi * (1 + 1e-9):
            raise ValueError('frequency offset outside the range of the series')      # pragma: no cover
        k = np.arange(n)
        u = (k - 0.5 * (n - 1)) / (self.h * self.fs)
        z = x * np.exp(-1j * TWO_PI * self.f0 * (k / self.fs - self.tc))[:, None]      # (N, nch)
        V = np.empty((SUBSYNC_TAYLOR_TERMS, n))                                        # V[m] = u^m
        V[0] = 1.0
        for m in range(1, SUBSYNC_TAYLOR_TERMS):
            np.multiply(V[m - 1], u, out=V[m])
        self.mom = (V @ z.view(float)).view(complex)                                   # (M, nch)
        self.sx = np.sum(x, axis=0)
        self.sxx = float(np.sum(x * x))
        fact = np.cumprod(np.concatenate(([1.0], np.arange(1, SUBSYNC_TAYLOR_TERMS, dtype=float))))
        self.inv_fact = 1.0 / fact
        self.powers = np.arange(SUBSYNC_TAYLOR_TERMS)

    def solve(self, f: float):
        """Return (coef (3, nch) of [1, cos, sin], b (3, nch) = D^T x) at frequency f [Hz]."""
        a = TWO_PI * (f - self.f0) * self.h
        c = (-1j * a) ** self.powers * self.inv_fact                                 # (M,)
        S = cmath.exp(-1j * TWO_PI * f * self.tc) * (c @ self.mom)                     # (nch,)
        theta = TWO_PI * f / self.fs
        e1, e2 = _geometric_sum(theta, self.n), _geometric_sum(2.0 * theta, self.n)
        n = float(self.n)
        # G = D^T D of D = [1, cos, sin] (symmetric 3x3, well conditioned): solved by its adjugate
        g00, g01, g02 = n, e1.real, e1.imag
        g11, g12, g22 = 0.5 * (n + e2.real), 0.5 * e2.imag, 0.5 * (n - e2.real)
        a00, a01, a02 = g11 * g22 - g12 * g12, g02 * g12 - g01 * g22, g01 * g12 - g02 * g11
        a11, a12, a22 = g00 * g22 - g02 * g02, g01 * g02 - g00 * g12, g00 * g11 - g01 * g01
        det = g00 * a00 + g01 * a01 + g02 * a02
        b0, b1, b2 = self.sx, S.real, -S.imag
        coef = np.array([a00 * b0 + a01 * b1 + a02 * b2, a01 * b0 + a11 * b1 + a12 * b2,
                         a02 * b0 + a12 * b1 + a22 * b2]) / det
        return coef, np.array([b0, b1, b2])

    def __call__(self, f: float) -> float:
        """Return the summed residual sum of squares [m^2] of the best [1, cos, sin] fit at f [Hz]."""
        coef, b = self.solve(f)
        return self.sxx - float(np.sum(coef * b))

    def phasors(self, f: float) -> np.ndarray:
        """Return X (nch,) complex, x = Re{X exp(j 2 pi f t)} (t from the first sample), at f [Hz]."""
        coef, _ = self.solve(f)
        return coef[1] - 1j * coef[2]


def _subsync_component(sp, ratio_range, xy, cache: dict) -> SubsyncComponent:
    """Return the strongest component within ``ratio_range`` of a prepared window (:func:`_subsync_spectrum`)."""
    x, freqs, power = sp['x'], sp['freqs'], sp['power']
    k, idx = _subsync_peak(sp, ratio_range)
    if k not in cache:          # another band with the same peak bin: the same search
        df = freqs[1] - freqs[0]
        cost = SinusoidCost(sp['resid'], sp['fs'], freqs[k], df)
        f = _golden_min(cost, freqs[k] - df, freqs[k] + df)
        cache[k] = (f, cost.phasors(f))
    f, X = cache[k]
    floor = np.median(np.sqrt(power[idx]))
    whirl = None
    if xy is not None and x.shape[1] > max(xy):
        whirl = whirl_direction(X[xy[0]], X[xy[1]])
    return SubsyncComponent(ratio=float(f / sp['speed_hz']), frequency=float(f), X=X.copy(), amplitude=np.abs(X),
                            whirl=whirl, snr=float(np.sqrt(power[k]) / max(floor, 1e-300)))


def subsynchronous(samples, angle, sample_rate: float, *, ratio_range=(0.05, 0.95), sync_orders=(1, 2, 3),
                   xy=(0, 1)) -> SubsyncComponent:
    """
    Strongest sub-synchronous component of ``samples`` (N, nch) [m] with keyphasor ``angle`` (N,) [rad].

    Method: the synchronous orders ``sync_orders`` are fitted and removed (:func:`harmonic_vectors`), the residual is
    Hann-windowed and Fourier transformed, the channel-summed power peak with frequency ratio inside ``ratio_range``
    (ratio = f / mean speed) is found and refined within +-1 FFT bin by the least-squares fit of an offset and a
    sinusoid per channel (golden-section search on f of the summed residual, :class:`SinusoidCost`), which gives
    the phasor per channel.  ``xy`` = (i_x, i_y) channel indices of an x/y probe pair for the whirl direction
    (None to skip).  ``sample_rate`` [Hz].  Needs evenly sampled data: NaN/inf samples are refused (ValueError with
    the count).  :func:`subsynchronous_bands` searches several bands of one window with one synchronous fit.
    """
    return subsynchronous_bands(samples, angle, sample_rate, [ratio_range], sync_orders=sync_orders, xy=xy,
                                missing='raise')[0]


def subsynchronous_bands(samples, angle, sample_rate: float, ratio_ranges, *, sync_orders=(1, 2, 3), xy=(0, 1),
                         missing: str = 'none') -> list:
    """
    Return :func:`subsynchronous` of one window for each band of ``ratio_ranges`` (the synchronous fit done once).

    A band too narrow for three FFT bins gives None (``missing='none'``) or raises ValueError (``'raise'``); a
    window in which the rotor does not turn, or that holds NaN/inf, raises ValueError.
    """
    sp = _subsync_spectrum(samples, angle, sample_rate, sync_orders)
    out, cache = [], {}
    for band in ratio_ranges:
        try:
            out.append(_subsync_component(sp, band, xy, cache))
        except ValueError:
            if missing == 'raise':
                raise
            out.append(None)
    return out
