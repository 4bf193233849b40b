"""
The paper method's fast paths (identify/paper.py, kalman.py) tied to their references.

* The steady-state filter's closed-form 1X response (kf_transfer, kf_bearing_phasors) against the time-domain
  filter (fast_filter, itself tied to filterpy in test_kalman.py) on a steady window: 1e-9 relative.
* The innovations-only operator (kalman.innovations) against fast_filter and filterpy's loop: 1e-9 relative.
* The analytic derivative of the KF's bearing-node phasors (kf_phasor_jacobian) and of the identified coefficients
  (theory_sensitivity_analytic) against central finite differences of the full re-solve (Riccati included).  The
  finite-difference reference carries the Riccati solution's own error (relative ~1e-11) divided by the step, plus a
  truncation error O(step^2): at step 1e-3 of each group's size it is good to ~1e-7, so the tolerance is 1e-5;
  Richardson extrapolation of two steps is checked too.  The old production forward difference (1 % step) differs
  from the tangent by its O(step) truncation error: <= 2 % of the largest entry here.
* The Frechet derivative of expm in the eigenbasis (Daleckii-Krein) against scipy.linalg.expm_frechet.
* The NIS band with scipy.special.chdtri against scipy.stats.chi2.
"""
from bearing_id.config.params import load_rig, Probe
from bearing_id.estimation import kalman
from bearing_id.identify import harmonics, paper
from bearing_id.identify.lsq import coefficient_scales
from bearing_id.rotor.assembly import RotorModel
from bearing_id.simulation import rig as rigmod
from bearing_id.simulation.rig import simulate_data
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


def test_transfer_equals_time_domain_filter_on_a_steady_window(setup):
    # A steady window: constant speed, the probes reading a pure 1X (not the theory model's response, so the filter
    # has something to correct) plus a DC, and the filter started in its own periodic steady state.  The time-domain
    # filter's estimates are then exactly periodic and their 1X fit must equal E Xp + T (X - H Xp).
    rig, model = setup
    w = 1800 * 2 * np.pi / 60
    probes = (Probe('p6x', 6, 'x'), Probe('p6y', 6, 'y'))
    run = rig.simulation.runs[0]
    from bearing_id.excitation import harmonic_forces
    forces = harmonic_forces(run.excitation, w, model.n_nodes)
    km = kalman.rotor_kalman_model(model, w, theory_fn(w), probes, FS, forces=forces, Q=1e-16,
                                   R=np.array([4e-14, 9e-14]))
    X = np.array([3e-6 * np.exp(0.4j), 2.2e-6 * np.exp(-1.1j)])
    N = int(round(FS * 2 * np.pi / w * 40))                  # 40 revolutions
    angle = 0.3 + w * np.arange(N) / FS
    y = np.real(X[None, :] * np.exp(1j * angle)[:, None])
    T = paper.kf_transfer(km, w)
    Xp = km.Xp[1.0]
    z_transfer = km.E @ Xp + T @ (X - km.H @ Xp)
    # periodic steady state of the prior deviation: e-(k) = Re{Ehat exp(j angle_k)}, Ehat = (zeta I - Fc)^-1 Phi K Y
    P, K, S = km.steady_state()
    Fc = km.Phi @ (np.eye(km.n) - K @ km.H)
    zeta = np.exp(1j * w / FS)
    Ehat = np.linalg.solve(zeta * np.eye(km.n) - Fc, km.Phi @ K @ (X - km.H @ Xp))
    x0 = kalman.particular_state(km.Xp, [angle[0]])[0] + np.real(Ehat * np.exp(1j * angle[0]))
    from bearing_id.signals.harmonics import harmonic_vectors
    out = kalman.fast_filter(km, y, angle, x0=x0)
    z_time = harmonic_vectors(out.estimates, angle).X[0]
    assert np.abs(z_time - z_transfer).max() <= 1e-9 * np.abs(z_transfer).max()
    # kf_bearing_phasors is the same closed form through its own model build
    zb = paper.kf_bearing_phasors(model, theory_fn(w), probes, w, X[None], np.array([forces[1.0]]), FS, Q=1e-16,
                                  R=np.array([4e-14, 9e-14]))
    assert np.abs(zb.reshape(-1) - z_transfer).max() <= 1e-9 * np.abs(z_transfer).max()


def test_paper_transfer_route_agrees_with_the_time_route_on_simulated_windows(setup):
    # Noisy simulated windows, filter started at the theory model's steady state: the routes differ only by the
    # time-domain filter's start transient and edge effects of the noise (a few 0.1 %), and the NIS is the same
    # number (the innovations are computed in the time domain by both).
    rig, model = setup
    probes = (Probe('p6x', 6, 'x'), Probe('p6y', 6, 'y'))
    recs = [rigmod.simulate_run(rig, run, speeds_rpm=[1500], dwell=1.0, probes=probes, noise=0.01, seed=5 + k,
                                model=model) for k, run in enumerate(rig.simulation.runs)]
    data = harmonics.from_recordings(recs)
    th = theory_fn(float(data.speeds[0]))
    dt, dr = {}, {}
    zt, _, nis_t, _ = paper.kf_bearing_vectors(model, th, probes, data, 0, route='time', details=dt)
    zr, _, nis_r, _ = paper.kf_bearing_vectors(model, th, probes, data, 0, route='transfer', details=dr)
    assert np.linalg.norm(zr - zt) <= 0.01 * np.linalg.norm(zt)
    np.testing.assert_allclose(nis_r, nis_t, rtol=1e-9)
    for a, b in zip(dt['R'], dr['R']):
        np.testing.assert_allclose(a, b, rtol=1e-12)


def test_innovations_equal_fast_filter_and_filterpy(setup):
    rig, model = setup
    w = 1200 * 2 * np.pi / 60
    probes = (Probe('p6x', 6, 'x'), Probe('p6y', 6, 'y'))
    from bearing_id.excitation import harmonic_forces
    km = kalman.rotor_kalman_model(model, w, theory_fn(w), probes, FS,
                                   forces=harmonic_forces(rig.simulation.runs[0].excitation, w, model.n_nodes),
                                   Q=1e-16, R=np.array([1e-13, 2e-13]))
    rng = np.random.default_rng(2)
    N = 1000                                                  # not a multiple of the chunk: the padded tail too
    angle = 0.1 + w * np.arange(N) / FS
    z = np.real(np.array([2e-6, 1e-6j])[None, :] * np.exp(1j * angle)[:, None]) + 3e-7 * rng.standard_normal((N, 2))
    nu, nis, nm, band = kalman.innovations(km, z, angle)
    ff = kalman.fast_filter(km, z, angle)
    ref = kalman.reference_filter(km, z, angle)
    for other in (ff, ref):
        assert np.abs(nu - other.innovations).max() <= 1e-9 * np.abs(other.innovations).max()
        np.testing.assert_allclose(nis, other.nis, rtol=1e-9, atol=1e-12)
    assert nm == pytest.approx(ff.nis_mean, rel=1e-12) and band == pytest.approx(ff.nis_band, rel=1e-12)


def test_nis_band_equals_scipy_stats_chi2():
    from scipy.stats import chi2
    for n, m in ((1, 1), (100, 2), (20480, 2), (7, 3)):
        lo, hi = kalman.nis_band(n, m)
        assert lo == pytest.approx(chi2.ppf(0.025, n * m) / n, rel=1e-12)
        assert hi == pytest.approx(chi2.ppf(0.975, n * m) / n, rel=1e-12)


def test_expm_frechet_in_the_eigenbasis_equals_scipy(setup):
    # L(A dt, E) = U [(U^-1 E U) o D] U^-1 with D the divided differences of exp at the eigenvalues (what
    # kf_phasor_jacobian contracts with), for the rank-one bearing directions E = u v^T.  Reference: scipy's
    # expm_frechet (block Pade) on the balanced matrix T^-1 A T (L transforms by the same similarity); compared in
    # those balanced coordinates.  (scipy on the unbalanced A, entries 1 ... 2.5e11, is off by up to 7e-4.)
    rig, model = setup
    w = 1500 * 2 * np.pi / 60
    from bearing_id.rotor.assembly import state_space
    A, _ = state_space(model, w, theory_fn(w))
    dt = 1 / FS
    n = A.shape[0]
    lam, U, Ui, cond = paper._eig_balanced(A)
    assert cond < 1e5
    Ab, (t, _) = sla.matrix_balance(A, permute=False, separate=True)
    for i, j in ((4, 4), (4, 5), (40, 40), (5, n // 2 + 4)):
        E = np.zeros((n, n))
        E[n // 2:, j] = -model.Minv[:, i]
        L = (U @ ((Ui @ (E * dt) @ U) * paper._exp_divided_differences(lam * dt)) @ Ui).real
        _, Lb = sla.expm_frechet(Ab * dt, E / t[:, None] * t[None, :] * dt)
        Lb_eig = L / t[:, None] * t[None, :]
        assert np.abs(Lb_eig - Lb).max() <= 1e-10 * np.abs(Lb).max()


def test_divided_differences_close_and_far_points():
    # reference: expm([[a, 1], [0, b]])[0, 1] = (e^a - e^b) / (a - b) (e^a when a = b), scipy's Pade expm
    x = np.array([-1e-3 + 2j, -1e-3 + 2j + 1e-9, -50.0 + 0j, -3.0 - 1j, -3.0 - 1j + 1e-6j])
    D = paper._exp_divided_differences(x)
    for a in range(x.size):
        for b in range(x.size):
            ref = sla.expm(np.array([[x[a], 1.0], [0.0, x[b]]]))[0, 1]
            assert abs(D[a, b] - ref) <= 1e-12 * abs(ref)


def _theta(th0, k, h, w):
    t = th0.copy()
    t[k] += h
    K, C = paper.theta_to_KC(t, w, 2)
    return {n: (K[i], C[i]) for i, n in enumerate((2, 10))}


def test_phasor_jacobian_matches_central_differences(force_case):
    model, w, probes, X, F, R = force_case
    th = theory_fn(w)
    zB, dz = paper.kf_phasor_jacobian(model, th, probes, w, X, F, FS, Q=1e-16, R=R)
    zref = paper.kf_bearing_phasors(model, th, probes, w, X, F, FS, Q=1e-16, R=R)
    assert np.abs(zB - zref).max() <= 1e-9 * np.abs(zref).max()
    th0 = paper.coeffs_to_theta(th, w, model.bearing_nodes)
    sc = coefficient_scales(th, w, model.bearing_nodes)

    def zof(k, h):
        return paper.kf_bearing_phasors(model, _theta(th0, k, h, w), probes, w, X, F, FS, Q=1e-16, R=R)

    for k in (0, 1, 6, 9, 12, 15):                     # K and Omega C entries, both bearings, direct and cross
        h = 2e-3 * sc[k]
        fd = (zof(k, h) - zof(k, -h)) / (2 * h)
        fd2 = (zof(k, h / 2) - zof(k, -h / 2)) / h
        rich = (4 * fd2 - fd) / 3
        ref = np.abs(dz[..., k]).max()
        assert np.abs(fd - dz[..., k]).max() <= 1e-5 * ref
        assert np.abs(rich - dz[..., k]).max() <= 1e-5 * ref


def test_analytic_theory_sensitivity_matches_the_finite_difference_reference(force_case):
    model, w, probes, X, F, R = force_case
    th = theory_fn(w)
    G, _ = paper.theory_sensitivity_analytic(model, w, th, probes, X, F, FS, Q=1e-16, R=R)

    def zb_of(co):
        return paper.kf_bearing_phasors(model, co, probes, w, X, F, FS, Q=1e-16, R=R)

    Gc = paper.theory_sensitivity(model, w, th, zb_of, F, step=1e-3, central=True)
    assert np.abs(G - Gc).max() <= 1e-5 * np.abs(G).max()
    Gf = paper.theory_sensitivity(model, w, th, zb_of, F)      # the old production route: forward, 1 % step
    assert np.abs(G - Gf).max() <= 0.02 * np.abs(G).max()
    s_a, f_a = paper.theory_fractions(G)
    s_f, f_f = paper.theory_fractions(Gf)
    assert f_a == pytest.approx(f_f, rel=0.02)


def test_ls_jacobian_matches_central_differences(setup):
    # eqs 30-37 solution derivative (Golub-Pereyra) against central differences of svd_solve: square (2 runs) and
    # overdetermined (3 runs) systems; the map is smooth and cheap, so FD at 1e-6 is good to ~1e-8
    rig, model = setup
    w = 1500 * 2 * np.pi / 60
    rng = np.random.default_rng(4)
    runs = rigmod.scenario('force')
    for nr in (2, 3):
        F = paper.forces_at(model, runs[:nr], w)
        z = (rng.standard_normal((nr, 2, 2)) + 1j * rng.standard_normal((nr, 2, 2))) * 1e-6
        theta, Jre, Jim = paper.ls_jacobian(model, w, z, F)

        def th_of(zz):
            A, d = paper.ls_system(zz, paper.bearing_forces(model, w, zz, F))
            return paper.svd_solve(A, d, paper.DEFAULT_RTOL)[0]

        np.testing.assert_allclose(theta, th_of(z), rtol=1e-12, atol=1e-12 * np.abs(theta).max())
        h = 1e-6 * np.abs(z).max()
        for q in range(z.size):
            for unit, J in ((1.0, Jre), (1j, Jim)):
                dzq = np.zeros(z.size, dtype=complex)
                dzq[q] = unit * h
                fd = (th_of(z + dzq.reshape(z.shape)) - th_of(z - dzq.reshape(z.shape))) / (2 * h)
                assert np.abs(fd - J[:, q]).max() <= 1e-6 * np.abs(J).max()


def test_identify_paper_analytic_and_fd_sensitivity_agree_and_time_route_still_runs(setup):
    rig, model = setup
    p6 = tuple(Probe(f'p6{d}', 6, d) for d in ('x', 'y'))
    recs = [rigmod.simulate_run(rig, run, speeds_rpm=[1500], dwell=0.6, ramp=0.0, probes=p6,
                                bearing_fn=lambda s: theory_fn(s, 1.25), noise=0.01, seed=3 + k, model=model)
            for k, run in enumerate(rigmod.scenario('force'))]
    d = harmonics.from_recordings(recs)
    ra = paper.identify_paper(model, rig, d, d.probes, d.runs, {'bearing_fn': theory_fn})[0]
    rf = paper.identify_paper(model, rig, d, d.probes, d.runs, {'bearing_fn': theory_fn, 'sensitivity': 'fd'})[0]
    np.testing.assert_allclose(ra.K, rf.K, rtol=1e-12)             # same vectors, same solve
    Ga, Gf = ra.extra['theory_jacobian'], rf.extra['theory_jacobian']
    assert np.abs(Ga - Gf).max() <= 0.02 * np.abs(Ga).max()
    assert any('analytic derivative' in n for n in ra.notes)
    assert any('finite differences' in n for n in rf.notes)
    rt = paper.identify_paper(model, rig, d, d.probes, d.runs, {'bearing_fn': theory_fn, 'kf_route': 'time'})[0]
    assert rt.extra['kf_route'] == 'time' and ra.extra['kf_route'] == 'transfer'
    assert np.linalg.norm(rt.extra['z_B'] - ra.extra['z_B']) <= 0.02 * np.linalg.norm(ra.extra['z_B'])
    with pytest.raises(ValueError, match='kf_route'):
        paper.identify_paper(model, rig, d, d.probes, d.runs, {'kf_route': 'fast'})


def test_bearing_force_map_and_the_solve_equal_the_reference(setup):
    # eqs 30-32 as one precomputed affine map must equal bearing_forces (a rotor solve per call), and the eqs 33-37
    # solve with it (std by finite differences, misfit) must equal the solve without it
    from bearing_id.identify.lsq import solve_coefficients
    rig, model = setup
    w = 1500 * 2 * np.pi / 60
    rng = np.random.default_rng(7)
    runs = rigmod.scenario('force')
    F = paper.forces_at(model, runs, w)
    z = (rng.standard_normal((len(F), 2, 2)) + 1j * rng.standard_normal((len(F), 2, 2))) * 1e-6
    fmap, _ = paper.bearing_force_map(model, w, F)
    ref = paper.bearing_forces(model, w, z, F)
    assert np.abs(fmap(z) - ref).max() <= 1e-12 * np.abs(ref).max()
    zs = np.abs(z) * 1e-2
    a = solve_coefficients(model, w, z, F, z_B_std=zs)
    b = solve_coefficients(model, w, z, F, z_B_std=zs, forces_of=fmap)
    np.testing.assert_allclose(b.theta, a.theta, rtol=1e-9, atol=1e-9 * np.abs(a.theta).max())
    np.testing.assert_allclose(b.theta_std, a.theta_std, rtol=1e-6)           # FD std: step-size noise ~1e-8
    assert b.chi2 == pytest.approx(a.chi2, rel=1e-6) and b.dof == a.dof
