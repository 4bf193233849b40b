"""
``direct`` identification: output-error fit of the 16 bearing coefficients through the FE model.

References (independent of the fit):
* the FE model's own frequency response (rotor.assembly.harmonic_response, a plain linear solve) makes the data;
* the analytic Jacobian is checked against central finite differences of a dense solve of the assembled dynamic
  stiffness (truncation and rounding bounds derived in the test);
* the rank claims follow from a counting argument, not from the code: with synchronous unbalance on an axisymmetric
  shaft the bearing-node responses of every run lie in one 2-D complex subspace per speed, so one probe location
  (2 complex equations per run) gives at most 2 x 2 complex = 8 real independent equations however many runs are
  stacked; the x/y shaker at both discs (4 runs) excites the full 4-D space: 4 x 2 complex = 16 real equations;
* noise: 1 % of the channel RMS on 2 s x 10240 Hz time series, 75 % of each dwell used (identify.harmonics), gives
  a 1X phasor error of std noise x |X| / sqrt(N_used) on Re and Im (least squares of a sinusoid in white noise).

Tolerance: the issue's target for ``direct`` with the directional force plan at 1 % noise is <= 3 % eq. 38 error for
K and for C (the accuracy benchmark, benchmarks/bench_accuracy.py, uses the same target).
"""
import math

from bearing_id.config.params import ExcitationEntry, Probe, Run
from bearing_id.conventions import rpm_to_rad_s
from bearing_id.excitation import harmonic_forces
from bearing_id.identify import eq38_error
from bearing_id.identify.direct import beta_to_coeffs, Case, coeffs_to_beta, fit_speed, identify_direct, SpeedResponse
from bearing_id.identify.harmonics import from_recordings
from bearing_id.rotor.assembly import dynamic_stiffness, harmonic_response, probe_matrix
from bearing_id.simulation.rig import scenario, simulate_data, simulate_run
from error_bounds import solve_tol
import numpy as np
import pytest

NOISE = 0.01
N_USED = int(0.75 * 2.0 * 10240)          # samples per 1X fit in the default plan (2 s dwell, 25 % settle dropped)
P6 = (Probe('p6x', 6, 'x'), Probe('p6y', 6, 'y'))

# coefficients NOT from the bearing module: an arbitrary non-symmetric set (N/m, N s/m)
K_ARB = {2: np.array([[3.1e5, 1.2e5], [-2.4e5, 5.2e5]]), 10: np.array([[2.6e5, 0.9e5], [-1.9e5, 4.4e5]])}
C_ARB = {2: np.array([[420.0, 90.0], [110.0, 640.0]]), 10: np.array([[380.0, 70.0], [95.0, 590.0]])}
TRUTH_ARB = {n: (K_ARB[n], C_ARB[n]) for n in (2, 10)}


def exact_cases(model, runs, probes, speed, coeffs):
    out = []
    for run in runs:
        F = harmonic_forces(run.excitation, speed, model.n_nodes)[1.0]
        X = probe_matrix(model, probes) @ harmonic_response(model, speed, speed, F, coeffs)
        out.append(Case(F, tuple(probes), X, np.full(X.size, 1e-6 * np.max(np.abs(X)))))
    return out


def noisy(data, seed):
    """Add the time-domain-equivalent 1X noise (module docstring) to simulate_data output, in place."""
    rng = np.random.default_rng(seed)
    std = NOISE * np.abs(data.X) / math.sqrt(N_USED)
    data.X = data.X + std * (rng.standard_normal(data.X.shape) + 1j * rng.standard_normal(data.X.shape))
    data.X_std = std
    return data


def test_jacobian_matches_finite_differences(model):
    """
    The fit's Jacobian (direct.SpeedResponse) against central differences of a dense solve y = P Z(beta)^-1 F.

    Tolerance per coefficient k (derived): Z is linear in beta, so y(beta + t e_k) = sum_n (-t)^n P (Z^-1 dZ_k)^n q
    and the central difference with step h is off the derivative by h^2 |P (Z^-1 dZ_k)^3 q| (+ O(h^4): twice that
    is allowed), plus the rounding of the two solves, s max|y| / h, plus the route's own bound s max|dy|, with s the
    backward-stable solve's bound 8 n eps cond(Z) (test/error_bounds.py solve_tol).
    """
    W = rpm_to_rad_s(1700.0)
    nodes = (2, 10)
    cases = exact_cases(model, scenario('force'), P6 + (Probe('p3x', 3, 'x'),), W, TRUTH_ARB)
    beta = coeffs_to_beta(TRUTH_ARB, nodes)
    _, dy = SpeedResponse(model, W, cases, nodes, beta)(beta)
    P = probe_matrix(model, cases[0].probes)
    F = np.stack([c.F for c in cases], axis=1)
    Z = dynamic_stiffness(model, W, W, TRUTH_ARB)
    Z_empty = dynamic_stiffness(model, W, W, {n: (np.zeros((2, 2)), np.zeros((2, 2))) for n in nodes})
    s = solve_tol(Z)

    def y_of(b):
        return (P @ np.linalg.solve(dynamic_stiffness(model, W, W, beta_to_coeffs(b, nodes)), F)).T.reshape(-1)

    y0 = y_of(beta)
    scale = np.repeat([3e5, 500.0, 3e5, 500.0], 4)        # block magnitudes: K then C per bearing
    for k in range(16):
        e = np.zeros(16)
        e[k] = 1.0
        dZ = dynamic_stiffness(model, W, W, beta_to_coeffs(e, nodes)) - Z_empty
        third = np.linalg.solve(Z, F)
        for _ in range(3):
            third = np.linalg.solve(Z, dZ @ third)
        h = 1e-5 * scale[k]
        fd = (y_of(beta + h * e) - y_of(beta - h * e)) / (2 * h)
        tol = 2 * h ** 2 * np.abs(P @ third).max() + s * np.abs(y0).max() / h + s * np.abs(dy[:, k]).max()
        assert np.abs(dy[:, k] - fd).max() <= tol, (k, np.abs(dy[:, k] - fd).max(), tol)


def test_zero_noise_force_plan_recovers_coefficients_exactly(model):
    """Algebra check: data from the model itself, start 30 % off -> the 16 coefficients to 1e-6 relative."""
    W = rpm_to_rad_s(2100.0)
    theory = {n: (1.3 * K, 0.7 * C) for n, (K, C) in TRUTH_ARB.items()}
    res = fit_speed(model, W, exact_cases(model, scenario('force'), P6, W, TRUTH_ARB), (2, 10), theory=theory)
    assert res.rank == 16 and res.unknowns == 16 and res.fully_determined
    for i, n in enumerate((2, 10)):
        np.testing.assert_allclose(res.K[i], K_ARB[n], rtol=1e-6, atol=1e-6 * np.abs(K_ARB[n]).max())
        np.testing.assert_allclose(res.C[i], C_ARB[n], rtol=1e-6, atol=1e-6 * np.abs(C_ARB[n]).max())
    assert res.residual < 1e-9


def test_force_plan_node6_one_percent_noise_within_benchmark_tolerance(rig, model):
    """Truth = the rig's (viscosity x1.25, clearance x0.8), theory = nominal, node 6 only: <= 3 % (eq. 38)."""
    speeds = (900, 1500, 2100, 2700)
    data = noisy(simulate_data(rig, scenario('force'), speeds, probes=P6, model=model), seed=11)
    res = identify_direct(model, rig, data)
    err = eq38_error(res, [data.truth[float(w)] for w in data.speeds])
    assert err['K'] <= 3.0 and err['C'] <= 3.0, err
    for r in res:
        assert r.rank == 16 and r.fully_determined
    # the reported 1-sigma describes the actual error: normalised errors have an RMS of order one
    z = []
    for r in res:
        t = data.truth[float(r.speed)]
        for i, n in enumerate(r.nodes):
            z += list(((r.K[i] - t[n][0]) / r.K_std[i]).ravel()) + list(((r.C[i] - t[n][1]) / r.C_std[i]).ravel())
    zr = math.sqrt(np.mean(np.square(z)))
    assert 0.4 < zr < 2.5, zr


@pytest.mark.parametrize('n_runs', [2, 3])
def test_unbalance_node6_is_rank_8_and_undetermined(rig, model, n_runs):
    runs = list(rig.simulation.runs)
    if n_runs == 3:   # a third, different unbalance distribution adds no rank (the 2-D subspace argument)
        runs.append(Run('C', (ExcitationEntry('unbalance', 4, 2.0e-5, 2.0, 'forward'),
                              ExcitationEntry('unbalance', 8, 1.0e-5, -1.0, 'forward'))))
    data = noisy(simulate_data(rig, runs, (1200, 2400), probes=P6, model=model), seed=5)
    for r in identify_direct(model, rig, data):
        assert (r.rank, r.unknowns) == (8, 16)
        assert math.isinf(r.condition)
        assert not r.K_determined.any() and not r.C_determined.any()
        assert np.all(np.isnan(r.K_std)) and np.all(np.isnan(r.C_std))
        assert len(r.undetermined_names()) == 16


def test_unbalance_node6_with_prior_is_flagged_prior_dominated(rig, model):
    data = noisy(simulate_data(rig, rig.simulation.runs, (1800,), probes=P6, model=model), seed=3)
    (r,) = identify_direct(model, rig, data, prior_weight=4.0)
    assert r.rank == 8
    assert not r.K_determined.any() and not r.C_determined.any()
    assert np.all(np.isfinite(r.K_std)) and np.all(np.isfinite(r.C_std))   # the posterior, flagged as such


def test_prior_does_not_spoil_a_determined_problem(rig, model):
    """With the force plan a weak prior (1-sigma = 100 % of the block scale) changes the answer by << its std."""
    data = noisy(simulate_data(rig, scenario('force'), (2400,), probes=P6, model=model), seed=8)
    (a,) = identify_direct(model, rig, data)
    (b,) = identify_direct(model, rig, data, prior_weight=1.0)
    assert b.fully_determined
    assert np.all(np.abs(a.K - b.K) < 0.5 * a.K_std) and np.all(np.abs(a.C - b.C) < 0.5 * a.C_std)


def test_unknown_option_is_refused(rig, model):
    data = simulate_data(rig, rig.simulation.runs, (1200,), probes=P6, model=model)
    with pytest.raises(ValueError, match='unknown option'):
        identify_direct(model, rig, data, options={'prior': 1.0})
    with pytest.raises(ValueError, match='prior_weight'):
        identify_direct(model, rig, data, prior_weight=-1.0)


# ------------------------------------------------------------------------------------------------ the rig's schedule
# Time-domain recordings on the rig's own schedule (2 s dwells joined by 0.5 s ramps, params/rig.yaml): the rotor's
# lightly damped ~33 Hz and ~103 Hz modes ring after every speed change.  Reference: the exact steady-state phasors
# of the truth system (simulation.rig.simulate_data, a linear solve, no time series).
# The whole default schedule (600..3000 rpm): the target is the mean over the benchmark's speeds.


@pytest.fixture(scope='module')
def force_schedule_data(rig, model):
    recs = [simulate_run(rig, run, probes=P6, seed=40 + k)
            for k, run in enumerate(scenario('force'))]
    return from_recordings(recs)


def test_schedule_1x_vectors_equal_steady_state_phasors_within_their_std(rig, model, force_schedule_data):
    data = force_schedule_data
    ref = simulate_data(rig, data.runs, [w * 30 / math.pi for w in data.speeds], probes=P6, model=model)
    assert len(data.speeds) == len(rig.simulation.speeds_rpm)
    z = (data.X - ref.X) / data.X_std                      # X_std: 1-sigma of Re and of Im
    for s, rpm in enumerate(rig.simulation.speeds_rpm):
        zs = np.concatenate([z[:, s].real.ravel(), z[:, s].imag.ravel()])     # 16 normalised errors per speed
        assert np.max(np.abs(zs)) < 4.5, (rpm, zs)
        assert math.sqrt(np.mean(zs ** 2)) < 2.0, (rpm, zs)
    zall = np.concatenate([z.real.ravel(), z.imag.ravel()])
    assert 0.6 < math.sqrt(np.mean(zall ** 2)) < 1.5
    # and the std is useful, not inflated to cover the bias: 1-sigma < 0.5 % of |X| even at 2100 rpm
    assert np.all(data.X_std / np.abs(ref.X) < 5e-3)


def test_direct_on_the_schedule_meets_target_and_its_std_predicts_its_error(rig, model, force_schedule_data):
    """
    Issue-4 target (<= 3 % eq. 38 for K and C, force plan, node 6) on the default schedule.

    Every coefficient determined, and normalised errors (estimate - truth) / std with an RMS of order one.
    """
    data = force_schedule_data
    res = identify_direct(model, rig, data)
    err = eq38_error(res, [data.truth_at(r.speed) for r in res])
    assert err['K'] <= 3.0 and err['C'] <= 3.0, err
    z = []
    for r in res:
        assert r.fully_determined
        t = data.truth_at(r.speed)
        for i, n in enumerate(r.nodes):
            z += list(((r.K[i] - t[n][0]) / r.K_std[i]).ravel()) + list(((r.C[i] - t[n][1]) / r.C_std[i]).ravel())
        # 4 runs x 2 channels x Re/Im = 16 equations for 16 unknowns: the notes must say the residual checks nothing
        assert r.extra['redundancy'] == 0
        assert any('no redundancy' in note for note in r.notes)
    zr = math.sqrt(np.mean(np.square(z)))
    assert 0.5 < zr < 1.8, zr
