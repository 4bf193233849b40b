"""
Decaying modes fitted jointly with the harmonics of a window: the transient-aware 1X fit.

After a speed change lightly damped rotor modes ring for seconds; a decaying mode near running speed (e.g. a 33 Hz
bending mode at 35 Hz running speed) is nearly collinear with 1X over a short window and biases the plain harmonic
fit by percent, in a way that comparing window halves does not always catch.  The model of channel c is

    x_c(t) = D b_c + sum_m exp(-s_m t) (a_mc cos w_m t + b_mc sin w_m t)

with D (N, L0) the harmonic regressors (offset, cos and sin of k phi), (s_m, w_m) [1/s, rad/s] shared by all
channels of the window and t [s] from the first sample used.  Model free: the components are found in the data, not
from a rotor model.  :func:`fit_decaying_modes` is called by :func:`bearing_id.signals.harmonics.harmonic_vectors`.

* (s, w) by variable projection (:class:`VariableProjection`): the linear coefficients are eliminated by least
  squares, and ``scipy.optimize.least_squares`` (Levenberg-Marquardt, Kaufman's Jacobian) searches the nonlinear
  ones on every q-th sample (<= TRANSIENT_MAX_POINTS points), then polishes them on all samples; channels are
  weighted by their plain-fit residual std.
* Greedy: candidates are the strongest peak of the channel-summed residual spectrum (Hann window) outside
  +-TRANSIENT_EXCLUDE_BINS bins around every harmonic order (and sub-synchronous ratio fitted), and frequencies
  beside each component already kept (two modes closer than the resolution, e.g. forward and backward whirl).
* A component is kept only if it reduces the residual significantly on all samples (BIC:
  n ln(RSS_before / RSS_after) > (2 + 2 nch) ln n, n = samples x channels) and every kept decay rate is
  s > TRANSIENT_DECAY_SIGMA x its 1-sigma and s > TRANSIENT_MIN_DECAY / T (T the window length [s]).  A significant
  but steady component (s ~ 0: a sub-synchronous whirl, an unfitted harmonic) is not a transient: it is skipped
  (``subsync`` / ``orders`` of harmonic_vectors fit those).
* Two modes closer than the resolution 2 pi / T (forward and backward whirl of one bending mode) beat, and one
  component fitted to them can look steady; before such a component is skipped, the pair is fitted
  (:func:`_close_pair`) and kept when its second component is significant too.  Decay rates closer in frequency
  than the resolution are judged by their sum (:func:`_decays`).  Left in the residual, such a pair can bias a
  nearby 1X by about 2 sigma.
* The std of the harmonic coefficients comes from the joint fit: sigma_c^2 diag(D_full^T D_full)^-1 plus the
  propagated uncertainty of (s, w) (D_full^+ dmodel/dp cov_p ...), so a transient nearly collinear with 1X inflates
  the std honestly (:func:`_joint_fit`).
* Every evaluation takes R of a Householder QR of the tall [D0, E, tE, x] (numpy): the Gram route (Cholesky of A^T A)
  squares the condition number and, on a window of a 14-probe force plan, flipped which component was kept
  (1X moved 6 sigma).  The triangular solves use numpy too (on an upper-triangular matrix its LU does no pivoting):
  scipy's OpenBLAS pool beside numpy's made the fit ~10 x slower with two BLAS threads.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares

TWO_PI = 2.0 * math.pi
TRANSIENT_MAX_POINTS = 2048     # the nonlinear search runs on every q-th sample (q = ceil(N / this)), then polishes
TRANSIENT_EXCLUDE_BINS = 2.0    # half-width of the band (in FFT bins) around each harmonic order not searched
TRANSIENT_DECAY_SIGMA = 2.0     # a kept component must decay: s > this x its 1-sigma ...
TRANSIENT_MIN_DECAY = 0.1       # ... and s T > this (fades by >= ~10 % over the window): slower is 'steady'
TRANSIENT_MAX_TRIES = 2         # candidates tried per allowed component (non-decaying ones are skipped)
TRANSIENT_PAIR_SPLIT = 0.25     # start half-separation [1/T Hz] of a pair fitted where one component did not decay
SCREEN_RATES = (0.5, 3.0, 15.0)     # decay rates [1/T] tried at each candidate frequency by the linear screen


# ------------------------------------------------------------------------------------------------ exponentials
def uniform_step(tt):
    """Return the step dt [s] of the times ``tt`` (N,) when they form a uniform grid to a few ulps, else None."""
    n = tt.size
    if n < 64:
        return None
    dt = (tt[-1] - tt[0]) / (n - 1)
    if not dt > 0:
        return None
    dev = np.max(np.abs(tt - (tt[0] + dt * np.arange(n))))
    return dt if dev <= 16 * np.finfo(float).eps * max(abs(tt[0]), abs(tt[-1])) else None


def exp_outer(tt, lam, dt=None) -> np.ndarray:
    """
    Return z = exp(outer(tt, lam)) (N, m) complex for times ``tt`` (N,) [s] and rates ``lam`` (m,) [1/s].

    On a uniform grid (``dt`` [s] from :func:`uniform_step`) z[i B + j] = exp(lam (tt[0] + j dt)) exp(lam i B dt):
    2 sqrt(N) m exponentials and N m products instead of N m exponentials; the two differ by rounding of the
    arguments (relative ~ eps |lam t|).  A trial step with a fast-growing component overflows to inf / nan quietly:
    the residual is then not finite and Levenberg-Marquardt rejects the step.
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


def _rates(p) -> np.ndarray:
    """Return lambda = -s + j w (m,) [1/s] of p = [s_1, w_1, s_2, w_2, ...]."""
    return -p[0::2] + 1j * p[1::2]


# ------------------------------------------------------------------------------------------------ variable projection
QR_BLOCK_ROWS = 1 << 17     # rows triangularised at a time (12.8 s at 10,240 Hz): bounds a long window's memory


def stacked_r(n: int, fill) -> np.ndarray:
    """
    Return R of the QR of an (n, k) matrix (n >= k) given by blocks of rows: ``fill(i, j)`` returns its rows i:j.

    At most :data:`QR_BLOCK_ROWS` rows are held at a time: R of the rows so far is stacked on the next block and
    triangularised again (R is the same up to the signs of its rows, which no use of it here depends on).  A matrix
    of at most that many rows is one ``np.linalg.qr`` (the same numbers as before blocks existed).
    """
    R = None
    for i in range(0, n, QR_BLOCK_ROWS):
        A = fill(i, min(n, i + QR_BLOCK_ROWS))
        R = np.linalg.qr(A if R is None else np.vstack((R, A)), mode='r')
    return R


class VariableProjection:
    """
    Least squares x = D0 b + E(p) c + noise over p = [s_1, w_1, ...] with b, c eliminated (variable projection).

    ``xw`` (N, nch) channel-weighted data, ``D0`` (N, L0) fixed (harmonic) regressors, ``tt`` (N,) times [s];
    E(p) = [Re z_1, Im z_1, ...] with z_m = exp((-s_m + j w_m) t).  The residual r_c = P x_c (P the projector out of
    span(D0, E)) and the Kaufman Jacobian columns -P dE c_c / dp_j of every channel lie in the span of
    [D0, E, t E, x] (dz/ds = -t z, dz/dw = j t z).  One QR (R only) of A = [D0, E, t E, x] (N, L0 + 4m + nch) gives
    their coordinates in an orthonormal basis of that span; dropping its first L0 + 2m rows projects out
    span(D0, E).  The reduced residual (nch (2m + nch),) and Jacobian have the inner products (r^T r, J^T J, J^T r)
    of the full (N nch,) ones, and those are all Levenberg-Marquardt uses.
    """

    def __init__(self, xw, D0, tt):
        self.xw, self.D0, self.tt = xw, D0, tt
        self.dt = uniform_step(tt)
        self.Q0, _ = np.linalg.qr(D0)
        self.xp = xw - self.Q0 @ (self.Q0.T @ xw)     # data outside span(D0)
        self._key = None
        self._buf = None             # (rows, k) Fortran-ordered work array, reused by every evaluation

    def evaluate(self, p, jac: bool = True):
        """Return (reduced residual (nch (2m + nch),), Jacobian (nch (2m + nch), 2m) or None, c (2m, nch))."""
        key = p.tobytes()
        if key != self._key:
            lam = _rates(p)
            n, m2 = self.tt.size, 2 * lam.size
            L0, nch = self.D0.shape[1], self.xw.shape[1]
            L = L0 + m2
            k = L + m2 + nch
            rows = min(n, QR_BLOCK_ROWS)
            if self._buf is None or self._buf.shape[1] < k:
                self._buf = np.empty((rows, k), order='F')

            def fill(i, j):
                A = self._buf[:j - i, :k]
                E = exp_outer(self.tt[i:j], lam, self.dt).view(float)      # (j - i, 2m) [Re z, Im z]
                if not np.isfinite(E).all():           # a growth rate the window's length overflows
                    raise ValueError('the decay-rate search left the range the window can represent')
                A[:, :L0] = self.D0[i:j]
                A[:, L0:L] = E
                np.multiply(E, self.tt[i:j, None], out=A[:, L:L + m2])
                A[:, L + m2:] = self.xw[i:j]
                return A

            R = stacked_r(n, fill)
            try:
                c1 = np.linalg.solve(R[:L, :L], R[:L, L + m2:])[L0:]        # (2m, nch) on [Re z, Im z]
            except np.linalg.LinAlgError:
                E = exp_outer(self.tt, lam, self.dt).view(float)
                c1 = np.linalg.lstsq(E - self.Q0 @ (self.Q0.T @ E), self.xp, rcond=None)[0]
            if not np.isfinite(c1).all():          # components numerically collinear: this p describes nothing
                raise ValueError('the decaying components are collinear at this point of the search')
            rho = R[L:, L + m2:]                                       # (2m + nch, nch): residual coordinates
            RT = R[L:, L:L + m2]                                       # P t E coordinates (rows past 2m are 0)
            a, b = c1[0::2], c1[1::2]                                  # (m, nch)
            J = np.empty((m2 + nch, nch, m2))
            J[:, :, 0::2] = np.transpose(RT[:, 0::2, None] * a + RT[:, 1::2, None] * b, (0, 2, 1))      # -P d/ds
            J[:, :, 1::2] = np.transpose(RT[:, 1::2, None] * a - RT[:, 0::2, None] * b, (0, 2, 1))      # -P d/dw
            self._key, self._state = key, (rho.reshape(-1), J.reshape(-1, m2), c1)
        r, J, c1 = self._state
        return r, (J if jac else None), c1

    def screen(self, p, rates) -> np.ndarray:
        """
        Return the residual sum of squares (k,) of the linear fit at [p, s_i, w_i] for every ``rates`` row (k, 2).

        The r^T r of ``evaluate(concatenate([p, rates[i]]))`` for all candidates at once: the candidates' columns
        e_i (2 each) and the data are projected out of span(D0, E(p)) (twice, for orthogonality), then
        RSS_i = |P x|^2 - tr(h_i^T G_i^-1 h_i) with the 2x2 Gram matrix G_i = (P e_i)^T P e_i and
        h_i = (P e_i)^T P x.  A candidate (nearly) inside span(D0, E(p)) -- a projected column shorter than 1e-6 of
        the column, or its two projected columns parallel to 1e-12 -- explains nothing.  The screen only ranks.
        """
        if p.size:
            B = np.hstack([self.D0, exp_outer(self.tt, _rates(p), self.dt).view(float)])
        else:
            B = self.D0
        Qb, _ = np.linalg.qr(B)
        xr = self.xw - Qb @ (Qb.T @ self.xw)
        xr -= Qb @ (Qb.T @ xr)
        rates = np.asarray(rates, dtype=float).reshape(-1, 2)
        E = exp_outer(self.tt, -rates[:, 0] + 1j * rates[:, 1], self.dt).view(float)     # (N, 2k)
        En = E - Qb @ (Qb.T @ E)
        En -= Qb @ (Qb.T @ En)
        C = En.T @ np.hstack([En, xr])                                  # (2k, 2k + nch)
        k = En.shape[1] // 2
        i0, i1 = np.arange(0, 2 * k, 2), np.arange(1, 2 * k, 2)
        g11, g12, g22 = C[i0, i0], C[i0, i1], C[i1, i1]
        h1, h2 = C[i0, 2 * k:], C[i1, 2 * k:]                          # (k, nch)
        det = g11 * g22 - g12 * g12
        e2 = np.sum(E * E, axis=0)
        ok = (g11 > 1e-12 * e2[i0]) & (g22 > 1e-12 * e2[i1]) & (det > 1e-12 * g11 * g22)
        with np.errstate(divide='ignore', invalid='ignore'):
            explained = np.sum(g22[:, None] * h1 * h1 - 2 * g12[:, None] * h1 * h2 + g11[:, None] * h2 * h2,
                               axis=1) / det
        return float(np.sum(xr * xr)) - np.where(ok, explained, 0.0)

    def solve(self, p0, max_nfev: int = 40, xtol: float = 1e-8) -> np.ndarray:
        """Return p minimising the residual from ``p0`` (Levenberg-Marquardt, scipy.optimize.least_squares)."""
        return least_squares(lambda p: self.evaluate(p, False)[0], p0, jac=lambda p: self.evaluate(p)[1], method='lm',
                             xtol=xtol, ftol=1e-10, gtol=1e-10, max_nfev=max_nfev).x

    def time_residual(self, p) -> np.ndarray:
        """Return the residual (N, nch) in the time domain at p: xw outside span(D0, E(p))."""
        E = exp_outer(self.tt, _rates(p), self.dt).view(float)
        Q1, _ = np.linalg.qr(E - self.Q0 @ (self.Q0.T @ E))
        return self.xp - Q1 @ (Q1.T @ self.xp)


# ------------------------------------------------------------------------------------------------ tests and candidates
def _decays(p, J, rss, dof, T) -> bool:
    """
    Return True when all decay rates s = p[0::2] [1/s] are significant and fast enough.

    Each > TRANSIENT_DECAY_SIGMA x its 1-sigma (from the Kaufman Jacobian J, residual ``rss`` over ``dof``) and
    > TRANSIENT_MIN_DECAY / T (the component fades by at least that fraction of an e-fold over the window T [s]).
    Components closer in frequency than the resolution 2 pi / T [rad/s] (two modes beating, e.g. the forward and
    backward whirl of one bending mode) are judged together: their rates are not resolved one by one (strongly
    correlated), so their sum must pass both tests (its 1-sigma from the covariance) and none may grow
    significantly (s > -TRANSIENT_DECAY_SIGMA x its 1-sigma).
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
    """
    Return the strongest frequency [Hz] of the channel-summed spectrum of ``r`` (N, nch) outside the excluded bands.

    Excluded: every harmonic of ``speed_hz`` [Hz] below ``fmax`` [Hz], the non-integer ``ratios`` x speed_hz, the
    frequencies ``excluded`` [Hz] (each +-TRANSIENT_EXCLUDE_BINS bins) and the lowest bins; None if nothing is left.
    The peak is refined by a parabola through the log power of its bin and its neighbours.
    """
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


def _close_pair(coarse, full, p, p_one, rss_one, T, penalty_f, n_f, nch, L0):
    """
    Return (p with two more components, their RSS on all samples) where one component did not decay, or None.

    Two modes closer than the resolution 1/T (the forward and backward whirl of one bending mode, split by the
    gyroscopic effect) beat: one component ``p_one[-2:]`` fitted to the pair can come out steady or growing and be
    skipped as 'steady'; as its frequency is then excluded, the pair stays in the residual and biases a nearby 1X.  So
    before a significant component that does not decay is skipped, the pair is fitted (variable projection from
    starts +-TRANSIENT_PAIR_SPLIT / T Hz around its frequency, on ``coarse``; tests on ``full`` as for one
    component) and kept when the second component is significant (BIC: it reduces ``rss_one``, the RSS with the one
    component, by more than one component's ``penalty_f``) and the rates pass :func:`_decays`.  A steady component
    plus noise is not such a pair: it is still skipped.  ``n_f`` = samples x channels of ``full``, ``nch`` channels,
    ``L0`` harmonic regressors (for the dof).
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


# ------------------------------------------------------------------------------------------------ the fit
def _joint_fit(x, D, tt, p, dt=None):
    """
    Return the joint least-squares fit of x (N, nch) on [D, E(p)] at fixed p, with the uncertainty of p propagated.

    Returns coef (L, nch) (L = L0 + 2m), resid (N, nch), var (L, nch) = sigma_c^2 diag(D_full^T D_full)^-1 +
    diag(B_c cov_p B_c^T) with B_c = -D_full^+ dmodel_c/dp, and cov_p (2m, 2m) the covariance of p (Gauss-Newton,
    channels weighted by their residual variance).  One QR of [D, E, T, x] (T = t E, the derivatives' basis) gives
    the coefficients, the projections of the model derivatives out of span(D, E) (the rows past L) and D_full^+ T.
    """
    N, nch = x.shape
    L0 = D.shape[1]
    lam = _rates(p)
    m = lam.size
    m2 = 2 * m
    L = L0 + m2
    buf = np.empty((min(N, QR_BLOCK_ROWS), L + m2 + nch), order='F')

    def fill(i, j):
        A = buf[:j - i]
        z = exp_outer(tt[i:j], lam, dt)
        A[:, :L0] = D[i:j]
        A[:, L0:L:2] = z.real
        A[:, L0 + 1:L:2] = z.imag
        A[:, L:L + m2] = A[:, L0:L] * tt[i:j, None]
        A[:, L + m2:] = x[i:j]
        return A

    R = stacked_r(N, fill)
    Rf = R[:L, :L]
    coef = np.linalg.solve(Rf, R[:L, L + m2:])                      # (L, nch)
    if N <= buf.shape[0]:
        resid = x - buf[:, :L] @ coef                                # the one block is still in the buffer
    else:
        resid = np.empty_like(x)
        for i in range(0, N, buf.shape[0]):
            j = min(N, i + buf.shape[0])
            resid[i:j] = x[i:j] - fill(i, j)[:, :L] @ coef
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
    Rinv = np.linalg.solve(Rf, np.eye(L))
    cov_unit_diag = np.sum(Rinv ** 2, axis=1)                        # diag (Rf^T Rf)^-1
    B = -np.linalg.solve(Rf, np.einsum('lt,tcj->lcj', R[:L, L:L + m2], V).reshape(L, -1)).reshape(L, nch, m2)
    var = cov_unit_diag[:, None] * sigma2[None, :] + np.einsum('lcj,jk,lck->lc', B, cov_p, B)
    return coef, resid, var, cov_p


def fit_decaying_modes(x, D, tt, speed_hz, ratios, max_n, coef0=None) -> dict:
    """
    Greedy joint fit of harmonics + up to ``max_n`` decaying sinusoids (see the module docstring).

    ``x`` (N, nch) samples, ``D`` (N, L0) harmonic regressors, ``tt`` (N,) times [s] from the first sample,
    ``speed_hz`` the mean running speed [Hz], ``ratios`` the harmonic orders and sub-synchronous ratios in D (their
    bands are not searched), ``coef0`` (L0, nch) the plain fit lstsq(D, x) when the caller has it.

    Returns dict with ``rates`` (m,) complex lambda = -s + j w [1/s], ``A`` (m, nch) complex amplitudes at t = 0
    (x_tr = Re{A exp(lambda t)}), ``rejected`` (candidates tried and refused), and, when m > 0, ``coef`` (L0, nch),
    ``resid`` (N, nch), ``var`` (L0, nch) of the harmonic regressors from the joint fit (:func:`_joint_fit`) and
    ``cov_p`` (2m, 2m).
    """
    N, nch = x.shape
    L0 = D.shape[1]
    out = {'rates': np.zeros(0, dtype=complex), 'rejected': 0}
    if coef0 is None:
        coef0, *_ = np.linalg.lstsq(D, x, rcond=None)
    r0 = x - D @ coef0
    sig0 = np.sqrt(np.sum(r0 ** 2, axis=0) / (N - L0))
    del r0                                                   # (N, nch): not held through the search
    if not np.all(sig0 > 0):
        return out                                           # exact fit: nothing to explain
    w = 1.0 / sig0
    T = (tt[-1] - tt[0]) * N / max(N - 1, 1)
    q = max(1, int(math.ceil(N / TRANSIENT_MAX_POINTS)))
    full = VariableProjection(x * w, D, tt)
    coarse = full if q == 1 else VariableProjection(x[::q] * w, D[::q], tt[::q])
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
        trial = [(sd / T, fc, split) for fc, split in cands for sd in SCREEN_RATES]
        rss_all = coarse.screen(p, [(sd, TWO_PI * fc) for sd, fc, _ in trial])
        screen = [(float(v), sd, fc, split) for v, (sd, fc, split) in zip(rss_all, trial)]
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
    coef, resid, var, cov_p = _joint_fit(x, D, tt, p, full.dt)
    A = coef[L0::2] - 1j * coef[L0 + 1::2]                      # Re{A z} = a Re z + b Im z
    out.update(rates=_rates(p), A=A, coef=coef[:L0], resid=resid, var=var[:L0], cov_p=cov_p)
    return out
