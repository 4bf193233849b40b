"""
The process noise the data imply (estimation/process_noise.py): Monte-Carlo truth.

A two-mass oscillator is simulated with a known process noise s_true Q0 and measurement noise R; a steady-state filter
tuned for Q0 (wrong unless s_true = 1) runs on it, and the scale fitted to its innovation variances must recover
s_true within the spread of that estimate over independent seeds (measured here, not assumed).  The Lyapunov split
of the innovation variance is checked against a second Lyapunov solve of the measurement-noise term alone.
"""
from bearing_id.estimation import kalman as kf
from bearing_id.estimation.process_noise import innovation_variance_terms, process_noise_scale
import numpy as np
import pytest
import scipy.linalg as sla

FS = 2000.0
Q0 = 1e-10
R0 = 1e-8


def model():
    M = np.diag([1.0, 0.5])
    K = np.array([[3e4, -1e4], [-1e4, 1e4]])
    C = np.array([[4.0, -1.0], [-1.0, 1.0]])
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Mi @ K, -Mi @ C]])
    B = np.vstack([np.zeros((2, 2)), Mi])
    H = np.array([[0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]])
    return kf.kalman_model(A, B, H, 1 / FS, Q=Q0, R=R0)


def simulate(km, s_true, N, rng):
    """Measurements (N, m) of x_(k+1) = Phi x_k + w_k, w ~ N(0, s_true Q0 I), z = H x + v, v ~ N(0, R0 I)."""
    x = np.zeros(km.n)
    w = rng.standard_normal((N, km.n)) * np.sqrt(s_true * Q0)
    xs = np.empty((N, km.n))
    for k in range(N):
        xs[k] = x
        x = km.Phi @ x + w[k]
    return xs @ km.H.T + rng.standard_normal((N, km.m)) * np.sqrt(R0)


def test_the_variance_split_matches_a_separate_lyapunov_solve():
    km = model()
    base, per = innovation_variance_terms(km)
    P, K, S = km.steady_state()
    F = km.Phi @ (np.eye(km.n) - K @ km.H)
    sig_r = sla.solve_discrete_lyapunov(F, km.Phi @ K @ km.R @ K.T @ km.Phi.T)
    ref = np.diag(km.R + km.H @ sig_r @ km.H.T)
    # both are sums of the same positive terms: they agree to the Lyapunov solves' rounding
    assert np.allclose(base, ref, rtol=1e-7, atol=0)
    assert np.all(per > 0) and np.all(base >= np.diag(km.R))


@pytest.mark.parametrize('s_true', [0.0, 0.2, 1.0, 8.0])
def test_the_fitted_scale_recovers_the_simulated_process_noise(s_true):
    km = model()
    rng = np.random.default_rng(20261128)
    N, burn, seeds = 10000, 2000, 12
    est = []
    for _ in range(seeds):
        z = simulate(km, s_true, N, rng)
        nu, _, _, _ = kf.innovations(km, z, np.zeros(N), x0=np.zeros(km.n))
        est.append(process_noise_scale(km, np.mean(nu[burn:] ** 2, axis=0)))
    est = np.array(est)
    se = est.std(ddof=1) / np.sqrt(seeds)
    # unbiased: the mean over the seeds within 4 standard errors of the truth (plus the start-up transient's share,
    # bounded by the burn-in: the filter's closed loop decays by far more than 1e3 over 2000 steps)
    assert abs(est.mean() - s_true) <= 4 * se + 1e-3, (est.mean(), se, s_true)
    # and informative: the mean over the seeds resolves a change of process noise by half of Q0
    assert 4 * se < 0.5, se
