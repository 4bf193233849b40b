"""
Issue 12 item 4: the fast stability path (reduced screen, full-model shift-invert refinement) against the dense one.

Reference: :func:`bearing_id.rotor.stability.max_real_part` (every eigenvalue of the full 2 ndof state matrix,
numpy) and :func:`~bearing_id.rotor.stability.threshold_speed` with ``method='full'``.  Models: the paper rig
(10 elements) and the same rig refined to 40 elements (nodes mapped so the bearings, discs and probes sit at the
same positions), forced onto the fast path (``method='fast'``), which large models take by default.
"""
from __future__ import annotations

import math

from bearing_id.config.params import load_yaml_bounded, parse_rig
from bearing_id.identify import plausibility as pl
from bearing_id.rotor import stability
from bearing_id.rotor.assembly import RotorModel, state_space
from bearing_id.rotor.supports import bearing_fn
import numpy as np
import pytest


def paper_rig_refined(factor: int):
    """Return the paper rig with each of its 10 elements split into ``factor`` (same positions of everything)."""
    d = load_yaml_bounded('params/rig.yaml')
    d['shaft']['n_elements'] = 10 * factor
    for key in ('discs', 'bearings', 'probes'):
        for x in d[key]:
            x['node'] = factor * (x['node'] - 1) + 1
    return parse_rig(d)


@pytest.fixture(scope='module', params=[1, 4], ids=['paper_rig', 'paper_rig_40_elements'])
def case(request):
    rig = paper_rig_refined(request.param)
    model = RotorModel.from_params(rig)
    assert model.n_nodes == 10 * request.param + 1
    return rig, model, bearing_fn(rig)


def test_least_stable_eigenvalues_are_the_full_models(case):
    rig, model, bfn = case
    fs = stability.FastStability(model, bfn, 1200.0)
    for w in (60.0, 300.0, 700.0, 1200.0):
        A, _ = state_space(model, w, bfn(w))
        ref = np.linalg.eigvals(A)
        fast = fs.least_stable(w)
        for lam in fast:                                     # each refined value is an eigenvalue of the full model
            assert np.min(np.abs(ref - lam)) <= 1e-9 * abs(lam)
        top = ref[np.argmax(ref.real)]
        assert abs(fast[0].real - top.real) <= 1e-9 * abs(top)


def test_threshold_agrees_with_the_dense_search(case):
    rig, model, bfn = case
    top = 4.0 * 2 * math.pi * 4320 / 60
    full = stability.threshold_speed(model, bfn, top, method='full')
    fast = stability.threshold_speed(model, bfn, top, method='fast')
    assert math.isfinite(full)                               # the rig goes unstable within the range: a real test
    assert abs(fast - full) <= 2e-3 + 1e-9 * full            # brentq's xtol (1e-3 rad/s) on each; far inside 0.5 %
    fn = stability.max_real_part_fn(model, bfn, top, 'fast')
    assert fn(0.99 * full) < 0 < fn(1.01 * full)


def test_gate_fast_decides_as_full(case):
    rig, _, _ = case
    for top_rpm in (1500.0, 4320.0, 9000.0):
        w = 2 * math.pi * top_rpm / 60
        full = pl.threshold_for_gate(RotorModel.from_params(rig), rig, w, method='full')
        fast = pl.threshold_for_gate(RotorModel.from_params(rig), rig, w, method='fast')
        if math.isfinite(full):
            assert abs(fast - full) <= 2e-3 + 1e-9 * full
        else:
            assert fast == math.inf


def test_auto_picks_the_fast_path_only_for_large_models(case, monkeypatch):
    rig, model, bfn = case
    made = []
    orig = stability.FastStability.__init__
    monkeypatch.setattr(stability.FastStability, '__init__',
                        lambda self, *a, **k: made.append(1) or orig(self, *a, **k))
    stability.max_real_part_fn(model, bfn, 100.0, 'auto')
    assert bool(made) == (model.ndof > stability.FAST_NDOF)
    with pytest.raises(ValueError):
        stability.max_real_part_fn(model, bfn, 100.0, 'sparse')
