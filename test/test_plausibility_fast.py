"""
Issue 13: the plausibility gate's stability threshold, a search that stops once the speeds asked about are covered.

Oracle: the dense eigenvalues of the rig's state matrix by scipy.linalg.eig with LAPACK's error bound
(test/error_bounds.py).  Decisions: a speed is refused exactly when the oracle finds it unstable (the rig's onset is
its only crossing: beyond it the system stays unstable).  A finite threshold: brentq stops within ``xtol`` = 1e-3
rad/s of the crossing, so the oracle's signs at the threshold +- 2 (xtol + 2 e / |slope|) must differ (e the
eigenvalue bound, slope = d max Re / d speed there; test/test_stability_fast.py says the same of the large model).
"""
from __future__ import annotations

import math

from bearing_id.config.params import load_rig
from bearing_id.conventions import rpm_to_rad_s
from bearing_id.identify import plausibility as pl
from bearing_id.rotor import stability
from bearing_id.rotor.assembly import RotorModel
from bearing_id.rotor.supports import bearing_fn
import pytest
from test_stability_fast import check_threshold, dense_max_real


@pytest.fixture(scope='module')
def rig():
    return load_rig()


@pytest.mark.parametrize('top_rpm', [1500.0, 3000.0, 4320.0, 9000.0])
def test_gate_threshold_decides_as_the_eigenvalues(rig, top_rpm):
    speed_max = float(rpm_to_rad_s(top_rpm))
    model = RotorModel.from_params(rig)
    bfn = bearing_fn(rig)
    thr = pl.stability_threshold(model, rig, speed_max)
    if math.isfinite(thr):
        assert thr <= speed_max
        check_threshold(model, bfn, thr)
    for w in [speed_max * f for f in (0.2, 0.5, 0.9, 0.999, 1.0)]:
        top, err = dense_max_real(model, bfn, w)
        assert abs(top) > 2 * err                       # the oracle's sign is certain at these speeds
        assert (w >= thr) == (top > 0), (top_rpm, w, thr, top)


def test_the_stable_case_stops_early_and_is_kept(rig, monkeypatch):
    calls = []
    orig = stability.max_real_part
    monkeypatch.setattr(stability, 'max_real_part', lambda *a: calls.append(a[2]) or orig(*a))
    model = RotorModel.from_params(rig)
    w = float(rpm_to_rad_s(3000.0))
    assert pl.stability_threshold(model, rig, w) == math.inf
    assert len(calls) < 40                              # fewer than the 40 points of the whole grid
    assert max(calls) >= w > sorted(calls)[-2]          # stopped at the first grid point at or above w
    n = len(calls)
    assert pl.stability_threshold(model, rig, 0.8 * w) == math.inf and len(calls) == n     # kept on the model
    assert pl.stability_threshold(model, rig, 1.2 * w) == math.inf and len(calls) > n      # beyond it: searched
