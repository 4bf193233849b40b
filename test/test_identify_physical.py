"""
``physical`` identification: viscosity and clearance per bearing, all speeds at once, from node 6 only.

References (independent of the fit):
* the data come from the FE frequency response with the rig's truth bearings (the bearing model at viscosity x1.25
  and clearance x0.8 of nominal, params/rig.yaml); the fit starts from nominal, 25 % away;
* noise: 1 % of the channel RMS on 2 s x 10240 Hz, 75 % of each dwell used, gives a 1X error of std
  noise x |X| / sqrt(N_used) on Re and Im (least squares of a sinusoid in white noise);
* the load degeneracy is a scaling argument, not code output: a Reynolds bearing of fixed geometry has K = (W/c) k(eps),
  C = W / (c Omega) c(eps) with eps a function of mu Omega / (W c^2) only, so (mu, c, W) enter through two
  combinations: fitting all three per bearing gives rank 2 per bearing;
* the reported parameter std is checked against the scatter over independent noise draws.

Tolerances: the issue's benchmark targets for ``physical`` from one location, <= 2 % (K) and <= 3 % (C) eq. 38 error;
viscosity and clearance within 3 % (the "few %" of the issue).
"""
import math

from bearing_id.config.params import Probe
from bearing_id.identify import eq38_error, harmonics
from bearing_id.identify.physical import fit_physical, identify_physical
from bearing_id.simulation import rig as rigmod
from bearing_id.simulation.rig import simulate_data
import numpy as np
import pytest
from scipy.stats import chi2

NOISE = 0.01
N_USED = int(0.75 * 2.0 * 10240)
P6 = (Probe('p6x', 6, 'x'), Probe('p6y', 6, 'y'))
SPEEDS = (600, 1200, 1800, 2400, 3000)


@pytest.fixture(scope='module')
def clean(rig, model):
    return simulate_data(rig, rig.simulation.runs, SPEEDS, probes=P6, model=model)


def noisy(data, seed):
    rng = np.random.default_rng(seed)
    std = NOISE * np.abs(data.X) / math.sqrt(N_USED)
    X = data.X + std * (rng.standard_normal(data.X.shape) + 1j * rng.standard_normal(data.X.shape))
    return type(data)(data.speeds, data.probes, data.runs, X, std, [], [], data.truth)


def true_params(rig):
    t = rig.simulation.truth
    return {f'{b.name}.viscosity': b.viscosity * t.viscosity_factor[i] for i, b in enumerate(rig.bearings)} | \
        {f'{b.name}.clearance': b.clearance * t.clearance_factor[i] for i, b in enumerate(rig.bearings)}


def test_zero_noise_recovers_parameters_to_1e6(rig, model, clean):
    """Algebra check: truth = the estimator's model; noise-free phasors -> parameters to 1e-6 relative."""
    data = type(clean)(clean.speeds, clean.probes, clean.runs, clean.X, np.zeros(clean.X.shape), [], [], clean.truth)
    fit, res = fit_physical(model, rig, data)
    truth = true_params(rig)
    # the fit stops on ftol = 1e-12 (relative change of the cost): at a quadratic minimum that leaves the parameters
    # within sqrt(1e-12) = 1e-6 relative
    for name, v in zip(fit.names, fit.values):
        assert v == pytest.approx(truth[name], rel=1e-6), name
    assert fit.rank == 4 and fit.unknowns == 4


def test_node6_unbalance_one_percent_noise(rig, model, clean):
    data = noisy(clean, seed=21)
    fit, res = fit_physical(model, rig, data)
    truth = true_params(rig)
    assert fit.rank == 4 and np.all(fit.determined)
    for name, v, s in zip(fit.names, fit.values, fit.rel_std):
        assert abs(v / truth[name] - 1) <= 0.03, (name, v, truth[name])
        assert 0 < s < 0.03
    err = eq38_error(res, [data.truth[float(w)] for w in data.speeds])
    assert err['K'] <= 2.0 and err['C'] <= 3.0, err
    for r in res:
        assert r.fully_determined and r.unknowns == 4 and r.method == 'physical'
        assert np.all(np.isfinite(r.K_std)) and np.all(r.K_std > 0)


def test_parameter_std_matches_scatter_over_noise_draws(rig, model, clean):
    draws = [fit_physical(model, rig, noisy(clean, seed=100 + k))[0] for k in range(12)]
    logs = np.log([d.values for d in draws])
    scatter = logs.std(axis=0, ddof=1)
    reported = np.mean([d.rel_std for d in draws], axis=0)
    # 12 draws: the sample std is within a factor ~1.6 of the truth with high probability
    assert np.all(scatter < 2.0 * reported) and np.all(scatter > 0.4 * reported), (scatter, reported)


def test_fitting_the_load_too_is_rank_deficient_but_coefficients_stay_determined(rig, model, clean):
    data = noisy(clean, seed=4)
    fit, res = fit_physical(model, rig, data, load=True)
    assert (fit.rank, fit.unknowns) == (4, 6)
    assert not np.any(fit.determined) and np.all(np.isnan(fit.rel_std))
    err = eq38_error(res, [data.truth[float(w)] for w in data.speeds])
    assert err['K'] <= 2.0 and err['C'] <= 3.0, err
    assert all(r.fully_determined for r in res)


def test_dispatcher_signature_and_options(rig, model, clean):
    res = identify_physical(model, rig, noisy(clean, seed=2), options={'params': ('viscosity', 'clearance')})
    assert len(res) == len(SPEEDS) and 'fit' in res[0].extra
    with pytest.raises(ValueError, match='unknown option'):
        identify_physical(model, rig, clean, options={'viscosity_only': True})


@pytest.mark.parametrize('truth_model,misfit', [('finite', True), ('short', False)])
def test_model_form_misfit_is_declared_only_when_the_bearing_model_is_wrong(rig, model, truth_model, misfit):
    """
    Truth = finite-length Reynolds bearing, estimator = short bearing: chi2/dof >> 1 must be declared.

    The bias is then ~7 %, far beyond the noise-based 1-sigma; with a short-bearing truth it must not be declared.
    """
    truth = rigmod.with_truth(rig, bearing_model=truth_model)
    recs = [rigmod.simulate_run(truth, r, speeds_rpm=(900.0, 1800.0, 2700.0), dwell=1.0, ramp=0.0, model=model)
            for r in rig.simulation.runs]
    data = harmonics.from_recordings(recs)
    fit, res = fit_physical(model, rig, data)
    # misfit threshold: the 99.9 % point of chi-square(dof) / dof (issue 11; was a fixed 3)
    assert (fit.chi2 / fit.dof > chi2.ppf(0.999, fit.dof) / fit.dof) == misfit, fit.chi2 / fit.dof
    assert any('MODEL MISFIT' in n for n in res[0].notes) == misfit
    assert res[0].extra['misfit'] == misfit and res[0].misfit == misfit


def test_warm_start_gives_the_cold_answer_within_a_hundredth_of_its_sigma(rig, model, clean):
    """
    A warm start (p0 = the fit on fewer speeds, as the identifier node does) lands on the cold fit's solution.

    Both starts minimise the same chi2 on this well-conditioned problem; two routes to one quantity agree within 0.01
    of its stated 1-sigma (issue 21): parameters within 0.01 x their 1-sigma (value x rel_std), the coefficients
    within 0.01 x K_std / C_std, the stated 1-sigma themselves within 1 %, and the chi-square within 0.01 (at the
    minimum, 0.01 sigma in each of the 4 parameters raises it by at most (4 x 0.01)^2 = 0.0016).
    """
    data = noisy(clean, seed=8)
    cold, res_c = fit_physical(model, rig, data)
    fewer, _ = fit_physical(model, rig, data.select(range(len(SPEEDS) - 1)))
    for start in (fewer.values, cold.values * 1.02, cold.nominal):
        warm, res_w = fit_physical(model, rig, data, p0=start)
        assert np.all(np.abs(warm.values - cold.values) <= 0.01 * cold.std)
        np.testing.assert_allclose(warm.rel_std, cold.rel_std, rtol=0.01, atol=0)
        assert abs(warm.chi2 - cold.chi2) <= 0.01
        for a, b in zip(res_w, res_c):
            for sym in ('K', 'C'):
                assert np.all(np.abs(getattr(a, sym) - getattr(b, sym)) <= 0.01 * getattr(b, sym + '_std'))
                np.testing.assert_allclose(getattr(a, sym + '_std'), getattr(b, sym + '_std'), rtol=0.01, atol=0)
    with pytest.raises(ValueError, match='p0'):
        fit_physical(model, rig, data, p0=cold.values[:2])


def _drifting_oil(rig, model, factors):
    """Phasors of each run and speed from the truth whose viscosity is ``factors[r, s]`` times the rig's truth."""
    runs = rig.simulation.runs
    X = np.zeros((len(runs), len(SPEEDS), len(P6)), dtype=complex)
    for r, run in enumerate(runs):
        for s, rpm in enumerate(SPEEDS):
            one = simulate_data(rig, (run,), (rpm,), probes=P6, model=model,
                                bearing_fn=rigmod.changed_truth(rig, viscosity=float(factors[r, s])))
            X[r, s] = one.X[0, 0]
    base = simulate_data(rig, runs, SPEEDS, probes=P6, model=model)
    return type(base)(base.speeds, base.probes, base.runs, X, np.zeros(X.shape), [], [], base.truth)


def test_known_viscosity_factors_per_run_and_speed_recover_the_reference_viscosity(rig, model):
    # the oil warms while the plan runs: each run's vector at each speed saw its own viscosity (here -2 % to +2 %,
    # about 0.5 K of an ISO VG 46).  Told those factors, the fit's viscosity is the one at factor 1 (the rig's truth)
    # and the data fit within their noise; with one viscosity for all, the same data are a misfit
    factors = np.array([np.linspace(0.98, 1.0, len(SPEEDS)), np.linspace(1.0, 1.02, len(SPEEDS))])
    data = noisy(_drifting_oil(rig, model, factors), seed=4)
    truth = true_params(rig)
    fit, res = fit_physical(model, rig, data, viscosity_factors=factors)
    assert not fit.misfit and np.all(fit.determined), fit.quality.summary()
    for name, v, s in zip(fit.names, fit.values, fit.rel_std):
        assert abs(v / truth[name] - 1) <= 4 * s, (name, v, truth[name], s)
    assert any('known factor' in n for n in res[0].notes)
    # each speed's coefficients are the bearings' at the mean factor of its runs (the oil its data saw)
    for k, r in enumerate(res):
        co = rigmod.changed_truth(rig, viscosity=float(np.mean(factors[:, k])))(float(data.speeds[k]))
        for b, node in enumerate(r.nodes):
            assert np.all(np.abs(r.K[b] - co[node][0]) <= 4 * r.K_std[b] + 1e-12 * np.abs(co[node][0]))
    plain, _ = fit_physical(model, rig, data)
    assert plain.misfit, plain.quality.summary()


def test_viscosity_factors_of_the_wrong_shape_are_refused(rig, model, clean):
    with pytest.raises(ValueError, match='viscosity_factors'):
        fit_physical(model, rig, clean, viscosity_factors=np.ones(len(SPEEDS) + 1))
    with pytest.raises(ValueError, match='viscosity_factors'):
        fit_physical(model, rig, clean, viscosity_factors=-np.ones(len(SPEEDS)))
