"""
Fitting-side effect models and the diagnosis' prediction against independent routes.

Fitting-side effect models (diagnose/effects.py) against independent routes: the simulator-side truth effects
(simulation/effects.py, e.g. pedestal DOFs appended to the FE system), the model built from params (disc mass
factor), and closed forms (a bowed shaft on rigid supports at slow roll takes the bow's shape).  The diagnosis'
stacked prediction (``Problem.predict``) against the first-order state-space route of the rotor's equations.

Tolerance of two routes that each solve a linear system Z q = F: ``error_bounds.solve_tol`` (8 n eps cond(Z) ||q||
for each backward-stable solve, the sum for their difference).
"""
import math
import types

from bearing_id.config.params import load_rig, PACKAGE_PARAMS, parse_rig
from bearing_id.conventions import dof_index
from bearing_id.diagnose import effects as fx
from bearing_id.diagnose.locate import Observations, Window
from bearing_id.diagnose.predict import Problem
from bearing_id.diagnose.report import rig_to_dict
from bearing_id.excitation import harmonic_forces
from bearing_id.rotor import supports
from bearing_id.rotor.assembly import dynamic_stiffness, probe_matrix, RotorModel
from bearing_id.simulation import effects as te, rig as rigmod
from error_bounds import solve_tol
import numpy as np
import pytest
from scipy.linalg import matrix_balance
import yaml


def truth_dynamic_stiffness(model, W, coeffs, truth):
    """Dynamic stiffness at 1X of the simulator's truth system (its extra DOFs included)."""
    M, C, K = rigmod.system_matrices(model, W, coeffs, [truth])
    return K - W * W * M + 1j * W * C


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
        Z_truth = truth_dynamic_stiffness(model, W, bf(W), truth)
        assert np.linalg.norm(q_fit - q_truth) <= solve_tol(Z, Z_truth) * np.linalg.norm(q_truth)


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
        Z_params = dynamic_stiffness(model_upd, W, W, bf(W))
        tol = solve_tol(Z_params, truth_dynamic_stiffness(model, W, bf(W), truth),
                        fx.augmented_dynamic_stiffness(model, aug, W, W, bf(W))) * np.linalg.norm(q_params)
        assert np.linalg.norm(q_truth - q_params) <= tol
        assert np.linalg.norm(q_fit - q_params) <= tol


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


# ------------------------------------------------------------------------------------------------ the prediction
def synthetic_problem(params=None, runs=2):
    """Return a diagnosis Problem on synthetic windows (1X-3X at five speeds, each run's excitation)."""
    rig = load_rig(params)
    recs = [types.SimpleNamespace(run=rig.simulation.runs[r % len(rig.simulation.runs)], probes=tuple(rig.probes))
            for r in range(runs)]
    nch = len(rig.probes)
    wins = [Window(rec=r, i0=0, i1=0, speed=rpm * math.pi / 30 * (1.0 + 1e-4 * r), X=np.full((3, nch), 1e-6 + 0j),
                   std=np.full((3, nch), 1e-8)) for r in range(runs) for rpm in (300.0, 900.0, 1500.0, 2100.0, 2700.0)]
    return Problem(Observations(recordings=recs, windows=wins, orders=(1, 2, 3)), rig)


def state_space_here(model, W, coeffs):
    """
    Return (A, B) of x' = A x + B f, x = [q; q'], assembled here from the physics of the films.

    M, C + W G, K of the rotor model (and its pedestal DOFs); a film (kb, cb) at shaft node n acts on the relative
    displacement q_n - q_p of its pedestal p, on q_n alone without one: blocks [[k, -k], [-k, k]] on (n, p), k on
    (n, n).  The known elements (seals) likewise; A = [[0, I], [-M^-1 K, -M^-1 C]], B = [0; M^-1].
    """
    n = model.ndof
    K, C, M = model.K.copy(), model.C + W * model.G, model.M
    peds = model.pedestals or {}
    films = [(node, peds.get(node), kb, cb) for node, (kb, cb) in coeffs.items()]
    films += [(node, j, kb, cb) for node, j, kb, cb in model.known_coefficients(W)]
    for node, j, kb, cb in films:
        i = dof_index(node, 'x', model.n_nodes)
        idx = [i, i + 1] if j is None else [i, i + 1, j, j + 1]
        for X, b in ((K, kb), (C, cb)):
            X[np.ix_(idx, idx)] += b if j is None else np.block([[b, -b], [-b, b]])
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])
    return A, np.vstack([np.zeros((n, n)), Minv])


@pytest.mark.parametrize('params', [None, 'plant_like'])
def test_prediction_is_the_state_space_response(params):
    """
    Problem.predict (no effect, bearing nuisance off nominal) against the first-order route x' = A x + B f.

    Oracle per (window, order) at w = order x speed: x = (j w I - A)^-1 B F with A, B assembled in this test
    (:func:`state_space_here`; bearings from :func:`rotor.supports.bearing_fn` at the same factors), solved
    balanced (scipy.linalg.matrix_balance: its condition number ~1e6 instead of ~1e13); probe readings P q.
    Tolerance: solve_tol of the balanced state matrix and of the dynamic stiffness, times ||q||.  The plant-like
    rig's bearings sit on pedestals: the film acts between shaft and pedestal DOFs.
    """
    prob = synthetic_problem(None if params is None else PACKAGE_PARAMS / 'examples' / f'{params}.yaml')
    if params:
        assert prob.model.pedestals and prob.model.known
    nb = prob.nb
    theta = np.linspace(0.15, -0.2, prob.n_nuis)
    y0, A, idx = prob.predict(theta, [], [])
    assert A.shape == (y0.size, 0) and np.array_equal(idx, np.arange(y0.size))
    model = prob.model
    bf = supports.bearing_fn(prob.rig, viscosity_factor=np.exp(theta[:nb]), clearance_factor=np.exp(theta[nb:]))
    checked = 0
    for k, win in enumerate(prob.windows):
        S = probe_matrix(model, prob.obs.probes(win.rec))
        As, Bs = state_space_here(model, win.speed, bf(win.speed))
        got = y0[prob.slices[k]].reshape(win.X.shape)
        for o, r in enumerate(prob.orders):
            F = prob.known[k].get(r)
            if F is None:
                assert np.all(got[o] == 0)
                continue
            w = r * win.speed
            Sb, T = matrix_balance(1j * w * np.eye(2 * model.ndof) - As, permute=False)
            q = (T @ np.linalg.solve(Sb, np.linalg.solve(T, Bs @ F)))[:model.ndof]
            tol = solve_tol(Sb, dynamic_stiffness(model, win.speed, w, bf(win.speed))) * np.linalg.norm(q)
            assert np.max(np.abs(got[o] - S @ q)) <= tol, (k, r)
            checked += 1
    assert checked >= len(prob.windows)          # 1X at least in every window
