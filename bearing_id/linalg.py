"""
Dense linear algebra the physics needs beyond numpy.linalg, in numpy: so that a command need not import scipy.linalg.

Why
    Importing scipy.linalg costs ~0.3 s of CPU (scipy 1.17's array-API layer imports numpy.f2py and numpy.testing on
    the way), about half of ``bearing-id identify --method paper`` on the paper's job as a process (issue 13).  The
    paper method, the Kalman filter and the transient-aware 1X fit used it for four routines only, given here.

What
    * :func:`expm`: the matrix exponential by Al-Mohy and Higham's scaling and squaring (SIAM J. Matrix Anal. Appl.
      31(3) 2009, Algorithm 6.1) with exact 1-norms of the matrix powers (Pade orders 3 to 13, the order and
      scaling rules of scipy.sparse.linalg's ``_expm`` with exact norms), on the balanced matrix.  Equal to
      ``scipy.linalg.expm`` to ~1e-13 relative (norm-wise) on the rotor's state matrices and the discretisation block
      (test/test_linalg.py).
    * :func:`balance`: a diagonal similarity by powers of 2, T^-1 A T, with LAPACK dgebal's scaling rule (no
      permutation): exact, and it makes the rows and columns of the rotor's mixed-unit state matrix comparable so that
      its eigenvector basis is well conditioned and its exponential accurate.  Each sweep updates every index at
      once from the norms of the matrix at the start of the sweep (dgebal updates one index at a time), so the scales
      may differ from dgebal's; only the conditioning matters to the callers
      (:func:`bearing_id.identify.paper._eig_balanced`, :func:`expm`).
    * :func:`qr_r`: R of the thin QR (LAPACK dgeqrf through numpy).
    * :func:`solve_triangular`: R X = B for upper triangular R (numpy's LU solve: with R upper triangular its
      partial pivoting never swaps rows, so it is back substitution).

Units: whatever the caller's matrices hold.
"""
from __future__ import annotations

import math

import numpy as np

PADE = {
    3: (120., 60., 12., 1.),
    5: (30240., 15120., 3360., 420., 30., 1.),
    7: (17297280., 8648640., 1995840., 277200., 25200., 1512., 56., 1.),
    9: (17643225600., 8821612800., 2075673600., 302702400., 30270240., 2162160., 110880., 3960., 90., 1.),
    13: (64764752532480000., 32382376266240000., 7771770303897600., 1187353796428800., 129060195264000.,
         10559470521600., 670442572800., 33522128640., 1323241920., 40840800., 960960., 16380., 182., 1.),
}
THETA = {3: 1.495585217958292e-2, 5: 2.539398330063230e-1, 7: 9.504178996162932e-1, 9: 2.097847961257068,
         13: 4.25}
# 1 / |c_(2m+1)|: the leading coefficients of the backward-error series (Higham 2005, (2.2) and (2.6))
ELL_C = {3: 100800., 5: 10059033600., 7: 4487938430976000., 9: 5914384781877411840000.,
         13: 113250775606021113483283660800000000.}
UNIT_ROUNDOFF = 2.0 ** -53


def _onenorm(A) -> float:
    return float(np.max(np.sum(np.abs(A), axis=0))) if A.size else 0.0


def _ell(A, m: int) -> int:
    """Return the extra squarings Al-Mohy-Higham's bound asks for at Pade order ``m`` (0 when none)."""
    v = np.ones(A.shape[0])
    absA = np.abs(A)
    for _ in range(2 * m + 1):            # 1-norm of |A|^(2m+1): its largest column sum
        v = v @ absA
    norm_pow = float(np.max(v))
    if not norm_pow:
        return 0
    alpha = norm_pow / (_onenorm(A) * ELL_C[m])
    return max(int(math.ceil(math.log2(alpha / UNIT_ROUNDOFF) / (2 * m))), 0)


def _pade(A, eye, powers: dict, m: int):
    """Return (U, V) of the order-m Pade approximant from A and its even powers {2: A^2, 4: ..., } (13: scaled)."""
    b = PADE[m]
    if m == 13:
        A2, A4, A6 = powers[2], powers[4], powers[6]
        U = A @ (A6 @ (b[13] * A6 + b[11] * A4 + b[9] * A2) + b[7] * A6 + b[5] * A4 + b[3] * A2 + b[1] * eye)
        V = A6 @ (b[12] * A6 + b[10] * A4 + b[8] * A2) + b[6] * A6 + b[4] * A4 + b[2] * A2 + b[0] * eye
        return U, V
    u = b[1] * eye
    v = b[0] * eye
    for k in range(2, m + 1, 2):
        u = u + b[k + 1] * powers[k]
        v = v + b[k] * powers[k]
    return A @ u, v


def expm(A, balanced: bool = True) -> np.ndarray:
    """
    Return exp(A) for a square matrix ``A`` (n, n), real or complex: scipy's algorithm in numpy (module docstring).

    Al-Mohy & Higham (2009) Algorithm 6.1 with exact 1-norms: the lowest Pade order m in (3, 5, 7, 9) whose
    bound holds, else order 13 on A / 2^s squared s times.  ``balanced`` (default): on T^-1 A T (:func:`balance`,
    exact) and transformed back, exp(A) = T exp(T^-1 A T) T^-1: the rotor's state matrix mixes units (entries from
    1 to 1e11 s^-2) and its 1-norm would overstate the scaling the eigenvalues need, costing ~1e-10 of accuracy;
    balanced, it equals scipy.linalg.expm to ~1e-14 (test/test_linalg.py).
    """
    A = np.asarray(A)
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise ValueError(f'expm needs a square matrix, got shape {A.shape}')
    if not np.issubdtype(A.dtype, np.inexact):
        A = A.astype(float)
    n = A.shape[0]
    if n == 0:
        return np.zeros((0, 0), dtype=A.dtype)
    if n == 1:
        return np.exp(A)
    if balanced:
        Ab, t = balance(A)
        return t[:, None] * expm(Ab, balanced=False) / t[None, :]
    eye = np.eye(n, dtype=A.dtype)
    P = {2: A @ A}
    P[4] = P[2] @ P[2]
    P[6] = P[4] @ P[2]
    d4, d6 = _onenorm(P[4]) ** 0.25, _onenorm(P[6]) ** (1 / 6)
    eta1 = max(d4, d6)
    for m in (3, 5):
        if eta1 < THETA[m] and _ell(A, m) == 0:
            U, V = _pade(A, eye, P, m)
            return np.linalg.solve(V - U, U + V)
    P[8] = P[6] @ P[2]
    d8 = _onenorm(P[8]) ** 0.125
    eta3 = max(d6, d8)
    for m in (7, 9):
        if eta3 < THETA[m] and _ell(A, m) == 0:
            U, V = _pade(A, eye, P, m)
            return np.linalg.solve(V - U, U + V)
    d10 = _onenorm(P[4] @ P[6]) ** 0.1
    eta5 = min(eta3, max(d8, d10))
    s = 0 if eta5 == 0 else max(int(math.ceil(math.log2(eta5 / THETA[13]))), 0)
    s += _ell(A * 2.0 ** -s, 13)
    B = A * 2.0 ** -s
    Ps = {2: P[2] * 2.0 ** (-2 * s), 4: P[4] * 2.0 ** (-4 * s), 6: P[6] * 2.0 ** (-6 * s)}
    U, V = _pade(B, eye, Ps, 13)
    X = np.linalg.solve(V - U, U + V)
    for _ in range(s):
        X = X @ X
    return X


BALANCE_FACTOR = 0.95        # dgebal: rescale an index only when it lowers |column| + |row| below this share
BALANCE_PROGRESS = 0.99      # a sweep that lowers the sum of |column| + |row| by less than 1 % ends the balancing


def balance(A, max_sweeps: int = 30):
    """
    Return (T^-1 A T, t) with T = diag(t), t powers of 2, balancing the rows and columns of ``A`` (n, n).

    dgebal's rule (no permutation, 2-norms of the diagonal-inclusive column and row, radix 2, factor 0.95), every
    index of a sweep judged from the matrix at the start of the sweep; sweeps until none changes or a sweep lowers
    the sum of the column and row norms by less than 1 % (updating every index at once can make two coupled indices
    trade a factor 2 back and forth).  The similarity is exact (powers of 2): T^-1 A T has the eigenvalues of A.
    """
    A = np.array(A)
    if not np.issubdtype(A.dtype, np.inexact):
        A = A.astype(float)
    n = A.shape[0]
    t = np.ones(n)
    a2 = np.abs(A) ** 2
    c, r = np.sqrt(np.sum(a2, axis=0)), np.sqrt(np.sum(a2, axis=1))
    total = float(np.sum(c + r))
    for _ in range(max_sweeps):
        ok = (c > 0) & (r > 0) & np.isfinite(c) & np.isfinite(r)
        # f = 2^k, k the integer nearest log4(r / c): the column times f and the row over f made comparable
        k = np.zeros(n)
        k[ok] = np.round(0.5 * np.log2(r[ok] / c[ok]))
        f = 2.0 ** k
        improve = ok & (k != 0) & (c * f + r / f < BALANCE_FACTOR * (c + r))
        if not np.any(improve):
            break
        f = np.where(improve, f, 1.0)
        A_new = A * f[None, :] / f[:, None]
        a2 = np.abs(A_new) ** 2
        c_new, r_new = np.sqrt(np.sum(a2, axis=0)), np.sqrt(np.sum(a2, axis=1))
        total_new = float(np.sum(c_new + r_new))
        if not total_new < total:
            break
        A, t, c, r = A_new, t * f, c_new, r_new
        if total_new > BALANCE_PROGRESS * total:
            break
        total = total_new
    return A, t


def qr_r(A) -> np.ndarray:
    """Return R (k, k) of the thin QR of A (N, k), N >= k (LAPACK dgeqrf through numpy; Q not formed)."""
    return np.linalg.qr(A, mode='r')


def solve_triangular(R, B) -> np.ndarray:
    """
    Solve R X = B for X, R (k, k) upper triangular, B (k,) or (k, m); LinAlgError when R is singular.

    numpy's LU solve: on an upper triangular matrix partial pivoting finds every pivot on the diagonal (the entries
    below it are zero), so no row is swapped and the solve is back substitution, as LAPACK's dtrtrs does.
    """
    R = np.asarray(R)
    if R.size and not np.all(np.diag(R) != 0):
        raise np.linalg.LinAlgError('singular triangular matrix')
    return np.linalg.solve(R, B)


__all__ = ['expm', 'balance', 'qr_r', 'solve_triangular']
