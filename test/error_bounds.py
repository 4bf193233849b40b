"""
Error bounds the tests derive their tolerances from, and an eigenvalue oracle (not a test module).

* :func:`solve_tol`: two solutions of one linear system by backward-stable solves (LU with partial pivoting,
  Higham 2002 thm. 9.4, growth factor of a few) differ by at most 8 n eps cond(Z) ||q|| each.
* :func:`sum_tol`: a floating-point sum of terms is within n eps sum |terms| of the exact one (Higham 2002 eq. 4.4).
* :func:`eigen_with_bounds`: the eigenvalue oracle below.
* :func:`state_backward_error`: backward error of a computed mode in the oracle's balanced state matrix; a
  backward-stable eigensolver keeps it below n eps (the classic p(n) = n, n the state dimension).

Eigenvalue oracle for a state matrix, with LAPACK's error bound for each eigenvalue.

scipy.linalg.eig (LAPACK geev) on the balanced matrix Ab = T^-1 A T (scipy.linalg.matrix_balance, scaling only,
what geev does itself), with left and right eigenvectors.  Error bound (LAPACK Users' Guide, 3rd ed., section 4.8.1,
"approximate error bound for the computed eigenvalue"): |lambda_computed - lambda| <= p(n) eps ||Ab||_2 / s(lambda),
s = |y^H x| for unit left and right eigenvectors y, x (1 / s is the eigenvalue's condition number); p(n) is "a
modestly growing function of n", taken here as P_N = 10.  Two routes that each meet this bound agree within twice it.
Balancing matters: the rotor's state matrix [[0, I], [-M^-1 K, -M^-1 C]] has ||A|| ~ 1e12 ... 1e14 from the small
rotary inertias, the balanced one 1e5 ... 1e7.
"""
from __future__ import annotations

from bearing_id.rotor.assembly import state_space, system_matrices
import numpy as np
from scipy.linalg import eig, matrix_balance

P_N = 10
EPS_MACH = np.finfo(float).eps


def eigen_with_bounds(A: np.ndarray):
    """
    Return (lam (n,), bound (n,), X (n, n)) of the real or complex matrix ``A`` (n, n).

    lam: eigenvalues; bound: the error bound of each (P_N eps ||Ab|| / s); X: right eigenvectors of ``A`` itself (the
    balancing undone), unit columns.
    """
    Ab, T = matrix_balance(np.asarray(A), permute=False)
    lam, VL, VR = eig(Ab, left=True, right=True)
    s = np.abs(np.sum(VL.conj() * VR, axis=0)) / (np.linalg.norm(VL, axis=0) * np.linalg.norm(VR, axis=0))
    bound = P_N * EPS_MACH * np.linalg.norm(Ab, 2) / s
    X = T @ VR
    return lam, bound, X / np.linalg.norm(X, axis=0)


def solve_tol(*Zs) -> float:
    """Relative (to ||q||) agreement of the solutions of the systems ``Zs`` (n, n) by backward-stable solves."""
    return sum(8 * Z.shape[0] * EPS_MACH * np.linalg.cond(Z) for Z in Zs)


def sum_tol(terms) -> float:
    """Absolute error bound n eps sum |terms| of a floating-point sum of ``terms`` (any shape, summed entirely)."""
    t = np.abs(np.asarray(terms))
    return t.size * EPS_MACH * float(np.sum(t))


def nearest(lam: np.ndarray, value: complex) -> int:
    """Index of the eigenvalue in ``lam`` nearest ``value``."""
    return int(np.argmin(np.abs(lam - value)))


def state_backward_error(model, w: float, coeffs: dict, lam: complex, v: np.ndarray) -> float:
    """
    Backward error of a mode (lam [1/s], rotor shape v) of ``model`` at speed ``w`` on ``coeffs``.

    In the balanced state matrix Ab = T^-1 A T of :func:`eigen_with_bounds`: pedestal DOFs the shape leaves out are
    those that fit it best (least squares on the equations of motion), the state x = [q; lam q];
    returns ||Ab xb - lam xb|| / (||Ab|| ||xb||), xb = T^-1 x.
    """
    M, C, K = system_matrices(model, w, coeffs)
    P = lam**2 * M + lam * C + K
    q = np.zeros(model.ndof, complex)
    q[:v.size] = v
    if v.size < model.ndof:
        q[v.size:] = np.linalg.lstsq(P[:, v.size:], -P[:, :v.size] @ v, rcond=None)[0]
    Ab, T = matrix_balance(state_space(model, w, coeffs)[0], permute=False)
    xb = np.concatenate([q, lam * q]) / np.diag(T)
    return float(np.linalg.norm(Ab @ xb - lam * xb) / (np.linalg.norm(Ab, 2) * np.linalg.norm(xb)))
