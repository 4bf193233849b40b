"""
The process noise the data imply: covariance matching of a steady-state Kalman filter's innovations.

A steady-state filter runs with the gain K of its assumed (Q, R).  If the system's real process noise is s Q (same
shape, unknown scale s >= 0) and its real measurement noise R, the prior error e_k = x_k - x_hat(k|k-1) obeys
e_(k+1) = F e_k - Phi K v_k + w_k with F = Phi (I - K H), so its covariance Sigma solves the discrete Lyapunov equation

    Sigma = F Sigma F^T + Phi K R K^T Phi^T + s Q,

linear in s: Sigma = Sigma_R + s Sigma_Q, with Sigma_Q = F Sigma_Q F^T + Q; at s = 1 Sigma is the DARE's P (the Joseph
form of the Riccati equation), so Sigma_R = P - Sigma_Q.  The innovations nu_k = H e_k + v_k then have the variances

    c_i(s) = [R + H Sigma_R H^T]_ii + s [H Sigma_Q H^T]_ii,

and s is fitted to the measured ones by weighted least squares (weights 1 / S_ii, S the filter's own innovation
covariance).  Only the broadband part of the innovations is process noise: what is coherent with 1X or 2X is the
model mispredicting the synchronous response (the model health check), so the caller removes it before the fit.
This is Mehra's innovation-covariance matching (Mehra 1970, IEEE TAC 15(2) 175-184; one scale factor, zero lag) with
R taken from the data as a separate estimate.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla


def innovation_variance_terms(km) -> tuple:
    """
    Return (base (m,), per_scale (m,)) [m^2]: the innovation variances of ``km``'s filter are base + s per_scale.

    ``km`` a :class:`bearing_id.estimation.kalman.KalmanModel`; s the real process noise as a multiple of km.Q.
    Cached on the model (one Lyapunov solve of its size).
    """
    hit = km._chunked.get('variance_terms')
    if hit is not None:
        return hit
    P, K, S = km.steady_state()
    F = km.Phi @ (np.eye(km.n) - K @ km.H)
    sig_q = sla.solve_discrete_lyapunov(F, km.Q)
    sig_q = 0.5 * (sig_q + sig_q.T)
    per_scale = np.diag(km.H @ sig_q @ km.H.T).copy()
    base = np.diag(S).copy() - per_scale            # R + H (P - Sigma_Q) H^T
    out = (base, per_scale)
    km._chunked['variance_terms'] = out
    return out


def process_noise_scale(km, variances) -> float:
    """
    Return the scale s of km.Q that the measured broadband innovation ``variances`` (m,) [m^2] imply (may be <= 0).

    Weighted least squares of variances = base + s per_scale (:func:`innovation_variance_terms`), weights 1 / S_ii.
    A value <= 0 says the innovations hold no more than the measurement noise and the filter's own estimation error
    without process noise: the data ask for none.
    """
    base, per = innovation_variance_terms(km)
    S = np.diag(km.steady_state()[2])
    v = np.asarray(variances, float).reshape(-1)
    if v.size != base.size:
        raise ValueError(f'{v.size} innovation variances for a model of {base.size} measured channels')
    den = float(np.sum((per / S) ** 2))
    if not den > 0:
        return float('nan')
    return float(np.sum((v - base) * per / S ** 2) / den)
