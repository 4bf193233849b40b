"""
The short bearing's eccentricity against the exact root of its load equation, and the array interface.

Oracle: the load equation of the short (Ocvirk, pi film) bearing as the literature states it (Ocvirk & DuBois
1953; Childs 1993 eq. 3.38), pi S (L/D)^2 = (1 - eps^2)^2 / (eps sqrt(16 eps^2 + pi^2 (1 - eps^2))), written out here
and solved by bisection in 60-digit decimal arithmetic (its rounding is far below double precision).

Tolerance, derived: a double-precision solver gets the root of an equation whose two sides it evaluates with
relative rounding; with F(eps) the right-hand side, m = d ln F / d ln eps (written out below, |m| >= 1) and the logs
it works with no larger than Lmax = 1 + |ln sigma| + |ln eps|, the computed eps satisfies
|d eps| / eps <= eps_mach + K eps_mach Lmax / |m| (the first term: the root stored as a double, half an ulp, with
room); K = 32 (a few roundings per term, with room) -- about 1e-14 in the middle of the range, while a solver
stopped one Newton step early (or a wrong formula) misses by 1e-10 or more.
"""
from __future__ import annotations

from decimal import Decimal, localcontext
import math

from bearing_id import bearings
from bearing_id.bearings.short import ocvirk, ocvirk_batch, short_eccentricity
from bearing_id.config.params import load_rig
import numpy as np
import pytest

EPS_MACH = np.finfo(float).eps


def exact_root(sommerfeld: float, L_over_D: float) -> Decimal:
    """Eccentricity ratio solving the load equation in 60-digit arithmetic (bisection on (0, 1), 200 halvings)."""
    with localcontext() as ctx:
        ctx.prec = 60
        pi = Decimal('3.14159265358979323846264338327950288419716939937510582097494')
        sigma = pi * Decimal(sommerfeld) * Decimal(L_over_D) ** 2
        lo, hi = Decimal(0), Decimal(1)
        for _ in range(200):
            e = (lo + hi) / 2
            g = sigma * e * (16 * e * e + pi * pi * (1 - e * e)).sqrt() - (1 - e * e) ** 2     # increasing in e
            lo, hi = (e, hi) if g < 0 else (lo, e)
        return (lo + hi) / 2


def log_slope(e: float) -> float:
    """Return m = d ln F / d ln eps of the load equation's right-hand side F (|m| >= 1: F falls at least as 1/eps)."""
    q = 16 * e * e + math.pi**2 * (1 - e * e)
    return -1.0 - 4 * e * e / (1 - e * e) - (16 - math.pi**2) * e * e / q


@pytest.mark.parametrize('L_over_D', [0.25, 0.5, 1.0])
def test_eccentricity_is_the_root_of_the_load_equation(L_over_D):
    S = np.geomspace(1e-8, 1e8, 41)                     # eps from ~1e-8 to 1 - 1e-4
    got = short_eccentricity(S, L_over_D)                # the array call
    assert got.shape == S.shape
    for s, e in zip(S, got):
        ref = exact_root(float(s), L_over_D)
        sigma = math.pi * s * L_over_D**2
        tol = EPS_MACH + 32 * EPS_MACH * (1 + abs(math.log(sigma)) + abs(math.log(e))) / abs(log_slope(e))
        assert abs(Decimal(float(e)) - ref) <= Decimal(tol) * ref, (s, e, ref, tol)
    assert got[0] > 0.999 and got[-1] < 1e-7              # the range really is covered
    one = short_eccentricity(float(S[20]), L_over_D)    # a number in, a number out
    assert isinstance(one, float)
    assert abs(Decimal(one) - exact_root(float(S[20]), L_over_D)) <= Decimal(1e-13)


def test_eccentricity_refuses_a_non_positive_sommerfeld_number():
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match='Sommerfeld'):
            short_eccentricity(np.array([0.1, bad]), 0.5)


def batch_tol(D, L, c, mu, W, w, name):
    """
    Return (largest |entry| difference allowed of a batch entry from ocvirk(D, L, c, mu, W, w), ocvirk's ``name``).

    ocvirk is the batch computation for one entry; an entry of a batch may differ from it by the rounding of the
    eccentricity (the bound of the test above, d eps / eps <= eps_mach + 32 eps_mach Lmax / |m|) times the
    coefficients' sensitivity to it (kappa = |d ln K / d ln S| |m|, central differences over the viscosity, S ~ mu),
    plus a few roundings of the closed forms, whose terms grow as 1 / (1 - eps^2):
    tol = 64 eps_mach (Lmax kappa + 1 / (1 - eps^2)) (the eps_mach of the stored root is inside the second term).
    """
    s = ocvirk(D, L, c, mu, W, w)
    e = s.eccentricity
    lmax = 1 + abs(math.log(math.pi * s.sommerfeld * (L / D) ** 2)) + abs(math.log(e))
    h = 1e-4
    ref = getattr(s, name)
    up = getattr(ocvirk(D, L, c, mu * math.exp(h), W, w), name)
    dn = getattr(ocvirk(D, L, c, mu * math.exp(-h), W, w), name)
    kappa = np.linalg.norm(up - dn) / (2 * h * np.linalg.norm(ref)) * abs(log_slope(e))
    return 64 * EPS_MACH * (lmax * kappa + 1 / (1 - e * e)) * np.abs(ref).max(), ref


def test_ocvirk_batch_broadcasts_and_checks_its_inputs():
    """Arrays of clearance (2, 1) and speed (3,) broadcast to (2, 3) bearings: K, C (2, 3, 2, 2), each ocvirk's."""
    c = np.array([[80e-6], [120e-6]])
    w = np.array([100.0, 300.0, 900.0])
    K, C = ocvirk_batch(0.05, 0.02, c, 0.03, 250.0, w)
    assert K.shape == C.shape == (2, 3, 2, 2)
    for i in range(2):
        for j in range(3):
            for got, name in ((K[i, j], 'K'), (C[i, j], 'C')):
                tol, ref = batch_tol(0.05, 0.02, float(c[i, 0]), 0.03, 250.0, float(w[j]), name)
                assert np.abs(got - ref).max() <= tol, (i, j, name)
    for kw in ({'c': -c}, {'w': 0 * w}, {'w': np.array([np.nan, 1.0, 2.0])}):
        args = {'c': c, 'w': w, **kw}
        with pytest.raises(ValueError):
            ocvirk_batch(0.05, 0.02, args['c'], 0.03, 250.0, args['w'])


@pytest.mark.parametrize('model', ['short', 'finite'])
def test_coefficients_at_many_speeds_are_each_speeds(model):
    """bearings.coefficients_at (the diagnosis' call): the short bearing in one batch, others speed by speed."""
    rig = load_rig()
    b = rig.bearings[0]
    w = np.array([60.0, 200.0, 650.0])
    K, C = bearings.coefficients_at(b, w, 9.7, viscosity=0.04, clearance=60e-6, model=model)
    assert K.shape == C.shape == (3, 2, 2)
    for j in range(3):
        Kr, Cr = bearings.coefficients(b, w[j], 9.7, viscosity=0.04, clearance=60e-6, model=model)
        if model == 'short':
            for got, name in ((K[j], 'K'), (C[j], 'C')):
                tol, ref = batch_tol(float(b.diameter), float(b.length), 60e-6, 0.04, 9.7, float(w[j]), name)
                assert np.abs(got - ref).max() <= tol
        else:                                         # the same call at each speed: a few ulp (another SIMD path)
            for got, ref in ((K[j], Kr), (C[j], Cr)):
                assert np.abs(got - ref).max() <= 8 * np.spacing(np.abs(ref).max())
    with pytest.raises(ValueError, match='speed'):
        bearings.coefficients_at(b, -w, 9.7, model=model)
