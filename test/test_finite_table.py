"""
Tabulated finite-length bearing (bearings/finite_table.py) and the physical fit with --bearing-model finite.

References (independent of the table):
* the direct finite-volume Reynolds solver (bearings/finite.py) on the table's grid and on its default grid, at
  Sommerfeld numbers between the table's samples, with the stated tolerances of finite_table.py;
* the closed-form short bearing (bearings/short.py) for the spline's representation error;
* simulated data with known truth parameters for the fit (simulation.rig.simulate_data, a linear solve per speed).
"""
from __future__ import annotations

import math
from pathlib import Path

from bearing_id import bearings
from bearing_id.bearings import finite, finite_table, short
from bearing_id.config.params import Probe
from bearing_id.identify.physical import fit_physical
from bearing_id.rotor import supports
from bearing_id.simulation.rig import simulate_data
import numpy as np
import pytest

D = L = 0.01265
C_RAD = 5e-5
MU = 0.03
W = 9.7
P6 = (Probe('p6x', 6, 'x'), Probe('p6y', 6, 'y'))


def speed_for(S):
    return S * 2 * math.pi * W / (MU * L * D * (D / 2 / C_RAD) ** 2)


def rel(a, b):
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / np.abs(np.asarray(b)).max())


def test_spline_representation_error_on_the_closed_form_short_bearing():
    """
    The table's spline layout fitted to the closed-form short bearing reproduces it to < 2e-5 of the largest entry.

    The layout: ln S knots every KNOT_EVERY samples; fitted to the smooth closed-form short bearing, it reproduces it
    between the samples.
    """
    s = np.geomspace(finite_table.S_MIN, finite_table.S_MAX, finite_table.N_SAMPLES)

    def row(S):
        e = short.short_eccentricity(S, 1.0)
        k, b = short.short_coefficients_lit(e)
        return np.r_[e, short.short_attitude_angle(e), k.ravel(), b.ravel()]

    tab = finite_table.fit_table(1.0, s, np.array([row(v) for v in s]), (0, 0))
    mids = np.sqrt(s[1:] * s[:-1])[3:-3:7]
    for S in mids:
        ref = row(S)
        e, phi, k, b = tab.evaluate(float(S))
        assert abs(e - ref[0]) < 2e-5 and abs(phi - ref[1]) < 2e-5
        assert rel(k.ravel(), ref[2:6]) < 2e-5 and rel(b.ravel(), ref[6:]) < 2e-5, S


def test_tables_written_as_json_read_back_to_the_same_doubles(tmp_path):
    """
    write_tables -> read_tables keeps every knot, coefficient and residual (the shipped tables' storage format).

    Bound: write_tables prints floats with repr, the shortest decimal that reads back to the same double, so the
    stored value is the written one within 0 ulp; allowed here: 1 ulp of each value (np.spacing).
    The shipped tables (both cavitations, L/D 1 and 0.5) are found in the package data.
    """
    s = np.geomspace(finite_table.S_MIN, finite_table.S_MAX, 97)
    rows = []
    for v in s:
        e = short.short_eccentricity(v, 1.0)
        k, b = short.short_coefficients_lit(e)
        rows.append(np.r_[e, short.short_attitude_angle(e), k.ravel(), b.ravel()])
    tabs = [finite_table.fit_table(LD, s, np.array(rows) * LD, (96, 12), knot_every=8, cavitation='gumbel')
            for LD in (1.0, 0.7)]
    back = finite_table.read_tables(Path(finite_table.write_tables(tabs, tmp_path / 't.json', 'gumbel')).read_text())
    assert len(back) == 2
    for t, r in zip(tabs, back):
        assert (r.L_over_D, r.s_min, r.s_max, r.grid, r.cavitation) == (t.L_over_D, t.s_min, t.s_max, t.grid, 'gumbel')
        for name in ('knots', 'coef', 'fit_rms'):
            a, b = np.asarray(getattr(t, name)), getattr(r, name)
            assert a.shape == b.shape and np.all(np.abs(b - a) <= np.spacing(np.abs(a))), name
    for cav in ('swift_stieber', 'gumbel'):
        for LD in (1.0, 0.5):
            tab = finite_table.table_for(LD, build=False, cavitation=cav)
            assert tab is not None and tab.cavitation == cav and tab.grid == finite_table.TABLE_GRID
            assert (tab.s_min, tab.s_max) == (finite_table.S_MIN, finite_table.S_MAX)


@pytest.mark.parametrize('S', [0.03, 0.12, 1.3])
def test_table_matches_direct_solver_on_its_grid(S):
    w = speed_for(S)
    t = finite_table.solution(D, L, C_RAD, MU, W, w)
    d = finite.reynolds(D, L, C_RAD, MU, W, w, *finite_table.TABLE_GRID)
    assert t.model == 'finite' and math.isnan(t.force_error)
    assert abs(t.eccentricity - d.eccentricity) <= finite_table.TOL_ECC
    tol = finite_table.stated_tolerance(S, table_grid=True)
    assert rel(t.K, d.K) <= tol and rel(t.C, d.C) <= tol


@pytest.mark.parametrize('S', [0.008, 0.025, 0.07, 0.3, 3.0, 15.0])
def test_table_matches_direct_solver_on_the_default_grid(S):
    w = speed_for(S)
    t = finite_table.solution(D, L, C_RAD, MU, W, w)
    d = finite.reynolds(D, L, C_RAD, MU, W, w)
    assert abs(t.eccentricity - d.eccentricity) <= finite_table.TOL_ECC
    tol = finite_table.stated_tolerance(S, table_grid=False)
    assert rel(t.K, d.K) <= tol and rel(t.C, d.C) <= tol


def _count_direct_solves(monkeypatch) -> list:
    """Count the calls of the direct finite-volume Reynolds solver, wherever the bearing code reaches it."""
    calls = []

    def counted(*a, **k):
        calls.append(a)
        return finite.reynolds(*a, **k)
    monkeypatch.setattr(bearings, 'reynolds', counted)
    monkeypatch.setattr(finite_table, 'reynolds', counted)
    return calls


def test_finite_model_uses_the_table_and_falls_back_outside_it(rig, monkeypatch):
    """Inside the table's Sommerfeld range no direct Reynolds solve is run (0.1-0.4 s each); outside it one is."""
    b = rig.bearings[0]
    bearings._solve.cache_clear()
    calls = _count_direct_solves(monkeypatch)
    for i in range(500):
        K, C = bearings.coefficients(b, 50.0 + 0.37 * i, 9.7, model='finite')
    assert calls == []
    S_big = 2 * finite_table.S_MAX
    s = bearings.solution(b, speed_for(S_big), W, model='finite')       # outside the table: the direct solver
    assert s.force_error <= 1e-8 and s.sommerfeld > finite_table.S_MAX
    d = bearings.solution(b, speed_for(0.2), W, model='finite_direct')
    assert d.force_error <= 1e-8


@pytest.fixture(scope='module')
def finite_truth(rig, model):
    """
    Simulate node 6, unbalance A+B, 6 speeds 600-3528 rpm.

    Truth = finite bearing at viscosity x1.3 / clearance x0.7, x0.85.
    """
    bfn = supports.bearing_fn(rig, model='finite', viscosity_factor=(1.3, 1.3), clearance_factor=(0.7, 0.85))
    return simulate_data(rig, rig.simulation.runs, tuple(np.linspace(600, 3528, 6)), probes=P6, bearing_fn=bfn,
                         model=model)


def _noisy(clean, seed):
    rng = np.random.default_rng(seed)
    std = 0.01 * np.abs(clean.X) / math.sqrt(15360)
    X = clean.X + std * (rng.standard_normal(clean.X.shape) + 1j * rng.standard_normal(clean.X.shape))
    return type(clean)(clean.speeds, clean.probes, clean.runs, X, std, [], [], clean.truth)


def test_physical_finite_fits_a_finite_truth_from_the_table(rig, model, finite_truth, monkeypatch):
    """
    `--bearing-model finite` fits a finite-length truth from the table (no direct Reynolds solve: each takes 0.1-0.4 s).

    No misfit, parameters within 3 sigma of the truth, and the short model on the same data is declared a misfit
    whose note suggests the finite model.
    """
    data = _noisy(finite_truth, 5)
    bearings._solve.cache_clear()
    calls = _count_direct_solves(monkeypatch)
    fit, res = fit_physical(model, rig, data, bearing_model='finite')
    assert calls == []
    assert not fit.misfit and fit.chi2 / fit.dof < 2.0
    truth = [0.03 * 1.3, 5e-5 * 0.7, 0.03 * 1.3, 5e-5 * 0.85]
    z = np.log(fit.values / truth) / fit.rel_std
    assert np.all(np.abs(z) <= 3.0), z
    assert all(r.plainly_determined for r in res)
    fs, rs = fit_physical(model, rig, data, bearing_model='short')
    assert fs.misfit and any('--bearing-model finite' in n for n in rs[0].notes if n.startswith('MODEL MISFIT'))


def test_finite_misfit_note_does_not_suggest_the_finite_model(rig, model):
    """Data from the short bearing fitted with the finite model: a misfit whose note points elsewhere."""
    bfn = supports.bearing_fn(rig, model='short', viscosity_factor=1.3, clearance_factor=0.8)
    data = _noisy(simulate_data(rig, rig.simulation.runs, (900, 1800, 2700), probes=P6, bearing_fn=bfn,
                                model=model), 6)
    fit, res = fit_physical(model, rig, data, bearing_model='finite')
    assert fit.misfit
    note = next(n for n in res[0].notes if n.startswith('MODEL MISFIT'))
    assert '--bearing-model finite' not in note and 'LOWER BOUND' in note and 'diagnose' in note
