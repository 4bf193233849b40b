"""
``direct`` method: output-error fit of both bearings' K and C to the measured 1X phasors through the FE model.

Model (per speed Omega, synchronous excitation, conventions of :mod:`bearing_id.conventions`)::

    Z(beta) q_r = F_r,      Z(beta) = Z_rotor(Omega) + sum_k beta_k dZ_k,      y_r = P_r q_r

``beta`` = the 16 real unknowns (per bearing Kxx Kxy Kyx Kyy [N/m], then Cxx Cxy Cyx Cyy [N s/m]); ``dZ_k`` is a single
entry (1 for a K entry, j Omega for a C entry) at the bearing's (x, y) DOFs; ``F_r`` the known force phasors of run r
(:func:`bearing_id.excitation.harmonic_forces`); ``P_r`` its probe selection.  Z is linear in beta, so the Jacobian is
exact and cheap:  dq/dbeta_k = -Z^-1 dZ_k q.

Fit: weighted least squares on Re and Im of (P q - X) / sigma (sigma = 1-sigma of the measured Re/Im), solved by
Levenberg-Marquardt (scipy's MINPACK lmder; scipy's trf when there are fewer equations than unknowns)
from the theory, in scaled unknowns theta = beta / s (s = the largest |entry| of the
theory block: the problem is then well conditioned in the parameters).  Optional Gaussian prior toward the theory:
``prior_weight`` w adds rows sqrt(w) (theta - theta_theory), i.e. a prior 1-sigma of s / sqrt(w) per coefficient
(w = 4: 50 % of the block scale; w = 0: no prior).

What the data determine: the data-only information matrix I = J^T J (J the weighted Jacobian in theta at the
solution) is analysed by SVD.  ``rank`` counts singular values of J above 1e-8 x the largest; ``condition`` is
s_max / s_min of J (inf when rank deficient).  A coefficient is estimable when its unit vector lies in the row space
of J (its leakage into the numerical null space < 1e-6); its data-only variance is then the diagonal of the
pseudo-inverse of I.  ``determined`` is the one rule of :mod:`bearing_id.identify.determined` (shared by every method):
estimable, |value| >= 3 x its data-only 1-sigma, and -- with a prior -- the prior's pull 1 - var_post / var_data
<= 0.1.  (Until issue 11 the rule was "1-sigma <= 10 % of the block scale", which passed values smaller than their
own sigma; ``max_rel_std`` is now an optional *additional* bound, off by default.)  Std: without prior, the
pseudo-inverse of I for estimable coefficients, NaN for the others; with a prior, the posterior (I + I_prior)^-1.
Both come from the measured 1X std (``X_std``).

Nonlinearity (profile check): the model is nonlinear in beta (Z^-1), and where the data constrain a coefficient only
weakly the chi2 valley is curved: the linearised sigma can then be several times too small (an unbalance plan
with probes at nodes 3, 6, 9 gave estimates 5-12 linearised sigma from the truth while the truth's chi2 was only
~20 above the minimum).  For every coefficient that passes the rule, the chi2 is profiled at value +- 3 sigma (that
coefficient fixed, the others re-fitted, :func:`profile_widening`); a rise below 9 means the real 3-sigma interval is
wider, and the sigma is widened to the profile's (3 sigma / sqrt(rise), the larger side) before the rule is applied
again.  On well-determined coefficients (the force plan) the widening is <= 1.2 (mildly asymmetric intervals).

Misfit: with redundancy (equations > estimable unknowns) the weighted chi2 is tested against the 99.9 % point of
chi-square(equations - rank) (:func:`bearing_id.identify.determined.fit_quality`); on a misfit every std is
multiplied by sqrt(chi2/dof) (Birge) before the rule is applied, the result is flagged ``misfit`` and the note says
the std is still a lower bound.

Redundancy: when the real equations are no more than the estimable unknowns (e.g. the 4-run force plan at one x/y
probe: 16 equations, 16 unknowns) the fit reproduces the data exactly, chi2 is 0 and the residual cannot reveal a
bias in the 1X vectors; the notes say so (``extra['redundancy']`` = equations - rank).
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy.optimize import least_squares
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .determined import fit_quality, judge, prior_pull
from .result import empty_result, IdentResult
from ..conventions import COEFF_ORDER, dof_index
from ..excitation import harmonic_forces
from ..rotor import supports
from ..rotor.assembly import dynamic_stiffness, film_dofs, probe_matrix

RANK_RTOL = 1e-8          # singular values of the weighted Jacobian below this x the largest count as zero
LEAK_TOL = 1e-6           # a coefficient is estimable when |projection of e_k onto the null space| < this
MAX_REL_STD = None        # optional extra bound: 1-sigma < this x the block scale (None = only the one rule)
K_SCALE_DEFAULT = 1e5     # N/m, scale of the K unknowns when no theory is given
C_SCALE_DEFAULT = 1e2     # N s/m


@dataclass
class Case:
    """
    One excitation run at one speed: the data the output-error fit sees.

    F : complex (ndof,) force phasors [N] at the rotor speed (the synchronous component).
    probes : sequence of params.Probe (or (node, direction)), one per channel.
    X : complex (nch,) measured 1X phasors [m].
    X_std : (nch,) 1-sigma of Re X and of Im X [m].
    """

    F: np.ndarray
    probes: tuple
    X: np.ndarray
    X_std: np.ndarray


# ------------------------------------------------------------------------------------------------ parametrisation
def coeffs_to_beta(coeffs: dict, nodes) -> np.ndarray:
    """{node: (K, C)} -> beta (8 nb,) ordered per bearing [Kxx Kxy Kyx Kyy Cxx Cxy Cyx Cyy]."""
    return np.concatenate([np.concatenate([np.asarray(coeffs[n][0], float).reshape(4),
                                           np.asarray(coeffs[n][1], float).reshape(4)]) for n in nodes])


def beta_to_coeffs(beta: np.ndarray, nodes) -> dict:
    """Convert beta (8 nb,) -> {node: (K (2,2), C (2,2))}."""
    beta = np.asarray(beta, float)
    return {int(n): (beta[8 * i:8 * i + 4].reshape(2, 2).copy(), beta[8 * i + 4:8 * i + 8].reshape(2, 2).copy())
            for i, n in enumerate(nodes)}


def default_scale(nodes, theory: dict | None = None) -> np.ndarray:
    """Scale s (8 nb,) of the unknowns: max |entry| of each theory block (K or C per bearing), else 1e5 / 1e2."""
    s = []
    for n in nodes:
        for j, default in ((0, K_SCALE_DEFAULT), (1, C_SCALE_DEFAULT)):
            v = default
            if theory is not None and n in theory:
                m = float(np.max(np.abs(theory[n][j])))
                if m > 0 and math.isfinite(m):
                    v = m
            s.extend([v] * 4)
    return np.asarray(s)


def _bearing_dofs(model, nodes) -> np.ndarray:
    return np.array([[dof_index(n, 'x', model.n_nodes), dof_index(n, 'y', model.n_nodes)] for n in nodes])


# ------------------------------------------------------------------------------------------------ forward model
def response_and_jacobian(model, speed: float, cases, beta: np.ndarray, nodes, *, Z0=None):
    """
    Predicted probe phasors and their derivatives w.r.t. beta at one speed.

    Parameters
    ----------
    model
        rotor.assembly.RotorModel (no bearings).
    speed
        rad/s (the excitation frequency is the speed: 1X).
    cases
        list of :class:`Case`.
    beta
        (8 nb,) bearing coefficients in SI (see :func:`coeffs_to_beta`).
    nodes
        1-based bearing nodes (nb,).
    Z0
        optional precomputed rotor dynamic stiffness at this speed.

    Returns
    -------
    y : list of complex (nch_r,) predicted phasors [m];  dy : list of complex (nch_r, 8 nb) d y / d beta.

    """
    if Z0 is None:
        Z0 = dynamic_stiffness(model, speed, speed, {})
    Z = Z0.copy()
    bd = _bearing_dofs(model, nodes)
    peds = [film_dofs(model, n)[1] for n in nodes]           # pedestal x DOF per bearing or None
    w = speed
    for i in range(len(nodes)):
        a = bd[i]
        blk = beta[8 * i:8 * i + 4].reshape(2, 2) + 1j * w * beta[8 * i + 4:8 * i + 8].reshape(2, 2)
        Z[np.ix_(a, a)] += blk
        if peds[i] is not None:                               # film in series with a pedestal: acts on q_a - q_p
            p = np.array([peds[i], peds[i] + 1])
            Z[np.ix_(p, p)] += blk
            Z[np.ix_(a, p)] -= blk
            Z[np.ix_(p, a)] -= blk
    flat = bd.reshape(-1)                                     # (2 nb,) bearing DOFs
    E = np.zeros((Z.shape[0], flat.size), dtype=complex)
    E[flat, np.arange(flat.size)] = 1.0
    for i, j in enumerate(peds):
        if j is not None:
            E[[j, j + 1], [2 * i, 2 * i + 1]] = -1.0
    F = np.stack([np.asarray(c.F, dtype=complex) for c in cases], axis=1)
    sol = np.linalg.solve(Z, np.concatenate([F, E], axis=1))  # q for every run, Z^-1 columns at bearing DOFs
    Q, Ginv = sol[:, :F.shape[1]], sol[:, F.shape[1]:]
    ys, dys = [], []
    for r, c in enumerate(cases):
        P = probe_matrix(model, c.probes)
        q = Q[:, r]
        PG = P @ Ginv                                         # (nch, 2 nb)
        d = np.zeros((P.shape[0], 8 * len(nodes)), dtype=complex)
        for i in range(len(nodes)):
            qb = q[bd[i]]                                     # (2,) bearing-node displacement (film deflection)
            if peds[i] is not None:
                qb = qb - q[peds[i]:peds[i] + 2]
            for row in range(2):
                col_g = PG[:, 2 * i + row]
                for col in range(2):
                    k = 2 * row + col
                    d[:, 8 * i + k] = -col_g * qb[col]
                    d[:, 8 * i + 4 + k] = -col_g * qb[col] * (1j * w)
        ys.append(P @ q)
        dys.append(d)
    return ys, dys


SPARSE_NDOF = 200         # above this many DOFs :class:`SpeedResponse` factorises Z with a sparse LU (splu)
WOODBURY_COND = 1e10      # above this condition of the m x m capacitance :class:`SpeedResponse` re-factorises


def _film_blocks(model, nodes):
    """(bearing DOFs (nb, 2), pedestal x DOF per bearing or None, S: the DOFs beta acts on, position of each in S)."""
    bd = _bearing_dofs(model, nodes)
    peds = [film_dofs(model, n)[1] for n in nodes]
    S = []
    for i in range(len(nodes)):
        S += [int(bd[i, 0]), int(bd[i, 1])]
        if peds[i] is not None:
            S += [int(peds[i]), int(peds[i]) + 1]
    S = list(dict.fromkeys(S))
    pos = {d: k for k, d in enumerate(S)}
    return bd, peds, np.array(S, dtype=int), pos


class SpeedResponse:
    """
    Fast :func:`response_and_jacobian` at one speed: one factorisation per speed, Woodbury updates in beta.

    Z(beta) = Z_ref + P_S D(beta - beta_ref) P_S^T, where S are the m DOFs the films act on (bearing nodes and their
    pedestals, m <= 4 nb) and D (m, m) is linear in beta.  Z_ref = Z(beta_ref) is factorised once (sparse LU above
    :data:`SPARSE_NDOF` DOFs -- the FE dynamic stiffness is banded apart from the pedestal rows; dense below) and
    W = Z_ref^-1 [F, P_S] computed once; then for any beta, with H = (Z_ref^-1)_SS and
    K = (I + D H)^-1 D (m x m), Z^-1 X = Z_ref^-1 X - W_S K (Z_ref^-1 X)_S (Sherman-Morrison-Woodbury), and only
    the probe rows and the S rows of it are formed.  Per call: O(nch m + m^3) instead of a dense (ndof, ndof) solve.
    Equal to :func:`response_and_jacobian` (the reference) to 1e-9 relative (test/test_direct_fast.py); when the
    capacitance I + D H is ill-conditioned (cond > :data:`WOODBURY_COND`, beta far from beta_ref) it re-factorises at
    that beta.
    """

    def __init__(self, model, speed: float, cases, nodes, beta_ref, *, Z0=None, sparse: bool | None = None):
        self.model, self.speed, self.cases = model, float(speed), list(cases)
        self.nodes = tuple(int(n) for n in nodes)
        self.Z0 = dynamic_stiffness(model, speed, speed, {}) if Z0 is None else Z0
        self.sparse = (self.Z0.shape[0] > SPARSE_NDOF) if sparse is None else bool(sparse)
        self.bd, self.peds, self.S, self.pos = _film_blocks(model, self.nodes)
        nb, m = len(self.nodes), self.S.size
        Es = np.zeros((m, 2 * nb))                            # E = P_S Es: bearing-node columns, minus the pedestal
        for i in range(nb):
            for r in range(2):
                Es[self.pos[int(self.bd[i, r])], 2 * i + r] = 1.0
                if self.peds[i] is not None:
                    Es[self.pos[int(self.peds[i]) + r], 2 * i + r] = -1.0
        self.Es = Es
        self.F = np.stack([np.asarray(c.F, dtype=complex) for c in self.cases], axis=1)
        self.P = [probe_matrix(model, c.probes) for c in self.cases]
        # D(dbeta) is linear: its (m m, 8 nb) complex matrix, built column by column from D() itself
        self._Dmap = self._d_map()
        # positions in S of each bearing's (x, y) and of its pedestal's (or of the bearing's again: no pedestal)
        self._qa = np.array([[self.pos[int(self.bd[i, r])] for r in range(2)] for i in range(nb)])
        self._qp = np.array([[self.pos[int(self.peds[i]) + r] for r in range(2)] if self.peds[i] is not None
                             else [-1, -1] for i in range(nb)])
        self._has_ped = bool(np.any(self._qp >= 0))
        self._factor(np.asarray(beta_ref, float))

    def D(self, dbeta) -> np.ndarray:
        """Return the (m, m) complex change of Z on S for a change ``dbeta`` (8 nb,) of the coefficients."""
        m = self.S.size
        D = np.zeros((m, m), dtype=complex)
        w = self.speed
        for i in range(len(self.nodes)):
            blk = dbeta[8 * i:8 * i + 4].reshape(2, 2) + 1j * w * dbeta[8 * i + 4:8 * i + 8].reshape(2, 2)
            a = [self.pos[int(d)] for d in self.bd[i]]
            D[np.ix_(a, a)] += blk
            if self.peds[i] is not None:
                p = [self.pos[int(self.peds[i])], self.pos[int(self.peds[i]) + 1]]
                D[np.ix_(p, p)] += blk
                D[np.ix_(a, p)] -= blk
                D[np.ix_(p, a)] -= blk
        return D

    def _d_map(self) -> np.ndarray:
        """Return the (m m, 8 nb) complex matrix of the linear map dbeta -> D(dbeta).ravel() (:meth:`D`)."""
        m, nb = self.S.size, len(self.nodes)
        out = np.zeros((m, m, 8 * nb), dtype=complex)
        for i in range(nb):
            a = [self.pos[int(d)] for d in self.bd[i]]
            p = None if self.peds[i] is None else [self.pos[int(self.peds[i])], self.pos[int(self.peds[i]) + 1]]
            for r in range(2):
                for c in range(2):
                    for k, unit in ((8 * i + 2 * r + c, 1.0), (8 * i + 4 + 2 * r + c, 1j * self.speed)):
                        out[a[r], a[c], k] += unit
                        if p is not None:
                            out[p[r], p[c], k] += unit
                            out[a[r], p[c], k] -= unit
                            out[p[r], a[c], k] -= unit
        return out.reshape(m * m, 8 * nb)

    def _capacitance(self, beta):
        """Return (H, K = (I + D H)^-1 D) at ``beta``, or None when I + D H is too ill-conditioned (re-factorise)."""
        nr, m = self.nr, self.S.size
        D = (self._Dmap @ (beta - self.beta_ref)).reshape(m, m)
        H = self.WS[:, nr:]
        cap = np.eye(m) + D @ H
        try:
            ci = np.linalg.inv(cap)
        except np.linalg.LinAlgError:
            return None
        # cond_2 <= ||cap||_F ||cap^-1||_F: only a bound above WOODBURY_COND needs the exact condition (same decision)
        if np.linalg.norm(cap) * np.linalg.norm(ci) > WOODBURY_COND and np.linalg.cond(cap) > WOODBURY_COND:
            return None
        return H, np.linalg.solve(cap, D)

    def _factor(self, beta_ref) -> None:
        self.beta_ref = beta_ref.copy()
        Z = self.Z0.astype(complex, copy=True)
        S = self.S
        Z[np.ix_(S, S)] += self.D(beta_ref)
        nr, m = self.F.shape[1], S.size
        rhs = np.zeros((Z.shape[0], nr + m), dtype=complex)
        rhs[:, :nr] = self.F
        rhs[S, nr + np.arange(m)] = 1.0
        if self.sparse:
            try:
                W = splu(sp.csc_matrix(Z)).solve(rhs)
            except RuntimeError as e:                        # 'Factor is exactly singular': as the dense solve
                raise np.linalg.LinAlgError(str(e)) from None
        else:
            W = np.linalg.solve(Z, rhs)
        self.nr = nr
        self.WS = W[S]                                        # (m, nr + m): rows at S of Z_ref^-1 [F, P_S]
        self.PW = [P @ W for P in self.P]                     # (nch_r, nr + m) each
        sel = np.zeros((nr + m, nr + 2 * len(self.nodes)))   # [Z_ref^-1 F, Z_ref^-1 E] from [.. F, .. P_S]
        sel[:nr, :nr] = np.eye(nr)
        sel[nr:, nr:] = self.Es
        self._sel = sel
        self._XS = self.WS @ sel                              # (m, nr + 2 nb) rows at S of Z_ref^-1 [F, E]
        self._PWsel = [PW @ sel for PW in self.PW]
        if len({PW.shape[0] for PW in self.PW}) == 1:
            self._PWsel_st = np.stack(self._PWsel)            # (nr, nch, nr + 2 nb)
            self._PWm_st = np.stack([PW[:, nr:] for PW in self.PW])      # (nr, nch, m)

    def __call__(self, beta):
        """Return (ys, dys) as :func:`response_and_jacobian` at ``beta`` (8 nb,)."""
        beta = np.asarray(beta, float)
        nr, nb = self.nr, len(self.nodes)
        hk = self._capacitance(beta)
        if hk is None:
            self._factor(beta)
            return self(beta)
        H, Kc = hk                                            # H = (Z_ref^-1)_SS, Kc = (I + D H)^-1 D
        XS = self._XS                                         # (m, nr + 2 nb) rows at S of Z_ref^-1 [F, E]
        corr = Kc @ XS
        XS_new = XS - H @ corr                                # rows at S of Z^-1 [F, E]
        qS = XS_new[:, :nr]                                   # (m, nr)
        qb = qS[self._qa]                                     # (nb, 2, nr) film deflections at the bearings
        if self._has_ped:
            qb = qb - np.where((self._qp >= 0)[:, :, None], qS[np.maximum(self._qp, 0)], 0.0)
        jw = 1j * self.speed
        ys, dys = [], []
        for r, PW in enumerate(self.PW):
            PX = self._PWsel[r] - PW[:, nr:] @ corr           # (nch, nr + 2 nb): P Z^-1 [F, E]
            PG = PX[:, nr:].reshape(-1, nb, 2, 1)
            blockk = -(PG * qb[None, :, None, :, r]).reshape(PG.shape[0], nb, 4)
            d = np.concatenate([blockk, blockk * jw], axis=2).reshape(PG.shape[0], 8 * nb)
            ys.append(PX[:, r])
            dys.append(d)
        return ys, dys

    def stacked(self, beta):
        """
        Return :meth:`__call__` stacked over the runs: ys complex (nr, nch), dys complex (nr, nch, 8 nb).

        All runs must have the same number of channels (:attr:`uniform`); the same numbers, fewer array operations.
        """
        beta = np.asarray(beta, float)
        nr, nb = self.nr, len(self.nodes)
        hk = self._capacitance(beta)
        if hk is None:
            self._factor(beta)
            return self.stacked(beta)
        H, Kc = hk
        corr = Kc @ self._XS
        qS = (self._XS - H @ corr)[:, :nr]
        qb = qS[self._qa]                                     # (nb, 2, nr)
        if self._has_ped:
            qb = qb - np.where((self._qp >= 0)[:, :, None], qS[np.maximum(self._qp, 0)], 0.0)
        PX = self._PWsel_st - self._PWm_st @ corr             # (nr, nch, nr + 2 nb)
        nch = PX.shape[1]
        ys = PX[np.arange(nr), :, np.arange(nr)]              # (nr, nch)
        PG = PX[:, :, nr:].reshape(nr, nch, nb, 2, 1)
        blockk = -(PG * qb.transpose(2, 0, 1)[:, None, :, None, :]).reshape(nr, nch, nb, 4)
        dys = np.empty((nr, nch, nb, 8), dtype=complex)
        dys[..., :4] = blockk
        dys[..., 4:] = blockk * (1j * self.speed)
        return ys, dys.reshape(nr, nch, 8 * nb)

    @property
    def uniform(self) -> bool:
        """All runs have the same number of channels (:meth:`stacked` applies)."""
        return len({P.shape[0] for P in self.P}) == 1


class WeightedStack:
    """
    :func:`weighted_stack` of fixed ``cases`` and ``scale`` on stacked predictions (:meth:`SpeedResponse.stacked`).

    The 1-sigma (:func:`_sigma`) and the measured phasors are formed once; the same numbers as
    :func:`weighted_stack` (the reference; test/test_direct_fast.py).  Needs cases of equal channel count.
    """

    def __init__(self, cases, scale):
        self.X = np.stack([np.asarray(c.X, dtype=complex) for c in cases])      # (nr, nch)
        self.sg = np.stack([_sigma(c) for c in cases])                         # (nr, nch)
        self.scale = np.asarray(scale, dtype=float)

    def __call__(self, ys, dys):
        """Return (r, J) as :func:`weighted_stack` for ys (nr, nch), dys (nr, nch, n)."""
        e = (ys - self.X) / self.sg
        dd = dys * self.scale[None, None, :] / self.sg[:, :, None]
        nr, nch, n = dd.shape
        r = np.empty((nr, 2, nch))
        r[:, 0], r[:, 1] = e.real, e.imag
        J = np.empty((nr, 2, nch, n))
        J[:, 0], J[:, 1] = dd.real, dd.imag
        return r.reshape(-1), J.reshape(-1, n)


AUG_FD_STEP = 1e-6        # central-difference step of the augmented-model Jacobian, in units of the block scale


def response_and_jacobian_augmented(model, speed: float, cases, beta: np.ndarray, nodes, augment, scale):
    """
    Do as :func:`response_and_jacobian` but through an augmented-model hook.

    The hook is ``augment.dynamic_stiffness(speed, omega, coeffs)``; d y / d beta by central differences (step
    ``AUG_FD_STEP`` x ``scale`` per unknown).
    """
    P = [probe_matrix(model, c.probes) for c in cases]
    F = np.stack([np.asarray(c.F, dtype=complex) for c in cases], axis=1)

    def ys_of(b):
        Q = np.linalg.solve(augment.dynamic_stiffness(speed, speed, beta_to_coeffs(b, nodes)), F)
        return [P[r] @ Q[:, r] for r in range(len(cases))]

    ys = ys_of(beta)
    dys = [np.zeros((p.shape[0], beta.size), dtype=complex) for p in P]
    for k in range(beta.size):
        h = AUG_FD_STEP * float(scale[k])
        db = np.zeros_like(beta)
        db[k] = h
        yp, ym = ys_of(beta + db), ys_of(beta - db)
        for r in range(len(cases)):
            dys[r][:, k] = (yp[r] - ym[r]) / (2 * h)
    return ys, dys


# ------------------------------------------------------------------------------------------------ information analysis
def information_analysis(J: np.ndarray):
    """
    SVD analysis of a weighted Jacobian J (m, n): rank, condition, pseudo-inverse information, leakage per unknown.

    Returns dict: rank, condition (inf if rank < n), condition_range (s_max / s_rank: conditioning of what is
    determined), singular (s,), cov_pinv (n, n) = (J^T J)^+, leakage (n,) = norm of e_k's projection on the null space.
    """
    n = J.shape[1]
    if J.shape[0] == 0:
        return {'rank': 0, 'condition': math.inf, 'condition_range': math.inf, 'singular': np.zeros(0),
                'cov_pinv': np.full((n, n), np.nan), 'leakage': np.ones(n)}
    U, s, Vt = np.linalg.svd(J, full_matrices=True)
    smax = s[0] if s.size else 0.0
    rank = int(np.count_nonzero(s > RANK_RTOL * smax)) if smax > 0 else 0
    V = Vt.T
    Vr, V0 = V[:, :rank], V[:, rank:]
    cov = (Vr / s[:rank] ** 2) @ Vr.T if rank else np.zeros((n, n))
    leak = np.linalg.norm(V0, axis=1) if V0.size else np.zeros(n)
    cond = float(smax / s[n - 1]) if rank == n else math.inf
    cond_r = float(smax / s[rank - 1]) if rank else math.inf
    return {'rank': rank, 'condition': cond, 'condition_range': cond_r, 'singular': s, 'cov_pinv': cov, 'leakage': leak}


def _sigma(c: Case) -> np.ndarray:
    X = np.asarray(c.X, dtype=complex)
    s = np.asarray(c.X_std, dtype=float)
    floor = 1e-12 * max(float(np.max(np.abs(X))), 1e-30)
    return np.maximum(np.where(np.isfinite(s), s, np.inf), floor)


def weighted_stack(cases, ys, dys, scale):
    """Weighted real residual (Re and Im of (y - X) / sigma per case) and its Jacobian times ``scale`` (columns)."""
    r, J = [], []
    for c, y, d in zip(cases, ys, dys):
        sg = _sigma(c)
        e = (y - np.asarray(c.X, dtype=complex)) / sg
        dd = d * scale[None, :] / sg[:, None]
        r += [e.real, e.imag]
        J += [dd.real, dd.imag]
    return np.concatenate(r), np.vstack(J)


PROFILE_SIGMAS = 3.0      # the profile check looks at value +- this many linearised sigma


def profile_widening(fun_jac, theta, cov, k: int, chi2_min: float, birge: float = 1.0, *,
                     n_sigma: float = PROFILE_SIGMAS, max_nfev: int = 200) -> float:
    """
    Factor (>= 1) by which the profile chi2 says the linearised 1-sigma of unknown ``k`` is too small.

    fun_jac(theta) -> (weighted residual, Jacobian) of the fit (prior rows included); theta its minimum; cov the
    (Birge-scaled) covariance; chi2_min = |residual|^2 at theta.  Unknown k is fixed at theta_k +- n_sigma sigma_k
    (sigma_k = sqrt(cov_kk)), all the others re-fitted (started at the linear conditional optimum
    theta +- n_sigma cov[:, k] / sigma_k); the rise of chi2 over chi2_min, in units of birge^2, should be n_sigma^2
    for a linear model.  The implied 1-sigma on that side is n_sigma sigma_k / sqrt(rise): the factor returned is
    the larger implied / sigma_k of the two sides (1 when both rise at least as predicted; inf when a side finds
    a chi2 below the minimum or the fit fails).
    """
    theta = np.asarray(theta, float)
    sk = math.sqrt(max(float(cov[k, k]), 0.0))
    if not (sk > 0 and math.isfinite(sk)):
        return math.inf
    n = theta.size
    worst = 1.0
    for sgn in (-1.0, 1.0):
        fixed = theta[k] + sgn * n_sigma * sk

        def f(t):
            return fun_jac(np.insert(t, k, fixed))[0]

        def jac(t):
            return np.delete(fun_jac(np.insert(t, k, fixed))[1], k, axis=1)

        t0 = np.delete(theta + sgn * n_sigma * cov[:, k] / sk, k)
        m = f(t0).size
        try:
            sol = least_squares(f, t0, jac=jac, method='lm' if m >= n - 1 else 'trf', xtol=1e-10, ftol=1e-10,
                                gtol=1e-12, max_nfev=max_nfev)
        except (ValueError, np.linalg.LinAlgError):
            return math.inf
        rise = (2.0 * sol.cost - chi2_min) / birge ** 2
        if not rise > 0:
            return math.inf
        worst = max(worst, n_sigma / math.sqrt(rise))
    return worst


# ------------------------------------------------------------------------------------------------ one speed
def fit_speed(model, speed: float, cases, nodes, *, theory: dict | None = None, start: dict | None = None,
              prior_weight: float = 0.0, scale=None, bearings=None, method_name: str = 'direct',
              max_nfev: int = 200, max_rel_std: float | None = MAX_REL_STD, augment=None,
              profile_check: bool = True, fast: bool = True) -> IdentResult:
    """
    Output-error fit of the 8 nb bearing coefficients at one speed.

    Parameters
    ----------
    model
        RotorModel without bearings.
    speed
        rad/s.
    cases
        list of :class:`Case` (runs at this speed).
    nodes
        1-based bearing nodes.
    theory
        {node: (K, C)} theory (scale, start and prior mean).
    start
        {node: (K, C)} start of the iteration (default: theory).
    prior_weight
        w >= 0; prior 1-sigma = scale / sqrt(w) per coefficient (0 = no prior).
    scale
        (8 nb,) scale of the unknowns (default :func:`default_scale`).
    bearings
        bearing names for the result (default ``bearing1``, ``bearing2``, ...).
    method_name
        the result's method name (default 'direct').
    max_nfev
        evaluation limit of the least-squares fit (and of each profile in the nonlinearity check).
    max_rel_std
        optional extra bound on the 1-sigma relative to the scale (default :data:`MAX_REL_STD`; None = only the
        one rule).
    augment
        augmented-model hook (``dynamic_stiffness(speed, omega, coeffs) -> Z``; e.g. a flexible support in
        series with the film) or None.  With it the prediction is P Z_aug(beta)^-1 F and the Jacobian is taken by
        central differences in the scaled unknowns (relative step 1e-6).
    profile_check
        run the nonlinearity check (profile chi2, module docstring) on the determined coefficients (default True).
    fast
        the forward model through :class:`SpeedResponse` (one factorisation per speed; default True) instead of
        a dense solve per evaluation (:func:`response_and_jacobian`, the reference; False).

    Returns
    -------
    IdentResult (method 'direct'); ``extra`` holds theta covariance, singular values, chi2 and the prior used.

    """
    nodes = tuple(int(n) for n in nodes)
    nb = len(nodes)
    n = 8 * nb
    names = bearings or tuple(f'bearing{i + 1}' for i in range(nb))
    if prior_weight < 0 or not math.isfinite(prior_weight):
        raise ValueError(f'prior_weight must be a finite number >= 0, got {prior_weight!r}')
    if prior_weight > 0 and theory is None:
        raise ValueError('a prior (prior_weight > 0) needs the theory coefficients')
    res = empty_result(speed, method_name, names, nodes)
    cases = [c for c in cases if np.all(np.isfinite(np.asarray(c.X)))]
    if not cases:
        res.notes.append('no finite measurements at this speed')
        return res
    scale = np.asarray(scale if scale is not None else default_scale(nodes, theory), float)
    beta0 = coeffs_to_beta(start if start is not None else theory, nodes) if (start or theory) is not None \
        else np.zeros(n)
    theta0 = beta0 / scale
    theta_p = coeffs_to_beta(theory, nodes) / scale if theory is not None else None
    sw = math.sqrt(prior_weight)
    Z0 = dynamic_stiffness(model, speed, speed, {})
    fast_rj = SpeedResponse(model, speed, cases, nodes, beta0, Z0=Z0) if fast and augment is None else None

    def rj(beta):
        if fast_rj is not None:
            return fast_rj(beta)
        return response_and_jacobian(model, speed, cases, beta, nodes, Z0=Z0)

    stack = WeightedStack(cases, scale) if fast_rj is not None and fast_rj.uniform else None

    def fun_jac(theta):
        if augment is not None:
            ys, dys = response_and_jacobian_augmented(model, speed, cases, theta * scale, nodes, augment, scale)
        elif stack is not None:
            ys, dys = fast_rj.stacked(theta * scale)
        else:
            ys, dys = rj(theta * scale)
        r, J = stack(ys, dys) if stack is not None and augment is None else weighted_stack(cases, ys, dys, scale)
        if sw > 0:
            r = np.concatenate([r, sw * (theta - theta_p)])
            J = np.vstack([J, sw * np.eye(n)])
        return r, J

    cache = {}

    def f(theta):
        cache['rj'] = fun_jac(theta)
        cache['x'] = theta.copy()
        return cache['rj'][0]

    def jac(theta):
        if 'x' not in cache or not np.array_equal(cache['x'], theta):
            f(theta)
        return cache['rj'][1]

    m = f(theta0).size
    sol = least_squares(f, theta0, jac=jac, method='lm' if m >= n else 'trf', x_scale=1.0, xtol=1e-12, ftol=1e-12,
                        gtol=1e-12, max_nfev=max_nfev)
    theta = sol.x
    beta = theta * scale
    ys, dys = (response_and_jacobian_augmented(model, speed, cases, beta, nodes, augment, scale)
               if augment is not None else rj(beta))
    r_data, J_data = weighted_stack(cases, ys, dys, scale)
    info = information_analysis(J_data)
    redundancy = int(r_data.size - info['rank'])
    dof = max(redundancy, 1)
    chi2 = float(r_data @ r_data)
    fq = fit_quality(chi2, redundancy)
    estimable = info['leakage'] < LEAK_TOL
    var_data = np.where(estimable, np.clip(np.diag(info['cov_pinv']), 0, None), np.inf)
    if sw > 0:
        cov_theta = np.linalg.inv(J_data.T @ J_data + prior_weight * np.eye(n))
        var_post = np.diag(cov_theta)
        pull = prior_pull(var_post, var_data)
        std_theta = np.sqrt(var_post)
    else:
        cov_theta = info['cov_pinv']
        pull = None
        std_theta = np.where(estimable, np.sqrt(var_data), np.nan)
    if fq.misfit:              # Birge: the residual shows more noise than the stated 1X std
        cov_theta = cov_theta * fq.birge ** 2
        std_theta = std_theta * fq.birge
    sigma_data = np.sqrt(var_data) * fq.birge * scale       # data-only 1-sigma in SI (inf where not estimable)
    veto = None
    if max_rel_std is not None:
        veto = ~(np.sqrt(var_data) * fq.birge < float(max_rel_std))
    labels = [f'{names[i]}.{sym}{lab}' for i in range(nb) for sym in ('K', 'C') for lab in COEFF_ORDER]
    verdict = judge(theta * scale, sigma_data, estimable=estimable, pull=pull, veto=veto)
    # nonlinearity: the linearised sigma must describe the 3-sigma interval (profile chi2, module docstring)
    widen = np.ones(n)
    cand = np.nonzero(verdict.determined)[0]
    if cand.size and profile_check:
        chi2_tot = float(np.sum(fun_jac(theta)[0] ** 2))
        for k in cand:
            widen[k] = profile_widening(fun_jac, theta, cov_theta, k, chi2_tot, fq.birge, max_nfev=max_nfev)
        if np.any(widen > 1.0):
            std_theta = std_theta * widen
            cov_theta = cov_theta * np.outer(widen, widen)
            sigma_data = sigma_data * widen
            verdict = judge(theta * scale, sigma_data, estimable=estimable, pull=pull, veto=veto)
    determined = verdict.determined
    std = std_theta * scale
    num = math.sqrt(sum(float(np.sum(np.abs(y - c.X) ** 2)) for c, y in zip(cases, ys)))
    den = math.sqrt(sum(float(np.sum(np.abs(c.X) ** 2)) for c in cases))
    for i in range(nb):
        res.K[i] = beta[8 * i:8 * i + 4].reshape(2, 2)
        res.C[i] = beta[8 * i + 4:8 * i + 8].reshape(2, 2)
        res.K_std[i] = std[8 * i:8 * i + 4].reshape(2, 2)
        res.C_std[i] = std[8 * i + 4:8 * i + 8].reshape(2, 2)
        res.K_determined[i] = determined[8 * i:8 * i + 4].reshape(2, 2)
        res.C_determined[i] = determined[8 * i + 4:8 * i + 8].reshape(2, 2)
    res.rank, res.unknowns, res.condition = info['rank'], n, info['condition']
    res.residual = num / den if den > 0 else math.nan
    res.notes.append(f'direct output-error fit: {len(cases)} run(s), {r_data.size} real equations, rank '
                     f"{info['rank']} of {n}; " + fq.summary())
    if redundancy <= 0:
        res.notes.append(f"no redundancy: {r_data.size} real equations for {info['rank']} estimable unknowns, so "
                         f'the fit reproduces the data exactly and its residual cannot reveal a bias in the 1X '
                         f'vectors or a model error; the std rests entirely on the stated 1X std (add a probe or a '
                         f'run to make the residual a check)')
    vn = verdict.note(labels)
    if vn:
        res.notes.append(vn + ('; values of undetermined coefficients are prior-dominated' if sw > 0 else
                               "; values of undetermined coefficients are not the data's (start / minimum norm)"))
    if np.any(widen > 1.05):
        res.notes.append(f'nonlinearity: the profile chi2 at +-{PROFILE_SIGMAS:g} sigma of {int(np.sum(widen > 1.05))} '
                         f'coefficient(s) rose less than the linearised fit predicts; their 1-sigma were widened to '
                         f"the profile's (by up to x{np.max(widen):.2g}) before the rule was applied")
    if fq.misfit:
        res.notes.append(fq.misfit_note('the FE rotor model with linear bearings'
                                        + (' (augmented)' if augment is not None else '')))
        res.set_flag('misfit')
    if not sol.success:
        res.notes.append(f'least_squares did not converge: {sol.message}')
    res.extra.update(theta=theta, scale=scale, cov_theta=cov_theta, singular=info['singular'],
                     condition_range=info['condition_range'], leakage=info['leakage'], chi2=chi2, dof=dof,
                     prior_weight=prior_weight, theory=theory, nfev=sol.nfev, redundancy=redundancy,
                     fit_quality=fq, verdict=verdict, prior_pull=pull, profile_widening=widen)
    return res


# ------------------------------------------------------------------------------------------------ all speeds
def cases_from_data(model, data, probes, runs, i_speed: int, augment=None) -> list[Case]:
    """
    Return the :class:`Case` list of speed index ``i_speed`` from harmonic data (X (nr, ns, nch), X_std alike).

    ``augment`` : augmented-model hook; its ``extra_forces(speed)[1.0]`` (a residual unbalance, a bow: the same
    machine in every run) is added to every run's known synchronous force.
    """
    W = float(data.speeds[i_speed])
    extra = augment.extra_forces(W).get(1.0) if augment is not None else None
    out = []
    for r, run in enumerate(runs):
        X = np.asarray(data.X[r, i_speed], dtype=complex)
        if not np.all(np.isfinite(X)):
            continue
        F = harmonic_forces(run.excitation, W, model.n_nodes, model.ndof).get(1.0)
        if extra is not None:
            F = extra.copy() if F is None else F + extra
        if F is None:
            continue  # no synchronous excitation in this run: nothing for a 1X fit
        out.append(Case(F=F, probes=tuple(probes), X=X, X_std=np.asarray(data.X_std[r, i_speed], dtype=float)))
    return out


OPTIONS = {'prior_weight': 0.0, 'theory': None, 'bearing_model': None, 'max_nfev': 200, 'max_rel_std': MAX_REL_STD,
           'augment': None, 'fast': True}


def identify_direct(model, rig, data, probes=None, runs=None, options=None, **kw) -> list[IdentResult]:
    """
    ``direct`` identification at every speed of ``data`` (see the module docstring).

    Parameters
    ----------
    model
        rotor.assembly.RotorModel (no bearings).
    rig
        params.RigParams (bearing nodes/names, theory).
    data
        harmonic data with ``speeds`` (ns,) rad/s, ``X`` complex (nr, ns, nch) [m], ``X_std`` (nr, ns, nch) [m]
        (1-sigma of Re and Im), ``probes``, ``runs``.
    probes, runs
        override data.probes / data.runs.
    options, kw
        options / keywords: ``prior_weight`` (>= 0, default 0 = no prior), ``theory`` (bearing_fn speed -> coeffs;
        default the nominal theory of ``rig`` with ``bearing_model``), ``bearing_model`` ('short'/'finite'/None =
        the rig's), ``max_nfev``, ``max_rel_std`` (None: an optional extra bound on the 1-sigma relative
        to the block scale, on top of the one rule), ``augment`` (augmented-model hook, see :func:`fit_speed`
        and :func:`cases_from_data`; None = nominal model), ``fast`` (True: :class:`SpeedResponse`, one
        factorisation per speed; False: the dense reference solve per evaluation).

    Returns
    -------
    list of IdentResult (one per speed), method 'direct'.

    """
    opts = dict(OPTIONS)
    for k, v in {**(options or {}), **kw}.items():
        if k not in OPTIONS:
            raise ValueError(f'direct: unknown option {k!r} (known: {sorted(OPTIONS)})')
        opts[k] = v
    probes = tuple(probes if probes is not None else data.probes)
    runs = tuple(runs if runs is not None else data.runs)
    theory_fn = opts['theory']
    if theory_fn is None:
        theory_fn = supports.bearing_fn(rig, model=opts['bearing_model'])
    nodes = tuple(b.node for b in rig.bearings)
    names = tuple(b.name for b in rig.bearings)
    out = []
    for i, W in enumerate(np.asarray(data.speeds, float)):
        cases = cases_from_data(model, data, probes, runs, i, augment=opts['augment'])
        th = theory_fn(float(W))
        out.append(fit_speed(model, float(W), cases, nodes, theory=th, prior_weight=float(opts['prior_weight']),
                             bearings=names, max_nfev=int(opts['max_nfev']),
                             max_rel_std=(None if opts['max_rel_std'] is None else float(opts['max_rel_std'])),
                             augment=opts['augment'], fast=bool(opts['fast'])))
    return out


__all__ = ['Case', 'coeffs_to_beta', 'beta_to_coeffs', 'default_scale', 'response_and_jacobian', 'SpeedResponse',
           'WeightedStack',
           'response_and_jacobian_augmented',
           'information_analysis', 'weighted_stack', 'fit_speed', 'cases_from_data', 'identify_direct']
