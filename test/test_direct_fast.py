"""
The direct/physical forward model against a dense solve of the assembled dynamic stiffness.

:class:`bearing_id.identify.direct.SpeedResponse` factorises once per speed and updates in beta by Woodbury.

Oracle (plain numpy, no package route of the fit): Z(beta) = ``rotor.assembly.dynamic_stiffness`` with the bearings
inserted by the assembly (a film in series with a pedestal included), y = P Z^-1 F per run, and -- Z being linear in
beta -- the exact derivative dy/dbeta_k = -P Z^-1 dZ_k Z^-1 F with dZ_k = Z(e_k) - Z(0) taken from the assembly too.

Tolerance (derived, not tuned): both routes are backward-stable solves, so each one's relative forward error is at
most p(n) eps x the condition of what it solves (test/error_bounds.py solve_tol: LAPACK's bound, p(n) = P_N). The
dense oracle solves with Z(beta): cond(Z); the Woodbury route solves with Z_ref = Z(beta_ref) and then with the
capacitance I + D H (H = (Z_ref^-1)_SS, D = Z - Z_ref on the film DOFs S): cond(Z_ref) cond(I + D H). The test allows
P_N eps (cond(Z) + cond(Z_ref) cond(I + D H)) relative to the largest entry, all three conditions computed here from
the oracle's own matrices. Cases: dense and sparse factorisation, with and without a pedestal, coefficients up to x3
from the reference point and with sign-changed cross terms, runs with different probe sets (rows of unequal length).
"""
from __future__ import annotations

from pathlib import Path

from bearing_id.config.params import load_rig, Probe
from bearing_id.conventions import dof_index
from bearing_id.excitation import harmonic_forces
from bearing_id.identify import direct
from bearing_id.identify import plausibility as pl
from bearing_id.rotor.assembly import dynamic_stiffness, probe_matrix, RotorModel
from bearing_id.rotor.supports import bearing_fn
from bearing_id.simulation.rig import simulate_data
from error_bounds import P_N, solve_tol
import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / 'params' / 'examples'
EPS = np.finfo(float).eps


def _cases(model, rig, rng):
    """Three runs of random synchronous forces; the last run reads one probe fewer (unequal rows per run)."""
    probes = tuple(rig.probes) + (Probe('extra', 3, 'x'),)
    cases = []
    for r in range(3):
        F = np.zeros(model.ndof, dtype=complex)
        F[rng.integers(0, 4 * model.n_nodes, 3)] = rng.standard_normal(3) + 1j * rng.standard_normal(3)
        pr = probes if r < 2 else probes[:-1]
        cases.append(direct.Case(F, pr, np.zeros(len(pr), complex), np.ones(len(pr))))
    return cases


def dense_response(model, speed, cases, beta, nodes):
    """Oracle: (y (nrow,), dy (nrow, 8 nb)) from the assembled Z(beta), rows run by run as direct.probe_rows."""
    Z = dynamic_stiffness(model, speed, speed, direct.beta_to_coeffs(beta, nodes))
    Z_empty = dynamic_stiffness(model, speed, speed, direct.beta_to_coeffs(np.zeros_like(beta), nodes))
    dZ = []
    for k in range(beta.size):
        e = np.zeros(beta.size)
        e[k] = 1.0
        dZ.append(dynamic_stiffness(model, speed, speed, direct.beta_to_coeffs(e, nodes)) - Z_empty)
    y, dy = [], []
    for c in cases:
        P = probe_matrix(model, c.probes)
        q = np.linalg.solve(Z, c.F)
        G = np.linalg.solve(Z.T, P.T).T                          # P Z^-1
        y.append(P @ q)
        dy.append(np.stack([-(G @ (d @ q)) for d in dZ], axis=1))
    return np.concatenate(y), np.vstack(dy), Z


def _rel(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


@pytest.mark.parametrize('which', ['paper_rig', 'plant_like'])
@pytest.mark.parametrize('sparse', [False, True])
def test_speed_response_equals_the_dense_solve(which, sparse):
    rig = load_rig(None if which == 'paper_rig' else EXAMPLES / f'{which}.yaml')
    model = RotorModel.from_params(rig)
    if which == 'plant_like':
        assert model.pedestals                          # a film in series with a pedestal is exercised
    nodes = tuple(b.node for b in rig.bearings)
    rng = np.random.default_rng(3)
    fn = bearing_fn(rig)
    for speed in (150.0, 420.0):
        cases = _cases(model, rig, rng)
        beta_ref = direct.coeffs_to_beta(fn(speed), nodes)
        fast = direct.SpeedResponse(model, speed, cases, nodes, beta_ref, sparse=sparse)
        Z_ref = dynamic_stiffness(model, speed, speed, direct.beta_to_coeffs(beta_ref, nodes))
        H = np.linalg.inv(Z_ref)[np.ix_(fast.S, fast.S)]
        for factor in (1.0, 1.3, 3.0, -1.0):
            beta = beta_ref * (1 + 0.2 * rng.standard_normal(beta_ref.size)) * (factor if factor > 0 else 1.0)
            if factor < 0:                              # cross terms of the opposite sign
                beta = beta.copy()
                for i in range(len(nodes)):
                    beta[8 * i + 1:8 * i + 3] *= -1
            y_ref, dy_ref, Z = dense_response(model, speed, cases, beta, nodes)
            cap = np.eye(fast.S.size) + (Z - Z_ref)[np.ix_(fast.S, fast.S)] @ H
            tol = P_N * EPS * (np.linalg.cond(Z) + np.linalg.cond(Z_ref) * np.linalg.cond(cap))
            y, dy = fast(beta)
            assert y.shape == y_ref.shape and dy.shape == dy_ref.shape
            assert _rel(y, y_ref) <= tol, (_rel(y, y_ref), tol)
            assert _rel(dy, dy_ref) <= tol, (_rel(dy, dy_ref), tol)


@pytest.mark.parametrize('sparse_ndof', [10_000, 0])
def test_gate_orbits_equal_a_dense_solve_per_run(sparse_ndof, monkeypatch):
    """
    The plausibility gate's orbits (one factorisation of Z for all runs, dense then sparse LU) against numpy.

    Oracle: per run q = numpy.linalg.solve(Z, F), scaled by the least-squares ratio of measured to modelled probe
    amplitudes, orbit radius |(q_x, q_y)| at each bearing.  Two backward-stable solves: ||dq|| <= solve_tol ||q||
    (test/error_bounds.py); a radius moves by at most 3 x that times scale ||q|| (q, and twice through the scale).
    """
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
