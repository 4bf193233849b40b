"""
The Kalman filter's NIS band and its chunked evaluation, against independent references.

* :func:`bearing_id.estimation.kalman.nis_band` (scipy.special.chdtri, the inverse) against the chi-square CDF
  (scipy.special.gammainc) at the band's edges.  The band judges the mean NIS of N steps of m channels, whose own
  1-sigma is sqrt(2 m / N) (chi-square with N m dof, divided by N): each edge must sit within 0.01 of that sigma of
  the exact quantile, i.e. |CDF(edge) - level| <= pdf(edge) x 0.01 sigma (first order; the pdf in closed form).
* :class:`bearing_id.estimation.kalman._ChunkedLTI` (the filter's chunked linear map) against a plain per-sample loop
  written here.  Tolerance (derived): each route's rounding per step is at most n eps (||F|| |s| + ||G|| |u|),
  propagated through sum_j ||F^j|| (test/kf_oracle.py), and the chunked route's precomputed powers C F^i (formed by
  log2 L doublings) add log2 L times that; outputs map it by ||C||, plus the direct term's n eps ||D|| |u|.
"""
from __future__ import annotations

import math

from bearing_id.estimation import kalman
from kf_oracle import EPS, growth_sum
import numpy as np
import pytest
from scipy.special import gammainc, gammaln


@pytest.mark.parametrize('n,m', [(1, 1), (7, 3), (50, 2), (100, 2), (15360, 2), (15436, 6), (20480, 2)])
def test_nis_band_edges_are_the_chi_square_quantiles(n, m):
    lo, hi = kalman.nis_band(n, m)
    k = n * m
    sigma = math.sqrt(2 * m / n)
    for edge, level in ((lo, 0.025), (hi, 0.975)):
        x = edge * n                                           # the chi-square variable
        pdf = math.exp((k / 2 - 1) * math.log(x) - x / 2 - (k / 2) * math.log(2) - gammaln(k / 2))
        assert abs(gammainc(k / 2, x / 2) - level) <= pdf * (0.01 * sigma * n)


@pytest.mark.parametrize('L', [16, 32, 64, 128])
def test_chunked_innovations_equal_a_plain_loop(L):
    rng = np.random.default_rng(4)
    n, m = 12, 3
    A = rng.standard_normal((n, n))
    Phi = 0.95 * A / np.max(np.abs(np.linalg.eigvals(A)))
    H = rng.standard_normal((m, n))
    K = 0.05 * rng.standard_normal((n, m))
    F, G = Phi @ (np.eye(n) - K @ H), Phi @ K
    N = 1000 + 7                                        # a padded last chunk
    U = rng.standard_normal((N, m))
    s0 = rng.standard_normal(n)
    op = kalman._ChunkedLTI(F, G, -H, np.eye(m), L)
    Y, s_end = op.run(U, s0)
    s = s0.copy()
    ref = np.empty((N, m))
    states = np.empty((N, n))
    for k in range(N):
        states[k] = s
        ref[k] = U[k] - H @ s
        s = F @ s + G @ U[k]
    u_max, s_max = np.abs(U).max(), np.abs(states).max()
    step = n * EPS * (np.linalg.norm(F, 2) * s_max + np.linalg.norm(G, 2) * u_max) * math.sqrt(n)
    d = (2 + math.log2(L)) * growth_sum(F, N) * step
    assert np.abs(Y - ref).max() <= np.linalg.norm(H, 2) * d + n * EPS * u_max
    assert np.abs(s_end - s).max() <= d
