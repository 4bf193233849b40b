"""
The diagnosis' fast paths of issue 13 against their references.

* ``Problem.systems`` assembles the dynamic stiffness of many (window, ratio) pairs at once; every entry must equal
  ``Problem.system`` (the one-pair reference) bit for bit: the same elementwise operations in the same order, and the
  diagnosis' fits take finite-difference Jacobians, which turn any change of the residual's last bits into a change
  of the fitted parameters far above 1e-9.  Checked for every candidate effect (bearing hooks, pedestal effects, disc
  terms, bearing factors and forms), alone and three at once, on the default rig and on a rig whose bearing sits on
  a pedestal (film between shaft and pedestal DOFs); ``Problem.predict`` (built on it) against
  ``Problem.predict_reference`` to 1e-9 relative there as well.
* The hypothesis fits run scipy's trf step for step with numpy's SVD (``select.LSQ_SVD = 'numpy'``, no scipy import)
  instead of scipy.linalg's (the reference, 'scipy'): the same parameters, chi2 and 1-sigma to 1e-9 relative; the SVD
  factors come back in scipy's memory layout; a fit imports neither scipy.linalg nor scipy.optimize.
* ``locate.observe`` fits each window's nX vectors once, with the lines found in it: equal to a direct
  ``signals.harmonic_vectors`` of the window with those lines.

Problems: synthetic windows (measured vectors = the nominal model's prediction at bearing factors off nominal, times
a smooth deterministic perturbation) at five speeds and two excitation runs, so nothing is simulated.
"""
from __future__ import annotations

import sys
import types

from bearing_id.config.params import PACKAGE_PARAMS
from bearing_id.conventions import rpm_to_rad_s
import numpy as np
import pytest
from test_diagnose_trf import check_same_fit

SPEEDS_RPM = (300.0, 900.0, 1500.0, 2100.0, 2700.0)


def _rel(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)) if b.size else 0.0


def _select():
    import bearing_id.diagnose.select  # noqa: F401  (the module; bearing_id.diagnose.select is also a function)
    return sys.modules['bearing_id.diagnose.select']


def _problem(params=None, runs=2):
    """Problem on synthetic windows: the nominal prediction at nuisance ``theta_true``, perturbed by a few %."""
    from bearing_id.diagnose.locate import Observations, Window
    from bearing_id.diagnose.predict import Problem
    from bearing_id.config.params import load_rig
    rig = load_rig(params)
    recs = [types.SimpleNamespace(run=rig.simulation.runs[r % len(rig.simulation.runs)], probes=tuple(rig.probes))
            for r in range(runs)]
    nch = len(rig.probes)
    wins = [Window(rec=r, i0=0, i1=0, speed=float(rpm_to_rad_s(s)) * (1.0 + 1e-4 * r),
                   X=np.ones((3, nch), complex), std=np.ones((3, nch)))
            for r in range(runs) for s in SPEEDS_RPM]
    obs = Observations(recordings=recs, windows=wins, orders=(1, 2, 3))
    prob = Problem(obs, rig)
    theta_true = np.linspace(0.15, -0.2, prob.n_nuis)
    y0 = prob.predict(theta_true, [], [])[0]
    i = np.arange(y0.size)
    y = y0 * (1.0 + 0.03 * np.sin(0.7 * i) + 0.02j * np.cos(1.3 * i)) + 1e-8 * np.exp(0.3j * i)
    for k, w in enumerate(wins):
        sl = prob.slices[k]
        w.X = y[sl].reshape(w.X.shape)
        w.std = 0.01 * np.abs(w.X) + 1e-8
    return Problem(obs, rig, model=prob.model)


@pytest.fixture(scope='module')
def problems():
    plant = PACKAGE_PARAMS / 'examples' / 'plant_like.yaml'
    return {'default rig': _problem(), 'bearing on a pedestal': _problem(str(plant), runs=2)}


def _nl_of(e, rng):
    lo, hi = np.asarray(e.nl_lo, float), np.asarray(e.nl_hi, float)
    return lo + (hi - lo) * rng.uniform(0.2, 0.8, lo.size) if lo.size else np.zeros(0)


def _combos(prob):
    from bearing_id.diagnose.effects import candidates
    cands = candidates(prob)
    names = {e.name for e in cands}
    assert {'support_flexibility', 'disc_mass_error', 'bearing_model_form', 'probe_runout'} <= names
    return [[]] + [[e] for e in cands] + [cands[i:i + 3] for i in range(0, len(cands) - 2, 3)]


@pytest.mark.parametrize('name', ['default rig', 'bearing on a pedestal'])
def test_stacked_systems_equal_the_one_pair_reference_bit_for_bit(problems, name):
    prob = problems[name]
    if name == 'bearing on a pedestal':
        assert prob.model.pedestals, 'the rig must hold a bearing on a pedestal'
    rng = np.random.default_rng(5)
    theta = 0.25 * rng.standard_normal(prob.n_nuis)
    keys = [(k, r) for k in range(len(prob.windows)) for r in prob.orders]
    for effects in _combos(prob):
        nls = [_nl_of(e, rng) for e in effects]
        got = prob.systems(keys, theta, effects, nls)
        assert got.shape[0] == len(keys)
        for (k, r), Z in zip(keys, got):
            np.testing.assert_array_equal(Z, prob.system(k, r, theta, effects, nls), err_msg=str(effects))
        sub = keys[1::3]            # any subset, in any order
        got = prob.systems(sub[::-1], theta, effects, nls)
        for (k, r), Z in zip(sub[::-1], got):
            np.testing.assert_array_equal(Z, prob.system(k, r, theta, effects, nls))


def test_prediction_on_a_pedestal_rig_equals_the_reference(problems):
    prob = problems['bearing on a pedestal']
    rng = np.random.default_rng(6)
    theta = 0.25 * rng.standard_normal(prob.n_nuis)
    held = list(range(0, len(prob.windows), 2))
    for effects in _combos(prob):
        nls = [_nl_of(e, rng) for e in effects]
        for windows in (None, held):
            got = prob.predict(theta, effects, nls, windows)
            want = prob.predict_reference(theta, effects, nls, windows)
            for g, w in zip(got[:2], want[:2]):
                assert g.shape == w.shape and _rel(g, w) <= 1e-9, [e.label for e in effects]
            np.testing.assert_array_equal(got[2], want[2])


def test_svd_factors_match_scipys_in_value_and_layout():
    from scipy.linalg import svd
    rng = np.random.default_rng(1)
    for m, n in ((224, 4), (60, 7), (12, 12)):
        a = rng.standard_normal((m + n, n)) * np.exp(2.0 * rng.standard_normal(n))
        got, want = _select()._svd(a), svd(a, full_matrices=False)
        for g, w in zip(got, want):
            assert g.shape == w.shape and _rel(np.abs(g), np.abs(w)) <= 1e-9
            assert g.flags.f_contiguous == w.flags.f_contiguous
        U, s, Vh = got
        assert _rel((U * s) @ Vh, a) <= 1e-12


def test_fits_with_numpys_svd_equal_the_scipy_svd_reference(problems):
    from bearing_id.diagnose.effects import candidates
    select = _select()
    prob = problems['default rig']
    support = next(c for c in candidates(prob) if c.name == 'support_flexibility')
    unbalance = next(c for c in candidates(prob) if c.name == 'residual_unbalance')
    held = list(range(0, len(prob.windows), 2))
    old = select.LSQ_SVD
    try:
        for effects in ([], [unbalance], [support]):
            for windows in (None, held):
                out = {}
                for m in ('scipy', 'numpy'):
                    select.LSQ_SVD = m
                    out[m] = select.fit(prob, effects, windows=windows)
                check_same_fit(out['numpy'], out['scipy'])
                assert abs(out['numpy'].theta).max() > 0.05      # the nuisance moved: steps were taken
    finally:
        select.LSQ_SVD = old


def test_a_fit_imports_neither_scipy_linalg_nor_scipy_optimize(problems, monkeypatch):
    from bearing_id.diagnose.effects import candidates
    select = _select()
    prob = problems['default rig']
    support = next(c for c in candidates(prob) if c.name == 'support_flexibility')
    want = select.fit(prob, [support], windows=list(range(0, len(prob.windows), 2)))
    for name in ('scipy.linalg', 'scipy.optimize'):      # an import of either now fails
        monkeypatch.setitem(sys.modules, name, types.ModuleType(name))
    monkeypatch.setattr(select, 'LSQ_SVD', 'numpy')
    got = select.fit(prob, [support], windows=list(range(0, len(prob.windows), 2)))
    check_same_fit(got, want)


def test_observe_fits_each_window_once_with_its_lines(monkeypatch):
    from bearing_id.simulation import rig as rigmod
    from bearing_id.signals import harmonics as signals
    from bearing_id.simulation import effects as te
    import bearing_id.diagnose.locate  # noqa: F401  (the module; bearing_id.diagnose.locate is also a function)
    from bearing_id.config.params import load_rig
    locate = sys.modules['bearing_id.diagnose.locate']
    truth = rigmod.with_truth(load_rig(), viscosity_factor=(1.0, 1.0), clearance_factor=(1.0, 1.0))
    sched = [rigmod.Segment(float(rpm_to_rad_s(200)), 1.0)] + rigmod.step_schedule((900, 2200, 2800), 1.0)
    rec = rigmod.simulate(truth, truth.simulation.runs[0], sched, effects=[te.OilWhirl(10, 2000.0, 0.45, 0.5)])
    calls = []
    real = signals.harmonic_vectors

    class Counted:              # locate's view of bearing_id.signals.harmonics, its harmonic fits counted
        def __getattr__(self, name):
            return getattr(signals, name)

        @staticmethod
        def harmonic_vectors(x, ang, orders=(1,), **kw):
            calls.append(kw.get('whole_revs', True))
            return real(x, ang, orders, **kw)
    monkeypatch.setattr(locate, 'signals', Counted())
    obs = locate.observe([rec])
    monkeypatch.undo()
    assert obs.whirl_windows(), 'the recording holds a whirl'
    # one whole-revolution nX fit per window (the whirl test fits half windows), and one per sub-synchronous vector
    # taken at a whirl ratio assigned from other windows (Observations.sub_vector, cached)
    assert sum(calls) == len(obs.windows) + len(obs.sub_cache)
    for w in obs.windows:
        subs = [r for r in (w.own_ratio, w.transient_ratio) if r is not None]
        fit = real(np.asarray(rec.samples[w.i0:w.i1], float), np.asarray(rec.angle[w.i0:w.i1], float), obs.orders,
                   subsync=subs or None, nonfinite='drop')
        np.testing.assert_array_equal(w.X, fit.X)
        np.testing.assert_array_equal(w.std, fit.std)
