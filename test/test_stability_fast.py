"""
Issue 12 item 4: large models' stability (reduced screen, full-model shift-invert refinement) against dense LAPACK.

Model: the paper rig with each of its 10 elements split in 5 (bearings, discs and probes at the same positions):
204 DOFs, above ``rotor.stability.FAST_NDOF``, so the package takes :class:`~bearing_id.rotor.stability.FastStability`
on its own.  Oracle: every eigenvalue of the full 408-state matrix by scipy.linalg.eig with LAPACK's error bound for
each (test/error_bounds.py; two routes that each meet it agree within twice it).  The threshold: brentq stops within
``xtol`` = 1e-3 rad/s of the crossing of the fast route's largest real part, which lies within e / |slope| of the
dense one's (e the eigenvalue bound, slope = d max Re / d speed there); the dense signs at the threshold +- 2 (xtol +
e / |slope|) must differ.
"""
from __future__ import annotations

import math

from bearing_id.config.params import load_rig, load_yaml_bounded, parse_rig
from bearing_id.identify import plausibility as pl
from bearing_id.rotor import stability
from bearing_id.rotor.assembly import RotorModel, state_space
from bearing_id.rotor.supports import bearing_fn
from error_bounds import eigen_with_bounds, nearest
import numpy as np
import pytest

XTOL = 1e-3        # threshold_speed's brentq tolerance [rad/s] (its default)


def paper_rig_refined(factor: int):
    """Return the paper rig with each of its 10 elements split into ``factor`` (same positions of everything)."""
    d = load_yaml_bounded('params/rig.yaml')
    d['shaft']['n_elements'] = 10 * factor
    for key in ('discs', 'bearings', 'probes'):
        for x in d[key]:
            x['node'] = factor * (x['node'] - 1) + 1
    return parse_rig(d)


@pytest.fixture(scope='module')
def case():
    rig = paper_rig_refined(5)
    model = RotorModel.from_params(rig)
    assert model.ndof > stability.FAST_NDOF             # the fast route is the one under test
    return rig, model, bearing_fn(rig)


def dense_max_real(model, bfn, w):
    """(largest real part [1/s], its error bound) by the oracle."""
    lam, bound, _ = eigen_with_bounds(state_space(model, w, bfn(w))[0])
    k = int(np.argmax(lam.real))
    return float(lam[k].real), float(bound[k])


def check_threshold(model, bfn, thr):
    """Assert that the dense largest real part changes sign within the derived distance of ``thr`` [rad/s]."""
    lo, e_lo = dense_max_real(model, bfn, thr - 1.0)
    hi, e_hi = dense_max_real(model, bfn, thr + 1.0)
    slope = (hi - lo) / 2.0
    assert slope > 0, 'the largest real part must rise through zero at the threshold'
    d = 2 * (XTOL + 2 * max(e_lo, e_hi) / slope)
    assert d < 0.1                                      # a sharp test: the threshold fixed to better than 0.1 rad/s
    assert dense_max_real(model, bfn, thr - d)[0] < 0 < dense_max_real(model, bfn, thr + d)[0], (thr, d)


def test_least_stable_eigenvalues_are_the_full_models(case):
    _, model, bfn = case
    fs = stability.FastStability(model, bfn, 1200.0)
    for w in (60.0, 300.0, 700.0, 1200.0):
        lam, bound, _ = eigen_with_bounds(state_space(model, w, bfn(w))[0])
        fast = fs.least_stable(w)
        for mu in fast:                                    # each refined value is an eigenvalue of the full model
            j = nearest(lam, mu)
            assert abs(lam[j] - mu) <= 2 * bound[j], (w, mu, lam[j], bound[j])
        top = int(np.argmax(lam.real))                     # ... and the first is the least stable one
        assert abs(fast[0] - lam[top]) <= 2 * bound[top], (w, fast[0], lam[top])


def test_threshold_is_where_the_dense_eigenvalues_cross(case):
    _, model, bfn = case
    top = 4.0 * 2 * math.pi * 4320 / 60
    thr = stability.threshold_speed(model, bfn, top)
    assert math.isfinite(thr)                               # the rig goes unstable within the range: a real test
    check_threshold(model, bfn, thr)


def test_gate_threshold_on_the_large_model(case):
    """The plausibility gate's threshold: the crossing when it lies below the speeds asked about, else inf."""
    rig, model, bfn = case
    w = 2 * math.pi * 4320 / 60
    thr = pl.stability_threshold(model, rig, w)
    assert thr < w
    check_threshold(model, bfn, thr)
    fresh = RotorModel.from_params(rig)                     # no threshold kept on it
    assert pl.stability_threshold(fresh, rig, 0.5 * thr) == math.inf
    for f in (0.25, 0.5):
        assert dense_max_real(model, bfn, f * thr)[0] < 0


def test_the_fast_route_is_taken_for_large_models_only(case, monkeypatch):
    rig, model, bfn = case
    made = []
    orig = stability.FastStability.__init__
    monkeypatch.setattr(stability.FastStability, '__init__',
                        lambda self, *a, **k: made.append(1) or orig(self, *a, **k))
    small = RotorModel.from_params(load_rig())
    stability.max_real_part_fn(small, bearing_fn(load_rig()), 100.0)
    assert not made
    stability.max_real_part_fn(model, bfn, 100.0)
    assert made
