"""
The diagnosis' least squares without scipy.optimize against scipy's.

``bearing_id.trf.least_squares`` transcribes scipy's ``least_squares(method='trf', x_scale='jac')`` with
bounds and the 2-point Jacobian; it must take the same steps (same nfev, njev, status) and end at the same point,
to 1e-9 relative (it is bit for bit where the floating-point operations are the same).  Checked on bounded
problems of the kind the diagnosis solves (a few parameters, some ending on a bound, so that the reflective and
the bound-limited Jacobian steps are taken) and on the diagnosis' own fits (``select.fit`` with
``LSQ_METHOD='scipy'`` is the reference): the nuisance-only fit and a fit with a nonlinear effect, on all windows and
on a held-out fold.
"""
from __future__ import annotations

import sys

from bearing_id import trf
import numpy as np
import pytest
from scipy.optimize import least_squares as scipy_least_squares


def _rel(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)) if b.size else 0.0


def _problems():
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 3.0, 40)
    for i in range(12):
        a, k, c = rng.uniform(0.5, 2.0), rng.uniform(0.3, 2.0), rng.uniform(-0.5, 0.5)
        y = a * np.exp(-k * t) + c + 0.01 * rng.standard_normal(t.size)

        def fun(z, y=y):
            return np.concatenate([z[0] * np.exp(-z[1] * t) + z[2] - y, [0.1 * z[0]]])
        # every third problem has its optimum beyond a bound (active constraint at the end)
        hi = [3.0, 5.0, 1.0] if i % 3 else [3.0, 0.8 * k, 1.0]
        lo = [0.0, 0.0, -1.0] if i % 2 else [-np.inf, 0.0, -1.0]
        x0 = np.clip(rng.uniform([0.1, 0.1, -0.9], [2.9, 4.9, 0.9]), np.array(lo) + 1e-3, np.array(hi) - 1e-3)
        yield fun, x0, np.array(lo, float), np.array(hi, float)
    # log-factor nuisance with a Gaussian prior, bounds +-ln 3 (as select.fit), optimum pushed onto a bound
    M = rng.standard_normal((30, 4))
    d = M @ np.array([1.5, -0.4, 0.2, 2.0])

    def fun2(z):
        return np.concatenate([np.sin(M @ z) - np.sin(d), z / 0.3 * 1e-3])
    yield fun2, np.zeros(4), np.full(4, -np.log(3.0)), np.full(4, np.log(3.0))


def check_same_fit(a, b):
    """Assert two diagnose fits agree to 1e-9 relative: nuisance, nonlinear and linear parameters, chi2, 1-sigma."""
    assert _rel(a.theta, b.theta) <= 1e-9
    for x, y in zip(a.nls, b.nls):
        assert _rel(x, y) <= 1e-9
    assert _rel(a.lin, b.lin) <= 1e-9
    assert abs(a.chi2 - b.chi2) <= 1e-9 * b.chi2
    for pa, pb in zip(a.std, b.std):
        for key in pb:
            assert abs(pa[key] - pb[key]) <= 1e-9 * abs(pb[key]) or pa[key] == pb[key]


@pytest.mark.parametrize('case', list(range(13)))
def test_trf_takes_scipys_steps(case):
    fun, x0, lo, hi = list(_problems())[case]
    for max_nfev in (None, 5, 60):
        want = scipy_least_squares(fun, x0, bounds=(lo, hi), x_scale='jac', max_nfev=max_nfev, method='trf')
        got = trf.least_squares(fun, x0, lo, hi, max_nfev=max_nfev)
        assert (got.nfev, got.njev, got.status) == (want.nfev, want.njev, want.status)
        assert _rel(got.x, want.x) <= 1e-9
        assert abs(got.cost - want.cost) <= 1e-9 * max(abs(want.cost), 1e-300)
        assert _rel(got.fun, want.fun) <= 1e-9 or np.max(np.abs(got.fun - want.fun)) <= 1e-12


def test_fd_steps_respect_the_bounds():
    x0 = np.array([0.0, 1.0 - 1e-9, -2.0, 5.0])
    lo, hi = np.array([-1.0, 0.0, -2.0 - 1e-12, -np.inf]), np.array([1.0, 1.0, 3.0, np.inf])
    h = trf.fd_steps(x0, lo, hi)
    assert np.all(x0 + h >= lo) and np.all(x0 + h <= hi)
    assert h[1] < 0 and h[3] == pytest.approx(np.finfo(float).eps ** 0.5 * 5.0)


@pytest.fixture(scope='module')
def prob():
    from bearing_id import rig as rigmod
    from bearing_id.conventions import rpm_to_rad_s
    from bearing_id.diagnose.locate import observe
    from bearing_id.diagnose.predict import Problem
    from bearing_id.params import load_rig
    truth = rigmod.with_truth(load_rig(), viscosity_factor=(1.2, 0.9), clearance_factor=(0.85, 1.1))
    sched = [rigmod.Segment(float(rpm_to_rad_s(200)), 1.5)] + rigmod.step_schedule((800, 1400, 2000, 2600), 1.0)
    rec = rigmod.simulate(truth, truth.simulation.runs[0], sched)
    return Problem(observe([rec]), load_rig())


def test_diagnose_fits_equal_the_scipy_reference(prob):
    import bearing_id.diagnose.select  # noqa: F401  (the module; bearing_id.diagnose.select is also a function)
    from bearing_id.diagnose.effects import candidates
    select = sys.modules['bearing_id.diagnose.select']
    cands = candidates(prob)
    nonlin = [c for c in cands if len(c.nl_names)][:1]
    assert nonlin, 'a candidate with nonlinear parameters'
    held = list(range(0, len(prob.windows), 2))
    old = select.LSQ_METHOD
    try:
        for effects in ([], nonlin):
            for windows in (None, held):
                out = {}
                for m in ('scipy', 'fast'):
                    select.LSQ_METHOD = m
                    out[m] = select.fit(prob, effects, windows=windows)
                check_same_fit(out['fast'], out['scipy'])
    finally:
        select.LSQ_METHOD = old
