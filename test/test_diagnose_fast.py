"""
The diagnosis' stacked prediction against its reference.

``Problem.predict`` assembles the dynamic stiffness of every (window, order) as ``Problem.predict_reference`` does
and solves the systems of equal shape in one stacked ``numpy.linalg.solve``; the two must agree to 1e-9 relative
(they are equal to rounding: the same LAPACK solve per matrix).  Checked for every candidate effect the diagnosis
offers (extra pedestal DOFs, force columns, measurement columns, bearing factors and forms, the sub-synchronous
whirl), alone and three at once, at nonzero bearing nuisance, on all windows and on a held-out subset.

The recording: the simulated rig with a whirl line at 0.45X from 2000 rpm (simulator side,
bearing_id.simulation.effects), so that the problem carries sub-synchronous data; 1 s dwells at 5 speeds after a 1.5 s
slow roll.
"""
from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope='module')
def prob():
    from bearing_id.simulation import rig as rigmod
    from bearing_id.simulation import effects as te
    from bearing_id.conventions import rpm_to_rad_s
    from bearing_id.diagnose.locate import observe
    from bearing_id.diagnose.predict import Problem
    from bearing_id.config.params import load_rig
    truth = rigmod.with_truth(load_rig(), viscosity_factor=(1.0, 1.0), clearance_factor=(1.0, 1.0))
    sched = [rigmod.Segment(float(rpm_to_rad_s(200)), 1.5)] + rigmod.step_schedule((800, 1200, 1600, 2400, 2800), 1.0)
    rec = rigmod.simulate(truth, truth.simulation.runs[0], sched, effects=[te.OilWhirl(10, 2000.0, 0.45, 0.5)])
    return Problem(observe([rec]), load_rig())


def _close(a, b):
    scale = max(np.max(np.abs(b)), 1e-300) if b.size else 1.0
    return a.shape == b.shape and (a.size == 0 or np.max(np.abs(a - b)) <= 1e-9 * scale)


def test_stacked_prediction_equals_the_reference(prob):
    from bearing_id.diagnose.effects import candidates
    rng = np.random.default_rng(2)
    cands = candidates(prob)
    names = {e.name for e in cands}
    assert {'support_flexibility', 'probe_runout', 'residual_unbalance', 'oil_whirl'} <= names
    theta = 0.2 * rng.standard_normal(prob.n_nuis)
    assert prob.has_sub

    def nl_of(e):
        lo, hi = np.asarray(e.nl_lo, float), np.asarray(e.nl_hi, float)
        return lo + (hi - lo) * rng.uniform(0.2, 0.8, lo.size) if lo.size else np.zeros(0)

    combos = [[]] + [[e] for e in cands] + [cands[i:i + 3] for i in range(0, len(cands) - 2, 3)]
    held = list(range(0, len(prob.windows), 2))
    for effects in combos:
        nls = [nl_of(e) for e in effects]
        for windows in (None, held):
            got = prob.predict(theta, effects, nls, windows)
            want = prob.predict_reference(theta, effects, nls, windows)
            assert all(_close(g, w) for g, w in zip(got, want)), [e.label for e in effects]
            np.testing.assert_array_equal(got[2], want[2])
