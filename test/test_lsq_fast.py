"""
The eqs 30-37 solve's derivative and the std and misfit statistic propagated through it (identify/lsq.py).

* :func:`bearing_id.identify.lsq.solve_derivatives` (Golub-Pereyra) against central differences of the SVD solve
  written here, for an overdetermined (4 runs), a square (2 runs) and a rank-deficient (1 run: rank 8 of 16, the
  minimum-norm solution) system.  Tolerance from Richardson's error estimate: fd(h/2) - f' ~ (fd(h) - fd(h/2)) / 3;
  allowed 2 |fd(h) - fd(h/2)| (6x the estimate, for the O(h^4) rest and rounding).
* Monte Carlo: bearing-node phasors drawn with their stated 1-sigma (Re and Im independent); the sample std of the
  solved coefficients must match the propagated ``theta_std`` within 5 sigma of a sample std of N draws,
  5 / sqrt(2 (N - 1)) relative, plus 1e-3 for the linearisation (ten times the noise's relative size, 1e-4 of
  |z_B|, which sets the second-order terms); and
  the misfit statistic chi2 must be chi-square(dof) distributed: its mean over the draws within 5 sigma,
  5 sqrt(2 dof / N), of dof.
"""
from __future__ import annotations

import math

from bearing_id.config.params import load_rig
from bearing_id.identify import lsq
from bearing_id.rotor.assembly import harmonic_response, RotorModel
from bearing_id.rotor.supports import bearing_fn
from bearing_id.simulation import rig as rigmod
from error_bounds import EPS_MACH, lstsq_acc, richardson_check
import numpy as np
import pytest


def _case(runs=None, seed=7, jitter=0.01):
    """Bearing-node phasors of the rig's model at 180 rad/s, each moved by ``jitter`` (relative, random)."""
    rig = load_rig()
    model = RotorModel.from_params(rig)
    w = 180.0
    runs = rig.simulation.runs if runs is None else runs
    F = lsq.forces_at(model, runs, w)
    co = bearing_fn(rig)(w)
    b = lsq.bearing_dofs(model)
    rng = np.random.default_rng(seed)
    zB = np.array([harmonic_response(model, w, w, f, co)[b].reshape(-1, 2) for f in F])
    zB = zB * (1 + jitter * (rng.standard_normal(zB.shape) + 1j * rng.standard_normal(zB.shape)))
    return model, w, F, zB


@pytest.mark.parametrize('n_runs,rank', [(4, 16), (2, 16), (1, 8)])
def test_solve_derivatives_equal_richardson_differences(n_runs, rank):
    model, w, F, zB = _case(rigmod.scenario('force')[:n_runs])
    fo, Lin = lsq.bearing_force_map(model, w, F)
    A, d = lsq.ls_system(zB, fo(zB))
    theta, U, s, Vh, r, n = lsq.svd_solve(A, d, lsq.DEFAULT_RTOL)
    assert r == rank
    G, Dres = lsq.solve_derivatives(A, d, theta, U, s, Vh, r, zB.shape, Lin)

    def th_res(z):
        A2, d2 = lsq.ls_system(z, fo(z))
        return lsq.svd_solve(A2, d2, lsq.DEFAULT_RTOL)[0], A2 @ theta - d2

    h = 1e-6 * np.max(np.abs(zB))
    n = A.shape[1]
    acc = lstsq_acc(s[0] / s[r - 1])                 # the solve on its kept rank
    # the residual A theta - d at fixed theta: each entry a sum of n + 1 terms, off by (n + 1) eps sum |terms|
    res_err = (n + 1) * EPS_MACH * (n * np.abs(A).max() * np.abs(theta).max() + np.abs(d).max())
    for e, idx in enumerate(np.ndindex(zB.shape)):
        for u, unit in enumerate((1.0, 1j)):
            def cd(hh, part):
                z1, z2 = zB.copy(), zB.copy()
                z1[idx] += unit * hh
                z2[idx] -= unit * hh
                return (th_res(z1)[part] - th_res(z2)[part]) / (2 * hh)
            richardson_check(lambda hh: cd(hh, 0), h, G[:, e, u], acc, np.abs(theta).max())
            # the residual is linear in z_B at fixed theta: the differences are exact up to its rounding
            richardson_check(lambda hh: cd(hh, 1), h, Dres[:, e, u], res_err, 1.0)


def test_propagated_std_and_misfit_statistic_match_monte_carlo():
    model, w, F, zB = _case(rigmod.scenario('force'), jitter=0.0)      # consistent with the model: chi2 ~ chi2(dof)
    fmap = lsq.bearing_force_map(model, w, F)
    zs = 1e-4 * np.abs(zB)
    sol = lsq.solve_coefficients(model, w, zB, F, z_B_std=zs, force_map=fmap)
    assert sol.rank == 16 and sol.dof > 0 and np.all(sol.determined)
    rng = np.random.default_rng(11)
    N = 1000
    thetas, chi2s = [], []
    exact = lsq.solve_coefficients(model, w, zB, F, force_map=fmap).theta
    for _ in range(N):
        z = zB + zs * (rng.standard_normal(zB.shape) + 1j * rng.standard_normal(zB.shape))
        s = lsq.solve_coefficients(model, w, z, F, z_B_std=zs, force_map=fmap)
        thetas.append(s.theta)
        chi2s.append(s.chi2)
    sample = np.std(np.array(thetas) - exact, axis=0, ddof=1)
    tol = 5 / math.sqrt(2 * (N - 1)) + 1e-3
    assert np.all(np.abs(sample / sol.theta_std - 1) <= tol), sample / sol.theta_std
    dof = sol.dof
    assert abs(np.mean(chi2s) - dof) <= 5 * math.sqrt(2 * dof / N), (np.mean(chi2s), dof)
