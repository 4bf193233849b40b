"""
Harmonic vectors (1X, nX, sub-synchronous) from a displacement stream with a keyphasor, steady windows, slow roll.

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
    After a speed change lightly damped rotor modes ring for seconds; a decaying mode near running speed (e.g. a
    33 Hz bending mode at 35 Hz running speed) is nearly collinear with 1X over a short window and biases the plain
    fit by percent, in a way that comparing window halves does not always catch.  The model becomes
    x_c(t) = offset_c + sum_k Re{X_kc e^{j k phi}} + sum_m exp(-s_m t)(a_mc cos w_m t + b_mc sin w_m t)
    with (s_m, w_m) shared by all channels of the window and t from the first sample used.  Model free: the
    components are found in the data, not from a rotor model.
    * (s, w) by variable projection: the linear coefficients are solved by least squares inside
      scipy.optimize.least_squares (Levenberg-Marquardt, Kaufman's Jacobian) over the nonlinear ones, searched on
      every q-th sample (<= TRANSIENT_MAX_POINTS points) and polished on all of them; channels weighted by their
      plain-fit residual std.
    * Greedy: candidates are the strongest peak of the channel-summed residual spectrum (Hann window) outside
      +-TRANSIENT_EXCLUDE_BINS bins around every harmonic order (and sub-synchronous ratio fitted), and frequencies
      beside each component already kept (two modes closer than the resolution, e.g. forward and backward whirl).
    * A component is kept only if it reduces the residual significantly on all samples (BIC:
      n ln(RSS_before / RSS_after) > (2 + 2 nch) ln n, n = samples x channels) and every kept decay rate is
      s > TRANSIENT_DECAY_SIGMA x its 1-sigma and s > TRANSIENT_MIN_DECAY / T (T the window length).  A significant
      but steady component (s ~ 0: a sub-synchronous whirl, an unfitted harmonic) is not a transient: it is skipped
      (use ``subsync`` / ``orders`` for those).
    * Two modes closer than the resolution 2 pi / T (forward and backward whirl of one bending mode) beat, and one
      component fitted to them can look steady; before such a component is skipped, the pair is fitted
      (:func:`_close_pair`) and kept when its second component is significant too.  Decay rates closer in frequency
      than the resolution are judged by their sum (:func:`_decays`; they are not resolved one by one).  Without
      this the pair stayed in the residual and biased a nearby 1X by ~2 sigma on every noise draw (issue 11, the
      look-alike's 1186 rpm dwell).
    * The std of X comes from the joint fit: sigma_c^2 diag(D^T D)^-1 (D = harmonics + kept components) plus the
      propagated uncertainty of (s, w) (D^+ dmodel/dp cov_p ...), so a transient nearly collinear with 1X inflates
      the std honestly.
    * With no component kept the result is the plain fit, bit for bit.
    * Fast path (:func:`_transient_fit`, the default): the same steps as the reference :func:`_transient_fit_reference`
      (kept unchanged), each variable-projection evaluation in reduced coordinates -- one QR of [D, E, t E, x] gives
      residual and Jacobian with the full ones' inner products, so Levenberg-Marquardt takes the same steps --,
      exponentials on a uniform time grid by products, all screening candidates at once (2x2 Gram matrices;
      ``_VarProFast.screen_qr``, one stacked QR, is its reference), the final joint fit from one QR, and
      Levenberg-Marquardt by :func:`bearing_id.lm.lmder` (MINPACK's lmder in numpy: scipy's steps without importing
      scipy.optimize; test/test_lm.py).  Equal to the reference to rounding (1e-9 relative tested, ~1e-13 seen;
      test/test_transient_fast.py); ``harmonic_vectors(..., transient_method='reference')`` runs the reference.
      The fits use no scipy.linalg (:mod:`bearing_id.linalg`: numpy's QR and triangular solves).
    Cost (2 channels, 1.5 s at 10240 Hz, one core): ~5 ms when nothing is found, ~15-50 ms with 2-3 components
    (reference ~50-150 ms; benchmarks/bench_transient_fit.py).

Units: samples in metres (any unit works: X, offset and std come back in the same unit), angle in rad, rates in Hz.
"""
from __future__ import annotations

import cmath
from dataclasses import dataclass, field
import math

import numpy as np
from scipy.linalg import solve_triangular
from scipy.optimize import least_squares

from ..conventions import whirl_direction

TWO_PI = 2.0 * math.pi


# ------------------------------------------------------------------------------------------------ input checks
def _as_2d(samples) -> np.ndarray:
    x = np.asarray(samples, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise ValueError(f'samples must be (N, nch), got shape {x.shape}')
    return x


def _check_angle(angle, n) -> np.ndarray:
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
    x = _as_2d(samples)
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
        z = _exp_outer(tt, self.transient_rates, _uniform_step(tt))
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
                     nonfinite: str = 'raise', transients: int = 0, t=None, sample_rate=None,
                     transient_method: str = 'fast') -> HarmonicFit:
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
    transient_method
        'fast' (default, :func:`_transient_fit`) or 'reference' (:func:`_transient_fit_reference`, the first
        implementation); the two agree to rounding (1e-9 relative, test/test_transient_fast.py).

    Returns
    -------
    HarmonicFit (X complex (n_orders, nch) with x = offset + sum_k Re{X_k e^{j k angle}}, 1-sigma std, offset,
    residual RMS, the kept decaying components, ...).

    """
    x = _as_2d(samples)
    a = _check_angle(angle, x.shape[0])
    orders = tuple(float(k) if not float(k).is_integer() else int(k) for k in np.atleast_1d(orders))
    if len(orders) == 0:
        raise ValueError('orders must hold at least one harmonic order')
    if any(k <= 0 for k in orders):
        raise ValueError(f'harmonic orders must be positive, got {orders}')
    sub = () if subsync is None else tuple(float(r) for r in np.atleast_1d(subsync))
    transients = int(transients)
    if transients < 0:
        raise ValueError(f'transients must be >= 0, got {transients}')
    if transient_method not in ('fast', 'reference'):
        raise ValueError(f"transient_method must be 'fast' or 'reference', got {transient_method!r}")
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
    tr = (_transient_fit(x, D, tt - t0, speed_hz, ratios, transients, coef0=coef) if transient_method == 'fast'
          else _transient_fit_reference(x, D, tt - t0, speed_hz, ratios, transients))
    if not tr['rates'].size:
        return result(coef, resid, var_all, transient_X=empty, transient_t0=t0, transient_rejected=tr['rejected'])
    return result(tr['coef'], tr['resid'], tr['var'], transient_rates=tr['rates'], transient_X=tr['A'],
                  transient_t0=t0, transient_rejected=tr['rejected'],
                  plain=result(coef, resid, var_all, transient_X=empty))


# ------------------------------------------------------------------------------------------------ transient-aware fit
TRANSIENT_MAX_POINTS = 2048     # the nonlinear search runs on every q-th sample (q = ceil(N / this)), then polishes
TRANSIENT_EXCLUDE_BINS = 2.0    # half-width of the band (in FFT bins) around each harmonic order not searched
TRANSIENT_DECAY_SIGMA = 2.0     # a kept component must decay: s > this x its 1-sigma ...
TRANSIENT_MIN_DECAY = 0.1       # ... and s T > this (fades by >= ~10 % over the window): slower is 'steady'
TRANSIENT_MAX_TRIES = 2         # candidates tried per allowed component (non-decaying ones are skipped)


def _decay_columns(tt, p):
    """
    E (N, 2m) = [Re z_1, Im z_1, ...] with z_m = exp((-s_m + j w_m) t); and z (N, m) complex.

    A trial step with a fast-growing component (s << 0) overflows to inf / nan without a warning: the residual is then
    not finite, and Levenberg-Marquardt rejects the step (MINPACK's rule: no actual reduction).
    """
    with np.errstate(over='ignore', invalid='ignore'):
        z = np.exp(np.outer(tt, -p[0::2] + 1j * p[1::2]))
    E = np.empty((tt.size, 2 * z.shape[1]))
    E[:, 0::2] = z.real
    E[:, 1::2] = z.imag
    return E, z


class _VarPro:
    """
    Variable projection for x = D0 b + E(p) c + noise, channels sharing p = [s_1, w_1, s_2, w_2, ...].

    ``xw`` (N, nch) is the channel-weighted data; D0 (N, L0) the fixed (harmonic) regressors.  The residual of a
    given p is the part of xw outside span(D0, E(p)); its Jacobian is Kaufman's (the marginal one of p).
    """

    def __init__(self, xw, D0, tt):
        self.Q0, _ = np.linalg.qr(D0)
        self.xp = xw - self.Q0 @ (self.Q0.T @ xw)     # data outside span(D0)
        self.tt = tt
        self._key = None

    def _proj_out(self, V, Q1):
        return V - self.Q0 @ (self.Q0.T @ V) - Q1 @ (Q1.T @ V)

    def evaluate(self, p, jac: bool = True):
        """(residual (N nch,), Kaufman Jacobian (N nch, len p) or None, linear coefficients c1 (2m, nch))."""
        key = p.tobytes()
        if key != self._key:
            E, z = _decay_columns(self.tt, p)
            Ep = E - self.Q0 @ (self.Q0.T @ E)
            Q1, R1 = np.linalg.qr(Ep)
            pr = Q1.T @ self.xp
            r = self.xp - Q1 @ pr
            try:
                c1 = solve_triangular(R1, pr)                  # (2m, nch) on [Re z, Im z]
            except np.linalg.LinAlgError:
                c1 = np.linalg.lstsq(Ep, self.xp, rcond=None)[0]
            self._key, self._state, self._J = key, (r.reshape(-1), z, c1, Q1), None
        r, z, c1, Q1 = self._state
        if jac and self._J is None:
            G = self.model_derivatives(z, c1)                  # list of (N, nch), one per p entry
            self._J = np.column_stack([-self._proj_out(g, Q1).reshape(-1) for g in G])
        return r, self._J, c1

    def model_derivatives(self, z, c1):
        """d(E c1)/dp_j (N, nch) per nonlinear parameter j."""
        out = []
        t = self.tt[:, None]
        for m in range(z.shape[1]):
            zr, zi = z[:, m:m + 1].real, z[:, m:m + 1].imag
            a, b = c1[2 * m][None, :], c1[2 * m + 1][None, :]
            part = zr * a + zi * b
            out.append(-t * part)                              # d/ds
            out.append(t * (zr * b - zi * a))                  # d/dw
        return out

    def solve(self, p0, max_nfev=40, xtol=1e-8):
        sol = least_squares(lambda p: self.evaluate(p, False)[0], p0, jac=lambda p: self.evaluate(p)[1], method='lm',
                            x_scale='jac', xtol=xtol, ftol=1e-10, gtol=1e-10, max_nfev=max_nfev)
        return sol.x


def _decays(p, J, rss, dof, T):
    """
    Return True when all decay rates s = p[0::2] are significant and fast enough.

    Each > TRANSIENT_DECAY_SIGMA x its 1-sigma (Kaufman Jacobian J) and > TRANSIENT_MIN_DECAY / T (the component fades
    by at least that fraction of an e-fold over the window T [s]).  Components closer in frequency than the resolution
    2 pi / T [rad/s] (two modes beating, e.g. the forward and backward whirl of one bending mode) are judged together:
    their rates are not resolved one by one (strongly correlated), so their sum must pass both tests (its 1-sigma
    from the covariance) and none may grow significantly (s > -TRANSIENT_DECAY_SIGMA x its 1-sigma).  A lone
    component is judged exactly as before.
    """
    cov = np.linalg.pinv(J.T @ J) * (rss / max(dof, 1))
    cs = cov[0::2, 0::2]
    s_std = np.sqrt(np.clip(np.diag(cs), 0, None))
    sd, wd = p[0::2], p[1::2]
    order = np.argsort(wd)
    groups = [[int(order[0])]]
    for i, j in zip(order[:-1], order[1:]):
        if wd[j] - wd[i] < TWO_PI / T:
            groups[-1].append(int(j))
        else:
            groups.append([int(j)])
    for g in groups:
        e = np.zeros(sd.size)
        e[g] = 1.0
        s_sum, s_sum_std = float(e @ sd), math.sqrt(max(float(e @ cs @ e), 0.0))
        if not (s_sum > len(g) * TRANSIENT_MIN_DECAY / T and s_sum > TRANSIENT_DECAY_SIGMA * s_sum_std):
            return False
        if len(g) > 1 and not np.all(sd[g] > -TRANSIENT_DECAY_SIGMA * s_std[g]):
            return False
    return True


def _peak_candidate(r, tt, speed_hz, ratios, excluded, fmax):
    """Strongest frequency [rad/s] of the channel-summed residual spectrum outside the excluded bands, or None."""
    n = r.shape[0]
    dt = (tt[-1] - tt[0]) / max(n - 1, 1)
    win = np.hanning(n)
    P = np.sum(np.abs(np.fft.rfft(r * win[:, None], axis=0)) ** 2, axis=1)
    f = np.fft.rfftfreq(n, dt)
    df = f[1] - f[0]
    ok = (f > TRANSIENT_EXCLUDE_BINS * df) & (f < fmax)
    bands = [k * speed_hz for k in range(1, int(fmax / max(speed_hz, 1e-300)) + 1)] if speed_hz > 0 else []
    bands += [float(q) * speed_hz for q in ratios if not float(q).is_integer()] + list(excluded)
    for fb in bands:
        ok &= np.abs(f - fb) > TRANSIENT_EXCLUDE_BINS * df
    ok[-1] = False
    if not np.any(ok):
        return None
    Pm = np.where(ok, P, -np.inf)
    k = int(np.argmax(Pm))
    fk = f[k]
    if 0 < k < n // 2 and np.isfinite(Pm[k - 1]) and np.isfinite(Pm[k + 1]) and min(P[k - 1], P[k + 1]) > 0:
        l0, l1, l2 = np.log(P[k - 1]), np.log(P[k]), np.log(P[k + 1])
        den = l0 - 2 * l1 + l2
        if den < 0:
            fk += 0.5 * (l0 - l2) / den * df
    return fk


TRANSIENT_PAIR_SPLIT = 0.25     # start half-separation [1/T Hz] of a pair fitted where one component did not decay


def _close_pair(coarse, full, p, p_one, rss_one, T, penalty_f, n_f, nch, L0):
    """
    Return (p with two more components, their RSS on all samples) where one component did not decay, or None.

    Two modes closer than the resolution 1/T (the forward and backward whirl of one bending mode, split by the
    gyroscopic effect) beat: one component ``p_one[-2:]`` fitted to the pair can come out steady or growing and be
    skipped as 'steady'; as its frequency is then excluded, the pair stays in the residual and biases a nearby 1X.  So
    before a significant component that does not decay is skipped, the pair is fitted (variable projection from
    starts +-TRANSIENT_PAIR_SPLIT / T Hz around its frequency, on ``coarse``; tests on ``full`` as for one
    component) and kept when the second component is significant (BIC: it reduces ``rss_one``, the RSS with the one
    component, by more than one component's ``penalty_f``) and the rates pass :func:`_decays` (a pair closer than the
    resolution is judged by its summed rate).  A steady component plus noise is not such a pair: it is still skipped.
    ``n_f`` = samples x channels of ``full``, ``nch`` channels, ``L0`` harmonic regressors (for the dof).
    """
    s0, w0, dw = max(float(p_one[-2]), 1.0 / T), float(p_one[-1]), TWO_PI * TRANSIENT_PAIR_SPLIT / T
    try:
        p2 = coarse.solve(np.concatenate([p, [s0, w0 - dw, s0, w0 + dw]]))
        r, J, _ = full.evaluate(p2)
    except (np.linalg.LinAlgError, ValueError):
        return None
    rss = float(r @ r)
    if not (np.isfinite(rss) and rss > 0 and n_f * math.log(rss_one / rss) > penalty_f):
        return None
    return (p2, rss) if _decays(p2, J, rss, n_f - nch * (L0 + p2.size) - p2.size, T) else None


def _transient_fit_reference(x, D, tt, speed_hz, ratios, max_n):
    """
    Greedy joint fit of harmonics + up to ``max_n`` decaying sinusoids (see the module docstring): the reference.

    The first implementation, kept unchanged: every evaluation of the variable projection works on the (N nch,)
    residual (:class:`_VarPro`).  :func:`_transient_fit` takes the same steps in reduced coordinates and must equal
    this to 1e-9 relative (test/test_transient_fast.py).

    Returns dict with rates (m,) complex, A (m, nch), and, when m > 0, coef (L0, nch), resid (N, nch), var (L0, nch)
    of the harmonic regressors from the joint fit's covariance (including the uncertainty of the decay rates and
    frequencies); ``rejected`` = candidates tried and refused.
    """
    N, nch = x.shape
    L0 = D.shape[1]
    out = {'rates': np.zeros(0, dtype=complex), 'rejected': 0}
    coef0, *_ = np.linalg.lstsq(D, x, rcond=None)
    r0 = x - D @ coef0
    sig0 = np.sqrt(np.sum(r0 ** 2, axis=0) / (N - L0))
    if not np.all(sig0 > 0):
        return out                                           # exact fit: nothing to explain
    w = 1.0 / sig0
    T = (tt[-1] - tt[0]) * N / max(N - 1, 1)
    q = max(1, int(math.ceil(N / TRANSIENT_MAX_POINTS)))
    full = _VarPro(x * w, D, tt)
    coarse = full if q == 1 else _VarPro(x[::q] * w, D[::q], tt[::q])
    nq = coarse.xp.shape[0]
    n_c = nq * nch
    k_new = 2 + 2 * nch                                      # parameters one component adds
    penalty = k_new * math.log(n_c)                          # BIC
    fmax = 0.4 * nq / max(tt[::q][-1] - tt[0], 1e-300)       # 80 % of the search grid's Nyquist frequency [Hz]
    rss = float(np.sum(coarse.xp ** 2))
    n_f = N * nch
    penalty_f = k_new * math.log(n_f)
    rss_f = float(np.sum(full.xp ** 2))
    p = np.zeros(0)
    excluded = []
    resid_w = coarse.xp
    tries = 0
    tried_split = False
    while p.size // 2 < max_n and tries < TRANSIENT_MAX_TRIES * max_n:
        tries += 1
        # candidate frequencies [Hz]: the strongest residual peak, and beside each kept component (two modes
        # closer than the spectral resolution, e.g. the forward and backward whirl of one bending mode)
        fk = _peak_candidate(resid_w, tt[::q], speed_hz, ratios, excluded, fmax)
        cands = [] if fk is None else [(fk, False)]
        cands += [(p[2 * i + 1] / TWO_PI + d / T, True) for i in range(p.size // 2) for d in (-0.5, 0.0, 0.5)]
        cands = [c for c in cands if all(abs(c[0] - fe) > 0.25 / T for fe in excluded)]
        if not cands:
            break
        # cheap screen: a few decay rates at each candidate frequency, linear fit only; the best one goes on.
        # A second component beside a kept one cannot be screened this way (the kept one must move as well to
        # make room: two modes closer than the resolution), so the best of those is tried once regardless.
        screen = []
        for fc, split in cands:
            for sd in (0.5 / T, 3.0 / T, 15.0 / T):
                r_s = coarse.evaluate(np.concatenate([p, [sd, TWO_PI * fc]]), False)[0]
                screen.append((float(r_s @ r_s), sd, fc, split))
        rss_s, s0, fk, split = min(screen)
        if not (rss_s > 0 and n_c * math.log(rss / rss_s) > 0.5 * penalty):
            splits = [c for c in screen if c[3]]
            if tried_split or not splits:
                break                                        # the strongest remaining candidate is noise: stop
            rss_s, s0, fk, split = min(splits)
            tried_split = True
        try:
            p_try = coarse.solve(np.concatenate([p, [s0, TWO_PI * fk]]))
            # the tests use every sample (the search grid alone would miss what only all the data resolve)
            r, J, _ = full.evaluate(p_try)
            rss_try = float(r @ r)
            significant = np.isfinite(rss_try) and rss_try > 0 and n_f * math.log(rss_f / rss_try) > penalty_f
            decays = significant and _decays(p_try, J, rss_try, n_f - nch * (L0 + p_try.size) - p_try.size, T)
        except (np.linalg.LinAlgError, ValueError):
            significant = decays = False
        if not significant:
            break
        if not decays:                  # two close modes beating, or a steady (non-synchronous) component: skip it
            pair = (_close_pair(coarse, full, p, p_try, rss_try, T, penalty_f, n_f, nch, L0)
                    if p.size // 2 + 2 <= max_n else None)
            if pair is None:
                excluded.append(fk)
                out['rejected'] += 1
                continue
            p_try, rss_try = pair
        p, rss_f = p_try, rss_try
        r_c = coarse.evaluate(p, False)[0]
        rss = float(r_c @ r_c)
        resid_w = r_c.reshape(nq, nch)
        tried_split = False
    if p.size and q > 1:                                     # polish on every sample
        try:
            p_full = full.solve(p, max_nfev=10, xtol=1e-10)
            r, J, _ = full.evaluate(p_full)
            if _decays(p_full, J, float(r @ r), N * nch - nch * (L0 + p.size) - p.size, T):
                p = p_full
        except (np.linalg.LinAlgError, ValueError):
            pass
    if p.size == 0:
        return out
    # final joint fit at p: linear coefficients and their covariance including the uncertainty of p
    E, z = _decay_columns(tt, p)
    Dfull = np.hstack([D, E])
    L = Dfull.shape[1]
    coef, *_ = np.linalg.lstsq(Dfull, x, rcond=None)          # (L, nch)
    resid = x - Dfull @ coef
    m2 = p.size
    dof = N - L - m2 / nch
    sigma2 = np.sum(resid ** 2, axis=0) / dof                  # (nch,)
    G = full.model_derivatives(z, coef[L0:])                   # unweighted d model / dp_j, (N, nch) each
    Qf, Rf = np.linalg.qr(Dfull)
    Gp = [g - Qf @ (Qf.T @ g) for g in G]
    info = np.array([[np.sum(gi * gj / sigma2[None, :]) for gj in Gp] for gi in Gp])
    cov_p = np.linalg.pinv(info)
    cov_unit = np.linalg.inv(Rf.T @ Rf)
    # d coef_c / dp = -D^+ G_c : (L, m2) per channel;  var = sigma_c^2 diag(D^T D)^-1 + diag(B cov_p B^T)
    Gst = np.stack(G, axis=-1)                                 # (N, nch, m2)
    B = -solve_triangular(Rf, Qf.T @ Gst.reshape(N, -1)).reshape(L, nch, m2)
    var = np.diag(cov_unit)[:, None] * sigma2[None, :] + np.einsum('lcj,jk,lck->lc', B, cov_p, B)
    A = coef[L0::2] - 1j * coef[L0 + 1::2]                      # Re{A z} = a Re z + b Im z
    out.update(rates=-p[0::2] + 1j * p[1::2], A=A, coef=coef[:L0], resid=resid, var=var[:L0], cov_p=cov_p)
    return out


# ------------------------------------------------------------------------------------------------ transient fit, fast
def _uniform_step(tt):
    """Return the step dt [s] of ``tt`` when it is a uniform grid to rounding (a few ulps), else None."""
    n = tt.size
    if n < 64:
        return None
    dt = (tt[-1] - tt[0]) / (n - 1)
    if not dt > 0:
        return None
    dev = np.max(np.abs(tt - (tt[0] + dt * np.arange(n))))
    return dt if dev <= 16 * np.finfo(float).eps * max(abs(tt[0]), abs(tt[-1])) else None


def _exp_outer(tt, lam, dt=None):
    """
    Return z = exp(outer(tt, lam)) (N, m) complex; cheap on a uniform grid (``dt`` the step from _uniform_step).

    On a uniform grid z[i B + j] = exp(lam (tt[0] + j dt)) exp(lam i B dt): 2 sqrt(N) m exponentials and N m products
    instead of N m exponentials; the two differ by rounding (~|lam t| eps).  Overflow (a trial step with a
    fast-growing component) gives inf / nan quietly, as in :func:`_decay_columns`.
    """
    with np.errstate(over='ignore', invalid='ignore'):
        if dt is None:
            return np.exp(np.outer(tt, lam))
        n = tt.size
        b = int(math.ceil(math.sqrt(n)))
        nb = -(-n // b)
        fine = np.exp(np.outer(tt[0] + dt * np.arange(b), lam))             # (b, m)
        coarse = np.exp(np.outer(dt * b * np.arange(nb), lam))              # (nb, m)
        return (coarse[:, None, :] * fine[None, :, :]).reshape(nb * b, lam.size)[:n]


def _qr_r(A, overwrite: bool = False):
    """Return R (k, k) of the thin QR of A (N, k), N >= k (LAPACK dgeqrf through numpy, Q not formed; A kept)."""
    return np.linalg.qr(A, mode='r')


class _VarProFast(_VarPro):
    """
    The variable projection of :class:`_VarPro` in reduced coordinates: the same least-squares problem, cheaper.

    For p = (s_m, w_m) the residual r_c = P x_c and the Kaufman Jacobian columns -P (d model_c / dp_j) of every
    channel c (P the projector out of span(D0, E), E = [Re z, Im z]) lie in the span of [D0, E, T, x] with T = t E
    (d z / dp = -t z, j t z).  One QR (R only) of A = [D0, E, T, x] (N, L0 + 4m + nch) gives their coordinates in an
    orthonormal basis of that span; dropping the first L0 + 2m rows of R projects out span(D0, E).  The reduced
    residual (nch (2m + nch),) and Jacobian have the inner products (r^T r, J^T J, J^T r, the column norms) of the
    full (N nch,) ones, and those are all Levenberg-Marquardt uses, so it takes the same steps (to rounding).  Cost
    per evaluation: one (N, L0 + 4m + nch) QR and N m complex products (uniform grid) instead of N m exponentials,
    two QR and 2m projections of (N, nch) arrays.
    """

    def __init__(self, xw, D0, tt):
        super().__init__(xw, D0, tt)
        self.dt = _uniform_step(tt)
        self.xw, self.D0 = xw, D0
        self._buf = None             # (N, k) Fortran-ordered work array, reused by every evaluation

    def evaluate(self, p, jac: bool = True):
        """(reduced residual (nch (2m + nch),), reduced Jacobian (nch (2m + nch), len p), coefficients c1 (2m, nch))."""
        key = p.tobytes()
        if key != self._key:
            E = _exp_outer(self.tt, -p[0::2] + 1j * p[1::2], self.dt).view(float)     # (N, 2m) [Re z, Im z]
            n, m2 = E.shape
            L0, nch = self.D0.shape[1], self.xw.shape[1]
            L = L0 + m2
            if self._buf is None or self._buf.shape[1] < L + m2 + nch:
                self._buf = np.empty((n, L + m2 + nch), order='F')
            A = self._buf[:, :L + m2 + nch]                            # F-contiguous: QR'd in place
            A[:, :L0] = self.D0
            A[:, L0:L] = E
            np.multiply(E, self.tt[:, None], out=A[:, L:L + m2])
            A[:, L + m2:] = self.xw
            R = _qr_r(A, overwrite=True)
            try:
                c1 = solve_triangular(R[:L, :L], R[:L, L + m2:])[L0:]        # (2m, nch) on [Re z, Im z]
            except np.linalg.LinAlgError:
                Ep = E - self.Q0 @ (self.Q0.T @ E)
                c1 = np.linalg.lstsq(Ep, self.xp, rcond=None)[0]
            rho = R[L:, L + m2:]                                       # (2m + nch, nch): residual coordinates
            RT = R[L:, L:L + m2]                                       # P T coordinates (rows past 2m are 0)
            a, b = c1[0::2], c1[1::2]                                  # (m, nch)
            J = np.empty((m2 + nch, nch, m2))
            J[:, :, 0::2] = np.transpose(RT[:, 0::2, None] * a + RT[:, 1::2, None] * b, (0, 2, 1))      # -P d/ds
            J[:, :, 1::2] = np.transpose(RT[:, 1::2, None] * a - RT[:, 0::2, None] * b, (0, 2, 1))      # -P d/dw
            self._key, self._state = key, (rho.reshape(-1), J.reshape(-1, m2), c1)
        r, J, c1 = self._state
        return r, (J if jac else None), c1

    def _screen_basis(self, p, rates):
        """Return (xr (N, nch), En (N, 2k)): data and candidate columns projected out of span(D0, E(p)) (twice)."""
        if p.size:
            B = np.hstack([self.D0, _exp_outer(self.tt, -p[0::2] + 1j * p[1::2], self.dt).view(float)])
        else:
            B = self.D0
        Qb, _ = np.linalg.qr(B)
        xr = self.xw - Qb @ (Qb.T @ self.xw)
        xr -= Qb @ (Qb.T @ xr)
        rates = np.asarray(rates, dtype=float).reshape(-1, 2)
        En = _exp_outer(self.tt, -rates[:, 0] + 1j * rates[:, 1], self.dt).view(float)   # (N, 2k)
        En = En - Qb @ (Qb.T @ En)
        En -= Qb @ (Qb.T @ En)
        return xr, En

    def screen(self, p, rates) -> np.ndarray:
        """
        Return the residual sum of squares (k,) of the linear fit at [p, s_i, w_i] for every ``rates`` row (k, 2).

        What ``evaluate(concatenate([p, rates[i]]))`` gives as r^T r, for all candidates at once: the candidates'
        columns e_i (2 each) and the data are projected out of span(D0, E(p)) (twice, for orthogonality); then
        RSS_i = |P x|^2 - tr(h_i^T G_i^-1 h_i) with the 2x2 Gram matrix G_i = (P e_i)^T P e_i and h_i = (P e_i)^T P x
        (one matrix product for all candidates).  :meth:`screen_qr` (one stacked QR of [P e_i, P x]) is the
        reference; they agree to rounding (the subtraction loses digits only when a candidate explains nearly all
        of P x, ~eps |P x|^2 / RSS_i; test/test_transient_fast.py).  The screen only ranks candidates.
        """
        xr, En = self._screen_basis(p, rates)
        C = En.T @ np.hstack([En, xr])                                  # (2k, 2k + nch)
        k = En.shape[1] // 2
        i0, i1 = np.arange(0, 2 * k, 2), np.arange(1, 2 * k, 2)
        g11, g12, g22 = C[i0, i0], C[i0, i1], C[i1, i1]
        h1, h2 = C[i0, 2 * k:], C[i1, 2 * k:]                          # (k, nch)
        det = g11 * g22 - g12 * g12
        if not np.all(det > 1e-12 * g11 * g22):     # a candidate (nearly) inside span(D0, E(p)): the QR route
            return self.screen_qr(p, rates)
        explained = np.sum(g22[:, None] * h1 * h1 - 2 * g12[:, None] * h1 * h2 + g11[:, None] * h2 * h2, axis=1) / det
        return float(np.sum(xr * xr)) - explained

    def screen_qr(self, p, rates) -> np.ndarray:
        """Return what :meth:`screen` returns by one stacked QR of [P e_i, P x] (k, N, 2 + nch): the reference."""
        xr, En = self._screen_basis(p, rates)
        n, nch = xr.shape
        S = np.empty((En.shape[1] // 2, n, 2 + nch))
        S[:, :, :2] = np.transpose(En.reshape(n, -1, 2), (1, 0, 2))
        S[:, :, 2:] = xr
        R = np.linalg.qr(S, mode='r')
        return np.sum(R[:, 2:, 2:] ** 2, axis=(1, 2))

    def solve(self, p0, max_nfev=40, xtol=1e-8):
        """
        Return p minimising the residual from ``p0``: :meth:`_VarPro.solve`'s Levenberg-Marquardt without scipy.

        :func:`bearing_id.lm.lmder` is MINPACK's lmder (what ``least_squares(method='lm')`` runs) in numpy, so the
        fast fit takes the reference's steps without importing scipy.optimize (test/test_lm.py).
        """
        return least_squares(lambda p: self.evaluate(p, False)[0], p0, jac=lambda p: self.evaluate(p)[1], method='lm',
                             xtol=xtol, ftol=1e-10, gtol=1e-10, max_nfev=max_nfev).x

    def time_residual(self, p) -> np.ndarray:
        """Return the residual (N, nch) in the time domain at p (as :meth:`_VarPro.evaluate` gives it)."""
        E, _ = _decay_columns(self.tt, p)
        Q1, _ = np.linalg.qr(E - self.Q0 @ (self.Q0.T @ E))
        return self.xp - Q1 @ (Q1.T @ self.xp)


def _joint_fit_fast(x, D, tt, p, dt=None):
    """
    Return the final joint fit of :func:`_transient_fit_reference` at p from one QR.

    Returns coef (L, nch), resid (N, nch), var (L, nch), cov_p (2m, 2m) with L = L0 + 2m.  One QR of [D, E, T, x]
    (T = t E, the derivatives' basis) gives the least-squares coefficients, the projections of
    the model derivatives out of span(D, E) (their coordinates in the rows past L) and D_full^+ dmodel/dp.
    """
    N, nch = x.shape
    L0 = D.shape[1]
    z = _exp_outer(tt, -p[0::2] + 1j * p[1::2], dt)
    m = z.shape[1]
    m2 = 2 * m
    L = L0 + m2
    A = np.empty((N, L + m2 + nch), order='F')
    A[:, :L0] = D
    A[:, L0:L:2] = z.real
    A[:, L0 + 1:L:2] = z.imag
    A[:, L:L + m2] = A[:, L0:L] * tt[:, None]
    A[:, L + m2:] = x
    R = _qr_r(A)
    Rf = R[:L, :L]
    coef = solve_triangular(Rf, R[:L, L + m2:])                      # (L, nch)
    resid = x - A[:, :L] @ coef
    dof = N - L - m2 / nch
    sigma2 = np.sum(resid ** 2, axis=0) / dof                        # (nch,)
    # d model_c / dp_j = T v_jc: v for d/ds_m = -(a_mc, b_mc), for d/dw_m = (b_mc, -a_mc) on (Re tz_m, Im tz_m)
    a, b = coef[L0::2], coef[L0 + 1::2]                              # (m, nch)
    V = np.zeros((m2, nch, m2))                                      # (T column, channel, parameter)
    for k in range(m):
        V[2 * k, :, 2 * k], V[2 * k + 1, :, 2 * k] = -a[k], -b[k]
        V[2 * k, :, 2 * k + 1], V[2 * k + 1, :, 2 * k + 1] = b[k], -a[k]
    Gp = np.einsum('it,tcj->icj', R[L:L + m2, L:L + m2], V)         # projected derivatives' coordinates
    info = np.einsum('icj,ick,c->jk', Gp, Gp, 1.0 / sigma2)
    cov_p = np.linalg.pinv(info)
    Rinv = solve_triangular(Rf, np.eye(L))
    cov_unit_diag = np.sum(Rinv ** 2, axis=1)                        # diag (Rf^T Rf)^-1
    B = -solve_triangular(Rf, np.einsum('lt,tcj->lcj', R[:L, L:L + m2], V).reshape(L, -1)).reshape(L, nch, m2)
    var = cov_unit_diag[:, None] * sigma2[None, :] + np.einsum('lcj,jk,lck->lc', B, cov_p, B)
    return coef, resid, var, cov_p


def _transient_fit(x, D, tt, speed_hz, ratios, max_n, coef0=None):
    """
    Greedy joint fit of harmonics + up to ``max_n`` decaying sinusoids (see the module docstring).

    The steps, tests and result of :func:`_transient_fit_reference` (to rounding), with every variable-projection
    evaluation in reduced coordinates (:class:`_VarProFast`), exponentials on a uniform grid by products, and the final
    joint fit from one QR (:func:`_joint_fit_fast`).  ``coef0``: the plain fit's coefficients lstsq(D, x) when the
    caller has them (:func:`harmonic_vectors`).

    Returns dict with rates (m,) complex, A (m, nch), and, when m > 0, coef (L0, nch), resid (N, nch), var (L0, nch)
    of the harmonic regressors from the joint fit's covariance (including the uncertainty of the decay rates and
    frequencies); ``rejected`` = candidates tried and refused.
    """
    N, nch = x.shape
    L0 = D.shape[1]
    out = {'rates': np.zeros(0, dtype=complex), 'rejected': 0}
    if coef0 is None:
        coef0, *_ = np.linalg.lstsq(D, x, rcond=None)
    r0 = x - D @ coef0
    sig0 = np.sqrt(np.sum(r0 ** 2, axis=0) / (N - L0))
    if not np.all(sig0 > 0):
        return out                                           # exact fit: nothing to explain
    w = 1.0 / sig0
    T = (tt[-1] - tt[0]) * N / max(N - 1, 1)
    q = max(1, int(math.ceil(N / TRANSIENT_MAX_POINTS)))
    full = _VarProFast(x * w, D, tt)
    coarse = full if q == 1 else _VarProFast(x[::q] * w, D[::q], tt[::q])
    nq = coarse.xp.shape[0]
    n_c = nq * nch
    k_new = 2 + 2 * nch                                      # parameters one component adds
    penalty = k_new * math.log(n_c)                          # BIC
    fmax = 0.4 * nq / max(tt[::q][-1] - tt[0], 1e-300)       # 80 % of the search grid's Nyquist frequency [Hz]
    rss = float(np.sum(coarse.xp ** 2))
    n_f = N * nch
    penalty_f = k_new * math.log(n_f)
    rss_f = float(np.sum(full.xp ** 2))
    p = np.zeros(0)
    excluded = []
    resid_w = coarse.xp
    tries = 0
    tried_split = False
    while p.size // 2 < max_n and tries < TRANSIENT_MAX_TRIES * max_n:
        tries += 1
        fk = _peak_candidate(resid_w, tt[::q], speed_hz, ratios, excluded, fmax)
        cands = [] if fk is None else [(fk, False)]
        cands += [(p[2 * i + 1] / TWO_PI + d / T, True) for i in range(p.size // 2) for d in (-0.5, 0.0, 0.5)]
        cands = [c for c in cands if all(abs(c[0] - fe) > 0.25 / T for fe in excluded)]
        if not cands:
            break
        trial = [(sd, fc, split) for fc, split in cands for sd in (0.5 / T, 3.0 / T, 15.0 / T)]
        rss_all = coarse.screen(p, [(sd, TWO_PI * fc) for sd, fc, _ in trial])      # all candidates at once
        screen = [(float(v), sd, fc, split) for v, (sd, fc, split) in zip(rss_all, trial)]
        rss_s, s0, fk, split = min(screen)
        if not (rss_s > 0 and n_c * math.log(rss / rss_s) > 0.5 * penalty):
            splits = [c for c in screen if c[3]]
            if tried_split or not splits:
                break
            rss_s, s0, fk, split = min(splits)
            tried_split = True
        try:
            p_try = coarse.solve(np.concatenate([p, [s0, TWO_PI * fk]]))
            r, J, _ = full.evaluate(p_try)
            rss_try = float(r @ r)
            significant = np.isfinite(rss_try) and rss_try > 0 and n_f * math.log(rss_f / rss_try) > penalty_f
            decays = significant and _decays(p_try, J, rss_try, n_f - nch * (L0 + p_try.size) - p_try.size, T)
        except (np.linalg.LinAlgError, ValueError):
            significant = decays = False
        if not significant:
            break
        if not decays:                  # two close modes beating, or a steady (non-synchronous) component: skip it
            pair = (_close_pair(coarse, full, p, p_try, rss_try, T, penalty_f, n_f, nch, L0)
                    if p.size // 2 + 2 <= max_n else None)
            if pair is None:
                excluded.append(fk)
                out['rejected'] += 1
                continue
            p_try, rss_try = pair
        p, rss_f = p_try, rss_try
        r_c = coarse.evaluate(p, False)[0]
        rss = float(r_c @ r_c)
        resid_w = coarse.time_residual(p)
        tried_split = False
    if p.size and q > 1:                                     # polish on every sample
        try:
            p_full = full.solve(p, max_nfev=10, xtol=1e-10)
            r, J, _ = full.evaluate(p_full)
            if _decays(p_full, J, float(r @ r), N * nch - nch * (L0 + p.size) - p.size, T):
                p = p_full
        except (np.linalg.LinAlgError, ValueError):
            pass
    if p.size == 0:
        return out
    coef, resid, var, cov_p = _joint_fit_fast(x, D, tt, p, full.dt)
    A = coef[L0::2] - 1j * coef[L0 + 1::2]                      # Re{A z} = a Re z + b Im z
    out.update(rates=-p[0::2] + 1j * p[1::2], A=A, coef=coef[:L0], resid=resid, var=var[:L0], cov_p=cov_p)
    return out


# ------------------------------------------------------------------------------------------------ steady windows
def speed_from_angle(angle, sample_rate: float) -> np.ndarray:
    """
    Per-sample rotor speed [rad/s], shape (N,), from the per-sample keyphasor angle [rad] (N,).

    Forward difference: speed[i] = (angle[i+1] - angle[i]) * sample_rate, the last sample repeating the one before
    (NaN for a single sample).  On a constant-speed step of the simulated rig this is the step's speed exactly; on an
    angle rebuilt from key marks it is each revolution's mean speed.  :class:`SteadyWindowTracker` users that receive
    the angle in chunks (:class:`bearing_id.identify.harmonics.RunStream`) compute the same numbers by holding back
    each chunk's last sample until the next chunk arrives.
    """
    a = np.asarray(angle, dtype=float).reshape(-1)
    if a.size < 2:
        return np.full(a.size, np.nan)
    d = np.diff(a) * float(sample_rate)
    return np.append(d, d[-1])


class SteadyWindowTracker:
    """
    The steady-window rule, fed one chunk of per-sample speeds at a time.

    A window is a maximal run of finite speeds in which max(speed) - min(speed) <= tol_rel * |mean speed of the run
    so far| (greedy from its first sample; the sample that breaks the rule starts the next window; a non-finite
    speed ends a window and belongs to none).  ``feed(speed_chunk)`` returns the windows (i0, i1) (absolute,
    half-open sample indices since the first sample fed) that the chunk closed; ``close()`` ends the open one.
    Feeding a record in any chunking gives the windows of feeding it whole: :func:`steady_windows` is this tracker
    fed at once, so the offline and the streaming routes cut the same windows.
    """

    def __init__(self, tol_rel: float = 0.005):
        if not tol_rel > 0:
            raise ValueError(f'tol_rel must be > 0, got {tol_rel}')
        self.tol_rel = float(tol_rel)
        self.n = 0              # samples fed so far
        self.i0 = None          # start of the open window (absolute index) or None
        self._hi = self._lo = self._sum = 0.0
        self._count = 0

    @property
    def open_length(self) -> int:
        """Return the number of samples in the open window (0 when none is open)."""
        return self._count if self.i0 is not None else 0

    def feed(self, speed) -> list[tuple[int, int]]:
        w = np.asarray(speed, dtype=float).reshape(-1)
        base = self.n
        self.n += w.size
        closed = []
        j = 0
        while j < w.size:
            if self.i0 is None:
                if not np.isfinite(w[j]):
                    j += 1
                    continue
                self.i0, self._count = base + j, 0
                self._hi, self._lo, self._sum = -np.inf, np.inf, 0.0
            end = min(w.size, j + max(self._count, 1024))     # bounded scan: O(window length) work per window
            seg = w[j:end]
            fin = np.isfinite(seg)
            stop = seg.size if fin.all() else int(np.argmin(fin))
            seg = seg[:stop]
            hi = np.maximum(np.maximum.accumulate(seg), self._hi)
            lo = np.minimum(np.minimum.accumulate(seg), self._lo)
            csum = np.cumsum(np.concatenate(([self._sum], seg)))[1:]    # sequential sum: any chunking, same bits
            ref = np.abs(csum / (self._count + np.arange(1, seg.size + 1)))
            br = np.nonzero(hi - lo > self.tol_rel * np.maximum(ref, 1e-300))[0]
            take = int(br[0]) if br.size else seg.size
            if take:
                self._hi, self._lo, self._sum = float(hi[take - 1]), float(lo[take - 1]), float(csum[take - 1])
                self._count += take
            j += take
            if br.size or j < end:             # broken by the rule, or by a non-finite speed at j
                closed.append((self.i0, base + j))
                self.i0 = None
        return closed

    def close(self) -> list[tuple[int, int]]:
        """End the open window (end of the record, a gap, a change of run); returns it if it holds samples."""
        out = [(self.i0, self.i0 + self._count)] if self.i0 is not None and self._count else []
        self.i0, self._count = None, 0
        return out


def steady_windows(t, speed, tol_rel: float = 0.005, min_duration: float = 0.5) -> list[tuple[int, int]]:
    """
    Sample ranges (i0, i1) (half open) where the speed is constant within ``tol_rel``.

    The rule of :class:`SteadyWindowTracker` applied to the whole record; windows shorter than ``min_duration`` [s]
    are dropped (duration = number of samples x the mean sample interval of the window).

    Parameters: t (N,) s, speed (N,) rad/s (or rpm: only ratios matter).
    """
    t = np.asarray(t, dtype=float).reshape(-1)
    w = np.asarray(speed, dtype=float).reshape(-1)
    if t.size != w.size:
        raise ValueError(f't has {t.size} values but speed has {w.size}')
    tr = SteadyWindowTracker(tol_rel)
    out = []
    for i0, i1 in tr.feed(w) + tr.close():
        if i1 - 1 > i0 and t[i1 - 1] - t[i0] + (t[i1 - 1] - t[i0]) / (i1 - 1 - i0) >= min_duration:
            out.append((i0, i1))
    return out


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
    x = _as_2d(samples)
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


# ------------------------------------------------------------------------------------------------ sub-synchronous
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


def _fit_sinusoid(x, tt, f):
    D = np.column_stack([np.ones_like(tt), np.cos(TWO_PI * f * tt), np.sin(TWO_PI * f * tt)])
    coef, *_ = np.linalg.lstsq(D, x, rcond=None)
    return coef[1] - 1j * coef[2], float(np.sum((x - D @ coef) ** 2))


SUBSYNC_GOLDEN_STEPS = 40       # golden-section steps refining the peak frequency within +-1 FFT bin
SUBSYNC_TAYLOR_TERMS = 32       # terms of the series in the frequency offset (truncation < 1e-19 of sum |x|)


def _subsync_spectrum(samples, angle, sample_rate: float, sync_orders):
    """
    Return the shared first step of the sub-synchronous search (both implementations).

    The samples with the synchronous orders fitted and removed (:func:`harmonic_vectors` over the whole window),
    Hann-windowed and Fourier transformed: dict with ``x`` (N, nch) [m], ``resid`` (N, nch) [m], ``tt`` (N,) [s]
    from the first sample, ``fs`` [Hz], ``speed_hz`` (mean running speed [Hz]), ``freqs`` (N // 2 + 1,) [Hz],
    ``power`` (N // 2 + 1,) channel-summed squared amplitude spectrum [m^2].
    """
    x = _as_2d(samples)
    a = _check_angle(angle, x.shape[0])
    finite_rows(x, 'raise')
    fs = float(sample_rate)
    n = x.shape[0]
    tt = np.arange(n) / fs
    speed_hz = (a[-1] - a[0]) / TWO_PI / (tt[-1] if n > 1 else 1.0)
    if speed_hz <= 0:
        raise ValueError('the rotor does not turn in this window')
    fit = harmonic_vectors(x, a, sync_orders, whole_revs=False)
    ph = np.outer(a, np.asarray(fit.orders, dtype=float))
    resid = x - fit.offset - np.real(np.exp(1j * ph) @ fit.X)
    win = np.hanning(n)
    spec = np.abs(np.fft.rfft(resid * win[:, None], axis=0)) / (np.sum(win) / 2)      # amplitude spectrum
    return {'x': x, 'resid': resid, 'tt': tt, 'fs': fs, 'speed_hz': speed_hz,
            'freqs': np.fft.rfftfreq(n, 1 / fs), 'power': np.sum(spec**2, axis=1)}


def _subsync_peak(sp, ratio_range):
    """Return (k, idx): the FFT bin of the channel-summed power peak within ``ratio_range`` and the band's bins."""
    freqs, power, speed_hz = sp['freqs'], sp['power'], sp['speed_hz']
    band = (freqs >= ratio_range[0] * speed_hz) & (freqs <= ratio_range[1] * speed_hz)
    if np.count_nonzero(band) < 3:
        raise ValueError('the window is too short to resolve sub-synchronous frequencies; use more revolutions')
    idx = np.nonzero(band)[0]
    return idx[int(np.argmax(power[idx]))], idx


def _golden_min(cost, lo, hi, steps: int = SUBSYNC_GOLDEN_STEPS) -> float:
    """Return the midpoint of [lo, hi] after ``steps`` golden-section steps on ``cost`` (the reference's search)."""
    g = (math.sqrt(5) - 1) / 2
    c1, c2 = hi - g * (hi - lo), lo + g * (hi - lo)
    f1, f2 = cost(c1), cost(c2)
    for _ in range(steps):
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


class _SinusoidCost:
    """
    The reference's cost, all channels at once: sum_c min ||x_c - d_c - a_c cos(2 pi f t) - b_c sin(2 pi f t)||^2.

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
        cost = _SinusoidCost(sp['resid'], sp['fs'], freqs[k], df)
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
                   xy=(0, 1), method: str = 'fast') -> SubsyncComponent:
    """
    Strongest sub-synchronous component of ``samples`` (N, nch) [m] with keyphasor ``angle`` (N,) [rad].

    Method: the synchronous orders ``sync_orders`` are fitted and removed (:func:`harmonic_vectors`), the residual is
    Hann-windowed and Fourier transformed, the channel-summed power peak with frequency ratio inside ``ratio_range``
    (ratio = f / mean speed) is found and refined by a least-squares sinusoid fit (golden search on f), which gives
    the phasor per channel.  ``xy`` = (i_x, i_y) channel indices of an x/y probe pair for the whirl direction
    (None to skip).  Needs evenly sampled data: NaN/inf samples are refused (ValueError with the count).
    ``method``: 'fast' (default: the same golden search on the same cost, each step O(nch) from moments computed
    once, :class:`_SinusoidCost`) or 'reference' (:func:`_subsynchronous_reference`, the first implementation: a
    3-column least-squares fit per channel at every step); they agree to rounding (test/test_subsync_fast.py).
    :func:`subsynchronous_bands` searches several bands of one window with one synchronous fit.
    """
    return subsynchronous_bands(samples, angle, sample_rate, [ratio_range], sync_orders=sync_orders, xy=xy,
                                method=method, missing='raise')[0]


def subsynchronous_bands(samples, angle, sample_rate: float, ratio_ranges, *, sync_orders=(1, 2, 3), xy=(0, 1),
                         method: str = 'fast', missing: str = 'none') -> list:
    """
    Return :func:`subsynchronous` of one window for each band of ``ratio_ranges`` (the synchronous fit done once).

    A band too narrow for three FFT bins gives None (``missing='none'``) or raises ValueError (``'raise'``); a
    window in which the rotor does not turn, or that holds NaN/inf, raises ValueError.
    """
    if method not in ('fast', 'reference'):
        raise ValueError(f"method must be 'fast' or 'reference', got {method!r}")
    if method == 'reference':
        out = []
        for band in ratio_ranges:
            try:
                out.append(_subsynchronous_reference(samples, angle, sample_rate, ratio_range=band,
                                                     sync_orders=sync_orders, xy=xy))
            except ValueError as exc:
                if missing == 'raise' or 'too short' not in str(exc):
                    raise
                out.append(None)
        return out
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


def _subsynchronous_reference(samples, angle, sample_rate: float, *, ratio_range=(0.05, 0.95), sync_orders=(1, 2, 3),
                              xy=(0, 1)) -> SubsyncComponent:
    """
    Return the strongest sub-synchronous component: the first implementation of :func:`subsynchronous`, the reference.

    Kept unchanged: every golden-section step fits [1, cos, sin] by least squares per channel on all N samples.
    """
    x = _as_2d(samples)
    a = _check_angle(angle, x.shape[0])
    finite_rows(x, 'raise')
    fs = float(sample_rate)
    n = x.shape[0]
    tt = np.arange(n) / fs
    speed_hz = (a[-1] - a[0]) / TWO_PI / (tt[-1] if n > 1 else 1.0)
    if speed_hz <= 0:
        raise ValueError('the rotor does not turn in this window')
    fit = harmonic_vectors(x, a, sync_orders, whole_revs=False)
    ph = np.outer(a, np.asarray(fit.orders, dtype=float))
    resid = x - fit.offset - np.real(np.exp(1j * ph) @ fit.X)
    win = np.hanning(n)
    spec = np.abs(np.fft.rfft(resid * win[:, None], axis=0)) / (np.sum(win) / 2)      # amplitude spectrum
    freqs = np.fft.rfftfreq(n, 1 / fs)
    band = (freqs >= ratio_range[0] * speed_hz) & (freqs <= ratio_range[1] * speed_hz)
    if np.count_nonzero(band) < 3:
        raise ValueError('the window is too short to resolve sub-synchronous frequencies; use more revolutions')
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
