"""
Issue 12 item 4: the direct/physical forward model's fast path (one factorisation per speed, Woodbury updates).

Reference: :func:`bearing_id.identify.direct.response_and_jacobian` (a dense solve of the full dynamic stiffness per
evaluation).  :class:`~bearing_id.identify.direct.SpeedResponse` must give the same probe phasors and Jacobian to
1e-9 relative, dense and sparse factorisation, with and without a pedestal in series with a film, at coefficients
far from the reference point (up to x3 and with sign-changed cross terms); and whole fits must agree.
"""
from __future__ import annotations

from pathlib import Path

from bearing_id.config.params import load_rig, Probe
from bearing_id.conventions import dof_index
from bearing_id.identify import direct
from bearing_id.rotor.assembly import RotorModel
from bearing_id.rotor.supports import bearing_fn
import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / 'params' / 'examples'


def _cases(model, rig, speed, rng):
    probes = tuple(rig.probes) + (Probe('extra', 3, 'x'),)
    cases = []
    for _ in range(3):
        F = np.zeros(model.ndof, dtype=complex)
        F[rng.integers(0, 4 * model.n_nodes, 3)] = rng.standard_normal(3) + 1j * rng.standard_normal(3)
        cases.append(direct.Case(F, probes, np.zeros(len(probes), complex), np.ones(len(probes))))
    return cases


def _rel(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


@pytest.mark.parametrize('which', ['paper_rig', 'plant_like'])
@pytest.mark.parametrize('sparse', [False, True])
def test_speed_response_equals_the_dense_solve(which, sparse):
    rig = load_rig(EXAMPLES / f'{which}.yaml')
    model = RotorModel.from_params(rig)
    if which == 'plant_like':
        assert model.pedestals                          # a film in series with a pedestal is exercised
    nodes = tuple(b.node for b in rig.bearings)
    rng = np.random.default_rng(3)
    fn = bearing_fn(rig)
    for speed in (150.0, 420.0):
        cases = _cases(model, rig, speed, rng)
        beta_ref = direct.coeffs_to_beta(fn(speed), nodes)
        fast = direct.SpeedResponse(model, speed, cases, nodes, beta_ref, sparse=sparse)
        for factor in (1.0, 1.3, 3.0, -1.0):
            beta = beta_ref * (1 + 0.2 * rng.standard_normal(beta_ref.size)) * (factor if factor > 0 else 1.0)
            if factor < 0:                              # cross terms of the opposite sign
                beta = beta.copy()
                for i in range(len(nodes)):
                    beta[8 * i + 1:8 * i + 3] *= -1
            ys, dys = direct.response_and_jacobian(model, speed, cases, beta, nodes)
            yf, dyf = fast(beta)
            for a, b in zip(yf, ys):
                assert _rel(a, b) <= 1e-9
            for a, b in zip(dyf, dys):
                assert _rel(a, b) <= 1e-9


def test_whole_fit_agrees_with_the_reference():
    rig = load_rig(EXAMPLES / 'paper_rig.yaml')
    model = RotorModel.from_params(rig)
    nodes = tuple(b.node for b in rig.bearings)
    speed = 300.0
    th = bearing_fn(rig)(speed)
    truth = {n: (1.2 * K, 0.85 * C) for n, (K, C) in th.items()}
    probes = tuple(Probe(f'p{n}{d}', n, d) for n in (3, 4, 6, 8, 9) for d in ('x', 'y'))
    cases = []
    for node in (4, 8):
        for k in range(2):                               # a synchronous force in x, then y, at each disc
            F = np.zeros(model.ndof, dtype=complex)
            F[dof_index(node, 'xy'[k], model.n_nodes)] = 10.0
            cases.append(direct.Case(F, probes, np.zeros(len(probes), complex), np.ones(len(probes))))
    ys, _ = direct.response_and_jacobian(model, speed, cases, direct.coeffs_to_beta(truth, nodes), nodes)
    cases = [direct.Case(c.F, c.probes, y, np.full(y.size, 1e-3 * np.max(np.abs(y)))) for c, y in zip(cases, ys)]
    a = direct.fit_speed(model, speed, cases, nodes, theory=th, fast=True)
    b = direct.fit_speed(model, speed, cases, nodes, theory=th, fast=False)
    assert np.max(np.abs(a.K - b.K)) <= 1e-7 * np.max(np.abs(b.K))
    assert np.max(np.abs(a.C - b.C)) <= 1e-7 * np.max(np.abs(b.C))
    assert b.K_determined.all() and b.C_determined.all()
    Kt = np.stack([truth[n][0] for n in nodes])
    assert np.max(np.abs(a.K - Kt)) <= 1e-6 * np.max(np.abs(Kt))   # noise-free data: the truth back


@pytest.mark.parametrize('sparse_ndof', [10_000, 0])
def test_gate_orbits_equal_a_dense_solve_per_run(sparse_ndof, monkeypatch):
    """
    The plausibility gate's orbits (one factorisation of Z for all runs, dense then sparse LU) against numpy.

    Oracle: per run q = numpy.linalg.solve(Z, F), scaled by the least-squares ratio of measured to modelled probe
    amplitudes, orbit radius |(q_x, q_y)| at each bearing.  Two backward-stable solves: ||dq|| <= solve_tol ||q||
    (test/error_bounds.py); a radius moves by at most 3 x that times scale ||q|| (q, and twice through the scale).
    """
    from bearing_id.excitation import harmonic_forces
    from bearing_id.identify import plausibility as pl
    from bearing_id.rotor.assembly import dynamic_stiffness, probe_matrix
    from bearing_id.simulation.rig import simulate_data
    from error_bounds import solve_tol
    monkeypatch.setattr(direct, 'SPARSE_NDOF', sparse_ndof)       # dense, then the sparse LU on the same model
    rig = load_rig(EXAMPLES / 'plant_like.yaml')
    model = RotorModel.from_params(rig)
    data = simulate_data(rig, rig.simulation.runs, (1500, 3000), model=model)
    res = direct.identify_direct(model, rig, data)
    S = probe_matrix(model, data.probes)
    for s, r in enumerate(res):
        got = pl.bearing_orbits(r, model, data, s, data.runs, data.probes)
        w = float(data.speeds[s])
        Z = dynamic_stiffness(model, w, w, r.coeffs())
        tol = 3 * solve_tol(Z, Z)
        want = dict.fromkeys(got, 0.0)
        size = 0.0
        for k, run in enumerate(data.runs):
            F = harmonic_forces(run.excitation, w, model.n_nodes, model.ndof).get(1.0)
            if F is None:
                continue
            q = np.linalg.solve(Z, F)
            pred, meas = np.abs(S @ q), np.abs(data.X[k, s])
            scale = pred @ meas / (pred @ pred)
            size = max(size, scale * np.linalg.norm(q))
            for n in want:
                i = dof_index(n, 'x', model.n_nodes)
                want[n] = max(want[n], scale * np.hypot(abs(q[i]), abs(q[i + 1])))
        assert got.keys() == want.keys()
        for n in got:
            assert abs(got[n] - want[n]) <= tol * size


@pytest.mark.parametrize('which', ['paper_rig', 'plant_like'])
def test_stacked_response_and_weighted_stack_equal_the_per_run_path(which):
    """
    Issue 13: SpeedResponse.stacked and WeightedStack (the fit's path) against their references.

    __call__ and the dense solve to 1e-9 relative, weighted_stack to 1e-15 (the same arithmetic).
    """
    rig = load_rig(EXAMPLES / f'{which}.yaml')
    model = RotorModel.from_params(rig)
    nodes = tuple(b.node for b in rig.bearings)
    rng = np.random.default_rng(5)
    fn = bearing_fn(rig)
    speed = 300.0
    cases = _cases(model, rig, speed, rng)
    cases = [direct.Case(c.F, c.probes, 1e-6 * (rng.standard_normal(len(c.X)) + 1j * rng.standard_normal(len(c.X))),
                         1e-8 * (1 + rng.random(len(c.X)))) for c in cases]
    beta_ref = direct.coeffs_to_beta(fn(speed), nodes)
    fast = direct.SpeedResponse(model, speed, cases, nodes, beta_ref)
    assert fast.uniform
    scale = direct.default_scale(nodes, fn(speed))
    stack = direct.WeightedStack(cases, scale)
    for factor in (1.0, 1.5, 0.7):
        beta = beta_ref * factor * (1 + 0.1 * rng.standard_normal(beta_ref.size))
        ys, dys = direct.response_and_jacobian(model, speed, cases, beta, nodes)
        y1, d1 = fast(beta)
        ysf, dysf = fast.stacked(beta)
        for r in range(len(cases)):
            assert _rel(ysf[r], ys[r]) < 1e-9 and _rel(dysf[r], dys[r]) < 1e-9
            assert _rel(ysf[r], y1[r]) < 1e-12 and _rel(dysf[r], d1[r]) < 1e-12
        r_ref, J_ref = direct.weighted_stack(cases, list(ysf), list(dysf), scale)
        r_f, J_f = stack(ysf, dysf)
        assert _rel(r_f, r_ref) < 1e-15 and _rel(J_f, J_ref) < 1e-15
