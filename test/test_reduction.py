"""
Craig-Bampton reduction for the Kalman filter (bearing_id/rotor/reduction.py) and the paper route on it.

References: the full FE model (every fixed-interface mode kept makes the reduction an exact change of coordinates, so
the reduced filter is the full one in other coordinates); the Guyan property (no mode kept: the static receptance
between kept DOFs is exact); convergence of the 1X receptance with the cutoff.

Tolerances (derived): a change of coordinates T moves a solve's rounding by ~eps cond(T); each filter's bearing
phasors carry its Riccati solution's error, estimated here by one Newton step on that solution (P + L^-1 Res(P),
the Stein operator L solved by scipy) and re-evaluating the phasors and their derivative -- x10 for the
linearisation -- plus the rounding of the transfer's solve and of expm, eps x their balanced condition numbers.
"""
import dataclasses

from bearing_id.config.params import load_rig, Probe
from bearing_id.conventions import dof_index
from bearing_id.estimation import kalman
from bearing_id.identify import harmonics, paper
from bearing_id.identify.lsq import coefficient_scales
from bearing_id.rotor import reduction
from bearing_id.rotor.assembly import dynamic_stiffness, RotorModel
from bearing_id.simulation import rig as rigmod
from error_bounds import RICCATI_RESIDUAL, richardson_check, solve_tol
import numpy as np
import pytest
import scipy.linalg as sla

EPS = np.finfo(float).eps

FS = 10240.0
P6 = (Probe('p6x', 6, 'x'), Probe('p6y', 6, 'y'))


def theory_fn(w, f=1.0):
    K = f * np.array([[2.0e5, 1.2e5], [-0.6e5, 3.0e5]]) * (1 + w / 300)
    C = f * np.array([[300.0, 60.0], [60.0, 500.0]])
    return {2: (K, C), 10: (1.1 * K, 0.9 * C)}


@pytest.fixture(scope='module')
def setup():
    rig = load_rig()
    model = RotorModel.from_params(rig)
    w = 1500 * 2 * np.pi / 60
    runs = rigmod.scenario('force')
    F = paper.forces_at(model, runs, w)
    kept = reduction.kf_kept_dofs(model, P6, F)
    return rig, model, w, runs, F, kept


def test_kept_dofs_are_bearings_probes_and_forces(setup):
    rig, model, w, runs, F, kept = setup
    for node in (2, 10, 6):
        assert dof_index(node, 'x', model.n_nodes) in kept and dof_index(node, 'y', model.n_nodes) in kept
    for f in F:
        assert set(np.flatnonzero(np.abs(f) > 0)) <= set(kept)


def test_transformation_and_left_inverse(setup):
    # products of length ndof: rounding <= ndof eps ||A|| ||B|| (2-norms)
    rig, model, w, runs, F, kept = setup
    red = reduction.craig_bampton(model, kept, n_modes=6)
    nd = model.ndof
    L2, T2 = np.linalg.norm(red.L, 2), np.linalg.norm(red.T, 2)
    assert np.abs(red.L @ red.T - np.eye(red.nr)).max() <= nd * EPS * L2 * T2
    assert np.all(red.T[red.kept] == np.eye(red.nr)[:red.kept.size])     # kept rows are unit rows (set, not computed)
    modal = red.M[red.kept.size:, red.kept.size:]                                           # mass-normalised modes
    assert np.abs(modal - np.eye(red.n_modes)).max() <= nd * EPS * T2 ** 2 * np.linalg.norm(model.M, 2)


def _exact_bound(model, red, w, omega):
    """Return the rounding of the two receptances when the reduction is exact: two solves' bounds, relative."""
    return solve_tol(dynamic_stiffness(model, w, omega, theory_fn(w)), red.dynamic_stiffness(w, omega, theory_fn(w)))


def test_guyan_static_receptance_is_exact(setup):
    # no fixed-interface mode: the reduction is Guyan's, exact for static loads on kept DOFs (omega = 0)
    rig, model, w, runs, F, kept = setup
    red = reduction.craig_bampton(model, kept)
    assert red.n_modes == 0
    assert reduction.receptance_error(red, w, theory_fn(w), omega=0.0) <= _exact_bound(model, red, w, 0.0)


def test_receptance_converges_with_the_cutoff(setup):
    rig, model, w, runs, F, kept = setup
    reds = [reduction.craig_bampton(model, kept, cutoff_hz=c) for c in (500.0, 2000.0, 8000.0, 1e6)]
    errs = [reduction.receptance_error(r, w, theory_fn(w)) for r in reds]
    assert all(b <= a for a, b in zip(errs, errs[1:]))
    assert errs[-1] <= _exact_bound(model, reds[-1], w, w)          # every mode kept: exact
    # and the reduced dynamic stiffness is the projected full one (products of length ndof, as above)
    red = reduction.craig_bampton(model, kept, n_modes=5)
    Z = dynamic_stiffness(model, w, w, theory_fn(w))
    tol = model.ndof * EPS * np.linalg.norm(red.T, 2) ** 2 * np.abs(Z).max()
    assert np.abs(red.dynamic_stiffness(w, w, theory_fn(w)) - red.T.T @ Z @ red.T).max() <= tol


def _balanced_cond(M):
    return np.linalg.cond(sla.matrix_balance(M, permute=False)[0])


def _route_error(model, rotor, w, X, F, R):
    """
    Estimated error of one filter's (z_B, dz) from its Riccati solution, and its rounding scale (module docstring).

    Returns (|z(P*) - z(P)|, |dz(P*) - dz(P)|, eps x balanced cond of the transfer's M and of Phi).
    """
    km = kalman.rotor_kalman_model(rotor, w, theory_fn(w), P6, FS, Q=1e-16, R=R[0])
    P, K, S = km.steady_state()
    Fc = km.Phi @ (np.eye(km.n) - K @ km.H)
    Pn = P + sla.solve_discrete_lyapunov(Fc, kalman.riccati_residual(km.Phi, km.H, km.Q, km.R, P))
    Sn = km.H @ Pn @ km.H.T + km.R
    refined = dataclasses.replace(km, _ss=(Pn, np.linalg.solve(Sn, km.H @ Pn).T, Sn), _chunked={})
    kf_rotor = None if rotor is model else rotor
    out = []
    for k in (km, refined):
        Xp = np.linalg.solve(1j * w * np.eye(k.n) - k.A, k.B @ F.T)
        T = paper.kf_transfer(k, w)
        z = np.array([k.E @ Xp[:, r] + T @ (X[r] - k.H @ Xp[:, r]) for r in range(len(F))])
        dz = paper.kf_phasor_jacobian(model, theory_fn(w), P6, w, X, F, FS, R=R, kms=[k] * len(F), kf_rotor=kf_rotor)
        out.append((z, dz))
    M = np.eye(km.n) - (np.eye(km.n) - K @ km.H) @ km.Phi * np.exp(-1j * w / FS)
    return (np.abs(out[1][0] - out[0][0]).max(), np.abs(out[1][1] - out[0][1]).max(),
            EPS * (_balanced_cond(M) + _balanced_cond(km.Phi)))


def test_reduced_filter_with_every_mode_equals_the_full_filter(setup):
    # T square: the reduced filter (process noise mapped by L) is the full filter in other coordinates
    rig, model, w, runs, F, kept = setup
    n_int = model.ndof - len(kept)
    red = reduction.craig_bampton(model, kept, n_modes=n_int)
    X = np.array([[3e-6 * np.exp(0.4j), 2e-6 * np.exp(-1.0j)]] * len(F))
    R = [np.array([1e-14, 2e-14])] * len(F)
    z_full = paper.kf_bearing_phasors(model, theory_fn(w), P6, w, X, F, FS, R=R)
    z_red = paper.kf_bearing_phasors(model, theory_fn(w), P6, w, X, F, FS, R=R, kf_rotor=red)
    dz_full = paper.kf_phasor_jacobian(model, theory_fn(w), P6, w, X, F, FS, R=R)
    dz_red = paper.kf_phasor_jacobian(model, theory_fn(w), P6, w, X, F, FS, R=R, kf_rotor=red)
    ez_f, edz_f, rnd_f = _route_error(model, model, w, X, F, R)
    ez_r, edz_r, rnd_r = _route_error(model, red, w, X, F, R)
    rounding = rnd_f + rnd_r + EPS * np.linalg.cond(red.T)
    assert np.abs(z_red - z_full).max() <= 10 * (ez_f + ez_r) + rounding * np.abs(z_full).max()
    assert np.abs(dz_red - dz_full).max() <= 10 * (edz_f + edz_r) + rounding * np.abs(dz_full).max()


def test_reduced_jacobian_matches_finite_differences_on_the_reduced_filter(setup):
    rig, model, w, runs, F, kept = setup
    red = reduction.craig_bampton(model, kept, cutoff_hz=FS / 2)
    X = np.array([[3e-6 * np.exp(0.4j), 2e-6 * np.exp(-1.0j)]] * len(F))
    R = 2e-14
    th = theory_fn(w)
    dz = paper.kf_phasor_jacobian(model, th, P6, w, X, F, FS, R=R, kf_rotor=red)
    th0 = paper.coeffs_to_theta(th, w, model.bearing_nodes)
    sc = coefficient_scales(th, w, model.bearing_nodes)

    def z_of(k, h):
        t = th0.copy()
        t[k] += h
        K, C = paper.theta_to_KC(t, w, 2)
        co = {n: (K[i], C[i]) for i, n in enumerate(model.bearing_nodes)}
        return paper.kf_bearing_phasors(model, co, P6, w, X, F, FS, R=R, kf_rotor=red)

    # Richardson's error estimate plus the filter's rounding (test/error_bounds.py richardson_check)
    for k in (0, 5, 10, 15):
        _, tol = richardson_check(lambda h: (z_of(k, h) - z_of(k, -h)) / (2 * h), 2e-3 * sc[k], dz[..., k],
                                  RICCATI_RESIDUAL, np.abs(z_of(k, 0.0)).max())
        assert tol <= 2e-4 * np.abs(dz[..., k]).max()       # the check has teeth


def test_identify_paper_on_a_reduced_filter_reports_it_and_stays_close(setup):
    rig, model, w, runs, F, kept = setup
    recs = [rigmod.simulate_run(rig, run, speeds_rpm=[1500], dwell=0.6, ramp=0.0, probes=P6,
                                bearing_fn=lambda s: theory_fn(s, 1.25), noise=0.01, seed=3 + k, model=model)
            for k, run in enumerate(runs)]
    d = harmonics.from_recordings(recs)
    full = paper.identify_paper(model, rig, d, d.probes, d.runs, {'bearing_fn': theory_fn})[0]
    red = paper.identify_paper(model, rig, d, d.probes, d.runs, {'bearing_fn': theory_fn, 'reduce': True})[0]
    info = red.extra['reduction']
    assert info['states'] < info['full_states'] and info['receptance_error'] < 1e-4
    assert any('Craig-Bampton' in n for n in red.notes)
    # the reduced filter (cutoff at Nyquist) moves the KF's bearing vectors by well under 1 % here
    dz = np.linalg.norm(red.extra['z_B'] - full.extra['z_B']) / np.linalg.norm(full.extra['z_B'])
    assert dz < 0.01
    chk = paper.identify_paper(model, rig, d, d.probes, d.runs,
                               {'bearing_fn': theory_fn, 'reduce': {'cutoff_hz': FS / 2, 'check': True}})[0]
    info = chk.extra['reduction']
    assert info['check_states'] > info['states']
    # the check is an estimate of the KF-level truncation: of the size of the actual difference from the full filter
    dzc = np.linalg.norm(chk.extra['z_B'] - full.extra['z_B']) / np.linalg.norm(full.extra['z_B'])
    assert 0.2 * dzc <= info['kf_truncation'] <= 5 * dzc
    assert any('truncation check' in n for n in chk.notes)
    with pytest.raises(ValueError, match='reduce'):
        paper.identify_paper(model, rig, d, d.probes, d.runs, {'bearing_fn': theory_fn, 'reduce': 'yes'})


def test_reduced_kalman_model_builds_and_filters(setup):
    rig, model, w, runs, F, kept = setup
    red = reduction.craig_bampton(model, kept, cutoff_hz=3000.0)
    km = kalman.rotor_kalman_model(red, w, theory_fn(w), P6, FS, forces={1.0: F[0]}, Q=1e-16, R=1e-14)
    assert km.n == 2 * red.nr and km.H.shape == (2, km.n) and km.E.shape == (4, km.n)
    N = 600
    angle = w * np.arange(N) / FS
    y = km.particular(angle)                                        # the model's own response: zero innovations
    out = kalman.fast_filter(km, y, angle, return_states=True)
    # only rounding is left: one step's rounding propagated through the closed loop (test/kf_oracle.py)
    from kf_oracle import balancing, closed_loop, growth_sum, output_bounds, rounding_step
    Fc = closed_loop(km)
    t = balancing(Fc)
    d = growth_sum(Fc * t[None, :] / t[:, None], N) * rounding_step(km, out.states, y, t)
    assert np.abs(out.innovations).max() <= output_bounds(km, d, t)[2]
