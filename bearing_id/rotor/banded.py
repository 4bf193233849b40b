"""
Stacks of dynamic-stiffness systems solved in their band.

A rotor's finite-element dynamic stiffness couples each node's DOFs only with its neighbours': with the DOFs numbered
node by node (:mod:`bearing_id.conventions`) its nonzeros lie within 2 x DOF_PER_NODE - 1 = 7 places of the
diagonal, and a bearing (one node's DOFs), a crack (one element's) or a pedestal in series with a film stays there.
LAPACK's banded LU with partial pivoting (``scipy.linalg.solve_banded``, gbsv) then costs O(N (l + u)^2) instead of
the dense O(N^3): for 150 systems of 224 DOFs (an imported compressor) about 8x less than numpy's stacked dense
solve.  :func:`solve_stack` measures the band of the stack's nonzeros and uses it where it pays (at least
``BAND_MIN_N`` DOFs and a band at most a quarter of them), numpy's stacked dense solve otherwise.  Either is a
backward-stable LU solve; they differ by rounding (of order the condition number times the machine epsilon).
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import solve_banded

BAND_MIN_N = 96          # below this many DOFs the stacked dense solve is as fast (per-system call overhead)


def band_of(Z: np.ndarray) -> tuple[int, int]:
    """Return (l, u): the lower and upper bandwidth of the union of the nonzeros of ``Z`` (n, N, N) or (N, N)."""
    nz = np.any(Z != 0, axis=0) if Z.ndim == 3 else Z != 0
    i, j = np.nonzero(nz)
    if not i.size:
        return 0, 0
    return int(max((i - j).max(), 0)), int(max((j - i).max(), 0))


def solve_stack(Z: np.ndarray, B: np.ndarray) -> np.ndarray:
    """
    Return X (n, N, m) with Z[k] X[k] = B[k] for a stack ``Z`` (n, N, N) and right-hand sides ``B`` (n, N, m).

    Raises ``numpy.linalg.LinAlgError`` for a singular system, as ``numpy.linalg.solve`` does.
    """
    n, N = Z.shape[0], Z.shape[-1]
    if N < BAND_MIN_N or n == 0:
        return np.linalg.solve(Z, B)
    lo, up = band_of(Z)
    width = lo + up + 1
    if 4 * width > N:
        return np.linalg.solve(Z, B)
    dtype = np.result_type(Z, B)
    ab = np.zeros((n, width, N), dtype)            # ab[:, up + i - j, j] = Z[:, i, j]
    for r in range(width):
        off = up - r                               # the diagonal j - i = off
        d = np.diagonal(Z, offset=off, axis1=1, axis2=2)
        if off >= 0:
            ab[:, r, off:] = d
        else:
            ab[:, r, :N + off] = d
    out = np.empty(B.shape, dtype)
    for k in range(n):
        out[k] = solve_banded((lo, up), ab[k], B[k], overwrite_ab=True, check_finite=False)
    return out


__all__ = ['solve_stack', 'band_of', 'BAND_MIN_N']
