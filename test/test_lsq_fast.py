"""
Issue 13: the analytic propagation of the bearing-node 1X std through the eqs 30-37 solve (opt-in).

Reference: the central differences of :func:`bearing_id.identify.lsq.solve_coefficients` (``propagation='fd'``,
the default), whose step (1e-6 of the largest |z_B|) leaves a truncation error of up to a few 1e-6 relative (the solve
is strongly nonlinear in the small entries of z_B); so the exact derivative (:func:`bearing_id.identify.lsq.
solve_derivatives`) is tied to Richardson-extrapolated central differences (error O(h^4)) to 1e-6, and the two std
to 1e-4 relative.
"""
from __future__ import annotations

from bearing_id.config.params import load_rig
from bearing_id.identify import lsq
from bearing_id.rotor.assembly import harmonic_response, RotorModel
from bearing_id.rotor.supports import bearing_fn
import numpy as np


def _case():
    rig = load_rig()
    model = RotorModel.from_params(rig)
    w = 180.0
    F = lsq.forces_at(model, rig.simulation.runs, w)
    co = bearing_fn(rig)(w)
    b = lsq.bearing_dofs(model)
    rng = np.random.default_rng(7)
    zB = np.array([harmonic_response(model, w, w, f, co)[b].reshape(-1, 2) for f in F])
    zB = zB * (1 + 0.01 * (rng.standard_normal(zB.shape) + 1j * rng.standard_normal(zB.shape)))
    return model, w, F, zB


def testsolve_derivatives_equal_richardson_differences():
    model, w, F, zB = _case()
    fo, Lin = lsq.bearing_force_map(model, w, F)
    A, d = lsq.ls_system(zB, fo(zB))
    theta, U, s, Vh, r, n = lsq.svd_solve(A, d, lsq.DEFAULT_RTOL)
    assert r == n
    G, Dres = lsq.solve_derivatives(A, d, theta, U, s, Vh, r, zB.shape, Lin)

    def th_res(z):
        A2, d2 = lsq.ls_system(z, fo(z))
        return lsq.svd_solve(A2, d2, lsq.DEFAULT_RTOL)[0], A2 @ theta - d2

    h = 1e-6 * np.max(np.abs(zB))
    for e, idx in enumerate(np.ndindex(zB.shape)):
        for u, unit in enumerate((1.0, 1j)):
            def cd(hh):
                z1, z2 = zB.copy(), zB.copy()
                z1[idx] += unit * hh
                z2[idx] -= unit * hh
                (t1, r1), (t2, r2) = th_res(z1), th_res(z2)
                return (t1 - t2) / (2 * hh), (r1 - r2) / (2 * hh)
            (g1, m1), (g2, _) = cd(h), cd(h / 2)
            rich = (4 * g2 - g1) / 3
            assert np.max(np.abs(rich - G[:, e, u])) <= 1e-6 * np.max(np.abs(G[:, e, u]))
            assert np.max(np.abs(m1 - Dres[:, e, u])) <= 1e-6 * np.max(np.abs(Dres[:, e, u]))


def test_analytic_std_close_to_the_difference_std():
    model, w, F, zB = _case()
    fo, Lin = lsq.bearing_force_map(model, w, F)
    zs = 0.01 * np.abs(zB)
    a = lsq.solve_coefficients(model, w, zB, F, z_B_std=zs, forces_of=fo, force_lin=Lin, propagation='analytic')
    b = lsq.solve_coefficients(model, w, zB, F, z_B_std=zs, forces_of=fo)
    assert np.array_equal(a.theta, b.theta)
    assert np.max(np.abs(a.theta_std - b.theta_std)) <= 1e-4 * np.max(np.abs(b.theta_std))
