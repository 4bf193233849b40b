"""
Issue 13: the plausibility gate's shortened stability search decides as the full search does.

Reference: :func:`bearing_id.identify.plausibility.stability_threshold` (the full geometric-grid search of
:func:`bearing_id.rotor.stability.threshold_speed` with brentq), on fresh models (no cached threshold), for data
below the threshold (the shortened search stops early) and data reaching above it (it must find the same threshold).
"""
from __future__ import annotations

import math

from bearing_id.config.params import load_rig
from bearing_id.conventions import rpm_to_rad_s
from bearing_id.identify import plausibility as pl
from bearing_id.rotor.assembly import RotorModel
import pytest


@pytest.fixture(scope='module')
def rig():
    return load_rig()


@pytest.mark.parametrize('top_rpm', [1500.0, 3000.0, 4320.0, 9000.0])
def test_gate_threshold_decides_as_the_full_search(rig, top_rpm):
    speed_max = float(rpm_to_rad_s(top_rpm))
    full = pl.stability_threshold(RotorModel.from_params(rig), rig, speed_max)
    fast = pl.threshold_for_gate(RotorModel.from_params(rig), rig, speed_max)
    if math.isfinite(fast):
        assert fast == full                                   # same grid, same bracket, same brentq: same bits
    else:
        assert full > speed_max
    speeds = [speed_max * f for f in (0.2, 0.5, 0.9, 0.999, 1.0)]
    assert [w >= fast for w in speeds] == [w >= full for w in speeds]


def test_the_stable_case_stops_early(rig, monkeypatch):
    from bearing_id.rotor import stability
    calls = []
    orig = stability.max_real_part
    monkeypatch.setattr(stability, 'max_real_part', lambda *a: calls.append(a[2]) or orig(*a))
    model = RotorModel.from_params(rig)
    thr = pl.threshold_for_gate(model, rig, float(rpm_to_rad_s(3000.0)), certify=False)
    assert thr == math.inf and len(calls) < pl.THRESHOLD_GRID
    assert max(calls) >= rpm_to_rad_s(3000.0) > sorted(calls)[-2]


@pytest.mark.parametrize('top_rpm', [1500.0, 3000.0, 4320.0, 9000.0])
def test_certified_search_decides_as_the_eigenvalues(rig, top_rpm):
    """Issue 13: the Cayley-power certificate only skips eigenvalue problems; the threshold is the same bits."""
    speed_max = float(rpm_to_rad_s(top_rpm))
    plain = pl.threshold_for_gate(RotorModel.from_params(rig), rig, speed_max, certify=False)
    cert = pl.threshold_for_gate(RotorModel.from_params(rig), rig, speed_max, certify=True)
    assert cert == plain or (math.isinf(cert) and math.isinf(plain))


@pytest.mark.parametrize('example', ['paper_rig', 'plant_like'])
def test_certificate_never_proves_an_unstable_model_stable(example):
    """
    Check certified_stable => every eigenvalue in the left half plane (the dense eigenvalues, the reference).

    Over a speed range that crosses the rig's threshold; and it does prove the clearly stable points.
    """
    from pathlib import Path
    import numpy as np
    from bearing_id.rotor.supports import bearing_fn
    from bearing_id.rotor.assembly import state_space
    rig = load_rig(None if example == 'paper_rig' else
                   Path(__file__).resolve().parent.parent / 'params' / 'examples' / f'{example}.yaml')
    model = RotorModel.from_params(rig)
    fn = bearing_fn(rig)
    proved, unstable = 0, 0
    for w in np.geomspace(30.0, 3000.0, 25):
        A = state_space(model, w, fn(w))[0]
        top = float(np.max(np.linalg.eigvals(A).real))
        ok = pl.certified_stable(A, pl.CAYLEY_STEP / w)
        if ok:
            assert top < 0, w
            proved += 1
        unstable += top > 0
    assert proved >= 5 and unstable >= 1
