"""Live model health from Kalman innovations (kf_estimator's /diagnostics item), against closed forms and the rig."""
from bearing_id.config.params import load_rig
from bearing_id.conventions import rpm_to_rad_s
from bearing_id.estimation.kalman import rotor_kalman_model, StreamingKF
from bearing_id.excitation import harmonic_forces
from bearing_id.nodes.kf_estimator_core import HEALTH_COHERENT, innovation_health, innovation_health_terms
from bearing_id.rotor.assembly import RotorModel
from bearing_id.rotor.supports import bearing_fn
from bearing_id.simulation import rig as rigmod
import numpy as np
import pytest


def blocks(nu, angle, n=1024):
    return [innovation_health_terms(nu[i:i + n], angle[i:i + n]) for i in range(0, len(angle), n)]


def test_shares_match_closed_form():
    rng = np.random.default_rng(3)
    N, sigma, A = 40960, 1.0, 0.8
    angle = 2 * np.pi * 37.3 * np.arange(N) / 10240.0
    white = rng.standard_normal((N, 2)) * sigma
    h = innovation_health(blocks(white, angle))
    assert h['fraction'][1] < 10 / N and h['fraction'][2] < 10 / N and abs(h['lag1']) < 0.05
    nu = white + A * np.cos(angle + 0.3)[:, None]
    h = innovation_health(blocks(nu, angle))
    # power share of a sinusoid of amplitude A in white noise of variance sigma^2; the noise power estimated from N
    # samples per channel is off by sqrt(2 / N) relative (0.5 % here) and its cross term with the sinusoid by about
    # as much: 5 % is ~7 of those
    assert h['fraction'][1] == pytest.approx(A**2 / 2 / (A**2 / 2 + sigma**2), rel=0.05)
    assert h['fraction'][2] < 10 / N


@pytest.fixture(scope='module')
def setting():
    rig = load_rig()
    model = RotorModel.from_params(rig)
    run = rig.simulation.runs[0]
    rec = rigmod.simulate_run(rig, run, speeds_rpm=[1500.0], dwell=1.0, noise=0.01, model=model)
    return rig, model, run, rec


@pytest.mark.parametrize('truth_model,flagged', [(True, False), (False, True)])
def test_health_flags_a_wrong_model_only(setting, truth_model, flagged):
    rig, model, run, rec = setting
    W = rpm_to_rad_s(1500.0)
    bfn = rigmod.truth_bearing_fn(rig) if truth_model else bearing_fn(rig)
    R = float(np.mean((0.01 * np.sqrt(np.mean(rec.samples**2, axis=0))) ** 2))
    km = rotor_kalman_model(model, W, bfn(W), rec.probes, rec.sample_rate,
                            forces=harmonic_forces(run.excitation, W, model.n_nodes), Q=1e-16, R=R)
    kf = StreamingKF(km)
    terms = []
    for i in range(0, rec.samples.shape[0], 1024):
        _, nu, _ = kf.step_block(rec.samples[i:i + 1024], rec.angle[i:i + 1024], W)
        terms.append(innovation_health_terms(nu, rec.angle[i:i + 1024]))
    h = innovation_health(terms)
    assert (h['fraction'][1] > HEALTH_COHERENT) == flagged, h
