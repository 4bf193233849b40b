"""
Kalman filter on the FE rotor's state space (Kang et al. 2020, section 3.1, eqs 5-18): the steady-state filter.

Model (eqs 5-11)
    Continuous state x = [q; q'] (2 ndof), x' = A x + B f(t), measurement z_k = H x(t_k) + v_k (probe DOFs), with
    (A, B) from ``rotor.assembly.state_space`` (or any (A, B, H) system).  Discretised exactly: Phi = expm(A dt).

Known sinusoidal input, exact discretisation
    Every known excitation is f(t) = sum_r Re{F_r exp(j r phi(t))} (phi the keyphasor rotor angle, r the frequency
    ratio; :func:`bearing_id.excitation.harmonic_forces`).  Its particular solution is x_p(t) = sum_r Re{Xp_r
    exp(j r phi(t))} with Xp_r = (j r Omega I - A)^-1 B F_r, and the input term over one step is
    d_k = x_p(t_{k+1}) - Phi x_p(t_k): exact for a sinusoid (no zero-order hold on the force).  Equivalently the filter
    runs on the deviation e = x - x_p, which obeys e_{k+1} = Phi e_k + w_k with the pseudo-measurement
    z_k - H x_p(t_k) = H e_k + v_k; both forms give the same numbers, and the second needs no future angle (streaming).

Start rule
    Unless ``x0`` is given the filter starts from the model's steady state at the first sample,
    x_hat(0|-1) = x_p(t_0) (the machine was already running at this speed), with the steady-state prior covariance
    P(0|-1) = P_ss from the discrete algebraic Riccati equation.  With that start the paper's time-varying filter
    (eqs 12-18) is the steady-state filter computed here (test/test_kalman.py runs filterpy's KalmanFilter as the
    oracle); its gain sequence starts at, and stays at, the steady-state gain.

Noise
    Q (process) and R (measurement) are configurable; a scalar means that times the identity, so the paper's
    Q = 1e-16 ... 1e-18 I is ``Q=1e-16``.  Units: Q in the state's units squared (m^2 and (m/s)^2), R in m^2.

Outputs (:class:`KFResult`)
    Selected DOFs (default: x and y at the bearing nodes) of the posterior x_hat(k|k), innovations
    nu_k = z_k - H x_hat(k|k-1), the innovation covariance S, the normalised innovation squared
    NIS_k = nu_k^T S^-1 nu_k, its mean and the two-sided 95 % chi-square band of that mean for a consistent filter.

The filter is LTI, so it runs as a chunked linear map (:class:`_ChunkedLTI`: one matrix product per chunk of samples
instead of one step per sample); NaN/inf samples are refused (ValueError naming the count).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
import math

import numpy as np
import scipy.linalg as sla
from scipy.special import chdtri, ndtri

from ..config import defaults
from ..conventions import dof_index
from ..rotor.assembly import probe_matrix, state_space

CHUNK = 64          # samples per chunk of the vectorised LTI evaluation


# ------------------------------------------------------------------------------------------------ discretisation
def expm(A) -> np.ndarray:
    """
    Return exp(A) of a square matrix computed on its balanced form T^-1 A T (``scipy.linalg.matrix_balance``).

    The filter's Phi = expm(A dt) (exact discretisation of x' = A x; the known input enters through the particular
    solution, :func:`input_phasors`, not through a zero-order hold).

    T is diagonal with powers of 2 (an exact similarity), exp(A) = T exp(T^-1 A T) T^-1: the rotor's state matrix
    mixes units (entries from 1 to 1e11 s^-2) and its unbalanced 1-norm overstates the scaling the eigenvalues need.
    """
    Ab, (t, _) = sla.matrix_balance(A, permute=False, separate=True)
    return t[:, None] * sla.expm(Ab) / t[None, :]


def forced_states(A, B, forces, omega: float) -> np.ndarray:
    """
    Return forced-response state phasors (n, k) = (j omega I - A)^-1 B F^T.

    forces : complex (k, n_inputs) force phasors [N] (one per run or ratio); omega [rad/s].
    """
    A = np.asarray(A, dtype=float)
    rhs = np.asarray(B) @ np.atleast_2d(np.asarray(forces, dtype=complex)).T
    return np.linalg.solve(1j * float(omega) * np.eye(A.shape[0]) - A, rhs)


def input_phasors(A, B, forces: dict, speed: float) -> dict:
    """
    State phasors of the particular solution: {r: Xp_r = (j r speed I - A)^-1 B F_r} (complex (n,)).

    forces : {frequency ratio r: complex force phasor (n_inputs,)} [N]; speed [rad/s].
    """
    return {float(r): forced_states(A, B, F, float(r) * float(speed))[:, 0] for r, F in (forces or {}).items()}


def particular_state(Xp: dict, angle) -> np.ndarray:
    """
    Return x_p at each angle: sum_r Re{Xp_r exp(j r angle)} -> (N, n).

    Xp {ratio r: complex phasor (n,)} (the particular solution's state phasors, or any projection of them, e.g.
    {r: H Xp_r}); angle (N,) [rad].  Re{X e^{j r a}} = cos(r a) Re X - sin(r a) Im X.
    """
    angle = np.asarray(angle, dtype=float).reshape(-1)
    if not Xp:
        return np.zeros((angle.size, 0))
    out = np.zeros((angle.size, next(iter(Xp.values())).size))
    for r, X in Xp.items():
        x = np.asarray(X)
        ra = r * angle
        out += np.cos(ra)[:, None] * x.real[None, :] - np.sin(ra)[:, None] * x.imag[None, :]
    return out


def _as_cov(v, n, name) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.ndim == 0:
        if not a > 0:
            raise ValueError(f'{name} must be > 0, got {float(a)}')
        return float(a) * np.eye(n)
    if a.ndim == 1:
        if a.size != n or np.any(a <= 0):
            raise ValueError(f'{name} as a vector must hold {n} positive variances')
        return np.diag(a)
    if a.shape != (n, n):
        raise ValueError(f'{name} must be a scalar, ({n},) or ({n}, {n}); got shape {a.shape}')
    return 0.5 * (a + a.T)


def riccati_residual(Phi, H, Q, R, P) -> np.ndarray:
    """Ric(P) - P for the filter DARE  P = Phi P Phi^T - Phi P H^T (H P H^T + R)^-1 H P Phi^T + Q."""
    S = H @ P @ H.T + R
    return Phi @ P @ Phi.T - Phi @ P @ H.T @ np.linalg.solve(S, H @ P @ Phi.T) + Q - P


def _dare_sda(Phi, H, Q, R, max_iter=80):
    """
    Structure-preserving doubling (Chu, Fan & Lin 2005) on the dual problem; quadratic convergence.

    Stops when the relative change of the iterate is <= 1e-15, or <= 1e-9 once the changes fall quadratically
    (d_k <= d_(k-1)^1.5: the next change, and so the remaining error, is then ~d_k^2); the caller checks the Riccati
    residual.  One LU solve (numpy, LAPACK gesv) per doubling for both right-hand sides.
    """
    n = Phi.shape[0]
    Ak = np.array(Phi.T, order='F')
    Gk = H.T @ np.linalg.solve(R, H)
    Hk = np.array(Q, dtype=float)
    rhs = np.empty((n, 2 * n), order='F')
    diag = np.diag_indices(n)
    dprev = np.inf
    for _ in range(max_iter):
        Mx = Gk @ Hk
        Mx[diag] += 1.0
        rhs[:, :n] = Ak
        rhs[:, n:] = Gk
        try:
            W = np.linalg.solve(Mx, rhs)
        except np.linalg.LinAlgError:
            return None
        IA, IG = W[:, :n], W[:, n:]
        Hn = Hk + Ak.T @ (Hk @ IA)
        Gk = Gk + (Ak @ IG) @ Ak.T
        Ak = Ak @ IA
        Hn = 0.5 * (Hn + Hn.T)
        big = np.max(np.abs(Hn))
        d = np.max(np.abs(Hn - Hk)) / big if big > 0 else 0.0
        Hk = Hn
        if not np.isfinite(d):
            return None
        if d <= 1e-15 or (d <= 1e-9 and d <= dprev ** 1.5):
            return Hk
        dprev = d
    return None


def steady_state_gain(Phi, H, Q, R):
    """
    Steady-state prior covariance P, Kalman gain K = P H^T S^-1 and innovation covariance S = H P H^T + R.

    P solves the filter DARE  P = Phi P Phi^T - Phi P H^T (H P H^T + R)^-1 H P Phi^T + Q (the dual of the control
    DARE with (Phi^T, H^T)), by structure-preserving doubling (:func:`_dare_sda`): on the 88-state rotor with
    Q = 1e-16 I about 4x faster than scipy.linalg.solve_discrete_are, with a relative Riccati residual ~1e-14 where
    scipy's is ~5e-7 (benchmarks/bench_speed.py (b) measures both; test/test_kalman.py checks them against each
    other).  Raises RuntimeError if the doubling does not converge or the final relative residual exceeds 1e-10
    (check Q, R scaling and detectability).
    """
    P = _dare_sda(Phi, H, Q, R)
    if P is None:
        raise RuntimeError('the discrete Riccati equation did not converge by doubling; check Q, R scaling and '
                           'detectability of (Phi, H)')
    S = H @ P @ H.T + R
    S = 0.5 * (S + S.T)
    K = np.linalg.solve(S, H @ P).T
    res = riccati_residual(Phi, H, Q, R, P)
    if np.max(np.abs(res)) > 1e-10 * max(np.max(np.abs(P)), np.max(np.abs(Q))):
        raise RuntimeError(f'the discrete Riccati solution is inaccurate (residual {np.max(np.abs(res)):.3g} vs '
                           f'max|P| {np.max(np.abs(P)):.3g}); check Q, R scaling and detectability')
    return P, K, S


# ------------------------------------------------------------------------------------------------ model
@dataclass
class KalmanModel:
    """
    A discretised model for the filter (build with :func:`kalman_model` or :func:`rotor_kalman_model`).

    A (n, n), B (n, nu) continuous; H (m, n) measurement; E (k, n) output selection; Phi = expm(A dt); Q (n, n),
    R (m, m); dt [s]; speed [rad/s] the model's speed; Xp {ratio: complex (n,)} particular-solution state phasors;
    out_names (k,) names of the outputs; meas_names (m,) names of the measured channels.
    """

    A: np.ndarray
    B: np.ndarray
    H: np.ndarray
    E: np.ndarray
    Phi: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    dt: float
    speed: float
    Xp: dict
    out_names: tuple = ()
    meas_names: tuple = ()
    _ss: tuple | None = field(default=None, repr=False)
    _chunked: dict = field(default_factory=dict, repr=False)

    @property
    def n(self) -> int:
        return self.Phi.shape[0]

    @property
    def m(self) -> int:
        return self.H.shape[0]

    def steady_state(self):
        """(P_prior, K, S) of the steady-state filter (cached)."""
        if self._ss is None:
            self._ss = steady_state_gain(self.Phi, self.H, self.Q, self.R)
        return self._ss

    def with_forces(self, forces: dict, speed: float | None = None) -> 'KalmanModel':
        """
        Return the same model (matrices, gain) with new known excitation phasors at ``speed`` [rad/s].

        ``speed`` defaults to the model's.
        """
        sp = self.speed if speed is None else float(speed)
        return KalmanModel(self.A, self.B, self.H, self.E, self.Phi, self.Q, self.R, self.dt, sp,
                           input_phasors(self.A, self.B, forces, sp), self.out_names, self.meas_names, self._ss,
                           self._chunked)

    def bias_gain(self) -> np.ndarray:
        """
        (m, m) mean innovation of the steady-state filter per unit constant bias on the measurements (cached).

        M = I - H (I - Phi (I - K H))^-1 Phi K: a bias b leaves the innovations a mean M b, the filter takes the rest
        into its state (M ~ I with a small Q, ~ 0 with a large one).
        """
        M = self._chunked.get('bias_gain')
        if M is None:
            P, K, S = self.steady_state()
            F = self.Phi @ (np.eye(self.n) - K @ self.H)
            M = np.eye(self.m) - self.H @ np.linalg.solve(np.eye(self.n) - F, self.Phi @ K)
            self._chunked['bias_gain'] = M
        return M

    def with_noise(self, R=None, Q=None) -> 'KalmanModel':
        """
        Return the same system (A, B, H, E, Phi, excitation) with another R and/or Q (the gain is re-solved lazily).

        R [m^2], Q as in :func:`kalman_model` (scalar, vector or matrix); None keeps the model's.
        """
        Qn = self.Q if Q is None else _as_cov(Q, self.n, 'Q')
        Rn = self.R if R is None else _as_cov(R, self.m, 'R')
        return KalmanModel(self.A, self.B, self.H, self.E, self.Phi, Qn, Rn, self.dt, self.speed, self.Xp,
                           self.out_names, self.meas_names)

    def particular(self, angle, rows=None) -> np.ndarray:
        """
        Return ``rows`` x_p (N, k) at the angles (N,) [rad]: the model's forced response seen through ``rows`` (k, n).

        ``rows`` defaults to H (the measured channels); E gives the outputs, the identity the full state.
        """
        M = self.H if rows is None else np.atleast_2d(rows)
        ang = np.asarray(angle, dtype=float).reshape(-1)
        if not self.Xp:
            return np.zeros((ang.size, M.shape[0]))
        return particular_state({r: M @ X for r, X in self.Xp.items()}, ang)


def kalman_model(A, B, H, dt: float, *, Q=defaults.KF_PROCESS_NOISE, R, forces=None, speed: float = 0.0, E=None,
                 out_names=(), meas_names=()) -> KalmanModel:
    """
    Build a :class:`KalmanModel` from a continuous (A, B, H) system.

    dt [s] sample interval; Q, R scalar (times identity), vector (diagonal) or matrix; forces {ratio: F (nu,)} known
    excitation phasors [N] at ``speed`` [rad/s]; E (k, n) output selection (default H).
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    H = np.atleast_2d(np.asarray(H, dtype=float))
    n = A.shape[0]
    if A.shape != (n, n) or B.shape[0] != n or H.shape[1] != n:
        raise ValueError(f'inconsistent shapes A {A.shape}, B {B.shape}, H {H.shape}')
    if not dt > 0:
        raise ValueError(f'dt must be > 0 s, got {dt}')
    E = H.copy() if E is None else np.atleast_2d(np.asarray(E, dtype=float))
    Phi = expm(A * dt)
    return KalmanModel(A, B, H, E, Phi, _as_cov(Q, n, 'Q'), _as_cov(R, H.shape[0], 'R'), float(dt), float(speed),
                       input_phasors(A, B, forces or {}, speed), tuple(out_names), tuple(meas_names))


def _dof_rows(items, n_nodes):
    rows, names = [], []
    for it in items:
        node, direction = (it.node, it.direction) if hasattr(it, 'node') else it
        rows.append(dof_index(node, direction, n_nodes))
        names.append(getattr(it, 'name', None) or f'n{node}{direction}')
    return rows, names


def rotor_kalman_model(rotor, speed: float, coeffs: dict, measured, sample_rate: float, *, forces=None,
                       outputs=None, Q=defaults.KF_PROCESS_NOISE, R) -> KalmanModel:
    """
    Build the paper's filter model of the FE rotor at ``speed`` [rad/s] with bearing ``coeffs`` {node: (K, C)}.

    measured : probes (objects with .node, .direction[, .name]) or (node, 'x'|'y') pairs, 1-based nodes.
    forces : {ratio: complex (ndof,)} known excitation phasors [N] (``excitation.harmonic_forces``).
    outputs : DOFs to estimate, same form as ``measured`` (default: x and y at every bearing node).
    Q : process noise (paper: 1e-16 ... 1e-18 times identity); R : probe noise variance [m^2].
    ``rotor`` may be a :class:`bearing_id.rotor.reduction.ReducedRotor`: the filter then runs on its reduced states
    [q_r; q_r'] (H and E are the full rows times its T, forces stay full (ndof,) vectors, Q is given on the full
    states and mapped by its left inverse, :meth:`~bearing_id.rotor.reduction.ReducedRotor.reduce_covariance`).
    """
    reduced = hasattr(rotor, 'full') and hasattr(rotor, 'T')
    full = rotor.full if reduced else rotor
    A, B = rotor.state_space(speed, coeffs) if reduced else state_space(rotor, speed, coeffs)
    if reduced:
        measured = list(measured)
        mnames = [getattr(it, 'name', None)
                  or 'n{}{}'.format(*((it.node, it.direction) if hasattr(it, 'node') else it)) for it in measured]
        if outputs is None:
            outputs = [(b, d) for b in full.bearing_nodes for d in ('x', 'y')]
        orows, onames = _dof_rows(outputs, full.n_nodes)
        nr = rotor.nr
        H = np.zeros((len(measured), 2 * nr))
        H[:, :nr] = rotor.reduce_rows(probe_matrix(full, measured))
        Ef = np.zeros((len(orows), full.ndof))
        Ef[np.arange(len(orows)), orows] = 1.0
        E = np.zeros((len(orows), 2 * nr))
        E[:, :nr] = rotor.reduce_rows(Ef)
        return kalman_model(A, B, H, 1.0 / float(sample_rate), Q=rotor.reduce_covariance(Q), R=R, forces=forces,
                            speed=speed, E=E, out_names=onames, meas_names=mnames)
    nn = rotor.n_nodes
    measured = list(measured)
    mnames = [getattr(it, 'name', None) or 'n{}{}'.format(*((it.node, it.direction) if hasattr(it, 'node') else it))
              for it in measured]
    if outputs is None:
        outputs = [(b, d) for b in rotor.bearing_nodes for d in ('x', 'y')]
    orows, onames = _dof_rows(outputs, nn)
    n = A.shape[0]
    H = np.zeros((len(measured), n))
    H[:, :rotor.ndof] = probe_matrix(rotor, measured)   # measurement rows: probes at any angle, with their gain
    E = np.zeros((len(orows), n))
    E[np.arange(len(orows)), orows] = 1.0
    return kalman_model(A, B, H, 1.0 / float(sample_rate), Q=Q, R=R, forces=forces, speed=speed, E=E,
                        out_names=onames, meas_names=mnames)


# ------------------------------------------------------------------------------------------------ results
@dataclass
class KFResult:
    """
    Filter (or smoother) output.

    estimates (N, k) selected DOFs of x_hat(k|k) (smoother: x_hat(k|N)) [m]; innovations (N, m) [m]; S (m, m) steady
    or (N, m, m) per step [m^2]; nis (N,); nis_mean; nis_band (lo, hi) the 95 % chi-square band of the mean NIS of a
    consistent filter (dof = N m); states (N, n) full state if requested; out_names.
    """

    estimates: np.ndarray
    innovations: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    nis_mean: float
    nis_band: tuple
    states: np.ndarray | None = None
    out_names: tuple = ()

    @property
    def consistent(self) -> bool:
        """Mean NIS inside its 95 % chi-square band."""
        return bool(self.nis_band[0] <= self.nis_mean <= self.nis_band[1])


def nis_band(n_steps: int, m: int, level: float = 0.95, rel_std: float = 0.0) -> tuple:
    """
    Two-sided ``level`` band of the mean of n_steps NIS values of dimension m (chi-square with n_steps m dof).

    ``rel_std``: the relative 1-sigma of the noise covariance the NIS is normalised by, when that is itself estimated
    from data (the mean NIS scales with its inverse).  The chi-square band assumes it known; with ``rel_std`` > 0 each
    half-width is combined in quadrature with the normal ``level`` quantile of m x ``rel_std``.  Kept per
    (n_steps, m, level): the windows of one speed usually have equal lengths.
    """
    lo, hi = _nis_band(int(n_steps), int(m), float(level))
    if not rel_std > 0:
        return lo, hi
    w = float(ndtri(0.5 + float(level) / 2)) * int(m) * float(rel_std)
    return m - math.hypot(m - lo, w), m + math.hypot(hi - m, w)


@lru_cache(maxsize=512)
def _nis_band(n_steps: int, m: int, level: float) -> tuple:
    a = (1.0 - level) / 2
    dof = float(n_steps * m)
    return float(chdtri(dof, 1.0 - a)) / n_steps, float(chdtri(dof, a)) / n_steps


def _result(est, nu, S, nis, states=None, out_names=()):
    nm = float(np.mean(nis)) if nis.size else float('nan')
    return KFResult(est, nu, S, nis, nm, nis_band(max(nis.size, 1), nu.shape[1]), states, tuple(out_names))


def _check_inputs(km: KalmanModel, samples, angle):
    z = np.asarray(samples, dtype=float)
    if z.ndim == 1:
        z = z[:, None]
    if z.ndim != 2 or z.shape[1] != km.m:
        raise ValueError(f"samples must be (N, {km.m}) for this model's {km.m} measured channel(s), got {z.shape}")
    a = np.asarray(angle, dtype=float).reshape(-1)
    if a.size != z.shape[0]:
        raise ValueError(f'angle has {a.size} values but samples have {z.shape[0]} rows')
    bad = int(np.count_nonzero(~np.isfinite(z)))
    if bad:
        raise ValueError(f'samples hold {bad} non-finite value(s) (NaN/inf); the Kalman filter needs complete '
                         f'blocks: drop or repair the block')
    bad = int(np.count_nonzero(~np.isfinite(a)))
    if bad:
        raise ValueError(f'angle holds {bad} non-finite value(s) (NaN/inf)')
    return z, a


# ------------------------------------------------------------------------------------------------ chunked filter
class _ChunkedLTI:
    """
    Vectorised evaluation of s_{k+1} = F s_k + G u_k, y_k = C s_k + D u_k over chunks of L samples.

    Within a chunk starting at s_c: y_{c+i} = C F^i s_c + sum_{j<i} C F^(i-1-j) G u_{c+j} + D u_{c+i}; the chunk
    starts follow s_{c+L} = F^L s_c + [F^(L-1) G ... G] u_chunk.  Exact (no approximation), one matrix product for the
    outputs of all chunks and a short loop over chunk starts.
    """

    def __init__(self, F, G, C, D, L=CHUNK):
        n, m = G.shape
        p = C.shape[0]
        self.L, self.n, self.m, self.p = L, n, m, p
        self.F, self.G = F, G
        # C F^i and F^i G for i < L by doubling: [O; O F^k] and [W, F^k W] (log2 L matrix products, not L)
        Ob, Wc, Fk, k = np.asarray(C, dtype=float), np.asarray(G, dtype=float), F, 1
        while k < L:
            Ob = np.vstack([Ob, Ob @ Fk])
            Wc = np.hstack([Wc, Fk @ Wc])
            Fk = Fk @ Fk
            k *= 2
        obs = Ob[:L * p].reshape(L, p, n)
        ctr = Wc[:, :L * m].reshape(n, L, m).transpose(1, 0, 2)          # F^i G
        self.FL = Fk if k == L else np.linalg.matrix_power(F, L)
        self.obs = obs.reshape(L * p, n)
        self.W = ctr[::-1].transpose(1, 0, 2).reshape(n, L * m)          # [F^(L-1) G, ..., G]
        # block lower-triangular Toeplitz T[i, j] = markov[i - j] (C F^(i-j-1) G, D on the diagonal, 0 above)
        padded = np.zeros((2 * L - 1, p, m))                              # padded[L - 1 + d] = markov[d]
        padded[L - 1] = D
        padded[L:] = (Ob[:(L - 1) * p] @ G).reshape(L - 1, p, m)
        i = np.arange(L)
        T = padded[(L - 1) + i[:, None] - i[None, :]]                      # (L, L, p, m): padded[L - 1 + i - j]
        self.T = T.transpose(0, 2, 1, 3).reshape(L * p, L * m)

    def run(self, U, s0):
        """Return the outputs (N, p) and the state after the last sample for inputs U (N, m) from state s0 (n,)."""
        N = U.shape[0]
        L, m, p = self.L, self.m, self.p
        nc = -(-N // L)
        Up = np.zeros((nc * L, m))
        Up[:N] = U
        Uc = Up.reshape(nc, L * m).T                  # (L m, nc)
        WU = self.W @ Uc                              # (n, nc)
        S = np.empty((self.n, nc + 1))
        S[:, 0] = s0
        FL = self.FL
        for c in range(nc):
            S[:, c + 1] = FL @ S[:, c] + WU[:, c]
        Y = self.obs @ S[:, :nc] + self.T @ Uc        # (L p, nc)
        Y = Y.T.reshape(nc * L, p)[:N]
        if N == nc * L:
            s_end = S[:, nc]
        else:                                         # padded tail: recompute the state at sample N exactly
            s = S[:, nc - 1]
            for k in range((nc - 1) * L, N):
                s = self.F @ s + self.G @ U[k]
            s_end = s
        return Y, s_end


def innovation_chunk(m: int) -> int:
    """
    Chunk length of the innovation operator for ``m`` measured channels (samples per chunk).

    The Toeplitz product costs ~L m^2 per sample and the loop over chunk starts ~1/L: 64 samples for up to two
    probes, 32 above.
    """
    return CHUNK if m <= 2 else CHUNK // 2


def _operator(km: KalmanModel, outputs: str) -> _ChunkedLTI:
    """
    Return the steady-state filter as a chunked LTI map (cached on ``km``), from the prior deviation e(k|k-1).

    Input: the pseudo-measurements zt_k = z_k - H x_p(t_k); state: e(k|k-1) = x_hat(k|k-1) - x_p(t_k), with
    e(k+1|k) = Phi (I - K H) e(k|k-1) + Phi K zt_k.  Outputs: the innovations nu_k = zt_k - H e(k|k-1)
    ('innovations'), followed by E e(k|k) ('estimates') or e(k|k) itself ('states'), e(k|k) = (I - K H) e(k|k-1)
    + K zt_k.  One operator per kind and model; the innovations alone are cheaper to build and to run.
    """
    op = km._chunked.get(outputs)
    if op is None:
        P, K, S = km.steady_state()
        IKH = np.eye(km.n) - K @ km.H
        C, D = -km.H, np.eye(km.m)
        if outputs != 'innovations':
            M = km.E if outputs == 'estimates' else np.eye(km.n)
            C, D = np.vstack([C, M @ IKH]), np.vstack([D, M @ K])
        L = innovation_chunk(km.m) if outputs == 'innovations' else CHUNK
        op = _ChunkedLTI(km.Phi @ IKH, km.Phi @ K, C, D, L)
        km._chunked[outputs] = op
    return op


def _nis(nu, S) -> np.ndarray:
    """Normalised innovation squared nu_k^T S^-1 nu_k (N,) for innovations nu (N, m)."""
    return np.sum((nu @ np.linalg.inv(S)) * nu, axis=1)


def _initial_deviation(km: KalmanModel, a0: float, x0):
    """e(0|-1) = x0 - x_p(t0) (zero for the default steady-state start)."""
    if x0 is None:
        return np.zeros(km.n)
    return np.asarray(x0, dtype=float) - km.particular([a0], np.eye(km.n))[0]


def _run(km: KalmanModel, samples, angle, x0, outputs: str):
    """Check the inputs and run the chunked filter (:func:`_operator` ``outputs``) from x0: (Y (N, ...), angle (N,))."""
    z, a = _check_inputs(km, samples, angle)
    zt = z - km.particular(a)
    Y, _ = _operator(km, outputs).run(zt, _initial_deviation(km, a[0], x0))
    return Y, a


def innovations(km: KalmanModel, samples, angle, *, x0=None):
    """
    Innovations of the steady-state filter alone: (nu (N, m) [m], nis (N,), nis_mean, nis_band).

    The numbers :func:`fast_filter` gives, without the state estimates (the operator has only the m innovation
    outputs).
    """
    nu, _ = _run(km, samples, angle, x0, 'innovations')
    nis = _nis(nu, km.steady_state()[2])
    nm = float(np.mean(nis)) if nis.size else float('nan')
    return nu, nis, nm, nis_band(max(nis.size, 1), km.m)


def fast_filter(km: KalmanModel, samples, angle, *, x0=None, return_states: bool = False) -> KFResult:
    """
    Steady-state Kalman filter (gain from the DARE), vectorised.

    samples (N, m) [m] measured channels in the order of km.H; angle (N,) keyphasor angle [rad]; x0 (n,) initial
    prior state (default: the model's steady state x_p(t0), see module docstring).  With the default start this is
    the paper's time-varying filter started at its steady-state covariance.
    """
    Y, a = _run(km, samples, angle, x0, 'states' if return_states else 'estimates')
    m = km.m
    nu = Y[:, :m]
    states = None
    if return_states:
        states = Y[:, m:] + km.particular(a, np.eye(km.n))
        est = states @ km.E.T
    else:
        est = Y[:, m:] + km.particular(a, km.E)
    S = km.steady_state()[2]
    return _result(est, nu, S, _nis(nu, S), states, km.out_names)


# ------------------------------------------------------------------------------------------------ smoother
def rts_smoother(km: KalmanModel, samples, angle, *, x0=None, return_states: bool = False) -> KFResult:
    """
    Rauch-Tung-Striebel smoother with the steady-state filter (offline).

    x_hat(k|N) = x_hat(k|k) + Cs (x_hat(k+1|N) - x_hat(k+1|k)), Cs = P(k|k) Phi^T P(k+1|k)^-1 with the steady-state
    covariances; the known input cancels in the bracket, so the recursion runs on the deviation from x_p.
    ``innovations``/``nis`` are the forward filter's (:func:`fast_filter`); ``estimates`` are smoothed.
    """
    Y, a = _run(km, samples, angle, x0, 'states')
    P, K, S = km.steady_state()
    nu, ef = Y[:, :km.m], Y[:, km.m:]                             # innovations, e(k|k)
    Ppost = (np.eye(km.n) - K @ km.H) @ P
    Cs = np.linalg.solve(P.T, (Ppost @ km.Phi.T).T).T            # Ppost Phi^T P^-1 (P symmetric)
    es = np.empty_like(ef)
    es[-1] = ef[-1]
    g = ef - ef @ (Cs @ km.Phi).T                                 # (I - Cs Phi) e(k|k)
    for k in range(ef.shape[0] - 2, -1, -1):
        es[k] = g[k] + Cs @ es[k + 1]
    xs = es + km.particular(a, np.eye(km.n))
    return _result(xs @ km.E.T, nu, S, _nis(nu, S), xs if return_states else None, km.out_names)


# ------------------------------------------------------------------------------------------------ streaming
class StreamingKF:
    """
    Block-by-block steady-state filter for a node: state carried across blocks, identical to one batch call.

    Build one per speed band (``km`` from :func:`rotor_kalman_model` at the band's speed); ``band_tol_rel`` is the
    relative speed deviation the model is accepted for (a block outside raises ValueError: rebuild the model).
    The filter starts from the model's steady state at the first sample it sees.
    """

    def __init__(self, km: KalmanModel, band_tol_rel: float = 0.05):
        self.km = km
        self.band_tol_rel = float(band_tol_rel)
        self._op = _operator(km, 'estimates')
        self._e = np.zeros(km.n)           # e(k|k-1) for the next sample
        self.n_samples = 0

    def continue_from(self, prev: 'StreamingKF', angle: float) -> None:
        """
        Start from ``prev``'s predicted state at the next sample (keyphasor ``angle`` [rad]) instead of a steady state.

        The model changed (the speed moved to the next band, the bearings or the noise were updated) but the rotor did
        not: the physical state x = e + x_p carries over, e' = x - x_p' (x_p, x_p' each model's forced response at the
        sample).  Both models need the same states (the full FE model).
        """
        if prev.km.n != self.km.n:
            raise ValueError(f'models of {prev.km.n} and {self.km.n} states: the state cannot carry over')
        eye = np.eye(self.km.n)
        a = np.array([float(angle)])
        self._e = prev._e + prev.km.particular(a, eye)[0] - self.km.particular(a, eye)[0]

    def in_band(self, speed: float) -> bool:
        sp = self.km.speed
        return sp == 0.0 or abs(float(speed) - sp) <= self.band_tol_rel * abs(sp)

    def step_block(self, samples, angle, speed: float):
        """(estimates (n, k) [m], innovations (n, m) [m], nis (n,)) for one block; samples (n, m), angle (n,)."""
        if not self.in_band(speed):
            raise ValueError(f"speed {speed:.4g} rad/s is outside this model's band ({self.km.speed:.4g} rad/s "
                             f'+- {100 * self.band_tol_rel:.3g} %); rebuild the model for this speed')
        km = self.km
        z, a = _check_inputs(km, samples, angle)
        Y, self._e = self._op.run(z - km.particular(a), self._e)
        nu = Y[:, :km.m]
        self.n_samples += z.shape[0]
        return Y[:, km.m:] + km.particular(a, km.E), nu, _nis(nu, km.steady_state()[2])
