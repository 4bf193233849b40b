"""
Issue 11, identification side.

One rule for "determined", a misfit test tied to the degrees of freedom, fitted physical parameters in the result, the
paper method's static offset, and no import circle in identify/.

Independent references only (never numbers copied from the code's output):
* the chi-square quantile against scipy.stats (imported here, in the test, not by the package);
* Monte-Carlo truth: linear-Gaussian problems drawn with numpy whose estimator distribution is known in closed form,
  and simulated rigs whose true coefficients/parameters are known (rig.simulate_run / rig.simulate_data);
* the Kalman filter's NIS against its chi-square band (kalman.nis_band, scipy.stats);
* the import graph read from the source files with ast, and fresh interpreters.
"""
from __future__ import annotations

import ast
import dataclasses
import json
import math
from pathlib import Path
import subprocess
import sys

from agreement import assert_results_agree
from bearing_id.config.params import Probe
from bearing_id.estimation.kalman import nis_band
from bearing_id.identify import determined as dt
from bearing_id.identify.direct import coeffs_to_beta, identify_direct
from bearing_id.identify.harmonics import from_recordings
from bearing_id.identify.paper import identify_paper
from bearing_id.identify.physical import fit_physical, identify_physical
from bearing_id.rotor import supports
from bearing_id.simulation import rig as rigmod
from bearing_id.simulation.rig import simulate_data
import numpy as np
import pytest
from scipy import stats

ROOT = Path(__file__).resolve().parent.parent
IDENT = ROOT / 'bearing_id' / 'identify'
P369 = tuple(Probe(f'p{n}{d}', n, d) for n in (3, 6, 9) for d in ('x', 'y'))
P6 = (Probe('p6x', 6, 'x'), Probe('p6y', 6, 'y'))
VF, CF = (1.3, 1.3), (0.7, 0.85)          # truth ~30 % off nominal, unequal clearances (the look-alike)


def test_threshold_at_68_dof_is_about_1_6_not_3():
    # the threshold applies to chi2 / dof, whose own 1-sigma is sqrt(2 / dof): it must sit within 0.01 of that of
    # the 99.9 % point of scipy.stats.chi2
    thr = dt.misfit_threshold(68)
    assert abs(thr - stats.chi2.ppf(0.999, 68) / 68) <= 0.01 * math.sqrt(2 / 68) and 1.5 < thr < 1.7
    assert dt.fit_quality(2.56 * 68, 68).misfit and not dt.fit_quality(1.3 * 68, 68).misfit


def test_misfit_false_alarm_rate_is_the_level():
    """Correct model and sigma: chi2 ~ chi-square(dof); 1e5 draws flag 0.1 % of fits (binomial 5-sigma band)."""
    rng = np.random.default_rng(1)
    n, dof = 100_000, 20
    chi2 = rng.chisquare(dof, n)
    flagged = np.mean([dt.fit_quality(c, dof).misfit for c in chi2[:20000]])
    p = 1 - dt.MISFIT_LEVEL
    assert abs(flagged - p) <= 5 * math.sqrt(p * (1 - p) / 20000)
    q = dt.fit_quality(3.0 * dof, dof)
    assert q.misfit and q.birge == pytest.approx(math.sqrt(3.0)) and 'LOWER BOUND' in q.misfit_note()
    assert not dt.fit_quality(5.0, 0).testable and not dt.fit_quality(5.0, 0).misfit


# ------------------------------------------------------------------------------------------------ the rule
def test_rule_closed_form_cases():
    # the example: Kyx = 1.0e4 +- 9.0e4 N/m passed "1-sigma <= 10 % of the block scale"; it is not determined
    v = dt.judge([1.0e4, 3.1e5, 3.1e5, -2.0e5, 5.0], [9.0e4, 1.0e5, 1.0e5, 1.0e4, np.nan],
                 pull=[0.0, 0.0, 0.2, 0.05, 0.0])
    assert v.determined.tolist() == [False, True, False, True, False]
    assert not v.significant[0] and v.significant[1] and not v.data_led[2] and not v.estimable[4]
    assert 'not determined' in v.note(['a', 'b', 'c', 'd', 'e'])
    # prior pull of a scalar Gaussian prior: posterior mean = (1 - s) data + s prior, s = I_p / (I_d + I_p)
    Id, Ip = 9.0, 1.0
    assert dt.prior_pull(1 / (Id + Ip), 1 / Id) == pytest.approx(Ip / (Id + Ip))


def test_rule_on_a_linear_gaussian_problem_monte_carlo():
    """
    Check the rule on Y = A theta + e with known sigma (Monte Carlo).

    OLS coefficients that the rule calls determined lie within 3 sigma of the truth 99.73 % of the time (Gaussian,
    closed form), and a coefficient that is really 0 is called determined in <= 0.27 % of the draws (two-sided 3-sigma).
    """
    rng = np.random.default_rng(7)
    A = rng.standard_normal((40, 6)) @ np.diag([1.0, 1.0, 0.3, 0.1, 0.03, 1.0])
    theta = np.array([2.0, -1.0, 1.5, 3.0, 40.0, 0.0])          # the last one is zero
    cov = np.linalg.inv(A.T @ A)
    sd = np.sqrt(np.diag(cov))
    ins, tot, zero_det = 0, 0, 0
    n = 4000
    for _ in range(n):
        y = A @ theta + rng.standard_normal(40)
        est = cov @ A.T @ y
        v = dt.judge(est, sd)
        d = v.determined
        tot += int(d.sum())
        ins += int(np.sum(np.abs(est - theta)[d] <= 3 * sd[d]))
        zero_det += int(d[5])
    assert tot > 3 * n
    assert ins / tot >= 0.995
    assert zero_det / n <= 0.0027 + 5 * math.sqrt(0.0027 / n)


# ------------------------------------------------------------------------------------------------ look-alike rig
def _lookalike(rig, model, runs, probes, speeds, seed, *, dc=50e-6, dwell=1.0, ramp=None, truth=None):
    """Time-domain recordings: truth ~30 % off nominal with unequal clearances, a static DC per channel."""
    bfn = truth or supports.bearing_fn(rig, viscosity_factor=VF, clearance_factor=CF)
    rng = np.random.default_rng(900 + seed)
    recs = []
    for k, run in enumerate(runs):
        r = rigmod.simulate_run(rig, run, speeds_rpm=speeds, dwell=dwell, ramp=ramp, probes=probes, bearing_fn=bfn,
                                seed=10 * seed + k, model=model)
        if dc:
            r = dataclasses.replace(r, samples=r.samples + rng.uniform(-dc, dc, len(probes))[None, :])
        recs.append(r)
    return recs


def _zscores(results, data):
    z, det = [], 0
    for r in results:
        t = data.truth_at(r.speed)
        for i, n in enumerate(r.nodes):
            for val, std, d, j in ((r.K, r.K_std, r.K_determined, 0), (r.C, r.C_std, r.C_determined, 1)):
                zz = (val[i] - t[n][j]) / std[i]
                z += list(zz[d[i]])
                det += int(d[i].sum())
    return np.array(z), det


@pytest.fixture(scope='module')
def multiprobe(rig, model):
    """
    Simulate the issue's scenario.

    Unbalance A+B, probes 3/6/9 x and y, 6 speeds 600-3528 rpm, 1 s dwells, DC offsets.
    """
    speeds = tuple(np.linspace(600.0, 3528.0, 6))
    return [from_recordings(_lookalike(rig, model, rig.simulation.runs, P369, speeds, seed)) for seed in (0, 1)]


def test_direct_multiprobe_unbalance_determined_coefficients_are_within_3_sigma(rig, model, multiprobe):
    """
    Before issue 11 this plan called 0-5 of 16 determined per speed, 6 of them 51-125 % off (up to 10 sigma).

    Now every determined coefficient is within 3 sigma of the truth, none beyond 5 sigma (Monte-Carlo truth).
    """
    zs, old_bad = [], 0
    for data in multiprobe:
        res = identify_direct(model, rig, data)
        z, _ = _zscores(res, data)
        zs += list(z)
        for r in res:
            assert not r.misfit, r.notes                       # the 1X std is honest: the fit is consistent
            # the pre-issue-11 rule on the same fit: estimable and 1-sigma <= 10 % of the block scale
            sd = np.sqrt(np.clip(np.diag(r.extra['cov_theta']), 0, None))
            old = (r.extra['leakage'] < 1e-6) & (sd < 0.10)
            err = np.abs(r.extra['theta'] * r.extra['scale'] - coeffs_to_beta(data.truth_at(r.speed), r.nodes))
            old_bad += int(np.sum(old & (err > 3 * sd * r.extra['scale'])))
    zs = np.abs(np.array(zs))
    assert old_bad >= 1                    # the old rule passed coefficients more than 3 (linearised) sigma off
    if zs.size:
        assert np.mean(zs <= 3) >= 0.95 and np.max(zs) <= 5.0, zs


def test_direct_force_plan_with_dc_determined_coefficients_are_within_3_sigma(rig, model):
    """
    The same rule where the data do determine: most coefficients determined and within 3 sigma of the truth.

    Directional shaker x, y at both discs, probes 3/6/9, DC offsets, 1 s dwells -- most coefficients determined, >= 95 %
    of them within 3 sigma of the truth, none beyond 5.
    """
    speeds = (600.0, 1771.0, 2942.0)
    zs, det = [], 0
    for seed in (0, 1):
        data = from_recordings(_lookalike(rig, model, rigmod.scenario('force'), P369, speeds, seed))
        res = identify_direct(model, rig, data)
        z, d = _zscores(res, data)
        zs += list(z)
        det += d
    zs = np.abs(np.array(zs))
    assert det >= 0.8 * 2 * 3 * 16
    assert np.mean(zs <= 3) >= 0.95 and np.max(zs) <= 5.0, np.sort(zs)[-5:]


def test_physical_multiprobe_unbalance_all_determined_within_3_sigma(rig, model, multiprobe):
    zs = []
    for data in multiprobe:
        res = identify_physical(model, rig, data)
        z, det = _zscores(res, data)
        assert det == 16 * len(res)
        zs += list(z)
        p = res[0].extra['parameters']
        for i, b in enumerate(rig.bearings):
            for kind, f in (('viscosity', VF[i]), ('clearance', CF[i])):
                e = p[f'{b.name}.{kind}']
                assert abs(e['factor'] - f) <= 4 * e['factor_std'], (b.name, kind, e)
    zs = np.abs(np.array(zs))
    assert np.mean(zs <= 3) >= 0.95 and np.max(zs) <= 5.0


# ------------------------------------------------------------------------------------------------ physical misfit
N_USED = int(0.75 * 2.0 * 10240)


def _noisy(clean, seed, true_factor):
    """1X noise of std true_factor x the stated one (the stated X_std is the rig's 1 % of RMS over N_USED samples)."""
    rng = np.random.default_rng(seed)
    std = 0.01 * np.abs(clean.X) / math.sqrt(N_USED)
    X = clean.X + true_factor * std * (rng.standard_normal(clean.X.shape) + 1j * rng.standard_normal(clean.X.shape))
    return type(clean)(clean.speeds, clean.probes, clean.runs, X, std, [], [], clean.truth)


@pytest.fixture(scope='module')
def node_route_clean(rig, model):
    """Node 6, unbalance A+B, the rig's 9 speeds: 72 real equations, 4 unknowns -> 68 dof (the issue's node route)."""
    bfn = supports.bearing_fn(rig, viscosity_factor=VF, clearance_factor=CF)
    return simulate_data(rig, rig.simulation.runs, rig.simulation.speeds_rpm, probes=P6, bearing_fn=bfn,
                         model=model)


def test_physical_underestimated_noise_is_a_misfit_and_birge_scaled(rig, model, node_route_clean):
    """
    True 1X noise 1.7x the stated one: a misfit, flagged, and the sigma Birge-scaled.

    chi2/dof ~ 2.9 at 68 dof (5 of 8 seeds fitted at 2.56-2.97 in the issue, unscaled under the old 'above 3' rule).
    Now: misfit flagged, sigma Birge-scaled, parameters' normalised errors over seeds with an RMS of order one (before
    scaling: ~1.7).
    """
    truth = {f'{b.name}.{k}': (getattr(b, k) * (VF if k == 'viscosity' else CF)[i])
             for i, b in enumerate(rig.bearings) for k in ('viscosity', 'clearance')}
    z_scaled, z_raw = [], []
    for seed in range(8):
        fit, res = fit_physical(model, rig, _noisy(node_route_clean, 300 + seed, 1.7))
        assert fit.dof == 68
        assert fit.misfit and all(r.misfit and 'misfit' in r.flags for r in res)
        assert any(n.startswith('MODEL MISFIT') and 'LOWER BOUND' in n for n in res[0].notes)
        b = fit.quality.birge
        assert b == pytest.approx(math.sqrt(fit.chi2 / fit.dof))
        for name, v, s in zip(fit.names, fit.values, fit.rel_std):
            z_scaled.append(math.log(v / truth[name]) / s)
            z_raw.append(math.log(v / truth[name]) / (s / b))
    rs, rr = math.sqrt(np.mean(np.square(z_scaled))), math.sqrt(np.mean(np.square(z_raw)))
    assert 0.6 < rs < 1.5 and rr > 1.3, (rs, rr)


def test_physical_correct_noise_is_not_a_misfit_and_parameters_are_in_the_json(rig, model, node_route_clean):
    res = identify_physical(model, rig, _noisy(node_route_clean, 41, 1.0))
    r = res[0]
    assert not r.misfit and r.plainly_determined
    d = json.loads(json.dumps(r.to_dict()))
    assert d['misfit'] is False and d['fit_quality']['dof'] == 68
    for i, b in enumerate(rig.bearings):
        for kind, f, unit in (('viscosity', VF[i], 'Pa s'), ('clearance', CF[i], 'm')):
            e = d['parameters'][f'{b.name}.{kind}']
            nominal = getattr(b, kind)
            assert e['unit'] == unit and e['nominal'] == pytest.approx(nominal)
            assert abs(e['value'] - f * nominal) <= 4 * e['std'], (kind, e)
            assert e['factor'] == pytest.approx(e['value'] / nominal)
    assert any(n.startswith('fitted parameters (short bearing model)') and 'bearing2 clearance' in n
               for n in r.notes)


# ------------------------------------------------------------------------------------------------ paper: static DC
def test_paper_kf_removes_static_offset_nis_in_band_and_coefficients_unchanged(rig, model):
    """
    The paper's KF removes a static offset: NIS in its band and the coefficients unchanged.

    Truth = the KF's theory (a consistent filter), one steady dwell per run, Q = 1e-18 (the paper's range): the mean NIS
    is inside its 95 % chi-square band with or without a 30/-20 um DC in the samples, and the coefficients from the DC
    data equal the no-DC ones well within their stated sigma.  Without the removal NIS is ~1e3.
    """
    nom = supports.bearing_fn(rig)
    recs = [rigmod.simulate_run(rig, run, speeds_rpm=[1500.0], dwell=1.0, probes=P6, bearing_fn=nom, noise=0.01,
                                seed=7 + k, model=model) for k, run in enumerate(rig.simulation.runs)]
    dc = np.array([30e-6, -20e-6])
    d0 = from_recordings(recs)
    d1 = from_recordings([dataclasses.replace(r, samples=r.samples + dc) for r in recs])
    opts = {'bearing_fn': nom, 'Q': 1e-18}
    (r0,) = identify_paper(model, rig, d0, P6, d0.runs, opts)
    (r1,) = identify_paper(model, rig, d1, P6, d1.runs, opts)
    n_steps = [w[0][1] - w[0][0] for w in d1.windows]
    for nis, n in zip(r1.extra['nis'], n_steps):
        lo, hi = nis_band(n, 2)
        assert lo <= nis <= hi, (nis, lo, hi)
    # the window's mean removed: the offset estimated from the window, known to the 1 % noise / sqrt(N) (~1e-7 m)
    assert np.allclose(r1.extra['dc_removed'], dc, atol=1e-7)
    # the 1X fits carry an offset regressor, so the two data sets give the same 1X vectors and the same result:
    # two routes to one quantity, within 0.01 of its stated 1-sigma (undetermined ones to eps x condition)
    assert_results_agree([r1], [r0], 'DC added and removed vs none')
    (rk,) = identify_paper(model, rig, d1, P6, d1.runs, {**opts, 'remove_dc': False})
    assert min(rk.extra['nis']) > 100


# ------------------------------------------------------------------------------------------------ import circle
IDENT_MODULES = sorted(p.stem for p in IDENT.glob('*.py') if p.stem != '__init__')


def _intra_imports(path: Path) -> set:
    """
    Return the identify/ submodules a file imports.

    Top level and inside functions: ``from .x import``, ``from . import x``, ``bearing_id.identify.x``.
    """
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            mod = node.module or ''
            if node.level == 1:
                if mod:
                    out.add(mod.split('.')[0])
                else:
                    out.update(a.name for a in node.names)
            elif mod.startswith('bearing_id.identify.'):
                out.add(mod.split('.')[2])
            elif node.level == 2 and mod.startswith('identify.'):
                out.add(mod.split('.')[1])
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith('bearing_id.identify.'):
                    out.add(a.name.split('.')[2])
    return out & set(IDENT_MODULES)


def test_identify_import_graph_has_no_cycle():
    graph = {m: _intra_imports(IDENT / f'{m}.py') - {m} for m in IDENT_MODULES}
    # the shared least-squares helpers live in lsq; paper, design and conventional import it, not each other
    for m in ('paper', 'design', 'conventional'):
        assert 'lsq' in graph[m]
        assert not graph[m] & {'paper', 'design', 'conventional'}, (m, graph[m])
    state = {}

    def visit(m, stack):
        state[m] = 1
        for n in graph[m]:
            if state.get(n) == 1:
                raise AssertionError(f"import cycle: {' -> '.join(stack + [m, n])}")
            if n not in state:
                visit(n, stack + [m])
        state[m] = 2

    for m in IDENT_MODULES:
        if m not in state:
            visit(m, [])


@pytest.mark.parametrize('mod', IDENT_MODULES)
def test_each_identify_module_imports_alone_in_a_fresh_interpreter(mod):
    out = subprocess.run([sys.executable, '-c', f'import bearing_id.identify.{mod}'], capture_output=True,
                         text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
