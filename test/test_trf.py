"""
bearing_id.trf.least_squares (scipy's trf transcribed) against scipy's least_squares(method='trf'), the reference.

The physical fit of ``bearing-id identify`` runs its bounded least squares through bearing_id.trf so that it needs no
scipy.optimize import (issue 13).  The transcription performs scipy's floating-point operations in scipy's order, so
the iterates are the same bit for bit: compared here with an analytic Jacobian and fixed scales (the physical fit's
options) and with scipy's defaults (finite differences, x_scale='jac'), on random bounded problems with active
bounds; with numpy's SVD (the physical fit's choice: no scipy.linalg import) to rounding; and on whole physical
identifications (fitted parameters and coefficients to 1e-12 relative).
"""
from bearing_id import trf
from bearing_id.identify import physical
import numpy as np
import pytest
from scipy.optimize import least_squares as scipy_least_squares


def _problem(seed):
    """Return (fun, jac, x0, lb, ub): a smooth nonlinear residual (m = 3 n) with some bounds active at the minimum."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 6))
    A = rng.standard_normal((3 * n, n))
    b = rng.standard_normal(3 * n)
    c = rng.uniform(0.1, 1.0, 3 * n)

    def fun(x):
        return A @ x + c * np.sin(A @ x) - b

    def jac(x):
        return A + (c * np.cos(A @ x))[:, None] * A

    x0 = rng.uniform(-0.35, 0.35, n)
    lb = np.full(n, -np.inf)
    ub = np.full(n, np.inf)
    lb[0], ub[-1] = -0.6, 0.4                     # tight enough to be active at many minima
    return fun, jac, x0, lb, ub


@pytest.mark.parametrize('seed', range(12))
@pytest.mark.parametrize('options', [{'x_scale': 1.0, 'ftol': 1e-12, 'xtol': 1e-12, 'gtol': 1e-12},
                                     {'x_scale': np.array([2.0, 0.5, 1.0, 3.0, 1.5]), 'ftol': 1e-10},
                                     {}])
@pytest.mark.parametrize('analytic', [True, False])
def test_trf_takes_scipys_steps(seed, options, analytic):
    fun, jac, x0, lb, ub = _problem(seed)
    opts = dict(options)
    if isinstance(opts.get('x_scale'), np.ndarray):
        opts['x_scale'] = opts['x_scale'][:x0.size]
    want = scipy_least_squares(fun, x0, jac=jac if analytic else '2-point', bounds=(lb, ub), method='trf',
                               **({'x_scale': 'jac'} | opts))
    got = trf.least_squares(fun, x0, lb, ub, jac=jac if analytic else None, **opts)
    np.testing.assert_array_equal(got.x, want.x)
    assert (got.nfev, got.njev, got.status, got.success, got.message) == \
        (want.nfev, want.njev, want.status, want.success, want.message)
    assert got.cost == want.cost


@pytest.mark.parametrize('seed', range(12))
def test_trf_with_numpys_svd_takes_scipys_steps_to_rounding(seed):
    """With numpy's gesdd (the physical fit's, no scipy.linalg import): scipy's result to 1e-10, same status."""
    fun, jac, x0, lb, ub = _problem(seed)
    opts = {'x_scale': 1.0, 'ftol': 1e-12, 'xtol': 1e-12, 'gtol': 1e-12}
    want = scipy_least_squares(fun, x0, jac=jac, bounds=(lb, ub), method='trf', **opts)
    got = trf.least_squares(fun, x0, lb, ub, jac=jac, svd=np.linalg.svd, **opts)
    np.testing.assert_allclose(got.x, want.x, rtol=1e-10, atol=1e-12)
    assert got.success == want.success
    assert got.cost == pytest.approx(want.cost, rel=1e-10, abs=1e-20)


def test_trf_refuses_what_it_does_not_transcribe():
    fun, jac, x0, lb, ub = _problem(0)
    with pytest.raises(ValueError):
        trf.least_squares(fun, x0, np.full(x0.size, -np.inf), np.full(x0.size, np.inf), jac=jac)
    with pytest.raises(ValueError):
        trf.least_squares(fun, x0, lb, ub, jac=jac, ftol=1e-20)
    with pytest.raises(ValueError):
        trf.least_squares(fun, x0, lb, ub, jac=jac, x_scale=-1.0)


@pytest.mark.parametrize('bearing_model', ['short', 'finite'])
def test_physical_fit_by_trf_equals_scipy(bearing_model, monkeypatch):
    """Whole physical identifications (3 speeds, 2 runs, noisy 1X data): the same parameters and coefficients."""
    from bearing_id.identify.harmonics import simulate_data
    from bearing_id.params import load_rig
    from bearing_id.rotor.assembly import RotorModel
    rig = load_rig()
    model = RotorModel.from_params(rig)
    data = simulate_data(rig, rig.simulation.runs, (900, 1800, 2700), model=model)
    rng = np.random.default_rng(7)
    data.X_std = 1e-3 * np.abs(data.X) + 1e-12
    data.X = data.X + data.X_std * (rng.standard_normal(data.X.shape) + 1j * rng.standard_normal(data.X.shape))
    calls = []
    orig = trf.least_squares

    def counted(*a, **k):
        calls.append(1)
        return orig(*a, **k)

    monkeypatch.setattr(trf, 'least_squares', counted)
    fast = physical.identify_physical(model, rig, data, bearing_model=bearing_model)
    assert calls                                            # bearing_id.trf ran
    monkeypatch.setattr(physical, 'LSQ_METHOD', 'scipy')
    ref = physical.identify_physical(model, rig, data, bearing_model=bearing_model)
    fa, fb = fast[0].extra['fit'], ref[0].extra['fit']
    np.testing.assert_allclose(fa.values, fb.values, rtol=1e-12, atol=0)
    for a, b in zip(fast, ref):
        np.testing.assert_allclose(a.K, b.K, rtol=1e-12, atol=0)
        np.testing.assert_allclose(a.C, b.C, rtol=1e-12, atol=0)
        np.testing.assert_allclose(a.K_std, b.K_std, rtol=1e-12, atol=0)
