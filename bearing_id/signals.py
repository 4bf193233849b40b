"""Harmonic vectors (1X, nX, sub-synchronous) from a displacement stream with a keyphasor, steady windows, slow roll.

Phasor rule (:mod:`bearing_id.conventions`): the order-k component of a channel is ``Re{X_k exp(j k phi)}`` with phi
the keyphasor rotor angle [rad]; a fit returns ``x(t) = offset + sum_k Re{X_k exp(j k phi(t))} + residual``.

Why regress on the measured angle
    The regressors are cos(k phi) and sin(k phi) of the *measured* angle, not of omega t, so a slowly varying speed
    changes nothing: the component stays locked to the rotor.  The window is trimmed to a whole number of revolutions
    (from the angle) so that the offset and the harmonics are (nearly) orthogonal and a constant offset does not leak.

Non-finite samples
    ``nonfinite='raise'`` (default) refuses NaN/inf with a ValueError that names how many samples are bad;
    ``nonfinite='drop'`` removes the sample rows (all channels of that instant) that hold a NaN/inf before the fit and
    reports the count in ``HarmonicFit.n_dropped``.  Numbers are never produced silently from bad samples.

Units: samples in metres (any unit works: X, offset and std come back in the same unit), angle in rad, rates in Hz.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .conventions import whirl_direction

TWO_PI = 2.0 * math.pi


# ------------------------------------------------------------------------------------------------ input checks
def _as_2d(samples) -> np.ndarray:
    x = np.asarray(samples, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise ValueError(f"samples must be (N, nch), got shape {x.shape}")
    return x


def _check_angle(angle, n) -> np.ndarray:
    a = np.asarray(angle, dtype=float).reshape(-1)
    if a.size != n:
        raise ValueError(f"angle has {a.size} values but samples have {n} rows")
    bad = int(np.count_nonzero(~np.isfinite(a)))
    if bad:
        raise ValueError(f"angle holds {bad} non-finite value(s) (NaN/inf); the keyphasor angle must be complete")
    d = np.diff(a)
    if np.any(d < 0):
        a = np.unwrap(a)           # a wrapped (0..2 pi) keyphasor angle: unwrap it
        if np.any(np.diff(a) < 0):
            raise ValueError("angle must increase with time (the shaft turns one way; unwrapped angle expected)")
    return a


def finite_rows(samples, nonfinite: str = "raise") -> np.ndarray:
    """Boolean mask (N,) of sample rows with every channel finite; raises on NaN/inf if ``nonfinite='raise'``."""
    x = _as_2d(samples)
    ok = np.all(np.isfinite(x), axis=1)
    nbad = int(np.count_nonzero(~np.isfinite(x)))
    if nbad:
        if nonfinite == "raise":
            raise ValueError(f"samples hold {nbad} non-finite value(s) (NaN/inf) in {int(np.count_nonzero(~ok))} "
                             f"row(s); clean them or pass nonfinite='drop'")
        if nonfinite != "drop":
            raise ValueError(f"nonfinite must be 'raise' or 'drop', got {nonfinite!r}")
    return ok


# ------------------------------------------------------------------------------------------------ harmonic fit
@dataclass(frozen=True)
class HarmonicFit:
    """Least-squares harmonic vectors of one window.

    Attributes
    ----------
    X : complex (n_orders, nch), phasors with x = offset + sum_k Re{X_k exp(j k angle)} [unit of samples].
    std : (n_orders, nch), 1-sigma complex standard deviation sqrt(E|X_hat - X|^2) from the residual
        (each of Re and Im has about std / sqrt(2) over whole revolutions).
    std_re, std_im : (n_orders, nch) 1-sigma of Re X and Im X.
    offset : (nch,) mean value (DC) [unit of samples].
    residual_rms : (nch,) RMS of the fit residual.
    orders : the harmonic orders fitted.
    X_sub, std_sub : complex (n_sub, nch) / (n_sub, nch) for the ``subsync`` ratios (empty if none).
    subsync : the sub-synchronous ratios fitted.
    n_revolutions : whole revolutions used.  i0, i1 : sample range used (half open).  n_dropped : rows removed.

    ``X, std = fit`` unpacks as in docs/ARCHITECTURE.md.
    """
    X: np.ndarray
    std: np.ndarray
    std_re: np.ndarray
    std_im: np.ndarray
    offset: np.ndarray
    residual_rms: np.ndarray
    orders: tuple
    X_sub: np.ndarray
    std_sub: np.ndarray
    subsync: tuple
    n_revolutions: int
    i0: int
    i1: int
    n_dropped: int = 0

    def __iter__(self):
        yield self.X
        yield self.std

    @property
    def amplitude(self) -> np.ndarray:
        """|X| (n_orders, nch)."""
        return np.abs(self.X)

    @property
    def phase(self) -> np.ndarray:
        """arg X [rad] (n_orders, nch)."""
        return np.angle(self.X)


def whole_revolutions(angle) -> tuple[int, int, int]:
    """(i0, i1, n_rev): the longest prefix of ``angle`` [rad, unwrapped] spanning a whole number of revolutions.

    Samples i0..i1-1 satisfy angle - angle[i0] < 2 pi n_rev, so the window covers n_rev full turns (to one sample).
    """
    a = np.asarray(angle, dtype=float)
    span = a[-1] - a[0]
    # the last sample stands for a full sample interval of rotation
    step = span / max(a.size - 1, 1)
    n_rev = int(math.floor((span + step) / TWO_PI + 1e-9))
    if n_rev < 1:
        raise ValueError(f"the window covers {span / TWO_PI:.3f} revolution(s); at least one whole revolution "
                         f"is needed")
    i1 = int(np.searchsorted(a - a[0], TWO_PI * n_rev - 0.5 * step, side="left"))
    return 0, max(i1, 1), n_rev


def harmonic_vectors(samples, angle, orders=(1,), *, subsync=None, whole_revs: bool = True,
                     nonfinite: str = "raise") -> HarmonicFit:
    """Harmonic vectors of ``samples`` (N, nch) [m] against the keyphasor ``angle`` (N,) [rad].

    Parameters
    ----------
    samples : (N, nch) or (N,) displacement [m].
    angle : (N,) keyphasor rotor angle [rad], unwrapped (a wrapped 0..2 pi angle is unwrapped here).
    orders : harmonic orders k (1 = 1X, 2 = 2X, ...); non-integer values are allowed but not orthogonal.
    subsync : None, a ratio or a sequence of ratios (frequency / speed, e.g. 0.45) fitted in the same regression
        (so that a known sub-synchronous whirl does not leak into the nX vectors); returned as ``X_sub``.
    whole_revs : trim the window to a whole number of revolutions (default True).
    nonfinite : 'raise' (default) or 'drop' NaN/inf sample rows (see module docstring).

    Returns
    -------
    HarmonicFit (X complex (n_orders, nch) with x = offset + sum_k Re{X_k e^{j k angle}}, 1-sigma std, offset,
    residual RMS, ...).
    """
    x = _as_2d(samples)
    a = _check_angle(angle, x.shape[0])
    orders = tuple(float(k) if not float(k).is_integer() else int(k) for k in np.atleast_1d(orders))
    if len(orders) == 0:
        raise ValueError("orders must hold at least one harmonic order")
    if any(k <= 0 for k in orders):
        raise ValueError(f"harmonic orders must be positive, got {orders}")
    sub = () if subsync is None else tuple(float(r) for r in np.atleast_1d(subsync))
    if whole_revs:
        i0, i1, n_rev = whole_revolutions(a)
    else:
        i0, i1, n_rev = 0, x.shape[0], int((a[-1] - a[0]) // TWO_PI)
    x, a = x[i0:i1], a[i0:i1]
    ok = finite_rows(x, nonfinite)
    n_dropped = int(np.count_nonzero(~ok))
    if n_dropped:
        x, a = x[ok], a[ok]
    ratios = np.array(list(orders) + list(sub), dtype=float)
    nr = ratios.size
    npar = 1 + 2 * nr
    if x.shape[0] <= npar:
        raise ValueError(f"{x.shape[0]} samples cannot determine {npar} parameters")
    ph = np.outer(a, ratios)                       # (N, nr), absolute keyphasor angle
    D = np.empty((x.shape[0], npar))
    D[:, 0] = 1.0
    D[:, 1::2] = np.cos(ph)
    D[:, 2::2] = np.sin(ph)
    coef, *_ = np.linalg.lstsq(D, x, rcond=None)        # (npar, nch)
    resid = x - D @ coef
    dof = x.shape[0] - npar
    sigma2 = np.sum(resid**2, axis=0) / dof              # (nch,)
    cov_unit = np.linalg.inv(D.T @ D)                    # (npar, npar), times sigma2 per channel
    c, s = coef[1::2], coef[2::2]                        # x = c cos + s sin = Re{(c - j s) e^{j phi}}
    Xall = c - 1j * s
    var_c = np.diag(cov_unit)[1::2][:, None] * sigma2[None, :]
    var_s = np.diag(cov_unit)[2::2][:, None] * sigma2[None, :]
    std_re, std_im = np.sqrt(var_c), np.sqrt(var_s)
    std = np.sqrt(var_c + var_s)
    no = len(orders)
    return HarmonicFit(X=Xall[:no], std=std[:no], std_re=std_re[:no], std_im=std_im[:no], offset=coef[0],
                       residual_rms=np.sqrt(np.mean(resid**2, axis=0)), orders=orders, X_sub=Xall[no:],
                       std_sub=std[no:], subsync=sub, n_revolutions=n_rev, i0=i0, i1=i1, n_dropped=n_dropped)


# ------------------------------------------------------------------------------------------------ steady windows
def steady_windows(t, speed, tol_rel: float = 0.005, min_duration: float = 0.5) -> list[tuple[int, int]]:
    """Sample ranges (i0, i1) (half open) where the speed is constant within ``tol_rel``.

    A window is a maximal run in which max(speed) - min(speed) <= tol_rel * |mean speed| (greedy from the start);
    windows shorter than ``min_duration`` [s] are dropped.  Non-finite speeds break windows.

    Parameters: t (N,) s, speed (N,) rad/s (or rpm: only ratios matter).
    """
    t = np.asarray(t, dtype=float).reshape(-1)
    w = np.asarray(speed, dtype=float).reshape(-1)
    if t.size != w.size:
        raise ValueError(f"t has {t.size} values but speed has {w.size}")
    if tol_rel <= 0:
        raise ValueError(f"tol_rel must be > 0, got {tol_rel}")
    out = []
    n = w.size
    i0 = 0
    while i0 < n:
        if not np.isfinite(w[i0]):
            i0 += 1
            continue
        seg = w[i0:]
        fin = np.isfinite(seg)
        stop = int(np.argmin(fin)) if not fin.all() else seg.size
        seg = seg[:stop]
        hi = np.maximum.accumulate(seg)
        lo = np.minimum.accumulate(seg)
        ref = np.abs(np.cumsum(seg) / np.arange(1, seg.size + 1))
        br = np.nonzero(hi - lo > tol_rel * np.maximum(ref, 1e-300))[0]
        length = int(br[0]) if br.size else seg.size
        length = max(length, 1)
        i1 = i0 + length
        if i1 - 1 > i0 and t[i1 - 1] - t[i0] + (t[i1 - 1] - t[i0]) / (i1 - 1 - i0) >= min_duration:
            out.append((i0, i1))
        i0 = i1
    return out


# ------------------------------------------------------------------------------------------------ slow roll
def slow_roll_compensate(X, X_slow_roll):
    """Runout-compensated vectors X - X_slow_roll (complex, broadcasting; same order and channel layout)."""
    return np.asarray(X) - np.asarray(X_slow_roll)


def slow_roll_vector(samples, angle, t, speed, max_speed: float, orders=(1,), *, tol_rel: float = 0.005,
                     min_duration: float = 0.5, nonfinite: str = "raise") -> HarmonicFit:
    """Slow-roll (runout) vectors: harmonic vectors over the steady windows with |speed| <= ``max_speed``.

    Each steady window below ``max_speed`` [same unit as speed] is fitted on its own; the windows are combined with
    inverse-variance weights (X and std per order and channel).  The result is subtracted from running-speed vectors
    with :func:`slow_roll_compensate`.  Raises ValueError if no steady window lies below ``max_speed``.
    """
    x = _as_2d(samples)
    w = np.asarray(speed, dtype=float)
    fits = []
    for i0, i1 in steady_windows(t, w, tol_rel=tol_rel, min_duration=min_duration):
        if np.nanmax(np.abs(w[i0:i1])) <= max_speed:
            fits.append(harmonic_vectors(x[i0:i1], np.asarray(angle)[i0:i1], orders, nonfinite=nonfinite))
    if not fits:
        raise ValueError(f"no steady window at or below {max_speed} (speed unit) to estimate the slow roll from")
    if len(fits) == 1:
        return fits[0]
    wts = np.array([1.0 / np.maximum(f.std, 1e-300) ** 2 for f in fits])
    X = np.sum(wts * np.array([f.X for f in fits]), axis=0) / wts.sum(axis=0)
    std = 1.0 / np.sqrt(wts.sum(axis=0))
    f0 = fits[0]
    return HarmonicFit(X=X, std=std, std_re=std / math.sqrt(2), std_im=std / math.sqrt(2),
                       offset=np.mean([f.offset for f in fits], axis=0),
                       residual_rms=np.sqrt(np.mean([f.residual_rms**2 for f in fits], axis=0)), orders=f0.orders,
                       X_sub=f0.X_sub[:0], std_sub=f0.std_sub[:0], subsync=(),
                       n_revolutions=sum(f.n_revolutions for f in fits), i0=f0.i0, i1=fits[-1].i1,
                       n_dropped=sum(f.n_dropped for f in fits))


# ------------------------------------------------------------------------------------------------ sub-synchronous
@dataclass(frozen=True)
class SubsyncComponent:
    """The strongest sub-synchronous component of a window.

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


def _fit_sinusoid(x, tt, f):
    D = np.column_stack([np.ones_like(tt), np.cos(TWO_PI * f * tt), np.sin(TWO_PI * f * tt)])
    coef, *_ = np.linalg.lstsq(D, x, rcond=None)
    return coef[1] - 1j * coef[2], float(np.sum((x - D @ coef) ** 2))


def subsynchronous(samples, angle, sample_rate: float, *, ratio_range=(0.05, 0.95), sync_orders=(1, 2, 3),
                   xy=(0, 1)) -> SubsyncComponent:
    """Strongest sub-synchronous component of ``samples`` (N, nch) [m] with keyphasor ``angle`` (N,) [rad].

    Method: the synchronous orders ``sync_orders`` are fitted and removed (:func:`harmonic_vectors`), the residual is
    Hann-windowed and Fourier transformed, the channel-summed power peak with frequency ratio inside ``ratio_range``
    (ratio = f / mean speed) is found and refined by a least-squares sinusoid fit (golden search on f), which gives
    the phasor per channel.  ``xy`` = (i_x, i_y) channel indices of an x/y probe pair for the whirl direction
    (None to skip).  Needs evenly sampled data: NaN/inf samples are refused (ValueError with the count).
    """
    x = _as_2d(samples)
    a = _check_angle(angle, x.shape[0])
    finite_rows(x, "raise")
    fs = float(sample_rate)
    n = x.shape[0]
    tt = np.arange(n) / fs
    speed_hz = (a[-1] - a[0]) / TWO_PI / (tt[-1] if n > 1 else 1.0)
    if speed_hz <= 0:
        raise ValueError("the rotor does not turn in this window")
    fit = harmonic_vectors(x, a, sync_orders, whole_revs=False)
    ph = np.outer(a, np.asarray(fit.orders, dtype=float))
    resid = x - fit.offset - np.real(np.exp(1j * ph) @ fit.X)
    win = np.hanning(n)
    spec = np.abs(np.fft.rfft(resid * win[:, None], axis=0)) / (np.sum(win) / 2)      # amplitude spectrum
    freqs = np.fft.rfftfreq(n, 1 / fs)
    band = (freqs >= ratio_range[0] * speed_hz) & (freqs <= ratio_range[1] * speed_hz)
    if np.count_nonzero(band) < 3:
        raise ValueError("the window is too short to resolve sub-synchronous frequencies; use more revolutions")
    power = np.sum(spec**2, axis=1)
    idx = np.nonzero(band)[0]
    k = idx[int(np.argmax(power[idx]))]
    df = freqs[1] - freqs[0]

    def cost(f):
        return sum(_fit_sinusoid(resid[:, c], tt, f)[1] for c in range(x.shape[1]))

    lo, hi = freqs[k] - df, freqs[k] + df
    g = (math.sqrt(5) - 1) / 2
    c1, c2 = hi - g * (hi - lo), lo + g * (hi - lo)
    f1, f2 = cost(c1), cost(c2)
    for _ in range(40):
        if f1 < f2:
            hi, c2, f2 = c2, c1, f1
            c1 = hi - g * (hi - lo)
            f1 = cost(c1)
        else:
            lo, c1, f1 = c1, c2, f2
            c2 = lo + g * (hi - lo)
            f2 = cost(c2)
    f = 0.5 * (lo + hi)
    X = np.array([_fit_sinusoid(resid[:, c], tt, f)[0] for c in range(x.shape[1])])
    floor = np.median(np.sqrt(power[idx]))
    whirl = None
    if xy is not None and x.shape[1] > max(xy):
        whirl = whirl_direction(X[xy[0]], X[xy[1]])
    return SubsyncComponent(ratio=float(f / speed_hz), frequency=float(f), X=X, amplitude=np.abs(X), whirl=whirl,
                            snr=float(np.sqrt(power[k]) / max(floor, 1e-300)))
