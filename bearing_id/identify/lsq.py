"""
Least-squares helpers shared by the paper, conventional and design modules (one place, no import circle).

Import graph inside :mod:`bearing_id.identify` (checked by test/test_honest_numbers.py)::

    determined, result  <-  direct  <-  lsq  <-  paper, conventional, design
    determined, result  <-  direct  <-  physical

Contents
* eqs 19-37 of Kang et al. 2020: :func:`bearing_dofs`, :func:`bearing_forces`,
  :func:`ls_system`, :func:`solve_coefficients` (:class:`LSSolution`), :func:`theta_to_KC`, :func:`coeffs_to_theta`,
  :func:`forces_at`, :func:`noise_rel_of`, :func:`build_result`;
* the data-information analysis: :func:`coefficient_labels`, :func:`coefficient_scales`,
  :func:`coefficient_jacobian`, :func:`whitened_jacobian`, :func:`analyse` (:class:`Identifiability`);
* the two-probe interpolation pairs of the conventional method: :func:`probe_pairs`.

Rules of :func:`solve_coefficients` (eqs 33-37 solved by SVD)
    * LS rank: singular values above ``rtol`` (default 1e-8) x the largest; a coefficient is LS-estimable when at
      most 1 % of its unit vector lies in the null space.
    * Std: with the 1-sigma of the bearing-node phasors ``z_B_std`` it is propagated through the whole solve (its
      exact derivative, :func:`solve_derivatives`); without it, residual-based sigma^2 (A^T A)^+ when there are more
      equations than unknowns.
    * Misfit (more equations than unknowns and z_B_std given): the equation residual e = A(z) theta - d(z) is linear
      in z_B for fixed theta, so its covariance is M Sigma_z M^T (M = de/dz); the OLS residual r = P e (P the
      projector on the complement of range(A)) has covariance P M Sigma_z M^T P, and chi2 = r^T (P M Sigma M^T P)^+ r
      is chi-square(m - rank) for a correct model -- the input of :func:`bearing_id.identify.determined.fit_quality`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
import math

import numpy as np

from .determined import fit_quality, judge
from .direct import Case, coeffs_to_beta, SpeedResponse
from .result import eq38_error, IdentResult
from ..conventions import COEFF_ORDER, dof_index, probe_row
from ..excitation import harmonic_forces
from ..rotor.assembly import dynamic_stiffness

DEFAULT_RTOL = 1e-8
STRUCTURAL_RTOL = 1e-9
NULL_FRACTION = 0.01
DEFAULT_MAX_REL_STD = 0.05


# ------------------------------------------------------------------------------------------------ eqs 19-32
def bearing_dofs(model, nodes=None) -> np.ndarray:
    """0-based DOF indices [x_B1, y_B1, x_B2, y_B2, ...] of the bearing nodes (the reordered 'b' block)."""
    nodes = model.bearing_nodes if nodes is None else nodes
    return np.array([dof_index(n, d, model.n_nodes) for n in nodes for d in ('x', 'y')])


def bearing_forces(model, speed: float, z_B, forces) -> np.ndarray:
    """
    Eqs 30-32: bearing forces f_B (n_runs, nb, 2) [N] from bearing-node phasors z_B (n_runs, nb, 2) [m].

    forces : complex (n_runs, ndof) 1X excitation phasors [N].  H_R is the rotor without bearings at 1X.
    Bearings on pedestals are refused: from shaft displacements these equations give the impedance the shaft sees
    (film in series with the pedestal), not the film's coefficients -- ``direct`` and ``physical`` fit the film.
    """
    on = sorted(k for k in getattr(model, 'pedestals', {}) if not isinstance(k, tuple))   # ('known', i): in H_R
    if on:
        raise ValueError(f'the paper and conventional methods need bearings fixed to ground: bearing(s) at node(s) '
                         f'{on} sit on pedestals (support:) -- use direct or physical, which model the film in '
                         f'series with the pedestal')
    HR = dynamic_stiffness(model, speed, speed, {})
    b = bearing_dofs(model)
    u = np.setdiff1d(np.arange(model.ndof), b)
    z_B = np.asarray(z_B, dtype=complex)
    nr, nb = z_B.shape[:2]
    zb = z_B.reshape(nr, 2 * nb).T                                   # (2 nb, nr)
    F = np.asarray(forces, dtype=complex).T                          # (ndof, nr)
    z_u = np.linalg.solve(HR[np.ix_(u, u)], F[u] - HR[np.ix_(u, b)] @ zb)           # eq 30
    f_B = F[b] - HR[np.ix_(b, b)] @ zb - HR[np.ix_(b, u)] @ z_u                      # eqs 31-32
    return f_B.T.reshape(nr, nb, 2)


@lru_cache(maxsize=16)
def _ls_index(nb: int):
    """Index arrays of :func:`ls_system`: bearing, row i, component j, and the K and Omega C columns."""
    b, i, j = (a.reshape(-1) for a in np.meshgrid(np.arange(nb), np.arange(2), np.arange(2), indexing='ij'))
    return b, i, j, 4 * b + 2 * i + j, 4 * nb + 4 * b + 2 * i + j


def ls_system(z_B, f_B) -> tuple[np.ndarray, np.ndarray]:
    """
    Eqs 33-36 as a real system A theta = d over all runs; theta = [K_b (xx,xy,yx,yy) per bearing; Omega C_b].

    z_B, f_B complex (n_runs, nb, 2).  Rows: for each run, bearing, row i in (x, y): Re then Im parts.
    Returns A (2 n_runs 2 nb, 8 nb) [m] and d (same rows,) [N].
    """
    z_B = np.asarray(z_B, dtype=complex)
    f_B = np.asarray(f_B, dtype=complex)
    nr, nb = z_B.shape[:2]
    Ac = np.zeros((nr, nb, 2, 8 * nb), dtype=complex)
    b, i, j, ck, cc = _ls_index(nb)
    Ac[:, b, i, ck] = z_B[:, b, j]                 # row (run, bearing b, i): z_j in column (b, i, j) of K
    Ac[:, b, i, cc] = 1j * z_B[:, b, j]            # and of Omega C
    Ac = Ac.reshape(-1, 8 * nb)
    dc = f_B.reshape(-1)
    return np.vstack([Ac.real, Ac.imag]), np.concatenate([dc.real, dc.imag])


@dataclass
class LSSolution:
    """
    Solution of the eqs 33-37 system at one speed (theta = [K; Omega C] flat, bearings in model order).

    determined : LS-estimable (at most 1 % of the unit vector in the null space).   chi2, dof : the misfit statistic
    of the module docstring (NaN / 0 when it cannot be formed).
    """

    theta: np.ndarray
    theta_std: np.ndarray
    determined: np.ndarray
    rank: int
    unknowns: int
    condition: float
    residual: float
    singular_values: np.ndarray
    f_B: np.ndarray
    consistency: float = math.nan    # residual-based std / noise-propagated std (median over unknowns); NaN if n/a
    chi2: float = math.nan
    dof: int = 0


def svd_solve(A, d, rtol):
    """Minimum-norm least-squares solution by SVD: (theta, U, s, Vh, rank, n)."""
    U, s, Vh = np.linalg.svd(A, full_matrices=False)
    n = A.shape[1]
    r = int(np.count_nonzero(s > rtol * s[0])) if s.size and s[0] > 0 else 0
    theta = Vh[:r].T @ ((U[:, :r].T @ d) / s[:r])
    return theta, U, s, Vh, r, n


def bearing_force_map(model, speed: float, forces):
    """
    Return eqs 30-32 as an affine map z_B -> f_B (the function, and its linear part Lin (2 nb, 2 nb) complex).

    f_B,r = f0_r + Lin z_B,r with f0 = :func:`bearing_forces` at z_B = 0 and Lin the Schur-complement map of the
    rotor without bearings; equal to :func:`bearing_forces` (one rotor solve per speed instead of one per call).
    """
    forces = np.asarray(forces, dtype=complex)
    nb = len(model.bearing_nodes)
    q = 2 * nb
    nr = len(forces)
    # one solve for the runs' f0 and the basis columns together
    zb = np.concatenate([np.zeros((nr, q), dtype=complex), np.eye(q, dtype=complex)]).reshape(nr + q, nb, 2)
    fz = np.concatenate([forces, np.zeros((q, forces.shape[1]), dtype=complex)])
    out = bearing_forces(model, speed, zb, fz).reshape(nr + q, q)
    f0, Lin = out[:nr], out[nr:].T

    def forces_of(z):
        z = np.asarray(z, dtype=complex)
        n = z.shape[0]
        if n != nr:
            raise ValueError(f'bearing_force_map: built for {nr} runs, got {n}')
        return (f0 + z.reshape(n, q) @ Lin.T).reshape(z.shape)

    return forces_of, Lin


def solve_coefficients(model, speed: float, z_B, forces, *, z_B_std=None, rtol: float = DEFAULT_RTOL,
                       force_map=None) -> LSSolution:
    """
    Eqs 30-37 at one ``speed`` [rad/s]: bearing coefficients from bearing-node phasors of every run.

    z_B complex (n_runs, nb, 2) [m]; forces complex (n_runs, ndof) [N]; z_B_std (n_runs, nb, 2) 1-sigma of the Re
    and of the Im part of z_B [m] (optional, for the propagated std and the misfit statistic).  See the module
    docstring for the rules.  This is the one solve shared by the paper and the conventional methods.
    ``force_map``: (forces_of, Lin) of :func:`bearing_force_map` at this speed and these forces, if already built.
    The std is propagated through the exact derivative of the solve (:func:`solve_derivatives`, Golub-Pereyra;
    exact for a locally constant rank, which eqs 33-36 keep: their rank is structural).
    """
    z_B = np.asarray(z_B, dtype=complex)
    forces = np.asarray(forces, dtype=complex)
    forces_of, Lin = force_map if force_map is not None else bearing_force_map(model, speed, forces)
    f_B = forces_of(z_B)
    A, d = ls_system(z_B, f_B)
    theta, U, s, Vh, r, n = svd_solve(A, d, rtol)
    res = A @ theta - d
    dn = np.linalg.norm(d)
    residual = float(np.linalg.norm(res) / dn) if dn > 0 else math.nan
    null = Vh[r:] if r < n else np.zeros((0, n))
    if r < n and Vh.shape[0] < n:          # fewer equations than unknowns: complete the null space
        _, _, Vfull = np.linalg.svd(A, full_matrices=True)
        null = Vfull[r:]
    determined = np.sum(null**2, axis=0) <= NULL_FRACTION
    m = A.shape[0]
    dof = m - r
    var_res = None
    if dof > 0 and r > 0:
        sig2 = float(res @ res) / dof
        var_res = sig2 * np.sum((Vh[:r] / s[:r, None]) ** 2, axis=0)
    consistency, chi2, chi_dof = math.nan, math.nan, 0
    if z_B_std is not None:
        zs = np.repeat(np.asarray(z_B_std, dtype=float).reshape(-1, 1), 2, axis=1)      # (ne, 2): Re and Im
        zs = np.where(zs > 0, zs, 0.0)
        G, Dres = solve_derivatives(A, d, theta, U, s, Vh, r, z_B.shape, Lin)
        vp = np.sum((G * zs[None]) ** 2, axis=(1, 2))
        Mcols = (Dres * zs[None]).reshape(m, -1)[:, zs.reshape(-1) > 0] if dof > 0 else None
        var = vp
        if var_res is not None and np.any(vp > 0):
            ok = vp > 0
            consistency = float(np.median(np.sqrt(var_res[ok] / vp[ok])))
        if Mcols is not None and Mcols.size:
            M = Mcols
            Ur = U[:, :r]
            PM = M - Ur @ (Ur.T @ M)                       # P M, P = I - Ur Ur^T
            u_, sv_, _ = np.linalg.svd(PM, full_matrices=False)
            keep = sv_ > 1e-9 * (sv_[0] if sv_.size else 0.0)
            keep[dof:] = False
            if keep.any():
                proj = u_[:, keep].T @ res
                chi2 = float(np.sum((proj / sv_[keep]) ** 2))
                chi_dof = int(np.count_nonzero(keep))
    elif var_res is not None:
        var = var_res
    else:
        var = np.full(n, np.nan)
    std = np.where(determined, np.sqrt(var), np.nan)
    cond = float(s[0] / s[-1]) if s.size == n and s[-1] > 0 else math.inf
    return LSSolution(theta, std, determined, r, n, cond, residual, s, f_B, consistency, chi2, chi_dof)


def solve_derivatives(A, d, theta, U, s, Vh, r: int, shape, Lin):
    """
    Differentiate the eqs 33-37 solve per bearing-node phasor entry: (G (n, ne, 2), Dres (m, ne, 2)).

    For entry e of z_B (flattened ``shape`` (nr, nb, 2)) moved by a unit u (index 0: real 1, 1: imaginary j), with
    f_B moving by Lin (eqs 30-32 are affine in z_B): G = d theta, the Golub-Pereyra derivative of the (rank-truncated)
    SVD solution, d theta = A+ (dd - dA theta) + A+ A+^T dA^T res + (I - A+ A) dA^T A+^T theta (exact while the rank
    stays constant), and Dres = d (A theta - d) at fixed theta = dA theta - dd (A and d are linear in z_B and f_B).
    """
    nr, nb = shape[:2]
    q = 2 * nb
    n = A.shape[1]
    Ap = Vh[:r].T @ (U[:, :r].T / s[:r, None])
    res = d - A @ theta
    Null = np.eye(n) - Ap @ A
    ApApT = Ap @ Ap.T
    ApT_theta = Ap.T @ theta
    ne = nr * q
    G = np.zeros((n, ne, 2))
    Dres = np.zeros((A.shape[0], ne, 2))
    Lin = np.asarray(Lin, dtype=complex)
    for rr in range(nr):
        for j in range(q):
            for u, unit in enumerate((1.0, 1j)):
                dz = np.zeros((nr, nb, 2), dtype=complex)
                dz[rr].reshape(-1)[j] = unit
                df = np.zeros((nr, nb, 2), dtype=complex)
                df[rr] = (unit * Lin[:, j]).reshape(nb, 2)
                dA, dd = ls_system(dz, df)
                G[:, rr * q + j, u] = Ap @ (dd - dA @ theta) + ApApT @ (dA.T @ res) + Null @ (dA.T @ ApT_theta)
                Dres[:, rr * q + j, u] = dA @ theta - dd
    return G, Dres


def theta_to_KC(theta, speed: float, nb: int) -> tuple[np.ndarray, np.ndarray]:
    """Split theta = [K flat; Omega C flat] into K (nb, 2, 2) [N/m], C (nb, 2, 2) [N s/m]."""
    theta = np.asarray(theta, dtype=float)
    return theta[:4 * nb].reshape(nb, 2, 2), theta[4 * nb:].reshape(nb, 2, 2) / speed


def coeffs_to_theta(coeffs: dict, speed: float, nodes) -> np.ndarray:
    """{node: (K, C)} -> theta [K flat per bearing; Omega C flat per bearing]."""
    return np.concatenate([np.concatenate([np.asarray(coeffs[n][0], float).reshape(4) for n in nodes]),
                           np.concatenate([speed * np.asarray(coeffs[n][1], float).reshape(4) for n in nodes])])


def noise_rel_of(data, s: int) -> float:
    """Measured noise of the 1X vectors at speed index ``s`` relative to the RMS amplitude (design noise model)."""
    amp = np.sqrt(np.mean(np.abs(data.X[:, s]) ** 2))
    sd = np.sqrt(np.mean(data.X_std[:, s] ** 2))
    return float(max(sd / amp if amp > 0 else 1.0, 1e-9))


def forces_at(model, runs, speed: float) -> np.ndarray:
    """Complex (n_runs, ndof) 1X excitation phasors [N] of ``runs`` at ``speed`` [rad/s]."""
    out = []
    for r in runs:
        F = harmonic_forces(r.excitation, speed, model.n_nodes, model.ndof).get(1.0)
        out.append(F if F is not None else np.zeros(model.ndof, dtype=complex))
    return np.array(out)


# ------------------------------------------------------------------------------------------------ data information
def coefficient_labels(nodes) -> list[str]:
    """Names of the 8 nb unknowns in the order used here: K of each bearing, then C of each bearing."""
    out = [f'node{n}.K{c}' for n in nodes for c in COEFF_ORDER]
    return out + [f'node{n}.C{c}' for n in nodes for c in COEFF_ORDER]


def coefficient_scales(coeffs: dict, speed: float, nodes) -> np.ndarray:
    """Return the reference size (8 nb,) [N/m] of each unknown (K, then Omega C) from the coefficients ``coeffs``."""
    sk = [max(np.linalg.norm(coeffs[n][0]) / 2, 1e-300) for n in nodes]
    sc = [max(speed * np.linalg.norm(coeffs[n][1]) / 2, 1e-300) for n in nodes]
    return np.array([s for s in sk for _ in range(4)] + [s for s in sc for _ in range(4)])


def coefficient_jacobian(model, speed: float, coeffs: dict, probes, forces) -> tuple[np.ndarray, np.ndarray]:
    """
    (J, X): J complex (n_runs * nch, 8 nb) d X / d beta [m per N/m] and X complex (n_runs * nch,) [m].

    forces : list of complex (ndof,) 1X force phasors [N], one per run; probes : params.Probe list.
    beta = [K (per bearing xx, xy, yx, yy); Omega C (same)], bearings in ``model.bearing_nodes`` order.  The forward
    model and its exact Jacobian are the direct method's (:class:`bearing_id.identify.direct.SpeedResponse`, a film
    in series with a pedestal included), rows run by run.
    """
    nodes = tuple(model.bearing_nodes)
    nb = len(nodes)
    nch = len(probes)
    cases = [Case(np.asarray(F, dtype=complex), tuple(probes), np.zeros(nch, complex), np.ones(nch)) for F in forces]
    beta = coeffs_to_beta(coeffs, nodes)
    X, dX = SpeedResponse(model, speed, cases, nodes, beta)(beta)
    dX = dX.reshape(len(X), nb, 2, 4)                      # per bearing: K entries, then C entries (per N s/m)
    return np.concatenate([dX[:, :, 0].reshape(len(X), 4 * nb), dX[:, :, 1].reshape(len(X), 4 * nb) / speed],
                          axis=1), X


@dataclass
class Identifiability:
    """
    SVD analysis of a whitened, scaled information matrix (see :mod:`bearing_id.identify.design`).

    rel_std : 1-sigma relative to the coefficient scale over the noise-limited rank (NaN if undetermined there);
    data_rel_std : 1-sigma relative to the scale over the whole structural row space (the data-only sigma the one
    rule of :mod:`.determined` uses; inf where the coefficient is not structurally estimable); estimable : at most
    NULL_FRACTION of the unit vector in the structural null space.
    """

    singular_values: np.ndarray
    Vh: np.ndarray
    rank: int
    structural_rank: int
    unknowns: int
    condition: float
    determined: np.ndarray          # (unknowns,) bool
    rel_std: np.ndarray             # (unknowns,) 1-sigma relative to the coefficient scale, NaN if undetermined
    undetermined_combinations: list = field(default_factory=list)
    data_rel_std: np.ndarray | None = None
    estimable: np.ndarray | None = None


def analyse(Jw: np.ndarray, labels=None, *, max_rel_std=DEFAULT_MAX_REL_STD) -> Identifiability:
    """Return the identifiability of a real, whitened and scaled Jacobian ``Jw`` (m, n) (columns = scaled unknowns)."""
    Jw = np.asarray(Jw, dtype=float)
    n = Jw.shape[1]
    _, s, Vh = np.linalg.svd(Jw, full_matrices=True)
    sv = np.zeros(n)
    sv[:s.size] = s
    smax = sv[0] if sv.size and sv[0] > 0 else 1.0
    structural = int(np.count_nonzero(sv > STRUCTURAL_RTOL * smax))
    rank = int(np.count_nonzero(sv * max_rel_std >= 1.0))
    rank = min(rank, structural)
    null = Vh[rank:]
    leak = np.sum(null**2, axis=0)
    det = leak <= NULL_FRACTION
    Vr = Vh[:rank]
    with np.errstate(divide='ignore'):
        var = np.sum((Vr / sv[:rank, None]) ** 2, axis=0) if rank else np.zeros(n)
    rel_std = np.where(det, np.sqrt(var), np.nan)
    est = np.sum(Vh[structural:] ** 2, axis=0) <= NULL_FRACTION
    with np.errstate(divide='ignore'):
        var_s = np.sum((Vh[:structural] / sv[:structural, None]) ** 2, axis=0) if structural else np.full(n, np.inf)
    data_rel = np.where(est, np.sqrt(var_s), np.inf)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
    combos = []
    labels = labels or [f'p{k}' for k in range(n)]
    for v in null:
        big = np.argsort(-np.abs(v))
        terms = [f'{v[k]:+.2f} {labels[k]}' for k in big if abs(v[k]) >= 0.1][:6]
        combos.append(' '.join(terms))
    return Identifiability(sv, Vh, rank, structural, n, cond, det, rel_std, combos, data_rel, est)


def whitened_jacobian(model, speed, coeffs, probes, forces, noise_rel) -> tuple[np.ndarray, np.ndarray]:
    """(Jw real (2 n_runs nch, 8 nb), scales (8 nb,)): scaled coefficient Jacobian divided by the noise std."""
    nodes = list(model.bearing_nodes)
    J, X = coefficient_jacobian(model, speed, coeffs, probes, forces)
    scale = coefficient_scales(coeffs, speed, nodes)
    nch = len(probes)
    Xr = X.reshape(-1, nch)
    sig = noise_rel * np.sqrt(np.mean(np.abs(Xr) ** 2, axis=1))           # per run
    sig = np.repeat(np.maximum(sig, 1e-300), nch)
    Js = J * scale[None, :] / sig[:, None]
    return np.vstack([Js.real, Js.imag]), scale


# ------------------------------------------------------------------------------------------------ two-probe pairs
def node_xy_channels(probes) -> dict:
    """
    Return {node: {'x': ((channel, weight), ...), 'y': (...)}}: each probe node's x and y displacement as channels.

    A node with an x (or y) probe uses it ((channel, 1.0)); otherwise two non-parallel probes at any angle there
    (e.g. an API 670 pair at +-45 deg) give x and y by inverting their 2x2 measurement rows
    (:func:`bearing_id.conventions.probe_row`).
    """
    out: dict = {}
    nodes = []
    for p in probes:
        if p.node not in nodes:
            nodes.append(p.node)
    for n in nodes:
        at = [(c, p) for c, p in enumerate(probes) if p.node == n]
        m = {}
        for d in ('x', 'y'):
            c = next((c for c, p in at if p.direction == d), None)
            if c is not None:
                m[d] = ((c, 1.0),)
        if len(m) < 2:
            for i in range(len(at)):
                for j in range(i + 1, len(at)):
                    R = np.array([probe_row(at[i][1].direction), probe_row(at[j][1].direction)])
                    if abs(np.linalg.det(R)) > 1e-6 * np.abs(R).max() ** 2 and len(m) < 2:
                        Ri = np.linalg.inv(R)
                        for k, d in enumerate(('x', 'y')):
                            m.setdefault(d, ((at[i][0], float(Ri[k, 0])), (at[j][0], float(Ri[k, 1]))))
        if m:
            out[n] = m
    return out


def probe_pairs(model, probes, pairs=None) -> dict:
    """
    {(bearing_node, direction): ((channel, weight), ...)} for the interpolation: z = sum of weight x channel.

    Two probe nodes per bearing and direction, straight-line interpolation along the shaft; at each probe node the
    displacement in x (y) is its x (y) probe ((channel, 1 - t) and (channel, t)), or, for probes at other
    angles, the x (y) combination of two non-parallel probes there (:func:`node_xy_channels`).  Raises ValueError
    naming the bearing and direction that lack two probe nodes.
    """
    z = np.asarray(model.node_z, dtype=float)
    xy = node_xy_channels(probes)
    out = {}
    for n in model.bearing_nodes:
        zb = z[n - 1]
        for d in ('x', 'y'):
            chans = {k: v[d] for k, v in xy.items() if d in v}
            if pairs and n in pairs:
                na, nb_ = pairs[n]
                if na not in chans or nb_ not in chans:
                    raise ValueError(f'conventional: pair {pairs[n]} for bearing node {n} needs probes in {d} at '
                                     f'both nodes')
            else:
                if len(chans) < 2:
                    raise ValueError(f'conventional method: bearing at node {n} has {len(chans)} probe node(s) in '
                                     f'direction {d}; it needs two (one each side, or two on one side; a node '
                                     f'counts with an {d} probe or two non-parallel probes at any angle)')
                left = sorted((k for k in chans if z[k - 1] < zb), key=lambda k: zb - z[k - 1])
                right = sorted((k for k in chans if z[k - 1] >= zb), key=lambda k: z[k - 1] - zb)
                if left and right:
                    na, nb_ = left[0], right[0]
                else:
                    na, nb_ = (left or right)[:2]
            za, zz = z[na - 1], z[nb_ - 1]
            t = (zb - za) / (zz - za)
            out[(n, d)] = tuple((c, w * (1.0 - t)) for c, w in chans[na]) + tuple((c, w * t) for c, w in chans[nb_])
    return out


# ------------------------------------------------------------------------------------------------ result
def build_result(method, model, rig, speed, sol: LSSolution, *, probes, forces, X_std_rel, theory, truth=None,
                 max_rel_std=None, notes=(), extra=None, not_determined=None, pull=None, bias=None,
                 rank_cap=None) -> IdentResult:
    """
    Build the IdentResult from an LS solution, with the one rule of :mod:`bearing_id.identify.determined`.

    Per coefficient: estimable = LS-estimable and structurally estimable from the measured probes and runs
    (:func:`analyse` of the whitened Jacobian with the measured noise ``X_std_rel`` at the ``theory`` linearisation
    point); sigma = the larger of the LS std (Birge-scaled on a misfit of the LS system, :attr:`LSSolution.chi2`) and
    the data-only sigma of the measurements (what the probe data themselves can fix); determined = estimable,
    |value| >= 3 sigma, ``pull`` <= 0.1 and not in ``not_determined`` (the method's own vetoes, e.g. the
    conventional method's interpolation bias).

    X_std_rel : noise of the measured 1X vectors relative to their RMS amplitude (design noise model).
    theory : {node: (K, C)} the theory the method started from (linearisation point of the data check).
    pull : optional (8 nb,) d(identified) / d(theory) per coefficient (the paper method's theory sensitivity).
    bias : optional (8 nb,) the method's own estimate of its systematic error in theta units (the conventional
        method's interpolation bias); determined only when <= 0.5 sigma.
    rank_cap : optional upper bound on the reported rank.
    """
    nodes = tuple(model.bearing_nodes)
    nb = len(nodes)
    labels = coefficient_labels(nodes)
    Jw, scale = whitened_jacobian(model, speed, theory, probes, forces, X_std_rel)
    data = analyse(Jw, labels, max_rel_std=max_rel_std or DEFAULT_MAX_REL_STD)
    fq = fit_quality(sol.chi2, sol.dof)
    sigma_ls = sol.theta_std * fq.birge
    sigma_data = data.data_rel_std * scale
    sigma = np.where(np.isfinite(sigma_ls), np.fmax(sigma_ls, sigma_data), np.nan)
    estimable = sol.determined & data.estimable
    verdict = judge(sol.theta, sigma, estimable=estimable, pull=pull, veto=not_determined, bias=bias)
    det = verdict.determined
    K, C = theta_to_KC(sol.theta, speed, nb)
    Ks, Cs = theta_to_KC(np.where(det, sigma, np.nan), speed, nb)
    names = tuple(b.name for b in rig.bearings) if rig is not None else tuple(f'node{n}' for n in nodes)
    notes = list(notes)
    notes.append(f'eqs 33-37 system: rank {sol.rank} of {sol.unknowns} (SVD, relative tolerance '
                 f'{DEFAULT_RTOL:g}), condition {sol.condition:.3g}; measured data (probes '
                 f"{', '.join(p.name for p in probes)}, {len(forces)} run(s)): rank {data.rank} "
                 f'of {data.unknowns} (structural {data.structural_rank}; 1-sigma <= '
                 f'{100 * (max_rel_std or DEFAULT_MAX_REL_STD):g} % of the group size)')
    if fq.testable:
        notes.append('eqs 33-37 residual against the bearing-displacement noise: ' + fq.summary())
    if data.undetermined_combinations:
        notes.append('the data do not determine: ' + '; '.join(data.undetermined_combinations[:3])
                     + (' ...' if len(data.undetermined_combinations) > 3 else ''))
    vn = verdict.note(labels)
    if vn:
        notes.append(vn)
    th_err = eq38_error({n: (K[i], C[i]) for i, n in enumerate(nodes)}, theory)
    notes.append(f"distance from the theory the method was given (eq 38 mean): K {th_err['K']:.1f} %, "
                 f"C {th_err['C']:.1f} %")
    if truth is not None:
        tr = eq38_error(theory, truth)
        er = eq38_error({n: (K[i], C[i]) for i, n in enumerate(nodes)}, truth)
        notes.append(f"truth known: theory is off the truth by K {tr['K']:.1f} %, C {tr['C']:.1f} %; the result "
                     f"is off by K {er['K']:.1f} %, C {er['C']:.1f} %")
    if fq.misfit:
        notes.append(fq.misfit_note(f"the {method} method's eqs 33-37 model (bearing displacements -> forces)"))
    ex = {'theory': theory, 'f_B': sol.f_B, 'ls_rank': sol.rank, 'data_rank': data.rank,
          'data_structural_rank': data.structural_rank, 'singular_values': sol.singular_values,
          'fit_quality': fq, 'verdict': verdict}
    ex.update(extra or {})
    res = IdentResult(speed=float(speed), method=method, bearings=names, nodes=nodes, K=K, C=C, K_std=Ks,
                      C_std=Cs, K_determined=det[:4 * nb].reshape(nb, 2, 2),
                      C_determined=det[4 * nb:].reshape(nb, 2, 2),
                      rank=int(min(sol.rank, data.rank, sol.rank if rank_cap is None else rank_cap)),
                      unknowns=sol.unknowns, condition=sol.condition, residual=sol.residual, notes=notes, extra=ex)
    if fq.misfit:
        res.set_flag('misfit')
    return res


__all__ = ['DEFAULT_RTOL', 'STRUCTURAL_RTOL', 'NULL_FRACTION', 'DEFAULT_MAX_REL_STD', 'bearing_dofs',
           'bearing_forces', 'ls_system', 'LSSolution', 'svd_solve', 'bearing_force_map', 'solve_coefficients',
           'solve_derivatives',
           'theta_to_KC', 'coeffs_to_theta', 'noise_rel_of', 'forces_at', 'coefficient_labels', 'coefficient_scales',
           'coefficient_jacobian', 'Identifiability', 'analyse', 'whitened_jacobian', 'probe_pairs', 'node_xy_channels',
           'build_result']
