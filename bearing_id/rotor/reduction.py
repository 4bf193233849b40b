"""
Reduced-order rotor models for the Kalman filter: Craig-Bampton, the kept DOFs physical.

Why
    The paper method solves a discrete Riccati equation on the 2 ndof states of the FE rotor per speed and noise level;
    its cost grows as n^3 (8 ms at 10 elements, ~25 s per equation at 160).  The filter only has to represent the rotor
    between the DOFs it reads (the probes), the DOFs it estimates and where the bearings act (the bearing nodes, their
    pedestals and any known element), and where the known excitation enters.

Craig-Bampton (Craig & Bampton 1968) on the rotor WITHOUT bearings
    DOFs split into kept (boundary) b and interior i.  q = T [q_b; eta] with
    T = [[I, 0], [Psi, Phi_k]] (rows in b, i order), Psi = -K_ii^-1 K_ib the static constraint modes and Phi_k the
    first k fixed-interface modes (K_ii phi = w^2 M_ii phi, mass-normalised).  The rotor's M, K, damping C and
    gyroscopic G are projected: X_r = T^T X T; everything that acts on kept DOFs (bearing films, pedestals, known
    elements, forces at kept DOFs) is exact in the reduced coordinates, because T's rows at kept DOFs are unit rows.
    Interior DOFs are reconstructed by T (e.g. a probe at an interior node: H_r = H T).

Truncation error (reported, never assumed small)
    :func:`receptance_error`: max relative error of the 1X receptance between kept DOFs (Z^-1 restricted to the kept
    DOFs, with the bearings at a speed) of the reduced against the full model -- what the Kalman filter's steady 1X
    transfer is built on.  The identification reports it per speed next to the results.

The basis uses the non-rotating K and M (speed independent, built once); gyroscopics and damping are projected onto
it (the usual rotordynamic Craig-Bampton).  SI units; DOF numbering of :mod:`bearing_id.conventions`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.linalg as sla

from .assembly import add_known, bearing_matrices, dynamic_stiffness, first_order
from ..conventions import dof_index


@dataclass
class ReducedRotor:
    """
    A Craig-Bampton reduced rotor (build with :func:`craig_bampton`).

    full : the RotorModel reduced.  T (ndof, nr): q = T q_r.  L (nr, ndof): the left inverse L T = I that reads the
    kept DOFs directly and the modal coordinates as eta = Phi_k^T M_ii (q_i - Psi q_b) (the map of a full-state
    quantity, e.g. the process noise, into reduced coordinates).  kept (nk,) full DOF indices kept physical, in the
    order of q_r[:nk].  M, K, C, G (nr, nr): T^T X T of the rotor without bearings.  mode_hz (k,): fixed-interface
    natural frequencies kept [Hz]; cutoff_hz: the cutoff used (NaN when the count was given).
    """

    full: object
    T: np.ndarray
    L: np.ndarray
    kept: np.ndarray
    M: np.ndarray
    K: np.ndarray
    C: np.ndarray
    G: np.ndarray
    mode_hz: np.ndarray
    cutoff_hz: float = float('nan')
    _base: dict = field(default_factory=dict, repr=False)

    @property
    def nr(self) -> int:
        """Reduced DOFs (kept + modal)."""
        return self.T.shape[1]

    @property
    def n_modes(self) -> int:
        return self.mode_hz.size

    @property
    def bearing_nodes(self) -> tuple:
        return tuple(self.full.bearing_nodes)

    @cached_property
    def Minv(self) -> np.ndarray:
        return np.linalg.inv(self.M)

    @cached_property
    def _kept_pos(self) -> dict:
        return {int(d): i for i, d in enumerate(self.kept)}

    def kept_index(self, full_dof: int) -> int:
        """Index in q_r of a kept full DOF (ValueError for an interior DOF)."""
        try:
            return self._kept_pos[int(full_dof)]
        except KeyError:
            raise ValueError(f'DOF {full_dof} is not kept by this reduction') from None

    def reduce_rows(self, S) -> np.ndarray:
        """Rows over the full DOFs (k, ndof) -> rows over q_r (k, nr): S T."""
        return np.asarray(S, dtype=float) @ self.T

    def reduce_covariance(self, Q) -> np.ndarray:
        """
        Map a process noise of the full states [q; q'] to the reduced states: blkdiag(L, L) Q blkdiag(L, L)^T.

        Q: scalar q (q I), vector (diagonal) or (2 ndof, 2 ndof); returns (2 nr, 2 nr).

        With every fixed-interface mode kept (T square) the reduced filter is then the full filter in other
        coordinates; truncation drops only the noise on the discarded modes.
        """
        n, nr = self.full.ndof, self.nr
        Lb = np.zeros((2 * nr, 2 * n))
        Lb[:nr, :n] = self.L
        Lb[nr:, n:] = self.L
        Q = np.asarray(Q, dtype=float)
        if Q.ndim == 0:
            return float(Q) * (Lb @ Lb.T)
        if Q.ndim == 1:
            return (Lb * Q[None, :]) @ Lb.T
        return Lb @ Q @ Lb.T

    def project(self, X) -> np.ndarray:
        """T^T X T of a full (ndof, ndof) matrix; a sparse X (bearing blocks) through its non-zero rows/columns."""
        X = np.asarray(X, dtype=float)
        rows = np.flatnonzero(np.any(X != 0, axis=1))
        cols = np.flatnonzero(np.any(X != 0, axis=0))
        if rows.size == 0:
            return np.zeros((self.nr, self.nr))
        return self.T[rows].T @ X[np.ix_(rows, cols)] @ self.T[cols]

    def _base_matrices(self, speed: float):
        """(C_r + speed G_r + known elements' C, K_r + known elements' K) at ``speed`` [rad/s] (cached per speed)."""
        key = float(speed)
        out = self._base.get(key)
        if out is None:
            C = self.C + key * self.G
            K = self.K.copy()
            if getattr(self.full, 'known', ()):
                nd = self.full.ndof
                Kk, Ck = np.zeros((nd, nd)), np.zeros((nd, nd))
                add_known(self.full, Kk, Ck, key)
                K = K + self.project(Kk)
                C = C + self.project(Ck)
            out = self._base[key] = (C, K)
            if len(self._base) > 64:
                self._base.pop(next(iter(self._base)))
        return out

    def system_matrices(self, speed: float, coeffs: dict):
        """(M_r, C_r, K_r) of the reduced rotor on bearings ``coeffs`` {node: (K, C)} at ``speed`` [rad/s]."""
        C0, K0 = self._base_matrices(speed)
        Kb, Cb = bearing_matrices(self.full, coeffs)
        return self.M, C0 + self.project(Cb), K0 + self.project(Kb)

    def state_space(self, speed: float, coeffs: dict):
        """
        Reduced state space x_r' = A x_r + B f with x_r = [q_r; q_r'] (2 nr) and f the FULL force vector (ndof,).

        B = [0; M_r^-1 T^T] (2 nr, ndof): forces are given on the full DOFs and projected.
        """
        _, C, K = self.system_matrices(speed, coeffs)
        B = np.zeros((2 * self.nr, self.full.ndof))
        B[self.nr:] = self.Minv @ self.T.T
        return first_order(self.Minv, C, K), B

    def dynamic_stiffness(self, speed: float, omega: float, coeffs: dict) -> np.ndarray:
        """Return Z_r = K_r - omega^2 M_r + j omega C_r (nr, nr) complex (as assembly.dynamic_stiffness)."""
        M, C, K = self.system_matrices(speed, coeffs)
        return K - omega * omega * M + 1j * omega * C


def film_and_known_dofs(model) -> list:
    """Full DOF indices where the identified bearings, their pedestals and the known elements act (x, y each)."""
    out = set()
    unit = {n: (np.ones((2, 2)), np.ones((2, 2))) for n in model.bearing_nodes}
    Kb, Cb = bearing_matrices(model, unit)
    out.update(np.flatnonzero(np.any((Kb != 0) | (Cb != 0), axis=1)).tolist())
    if getattr(model, 'known', ()):
        nd = model.ndof
        Kk, Ck = np.zeros((nd, nd)), np.zeros((nd, nd))
        add_known(model, Kk, Ck, 100.0)
        out.update(np.flatnonzero(np.any((Kk != 0) | (Ck != 0), axis=1)).tolist())
    for p in (getattr(model, 'pedestals', None) or {}).values():
        out.update((int(p), int(p) + 1))
    return sorted(out)


def kf_kept_dofs(model, probes=(), forces=(), outputs=()) -> list:
    """
    List the full DOFs a Kalman-filter reduction keeps (sorted indices).

    Bearing films (and pedestals, known elements), the x and y of every probe node, the DOFs where a known force acts
    (non-zero entries of ``forces`` (k, ndof)), and ``outputs`` ((node, 'x'|'y') pairs; default: x, y of every
    bearing node).
    """
    keep = set(film_and_known_dofs(model))
    nn = model.n_nodes
    for p in probes:
        node = p.node if hasattr(p, 'node') else p[0]
        keep.update((dof_index(node, 'x', nn), dof_index(node, 'y', nn)))
    for F in forces:
        keep.update(np.flatnonzero(np.abs(np.asarray(F)) > 0).tolist())
    if not outputs:
        outputs = [(b, d) for b in model.bearing_nodes for d in ('x', 'y')]
    for node, d in outputs:
        keep.add(dof_index(node, d, nn))
    return sorted(int(k) for k in keep)


def craig_bampton(model, kept, *, n_modes: int | None = None, cutoff_hz: float | None = None) -> ReducedRotor:
    """
    Craig-Bampton reduction of ``model`` (a RotorModel) keeping the full DOFs ``kept`` physical.

    Fixed-interface modes: the first ``n_modes``, or all below ``cutoff_hz`` [Hz] (one of the two; neither = none,
    a Guyan reduction).  Raises ValueError when the interior with the kept DOFs fixed is not restrained (K_ii not
    positive definite: keep the translations of at least two bearing nodes).
    """
    nd = model.ndof
    kept = np.array(sorted({int(k) for k in kept}), dtype=int)
    if kept.size == 0 or kept.min() < 0 or kept.max() >= nd:
        raise ValueError(f'kept DOFs must be in 0 ... {nd - 1}')
    inter = np.setdiff1d(np.arange(nd), kept)
    M, K = np.asarray(model.M, dtype=float), np.asarray(model.K, dtype=float)
    Kii = K[np.ix_(inter, inter)]
    Mii = M[np.ix_(inter, inter)]
    try:
        cf = sla.cho_factor(Kii)
    except np.linalg.LinAlgError:
        raise ValueError('the interior is not restrained with the kept DOFs fixed (K_ii singular): keep the x and y '
                         'of at least two bearing nodes') from None
    Psi = -sla.cho_solve(cf, K[np.ix_(inter, kept)])
    if n_modes is not None and cutoff_hz is not None:
        raise ValueError('give n_modes or cutoff_hz, not both')
    if inter.size == 0:
        lam, Phi = np.zeros(0), np.zeros((0, 0))
    elif n_modes is not None:
        k = int(min(max(n_modes, 0), inter.size))
        lam, Phi = sla.eigh(Kii, Mii, subset_by_index=(0, k - 1)) if k else (np.zeros(0), np.zeros((inter.size, 0)))
    elif cutoff_hz is not None:
        wc = (2 * np.pi * float(cutoff_hz)) ** 2
        lam, Phi = sla.eigh(Kii, Mii, subset_by_value=(-np.inf, wc))
    else:
        lam, Phi = np.zeros(0), np.zeros((inter.size, 0))
    T = np.zeros((nd, kept.size + lam.size))
    T[kept, np.arange(kept.size)] = 1.0
    T[np.ix_(inter, np.arange(kept.size))] = Psi
    T[np.ix_(inter, kept.size + np.arange(lam.size))] = Phi
    L = np.zeros((kept.size + lam.size, nd))
    L[np.arange(kept.size), kept] = 1.0
    PtM = Phi.T @ Mii                                       # eta = Phi^T M_ii (q_i - Psi q_b)
    L[np.ix_(kept.size + np.arange(lam.size), inter)] = PtM
    L[np.ix_(kept.size + np.arange(lam.size), kept)] = -PtM @ Psi
    C = np.asarray(model.C, dtype=float)
    G = np.asarray(model.G, dtype=float)
    red = ReducedRotor(model, T, L, kept, T.T @ M @ T, T.T @ K @ T, T.T @ C @ T, T.T @ G @ T,
                       np.sqrt(np.maximum(lam, 0.0)) / (2 * np.pi),
                       float(cutoff_hz) if cutoff_hz is not None else float('nan'))
    red.M = 0.5 * (red.M + red.M.T)
    red.K = 0.5 * (red.K + red.K.T)
    return red


def receptance_error(red: ReducedRotor, speed: float, coeffs: dict, dofs=None, omega: float | None = None) -> float:
    """
    Max relative error of the reduced model's receptance between kept DOFs at ``omega`` (default the 1X, = speed).

    max |H_r - H| / max |H| over the (dofs x dofs) block, H = Z^-1 of the full model on bearings ``coeffs`` at
    ``speed`` [rad/s], H_r the reduced model's; ``dofs`` full DOF indices (default all kept DOFs).
    """
    w = float(speed if omega is None else omega)
    dofs = red.kept if dofs is None else np.asarray(dofs, dtype=int)
    Z = dynamic_stiffness(red.full, speed, w, coeffs)
    E = np.zeros((red.full.ndof, dofs.size), dtype=complex)
    E[dofs, np.arange(dofs.size)] = 1.0
    Hf = np.linalg.solve(Z, E)[dofs]
    ri = np.array([red.kept_index(d) for d in dofs])
    Er = np.zeros((red.nr, dofs.size), dtype=complex)
    Er[ri, np.arange(dofs.size)] = 1.0
    Hr = np.linalg.solve(red.dynamic_stiffness(speed, w, coeffs), Er)[ri]
    return float(np.max(np.abs(Hr - Hf)) / max(np.max(np.abs(Hf)), 1e-300))


__all__ = ['ReducedRotor', 'craig_bampton', 'film_and_known_dofs', 'kf_kept_dofs', 'receptance_error']
