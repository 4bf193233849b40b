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
<= 0.1; ``max_rel_std`` (1-sigma below a fraction of the block scale) is an optional *additional* bound, off by
default.  Std: without prior, the
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
SPARSE_NDOF = 200         # above this many DOFs :class:`SpeedResponse` factorises Z with a sparse LU (splu)
WOODBURY_COND = 1e10      # above this condition of the m x m capacitance :class:`SpeedResponse` re-factorises


def probe_rows(model, cases):
    """
    Every run's probe rows stacked: (P (nrow, ndof) real, run (nrow,) int) with nrow = sum of the runs' channels.

    Row i of P is the measurement row of one channel of run ``run[i]`` (:func:`bearing_id.rotor.assembly.probe_matrix`);
    the predicted phasors of all runs are then y_i = (P Q)[i, run[i]] with Q (ndof, nr) the runs' responses.
    """
    P = [probe_matrix(model, c.probes) for c in cases]
    return np.vstack(P), np.concatenate([np.full(p.shape[0], r) for r, p in enumerate(P)])


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
    Predicted probe phasors of every run at one speed and their Jacobian in beta: one factorisation per speed.

    Z(beta) = Z_ref + P_S D(beta - beta_ref) P_S^T, where S are the m DOFs the films act on (bearing nodes and their
    pedestals, m <= 4 nb) and D (m, m) is linear in beta (a film in series with a pedestal acts on q_a - q_p).
    Z_ref = Z(beta_ref) is factorised once (sparse LU above :data:`SPARSE_NDOF` DOFs -- the FE dynamic stiffness is
    banded apart from the pedestal rows; dense below) and W = Z_ref^-1 [F, P_S] computed once; then for any beta,
    with H = (Z_ref^-1)_SS and K = (I + D H)^-1 D (m x m), Z^-1 X = Z_ref^-1 X - W_S K (Z_ref^-1 X)_S
    (Sherman-Morrison-Woodbury), and only the probe rows and the S rows of it are formed.  Per call O(nrow m + m^3)
    instead of a dense (ndof, ndof) solve.  The Jacobian is exact (Z is linear in beta):
    dq/dbeta_k = -Z^-1 dZ_k q.  When the capacitance I + D H is ill-conditioned (cond > :data:`WOODBURY_COND`,
    beta far from beta_ref) it re-factorises at that beta.  test/test_direct_fast.py checks it against a dense solve
    of the assembled dynamic stiffness and finite differences of it.
    """

    def __init__(self, model, speed: float, cases, nodes, beta_ref, *, Z0=None, sparse: bool | None = None):
        self.speed = float(speed)
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
        self.F = np.stack([np.asarray(c.F, dtype=complex) for c in cases], axis=1)
        self.P, self.run = probe_rows(model, cases)
        self._Dmap = self._d_map()                            # D(dbeta) = (Dmap @ dbeta).reshape(m, m)
        # positions in S of each bearing's (x, y) and of its pedestal's (or -1: no pedestal)
        self._qa = np.array([[self.pos[int(self.bd[i, r])] for r in range(2)] for i in range(nb)])
        self._qp = np.array([[self.pos[int(self.peds[i]) + r] for r in range(2)] if self.peds[i] is not None
                             else [-1, -1] for i in range(nb)])
        self._has_ped = bool(np.any(self._qp >= 0))
        self._factor(np.asarray(beta_ref, float))

    def _d_map(self) -> np.ndarray:
        """Return the (m m, 8 nb) complex matrix of the linear map dbeta -> D(dbeta).ravel()."""
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
        nr, m = self.F.shape[1], self.S.size
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
        S = self.S
        nr, m = self.F.shape[1], S.size
        Z = self.Z0.astype(complex, copy=True)
        Z[np.ix_(S, S)] += (self._Dmap @ beta_ref).reshape(m, m)
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
        self.WS = W[S]                                        # (m, nr + m): rows at S of Z_ref^-1 [F, P_S]
        PW = self.P @ W                                       # (nrow, nr + m)
        sel = np.zeros((nr + m, nr + 2 * len(self.nodes)))   # [Z_ref^-1 F, Z_ref^-1 E] from [.. F, .. P_S]
        sel[:nr, :nr] = np.eye(nr)
        sel[nr:, nr:] = self.Es
        self._XS = self.WS @ sel                              # (m, nr + 2 nb) rows at S of Z_ref^-1 [F, E]
        self._PX = PW @ sel                                   # (nrow, nr + 2 nb) probe rows of the same
        self._PWm = PW[:, nr:]                                # (nrow, m)

    def __call__(self, beta):
        """
        Return (y, dy) at ``beta`` (8 nb,): y complex (nrow,) predicted phasors [m], dy complex (nrow, 8 nb) dy/dbeta.

        Rows in the order of :func:`probe_rows` (run by run, each run's channels in order).
        """
        beta = np.asarray(beta, float)
        nr, nb = self.F.shape[1], len(self.nodes)
        hk = self._capacitance(beta)
        if hk is None:
            self._factor(beta)
            return self(beta)
        H, Kc = hk                                            # H = (Z_ref^-1)_SS, Kc = (I + D H)^-1 D
        corr = Kc @ self._XS
        qS = (self._XS - H @ corr)[:, :nr]                    # rows at S of Z^-1 F (m, nr)
        qb = qS[self._qa]                                     # (nb, 2, nr) film deflections at the bearings
        if self._has_ped:
            qb = qb - np.where((self._qp >= 0)[:, :, None], qS[np.maximum(self._qp, 0)], 0.0)
        PX = self._PX - self._PWm @ corr                      # (nrow, nr + 2 nb): P Z^-1 [F, E]
        nrow = PX.shape[0]
        y = PX[np.arange(nrow), self.run]
        PG = PX[:, nr:].reshape(nrow, nb, 2, 1)               # P Z^-1 at the bearing rows
        qrow = qb.transpose(2, 0, 1)[self.run]                # (nrow, nb, 2) the row's run's film deflection
        blockk = -(PG * qrow[:, :, None, :]).reshape(nrow, nb, 4)
        dy = np.empty((nrow, nb, 8), dtype=complex)
        dy[..., :4] = blockk
        dy[..., 4:] = blockk * (1j * self.speed)
        return y, dy.reshape(nrow, 8 * nb)


def _sigma(c: Case) -> np.ndarray:
    X = np.asarray(c.X, dtype=complex)
    s = np.asarray(c.X_std, dtype=float)
    floor = 1e-12 * max(float(np.max(np.abs(X))), 1e-30)
    return np.maximum(np.where(np.isfinite(s), s, np.inf), floor)


class Weighting:
    """
    Weighted real residual of predicted phasors (rows of :func:`probe_rows`) against the measured ones of ``cases``.

    r = [Re e; Im e] with e = (y - X) / sigma per row (sigma = the measured 1-sigma of Re and Im, floored at 1e-12 of
    the run's largest |X|); the Jacobian columns are multiplied by ``scale`` (d r / d theta for beta = theta scale).
    """

    def __init__(self, cases, scale=None):
        self.X = np.concatenate([np.asarray(c.X, dtype=complex) for c in cases])      # (nrow,)
        self.sg = np.concatenate([_sigma(c) for c in cases])                          # (nrow,)
        self.scale = None if scale is None else np.asarray(scale, dtype=float)

    def residual(self, y) -> np.ndarray:
        """Return r (2 nrow,) for predictions y complex (nrow,)."""
        e = (y - self.X) / self.sg
        return np.concatenate([e.real, e.imag])

    def __call__(self, y, dy):
        """Return (r (2 nrow,), J (2 nrow, n)) for y (nrow,) and dy (nrow, n) = d y / d beta."""
        dd = dy * (self.scale[None, :] / self.sg[:, None])
        return self.residual(y), np.vstack([dd.real, dd.imag])


AUG_FD_STEP = 1e-6        # central-difference step of the augmented-model Jacobian, in units of the block scale


def augmented_response(model, speed: float, cases, coeffs: dict, augment, rows=None) -> np.ndarray:
    """
    Predicted phasors y complex (nrow,) [m] (rows of :func:`probe_rows`) through an augmented-model hook.

    ``rows``: the (P, run) of :func:`probe_rows` if already built.
    """
    P, run = probe_rows(model, cases) if rows is None else rows
    F = np.stack([np.asarray(c.F, dtype=complex) for c in cases], axis=1)
    Q = np.linalg.solve(augment.dynamic_stiffness(speed, speed, coeffs), F)
    return (P @ Q)[np.arange(run.size), run]


def response_and_jacobian_augmented(model, speed: float, cases, beta: np.ndarray, nodes, augment, scale):
    """
    Return (y, dy) as :meth:`SpeedResponse.__call__` but through an augmented-model hook.

    The hook is ``augment.dynamic_stiffness(speed, omega, coeffs)``; d y / d beta by central differences (step
    ``AUG_FD_STEP`` x ``scale`` per unknown).
    """
    rows = probe_rows(model, cases)

    def y_of(b):
        return augmented_response(model, speed, cases, beta_to_coeffs(b, nodes), augment, rows)

    y = y_of(beta)
    dy = np.zeros((y.size, beta.size), dtype=complex)
    for k in range(beta.size):
        h = AUG_FD_STEP * float(scale[k])
        db = np.zeros_like(beta)
        db[k] = h
        dy[:, k] = (y_of(beta + db) - y_of(beta - db)) / (2 * h)
    return y, dy


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
def fit_speed(model, speed: float, cases, nodes, *, theory: dict | None = None, prior_weight: float = 0.0,
              bearings=None, max_nfev: int = 200, max_rel_std: float | None = MAX_REL_STD,
              augment=None) -> IdentResult:
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
        {node: (K, C)} theory: the scale of the unknowns (:func:`default_scale`), the start of the iteration and the
        prior mean (None: default scales, start at zero, no prior).
    prior_weight
        w >= 0; prior 1-sigma = scale / sqrt(w) per coefficient (0 = no prior).
    bearings
        bearing names for the result (default ``bearing1``, ``bearing2``, ...).
    max_nfev
        evaluation limit of the least-squares fit (and of each profile in the nonlinearity check).
    max_rel_std
        optional extra bound on the 1-sigma relative to the scale (default :data:`MAX_REL_STD`; None = only the
        one rule).
    augment
        augmented-model hook (``dynamic_stiffness(speed, omega, coeffs) -> Z``; e.g. a flexible support in
        series with the film) or None.  With it the prediction is P Z_aug(beta)^-1 F and the Jacobian is taken by
        central differences in the scaled unknowns (relative step 1e-6).

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
    res = empty_result(speed, 'direct', names, nodes)
    cases = [c for c in cases if np.all(np.isfinite(np.asarray(c.X)))]
    if not cases:
        res.notes.append('no finite measurements at this speed')
        return res
    scale = default_scale(nodes, theory)
    beta0 = coeffs_to_beta(theory, nodes) if theory is not None else np.zeros(n)
    theta0 = beta0 / scale
    theta_p = coeffs_to_beta(theory, nodes) / scale if theory is not None else None
    sw = math.sqrt(prior_weight)
    response = SpeedResponse(model, speed, cases, nodes, beta0) if augment is None else None
    weigh = Weighting(cases, scale)

    def predict(beta):
        if response is not None:
            return response(beta)
        return response_and_jacobian_augmented(model, speed, cases, beta, nodes, augment, scale)

    def fun_jac(theta):
        r, J = weigh(*predict(theta * scale))
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
    y, dy = predict(beta)
    r_data, J_data = weigh(y, dy)
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
    if cand.size:
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
    num = float(np.linalg.norm(y - weigh.X))
    den = float(np.linalg.norm(weigh.X))
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
           'augment': None}


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
        and :func:`cases_from_data`; None = nominal model).

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
                             augment=opts['augment']))
    return out


__all__ = ['Case', 'coeffs_to_beta', 'beta_to_coeffs', 'default_scale', 'probe_rows', 'SpeedResponse', 'Weighting',
           'augmented_response', 'response_and_jacobian_augmented', 'information_analysis', 'fit_speed',
           'cases_from_data', 'identify_direct']
