"""
Large models' damped modes (reduced screen, full-model refinement) and Campbell data against dense LAPACK.

Models: the plant-like example (a pedestal, a seal table) and the paper rig refined to 40 elements, both above
``rotor.modal.FAST_NDOF``, so :func:`~bearing_id.rotor.modal.modes_solver` takes
:class:`~bearing_id.rotor.modal.FastModes` on its own.  Oracle: every eigenpair of the full state matrix by
scipy.linalg.eig with LAPACK's error bound e for each eigenvalue (test/error_bounds.py; two routes that each meet it
agree within 2 e).  Derived from it: damped frequency within 2 e, log decrement -2 pi sigma / wd within
2 pi 2 e (1 / wd + |sigma| / wd^2), damping ratio -sigma / |lambda| within 2 (2 e) / |lambda|.  Mode shapes: each
is an eigenvector of the full model to a backward error (in the oracle's balanced state matrix) below
n eps + 10 ITER_TOL: n eps (n the state dimension) is the classic bound of a backward-stable eigensolver (LAPACK's
own shapes reach ~3 eps here), ITER_TOL = ``rotor.eigen.ITER_TOL`` the refinement's stopping rule (its inverse
iterations stop when the eigenvalue moves by less than ITER_TOL |lambda|; the vector's error is of that order, 10 x
for the slower convergence of a vector of a non-normal matrix; measured up to 1e-13); and whirls as the oracle's
shapes whirl.
"""
from __future__ import annotations

from pathlib import Path
import sys

from bearing_id.config.params import load_rig
from bearing_id.conventions import rpm_to_rad_s
from bearing_id.plots.data import campbell_data, CRITICALLY_DAMPED
from bearing_id.rotor import eigen
from bearing_id.rotor.assembly import RotorModel, state_space
from bearing_id.rotor.modal import damped_modes, FAST_NDOF, FastModes, mode_whirl, modes_solver, UNDERDAMPED_RTOL
from bearing_id.rotor.supports import bearing_fn
from error_bounds import eigen_with_bounds, EPS_MACH, state_backward_error
import numpy as np
import pytest
from test_stability_fast import check_threshold, paper_rig_refined

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'benchmarks'))
from bench_large import large_rig  # noqa: E402, I100 - the scale benchmark's rotor (its folder is on the path now)


@pytest.fixture(scope='module', params=['plant_like', 'paper_rig_40_elements'])
def case(request):
    rig = load_rig('params/examples/plant_like.yaml') if request.param == 'plant_like' else paper_rig_refined(4)
    model = RotorModel.from_params(rig)
    assert model.ndof > FAST_NDOF
    return rig, model, bearing_fn(rig)


def oracle(model, w, coeffs, n):
    """(lowest n underdamped eigenvalues, their bounds, their rotor shapes (4 n_nodes, n), all eigenvalues, bounds)."""
    lam, bound, X = eigen_with_bounds(state_space(model, w, coeffs)[0])
    # modes of vibration by the package's definition (zeta < 0.99995, rotor.modal.underdamped), applied to numpy's
    # dense eigenvalues here
    under = np.flatnonzero(lam.imag > UNDERDAMPED_RTOL * np.maximum(1.0, np.abs(lam)))
    low = under[np.argsort(lam[under].imag)][:n]
    return lam[low], bound[low], X[:4 * model.n_nodes, low], lam, bound


def test_fast_modes_are_eigenpairs_of_the_full_model(case):
    rig, model, fn = case
    top = float(rpm_to_rad_s(6000.0))
    modes = modes_solver(model, top, fn, 8)
    fm = modes.__self__
    assert isinstance(fm, FastModes) and fm.eig.red.nr < model.ndof / 3   # a real reduction
    for rpm in (300.0, 1700.0, 3900.0, 6000.0):
        w = float(rpm_to_rad_s(rpm))
        got = modes(w, fn(w), 8)
        lam, bnd, X, every, every_bnd = oracle(model, w, fn(w), 8)
        e = 2 * bnd
        assert np.all(np.abs(got.eigenvalues - lam) <= e), (rpm, got.eigenvalues, lam, e)
        wd, sig = lam.imag, lam.real
        assert np.all(np.abs(got.log_dec - (-2 * np.pi * sig / wd)) <= 2 * np.pi * e * (1 / wd + np.abs(sig) / wd**2))
        assert got.whirl == tuple(mode_whirl(model, X[:, k]) for k in range(8))
        k = int(np.argmax(every.real))
        assert abs(got.max_real - every[k].real) <= 2 * every_bnd[k]
        bound = 2 * model.ndof * EPS_MACH + 10 * eigen.ITER_TOL
        for k in range(8):
            assert state_backward_error(model, w, fn(w), got.eigenvalues[k], got.shapes[:, k]) <= bound, (rpm, k)
    assert fm.fallbacks == 0       # every speed on the fast path
    # (the 40-element paper rig's stiffness-proportional damping turns high bending modes into heavily damped pairs
    # with Im of a few rad/s -- Im / |lambda| ~ 1e-6, zeta > 0.99999: no modes of vibration, left out by both routes)


def test_campbell_data_is_the_dense_eigenvalues(case):
    rig, model, fn = case
    top = float(rpm_to_rad_s(6000.0))
    cd = campbell_data(model, fn, top)
    for i, w in enumerate(cd.speeds):
        lam, bnd, X, _, _ = oracle(model, w, fn(w), 8)
        assert np.all(np.abs(cd.frequency[i] - lam.imag) <= 2 * bnd), (w, cd.frequency[i], lam.imag)
        assert tuple(cd.whirl[i]) == tuple(mode_whirl(model, X[:, k]) for k in range(8)), w
    if rig.name.startswith('plant_like'):
        assert cd.critical.size + cd.damped_crossings.size >= 1    # crossings to check (none on the paper rig)
    assert np.all(cd.critical_zeta <= CRITICALLY_DAMPED) and np.all(cd.damped_crossings_zeta > CRITICALLY_DAMPED)
    for c, z in zip(np.r_[cd.critical, cd.damped_crossings], np.r_[cd.critical_zeta, cd.damped_crossings_zeta]):
        _, _, X, every, every_bnd = oracle(model, c, fn(c), 8)
        fwd = [j for j in np.flatnonzero(every.imag > 0) if abs(every[j].imag - c) <= 0.01 * c]
        j = min(fwd, key=lambda j: abs(every[j].imag - c))
        assert abs(every[j].imag - c) <= 2 * every_bnd[j] + 4e-9 * c      # on the 1X line to brentq's 1e-9 c
        assert abs(z - (-every[j].real / abs(every[j]))) <= 4 * every_bnd[j] / abs(every[j])
    if cd.threshold is not None and np.isfinite(cd.threshold):
        check_threshold(model, fn, cd.threshold)


def test_a_160_element_rotor_lists_its_modes_of_vibration_only():
    """
    benchmarks/bench_large.py's 160-element rotor (1288 states) at 4000 rpm: dense and fast routes list the oracle's.

    Its dense eigenvalues hold ~150 x/y pairs of heavily damped element modes (zeta > 0.99999, genuinely complex);
    under the former 1e-9 threshold the dense route listed them as the lowest "modes" (0.06 ... 150 Hz, log dec
    5e3 ... 1e7) while the reduced screen never sees them.  Both routes now give the oracle's lowest 8 modes of
    vibration within 2 e.
    """
    rig = large_rig(5)
    model, fn = RotorModel.from_params(rig), bearing_fn(rig)
    w = float(rpm_to_rad_s(4000.0))
    lam, bnd, _, every, _ = oracle(model, w, fn(w), 8)
    assert np.sum((every.imag > 1e-9 * np.abs(every)) & (every.imag <= UNDERDAMPED_RTOL * np.abs(every))) >= 100
    for route in (damped_modes(model, w, fn(w), 8), modes_solver(model, w, fn, 8)(w, fn(w), 8)):
        assert np.all(np.abs(route.eigenvalues - lam) <= 2 * bnd), (route.eigenvalues, lam)
        assert np.all(route.log_dec < 10)
