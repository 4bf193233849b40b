"""
Kalman filter (paper section 3.1).

Exact discretisation, exact sinusoidal input, steady-state gain, the steady-state filter against filterpy's
time-varying filter, RTS smoother, NIS consistency and the streaming API.

Independent references: the eigen-decomposition for the discretisation; scipy solve_ivp (rtol 1e-11) for the forced
response; scipy.linalg.solve_discrete_are and the time-varying Riccati recursion for the steady-state covariance;
filterpy's KalmanFilter and rts_smoother (test/kf_oracle.py, with the tolerance it derives from the filter's gain
sequence and closed loop); chi-square theory for the NIS; the simulated rig (rig.simulate, exact response) for the
rotor case.
"""
import math

from bearing_id.config.params import load_rig, Probe
from bearing_id.estimation import kalman as kf
from bearing_id.excitation import harmonic_forces
from bearing_id.rotor.assembly import RotorModel
from bearing_id.simulation import rig as rigmod
from kf_oracle import (agreement_bound, balancing, closed_loop, EPS, filterpy_filter, growth_sum, output_bounds,
                       rounding_step)
import numpy as np
import pytest
from scipy.integrate import solve_ivp
import scipy.linalg as sla
from scipy.stats import chi2

FS = 2000.0


def two_dof(c_scale=1.0):
    """Two masses on springs (ground-m1-m2), viscous dampers: (A, B) with x = [q1, q2, q1', q2'], B = [0; M^-1]."""
    M = np.diag([1.0, 0.5])
    K = np.array([[3e4, -1e4], [-1e4, 1e4]])
    C = c_scale * np.array([[4.0, -1.0], [-1.0, 1.0]])
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Mi @ K, -Mi @ C]])
    B = np.vstack([np.zeros((2, 2)), Mi])
    return A, B


H2 = np.array([[0.0, 1.0, 0.0, 0.0]])           # measure q2
E2 = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
W = 50.0                                         # rad/s
FORCES = {1.0: np.array([1.0 + 0.5j, 0.3j]), 2.5: np.array([0.2, 0.0])}


def model2(Q=1e-10, R=1e-8, **kw):
    A, B = two_dof()
    return kf.kalman_model(A, B, H2, 1 / FS, Q=Q, R=R, forces=FORCES, speed=W, E=E2, **kw)


def simulate_discrete(km, N, x0, rng, q_true, r_true, angle):
    """Truth trajectory of the discretised stochastic model with exact sinusoidal input."""
    xp = kf.particular_state(km.Xp, angle)
    x = np.empty((N, km.n))
    x[0] = x0
    Lq = np.linalg.cholesky(q_true)
    for k in range(N - 1):
        x[k + 1] = km.Phi @ x[k] + (xp[k + 1] - km.Phi @ xp[k]) + Lq @ rng.standard_normal(km.n)
    z = x @ km.H.T + rng.standard_normal((N, km.m)) @ np.linalg.cholesky(r_true).T
    return x, z


# ------------------------------------------------------------------------------------------------ discretisation
def test_discretisation_matches_the_eigen_route():
    # Phi = expm(A dt) (balanced, scipy) against V exp(Lambda dt) V^-1: each route's error is ~eps cond(V) ||Phi||
    A, B = two_dof()
    dt = 1 / FS
    Phi = kf.kalman_model(A, B, H2, dt, R=1e-8).Phi
    lam, V = np.linalg.eig(A)
    Phi_eig = np.real(V @ np.diag(np.exp(lam * dt)) @ np.linalg.inv(V))
    tol = 10 * EPS * np.linalg.cond(V) * np.abs(Phi).max()
    assert np.abs(Phi - Phi_eig).max() <= tol


def test_exact_sinusoidal_input_matches_ode_integration():
    A, B = two_dof()
    km = kf.kalman_model(A, B, H2, 1 / FS, R=1e-8, forces=FORCES, speed=W)
    N = 400
    t = np.arange(N) / FS
    phi0 = 0.37
    angle = phi0 + W * t
    x0 = np.array([1e-4, -2e-4, 3e-3, 0.0])          # far from the steady state: a transient

    def force(tt):
        ph = phi0 + W * tt
        return sum(np.real(F * np.exp(1j * r * ph)) for r, F in FORCES.items())

    sol = solve_ivp(lambda tt, x: A @ x + B @ force(tt), (0, t[-1]), x0, t_eval=t, rtol=1e-11, atol=1e-14,
                    method='DOP853')
    xp = kf.particular_state(km.Xp, angle)
    x = np.empty((N, 4))
    x[0] = x0
    for k in range(N - 1):
        x[k + 1] = km.Phi @ x[k] + xp[k + 1] - km.Phi @ xp[k]
    np.testing.assert_allclose(x, sol.y.T, rtol=0, atol=1e-8 * np.abs(sol.y).max())


# ------------------------------------------------------------------------------------------------ steady state
def riccati_distance(km, P):
    """
    First-order distance of P from the Riccati solution: |L^-1 Res(P)|_max, L(X) = X - Fc X Fc^T (Fc the closed loop).

    For a small residual Res(P) = Ric(P) - P the solution is P* = P + L^-1(Res(P)) + O(Res^2) (one Newton step, the
    Stein equation solved by scipy.linalg.solve_discrete_lyapunov).
    """
    S = km.H @ P @ km.H.T + km.R
    Fc = km.Phi @ (np.eye(km.n) - P @ km.H.T @ np.linalg.solve(S, km.H))
    return np.abs(sla.solve_discrete_lyapunov(Fc, kf.riccati_residual(km.Phi, km.H, km.Q, km.R, P))).max()


@pytest.mark.parametrize('which', ['two_dof', 'rotor'])
def test_steady_state_gain_against_scipy_and_the_riccati_recursion(which, request):
    # The package's doubling against scipy.linalg.solve_discrete_are (QZ) on the dual problem.  Each route's distance
    # from the exact solution is estimated by its own Riccati residual mapped through the inverse Stein operator
    # (riccati_distance); they must agree within the sum of the two distances, x10 for the linearisation.
    if which == 'rotor':
        rig, model, coeffs, speed, rec, forces = request.getfixturevalue('rotor_case')
        km = kf.rotor_kalman_model(model, speed, coeffs, rig.probes, rec.sample_rate, Q=1e-16, R=1e-14)
    else:
        km = model2()
    P1, K1, S1 = kf.steady_state_gain(km.Phi, km.H, km.Q, km.R)
    P2 = sla.solve_discrete_are(km.Phi.T, km.H.T, km.Q, km.R)
    tol = 10 * (riccati_distance(km, P1) + riccati_distance(km, P2))
    assert np.abs(P1 - P2).max() <= tol, (np.abs(P1 - P2).max(), tol)
    np.testing.assert_allclose(K1, P1 @ km.H.T @ np.linalg.inv(S1), rtol=0, atol=1e3 * EPS * np.abs(K1).max())
    if which == 'rotor':
        return
    # the time-varying Riccati recursion from a large P0 converges to the same P (its distance estimated as above)
    P = 1e-2 * np.eye(km.n)
    for _ in range(20000):
        S = km.H @ P @ km.H.T + km.R
        Kg = P @ km.H.T @ np.linalg.inv(S)
        P = km.Phi @ (P - Kg @ km.H @ P) @ km.Phi.T + km.Q
    assert np.abs(P - P1).max() <= 10 * (riccati_distance(km, P) + riccati_distance(km, P1))


# ------------------------------------------------------------------------------------------------ against filterpy
def assert_agrees_with_filterpy(km, res, ref, z):
    """Assert the package's filter result ``res`` equals filterpy's run ``ref`` within the derived bound (kf_oracle)."""
    _, tol_est, tol_nu = agreement_bound(km, ref, z)
    assert np.abs(res.estimates - ref['estimates']).max() <= tol_est
    assert np.abs(res.innovations - ref['innovations']).max() <= tol_nu
    # NIS: nu^T S^-1 nu moves by <= 2 |nu| |S^-1| |d nu| + |nu|^2 |d S^-1| (S from the gains' covariance)
    S_inv = np.linalg.inv(res.S)
    dS = np.abs(ref['S'] - res.S).max()
    nu = np.abs(ref['innovations']).max()
    m = km.m
    tol_nis = m * (2 * nu * np.abs(S_inv).max() * tol_nu + m * nu ** 2 * np.abs(S_inv).max() ** 2 * dS)
    assert np.abs(res.nis - ref['nis']).max() <= tol_nis + 10 * EPS * np.abs(ref['nis']).max()


@pytest.mark.parametrize('start', ['steady', 'transient'])
def test_fast_filter_equals_filterpy(start):
    km = model2()
    rng = np.random.default_rng(4)
    N = 1500
    angle = 0.2 + W * np.arange(N) / FS
    xp = kf.particular_state(km.Xp, angle)
    x0 = xp[0] + (0 if start == 'steady' else np.array([2e-5, -1e-5, 1e-3, 2e-3]))
    x, z = simulate_discrete(km, N, x0, rng, 1e-10 * np.eye(4), 1e-8 * np.eye(1), angle)
    x0_filter = None if start == 'steady' else xp[0] + np.array([1e-5, 0, 0, 1e-3])
    fast = kf.fast_filter(km, z, angle, x0=x0_filter)
    ref = filterpy_filter(km, z, angle, x0=x0_filter)
    assert_agrees_with_filterpy(km, fast, ref, z)


def test_rts_smoother_matches_filterpy_and_beats_the_filter():
    from filterpy.kalman import KalmanFilter
    from filterpy.kalman import rts_smoother as fp_rts

    km = model2(Q=1e-9, R=1e-8)
    rng = np.random.default_rng(11)
    N = 1200
    angle = W * np.arange(N) / FS
    xp = kf.particular_state(km.Xp, angle)
    x, z = simulate_discrete(km, N, xp[0], rng, km.Q, km.R, angle)
    sm = kf.rts_smoother(km, z, angle, return_states=True)
    # filterpy on the deviation from the particular solution (no input there), started at the steady state
    P_ss = km.steady_state()[0]
    f = KalmanFilter(dim_x=4, dim_z=1)
    f.F, f.H, f.Q, f.R = km.Phi, km.H, km.Q, km.R
    f.x = np.zeros((4, 1))
    f.P = P_ss.copy()
    means, covs, _, _ = f.batch_filter((z - xp @ km.H.T).reshape(N, 1, 1), update_first=True)
    xs, _, Cs_seq, _ = fp_rts(means, covs, [km.Phi] * N, [km.Q] * N)
    ref_states = xs[:, :, 0] + xp
    # tolerance: the forward pass as in kf_oracle (gain sequence vs steady gain, rounding); the backward recursion
    # e_s(k) = (I - Cs Phi) e(k|k) + Cs e_s(k+1) carries that error (through ||I - Cs Phi||), its own gain deviation
    # |Cs_k - Cs| |e_s| and its rounding n eps (||Cs|| + ||I - Cs Phi||) |e| through the powers of Cs (growth_sum),
    # all in the coordinates that balance Cs
    P, K, S = km.steady_state()
    Cs = (np.eye(km.n) - K @ km.H) @ P @ km.Phi.T @ np.linalg.inv(P)
    tol_f, _, _ = agreement_bound(km, filterpy_filter(km, z, angle), z)
    t = balancing(Cs)
    Cs_t = Cs * t[None, :] / t[:, None]
    G_t = (np.eye(km.n) - Cs @ km.Phi) * t[None, :] / t[:, None]
    e_max = np.max(np.linalg.norm(xs[:, :, 0] / t[None, :], axis=1))
    cs_dev = max(np.linalg.norm((C - Cs) * t[None, :] / t[:, None], 2) for C in Cs_seq[:-1])
    step = (np.linalg.norm(G_t, 2) * tol_f / np.min(t) * np.sqrt(km.n) + cs_dev * e_max
            + km.n * EPS * (np.linalg.norm(Cs_t, 2) + np.linalg.norm(G_t, 2)) * e_max)
    tol = np.max(t) * growth_sum(Cs_t, N) * step
    assert np.abs(sm.states - ref_states).max() <= tol, (np.abs(sm.states - ref_states).max(), tol)
    filt = kf.fast_filter(km, z, angle)
    err_f = np.sqrt(np.mean((filt.estimates - x @ km.E.T) ** 2, axis=0))
    err_s = np.sqrt(np.mean((sm.estimates - x @ km.E.T) ** 2, axis=0))
    assert np.all(err_s < 0.9 * err_f)


# ------------------------------------------------------------------------------------------------ consistency
def test_nis_consistent_with_true_noise_and_flags_wrong_r():
    rng = np.random.default_rng(21)
    km = model2(Q=1e-9, R=1e-8)
    N = 4000
    angle = W * np.arange(N) / FS
    xp = kf.particular_state(km.Xp, angle)
    x, z = simulate_discrete(km, N, xp[0], rng, km.Q, km.R, angle)
    res = kf.fast_filter(km, z, angle)
    lo, hi = chi2.ppf([0.0005, 0.9995], N) / N            # 99.9 % band, computed here from chi-square theory
    assert lo <= res.nis_mean <= hi
    assert res.nis_band[0] < 1.0 < res.nis_band[1]
    # the estimate of the unmeasured DOF q1 is better than the model alone (x_p)
    err_kf = np.sqrt(np.mean((res.estimates[:, 0] - x[:, 0]) ** 2))
    err_model = np.sqrt(np.mean((xp[:, 0] - x[:, 0]) ** 2))
    assert err_kf < 0.8 * err_model
    # an R 100 times too small makes the filter overconfident: mean NIS far above its band
    bad = kf.fast_filter(model2(Q=1e-9, R=1e-10), z, angle)
    assert bad.nis_mean > 5 * bad.nis_band[1] and not bad.consistent


def test_refuses_nonfinite_and_bad_shapes():
    km = model2()
    angle = W * np.arange(100) / FS
    z = np.zeros((100, 1))
    z[[3, 7, 9]] = np.nan
    for fn in (kf.fast_filter, kf.innovations, kf.rts_smoother):
        with pytest.raises(ValueError, match='3 non-finite'):
            fn(km, z, angle)
    with pytest.raises(ValueError, match=r'\(N, 1\)'):
        kf.fast_filter(km, np.zeros((100, 2)), angle)
    with pytest.raises(ValueError, match='Q'):
        model2(Q=-1.0)


# ------------------------------------------------------------------------------------------------ streaming
def test_streaming_equals_batch_and_checks_band():
    km = model2()
    rng = np.random.default_rng(5)
    N = 2600
    angle = W * np.arange(N) / FS
    xp = kf.particular_state(km.Xp, angle)
    _, z = simulate_discrete(km, N, xp[0], rng, 1e-10 * np.eye(4), 1e-8 * np.eye(1), angle)
    batch = kf.fast_filter(km, z, angle, return_states=True)
    s = kf.StreamingKF(km, band_tol_rel=0.02)
    est, nu, nis = [], [], []
    edges = [0, 1, 64, 100, 1124, 1125, 2048, N]          # odd block sizes, including 1 sample
    for a, b in zip(edges[:-1], edges[1:]):
        e, v, n_ = s.step_block(z[a:b], angle[a:b], W * 1.01)
        est.append(e), nu.append(v), nis.append(n_)
    # the same linear recursion with other chunk boundaries: only rounding differs (kf_oracle: one step's rounding
    # propagated through the closed loop over N samples)
    F = closed_loop(km)
    t = balancing(F)
    d = growth_sum(F * t[None, :] / t[:, None], N) * 2 * rounding_step(km, batch.states, z, t)
    _, tol_est, tol_nu = output_bounds(km, d, t)
    assert np.abs(np.vstack(est) - batch.estimates).max() <= tol_est
    assert np.abs(np.vstack(nu) - batch.innovations).max() <= tol_nu
    S_inv = np.linalg.inv(batch.S)
    tol_nis = 2 * km.m * np.abs(batch.innovations).max() * np.abs(S_inv).max() * tol_nu
    assert np.abs(np.concatenate(nis) - batch.nis).max() <= tol_nis + 10 * EPS * np.abs(batch.nis).max()
    assert s.n_samples == N
    with pytest.raises(ValueError, match="outside this model's band"):
        s.step_block(z[:10], angle[:10], W * 1.1)
    bad = z[:10].copy()
    bad[2] = np.inf
    with pytest.raises(ValueError, match='1 non-finite'):
        s.step_block(bad, angle[:10], W)


# ------------------------------------------------------------------------------------------------ rotor
@pytest.fixture(scope='module')
def rotor_case():
    rig = load_rig()
    model = RotorModel.from_params(rig)
    kb = np.array([[4.0e5, 0.5e5], [0.3e5, 5.0e5]])
    cb = np.array([[400.0, 20.0], [20.0, 500.0]])
    coeffs = {node: (kb, cb) for node in model.bearing_nodes}
    speed = 1500 * 2 * math.pi / 60
    run = rig.simulation.runs[0]
    probes = [(6, 'x'), (6, 'y')] + [(b, d) for b in model.bearing_nodes for d in ('x', 'y')]
    probes = tuple(Probe(name=f'p{n}{d}', node=n, direction=d) for n, d in probes)
    rec = rigmod.simulate(rig, run, rigmod.step_schedule([1500.0], 0.3), probes=probes, noise=0.0,
                          bearing_fn=lambda w: coeffs, model=model)
    forces = harmonic_forces(run.excitation, speed, model.n_nodes)
    return rig, model, coeffs, speed, rec, forces


@pytest.mark.parametrize('q', [1e-16, 1e-17, 1e-18])
def test_rotor_bearing_node_estimates_paper_q(rotor_case, q):
    rig, model, coeffs, speed, rec, forces = rotor_case
    rng = np.random.default_rng(8)
    z_clean = rec.samples[:, :2]
    sigma = 0.01 * np.sqrt(np.mean(z_clean**2))
    z = z_clean + sigma * rng.standard_normal(z_clean.shape)
    km = kf.rotor_kalman_model(model, speed, coeffs, rig.probes, rec.sample_rate, forces=forces, Q=q, R=sigma**2)
    assert km.n == 2 * model.ndof and np.allclose(km.Q, q * np.eye(km.n))
    assert km.out_names == ('n2x', 'n2y', 'n10x', 'n10y')
    res = kf.fast_filter(km, z, rec.angle)
    truth = rec.samples[:, 2:]
    rel = np.sqrt(np.mean((res.estimates - truth) ** 2, axis=0)) / np.sqrt(np.mean(truth**2, axis=0))
    assert np.all(rel < 0.01), rel          # model == truth here: the bearing-node orbit to 1 %
    assert res.consistent, (res.nis_mean, res.nis_band)


def test_rotor_fast_filter_equals_filterpy_from_rest(rotor_case):
    rig, model, coeffs, speed, rec, forces = rotor_case
    rng = np.random.default_rng(9)
    N = 300
    z = rec.samples[:N, :2] + 1e-7 * rng.standard_normal((N, 2))
    km = kf.rotor_kalman_model(model, speed, coeffs, rig.probes, rec.sample_rate, forces=forces, Q=1e-16,
                               R=1e-14)
    x0 = np.zeros(km.n)                      # start at rest, not in the steady state: a real transient in the filter
    fast = kf.fast_filter(km, z, rec.angle[:N], x0=x0)
    ref = filterpy_filter(km, z, rec.angle[:N], x0=x0)
    assert_agrees_with_filterpy(km, fast, ref, z)


def test_rotor_nis_flags_wrong_bearing_model(rotor_case):
    rig, model, coeffs, speed, rec, forces = rotor_case
    rng = np.random.default_rng(10)
    z_clean = rec.samples[:, :2]
    sigma = 0.01 * np.sqrt(np.mean(z_clean**2))
    z = z_clean + sigma * rng.standard_normal(z_clean.shape)
    wrong = {n: (0.75 * k, 0.75 * c) for n, (k, c) in coeffs.items()}      # theory 25 % off the truth
    km = kf.rotor_kalman_model(model, speed, wrong, rig.probes, rec.sample_rate, forces=forces, Q=1e-16,
                               R=sigma**2)
    res = kf.fast_filter(km, z, rec.angle)
    assert res.nis_mean > 2 * res.nis_band[1] and not res.consistent
