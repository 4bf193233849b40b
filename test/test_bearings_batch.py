"""
Issue 13: the batched short-bearing solution (the physical method's fits) against the one-call reference.

Reference: :func:`bearing_id.bearings.short.ocvirk` (scipy's brentq on the load equation, xtol 1e-15), one call per
(clearance, viscosity, load, speed); :func:`bearing_id.bearings.short.ocvirk_batch` takes brentq's steps for all
entries at once with the same arithmetic, so the eccentricity, K and C are the same bits; the physical method's
batched coefficients and difference Jacobian (``beta_and_grad_speeds``) then equal ``beta_and_grad`` bit for bit
(short bearings; the finite model goes through the one-call path).
"""
from __future__ import annotations

from bearing_id.bearings.short import ocvirk, ocvirk_batch, short_eccentricity, short_eccentricity_batch
from bearing_id.config.params import load_rig
from bearing_id.identify.physical import _Parametrisation
from bearing_id.rotor.assembly import RotorModel
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


@pytest.mark.parametrize('load,bearing_model', [(False, 'short'), (True, 'short'), (False, 'finite')])
def test_physical_batched_coefficients_equal_the_per_call_path(load, bearing_model):
    rig = load_rig()
    model = RotorModel.from_params(rig)
    par = _Parametrisation(model, rig, ('viscosity', 'clearance'), load, bearing_model)
    p = np.log(par.nominal) + 0.1 * np.random.default_rng(2).standard_normal(par.nominal.size)
    speeds = [60.0, 150.0, 314.0]
    for (beta, G), w in zip(par.beta_and_grad_speeds(p, speeds), speeds):
        b_ref, G_ref = par.beta_and_grad(p, w)
        assert np.array_equal(beta, b_ref) and np.array_equal(G, G_ref)
    for (beta, G), w in zip(par.beta_and_grad_speeds(p, speeds, want_grad=False), speeds):
        assert G is None and np.array_equal(beta, par.beta(p, w))


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
