"""
Error bounds the tests derive their tolerances from, and an eigenvalue oracle (not a test module).

* :func:`solve_tol`: a linear solve by LAPACK (LU with partial pivoting) is off by at most p(n) eps cond(Z) ||q||
  (LAPACK Users' Guide, 3rd ed., section 4.4.1, the approximate error bound for linear systems; p(n) = P_N as for
  the eigenvalues below); two solutions of one system differ by at most the sum of their bounds.
* :func:`sum_tol`: a floating-point sum of terms is within n eps sum |terms| of the exact one (Higham 2002 eq. 4.4).
* :func:`richardson_check`: a central difference against an analytic derivative, with Richardson's truncation
  estimate and the evaluation's rounding (derivation in its docstring).
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
    """Relative (to ||q||) agreement of the solutions of the systems ``Zs`` (n, n) by LAPACK solves [-]."""
    return sum(P_N * EPS_MACH * np.linalg.cond(Z) for Z in Zs)


def sum_tol(terms) -> float:
    """Absolute error bound n eps sum |terms| of a floating-point sum of ``terms`` (any shape, summed entirely)."""
    t = np.abs(np.asarray(terms))
    return t.size * EPS_MACH * float(np.sum(t))


RICCATI_RESIDUAL = 1e-10    # relative Riccati residual bearing_id.estimation.kalman.steady_state_gain accepts


def richardson_check(fd_of, h: float, exact, acc: float, scale: float) -> tuple[float, float]:
    """
    Assert that the central difference ``fd_of(h / 2)`` is the derivative ``exact`` within its derived error.

    ``fd_of(h)`` = (f(x + h) - f(x - h)) / (2 h); ``acc``: relative accuracy of one evaluation of f, ``scale``: the
    size of f (max |f|), so each evaluation is off by at most acc scale and fd(h) by nu(h) = acc scale / h.  With
    fd(h) = f' + c h^2 + O(h^4) + N(h), |N(h)| <= nu(h): fd(h) - fd(h/2) = 3 c h^2 / 4 + N(h) - N(h/2), so
    |fd(h/2) - f'| <= |fd(h) - fd(h/2)| / 3 + (nu(h) + nu(h/2)) / 3 + nu(h/2) = |fd(h) - fd(h/2)| / 3 + 3 nu(h) (+ the
    O(h^4) rest).  Allowed: 2 |fd(h) - fd(h/2)| (6x the estimate, for the O(h^4) rest) + 3 nu(h).
    Returns (error, tolerance).
    """
    f1, f2 = np.asarray(fd_of(h)), np.asarray(fd_of(h / 2))
    err = float(np.abs(f2 - exact).max())
    tol = 2 * float(np.abs(f1 - f2).max()) + 3 * acc * scale / h
    assert err <= tol, (err, tol)
    return err, tol


def lstsq_acc(cond: float) -> float:
    """
    Relative accuracy of a least-squares solve (QR or SVD) with condition number ``cond`` [-].

    P_N eps (cond + cond^2): LAPACK Users' Guide, 3rd ed., section 4.5.1 (the approximate error bound of the linear
    least squares problem) with the residual term bounded by cond^2 (zero for a consistent system: an over-estimate).
    """
    return P_N * EPS_MACH * (cond + cond * cond)


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
