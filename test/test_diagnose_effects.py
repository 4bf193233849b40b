"""
Fitting-side effect models against independent routes.

Fitting-side effect models (diagnose/effects.py) against independent routes: the simulator-side truth effects
(truth_effects.py, e.g. pedestal DOFs appended to the FE system), the model built from params (disc mass factor), and
closed forms (a bowed shaft on rigid supports at slow roll takes the bow's shape).
"""
import math

from bearing_id.config.params import load_rig, parse_rig
from bearing_id.conventions import dof_index
from bearing_id.diagnose import effects as fx
from bearing_id.diagnose.report import rig_to_dict
from bearing_id.excitation import harmonic_forces
from bearing_id.rotor import supports
from bearing_id.rotor.assembly import dynamic_stiffness, probe_matrix, RotorModel
from bearing_id.simulation import effects as te, rig as rigmod
import numpy as np
import pytest


@pytest.fixture(scope='module')
def setup():
    rig = load_rig()
    model = RotorModel.from_params(rig)
    return rig, model, supports.bearing_fn(rig)


def test_support_series_impedance_equals_appended_pedestal_dofs(setup):
    rig, model, bf = setup
    truth = te.SupportFlexibility(10, k=(4e5, 2e5), c=(30.0, 80.0), mass=(0.4, 0.25))
    extra = {'effects': [{'effect': 'support_flexibility', 'bearing_node': 10, 'directions': d, 'mass': m,
                          f'k_{d}': k, f'c_{d}': c} for d, k, c, m in (('x', 4e5, 30.0, 0.4),
                                                                       ('y', 2e5, 80.0, 0.25))]}
    aug = rig.replace(extra=extra)
    run = rig.simulation.runs[1]
    for rpm in (700.0, 1900.0, 2900.0):
        W = rpm * math.pi / 30
        q_truth = rigmod.steady_state_response(model, W, bf(W), run.excitation, [truth])[1.0][:model.ndof]
        Z = fx.augmented_dynamic_stiffness(model, aug, W, W, bf(W))
        q_fit = np.linalg.solve(Z, harmonic_forces(run.excitation, W, model.n_nodes)[1.0])
        assert np.max(np.abs(q_fit - q_truth)) <= 1e-9 * np.max(np.abs(q_truth))


def test_disc_mass_error_three_routes_agree(setup):
    rig, model, bf = setup
    factor = 1.3
    truth = te.DiscMassError(rig, 4, factor)
    rig_updated = rig.replace(discs=tuple(d.__class__(**{**d.__dict__, 'mass_factor': factor}) if d.node == 4 else d
                                          for d in rig.discs))
    model_upd = RotorModel.from_params(rig_updated)
    aug = rig.replace(extra={'effects': [{'effect': 'disc_mass_error', 'node': 4, 'mass_factor': factor}]})
    run = rig.simulation.runs[0]
    for rpm in (900.0, 2500.0):
        W = rpm * math.pi / 30
        F = harmonic_forces(run.excitation, W, model.n_nodes)[1.0]
        q_truth = rigmod.steady_state_response(model, W, bf(W), run.excitation, [truth])[1.0]
        q_params = np.linalg.solve(dynamic_stiffness(model_upd, W, W, bf(W)), F)
        q_fit = np.linalg.solve(fx.augmented_dynamic_stiffness(model, aug, W, W, bf(W)), F)
        scale = np.max(np.abs(q_params))
        assert np.max(np.abs(q_truth - q_params)) <= 1e-9 * scale
        assert np.max(np.abs(q_fit - q_params)) <= 1e-9 * scale


def test_bow_on_rigid_supports_at_slow_roll_takes_the_bow_shape(setup):
    """
    Check the bow on rigid supports at slow roll against the closed form.

    Closed form: with rigid supports at the bearings and negligible speed, K q = K b with q = 0 at the supports,
    and the bow (zero at the bearings) is the solution: the midspan reads the bow amplitude.
    """
    rig, model, _ = setup
    bow = fx.ShaftBow(model)
    W = 0.5  # rad/s: inertia and gyroscopics negligible
    stiff = {n: (np.eye(2) * 1e13, np.zeros((2, 2))) for n in model.bearing_nodes}
    Z = dynamic_stiffness(model, W, W, stiff)
    q = np.linalg.solve(Z, bow.force)
    mid = dof_index(6, 'x', model.n_nodes)
    assert abs(q[mid] - 1.0) < 1e-5
    assert abs(q[mid + 1] - (-1j)) < 1e-5          # forward: y lags x by 90 deg


def test_truth_bow_force_matches_its_shape_through_the_shaft(setup):
    """
    Check the simulator's bow force against its shape through the shaft.

    Simulator bow (sine over the shaft) on rigid supports at slow roll: midspan reading = bow relative to the
    line through the bearing nodes, 1 - sin(pi z_b / L) for unit crest (a different route from the fit side).
    """
    rig, model, _ = setup
    truth = te.ShaftBow(rig, 1.0, 0.0)
    W = 0.5
    stiff = {n: (np.eye(2) * 1e13, np.zeros((2, 2))) for n in model.bearing_nodes}
    q = np.linalg.solve(dynamic_stiffness(model, W, W, stiff), truth.forces(W, model.ndof)[1.0])
    z = np.asarray(model.node_z)
    expected = 1.0 - math.sin(math.pi * z[1] / z[-1])
    assert abs(q[dof_index(6, 'x', model.n_nodes)] - expected) < 1e-5


def test_augmented_params_round_trip(setup, tmp_path):
    rig, model, bf = setup
    extra = {'effects': [{'effect': 'residual_unbalance', 'node': 8, 'me': 2e-5, 'phase_deg': 30.0},
                         {'effect': 'probe_runout', 'probe': 'p6x', 'runout': 4e-6, 'phase_deg': 10.0}]}
    aug = rig.replace(extra=extra)
    import yaml
    back = parse_rig(yaml.safe_load(yaml.safe_dump(rig_to_dict(aug))))
    assert back == rig and back.extra == extra
    W = 2000 * math.pi / 30
    F = fx.augmented_forces(model, back, W)[1.0]
    i = dof_index(8, 'x', model.n_nodes)
    me = 2e-5 * np.exp(1j * math.radians(30.0))
    assert abs(F[i] - me * W * W) < 1e-12 and abs(F[i + 1] + 1j * me * W * W) < 1e-12
    assert [d['effect'] for d in fx.measurement_corrections(back)] == ['probe_runout']
    S = probe_matrix(model, rig.probes)
    assert S.shape == (2, model.ndof)
