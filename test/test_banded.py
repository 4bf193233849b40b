"""
Stacks of dynamic-stiffness systems solved in their band (``rotor.banded``) against numpy's dense LU.

The oracle is ``numpy.linalg.solve`` on the same systems: both are backward-stable LU solves, so their solutions
agree within ``error_bounds.solve_tol`` (P_N eps cond(Z)) of each other.  The systems are a rotor's own (ROSS's
6-stage compressor as ``bearing-id import-ross`` gives it, 224 DOFs, its bearing tables, three speeds and orders) and
random banded ones; a stack whose nonzeros leave the band, and a small one, are solved dense.
"""
from __future__ import annotations

from pathlib import Path

from bearing_id.config.params import parse_rig
from bearing_id.io import ross_import
from bearing_id.rotor.assembly import dynamic_stiffness, RotorModel
from bearing_id.rotor.banded import BAND_MIN_N, band_of, solve_stack
from bearing_id.rotor.supports import bearing_fn
from error_bounds import solve_tol
import numpy as np
import pytest


def _agree(Z, B, X):
    ref = np.linalg.solve(Z, B)
    for k in range(Z.shape[0]):
        tol = solve_tol(Z[k])
        assert np.linalg.norm(X[k] - ref[k]) <= tol * np.linalg.norm(ref[k]), k


def test_a_rotors_systems_are_solved_in_their_band():
    d = ross_import.import_ross(Path(__file__).parent / 'data' / 'ross' / 'compressor.toml')
    d.pop('_notes', None)
    rig = parse_rig(d)
    model = RotorModel.from_params(rig)
    assert model.ndof >= BAND_MIN_N
    coeffs_of = bearing_fn(rig)
    Z = []
    for rpm in (900.0, 1800.0, 2700.0):
        W = rpm * np.pi / 30
        for ratio in (1.0, 2.0, 3.0):
            Z.append(dynamic_stiffness(model, W, ratio * W, coeffs_of(W)))
    Z = np.stack(Z)
    assert band_of(Z) == (7, 7)
    rng = np.random.default_rng(1)
    B = rng.standard_normal((Z.shape[0], model.ndof, 2)) + 1j * rng.standard_normal((Z.shape[0], model.ndof, 2))
    _agree(Z, B, solve_stack(Z, B))


@pytest.mark.parametrize('lo, up', [(7, 7), (3, 9), (0, 4)])
def test_random_banded_stacks(lo, up):
    rng = np.random.default_rng(lo + 10 * up)
    n, N = 5, 160
    Z = rng.standard_normal((n, N, N)) + 1j * rng.standard_normal((n, N, N))
    i, j = np.indices((N, N))
    Z[:, (i - j > lo) | (j - i > up)] = 0.0
    Z += 4 * np.eye(N)                         # well conditioned
    assert band_of(Z) == (lo, up)
    B = rng.standard_normal((n, N, 3)) + 0j
    _agree(Z, B, solve_stack(Z, B))


def test_a_system_outside_the_band_or_small_is_solved_dense_and_a_singular_one_raises():
    rng = np.random.default_rng(3)
    N = 128
    Z = np.stack([np.eye(N) * 3 + 0j] * 2)
    Z[:, 0, N - 1] = 1.0                       # a coupling from the first DOF to the last: no band
    B = rng.standard_normal((2, N, 1)) + 0j
    _agree(Z, B, solve_stack(Z, B))
    small = rng.standard_normal((3, 20, 20)) + 5 * np.eye(20)
    Bs = rng.standard_normal((3, 20, 1))
    _agree(small, Bs, solve_stack(small, Bs))
    S = np.stack([np.eye(N, dtype=complex)])
    S[0, 5, 5] = 0.0
    with pytest.raises(np.linalg.LinAlgError):
        solve_stack(S, np.ones((1, N, 1), complex))
