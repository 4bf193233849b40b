"""The paper's method (Kang et al., Sensors 2020, sections 3.1-3.2, eqs 5-37), done faithfully, reported honestly.

1. Kalman filter (:mod:`bearing_id.kalman`, eqs 5-18) on the FE state space with the THEORETICAL bearing
   coefficients at each speed and the known excitation as input estimates the bearing-node displacements from the
   measured probe(s).  Start rule: the KF's own (steady state of the model at the first sample); the window already
   had its first ``settle`` fraction removed (:mod:`.harmonics`).  R = the probe's residual variance around its 1X
   fit (data-based); Q = 1e-16 I by default (the paper's 1e-16 ... 1e-18).
2. 1X harmonic vectors of the estimates, per run: z_B (n_runs, nb, 2).
3. Eqs 19-37: with H_R(Omega) = K_R - Omega^2 M + j Omega (C_R + Omega G) the rotor WITHOUT bearings, the DOFs are
   reordered into b = (x, y) of the bearing nodes and u = everything else (all other translations AND every
   rotation, including the bearing nodes' rotations); eq 30  z_u = H_uu^-1 (F_u - H_ub z_B);  eqs 31-32
   f_B = F_b - H_bb z_B - H_bu z_u (the force the bearing exerts on the shaft is -f_B... here f_B = (K + j Omega C)
   z_B, the paper's sign); eqs 33-37 stack Re and Im of every run at this speed into a real least-squares system
   for the 8 nb unknowns [K; Omega C] (N/m both), solved by SVD.

Rank and uncertainty (stated rules)
    * LS rank: singular values above ``rtol`` (default 1e-8) x the largest.
    * Std: residual-based covariance sigma^2 (A^T A)^+ when there are more equations than unknowns; otherwise (the
      paper's two runs give 16 equations for 16 unknowns) the 1-sigma of z_B is propagated through the whole solve
      (finite differences); when both exist, the larger.
    * What the data determine: the KF can put nothing into z_B that the probes did not measure -- in directions the
      probe data do not constrain it returns the theory it was given.  The measurement Jacobian
      (:func:`bearing_id.identify.design.analyse`) with the measured noise decides which coefficients are
      determined; the others get determined=False and NaN std, and the notes say how far the result sits from the
      theory (and from the truth, when known).
    * How much of the answer is the theory (the data check above is necessary, not sufficient: with one probe
      location the KF's bearing-node estimates are pulled toward the model it was given, whatever the data rank).
      The steady-state filter is LTI, so its 1X bearing estimate is z_B = E Xp + T(Omega) (X - H Xp)
      (:func:`kf_bearing_phasors`; equal to the time-domain filter's fitted 1X up to its start transient, the
      difference is reported).  Each theory coefficient is moved by THEORY_STEP (1 %) of its bearing group's size,
      the KF + eqs 30-37 re-run, giving the scaled Jacobian G = d identified / d theory
      (:func:`theory_sensitivity`).  Per coefficient d(identified)/d(theory) = its row norm of G; above
      THEORY_FLAG = 0.5 the coefficient follows the KF's theory more than the data: determined=False, named in the
      notes.  The theory fraction ||G||_F^2 / 16 (0 = the data alone, 1 = the theory handed back, > 1 theory errors
      amplified) is in the notes and ``extra['theory_fraction']``; the reported rank is capped by the number of
      directions the data fix (singular values of G <= THEORY_FLAG).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..conventions import dof_index
from .result import IdentResult, eq38_error

DEFAULT_RTOL = 1e-8
DEFAULT_Q = 1e-16


# ------------------------------------------------------------------------------------------------ eqs 19-32
def bearing_dofs(model, nodes=None) -> np.ndarray:
    """0-based DOF indices [x_B1, y_B1, x_B2, y_B2, ...] of the bearing nodes (the reordered 'b' block)."""
    nodes = model.bearing_nodes if nodes is None else nodes
    return np.array([dof_index(n, d, model.n_nodes) for n in nodes for d in ("x", "y")])


def bearing_forces(model, speed: float, z_B, forces) -> np.ndarray:
    """Eqs 30-32: bearing forces f_B (n_runs, nb, 2) [N] from bearing-node phasors z_B (n_runs, nb, 2) [m].

    forces : complex (n_runs, ndof) 1X excitation phasors [N].  H_R is the rotor without bearings at 1X.
    """
    from ..rotor.assembly import dynamic_stiffness
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


def ls_system(z_B, f_B) -> tuple[np.ndarray, np.ndarray]:
    """Eqs 33-36 as a real system A theta = d over all runs; theta = [K_b (xx,xy,yx,yy) per bearing; Omega C_b].

    z_B, f_B complex (n_runs, nb, 2).  Rows: for each run, bearing, row i in (x, y): Re then Im parts.
    Returns A (2 n_runs 2 nb, 8 nb) [m] and d (same rows,) [N].
    """
    z_B = np.asarray(z_B, dtype=complex)
    f_B = np.asarray(f_B, dtype=complex)
    nr, nb = z_B.shape[:2]
    Ac = np.zeros((nr, nb, 2, 8 * nb), dtype=complex)
    for b in range(nb):
        for i in range(2):
            for j in range(2):
                Ac[:, b, i, 4 * b + 2 * i + j] = z_B[:, b, j]
                Ac[:, b, i, 4 * nb + 4 * b + 2 * i + j] = 1j * z_B[:, b, j]
    Ac = Ac.reshape(-1, 8 * nb)
    dc = f_B.reshape(-1)
    return np.vstack([Ac.real, Ac.imag]), np.concatenate([dc.real, dc.imag])


@dataclass
class LSSolution:
    """Solution of the eqs 33-37 system at one speed (theta = [K; Omega C] flat, bearings in model order)."""
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


def _svd_solve(A, d, rtol):
    U, s, Vh = np.linalg.svd(A, full_matrices=False)
    n = A.shape[1]
    r = int(np.count_nonzero(s > rtol * s[0])) if s.size and s[0] > 0 else 0
    theta = Vh[:r].T @ ((U[:, :r].T @ d) / s[:r])
    return theta, U, s, Vh, r, n


def solve_coefficients(model, speed: float, z_B, forces, *, z_B_std=None, rtol: float = DEFAULT_RTOL) -> LSSolution:
    """Eqs 30-37 at one ``speed`` [rad/s]: bearing coefficients from bearing-node phasors of every run.

    z_B complex (n_runs, nb, 2) [m]; forces complex (n_runs, ndof) [N]; z_B_std (n_runs, nb, 2) 1-sigma of the Re
    and of the Im part of z_B [m] (optional, for the propagated std).  See the module docstring for the rules.
    This is the one solve shared by the paper and the conventional methods.
    """
    z_B = np.asarray(z_B, dtype=complex)
    forces = np.asarray(forces, dtype=complex)

    def theta_of(z):
        A, d = ls_system(z, bearing_forces(model, speed, z, forces))
        return _svd_solve(A, d, rtol)[0]

    f_B = bearing_forces(model, speed, z_B, forces)
    A, d = ls_system(z_B, f_B)
    theta, U, s, Vh, r, n = _svd_solve(A, d, rtol)
    res = A @ theta - d
    dn = np.linalg.norm(d)
    residual = float(np.linalg.norm(res) / dn) if dn > 0 else math.nan
    null = Vh[r:] if r < n else np.zeros((0, n))
    if r < n and Vh.shape[0] < n:          # fewer equations than unknowns: complete the null space
        _, _, Vfull = np.linalg.svd(A, full_matrices=True)
        null = Vfull[r:]
    determined = np.sum(null**2, axis=0) <= 0.01
    var = np.zeros(n)
    var_res = None
    dof = A.shape[0] - r
    if dof > 0 and r > 0:
        sig2 = float(res @ res) / dof
        var_res = sig2 * np.sum((Vh[:r] / s[:r, None]) ** 2, axis=0)
        var = np.maximum(var, var_res)
    consistency = math.nan
    if z_B_std is not None:
        zs = np.asarray(z_B_std, dtype=float)
        h = 1e-6 * max(np.max(np.abs(z_B)), 1e-30)
        vp = np.zeros(n)
        for idx in np.ndindex(z_B.shape):
            for unit in (1.0, 1j):
                if zs[idx] <= 0:
                    continue
                z1 = z_B.copy()
                z1[idx] += unit * h
                z2 = z_B.copy()
                z2[idx] -= unit * h
                g = (theta_of(z1) - theta_of(z2)) / (2 * h)
                vp += (g * zs[idx]) ** 2
        var = np.maximum(var, vp)
        if var_res is not None and np.any(vp > 0):
            ok = vp > 0
            consistency = float(np.median(np.sqrt(var_res[ok] / vp[ok])))
    std = np.where(determined, np.sqrt(var), np.nan)
    cond = float(s[0] / s[-1]) if s.size == n and s[-1] > 0 else math.inf
    return LSSolution(theta, std, determined, r, n, cond, residual, s, f_B, consistency)


def theta_to_KC(theta, speed: float, nb: int) -> tuple[np.ndarray, np.ndarray]:
    """theta = [K flat; Omega C flat] -> K (nb, 2, 2) [N/m], C (nb, 2, 2) [N s/m]."""
    theta = np.asarray(theta, dtype=float)
    return theta[:4 * nb].reshape(nb, 2, 2), theta[4 * nb:].reshape(nb, 2, 2) / speed


def coeffs_to_theta(coeffs: dict, speed: float, nodes) -> np.ndarray:
    """{node: (K, C)} -> theta [K flat per bearing; Omega C flat per bearing]."""
    return np.concatenate([np.concatenate([np.asarray(coeffs[n][0], float).reshape(4) for n in nodes]),
                           np.concatenate([speed * np.asarray(coeffs[n][1], float).reshape(4) for n in nodes])])


# ------------------------------------------------------------------------------------------------ result
def build_result(method, model, rig, speed, sol: LSSolution, *, probes, forces, X_std_rel, theory, truth=None,
                 max_rel_std=None, notes=(), extra=None, not_determined=None, rank_cap=None) -> IdentResult:
    """IdentResult from an LS solution, with the data-determination check of the measured probes and runs.

    X_std_rel : noise of the measured 1X vectors relative to their RMS amplitude (design noise model).
    theory : {node: (K, C)} the theory the method started from (linearisation point of the data check).
    not_determined : optional bool (8 nb,) of coefficients the method itself cannot vouch for (the paper method's
        theory-dominated ones, the conventional method's interpolation-biased ones); they are also undetermined.
    rank_cap : optional upper bound on the reported rank (e.g. the number of directions the data, not the theory,
        fix in the paper method).
    """
    from .design import DEFAULT_MAX_REL_STD, analyse, coefficient_labels, whitened_jacobian
    nodes = tuple(model.bearing_nodes)
    nb = len(nodes)
    Jw, _ = whitened_jacobian(model, speed, theory, probes, forces, X_std_rel)
    data = analyse(Jw, coefficient_labels(nodes), max_rel_std=max_rel_std or DEFAULT_MAX_REL_STD)
    det = sol.determined & data.determined
    if not_determined is not None:
        det = det & ~np.asarray(not_determined, dtype=bool)
    K, C = theta_to_KC(sol.theta, speed, nb)
    Ks, Cs = theta_to_KC(np.where(det, sol.theta_std, np.nan), speed, nb)
    names = tuple(b.name for b in rig.bearings) if rig is not None else tuple(f"node{n}" for n in nodes)
    notes = list(notes)
    notes.append(f"eqs 33-37 system: rank {sol.rank} of {sol.unknowns} (SVD, relative tolerance "
                 f"{DEFAULT_RTOL:g}), condition {sol.condition:.3g}; measured data (probes "
                 f"{', '.join(f'{p.node}{p.direction}' for p in probes)}, {len(forces)} run(s)): rank {data.rank} "
                 f"of {data.unknowns} (structural {data.structural_rank}; 1-sigma <= {100 * (max_rel_std or DEFAULT_MAX_REL_STD):g} %)")
    if data.undetermined_combinations:
        notes.append("the data do not determine: " + "; ".join(data.undetermined_combinations[:3])
                     + (" ..." if len(data.undetermined_combinations) > 3 else ""))
    th_err = eq38_error({n: (K[i], C[i]) for i, n in enumerate(nodes)}, theory)
    notes.append(f"distance from the theory the method was given (eq 38 mean): K {th_err['K']:.1f} %, "
                 f"C {th_err['C']:.1f} %")
    if truth is not None:
        tr = eq38_error(theory, truth)
        er = eq38_error({n: (K[i], C[i]) for i, n in enumerate(nodes)}, truth)
        notes.append(f"truth known: theory is off the truth by K {tr['K']:.1f} %, C {tr['C']:.1f} %; the result "
                     f"is off by K {er['K']:.1f} %, C {er['C']:.1f} %")
    ex = {"theory": theory, "f_B": sol.f_B, "ls_rank": sol.rank, "data_rank": data.rank,
          "data_structural_rank": data.structural_rank, "singular_values": sol.singular_values}
    ex.update(extra or {})
    return IdentResult(speed=float(speed), method=method, bearings=names, nodes=nodes, K=K, C=C, K_std=Ks,
                       C_std=Cs, K_determined=det[:4 * nb].reshape(nb, 2, 2),
                       C_determined=det[4 * nb:].reshape(nb, 2, 2),
                       rank=int(min(sol.rank, data.rank, sol.rank if rank_cap is None else rank_cap)),
                       unknowns=sol.unknowns, condition=sol.condition, residual=sol.residual, notes=notes, extra=ex)


def noise_rel_of(data, s: int) -> float:
    """Measured noise of the 1X vectors at speed index ``s`` relative to the RMS amplitude (design noise model)."""
    amp = np.sqrt(np.mean(np.abs(data.X[:, s]) ** 2))
    sd = np.sqrt(np.mean(data.X_std[:, s] ** 2))
    return float(max(sd / amp if amp > 0 else 1.0, 1e-9))


def forces_at(model, runs, speed: float) -> np.ndarray:
    """Complex (n_runs, ndof) 1X excitation phasors [N] of ``runs`` at ``speed`` [rad/s]."""
    from ..excitation import harmonic_forces
    out = []
    for r in runs:
        F = harmonic_forces(r.excitation, speed, model.n_nodes).get(1.0)
        out.append(F if F is not None else np.zeros(model.ndof, dtype=complex))
    return np.array(out)


# ------------------------------------------------------------------------------------------------ KF route
def kf_bearing_vectors(model, theory, probes, data, s: int, *, Q=DEFAULT_Q, R=None, smoother=False):
    """KF (theory coefficients) bearing-node 1X vectors at speed index ``s``.

    Returns (z_B (nr, nb, 2), z_B_std (nr, nb, 2), NIS means (nr,), the KalmanModel of the first run).
    R default: each probe's residual variance around its 1X fit (first run) [m^2].
    """
    from ..excitation import harmonic_forces
    from ..kalman import fast_filter, rotor_kalman_model, rts_smoother
    from ..signals import harmonic_vectors
    if not data.recordings:
        raise ValueError("the paper method's Kalman filter needs the time series (recordings), not only 1X vectors")
    w = float(data.speeds[s])
    nb = len(model.bearing_nodes)
    zs, zsd, nis = [], [], []
    km = km0 = None
    for r, run in enumerate(data.runs):
        rec = data.recordings[r]
        i0, i1 = data.windows[r][s]
        y, a = rec.samples[i0:i1], rec.angle[i0:i1]
        forces = harmonic_forces(run.excitation, w, model.n_nodes)
        if km is None:
            if R is None:
                fit = harmonic_vectors(y, a)
                Rv = np.maximum(fit.residual_rms ** 2, 1e-30)
            else:
                Rv = R
            km = km0 = rotor_kalman_model(model, w, theory, probes, rec.sample_rate, forces=forces, Q=Q, R=Rv)
        else:
            km = km.with_forces(forces, w)
        out = (rts_smoother if smoother else fast_filter)(km, y, a)
        fit = harmonic_vectors(out.estimates, a)
        zs.append(fit.X[0].reshape(nb, 2))
        zsd.append(np.maximum(fit.std_re[0], fit.std_im[0]).reshape(nb, 2))
        nis.append(out.nis_mean)
    return np.array(zs), np.array(zsd), nis, km0


def kf_transfer(km, speed: float, *, smoother: bool = False) -> np.ndarray:
    """Steady-state filter's 1X transfer (k, m) complex: output phasor per unit pseudo-measurement phasor.

    The steady-state filter on the deviation from the model's forced response is LTI,
    e(k|k) = (I - K H) Phi e(k-1|k-1) + K y_k, so a 1X input y_k = Re{Y exp(j phi_k)} (phi advancing by
    speed * dt per sample) gives, once its own transient has died out,
    E_f = (I - exp(-j speed dt) (I - K H) Phi)^-1 K Y.  The RTS smoother's recursion
    e_s(k) = (I - Cs Phi) e(k|k) + Cs e_s(k+1) gives E_s = (I - exp(j speed dt) Cs)^-1 (I - Cs Phi) E_f.
    Returns E T with T the (n, m) state transfer (E = the model's output rows).
    """
    P, K, _ = km.steady_state()
    n = km.n
    I = np.eye(n)
    IKH = I - K @ km.H
    ph = np.exp(1j * float(speed) * km.dt)
    T = np.linalg.solve(I - IKH @ km.Phi / ph, K.astype(complex))
    if smoother:
        Ppost = IKH @ P
        Cs = np.linalg.solve(P.T, (Ppost @ km.Phi.T).T).T
        T = np.linalg.solve(I - ph * Cs, (I - Cs @ km.Phi) @ T)
    return km.E @ T


def kf_bearing_phasors(model, theory, probes, speed: float, X, forces, sample_rate: float, *, Q=DEFAULT_Q, R,
                       smoother: bool = False) -> np.ndarray:
    """Bearing-node 1X phasors (nr, nb, 2) of the steady-state KF, in the frequency domain (no time series).

    z_B,r = E Xp_r + T (X_r - H Xp_r): Xp_r the theory model's forced state response to run r, T
    :func:`kf_transfer`, X (nr, nch) the measured probe phasors [m], forces complex (nr, ndof) 1X phasors [N]
    (:func:`forces_at`).
    Equals the time-domain filter's fitted 1X (:func:`kf_bearing_vectors`) up to the filter's start transient; it is
    the route used for the sensitivity to the theory (:func:`theory_sensitivity`).
    """
    from ..kalman import rotor_kalman_model
    nb = len(model.bearing_nodes)
    km = rotor_kalman_model(model, speed, theory, probes, sample_rate, forces=None, Q=Q, R=R)
    T = kf_transfer(km, speed, smoother=smoother)
    X = np.asarray(X, dtype=complex)
    out = np.zeros((len(forces), nb, 2), dtype=complex)
    for r, F1 in enumerate(np.asarray(forces, dtype=complex)):
        Xp = km.with_forces({1.0: F1}, speed).Xp[1.0]
        out[r] = (km.E @ Xp + T @ (X[r] - km.H @ Xp)).reshape(nb, 2)
    return out


THEORY_FLAG = 0.5       # a coefficient with d(identified)/d(theory) above this follows the KF's theory, not the data
THEORY_STEP = 0.01      # theory perturbation of the sensitivity (fraction of each bearing group's size)


def theory_sensitivity(model, speed: float, theory: dict, z_B_of, forces, *, rtol=DEFAULT_RTOL,
                       step: float = THEORY_STEP) -> np.ndarray:
    """Scaled Jacobian G (8 nb, 8 nb) of the identified coefficients with respect to the theory fed to the KF.

    z_B_of : theory {node: (K, C)} -> bearing-node phasors (nr, nb, 2) (e.g. :func:`kf_bearing_phasors`).
    forces : complex (nr, ndof) 1X phasors [N].  Each theory coefficient k (order of :func:`coeffs_to_theta`) is
    moved by ``step`` x its bearing group's size s_k (:func:`bearing_id.identify.design.coefficient_scales`), the
    KF and the eqs 30-37 solve are re-run, and G[i, k] = (d theta_i / s_i) / (d theta_th_k / s_k).
    G = 0: the data alone fix the result; G = I: the method hands back the theory it was given.
    """
    from .design import coefficient_scales
    nodes = tuple(model.bearing_nodes)
    nb = len(nodes)
    th0 = coeffs_to_theta(theory, speed, nodes)
    sc = coefficient_scales(theory, speed, nodes)

    def theta_of(co):
        z = z_B_of(co)
        A, d = ls_system(z, bearing_forces(model, speed, z, forces))
        return _svd_solve(A, d, rtol)[0]

    base = theta_of(theory)
    G = np.zeros((8 * nb, 8 * nb))
    for k in range(8 * nb):
        th = th0.copy()
        th[k] += step * sc[k]
        K, C = theta_to_KC(th, speed, nb)
        G[:, k] = (theta_of({n: (K[i], C[i]) for i, n in enumerate(nodes)}) - base) / sc / step
    return G


def theory_fractions(G: np.ndarray) -> tuple[np.ndarray, float]:
    """(per-coefficient d(identified)/d(theory) = row 2-norms of the scaled Jacobian, overall theory fraction).

    The overall fraction is ||G||_F^2 / n: 1 when the result is the theory, 0 when it is the data's alone, k/n when
    k of the n directions come from the theory (G an orthogonal projector of rank k).
    """
    G = np.asarray(G, dtype=float)
    return np.linalg.norm(G, axis=1), float(np.sum(G ** 2) / G.shape[0])


def identify_paper(model, rig, data, probes, runs, options=None) -> list[IdentResult]:
    """The paper's method per speed (see module docstring).  Signature as in :mod:`bearing_id.identify`.

    options : 'bearing_fn' (theory, default the nominal bearings of ``rig``), 'Q' (default 1e-16), 'R' (default:
    the probe residual variance), 'smoother' (RTS instead of the filter; default False), 'rtol' (1e-8),
    'max_rel_std' (design threshold, 0.05), 'z_B' (complex (n_runs, n_speeds, nb, 2): bypass the KF with given
    bearing-node phasors, e.g. the exact ones, to test the algebra), 'z_B_std' (same shape, real), 'z_B_kf'
    ({'Q': ..., 'R': ..., 'sample_rate': Hz[, 'smoother': bool]}: the given z_B came from a KF with these settings
    and the theory of 'bearing_fn' -- e.g. the kf_estimator node's -- so the theory-dominance check is run on them;
    without it given z_B are taken as measured and no theory check is made).
    """
    opts = dict(options or {})
    allowed = {"bearing_fn", "Q", "R", "smoother", "rtol", "max_rel_std", "z_B", "z_B_std", "z_B_kf"}
    bad = set(opts) - allowed
    if bad:
        raise ValueError(f"identify_paper: unknown option(s) {sorted(bad)}; allowed {sorted(allowed)}")
    bfn = opts.get("bearing_fn")
    if bfn is None:
        from ..rig import nominal_bearing_fn
        bfn = nominal_bearing_fn(rig)
    out = []
    for s, w in enumerate(data.speeds):
        w = float(w)
        theory = bfn(w)
        F = forces_at(model, runs, w)
        notes = []
        not_det, extra = None, {}
        if opts.get("z_B") is not None:
            zB = np.asarray(opts["z_B"])[:, s]
            zBs = None if opts.get("z_B_std") is None else np.asarray(opts["z_B_std"])[:, s]
            kf = opts.get("z_B_kf")
            if kf is None:
                notes.append("bearing-node displacements given (no Kalman filter)")
            else:
                notes.append(f"bearing-node displacements given by a Kalman filter (Q = {kf['Q']:g})")
                not_det, extra = _theory_check(model, w, theory, probes, data.X[:, s], F, float(kf["sample_rate"]),
                                               kf["Q"], kf["R"], bool(kf.get("smoother", False)),
                                               opts.get("rtol", DEFAULT_RTOL), zB, notes)
        else:
            Q, smooth = opts.get("Q", DEFAULT_Q), bool(opts.get("smoother", False))
            zB, zBs, nis, km = kf_bearing_vectors(model, theory, probes, data, s, Q=Q, R=opts.get("R"),
                                                  smoother=smooth)
            notes.append(f"Kalman filter (theory coefficients, Q = {Q:g}); mean NIS per run "
                         + ", ".join(f"{v:.2f}" for v in nis))
            not_det, extra = _theory_check(model, w, theory, probes, data.X[:, s], F, data.recordings[0].sample_rate,
                                           Q, km.R, smooth, opts.get("rtol", DEFAULT_RTOL), zB, notes)
            # how much the KF moved the bearing displacements away from the theory model's prediction
            from ..rotor.assembly import harmonic_response
            zth = np.array([harmonic_response(model, w, w, f, theory)[_bdofs(model)].reshape(-1, 2) for f in F])
            dz = np.linalg.norm(zB - zth) / max(np.linalg.norm(zth), 1e-300)
            notes.append(f"KF bearing displacements differ from the theory model's prediction by {100 * dz:.1f} %")
        sol = solve_coefficients(model, w, zB, F, z_B_std=zBs, rtol=opts.get("rtol", DEFAULT_RTOL))
        out.append(build_result("paper", model, rig, w, sol, probes=probes, forces=list(F),
                                X_std_rel=noise_rel_of(data, s), theory=theory, truth=data.truth_at(w),
                                max_rel_std=opts.get("max_rel_std"), notes=notes, extra={"z_B": zB, **extra},
                                not_determined=not_det, rank_cap=extra.get("data_directions")))
    return out


def _theory_check(model, speed, theory, probes, X, F, sample_rate, Q, R, smoother, rtol, zB_kf, notes):
    """Sensitivity of the result to the KF's theory: (mask of theory-dominated coefficients, extra dict); notes."""
    from .design import coefficient_labels

    def zb_of(co):
        return kf_bearing_phasors(model, co, probes, speed, X, F, sample_rate, Q=Q, R=R, smoother=smoother)

    za = zb_of(theory)
    mism = float(np.linalg.norm(za - zB_kf) / max(np.linalg.norm(zB_kf), 1e-300))
    G = theory_sensitivity(model, speed, theory, zb_of, F, rtol=rtol)
    sens, frac = theory_fractions(G)
    flag = sens > THEORY_FLAG
    data_dirs = int(np.count_nonzero(np.linalg.svd(G, compute_uv=False) <= THEORY_FLAG))
    labels = coefficient_labels(model.bearing_nodes)
    notes.append(f"theory fraction {frac:.2f} (||d identified / d theory||_F^2 / {G.shape[0]} with the KF's theory "
                 f"moved by {100 * THEORY_STEP:g} % of each group's size; 0 = the data alone, 1 = the filter hands "
                 f"back its theory, > 1 = theory errors amplified); d(identified)/d(theory) per coefficient "
                 f"{np.min(sens):.2f} ... {np.max(sens):.2f}; {data_dirs} of {G.shape[0]} directions come from "
                 f"the data (singular values of the sensitivity <= {THEORY_FLAG:g}): rank capped there")
    if flag.any():
        notes.append(f"{int(flag.sum())} of {flag.size} coefficients follow the KF's theory more than the data "
                     f"(d identified / d theory > {THEORY_FLAG:g}): "
                     + ", ".join(lab for lab, f in zip(labels, flag) if f) + " -- not determined by the data")
    if mism > 0.05:
        notes.append(f"the KF's fitted 1X differs from its steady-state transfer by {100 * mism:.1f} % (a transient "
                     f"in the window): the theory fraction is approximate")
    return flag, {"theory_sensitivity": sens, "theory_fraction": frac, "theory_jacobian": G,
                  "kf_transfer_mismatch": mism, "data_directions": data_dirs}


def _bdofs(model):
    return bearing_dofs(model)


__all__ = ["bearing_dofs", "bearing_forces", "ls_system", "LSSolution", "solve_coefficients", "theta_to_KC",
           "coeffs_to_theta", "build_result", "noise_rel_of", "forces_at", "kf_bearing_vectors", "kf_transfer",
           "kf_bearing_phasors", "theory_sensitivity", "theory_fractions", "identify_paper", "THEORY_FLAG",
           "THEORY_STEP"]
