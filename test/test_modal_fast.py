"""
The fast damped-mode path (reduced screen, full-model refinement) against the dense eigen-decomposition.

Reference: :func:`bearing_id.rotor.modal.damped_modes` (every eigenpair of the full 2 ndof state matrix, numpy).
Models: the plant-like example (34 nodes, a pedestal, a seal table) and the paper rig refined to 40 elements, forced
onto the fast path; the Campbell data the report draws (critical speeds, their damping, the stability scan) must be
the dense ones.
"""
from __future__ import annotations

from bearing_id.config.params import load_rig
from bearing_id.conventions import rpm_to_rad_s
from bearing_id.plots.data import campbell_data
from bearing_id.rotor.assembly import RotorModel
from bearing_id.rotor.modal import damped_modes, FastModes, modes_solver
from bearing_id.rotor.supports import bearing_fn
import numpy as np
import pytest
from test_stability_fast import paper_rig_refined


@pytest.fixture(scope='module', params=['plant_like', 'paper_rig_40_elements'])
def case(request):
    rig = load_rig('params/examples/plant_like.yaml') if request.param == 'plant_like' else paper_rig_refined(4)
    return rig, RotorModel.from_params(rig), bearing_fn(rig)


def test_fast_modes_are_the_dense_ones(case):
    rig, model, fn = case
    top = float(rpm_to_rad_s(6000.0))
    fm = FastModes(model, top, fn(top), 8)
    assert fm.eig.red.nr < model.ndof / 3                  # a real reduction, else the test proves nothing
    for rpm in (300.0, 1700.0, 3900.0, 6000.0):
        w = float(rpm_to_rad_s(rpm))
        ref, got = damped_modes(model, w, fn(w), 8), fm.damped_modes(w, fn(w), 8)
        np.testing.assert_allclose(got.eigenvalues, ref.eigenvalues, rtol=1e-9)
        np.testing.assert_allclose(got.log_dec, ref.log_dec, rtol=1e-7, atol=1e-9)
        assert got.whirl == ref.whirl
        assert got.max_real == pytest.approx(ref.max_real, rel=1e-9)
        for k in range(8):                                  # the same shape up to a complex factor
            a, b = got.shapes[:, k], ref.shapes[:, k]
            assert abs(np.vdot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b)) == pytest.approx(1.0, abs=1e-9)
    if rig.name.startswith('plant_like'):
        assert fm.fallbacks == 0       # every speed on the fast path
    # (the 40-element paper rig's stiffness-proportional damping turns high bending modes into heavily damped pairs
    # with Im of a few rad/s that the dense solution counts among the lowest 8; the reduction has no such modes, so
    # each speed falls back to the dense solution -- the check above is what keeps the two paths equal)


def test_campbell_data_fast_equals_full(case):
    rig, model, fn = case
    top = float(rpm_to_rad_s(6000.0))
    ref = campbell_data(model, fn, top, method='full')
    got = campbell_data(model, fn, top, method='fast')
    np.testing.assert_allclose(got.frequency, ref.frequency, rtol=1e-9)
    np.testing.assert_array_equal(got.whirl, ref.whirl)
    np.testing.assert_allclose(got.critical, ref.critical, rtol=1e-8)
    np.testing.assert_allclose(got.critical_zeta, ref.critical_zeta, rtol=1e-7)
    assert got.threshold == ref.threshold or abs(got.threshold - ref.threshold) < 2e-3


def test_auto_takes_the_fast_path_only_for_large_models(case):
    rig, model, fn = case
    small = RotorModel.from_params(load_rig())
    assert not isinstance(getattr(modes_solver(small, 600.0), '__self__', None), FastModes)
    assert isinstance(getattr(modes_solver(model, 600.0, 'auto', fn), '__self__', None), FastModes)
    with pytest.raises(ValueError):
        modes_solver(model, 600.0, 'magic')
