"""
The paper method's frequency-domain Kalman filter (identify/paper.py) against independent oracles.

* The steady-state filter's closed-form 1X response (kf_transfer, kf_bearing_phasors) against filterpy's time-varying
  filter run on a steady window from the filter's periodic steady state (test/kf_oracle.py), its estimates fitted
  with a plain least-squares 1X + offset fit here; and the RTS smoother's transfer against filterpy's rts_smoother
  away from the window's end.  Tolerance: the oracle's derived agreement bound (gain sequence, rounding, closed-loop
  growth; the smoother's end transient through the powers of its gain), x sqrt(2) for the fit (the least-squares 1X
  of N samples moves by at most sqrt(2) x the largest sample change), plus the transfer's own solve,
  eps cond(M) |z|.
* The innovations of the steady-state filter (kalman.innovations, the NIS's source) against filterpy's.
* The analytic derivative of the KF's bearing-node phasors (kf_phasor_jacobian) and of the identified coefficients
  (theory_sensitivity_analytic) against central finite differences of the whole re-solve (Riccati included), written
  here.  Tolerance from Richardson's error estimate plus the evaluations' rounding (test/error_bounds.py
  richardson_check): a filter evaluation is taken as accurate to the relative Riccati residual the package accepts
  (1e-10), a least-squares solve to its backward-error bound.  The production fallback (theory_sensitivity: forward
  differences, 1 % of each group's size) is off the tangent by its truncation error, (h / 2) |f''|, estimated from
  the second difference.
* The Frechet derivative of expm in the eigenbasis (Daleckii-Krein) against scipy.linalg.expm_frechet, and the
  divided differences of exp against scipy's expm of a 2x2 block.
* The eqs 30-32 affine map and the Golub-Pereyra derivative of the eqs 30-37 solve (ls_jacobian).
"""
from bearing_id.config.params import load_rig, Probe
from bearing_id.estimation import kalman
from bearing_id.excitation import harmonic_forces
from bearing_id.identify import harmonics, paper
from bearing_id.identify.lsq import coefficient_scales
from bearing_id.rotor.assembly import dynamic_stiffness, RotorModel, state_space
from bearing_id.simulation import rig as rigmod
from bearing_id.simulation.rig import simulate_data
from error_bounds import lstsq_acc, RICCATI_RESIDUAL, richardson_check, solve_tol
from filterpy.kalman import KalmanFilter, rts_smoother
from kf_oracle import agreement_bound, balancing, EPS, filterpy_filter, growth_sum
import numpy as np
import pytest
import scipy.linalg as sla

FS = 10240.0


def theory_fn(w, f=1.0):
    K = f * np.array([[2.0e5, 1.2e5], [-0.6e5, 3.0e5]]) * (1 + w / 300)
    C = f * np.array([[300.0, 60.0], [60.0, 500.0]])
    return {2: (K, C), 10: (1.1 * K, 0.9 * C)}


@pytest.fixture(scope='module')
def setup():
    rig = load_rig()
    return rig, RotorModel.from_params(rig)


@pytest.fixture(scope='module')
def force_case(setup):
    """Four directional-force runs at 1500 rpm, probes at node 6, exact 1X phasors of a 25 % stiffer truth."""
    rig, model = setup
    w = 1500 * 2 * np.pi / 60
    runs = rigmod.scenario('force')
    probes = tuple(Probe(f'p6{d}', 6, d) for d in 'xy')
    data = simulate_data(rig, runs, (1500,), probes=probes, bearing_fn=lambda s: theory_fn(s, 1.25),
                         model=model)
    F = paper.forces_at(model, runs, w)
    # per-run R, two distinct values (one anisotropic), as the paper route builds them
    R = [np.array([1e-14, 2e-14]), 3e-14, 3e-14, np.array([1e-14, 2e-14])]
    return model, w, probes, data.X[:, 0], F, R


def fit_1x(y, angle):
    """Plain least-squares 1X + offset fit of the columns of y (N, k): complex phasors (k,) (Re{X e^{j angle}})."""
    D = np.column_stack([np.cos(angle), -np.sin(angle), np.ones_like(angle)])
    c = np.linalg.lstsq(D, y, rcond=None)[0]
    return c[0] + 1j * c[1]


P6 = (Probe('p6x', 6, 'x'), Probe('p6y', 6, 'y'))


def steady_window(model, rig, w, Q, R, n_samples):
    """Return a steady window: KalmanModel, angles, the probes' pure 1X (not the model's response), X, the forces."""
    forces = harmonic_forces(rig.simulation.runs[0].excitation, w, model.n_nodes)
    km = kalman.rotor_kalman_model(model, w, theory_fn(w), P6, FS, forces=forces, Q=Q, R=R)
    X = np.array([3e-6 * np.exp(0.4j), 2.2e-6 * np.exp(-1.1j)])
    angle = 0.3 + w * np.arange(n_samples) / FS
    return km, angle, np.real(X[None, :] * np.exp(1j * angle)[:, None]), X, forces[1.0]


def periodic_start(km, w, X, angle0):
    """Return the filter's periodic steady state at the first sample, x_p(t0) + Re{Ehat e^{j angle0}}, and a cond."""
    P, K, S = km.steady_state()
    Fc = km.Phi @ (np.eye(km.n) - K @ km.H)
    zeta = np.exp(1j * w / FS)
    Msys = zeta * np.eye(km.n) - Fc
    Ehat = np.linalg.solve(Msys, km.Phi @ K @ (X - km.H @ km.Xp[1.0]))
    return km.particular([angle0], np.eye(km.n))[0] + np.real(Ehat * np.exp(1j * angle0)), np.linalg.cond(Msys)


def test_transfer_equals_filterpy_on_a_steady_window(setup):
    # The probes read a pure 1X (not the theory model's response, so the filter has something to correct); filterpy's
    # filter, started in the periodic steady state, gives exactly periodic estimates (up to the oracle's bound), whose
    # 1X fit must equal E Xp + T (X - H Xp).
    rig, model = setup
    w = 1800 * 2 * np.pi / 60
    km, angle, y, X, F = steady_window(model, rig, w, 1e-16, np.array([4e-14, 9e-14]), 700)
    T = paper.kf_transfer(km, w)
    Xp = km.Xp[1.0]
    z_transfer = km.E @ Xp + T @ (X - km.H @ Xp)
    x0, cond_start = periodic_start(km, w, X, angle[0])
    ref = filterpy_filter(km, y, angle, x0=x0)
    _, tol_est, _ = agreement_bound(km, ref, y)
    P, K, S = km.steady_state()
    M = np.eye(km.n) - (np.eye(km.n) - K @ km.H) @ km.Phi * np.exp(-1j * w / FS)
    tol = (np.sqrt(2) * tol_est * (1 + cond_start * EPS * len(angle))
           + solve_tol(M) * np.abs(z_transfer).max())
    z_time = fit_1x(ref['estimates'], angle)
    assert np.abs(z_time - z_transfer).max() <= tol, (np.abs(z_time - z_transfer).max(), tol)
    assert tol <= 1e-3 * np.abs(z_transfer).max()            # the check has teeth (a wrong transfer is off by O(1))
    # kf_bearing_phasors is the same closed form through its own model build
    zb = paper.kf_bearing_phasors(model, theory_fn(w), P6, w, X[None], F[None], FS, Q=1e-16,
                                  R=np.array([4e-14, 9e-14]))
    assert np.abs(zb.reshape(-1) - z_transfer).max() <= 2 * solve_tol(M) * np.abs(z_transfer).max()


def two_dof_model(Q):
    """Two masses on springs (ground-m1-m2), q2 measured, 1X force on both: a small filter whose transients decay."""
    M, Ks = np.diag([1.0, 0.5]), np.array([[3e4, -1e4], [-1e4, 1e4]])
    C = np.array([[4.0, -1.0], [-1.0, 1.0]])
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Mi @ Ks, -Mi @ C]])
    B = np.vstack([np.zeros((2, 2)), Mi])
    return kalman.kalman_model(A, B, np.array([[0.0, 1.0, 0.0, 0.0]]), 1 / 2000.0, Q=Q, R=1e-8,
                               forces={1.0: np.array([1.0 + 0.5j, 0.3j])}, speed=50.0, E=np.eye(4)[:2])


def test_smoother_transfer_equals_filterpy_rts_away_from_the_window_end():
    # The RTS smoother's closed-form 1X response against filterpy's rts_smoother on the deviation from the forced
    # response, the filter started in its periodic steady state (a 4-state model: filterpy is cheap and the
    # smoother's end transient decays within the window).  The backward pass starts at the window's end from the
    # filtered estimate, a transient that decays as Cs^j backwards: the fit uses the first n_fit samples, D samples
    # before the end, and the tolerance adds max_(j >= D) ||Cs^j|| x that start's offset (balanced coordinates).
    km = two_dof_model(1e-10)
    w, fs = km.speed, 1 / km.dt
    n_fit, D = 500, 1500
    X = np.array([2e-5 * np.exp(0.7j)])
    angle = 0.3 + w * np.arange(n_fit + D) / fs
    y = np.real(X[None, :] * np.exp(1j * angle)[:, None])
    P, K, S = km.steady_state()
    Fc = km.Phi @ (np.eye(km.n) - K @ km.H)
    zeta = np.exp(1j * w / fs)
    Ehat = np.linalg.solve(zeta * np.eye(km.n) - Fc, km.Phi @ K @ (X - km.H @ km.Xp[1.0]))
    f = KalmanFilter(dim_x=km.n, dim_z=km.m)
    f.F, f.H, f.Q, f.R = km.Phi, km.H, km.Q, km.R
    f.x = np.real(Ehat * np.exp(1j * angle[0])).reshape(-1, 1)          # periodic steady state of e(0|-1)
    f.P = P.copy()
    means, covs, _, _ = f.batch_filter((y - km.particular(angle)).reshape(len(angle), km.m, 1), update_first=True)
    xs, _, Cs_seq, _ = rts_smoother(means, covs, [km.Phi] * len(angle), [km.Q] * len(angle))
    est = xs[:, :, 0] @ km.E.T + km.particular(angle, km.E)
    z_smooth = fit_1x(est[:n_fit], angle[:n_fit])
    Xp = km.Xp[1.0]
    z_transfer = km.E @ Xp + paper.kf_transfer(km, w, smoother=True) @ (X - km.H @ Xp)
    # tolerance: the forward pass (kf_oracle), the backward recursion e_s(k) = (I - Cs Phi) e(k|k) + Cs e_s(k+1)
    # carrying that error, its own gain deviation |Cs_k - Cs| |e_s| and rounding through the powers of Cs, and the
    # end transient
    x0 = km.particular([angle[0]], np.eye(km.n))[0] + np.real(Ehat * np.exp(1j * angle[0]))
    tol_f, _, _ = agreement_bound(km, filterpy_filter(km, y, angle, x0=x0), y)
    Cs = (np.eye(km.n) - K @ km.H) @ P @ km.Phi.T @ np.linalg.inv(P)
    t = balancing(Cs)
    Cs_t = Cs * t[None, :] / t[:, None]
    G_t = (np.eye(km.n) - Cs @ km.Phi) * t[None, :] / t[:, None]
    e_s = xs[:, :, 0] / t[None, :]
    e_max = np.max(np.linalg.norm(e_s, axis=1))
    cs_dev = max(np.linalg.norm((C - Cs) * t[None, :] / t[:, None], 2) for C in Cs_seq[:-1])
    step = (np.linalg.norm(G_t, 2) * tol_f / np.min(t) * np.sqrt(km.n) + cs_dev * e_max
            + km.n * EPS * (np.linalg.norm(Cs_t, 2) + np.linalg.norm(G_t, 2)) * e_max)
    tail, Cj = 0.0, np.linalg.matrix_power(Cs_t, D)
    for _ in range(n_fit):                       # max over the fitted samples of ||Cs^j||, j >= D
        tail = max(tail, np.linalg.norm(Cj, 2))
        Cj = Cs_t @ Cj
    bound_states = growth_sum(Cs_t, len(angle)) * step + tail * 2 * e_max
    M = np.eye(km.n) - (np.eye(km.n) - K @ km.H) @ km.Phi / zeta
    tol = (np.sqrt(2) * np.linalg.norm(km.E * t[None, :], 2) * bound_states
           + EPS * (np.linalg.cond(M) + np.linalg.cond(np.eye(km.n) - zeta * Cs)) * np.abs(z_transfer).max())
    assert np.abs(z_smooth - z_transfer).max() <= tol, (np.abs(z_smooth - z_transfer).max(), tol)
    assert tol <= 1e-6 * np.abs(z_transfer).max()            # the check has teeth
    z_filter = km.E @ Xp + paper.kf_transfer(km, w) @ (X - km.H @ Xp)
    assert np.abs(z_filter - z_transfer).max() > 1e3 * tol   # and the smoother is not the filter


def test_innovations_equal_filterpy(setup):
    rig, model = setup
    w = 1200 * 2 * np.pi / 60
    probes = (Probe('p6x', 6, 'x'), Probe('p6y', 6, 'y'))
    km = kalman.rotor_kalman_model(model, w, theory_fn(w), probes, FS,
                                   forces=harmonic_forces(rig.simulation.runs[0].excitation, w, model.n_nodes),
                                   Q=1e-16, R=np.array([1e-13, 2e-13]))
    rng = np.random.default_rng(2)
    N = 1000                                                  # not a multiple of the chunk: the padded tail too
    angle = 0.1 + w * np.arange(N) / FS
    z = np.real(np.array([2e-6, 1e-6j])[None, :] * np.exp(1j * angle)[:, None]) + 3e-7 * rng.standard_normal((N, 2))
    nu, nis, nm, band = kalman.innovations(km, z, angle)
    ref = filterpy_filter(km, z, angle)
    _, _, tol_nu = agreement_bound(km, ref, z)
    assert np.abs(nu - ref['innovations']).max() <= tol_nu
    S = km.steady_state()[2]
    S_inv = np.linalg.inv(S)
    tol_nis = (2 * km.m * np.abs(nu).max() * np.abs(S_inv).max() * tol_nu
               + km.m ** 2 * np.abs(nu).max() ** 2 * np.abs(S_inv).max() ** 2 * np.abs(ref['S'] - S).max())
    assert np.abs(nis - ref['nis']).max() <= tol_nis + 10 * EPS * np.abs(nis).max()
    assert nm == pytest.approx(float(np.mean(nis)), rel=N * EPS)


def test_expm_frechet_in_the_eigenbasis_equals_scipy(setup):
    # L(A dt, E) = U [(U^-1 E U) o D] U^-1 with D the divided differences of exp at the eigenvalues (what
    # kf_phasor_jacobian contracts with), for the rank-one bearing directions E = u v^T.  Reference: scipy's
    # expm_frechet (block Pade) on the balanced matrix T^-1 A T (L transforms by the same similarity); compared in
    # those balanced coordinates.  Tolerance: the eigenvector route's forward error eps cond(U), plus the Pade
    # route's eps ||A_b dt||_1, times the largest entry.
    rig, model = setup
    w = 1500 * 2 * np.pi / 60
    A, _ = state_space(model, w, theory_fn(w))
    dt = 1 / FS
    n = A.shape[0]
    lam, U, Ui, cond = paper._eig_balanced(A)
    assert cond < paper.EIG_COND_MAX
    Ab, (t, _) = sla.matrix_balance(A, permute=False, separate=True)
    for i, j in ((4, 4), (4, 5), (40, 40), (5, n // 2 + 4)):
        E = np.zeros((n, n))
        E[n // 2:, j] = -model.Minv[:, i]
        L = (U @ ((Ui @ (E * dt) @ U) * paper._exp_divided_differences(lam * dt)) @ Ui).real
        _, Lb = sla.expm_frechet(Ab * dt, E / t[:, None] * t[None, :] * dt)
        Lb_eig = L / t[:, None] * t[None, :]
        tol = EPS * (cond + np.linalg.norm(Ab * dt, 1)) * np.abs(Lb).max()
        assert np.abs(Lb_eig - Lb).max() <= tol


def test_divided_differences_close_and_far_points():
    # reference: expm([[a, 1], [0, b]])[0, 1] = (e^a - e^b) / (a - b) (e^a when a = b), scipy's Pade expm, whose
    # error grows with the block's norm (~max |x|); the series branch (|a - b| < 1e-4) truncates at a relative
    # (1e-4)^4 / 120 < 1e-18.  Tolerance 10 eps max(1, |a|, |b|) relative.
    x = np.array([-1e-3 + 2j, -1e-3 + 2j + 1e-9, -50.0 + 0j, -3.0 - 1j, -3.0 - 1j + 1e-6j])
    D = paper._exp_divided_differences(x)
    for a in range(x.size):
        for b in range(x.size):
            ref = sla.expm(np.array([[x[a], 1.0], [0.0, x[b]]]))[0, 1]
            assert abs(D[a, b] - ref) <= 10 * EPS * max(1.0, abs(x[a]), abs(x[b])) * abs(ref)


def _theta(th0, k, h, w):
    t = th0.copy()
    t[k] += h
    K, C = paper.theta_to_KC(t, w, 2)
    return {n: (K[i], C[i]) for i, n in enumerate((2, 10))}


def test_phasor_jacobian_matches_central_differences(force_case):
    model, w, probes, X, F, R = force_case
    th = theory_fn(w)
    dz = paper.kf_phasor_jacobian(model, th, probes, w, X, F, FS, Q=1e-16, R=R)
    th0 = paper.coeffs_to_theta(th, w, model.bearing_nodes)
    sc = coefficient_scales(th, w, model.bearing_nodes)

    def zof(k, h):
        return paper.kf_bearing_phasors(model, _theta(th0, k, h, w), probes, w, X, F, FS, Q=1e-16, R=R)

    for k in (0, 1, 6, 9, 12, 15):                     # K and Omega C entries, both bearings, direct and cross
        err, tol = richardson_check(lambda h: (zof(k, h) - zof(k, -h)) / (2 * h), 2e-3 * sc[k], dz[..., k],
                                    RICCATI_RESIDUAL, np.abs(zof(k, 0.0)).max())
        assert tol <= 1e-4 * np.abs(dz[..., k]).max()      # the check has teeth


def test_analytic_theory_sensitivity_matches_finite_differences(force_case):
    model, w, probes, X, F, R = force_case
    th = theory_fn(w)
    zB = paper.kf_bearing_phasors(model, th, probes, w, X, F, FS, Q=1e-16, R=R)
    dz = paper.kf_phasor_jacobian(model, th, probes, w, X, F, FS, Q=1e-16, R=R)
    G = paper.theory_sensitivity_analytic(model, w, th, zB, dz, F)
    nodes = model.bearing_nodes
    th0 = paper.coeffs_to_theta(th, w, nodes)
    sc = coefficient_scales(th, w, nodes)

    def theta_of(k, h):                                 # the whole re-solve: KF (Riccati included) + eqs 30-37
        z = paper.kf_bearing_phasors(model, _theta(th0, k, h * sc[k], w), probes, w, X, F, FS, Q=1e-16, R=R)
        A, d = paper.ls_system(z, paper.bearing_forces(model, w, z, F))
        return paper.svd_solve(A, d, paper.DEFAULT_RTOL)[0] / sc

    A0, _ = paper.ls_system(zB, paper.bearing_forces(model, w, zB, F))
    acc = RICCATI_RESIDUAL + lstsq_acc(np.linalg.cond(A0))
    for k in range(16):
        richardson_check(lambda h: (theta_of(k, h) - theta_of(k, -h)) / (2 * h), 1e-3, G[:, k], acc,
                         np.abs(theta_of(k, 0.0)).max())
    # the production fallback (forward differences at h = THEORY_STEP) is off the tangent by exactly
    # (h / 2) x the second difference at h (forward - central) plus the central difference's own error (Richardson)

    def zb_of(co):
        return paper.kf_bearing_phasors(model, co, probes, w, X, F, FS, Q=1e-16, R=R)

    Gf = paper.theory_sensitivity(model, w, th, zb_of, F)
    h = paper.THEORY_STEP
    base = theta_of(0, 0.0)
    for k in range(16):
        up, down = theta_of(k, h), theta_of(k, -h)
        c1, c2 = (up - down) / (2 * h), (theta_of(k, h / 2) - theta_of(k, -h / 2)) / h
        tol = (h / 2) * np.abs((up - 2 * base + down) / h ** 2).max() + 2 * np.abs(c1 - c2).max()
        assert np.abs(Gf[:, k] - G[:, k]).max() <= tol


def test_ls_jacobian_matches_central_differences(setup):
    # eqs 30-37 solution derivative (Golub-Pereyra) against central differences of svd_solve: square (2 runs) and
    # overdetermined (3 runs) systems, Richardson tolerance (module docstring)
    rig, model = setup
    w = 1500 * 2 * np.pi / 60
    rng = np.random.default_rng(4)
    runs = rigmod.scenario('force')
    for nr in (2, 3):
        F = paper.forces_at(model, runs[:nr], w)
        z = (rng.standard_normal((nr, 2, 2)) + 1j * rng.standard_normal((nr, 2, 2))) * 1e-6
        _, Jre, Jim = paper.ls_jacobian(model, w, z, F)

        def th_of(zz):
            A, d = paper.ls_system(zz, paper.bearing_forces(model, w, zz, F))
            return paper.svd_solve(A, d, paper.DEFAULT_RTOL)[0]

        A0 = paper.ls_system(z, paper.bearing_forces(model, w, z, F))[0]
        acc = lstsq_acc(np.linalg.cond(A0))
        scale = np.abs(th_of(z)).max()

        for q in range(z.size):
            for unit, J in ((1.0, Jre), (1j, Jim)):
                e = np.zeros(z.size, dtype=complex)
                e[q] = unit
                e = e.reshape(z.shape)
                richardson_check(lambda h: (th_of(z + h * e) - th_of(z - h * e)) / (2 * h), 1e-4 * np.abs(z).max(),
                                 J[:, q], acc, scale)


def test_bearing_force_map_equals_eqs_30_to_32(setup):
    # eqs 30-32 as one precomputed affine map (f0 + Lin z_B, built from the same equations at z_B = 0 and at the unit
    # vectors) against bearing_forces at the given z_B: both are solves with H_uu, each off by ~eps cond(H_uu) of
    # the largest force it involves
    rig, model = setup
    w = 1500 * 2 * np.pi / 60
    rng = np.random.default_rng(7)
    runs = rigmod.scenario('force')
    F = paper.forces_at(model, runs, w)
    z = (rng.standard_normal((len(F), 2, 2)) + 1j * rng.standard_normal((len(F), 2, 2))) * 1e-6
    fmap, Lin = paper.bearing_force_map(model, w, F)
    ref = paper.bearing_forces(model, w, z, F)
    HR = dynamic_stiffness(model, w, w, {})
    u = np.setdiff1d(np.arange(model.ndof), paper.bearing_dofs(model))
    scale = max(np.abs(F).max(), np.abs(HR).max() * np.abs(z).max())
    assert np.abs(fmap(z) - ref).max() <= 10 * EPS * np.linalg.cond(HR[np.ix_(u, u)]) * scale


def test_identify_paper_with_the_smoother_takes_the_difference_sensitivity(setup):
    rig, model = setup
    p6 = tuple(Probe(f'p6{d}', 6, d) for d in ('x', 'y'))
    recs = [rigmod.simulate_run(rig, run, speeds_rpm=[1500], dwell=0.6, ramp=0.0, probes=p6,
                                bearing_fn=lambda s: theory_fn(s, 1.25), noise=0.01, seed=3 + k, model=model)
            for k, run in enumerate(rigmod.scenario('force'))]
    d = harmonics.from_recordings(recs)
    ra = paper.identify_paper(model, rig, d, d.probes, d.runs, {'bearing_fn': theory_fn})[0]
    rs = paper.identify_paper(model, rig, d, d.probes, d.runs, {'bearing_fn': theory_fn, 'smoother': True})[0]
    assert any('analytic derivative' in n for n in ra.notes)
    assert any('finite differences' in n for n in rs.notes)
    assert np.all(np.isfinite(rs.extra['theory_jacobian']))
    for old in ('kf_route', 'sensitivity'):
        with pytest.raises(ValueError, match='unknown option'):
            paper.identify_paper(model, rig, d, d.probes, d.runs, {old: 'time'})
