"""
How uncertain an estimated bearing-node motion is.

Two sources: the measurement noise through the filter, and the bearing coefficients the model uses.

With one probe station the bearing-node motion is the model's extrapolation of what the probes see, so the 1-sigma
of the bearing coefficients the model was built on is the leading uncertainty once the noise is averaged out.

Coefficients
    First order: the 1X response q = Z^-1 F (Z = K + Kb - w^2 M + j w (C + Cb + W G), F the known 1X forces) moves by
    dq = sum_c (dq/dc) dc for independent coefficient errors dc of std sigma_c, so each output (row r of ``rows``) has
    a complex 1-sigma radius  s_r = sqrt(sum_c |r dq/dc|^2 sigma_c^2)  [m] (the RMS of |r dq|; a sample of
    x(t) = Re{a exp(j phi)} then has variance s_r^2 / 2).  dq/dc by central differences of the same response the
    model uses (:func:`bearing_id.rotor.assembly.harmonic_response`).

Noise
    The steady-state filter's posterior covariance E P(k|k) E^T (per sample, :func:`filter_std`).
"""
from __future__ import annotations

import numpy as np

from ..rotor.assembly import harmonic_response

REL_STEP = 1e-6      # central-difference step, relative to the coefficient's magnitude (or its 1-sigma)


def coefficient_sigma(model, speed: float, coeffs: dict, stds: dict, F, rows) -> np.ndarray:
    """
    Return the 1X phasor 1-sigma radius (k,) [m] of ``rows`` (k, ndof) from independent coefficient 1-sigmas.

    ``coeffs`` {node: (K (2, 2) [N/m], C (2, 2) [N s/m])} the model's bearings at ``speed`` [rad/s] (1X: omega =
    speed), ``stds`` the same shape, their 1-sigma (missing nodes: known exactly); ``F`` (ndof,) complex 1X forces [N].
    """
    rows = np.atleast_2d(np.asarray(rows, dtype=float))
    F = np.asarray(F, dtype=complex)
    var = np.zeros(rows.shape[0])
    for node, pair in stds.items():
        for which in (0, 1):                                  # K, then C
            sig = np.asarray(pair[which], dtype=float)
            for i in range(2):
                for j in range(2):
                    if not sig[i, j] > 0:
                        continue
                    h = REL_STEP * max(abs(float(coeffs[node][which][i, j])), float(sig[i, j]))
                    dq = [harmonic_response(model, speed, speed, F, _moved(coeffs, node, which, i, j, s * h))
                          for s in (1.0, -1.0)]
                    d = rows @ ((dq[0] - dq[1]) / (2 * h))
                    var += np.abs(d) ** 2 * sig[i, j] ** 2
    return np.sqrt(var)


def _moved(coeffs: dict, node: int, which: int, i: int, j: int, delta: float) -> dict:
    out = {n: (np.array(k, dtype=float), np.array(c, dtype=float)) for n, (k, c) in coeffs.items()}
    out[node][which][i, j] += delta
    return out


def filter_std(km) -> np.ndarray:
    """Return the per-sample posterior 1-sigma (k,) [m] of a Kalman model's outputs: sqrt(diag(E P(k|k) E^T))."""
    P, K, _ = km.steady_state()
    post = (np.eye(km.n) - K @ km.H) @ P
    return np.sqrt(np.maximum(np.einsum('ij,jk,ik->i', km.E, post, km.E), 0.0))
