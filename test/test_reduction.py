"""
Craig-Bampton reduction for the Kalman filter (bearing_id/rotor/reduction.py) and the paper route on it.

References: the full FE model (every fixed-interface mode kept makes the reduction an exact change of coordinates, so
the reduced filter must equal the full one to round-off: 1e-9); the Guyan property (no mode kept: the static
receptance between kept DOFs is exact); convergence of the 1X receptance with the cutoff.
"""
from bearing_id.config.params import load_rig, Probe
from bearing_id.estimation import kalman
from bearing_id.identify import harmonics, paper
from bearing_id.rotor import reduction
from bearing_id.rotor.assembly import dynamic_stiffness, RotorModel
from bearing_id.simulation import rig as rigmod
import numpy as np
import pytest

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
    from bearing_id.conventions import dof_index
    for node in (2, 10, 6):
        assert dof_index(node, 'x', model.n_nodes) in kept and dof_index(node, 'y', model.n_nodes) in kept
    for f in F:
        assert set(np.flatnonzero(np.abs(f) > 0)) <= set(kept)


def test_transformation_and_left_inverse(setup):
    rig, model, w, runs, F, kept = setup
    red = reduction.craig_bampton(model, kept, n_modes=6)
    np.testing.assert_allclose(red.L @ red.T, np.eye(red.nr), atol=1e-12)
    np.testing.assert_allclose(red.T[red.kept], np.eye(red.nr)[:red.kept.size], atol=0)     # kept rows are unit
    np.testing.assert_allclose(red.M[red.kept.size:, red.kept.size:], np.eye(red.n_modes), atol=1e-10)


def test_guyan_static_receptance_is_exact(setup):
    # no fixed-interface mode: the reduction is Guyan's, exact for static loads on kept DOFs (omega = 0)
    rig, model, w, runs, F, kept = setup
    red = reduction.craig_bampton(model, kept)
    assert red.n_modes == 0
    assert reduction.receptance_error(red, w, theory_fn(w), omega=0.0) <= 1e-10


def test_receptance_converges_with_the_cutoff(setup):
    rig, model, w, runs, F, kept = setup
    errs = [reduction.receptance_error(reduction.craig_bampton(model, kept, cutoff_hz=c), w, theory_fn(w))
            for c in (500.0, 2000.0, 8000.0, 1e6)]
    assert all(b <= a for a, b in zip(errs, errs[1:]))
    assert errs[-1] <= 1e-10                               # every mode kept: exact
    # and the reduced dynamic stiffness is the projected full one
    red = reduction.craig_bampton(model, kept, n_modes=5)
    Z = dynamic_stiffness(model, w, w, theory_fn(w))
    np.testing.assert_allclose(red.dynamic_stiffness(w, w, theory_fn(w)), red.T.T @ Z @ red.T,
                               atol=1e-9 * np.abs(Z).max())


def test_reduced_filter_with_every_mode_equals_the_full_filter(setup):
    # T square: the reduced filter (process noise mapped by L) is the full filter in other coordinates
    rig, model, w, runs, F, kept = setup
    n_int = model.ndof - len(kept)
    red = reduction.craig_bampton(model, kept, n_modes=n_int)
    X = np.array([[3e-6 * np.exp(0.4j), 2e-6 * np.exp(-1.0j)]] * len(F))
    R = [np.array([1e-14, 2e-14])] * len(F)
    z_full = paper.kf_bearing_phasors(model, theory_fn(w), P6, w, X, F, FS, R=R)
    z_red = paper.kf_bearing_phasors(model, theory_fn(w), P6, w, X, F, FS, R=R, kf_rotor=red)
    assert np.abs(z_red - z_full).max() <= 1e-9 * np.abs(z_full).max()
    _, dz_full = paper.kf_phasor_jacobian(model, theory_fn(w), P6, w, X, F, FS, R=R)
    _, dz_red = paper.kf_phasor_jacobian(model, theory_fn(w), P6, w, X, F, FS, R=R, kf_rotor=red)
    assert np.abs(dz_red - dz_full).max() <= 1e-7 * np.abs(dz_full).max()


def test_reduced_jacobian_matches_finite_differences_on_the_reduced_filter(setup):
    rig, model, w, runs, F, kept = setup
    red = reduction.craig_bampton(model, kept, cutoff_hz=FS / 2)
    X = np.array([[3e-6 * np.exp(0.4j), 2e-6 * np.exp(-1.0j)]] * len(F))
    R = 2e-14
    th = theory_fn(w)
    _, dz = paper.kf_phasor_jacobian(model, th, P6, w, X, F, FS, R=R, kf_rotor=red)
    th0 = paper.coeffs_to_theta(th, w, model.bearing_nodes)
    from bearing_id.identify.lsq import coefficient_scales
    sc = coefficient_scales(th, w, model.bearing_nodes)
    for k in (0, 5, 10, 15):
        h = 2e-3 * sc[k]
        co = []
        for sgn in (1, -1):
            t = th0.copy()
            t[k] += sgn * h
            K, C = paper.theta_to_KC(t, w, 2)
            co.append({n: (K[i], C[i]) for i, n in enumerate(model.bearing_nodes)})
        fd = (paper.kf_bearing_phasors(model, co[0], P6, w, X, F, FS, R=R, kf_rotor=red)
              - paper.kf_bearing_phasors(model, co[1], P6, w, X, F, FS, R=R, kf_rotor=red)) / (2 * h)
        assert np.abs(fd - dz[..., k]).max() <= 1e-5 * np.abs(dz[..., k]).max()


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
    y = kalman.particular_state(km.Xp, angle) @ km.H.T            # the model's own response: zero innovations
    out = kalman.fast_filter(km, y, angle)
    assert np.abs(out.innovations).max() <= 1e-9 * np.abs(y).max()
