"""
Physical plausibility gates (issue 10 item 3), applied by identify() for the CLI and the node alike.

Data the model cannot describe never give 'determined' coefficients, and the reason is in the notes.  References: the
nominal model's stability threshold (README: 3794 rpm), the bearing clearance of params/rig.yaml, and clean data that
pass.
"""
from __future__ import annotations

import copy

from bearing_id.config.params import load_rig
from bearing_id.identify import identify
from bearing_id.rotor.assembly import RotorModel
from bearing_id.simulation.rig import simulate_data
import numpy as np
import pytest


@pytest.fixture(scope='module')
def setup():
    rig = load_rig()
    model = RotorModel.from_params(rig)
    # 1-sigma 0.1 % of |X| per 1X vector (the rig's 1 % sample noise averaged over a dwell is smaller still)
    data = simulate_data(rig, rig.simulation.runs, [900.0, 1800.0, 2700.0], noise=0.001, model=model)
    rng = np.random.default_rng(5)
    data.X = data.X + (rng.standard_normal(data.X.shape) + 1j * rng.standard_normal(data.X.shape)) * data.X_std
    return rig, model, data


def notes(results):
    return ' | '.join(n for r in results for n in r.notes if n.startswith('NOT PLAUSIBLE'))


def test_clean_data_pass_the_gates(setup):
    rig, model, data = setup
    res = identify('physical', model, rig, data)
    assert all(r.fully_determined for r in res) and not notes(res)


def test_micrometres_sent_as_metres_are_refused(setup):
    rig, model, data = setup
    d = copy.copy(data)
    d.X, d.X_std = data.X * 1e6, data.X_std * 1e6
    res = identify('physical', model, rig, d)
    assert not any(r.fully_determined for r in res)
    assert all(np.all(np.isnan(r.K_std)) for r in res)
    assert 'radial clearance' in notes(res) and 'metres' in notes(res)


def test_a_speed_above_the_stability_threshold_is_refused(setup):
    rig, model, data = setup
    d = copy.copy(data)
    d.speeds = data.speeds * 1.6                      # 2700 rpm reads as 4320 rpm > 3794 rpm threshold
    res = identify('physical', model, rig, d)
    top = max(res, key=lambda r: r.speed)
    assert not top.fully_determined and 'stability threshold' in ' '.join(top.notes)
    assert '3794 rpm' in ' '.join(top.notes)


def test_a_dead_channel_is_refused(setup):
    rig, model, data = setup
    d = copy.copy(data)
    d.X, d.X_std = data.X.copy(), data.X_std.copy()
    d.X[:, :, 1] = 0.0
    d.X_std[:, :, 1] = 0.0
    res = identify('physical', model, rig, d)
    assert not any(r.fully_determined for r in res) and 'p6y' in notes(res)
