"""
Harmonic vectors (1X, nX, given sub-synchronous ratios) of a window against the keyphasor angle; slow roll.

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

Transient-aware fit (``transients=N`` > 0)
    Lightly damped rotor modes ringing after a speed change are fitted jointly with the harmonics as up to N
    decaying sinusoids whose rates and frequencies are found in the data (:mod:`bearing_id.signals.transient`); the
    std of X then includes their uncertainty.  With no component kept the result is the plain fit.

Steady windows and the speed are in :mod:`bearing_id.signals.windows`, sub-synchronous lines in
:mod:`bearing_id.signals.subsync`.

Units: samples in metres (any unit works: X, offset and std come back in the same unit), angle in rad, rates in Hz.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from .transient import exp_outer, fit_decaying_modes, uniform_step
from .windows import steady_windows

TWO_PI = 2.0 * math.pi


# ------------------------------------------------------------------------------------------------ input checks
def as_2d(samples) -> np.ndarray:
    """Return ``samples`` as a float array (N, nch); (N,) becomes (N, 1); ValueError for other shapes."""
    x = np.asarray(samples, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise ValueError(f'samples must be (N, nch), got shape {x.shape}')
    return x


def check_angle(angle, n) -> np.ndarray:
    """
    Return the keyphasor ``angle`` [rad] as a float array (n,), unwrapped if it was wrapped to 0..2 pi.

    ValueError when it has not n values, holds NaN/inf, or does not increase (the shaft turns one way).
    """
    a = np.asarray(angle, dtype=float).reshape(-1)
    if a.size != n:
        raise ValueError(f'angle has {a.size} values but samples have {n} rows')
    bad = int(np.count_nonzero(~np.isfinite(a)))
    if bad:
        raise ValueError(f'angle holds {bad} non-finite value(s) (NaN/inf); the keyphasor angle must be complete')
    d = np.diff(a)
    if np.any(d < 0):
        a = np.unwrap(a)           # a wrapped (0..2 pi) keyphasor angle: unwrap it
        if np.any(np.diff(a) < 0):
            raise ValueError('angle must increase with time (the shaft turns one way; unwrapped angle expected)')
    return a


def finite_rows(samples, nonfinite: str = 'raise') -> np.ndarray:
    """Boolean mask (N,) of sample rows with every channel finite; raises on NaN/inf if ``nonfinite='raise'``."""
    x = as_2d(samples)
    ok = np.all(np.isfinite(x), axis=1)
    nbad = int(np.count_nonzero(~np.isfinite(x)))
    if nbad:
        if nonfinite == 'raise':
            raise ValueError(f'samples hold {nbad} non-finite value(s) (NaN/inf) in {int(np.count_nonzero(~ok))} '
                             f"row(s); clean them or pass nonfinite='drop'")
        if nonfinite != 'drop':
            raise ValueError(f"nonfinite must be 'raise' or 'drop', got {nonfinite!r}")
    return ok


# ------------------------------------------------------------------------------------------------ harmonic fit
@dataclass(frozen=True)
class HarmonicFit:
    """
    Least-squares harmonic vectors of one window.

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
    transient_rates : complex (m,) lambda = -s + j w [1/s] of the decaying components kept (``transients`` > 0),
        s > 0 the decay rate, w the angular frequency [rad/s]; empty when none was kept.
    transient_X : complex (m, nch) their amplitudes at ``transient_t0`` [s]: x_tr = Re{A exp(lambda (t - t0))}.
    transient_rejected : candidate components tried and rejected (not significant or not decaying).
    plain : when decaying components were kept, the plain regression of the same samples (a HarmonicFit without
        them, what ``transients=0`` returns); None when none was kept (the fit is then the plain one).

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
    transient_rates: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=complex))
    transient_X: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=complex))
    transient_t0: float = 0.0
    transient_rejected: int = 0
    plain: 'HarmonicFit | None' = field(default=None, repr=False)

    def transient_part(self, t) -> np.ndarray:
        """
        Return the fitted decaying components at times ``t`` (M,) [s] (same clock as the fit's ``t``): (M, nch).

        x_tr(t) = sum_m Re{transient_X[m] exp(transient_rates[m] (t - transient_t0))}; zeros when none was kept.
        """
        tt = np.asarray(t, dtype=float).reshape(-1) - self.transient_t0
        if self.transient_rates.size == 0:
            return np.zeros((tt.size, self.X.shape[1]))
        z = exp_outer(tt, self.transient_rates, uniform_step(tt))
        return z.real @ self.transient_X.real - z.imag @ self.transient_X.imag

    def __iter__(self):
        yield self.X
        yield self.std

    @property
    def amplitude(self) -> np.ndarray:
        """|X| (n_orders, nch)."""
        return np.abs(self.X)

    @property
    def phase(self) -> np.ndarray:
        """Phase arg X [rad] (n_orders, nch)."""
        return np.angle(self.X)


def whole_revolutions(angle) -> tuple[int, int, int]:
    """
    (i0, i1, n_rev): the longest prefix of ``angle`` [rad, unwrapped] spanning a whole number of revolutions.

    Samples i0..i1-1 satisfy angle - angle[i0] < 2 pi n_rev, so the window covers n_rev full turns (to one sample).
    """
    a = np.asarray(angle, dtype=float)
    span = a[-1] - a[0]
    # the last sample stands for a full sample interval of rotation
    step = span / max(a.size - 1, 1)
    n_rev = int(math.floor((span + step) / TWO_PI + 1e-9))
    if n_rev < 1:
        raise ValueError(f'the window covers {span / TWO_PI:.3f} revolution(s); at least one whole revolution '
                         f'is needed')
    i1 = int(np.searchsorted(a - a[0], TWO_PI * n_rev - 0.5 * step, side='left'))
    return 0, max(i1, 1), n_rev


def harmonic_vectors(samples, angle, orders=(1,), *, subsync=None, whole_revs: bool = True,
                     nonfinite: str = 'raise', transients: int = 0, t=None, sample_rate=None) -> HarmonicFit:
    """
    Harmonic vectors of ``samples`` (N, nch) [m] against the keyphasor ``angle`` (N,) [rad].

    Parameters
    ----------
    samples
        (N, nch) or (N,) displacement [m].
    angle
        (N,) keyphasor rotor angle [rad], unwrapped (a wrapped 0..2 pi angle is unwrapped here).
    orders
        harmonic orders k (1 = 1X, 2 = 2X, ...); non-integer values are allowed but not orthogonal.
    subsync
        None, a ratio or a sequence of ratios (frequency / speed, e.g. 0.45) fitted in the same regression
        (so that a known sub-synchronous whirl does not leak into the nX vectors); returned as ``X_sub``.
    whole_revs
        trim the window to a whole number of revolutions (default True).
    nonfinite
        'raise' (default) or 'drop' NaN/inf sample rows (see module docstring).
    transients
        at most this many exponentially decaying sinusoids fitted jointly with the harmonics (0 = the
        plain fit); see "Transient-aware fit" in the module docstring.  Needs ``t`` or ``sample_rate``.
    t
        (N,) sample times [s] (only used with ``transients``); default ``arange(N) / sample_rate``.
    sample_rate
        Hz (used when ``t`` is not given).

    Returns
    -------
    HarmonicFit (X complex (n_orders, nch) with x = offset + sum_k Re{X_k e^{j k angle}}, 1-sigma std, offset,
    residual RMS, the kept decaying components, ...).

    """
    x = as_2d(samples)
    a = check_angle(angle, x.shape[0])
    orders = tuple(float(k) if not float(k).is_integer() else int(k) for k in np.atleast_1d(orders))
    if len(orders) == 0:
        raise ValueError('orders must hold at least one harmonic order')
    if any(k <= 0 for k in orders):
        raise ValueError(f'harmonic orders must be positive, got {orders}')
    sub = () if subsync is None else tuple(float(r) for r in np.atleast_1d(subsync))
    transients = int(transients)
    if transients < 0:
        raise ValueError(f'transients must be >= 0, got {transients}')
    tt = None
    if transients:
        if t is not None:
            tt = np.asarray(t, dtype=float).reshape(-1)
            if tt.size != x.shape[0]:
                raise ValueError(f't has {tt.size} values but samples have {x.shape[0]} rows')
        elif sample_rate is not None and float(sample_rate) > 0:
            tt = np.arange(x.shape[0]) / float(sample_rate)
        else:
            raise ValueError('a transient-aware fit (transients > 0) needs the sample times t or the sample_rate')
    if whole_revs:
        i0, i1, n_rev = whole_revolutions(a)
    else:
        i0, i1, n_rev = 0, x.shape[0], int((a[-1] - a[0]) // TWO_PI)
    x, a = x[i0:i1], a[i0:i1]
    tt = tt[i0:i1] if tt is not None else None
    ok = finite_rows(x, nonfinite)
    n_dropped = int(np.count_nonzero(~ok))
    if n_dropped:
        x, a = x[ok], a[ok]
        tt = tt[ok] if tt is not None else None
    ratios = np.array(list(orders) + list(sub), dtype=float)
    nr = ratios.size
    npar = 1 + 2 * nr
    if x.shape[0] <= npar:
        raise ValueError(f'{x.shape[0]} samples cannot determine {npar} parameters')
    ph = np.outer(a, ratios)                       # (N, nr), absolute keyphasor angle
    D = np.empty((x.shape[0], npar))
    D[:, 0] = 1.0
    D[:, 1::2] = np.cos(ph)
    D[:, 2::2] = np.sin(ph)
    del ph                                         # (N, nr): not held through the fits below
    coef, *_ = np.linalg.lstsq(D, x, rcond=None)        # (npar, nch)
    resid = x - D @ coef
    dof = x.shape[0] - npar
    sigma2 = np.sum(resid**2, axis=0) / dof              # (nch,)
    cov_unit = np.linalg.inv(D.T @ D)                    # (npar, npar), times sigma2 per channel
    var_all = np.diag(cov_unit)[:, None] * sigma2[None, :]        # (npar, nch)

    def result(coef, resid, var_all, **kw) -> HarmonicFit:
        c, s = coef[1:npar:2], coef[2:npar:2]            # x = c cos + s sin = Re{(c - j s) e^{j phi}}
        Xall = c - 1j * s
        var_c, var_s = var_all[1:npar:2], var_all[2:npar:2]
        std_re, std_im = np.sqrt(var_c), np.sqrt(var_s)
        std = np.sqrt(var_c + var_s)
        no = len(orders)
        return HarmonicFit(X=Xall[:no], std=std[:no], std_re=std_re[:no], std_im=std_im[:no], offset=coef[0],
                           residual_rms=np.sqrt(np.mean(resid**2, axis=0)), orders=orders, X_sub=Xall[no:],
                           std_sub=std[no:], subsync=sub, n_revolutions=n_rev, i0=i0, i1=i1, n_dropped=n_dropped,
                           **kw)

    empty = np.zeros((0, x.shape[1]), dtype=complex)            # no decaying component
    if not (transients and x.shape[0] > 4 * npar + 16):
        return result(coef, resid, var_all, transient_X=empty)
    t0 = float(tt[0])
    speed_hz = abs(a[-1] - a[0]) / TWO_PI / max(tt[-1] - tt[0], 1e-300)
    tr = fit_decaying_modes(x, D, tt - t0, speed_hz, ratios, transients, coef0=coef)
    if not tr['rates'].size:
        return result(coef, resid, var_all, transient_X=empty, transient_t0=t0, transient_rejected=tr['rejected'])
    return result(tr['coef'], tr['resid'], tr['var'], transient_rates=tr['rates'], transient_X=tr['A'],
                  transient_t0=t0, transient_rejected=tr['rejected'],
                  plain=result(coef, resid, var_all, transient_X=empty))


# ------------------------------------------------------------------------------------------------ slow roll
def slow_roll_compensate(X, X_slow_roll):
    """Runout-compensated vectors X - X_slow_roll (complex, broadcasting; same order and channel layout)."""
    return np.asarray(X) - np.asarray(X_slow_roll)


def slow_roll_vector(samples, angle, t, speed, max_speed: float, orders=(1,), *, tol_rel: float = 0.005,
                     min_duration: float = 0.5, nonfinite: str = 'raise') -> HarmonicFit:
    """
    Slow-roll (runout) vectors: harmonic vectors over the steady windows with |speed| <= ``max_speed``.

    Each steady window below ``max_speed`` [same unit as speed] is fitted on its own; the windows are combined with
    inverse-variance weights (X and std per order and channel).  The result is subtracted from running-speed vectors
    with :func:`slow_roll_compensate`.  Raises ValueError if no steady window lies below ``max_speed``.
    """
    x = as_2d(samples)
    w = np.asarray(speed, dtype=float)
    fits = []
    for i0, i1 in steady_windows(t, w, tol_rel=tol_rel, min_duration=min_duration):
        if np.nanmax(np.abs(w[i0:i1])) <= max_speed:
            fits.append(harmonic_vectors(x[i0:i1], np.asarray(angle)[i0:i1], orders, nonfinite=nonfinite))
    if not fits:
        raise ValueError(f'no steady window at or below {max_speed} (speed unit) to estimate the slow roll from')
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
