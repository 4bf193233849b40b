"""
Paper and conventional methods on simulated data with known truth (identify/paper.py, conventional.py, result.py).

The truth coefficients here are hand-made (anisotropic, cross-coupled, speed dependent, of the size of the rig's
short-bearing coefficients), so the tests do not depend on the bearing models.
"""
import json

from bearing_id.config.params import load_rig, Probe
from bearing_id.conventions import dof_index, rpm_to_rad_s
from bearing_id.identify import eq38_error, harmonics
from bearing_id.identify.conventional import identify_conventional, interpolate
from bearing_id.identify.lsq import coefficient_scales
from bearing_id.identify.paper import coeffs_to_theta, identify_paper, kf_bearing_vectors
from bearing_id.rotor.assembly import RotorModel
from bearing_id.simulation import rig as rigmod
from bearing_id.simulation.rig import simulate_data
from error_bounds import lstsq_acc, RICCATI_RESIDUAL, richardson_check
import numpy as np
import pytest


def theory_fn(w, f=1.0):
    K = f * np.array([[2.0e5, 1.2e5], [-0.6e5, 3.0e5]]) * (1 + w / 300)
    C = f * np.array([[300.0, 60.0], [60.0, 500.0]])
    return {2: (K, C), 10: (1.1 * K, 0.9 * C)}


def truth_fn(w):
    return theory_fn(w, 1.25)


@pytest.fixture(scope='module')
def setup():
    rig = load_rig()
    return rig, RotorModel.from_params(rig)


def exact_bearing_vectors(rig, model, runs, speeds):
    """Bearing-node phasors (nr, ns, nb, 2) from rig.steady_state_response (the simulator's own solve)."""
    out = np.zeros((len(runs), len(speeds), 2, 2), dtype=complex)
    for s, w in enumerate(speeds):
        for r, run in enumerate(runs):
            q = rigmod.steady_state_response(model, w, truth_fn(w), run.excitation)[1.0]
            for b, n in enumerate(model.bearing_nodes):
                out[r, s, b] = q[dof_index(n, 'x', model.n_nodes)], q[dof_index(n, 'y', model.n_nodes)]
    return out


def test_paper_algebra_recovers_truth_from_exact_bearing_displacements(setup):
    # Zero noise, exact bearing-node phasors of two runs: eqs 30-37 are exact, so the only error is round-off
    # amplified by the condition (~1e3 here): 1e-6 relative leaves 1e3 of margin over cond * eps * ||.||.
    rig, model = setup
    runs = rig.simulation.runs
    speeds = [float(rpm_to_rad_s(s)) for s in (900, 1800, 2700)]
    data = simulate_data(rig, runs, (900, 1800, 2700), bearing_fn=truth_fn, model=model)
    zB = exact_bearing_vectors(rig, model, runs, speeds)
    res = identify_paper(model, rig, data, rig.probes, runs, {'bearing_fn': theory_fn, 'z_B': zB})
    assert len(res) == 3
    for r in res:
        tr = truth_fn(r.speed)
        for b, n in enumerate(r.nodes):
            np.testing.assert_allclose(r.K[b], tr[n][0], rtol=1e-6, atol=1e-6 * np.abs(tr[n][0]).max())
            np.testing.assert_allclose(r.C[b], tr[n][1], rtol=1e-6, atol=1e-6 * np.abs(tr[n][1]).max())
        assert r.extra['ls_rank'] == 16 and r.unknowns == 16
        assert r.residual < 1e-10


def test_one_run_is_rank_deficient_per_bearing_row(setup):
    # one run gives one complex equation per bearing row for two complex unknowns: rank 8 of 16 (not 16)
    rig, model = setup
    runs = rig.simulation.runs[:1]
    w = float(rpm_to_rad_s(1500))
    data = simulate_data(rig, runs, (1500,), bearing_fn=truth_fn, model=model)
    zB = exact_bearing_vectors(rig, model, runs, [w])
    r = identify_paper(model, rig, data, rig.probes, runs, {'bearing_fn': theory_fn, 'z_B': zB})[0]
    assert r.extra['ls_rank'] == 8
    assert not r.fully_determined
    assert np.all(np.isnan(r.K_std[~r.K_determined]))


@pytest.fixture(scope='module')
def node6_recordings(setup):
    rig, model = setup
    return [rigmod.simulate_run(rig, run, speeds_rpm=[1200, 2100], dwell=1.0, bearing_fn=truth_fn, noise=0.01,
                                model=model) for run in rig.simulation.runs]


def test_paper_kf_route_flags_what_unbalance_at_node6_cannot_determine(setup, node6_recordings):
    rig, model = setup
    data = harmonics.from_recordings(node6_recordings)
    assert data.X.shape == (2, 2, 2)
    res = identify_paper(model, rig, data, data.probes, data.runs, {'bearing_fn': theory_fn})
    for r in res:
        # two unbalance runs and the node-6 probe pair: 8 real numbers per speed cannot fix 16 coefficients
        assert r.extra['data_structural_rank'] == 8
        assert r.rank <= 8
        assert not r.fully_determined
        assert np.all(np.isnan(r.K_std[~r.K_determined])) and np.all(np.isnan(r.C_std[~r.C_determined]))
        assert len(r.undetermined_names()) >= 8
        assert any('Kalman filter' in n for n in r.notes)
        # the KF is fed the theory: its bearing displacements stay within a few % of the theory model's prediction
        # even though the truth is 25 % stiffer -- the notes must say by how much
        assert any("differ from the theory model's prediction" in n for n in r.notes)


def test_conventional_with_a_probe_at_the_bearing_is_exact(setup):
    # probes at the bearing nodes (2, 10) and one node inward (3, 9): the interpolation weight of the bearing-node
    # probe is 1, so z_B is exact and the shared solve must return the truth to round-off (as above).
    rig, model = setup
    probes = tuple(Probe(f'p{n}{d}', n, d) for n in (2, 3, 9, 10) for d in ('x', 'y'))
    data = simulate_data(rig, rig.simulation.runs, (1200, 2400), probes=probes, bearing_fn=truth_fn,
                         model=model)
    res = identify_conventional(model, rig, data, probes, data.runs, {'bearing_fn': theory_fn})
    for r in res:
        tr = truth_fn(r.speed)
        for b, n in enumerate(r.nodes):
            np.testing.assert_allclose(r.K[b], tr[n][0], rtol=1e-6, atol=1e-6 * np.abs(tr[n][0]).max())
            np.testing.assert_allclose(r.C[b], tr[n][1], rtol=1e-6, atol=1e-6 * np.abs(tr[n][1]).max())


def test_conventional_interpolation_weights_closed_form(setup):
    # equal elements: a bearing at node 2 between probes at nodes 1 and 3 gets (X1 + X3) / 2; probes at 3 and 4
    # (same side) extrapolate: 2 X3 - X4
    rig, model = setup
    probes = (Probe('a', 1, 'x'), Probe('b', 3, 'x'), Probe('c', 1, 'y'), Probe('d', 3, 'y'),
              Probe('e', 9, 'x'), Probe('f', 8, 'x'), Probe('g', 9, 'y'), Probe('h', 8, 'y'))
    X = np.array([1 + 2j, 3 - 1j, 0.5j, 2.0, 4.0, 1j, -1.0, 2 + 2j])
    z, _ = interpolate(model, probes, X)
    assert z[0, 0] == pytest.approx((X[0] + X[1]) / 2)
    assert z[0, 1] == pytest.approx((X[2] + X[3]) / 2)
    assert z[1, 0] == pytest.approx(2 * X[4] - X[5])          # node 10 from nodes 9 and 8
    assert z[1, 1] == pytest.approx(2 * X[6] - X[7])


def test_conventional_needs_two_probes_per_direction(setup):
    rig, model = setup
    data = simulate_data(rig, rig.simulation.runs, (1200,), bearing_fn=truth_fn, model=model)
    with pytest.raises(ValueError, match='needs two'):
        identify_conventional(model, rig, data, rig.probes, data.runs, {'bearing_fn': theory_fn})


def test_eq38_error_closed_form():
    # paper eq 38: mean over speeds of |actual - estimated| / |actual| x 100
    tr = [truth_fn(100.0), truth_fn(200.0)]
    est = [{n: (1.1 * K, 0.8 * C) for n, (K, C) in t.items()} for t in tr]
    e = eq38_error(est, tr)
    assert e['K'] == pytest.approx(10.0) and e['C'] == pytest.approx(20.0)
    assert e['K_cross'] == pytest.approx(10.0) and e['node10.Cyy'] == pytest.approx(20.0)


def test_to_dict_is_json_and_hides_nothing_silently(setup):
    rig, model = setup
    runs = rig.simulation.runs[:1]
    w = float(rpm_to_rad_s(1500))
    data = simulate_data(rig, runs, (1500,), bearing_fn=truth_fn, model=model)
    r = identify_paper(model, rig, data, rig.probes, runs,
                       {'bearing_fn': theory_fn, 'z_B': exact_bearing_vectors(rig, model, runs, [w])})[0]
    d = json.loads(json.dumps(r.to_dict()))
    assert d['speed_rpm'] == pytest.approx(1500.0) and d['unknowns'] == 16 and d['method'] == 'paper'
    b = d['bearings'][0]
    assert np.array(b['K']).shape == (2, 2) and b['determined']['K'] == r.K_determined[0].tolist()
    assert all(v is None for row, ok in zip(b['K_std'], b['determined']['K']) for v, o in zip(row, ok) if not o)
    assert d['rank'] == r.rank and d['fully_determined'] is False


# ------------------------------------------------------------------------------------------------ theory dominance
def _force_recordings(rig, model, probes, speeds_rpm, noise, seed=3):
    return [rigmod.simulate_run(rig, run, speeds_rpm=speeds_rpm, dwell=0.6, ramp=0.0, probes=probes,
                                bearing_fn=truth_fn, noise=noise, seed=seed + k, model=model)
            for k, run in enumerate(rigmod.scenario('force'))]


@pytest.fixture(scope='module')
def force_node6(setup):
    rig, model = setup
    p6 = tuple(Probe(f'p6{d}', 6, d) for d in ('x', 'y'))
    return harmonics.from_recordings(_force_recordings(rig, model, p6, [1500], 0.01))


def test_theory_flag_trips_on_force_plan_at_node6(setup, force_node6):
    # Directional forces + node 6: the DATA determine all 16 (design check, structural rank 16) but the KF's
    # bearing-node estimates come from the theory it was given (25 % off the truth): the result must be flagged as
    # following the theory, not reported as 16 determined coefficients.
    rig, model = setup
    r = identify_paper(model, rig, force_node6, force_node6.probes, force_node6.runs, {'bearing_fn': theory_fn})[0]
    assert r.extra['data_structural_rank'] == 16
    sens = r.extra['theory_sensitivity']
    assert r.extra['theory_fraction'] > 0.5
    assert np.sum(sens > 0.5) >= 12
    det = np.concatenate([r.K_determined.reshape(-1), r.C_determined.reshape(-1)])
    assert not np.any(det & (sens > 0.5))                     # every theory-dominated coefficient is undetermined
    assert r.rank < 16
    assert any("follow the KF's theory" in n for n in r.notes)
    assert any(n.startswith('theory fraction') for n in r.notes)
    # and the flag is right to trip: the result is not the truth (eq 38 error of tens of %)
    assert eq38_error(r, truth_fn(r.speed))['K'] > 10


def test_theory_flag_does_not_trip_when_data_determine_and_theory_is_truth(setup):
    # Zero noise, probes AT the bearing nodes (what the KF must estimate is measured) and theory = truth: the KF hands
    # back the measured bearing displacements, the result is the truth and owes nothing to the theory.
    rig, model = setup
    probes = tuple(Probe(f'p{n}{d}', n, d) for n in (2, 10) for d in ('x', 'y'))
    data = harmonics.from_recordings(_force_recordings(rig, model, probes, [1500], 0.0))
    r = identify_paper(model, rig, data, probes, data.runs, {'bearing_fn': truth_fn, 'R': 1e-20})[0]
    assert r.extra['theory_fraction'] < 0.05
    assert np.all(r.extra['theory_sensitivity'] < 0.5)
    assert r.fully_determined
    assert not any("follow the KF's theory" in n for n in r.notes)
    tr = truth_fn(r.speed)
    for b, n in enumerate(r.nodes):
        np.testing.assert_allclose(r.K[b], tr[n][0], atol=1e-3 * np.abs(tr[n][0]).max())
        np.testing.assert_allclose(r.C[b], tr[n][1], atol=1e-3 * np.abs(tr[n][1]).max())


def test_theory_sensitivity_predicts_a_rerun(setup, force_node6):
    # Independent route: re-run the whole method (plain fits, KF with its Riccati equation, eqs 30-37) with every
    # theory coefficient scaled by 1 +- delta, and difference the results: the symmetric secant along that direction
    # must match the analytic sensitivity G (d identified / d theory) within Richardson's error estimate plus the
    # re-runs' rounding (test/error_bounds.py richardson_check: the filter to the Riccati residual the package
    # accepts, the eqs 30-37 solve to its least-squares bound at the result's condition number).
    rig, model = setup
    d = force_node6
    w = float(d.speeds[0])
    nodes = model.bearing_nodes
    sc = coefficient_scales(theory_fn(w), w, nodes)

    def identified(f):
        r = identify_paper(model, rig, d, d.probes, d.runs, {'bearing_fn': lambda s: theory_fn(s, f)})[0]
        return r, coeffs_to_theta(r.coeffs(), w, nodes) / sc

    r0, _ = identified(1.0)
    dth = coeffs_to_theta(theory_fn(w), w, nodes) / sc        # the direction of a relative change of every entry
    pred = r0.extra['theory_jacobian'] @ dth

    def secant(delta):
        return (identified(1 + delta)[1] - identified(1 - delta)[1]) / (2 * delta)

    assert np.linalg.norm(pred) > 0.1                          # the result does move with the theory
    acc = RICCATI_RESIDUAL + lstsq_acc(r0.condition)
    _, tol = richardson_check(secant, 0.03, pred, acc, np.abs(identified(1.0)[1]).max())
    assert tol <= 0.1 * np.abs(pred).max()                     # the check has teeth


def test_conventional_flags_interpolation_bias_only_where_the_line_misses(setup):
    # Probes at nodes 1, 3 / 9, 11: the straight line misses the bent shaft at the bearings (2, 10); with probes at
    # the bearing nodes it is exact.  Noise-free data, theory = truth, so the identified error is the bias alone:
    # every coefficient still called determined must be within the 5 % (of its group size) threshold of the truth.
    rig, model = setup
    runs = rigmod.scenario('force')
    far = tuple(Probe(f'p{n}{d}', n, d) for n in (1, 3, 9, 11) for d in ('x', 'y'))
    data = simulate_data(rig, runs, (1500,), probes=far, bearing_fn=truth_fn, model=model)
    r = identify_conventional(model, rig, data, far, data.runs, {'bearing_fn': truth_fn})[0]
    assert not r.fully_determined
    assert any('interpolation bias' in n for n in r.notes)
    w = r.speed
    err = np.abs(coeffs_to_theta(r.coeffs(), w, r.nodes) - coeffs_to_theta(truth_fn(w), w, r.nodes)) \
        / coefficient_scales(truth_fn(w), w, r.nodes)
    det = np.concatenate([r.K_determined.reshape(-1), r.C_determined.reshape(-1)])
    assert np.all(err[det] <= 0.05) and np.any(err[~det] > 0.05)
    near = tuple(Probe(f'p{n}{d}', n, d) for n in (2, 3, 9, 10) for d in ('x', 'y'))
    data = simulate_data(rig, runs, (1500,), probes=near, bearing_fn=truth_fn, model=model)
    r = identify_conventional(model, rig, data, near, data.runs, {'bearing_fn': truth_fn})[0]
    assert r.fully_determined and not any('carry an interpolation bias' in n for n in r.notes)


def test_theory_check_also_runs_on_kf_vectors_given_from_outside(setup, force_node6):
    # the ROS route hands over the kf_estimator's bearing vectors (z_B); with their KF settings the same theory check
    # must trip as on the offline KF route
    rig, model = setup
    d = force_node6
    zB, zBs, _, km = kf_bearing_vectors(model, theory_fn(float(d.speeds[0])), d.probes, d, 0)
    r = identify_paper(model, rig, d, d.probes, d.runs,
                       {'bearing_fn': theory_fn, 'z_B': zB[:, None], 'z_B_std': zBs[:, None],
                        'z_B_kf': {'Q': 1e-16, 'R': km.R, 'sample_rate': d.recordings[0].sample_rate}})[0]
    assert r.extra['theory_fraction'] > 0.5 and not r.fully_determined
