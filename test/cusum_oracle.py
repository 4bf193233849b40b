"""
The average run length of a one-sided CUSUM by its integral equation: the oracle of test/test_cusum.py (not a test).

For S_n = max(0, S_{n-1} + z_n - k), z ~ N(mu, 1), alarm at S_n > h, the zero-state ARL is L(0) of (Page 1954;
Goel & Wu 1971; Vance 1986)

    L(u) = 1 + L(0) Phi(k - mu - u) + int_0^h L(x) phi(x - u + k - mu) dx      (u in [0, h]),

solved by the Nystroem method on Gauss-Legendre nodes of [0, h] with the atom at 0 as one more unknown.  The kernel
is a smooth Gaussian, so the quadrature converges fast; :func:`arl` returns the value at n and 2n nodes' difference as
its error estimate.  Independent of bearing_id.monitor.cusum (which uses Siegmund's closed-form approximation).
"""
from __future__ import annotations

import numpy as np
from scipy.stats import norm


def _arl_n(mu: float, k: float, h: float, n: int) -> float:
    x, w = np.polynomial.legendre.leggauss(n)
    x = (x + 1.0) * h / 2.0
    w = w * h / 2.0
    u = np.concatenate([[0.0], x])                    # rows: L at 0, then at the nodes
    A = np.zeros((n + 1, n + 1))
    A[:, 0] = norm.cdf(k - mu - u)                     # to the atom at 0
    A[:, 1:] = w[None, :] * norm.pdf(x[None, :] - u[:, None] + k - mu)
    L = np.linalg.solve(np.eye(n + 1) - A, np.ones(n + 1))
    return float(L[0])


def arl(mu: float, k: float, h: float, n: int = 64) -> tuple[float, float]:
    """Return (zero-state ARL [samples] of the upper CUSUM (k, h) for z ~ N(mu, 1), its quadrature error estimate)."""
    a, b = _arl_n(mu, k, h, n), _arl_n(mu, k, h, 2 * n)
    return b, abs(a - b)


def two_sided_arl(mu: float, k: float, h: float) -> tuple[float, float]:
    """
    Return (ARL, error estimate) of the two-sided scheme by 1 / ARL = 1 / ARL+ + 1 / ARL- from the integral equation.

    The combination is exact for k > 0 when the upper and lower sums cannot be positive at once (Lucas & Crosier 1982
    note it holds for the usual designs); the Monte-Carlo test checks it.
    """
    (p, ep), (m, em) = arl(mu, k, h), arl(-mu, k, h)
    a = 1.0 / (1.0 / p + 1.0 / m)
    return a, a * a * (ep / p ** 2 + em / m ** 2)
