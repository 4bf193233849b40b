"""
Issue 13: the batched short-bearing solution (the physical method's fits) against the one-call reference.

Reference: :func:`bearing_id.bearings.short.ocvirk` (scipy's brentq on the load equation, xtol 1e-15), one call per
(clearance, viscosity, load, speed); :func:`bearing_id.bearings.short.ocvirk_batch` takes brentq's steps for all
entries at once with the same arithmetic, so the eccentricity, K and C are the same bits.
"""
from __future__ import annotations

from bearing_id.bearings.short import ocvirk, ocvirk_batch, short_eccentricity, short_eccentricity_batch
import numpy as np
import pytest


def test_eccentricity_batch_equals_brentq_over_the_whole_range():
    rng = np.random.default_rng(1)
    S = np.exp(rng.uniform(-14, 10, 3000))                 # eps from ~3e-5 to ~0.999
    for ld in (0.25, 0.4, 0.5, 1.0):
        e = short_eccentricity_batch(S, ld)
        ref = np.array([short_eccentricity(x, ld) for x in S])
        assert np.array_equal(e, ref)


def test_ocvirk_batch_equals_ocvirk():
    rng = np.random.default_rng(0)
    n = 400
    c = 1e-4 * np.exp(rng.uniform(-2.3, 2.3, n))
    mu = 0.03 * np.exp(rng.uniform(-2.3, 2.3, n))
    W = 100 * np.exp(rng.uniform(-3, 3, n))
    w = rng.uniform(10, 2000, n)
    K, C = ocvirk_batch(0.05, 0.02, c, mu, W, w)
    for i in range(n):
        s = ocvirk(0.05, 0.02, c[i], mu[i], W[i], w[i])
        assert np.array_equal(K[i], s.K) and np.array_equal(C[i], s.C)
    with pytest.raises(ValueError):
        ocvirk_batch(0.05, 0.02, c, mu, W, -w)


def test_brentq_port_equals_scipy():
    """bearing_id.bearings.short.brentq (no scipy.optimize import) takes scipy's brentq steps: the same roots."""
    import math
    from bearing_id.bearings.short import brentq
    from scipy.optimize import brentq as scipy_brentq
    rng = np.random.default_rng(5)
    for x in np.exp(rng.uniform(-14, 10, 2000)):
        sigma = math.pi * x * 0.16

        def g(e):
            return sigma * e * math.sqrt(16 * e * e + math.pi**2 * (1 - e * e)) - (1 - e * e) ** 2
        kw = {'xtol': 1e-15, 'rtol': 4 * np.finfo(float).eps, 'maxiter': 200}
        assert brentq(g, 0.0, 1.0, **kw) == scipy_brentq(g, 0.0, 1.0, **kw)
    for c in rng.uniform(-5, 5, (500, 3)):
        def f(x):
            return math.tanh(x - c[0]) + 0.1 * math.sin(c[1] * x) + 1e-3 * c[2]
        if f(-20.0) * f(20.0) < 0:
            assert brentq(f, -20.0, 20.0, 2e-12, 4 * np.finfo(float).eps) == scipy_brentq(f, -20.0, 20.0)
