"""
The simulated rig: exact steady state and transients, noise level, validity flags, file round trip.

References: the FE model's frequency response (rotor.assembly.harmonic_response) for the steady state, an
independent adaptive ODE integration (scipy solve_ivp, rtol 1e-10) of M q'' + C q' + K q = f(t) across a speed
step for the transient, and a plain least-squares sine fit written here.
"""
import math

from bearing_id.conventions import dof_index, rpm_to_rad_s
from bearing_id.excitation import harmonic_forces
from bearing_id.io import recordings
from bearing_id.io.recordings import save_npz
from bearing_id.rotor.assembly import harmonic_response
from bearing_id.rotor.supports import bearing_fn
from bearing_id.simulation import rig as rigmod
import numpy as np
import pytest
from scipy.integrate import solve_ivp


def lsq_phasor(y, phi):
    """Least-squares 1X phasor of y = a + Re{X e^{j phi}} (independent of bearing_id.signals.harmonics)."""
    A = np.column_stack([np.ones_like(phi), np.cos(phi), -np.sin(phi)])
    c, *_ = np.linalg.lstsq(A, y, rcond=None)
    return c[1] + 1j * c[2]


def test_steady_state_matches_frequency_response(rig, model):
    run = rig.simulation.runs[1]
    rec = rigmod.simulate_run(rig, run, speeds_rpm=[1500.0], dwell=0.25, noise=0.0)
    W = rpm_to_rad_s(1500.0)
    coeffs = rigmod.truth_bearing_fn(rig)(W)
    F = harmonic_forces(run.excitation, W, model.n_nodes)[1.0]
    q = harmonic_response(model, W, W, F, coeffs)
    for j, p in enumerate(rec.probes):
        X = lsq_phasor(rec.samples[:, j], rec.angle)
        ref = q[dof_index(p.node, p.direction, model.n_nodes)]
        # the run starts in its steady state, so the samples are the particular solution Z^-1 F (condition of Z 1.8e5
        # at 1500 rpm) evaluated at every sample and fitted by least squares: rounding ~ 1.8e5 x eps ~ 4e-11 of |ref|
        assert abs(X - ref) <= 1e-9 * abs(ref), (p.name, X, ref)


def test_transient_after_speed_step_matches_ode_integration(rig, model):
    run = rig.simulation.runs[0]
    speeds = [1200.0, 1800.0]
    dwell = 0.05
    rec = rigmod.simulate_run(rig, run, speeds_rpm=speeds, dwell=dwell, ramp=0.0, noise=0.0)
    # independent route: start from the steady state of segment 1 at t = dwell, integrate segment 2 by solve_ivp
    W1, W2 = (rpm_to_rad_s(s) for s in speeds)
    bf = rigmod.truth_bearing_fn(rig)
    n1 = rec.segments[0][1]
    phi1 = rec.angle[n1 - 1] + W1 / rec.sample_rate  # angle at the step
    F1 = harmonic_forces(run.excitation, W1, model.n_nodes)[1.0]
    M1, C1, K1 = rigmod.system_matrices(model, W1, bf(W1))
    q1 = np.linalg.solve(K1 - W1**2 * M1 + 1j * W1 * C1, F1)
    x0 = np.concatenate([np.real(q1 * np.exp(1j * phi1)), np.real(1j * W1 * q1 * np.exp(1j * phi1))])
    M2, C2, K2 = rigmod.system_matrices(model, W2, bf(W2))
    F2 = harmonic_forces(run.excitation, W2, model.n_nodes)[1.0]
    Minv = np.linalg.inv(M2)
    n = M2.shape[0]

    def rhs(t, x):
        f = np.real(F2 * np.exp(1j * (phi1 + W2 * t)))
        return np.concatenate([x[n:], Minv @ (f - C2 @ x[n:] - K2 @ x[:n])])

    tt = np.arange(rec.segments[1][1] - n1) / rec.sample_rate
    sol = solve_ivp(rhs, (0, tt[-1]), x0, t_eval=tt, rtol=1e-10, atol=1e-16, method='DOP853')
    sel = [dof_index(p.node, p.direction, model.n_nodes) for p in rec.probes]
    ref = sol.y[sel].T
    got = rec.samples[n1:]
    scale = np.max(np.abs(ref))
    # DOP853 keeps each step's error below rtol 1e-10 of the state; over the ~2,000 steps of this window the global
    # error stays below ~1e-7 of the response (its error estimate is not a bound: 1e-6 leaves a factor 10)
    assert np.max(np.abs(got - ref)) <= 1e-6 * scale
    # and the step really produced a transient (the test would be void if segment 2 were pure steady state)
    q2 = np.linalg.solve(K2 - W2**2 * M2 + 1j * W2 * C2, F2)
    steady = np.real(np.outer(np.exp(1j * (phi1 + W2 * tt)), q2[sel]))
    assert np.max(np.abs(got[:50] - steady[:50])) > 1e-3 * scale


def test_ramp_schedule_is_continuous_and_monotonic(rig):
    rec = rigmod.simulate_run(rig, rig.simulation.runs[0], speeds_rpm=[600.0, 1200.0], dwell=0.1, ramp=0.3)
    rpm = rec.speed * 60 / (2 * math.pi)
    assert rpm[0] == pytest.approx(600.0) and rpm[-1] == pytest.approx(1200.0)
    assert np.all(np.diff(rpm) >= 0) and len(rec.t) == int(round(0.5 * rec.sample_rate))
    # the keyphasor angle advances by speed * dt at every sample (no jump at segment joins); the difference of two
    # accumulated angles carries the rounding of each, at most 2 ulp of the largest angle
    bound = 2 * np.spacing(np.max(np.abs(rec.angle)))
    assert np.max(np.abs(np.diff(rec.angle) - rec.speed[:-1] / rec.sample_rate)) <= bound


def test_noise_level_is_the_stated_fraction_of_rms(rig):
    run = rig.simulation.runs[0]
    clean = rigmod.simulate_run(rig, run, speeds_rpm=[2400.0], dwell=0.5, noise=0.0)
    noisy = rigmod.simulate_run(rig, run, speeds_rpm=[2400.0], dwell=0.5, noise=0.01, seed=7)
    rms = np.sqrt(np.mean(clean.samples**2, axis=0))
    std = np.std(noisy.samples - clean.samples, axis=0)
    # a sample std over N draws is off by 1/sqrt(2 N) relative (1-sigma): 5 of those
    n = noisy.samples.shape[0]
    assert np.allclose(std / rms, 0.01, rtol=5 / math.sqrt(2 * n))


def test_default_scenario_is_physically_consistent_and_paper_scenario_is_flagged(rig, model):
    speeds = [rpm_to_rad_s(s) for s in rig.simulation.speeds_rpm]
    assert rigmod.check_validity(rig, rig.simulation.runs, speeds, model=model) == []
    issues = rigmod.check_validity(rig, rigmod.scenario('paper_table3'), speeds, model=model)
    assert any(i.kind == 'orbit' for i in issues)
    flagged = sorted({i.speed for i in issues})
    assert rpm_to_rad_s(1800.0) in flagged
    issues = rigmod.check_validity(rig, rig.simulation.runs, speeds, model=model, threshold=speeds[3])
    assert {i.speed for i in issues if i.kind == 'stability'} == set(speeds[3:])


def test_npz_round_trip(rig, tmp_path):
    rec = rigmod.simulate_run(rig, rig.simulation.runs[1], speeds_rpm=[900.0, 1200.0], dwell=0.05)
    back = recordings.load_npz(save_npz(rec, tmp_path / 'r.npz'))
    assert np.array_equal(back.samples, rec.samples) and np.array_equal(back.angle, rec.angle)
    assert back.probes == rec.probes and back.run == rec.run and back.segments == rec.segments
    for s, c in rec.truth['coefficients'].items():
        for node, (K, C) in c.items():
            assert np.array_equal(back.truth['coefficients'][s][node][0], K)
    (tmp_path / 'bad.npz').write_bytes(b'PK\x03\x04 truncated')
    with pytest.raises(ValueError, match='bad.npz'):
        recordings.load_npz(tmp_path / 'bad.npz')


def test_truth_differs_from_theory_by_about_a_quarter(rig):
    W = rpm_to_rad_s(1800.0)
    t, n = rigmod.truth_bearing_fn(rig)(W), bearing_fn(rig)(W)
    for node in t:
        rel = np.linalg.norm(t[node][0] - n[node][0]) / np.linalg.norm(n[node][0])
        assert 0.1 < rel < 1.0
    assert math.isfinite(rel)


def test_transient_modes_are_left_out_only_below_the_stated_floor():
    # definition: a mode is evaluated until amplitude exp(Re(lam) t) falls to floor / n_modes, so at any time the
    # modes left out sum to less than the floor; a mode that does not decay is never left out
    rng = np.random.default_rng(5)
    lam = np.concatenate([-rng.uniform(0.1, 1e4, 40) + 1j * rng.uniform(0, 1e4, 40), [0.0 + 5j, 0.3 - 2j]])
    amp = 10.0 ** rng.uniform(-15, -3, lam.size)
    floor = 1e-12
    ends = rigmod.transient_ends(lam, amp, floor)
    assert np.all(np.isinf(ends[-2:]))
    for t in np.concatenate([[0.0], np.sort(ends[np.isfinite(ends)]), np.linspace(0, 0.1, 50)]):
        left_out = ends <= t
        assert np.sum(amp[left_out] * np.exp(np.real(lam[left_out]) * t)) <= floor * (1 + 1e-9)
    # and no mode is dropped while it is above that share
    live = np.isfinite(ends) & (ends > 0)
    at_end = amp[live] * np.exp(np.real(lam[live]) * ends[live])
    assert np.allclose(at_end, floor / lam.size, rtol=1e-9)
