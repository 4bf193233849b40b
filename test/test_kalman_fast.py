"""
Issue 13: the Kalman filter's NIS band and chunked innovations, fast paths against their references.

* :func:`bearing_id.estimation.kalman.chi2_quantile_fast` (the lower tail of a large-dof chi-square, the gamma series
summed with
  numpy) against :func:`bearing_id.stats.chi2_quantile` (the reference, itself tied to scipy) to 1e-12 relative;
  :func:`bearing_id.estimation.kalman.nis_band` against the band computed with the reference.
* :class:`bearing_id.estimation.kalman._ChunkedLTI` (the Toeplitz block now gathered by one index array, the innovation
operator
  on 64-sample chunks) against a plain per-sample loop of the same steady-state filter, 1e-9 relative.
"""
from __future__ import annotations

from bearing_id.estimation import kalman
from bearing_id.stats import chi2_quantile
import numpy as np
import pytest


@pytest.mark.parametrize('dof', [2000.0, 4096.0, 30720.0, 92604.0, 1e6])
@pytest.mark.parametrize('p', [1e-4, 0.025, 0.3, 0.5, 0.975])
def test_chi2_quantile_fast_equals_the_reference(dof, p):
    a, b = kalman.chi2_quantile_fast(p, dof), chi2_quantile(p, dof)
    assert abs(a - b) <= 1e-12 * b


def test_nis_band_equals_the_reference_band():
    for n, m in ((15436, 6), (15360, 2), (50, 2)):
        lo, hi = kalman.nis_band(n, m)
        assert lo == pytest.approx(chi2_quantile(0.025, n * m) / n, rel=1e-12)
        assert hi == pytest.approx(chi2_quantile(0.975, n * m) / n, rel=1e-12)


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
    for k in range(N):
        ref[k] = U[k] - H @ s
        s = F @ s + G @ U[k]
    assert np.max(np.abs(Y - ref)) <= 1e-9 * np.max(np.abs(ref))
    assert np.max(np.abs(s_end - s)) <= 1e-9 * np.max(np.abs(s))
