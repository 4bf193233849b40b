"""
Independent Kalman-filter oracle for the tests: filterpy's time-varying filter and the bound on its distance.

:func:`filterpy_filter` runs the paper's eqs 12-18 with filterpy's ``KalmanFilter`` (one predict/update per sample,
its own covariance recursion), the known sinusoidal input entering as u_k = x_p(t_{k+1}) - Phi x_p(t_k) through
B = I.  Started at the steady-state covariance it is the package's steady-state filter up to (a) the distance of its
gain sequence K_k from the steady-state gain K (the Riccati solution's own error, which the recursion keeps or damps)
and (b) rounding.  :func:`agreement_bound` turns both into a tolerance.  The difference d_k of two runs' posterior
estimates obeys

    d_k = (I - K H) Phi d_(k-1) + delta_k,   |delta_k| <= |(K_k - K) nu_k| + (rounding of one step),

so |d_k| <= sum_j ||F^j|| max |delta| with F = (I - K H) Phi.  One step's rounding is at most n eps (||Phi|| |x| +
||K|| |z|) (matrix-vector products of size n).  The state mixes units (m and m/s), so the norms are taken in the
coordinates x / t that balance F (``scipy.linalg.matrix_balance``, t powers of 2), and mapped back by the output rows.
"""
from __future__ import annotations

from filterpy.kalman import KalmanFilter
import numpy as np
import scipy.linalg as sla

EPS = np.finfo(float).eps


def filterpy_filter(km, z, angle, *, x0=None, P0=None) -> dict:
    """
    Run filterpy's KalmanFilter on a KalmanModel ``km`` (prior at the first sample: x0, default x_p(t0); P0, P_ss).

    Returns a dict with 'estimates' (N, k) = E x_hat(k|k), 'states' (N, n) x_hat(k|k), 'innovations' (N, m),
    'S' (N, m, m), 'nis' (N,), 'gains' (N, n, m) the gain of each update.
    """
    z = np.asarray(z, dtype=float).reshape(len(angle), -1)
    n, m, N = km.n, km.m, z.shape[0]
    xp = np.zeros((N, n))
    for r, X in km.Xp.items():
        xp += np.real(np.exp(1j * r * np.asarray(angle))[:, None] * X[None, :])
    kf = KalmanFilter(dim_x=n, dim_z=m, dim_u=n)
    kf.F = km.Phi.copy()
    kf.B = np.eye(n)
    kf.H = km.H.copy()
    kf.Q = km.Q.copy()
    kf.R = km.R.copy()
    kf.x = (xp[0] if x0 is None else np.asarray(x0, dtype=float)).reshape(n, 1).copy()
    kf.P = (km.steady_state()[0] if P0 is None else np.asarray(P0, dtype=float)).copy()
    out = {'states': np.empty((N, n)), 'innovations': np.empty((N, m)), 'S': np.empty((N, m, m)),
           'nis': np.empty(N), 'gains': np.empty((N, n, m))}
    for k in range(N):
        kf.update(z[k].reshape(m, 1))
        out['innovations'][k] = kf.y[:, 0]
        out['S'][k] = kf.S
        out['nis'][k] = float(kf.y[:, 0] @ np.linalg.solve(kf.S, kf.y[:, 0]))
        out['gains'][k] = kf.K
        out['states'][k] = kf.x[:, 0]
        if k + 1 < N:
            kf.predict(u=(xp[k + 1] - km.Phi @ xp[k]).reshape(n, 1))
    out['estimates'] = out['states'] @ km.E.T
    return out


def growth_sum(F, N: int) -> float:
    """Return sum over 0 <= j < N of ||F^j||_2: the worst-case gain of d_k = F d_(k-1) + delta_k over N steps."""
    Fj = np.eye(F.shape[0])
    total = 0.0
    for _ in range(N):
        nj = np.linalg.norm(Fj, 2)
        total += nj
        if nj < EPS * total:
            break
        Fj = F @ Fj
    return total


def balancing(F) -> np.ndarray:
    """Diagonal t (n,) with T^-1 F T balanced (T = diag(t), powers of 2): the coordinates the bounds use."""
    return sla.matrix_balance(F, permute=False, separate=True)[1][0]


def closed_loop(km) -> np.ndarray:
    """F = (I - K H) Phi: the propagation of a difference of posterior estimates."""
    P, K, S = km.steady_state()
    return (np.eye(km.n) - K @ km.H) @ km.Phi


def rounding_step(km, x, z, t) -> float:
    """Return one filter step's rounding bound in x / t: n eps (||Phi_t|| max |x_k / t| + ||K / t|| max |z_k|)."""
    K = km.steady_state()[1]
    Phi_t = km.Phi * t[None, :] / t[:, None]
    x_t = np.max(np.linalg.norm(np.atleast_2d(x) / t[None, :], axis=1))
    z_n = np.max(np.linalg.norm(np.atleast_2d(z), axis=1))
    return km.n * EPS * (np.linalg.norm(Phi_t, 2) * x_t + np.linalg.norm(K / t[:, None], 2) * z_n)


def output_bounds(km, d: float, t) -> tuple[float, float, float]:
    """Map a bound d on |d_k / t|_2 to bounds on max |difference| of (states, estimates E x, innovations H Phi x)."""
    return (float(np.max(t)) * d, np.linalg.norm(km.E * t[None, :], 2) * d,
            np.linalg.norm((km.H @ km.Phi) * t[None, :], 2) * d)


def agreement_bound(km, ref: dict, z) -> tuple[float, float, float]:
    """
    Return bounds on max |difference| of (states, estimates, innovations) against filterpy's run ``ref``.

    ``ref`` from :func:`filterpy_filter` on the samples ``z``; see the module docstring for the derivation.
    """
    F = closed_loop(km)
    t = balancing(F)
    K = km.steady_state()[1]
    gain_dev = max(np.linalg.norm((Kk - K) / t[:, None], 2) for Kk in ref['gains'])
    step = (gain_dev * np.max(np.linalg.norm(ref['innovations'], axis=1))
            + rounding_step(km, ref['states'], z, t))
    d = growth_sum(F * t[None, :] / t[:, None], len(ref['innovations'])) * step
    return output_bounds(km, d, t)
