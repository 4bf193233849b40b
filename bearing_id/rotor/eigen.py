"""
Eigenpairs of a large rotor-bearing system without its dense eigen-decomposition: reduced screen, full refinement.

The dense eigenvalues of the 2 ndof state matrix cost O(ndof^3) per speed (~35 ms at 134 DOFs, ~1.3 s at 640): a
Campbell diagram, a critical-speed search or a stability threshold asks for dozens of speeds but only for a few
modes.  :class:`ReducedEigen` (1) screens them on a Craig-Bampton reduction of the rotor
(:func:`bearing_id.rotor.reduction.craig_bampton`, bearing, pedestal and known-element DOFs kept physical,
fixed-interface modes up to a cutoff; the speed-dependent films, pedestals, seals and gyroscopics act on it exactly
or through the projection): all eigenvalues of a ~30-60 state dense problem, then (2) refines each wanted one on
the FULL model by inverse iteration on the sparse pencil A x = lambda B x, A = [[0, I], [-K, -C]],
B = blkdiag(I, M) (the eigenvalues of :func:`bearing_id.rotor.assembly.state_space`'s matrix): one sparse LU at
the shift = the reduced eigenvalue, started from the reduced eigenvector mapped by the reduction, accepted on a
residual check against the pencil, else ARPACK shift-invert decides.  Refined eigenpairs are the full model's
(within LAPACK's error bound of the dense eigenvalues: test/test_stability_fast.py, test/test_modal_fast.py).

The assumption, stated: the modes asked for (the least stable, or the lowest n) are among the reduced model's, i.e.
below the cutoff; the callers check what they can (distinct refined eigenvalues, modes well below the cutoff) and
fall back to the dense solution otherwise.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import eigs, splu

from .assembly import system_matrices
from .reduction import craig_bampton, film_and_known_dofs

ITER_MAX = 30             # inverse iterations per refined eigenvalue before ARPACK takes over
ITER_TOL = 1e-13          # relative change of the eigenvalue estimate at convergence
RESIDUAL_TOL = 1e-8       # and backward error |A x - lambda B x| / (|A x| + |lambda| |B x|) of the eigenpair
MAX_SHIFTS = 3            # re-factorisations at the current estimate when the iteration creeps ...
SHIFT_SETTLED = 1e-4      # ... once consecutive estimates agree to this (relative): the iterate is on one eigenvalue


def least_stable(lam: np.ndarray, n: int) -> np.ndarray:
    """Return the indices of the ``n`` eigenvalues of ``lam`` with Im >= 0 (conjugates follow) and the largest Re."""
    up = np.flatnonzero(lam.imag >= -1e-9 * np.maximum(np.abs(lam), 1.0))
    return up[np.argsort(-lam[up].real)][:n]


class ReducedEigen:
    """
    Reduced screen and full-pencil refinement of the eigenpairs of ``model`` on its bearings (see the module doc).

    ``model`` a RotorModel; ``cutoff_hz`` the highest fixed-interface mode kept in the reduction [Hz].
    """

    def __init__(self, model, cutoff_hz: float):
        self.model = model
        self.cutoff = 2 * math.pi * float(cutoff_hz)          # rad/s
        self.red = craig_bampton(model, film_and_known_dofs(model), cutoff_hz=float(cutoff_hz))
        n = model.ndof
        self.B = sp.block_diag([sp.identity(n, format='csc'), sp.csc_matrix(np.asarray(model.M, dtype=float))],
                               format='csc')

    def reduced(self, speed: float, coeffs: dict, vectors: bool = False):
        """All eigenvalues [1/s] of the reduced state matrix at ``speed`` [rad/s] on ``coeffs`` (and eigenvectors)."""
        A, _ = self.red.state_space(speed, coeffs)
        return np.linalg.eig(A) if vectors else np.linalg.eigvals(A)

    def pencil(self, speed: float, coeffs: dict):
        """Return the full pencil's A = [[0, I], [-K, -C]] (2 ndof, 2 ndof) sparse complex at ``speed`` [rad/s]."""
        _, C, K = system_matrices(self.model, speed, coeffs)
        n = self.model.ndof
        A = np.zeros((2 * n, 2 * n), dtype=complex)      # dense then compressed: ~10x cheaper than sparse bmat
        A[np.arange(n), n + np.arange(n)] = 1.0
        A[n:, :n] = -K
        A[n:, n:] = -C
        return sp.csc_matrix(A)

    def lift(self, v_r: np.ndarray) -> np.ndarray:
        """Map a reduced state vector (2 nr,) to the full state (2 ndof,): [T q_r; T q_r']."""
        nr, T = self.red.nr, self.red.T
        return np.concatenate([T @ v_r[:nr], T @ v_r[nr:]])

    def refine(self, A, lam_r: complex, x0: np.ndarray) -> tuple[complex, np.ndarray]:
        """
        Return the full pencil's eigenpair (lambda [1/s], unit state vector (2 ndof,)) nearest ``lam_r``.

        Inverse iteration from ``x0`` with a sparse LU at a shift 1e-7 |lam_r| off ``lam_r`` (never exactly on an
        eigenvalue); when the estimates have settled (consecutive ones within 1e-4) but still creep -- a reduced
        eigenvalue far from the full one, near others -- the shift moves to the current estimate (at most ``MAX_SHIFTS``
        times: Rayleigh-quotient iteration).  Converged when two iterates agree to 1e-13 |lambda| and the backward error
        is below 1e-8 (it floors at 1e-12 ... 1e-10 on this badly scaled pencil; 2-6 iterations from the reduced
        eigenpair); otherwise ARPACK shift-invert (scipy ``eigs``) decides.
        """
        B = self.B

        def factor(at):
            s = complex(at) + 1e-7 * max(abs(at), 1.0) * (1 + 1j)
            return s, splu((A - s * B).tocsc())

        sig, lu = factor(lam_r)
        x = x0 / np.linalg.norm(x0)
        lam_prev, shifts = None, 0
        for it in range(ITER_MAX):
            y = lu.solve(B @ x)
            mu = np.vdot(x, y)                                # x^H y: Rayleigh quotient of (A - sig B)^-1 B
            lam = sig + 1.0 / mu
            x = y / np.linalg.norm(y)
            step = math.inf if lam_prev is None else abs(lam - lam_prev)
            if step <= ITER_TOL * abs(lam):
                Ax, Bx = A @ x, B @ x                         # residual check against the pencil itself
                if np.linalg.norm(Ax - lam * Bx) <= RESIDUAL_TOL * (np.linalg.norm(Ax) + abs(lam) * np.linalg.norm(Bx)):
                    return complex(lam), x
            elif it >= 2 and shifts < MAX_SHIFTS and step <= SHIFT_SETTLED * abs(lam) \
                    and abs(lam - sig) > 1e3 * 1e-7 * max(abs(lam), 1.0):
                # settled on one eigenvalue but creeping (the reduced estimate lay far from it, near others): move
                # the shift to the estimate (Rayleigh-quotient iteration: converges in a few steps)
                sig, lu = factor(lam)
                shifts += 1
            lam_prev = lam
        vals, vecs = eigs(A, k=2, M=B, sigma=sig, which='LM', tol=0.0)
        k = int(np.argmin(np.abs(vals - sig)))
        return complex(vals[k]), vecs[:, k] / np.linalg.norm(vecs[:, k])


__all__ = ['ReducedEigen', 'least_stable', 'ITER_MAX', 'ITER_TOL', 'RESIDUAL_TOL', 'MAX_SHIFTS']
