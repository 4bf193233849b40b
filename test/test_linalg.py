"""
bearing_id.linalg (numpy only) against scipy.linalg, the reference it replaces on the identify path (issue 13).

* expm: scipy.linalg.expm to 1e-12 relative (1-norm) on the rotor's state matrices times the sample step (paper rig
  and the plant-like example, three speeds each), on the discretisation block [[A dt, B dt], [0, 0]] the Kalman
  filter exponentiates, on random real and complex matrices of every size class (each Pade order 3-13 taken), and
  exp of a diagonal / nilpotent matrix against its closed form.
* balance: an exact similarity by powers of 2 (same eigenvalues), and an eigenvector basis as well conditioned as
  scipy.linalg.matrix_balance's (within a factor 10) where the unbalanced one is ~1e7.
* qr_r and solve_triangular: scipy's dgeqrf R (up to the signs of its rows) and solve_triangular to 1e-12.
"""
from pathlib import Path

from bearing_id import linalg
from bearing_id.bearings import bearing_fn
from bearing_id.params import load_rig
from bearing_id.rotor.assembly import RotorModel, state_space
import numpy as np
import pytest
import scipy.linalg as sla

EXAMPLES = Path(__file__).resolve().parent.parent / 'params' / 'examples'


def _rel(a, b):
    return np.linalg.norm(a - b, 1) / np.linalg.norm(b, 1)


@pytest.fixture(scope='module', params=['paper_rig', 'plant_like'])
def rotor(request):
    rig = load_rig(EXAMPLES / f'{request.param}.yaml')
    model = RotorModel.from_params(rig)
    fn = bearing_fn(rig)
    return [state_space(model, w, fn(w)) for w in np.array([300.0, 1500.0, 3000.0]) * np.pi / 30]


def test_expm_of_the_rotor_state_matrix_and_the_discretisation_block(rotor):
    dt = 1.0 / 10240
    for A, B in (ss[:2] for ss in rotor):
        assert _rel(linalg.expm(A * dt), sla.expm(A * dt)) <= 1e-12
        n, nu = B.shape
        blk = np.zeros((n + nu, n + nu))
        blk[:n, :n], blk[:n, n:] = A * dt, B * dt
        assert _rel(linalg.expm(blk), sla.expm(blk)) <= 1e-12


@pytest.mark.parametrize('scale', [1e-4, 1e-2, 0.3, 1.0, 3.0, 30.0])
@pytest.mark.parametrize('complex_', [False, True])
def test_expm_of_random_matrices_every_pade_order(scale, complex_):
    rng = np.random.default_rng(int(scale * 1e4) + complex_)
    for n in (2, 7, 30):
        M = rng.standard_normal((n, n)) * scale / np.sqrt(n)
        if complex_:
            M = M + 1j * rng.standard_normal((n, n)) * scale / np.sqrt(n)
        assert _rel(linalg.expm(M), sla.expm(M)) <= 1e-12
        assert _rel(linalg.expm(M, balanced=False), sla.expm(M)) <= 1e-12


def test_expm_closed_forms():
    d = np.array([-3.0, 0.5, 2.0])
    np.testing.assert_allclose(linalg.expm(np.diag(d)), np.diag(np.exp(d)), rtol=1e-14)
    N = np.array([[0.0, 2.0], [0.0, 0.0]])                          # nilpotent: exp = I + N
    np.testing.assert_allclose(linalg.expm(N), np.eye(2) + N, rtol=0, atol=1e-15)
    np.testing.assert_allclose(linalg.expm(np.array([[0.7]])), [[np.exp(0.7)]], rtol=1e-15)
    assert linalg.expm(np.zeros((0, 0))).shape == (0, 0)
    with pytest.raises(ValueError):
        linalg.expm(np.zeros((2, 3)))


def _eig_cond(M):
    _, U = np.linalg.eig(M)
    return np.linalg.cond(U, 1)


def test_balance_is_an_exact_similarity_that_conditions_the_eigenvectors(rotor):
    for A, *_ in rotor:
        Ab, t = linalg.balance(A)
        assert np.all(np.log2(t) == np.round(np.log2(t)))          # powers of 2: the similarity is exact
        np.testing.assert_array_equal(Ab, A * t[None, :] / t[:, None])
        lam = np.sort_complex(np.linalg.eigvals(A))
        np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(Ab)), lam, rtol=1e-9,
                                   atol=1e-9 * np.abs(lam).max())
        As, _ = sla.matrix_balance(A, permute=False, separate=True)
        raw, ours, ref = _eig_cond(A), _eig_cond(Ab), _eig_cond(As)
        assert raw > 1e6                                            # the case balancing is for
        assert ours <= 10 * ref, (raw, ours, ref)


def test_qr_r_and_solve_triangular_equal_scipys():
    rng = np.random.default_rng(4)
    A = rng.standard_normal((500, 12)) * np.geomspace(1e-3, 1e3, 12)
    R = linalg.qr_r(A)
    h, _, _, _ = sla.lapack.dgeqrf(A)
    Rs = np.triu(h[:12])
    np.testing.assert_allclose(np.abs(R), np.abs(Rs), rtol=1e-12, atol=1e-12 * np.abs(Rs).max())
    np.testing.assert_allclose(R.T @ R, A.T @ A, rtol=1e-10, atol=1e-10 * np.abs(A.T @ A).max())
    B = rng.standard_normal((12, 3))
    np.testing.assert_allclose(linalg.solve_triangular(Rs, B), sla.solve_triangular(Rs, B), rtol=1e-12)
    S = Rs.copy()
    S[5, 5] = 0.0
    with pytest.raises(np.linalg.LinAlgError):
        linalg.solve_triangular(S, B)
