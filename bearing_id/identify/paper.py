"""
The paper's method (Kang et al., Sensors 2020, sections 3.1-3.2, eqs 5-37), done faithfully, reported honestly.

1. Kalman filter (:mod:`bearing_id.estimation.kalman`, eqs 5-18) on the FE state space with the THEORETICAL bearing
   coefficients at each speed and the known excitation as input estimates the bearing-node displacements from the
   measured probe(s).  Start rule: the KF's own (steady state of the model at the first sample); the window already
   had its first ``settle`` fraction removed (:mod:`.harmonics`).  R = the probe's residual variance around its 1X
   fit (data-based); Q = 1e-16 I by default (the paper's 1e-16 ... 1e-18).
2. 1X harmonic vectors of the estimates, per run: z_B (n_runs, nb, 2).  The steady-state filter is LTI, so on a
   steady window its 1X response is a closed form, the filter's transfer function at the running speed:
   z_B = E Xp + T(Omega) (X - H Xp) with X the probes' 1X fit of the same window (:func:`kf_bearing_vectors`) --
   what a 1X fit of the time-domain filter's estimates gives once the filter's start transient has died out
   (test/test_kf_transfer.py runs filterpy's filter on a steady window to check it), without that transient.  The
   filter does run on the samples for its consistency check: the mean NIS comes from its time-domain innovations.
3. Eqs 19-37: with H_R(Omega) = K_R - Omega^2 M + j Omega (C_R + Omega G) the rotor WITHOUT bearings, the DOFs are
   reordered into b = (x, y) of the bearing nodes and u = everything else (all other translations AND every
   rotation, including the bearing nodes' rotations); eq 30  z_u = H_uu^-1 (F_u - H_ub z_B);  eqs 31-32
   f_B = F_b - H_bb z_B - H_bu z_u (the force the bearing exerts on the shaft is -f_B... here f_B = (K + j Omega C)
   z_B, the paper's sign); eqs 33-37 stack Re and Im of every run at this speed into a real least-squares system
   for the 8 nb unknowns [K; Omega C] (N/m both), solved by SVD.

Static offset: a probe's DC (its gap) is no state of the model; each window's DC is removed before the KF
(:func:`kf_bearing_vectors`), and the mean NIS is reported against its chi-square band.

Rank and uncertainty (stated rules; the shared solve and result are in :mod:`.lsq`)
    * LS rank: singular values above ``rtol`` (default 1e-8) x the largest.
    * Std: the 1-sigma of z_B propagated through the whole solve (its exact derivative); without it the residual-based
      covariance sigma^2 (A^T A)^+ when there are more equations than unknowns.  With more runs than the paper's two
      the eqs 33-37 residual is a chi-square test against the z_B noise (:func:`bearing_id.identify.lsq.
      solve_coefficients`); a misfit Birge-scales the std and flags the result.
    * What the data determine: the KF can put nothing into z_B that the probes did not measure -- in directions the
      probe data do not constrain it returns the theory it was given.  The one rule of
      :mod:`bearing_id.identify.determined` decides, with the data-only sigma of the measured probes and runs
      (:func:`bearing_id.identify.lsq.analyse` of the measurement Jacobian with the measured noise) as a floor under
      the std, and the theory sensitivity below as the prior's pull (<= 0.1); the others get determined=False and NaN
      std, and the notes say how far the result sits from the theory (and from the truth, when known).
    * How much of the answer is the theory (the data check above is necessary, not sufficient: with one probe
      location the KF's bearing-node estimates are pulled toward the model it was given, whatever the data rank).
      The scaled Jacobian G = d identified / d theory of the 1X route above is computed analytically
      (:func:`kf_phasor_jacobian`: the derivative of z_B through Xp, expm (Frechet, in the eigenbasis of A) and the
      Riccati solution (a Stein equation in the eigenbasis of the closed loop), chained with the derivative of the
      eqs 30-37 solve, :func:`ls_jacobian`; no Riccati equation is re-solved).  Where that derivative is not
      available -- the RTS smoother's transfer, or an eigenvector basis too ill-conditioned to use -- each theory
      coefficient is moved by THEORY_STEP = 1 % of its bearing group's size and the KF + eqs 30-37 re-run
      (:func:`theory_sensitivity`, forward differences: a secant, within ~0.2 % of the tangent).  Per coefficient
      d(identified)/d(theory) = its row norm of G = the pull of the theory on it (determined only when <= 0.1);
      above THEORY_FLAG = 0.5 the coefficient follows the KF's theory more than the data, named in the notes.  The
      theory fraction ||G||_F^2 / 16 (0 = the data alone, 1 = the theory handed back, > 1 theory errors amplified) is
      in the notes and ``extra['theory_fraction']``; the reported rank is capped by the number of directions the data
      fix (singular values of G <= THEORY_FLAG).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.linalg import matrix_balance

from .harmonics import PlainFit
from .lsq import (bearing_dofs, bearing_force_map, bearing_forces, build_result, coefficient_labels, coefficient_scales,
                  coeffs_to_theta, DEFAULT_RTOL, forces_at, ls_system, LSSolution, noise_rel_of, solve_coefficients,
                  solve_derivatives, svd_solve, theta_to_KC)
from .result import IdentResult
from ..config import defaults
from ..estimation.kalman import forced_states, innovations, rotor_kalman_model
from ..rotor.assembly import bearing_matrices
from ..rotor.reduction import craig_bampton, kf_kept_dofs, receptance_error
from ..rotor.supports import bearing_fn
from ..signals.harmonics import harmonic_vectors


# ------------------------------------------------------------------------------------------------ KF route
def _kf_models(model, speed: float, theory, probes, sample_rate: float, Q, Rs, kf_rotor=None) -> list:
    """
    One KalmanModel per run (R per run in ``Rs``), sharing the state space and Phi (one expm per speed).

    Runs with equal R share the model object, so each distinct R's Riccati equation is solved once.  ``kf_rotor``: a
    :class:`bearing_id.rotor.reduction.ReducedRotor` of ``model`` to filter on (default the full model).
    """
    km0 = rotor_kalman_model(model if kf_rotor is None else kf_rotor, speed, theory, probes, sample_rate,
                             forces=None, Q=Q, R=Rs[0])
    seen, out = {}, []
    for R in Rs:
        key = _rkey(R)
        if key not in seen:
            seen[key] = km0 if not seen else km0.with_noise(R)
        out.append(seen[key])
    return out


def _sample_rate(data, required: bool = True) -> float | None:
    """Return the sample rate [Hz] of the data's recordings (or of the live identifier's windows); None if unknown."""
    fs = data.sample_rate or (data.recordings[0].sample_rate if data.recordings else None)
    if not fs and required:
        raise ValueError("the paper method's Kalman filter needs the sample rate of the recordings")
    return float(fs) if fs else None


def kf_bearing_vectors(model, theory, probes, data, s: int, *, Q=defaults.KF_PROCESS_NOISE, R=None, smoother=False,
                       remove_dc: bool = True, details: dict | None = None, jacobian=False, kf_rotor=None):
    """
    KF (theory coefficients) bearing-node 1X vectors at speed index ``s``: (z_B, z_B_std (nr, nb, 2), NIS means, km).

    z_B = E Xp + T (X - H Xp) per run (:func:`kf_bearing_phasors`): the steady-state filter's closed-form 1X response
    (:func:`kf_transfer`; the RTS smoother's with ``smoother``) to each window's plain 1X fit X (``data.plain``, or
    fitted here from the recordings), its std propagated from the fit's (var Re/Im z = sum |T|^2 var X).  R default:
    each probe's residual variance around that fit, per run [m^2] (the rig's and a real probe's noise differ between
    runs; one R for all runs put the NIS of the louder run outside its band).  The live identifier carries these fits
    with its vectors, so it gets the same z_B without the time series.

    The NIS needs the time series: computed when the data carry their recordings (offline), from the steady-state
    filter's time-domain innovations (:func:`bearing_id.estimation.kalman.innovations`), else None.  Static offset: a
    displacement probe reads gap + vibration; the gap (DC) is no state of the rotor model, so a filter fed it sees a
    constant innovation the size of the gap (NIS 1e5 instead of ~m).  With ``remove_dc`` (default) each window's DC,
    estimated by the 1X-plus-offset least-squares fit over whole revolutions
    (:func:`bearing_id.signals.harmonics.harmonic_vectors`, unbiased by the 1X), is subtracted from the samples first.
    ``details`` (a dict, optional) receives 'dc' (nr, nch) [m] removed, 'nis_band' and 'R' (m, m) per run, 'X'
    (nr, nch) the probes' 1X fit, 'kms' the per-run KalmanModels, 'Xp' the forced states and, with ``jacobian``,
    'dz' = d z_B / d theta_th (:func:`kf_phasor_jacobian`; None for the smoother or an ill-conditioned eigenbasis).
    """
    w = float(data.speeds[s])
    nr = len(data.runs)
    fs = _sample_rate(data)
    timed = bool(data.recordings) and bool(data.windows)
    ys, angs, plains, dcs = [], [], [], []
    for r in range(nr):
        fit = None
        if timed:
            i0, i1 = data.windows[r][s]
            y = np.asarray(data.recordings[r].samples[i0:i1], dtype=float)
            a = np.asarray(data.recordings[r].angle[i0:i1], dtype=float)
            fit = harmonic_vectors(y, a)      # 1X + offset over whole revolutions: the DC, the 1X and the noise
            if remove_dc:
                y = y - np.asarray(fit.offset, dtype=float)[None, :]
                dcs.append(np.asarray(fit.offset, dtype=float))
            ys.append(y)
            angs.append(a)
        if data.plain is not None:
            plains.append(data.plain.take((r, s)))
        elif fit is not None:
            plains.append(PlainFit.of(fit))
        else:
            raise ValueError("the paper method's Kalman filter needs each window's plain 1X fit (HarmonicData.plain) "
                             'or the recordings')
    X = np.array([p.X for p in plains])
    Rs = [np.maximum(p.noise_var, 1e-30) if R is None else R for p in plains]
    kms = _kf_models(model, w, theory, probes, fs, Q, Rs, kf_rotor)
    F = forces_at(model, data.runs, w)
    Xp = forced_states(kms[0].A, kms[0].B, F, w)
    Ts = {}
    dz = None
    if jacobian and not smoother:
        dz = kf_phasor_jacobian(model, theory, probes, w, X, F, fs, Q=Q, R=Rs, kms=kms, kf_rotor=kf_rotor,
                                transfers=Ts)
    zB, Ts = _phasors(kms, Xp, X, w, smoother, Ts)
    zsd, nis, bands = [], [], []
    for r in range(nr):
        km, T = kms[r], Ts[id(kms[r])]
        Tr, Ti = T.real ** 2, T.imag ** 2
        vre = Tr @ plains[r].var_re + Ti @ plains[r].var_im
        vim = Ti @ plains[r].var_re + Tr @ plains[r].var_im
        zsd.append(np.sqrt(np.maximum(vre, vim)).reshape(zB.shape[1:]))
        if timed:              # the filter's consistency on the window's samples (innovations alone)
            kmf = replace(km, speed=w, Xp={1.0: Xp[:, r]})          # same matrices and gain, this run's forcing
            _, _, nm, band = innovations(kmf, ys[r], angs[r])
            nis.append(nm)
            bands.append(tuple(band))
    if details is not None:
        details['dc'] = np.array(dcs) if dcs else None
        details['nis_band'] = bands if timed else None
        details['R'] = [km.R for km in kms]
        details['X'] = X
        details['kms'] = kms
        details['Xp'] = Xp
        details['dz'] = dz
    return zB, np.array(zsd), (nis if timed else None), kms[0]


def kf_transfer(km, speed: float, *, smoother: bool = False) -> np.ndarray:
    """
    Steady-state filter's 1X transfer (k, m) complex: output phasor per unit pseudo-measurement phasor.

    The steady-state filter on the deviation from the model's forced response is LTI,
    e(k|k) = (I - K H) Phi e(k-1|k-1) + K y_k, so a 1X input y_k = Re{Y exp(j phi_k)} (phi advancing by
    speed * dt per sample) gives, once its own transient has died out,
    E_f = (I - exp(-j speed dt) (I - K H) Phi)^-1 K Y.  The RTS smoother's recursion
    e_s(k) = (I - Cs Phi) e(k|k) + Cs e_s(k+1) gives E_s = (I - exp(j speed dt) Cs)^-1 (I - Cs Phi) E_f.
    Returns E T with T the (n, m) state transfer (E = the model's output rows).
    """
    P, K, _ = km.steady_state()
    n = km.n
    Id = np.eye(n)
    IKH = Id - K @ km.H
    ph = np.exp(1j * float(speed) * km.dt)
    T = np.linalg.solve(Id - IKH @ km.Phi / ph, K.astype(complex))
    if smoother:
        Ppost = IKH @ P
        Cs = np.linalg.solve(P.T, (Ppost @ km.Phi.T).T).T
        T = np.linalg.solve(Id - ph * Cs, (Id - Cs @ km.Phi) @ T)
    return km.E @ T


def _phasors(kms, Xp, X, speed: float, smoother: bool, transfers: dict | None = None):
    """
    Return (z_B (nr, nb, 2), {id(KalmanModel): T}): z_B,r = E Xp_r + T (X_r - H Xp_r), T of each distinct model.

    ``transfers``: the :func:`kf_transfer` already known (e.g. from :func:`kf_phasor_jacobian`), completed here.
    """
    Ts = dict(transfers or {})
    out = []
    for r, km in enumerate(kms):
        if id(km) not in Ts:
            Ts[id(km)] = kf_transfer(km, speed, smoother=smoother)
        out.append(km.E @ Xp[:, r] + Ts[id(km)] @ (X[r] - km.H @ Xp[:, r]))
    return np.array(out).reshape(len(kms), -1, 2), Ts


def kf_bearing_phasors(model, theory, probes, speed: float, X, forces, sample_rate: float, *,
                       Q=defaults.KF_PROCESS_NOISE, R,
                       smoother: bool = False, kf_rotor=None) -> np.ndarray:
    """
    Bearing-node 1X phasors (nr, nb, 2) of the steady-state KF, in the frequency domain (no time series).

    z_B,r = E Xp_r + T (X_r - H Xp_r): Xp_r the theory model's forced state response to run r, T
    :func:`kf_transfer`, X (nr, nch) the measured probe phasors [m], forces complex (nr, ndof) 1X phasors [N]
    (:func:`forces_at`).  R: the probe noise (one for all runs, or a list with one per run).  On a steady window this
    is the time-domain filter's fitted 1X once the filter's start transient has died out (exactly, when it starts in
    its periodic steady state).  The state space, expm and each distinct R's Riccati equation are solved once per
    call.
    """
    X = np.asarray(X, dtype=complex)
    forces = np.asarray(forces, dtype=complex)
    kms = _kf_models(model, speed, theory, probes, sample_rate, Q, _per_run(R, len(forces)), kf_rotor)
    return _phasors(kms, forced_states(kms[0].A, kms[0].B, forces, speed), X, speed, smoother)[0]


def _per_run(R, nr: int) -> list:
    """R as a list with one entry per run (a list/tuple is taken as per run, anything else as shared)."""
    if isinstance(R, (list, tuple)):
        if len(R) != nr:
            raise ValueError(f'R given per run must have {nr} entries, got {len(R)}')
        return list(R)
    return [R] * nr


def _rkey(R):
    a = np.asarray(R, dtype=float)
    return (a.shape, a.tobytes())


def _exp_divided_differences(x) -> np.ndarray:
    """
    Divided differences of exp on the points x (n,) complex: D_ab = (e^x_a - e^x_b) / (x_a - x_b), D_aa = e^x_a.

    Computed as e^m phi1(o - m) with m the point of larger real part and phi1(d) = expm1(d) / d (no overflow, no
    cancellation when the points are close).
    """
    a = x[:, None]
    b = x[None, :]
    take_a = a.real >= b.real
    m = np.where(take_a, a, b)
    d = np.where(take_a, b - a, a - b)             # Re d <= 0
    small = np.abs(d) < 1e-4
    ds = np.where(small, 1.0, d)
    phi = np.where(small, 1.0 + d / 2 + d * d / 6 + d ** 3 / 24, np.expm1(ds) / ds)
    return np.exp(m) * phi


EIG_COND_MAX = 1e8      # analytic sensitivity only with eigenvector bases better conditioned than this


def _eig_balanced(A):
    """
    Eigendecomposition A = U diag(lam) U^-1 through the diagonally balanced matrix (lam, U, U^-1, cond).

    The rotor's state matrix mixes m, rad, m/s and rad/s (entries from 1 to 1e11): balancing T^-1 A T
    (``scipy.linalg.matrix_balance``, powers of 2, no permutation) first makes the eigenvector basis well
    conditioned (~1e3 instead of ~1e7 here); U = T U_b and U^-1 = U_b^-1 T^-1 are then formed exactly, ``cond`` is
    that of U_b (1-norm).
    """
    Ab, (t, _) = matrix_balance(A, permute=False, separate=True)
    lam, Ub = np.linalg.eig(Ab)
    Ubi = np.linalg.inv(Ub)
    cond = float(np.linalg.norm(Ub, 1) * np.linalg.norm(Ubi, 1))
    return lam, t[:, None] * Ub, Ubi / t[None, :], cond


def kf_phasor_jacobian(model, theory, probes, speed: float, X, forces, sample_rate: float, *,
                       Q=defaults.KF_PROCESS_NOISE, R,
                       kms=None, kf_rotor=None, transfers: dict | None = None):
    """
    Analytic derivative of the steady-state KF's bearing-node 1X phasors with respect to the theory coefficients.

    Returns dz complex (nr, nb, 2, 8 nb) [m per N/m]: d z_B / d theta_th (z_B of :func:`kf_bearing_phasors`,
    theta_th = [K; Omega C] of :func:`coeffs_to_theta`), or None when an eigenvector basis is too ill-conditioned
    (condition > EIG_COND_MAX; the caller falls back to finite differences, :func:`theory_sensitivity`).

    Filter only (no smoother).  With y = X - H Xp, M = I - zeta^-1 (I - K H) Phi, zeta = exp(j speed dt),
    w = M^-1 K y and z_B = E (Xp + w), each theory coefficient moves A by a rank-one dA = u v^T (the bearing block of
    -M_mass^-1 K_b or -M_mass^-1 C_b), and

        dXp = (j speed I - A)^-1 dA Xp,      dPhi = L_exp(A dt, dA dt) (Frechet derivative of expm),
        dP  = Fc dP Fc^T + dPhi P+ Phi^T + Phi P+ dPhi^T   (Stein; Fc = Phi (I - K H), P+ = (I - K H) P),
        dK  = (I - K H) dP H^T S^-1,
        dz_B = (E - E M^-1 K H) dXp + Psi dP h + zeta^-1 Psi dPhi w,   Psi = E M^-1 (I - K H),
               h = H^T S^-1 (y - zeta^-1 H Phi w).

    The dP and dPhi terms are evaluated in adjoint form: per output row psi the Stein adjoint
    Y = Fc^T Y Fc + psi h^T is solved in the eigenbasis of Fc, and <Z, L_exp(A dt, E)> = <L_exp(A^T dt, Z), E> in
    the eigenbasis of A (Daleckii-Krein: divided differences of exp at the eigenvalues), so that each rank-one
    direction costs O(n^2): one eigendecomposition of A per speed and one of Fc per distinct R (each balanced first,
    :func:`_eig_balanced`), no Riccati re-solve.  test/test_kf_transfer.py checks it against central differences.
    ``kms``: the per-run KalmanModels of this speed and theory (:func:`_kf_models`), to reuse their gains;
    ``kf_rotor``: the ReducedRotor they filter on (None: the full model); ``transfers`` (a dict, optional) receives
    {id(KalmanModel): T} the :func:`kf_transfer` of each distinct model, T = E M^-1 K (filter).
    """
    nodes = tuple(model.bearing_nodes)
    nb = len(nodes)
    X = np.asarray(X, dtype=complex)
    forces = np.asarray(forces, dtype=complex)
    nr = len(forces)
    speed = float(speed)
    if kms is None:
        kms = _kf_models(model, speed, theory, probes, sample_rate, Q, _per_run(R, nr), kf_rotor)
    km0 = kms[0]
    A, H, E, Phi, dt = km0.A, km0.H, km0.E, km0.Phi, km0.dt
    n = A.shape[0]
    Id = np.eye(n)
    zeta = np.exp(1j * speed * dt)
    # dA_k = sum_e val_e [0; -M^-1 e_i] e_j^T over the entries e of the bearing's global K or C block for a unit
    # theory coefficient k (order of coeffs_to_theta; the assembly's own bearing_matrices, so a film in series with
    # a pedestal is covered); u_e = [0; -M^-1 e_i] val_e, v_e = e_j (K: displacement, C: velocity columns)
    Udir, vidx, kof = _bearing_directions(model, speed, nodes, kf_rotor)
    lam, Ua, Uai, cond = _eig_balanced(A)
    if not cond <= EIG_COND_MAX:
        return None
    Dl = _exp_divided_differences(lam * dt)
    ut = Uai @ Udir                                   # U^-1 u_k  (n, 8 nb)
    vt = Ua[vidx, :].T                                # U^T v_k   (n, 8 nb)
    Zs = 1j * speed * Id - A
    Xp = forced_states(km0.A, km0.B, forces, speed)   # (n, nr)
    dz = np.zeros((nr, 2 * nb, 8 * nb), dtype=complex)
    lin = {}
    for r in range(nr):
        key = id(kms[r])
        if key not in lin:
            P, K, S = kms[r].steady_state()
            IKH = Id - K @ H
            Ppost = IKH @ P
            Mm = Id - IKH @ Phi / zeta
            lc, V, Vi, cond = _eig_balanced(Phi @ IKH)
            if not cond <= EIG_COND_MAX:
                return None
            lnl = np.log(lc)
            den = -np.expm1(lnl[:, None] + lnl[None, :])          # 1 - lc_a lc_b without cancellation
            OmE = np.linalg.solve(Mm.T, E.T.astype(complex)).T               # E M^-1 (p, n)
            Psi = OmE @ IKH
            Gam = np.linalg.solve(Zs.T, (E - OmE @ K @ H).T).T               # (E - E M^-1 K H) (j w I - A)^-1
            Lr = (Vi @ Ua).T                                                  # U^T V^-T
            Rr = Vi @ (Phi @ Ppost) @ Uai.T                                   # V^-1 Phi P+ U^-T
            lin[key] = (K, S, Mm, Psi, Gam, V, den, Lr, Rr)
            if transfers is not None:
                transfers[key] = OmE @ K
        K, S, Mm, Psi, Gam, V, den, Lr, Rr = lin[key]
        y = X[r] - H @ Xp[:, r]
        w = np.linalg.solve(Mm, K @ y)
        h = H.T @ np.linalg.solve(S, y - H @ (Phi @ w) / zeta)
        d1 = (Gam @ Udir) * Xp[vidx, r][None, :]                  # via dXp (per entry)
        a = V.T @ Psi.T                                           # (n, p)
        c = V.T @ h                                               # (n,)
        Yt = a.T[:, :, None] * c[None, None, :] / den[None]       # Stein adjoint in the Fc eigenbasis (p, n, n)
        Yt = Yt + Yt.transpose(0, 2, 1)
        # one BLAS product per slice (faster here than the broadcast stacked product)
        Zt = np.stack([Lr @ Yt[i] @ Rr for i in range(Yt.shape[0])])
        Zt += (Ua.T @ Psi.T).T[:, :, None] * (Uai @ w)[None, None, :] / zeta
        ZD = Zt * Dl[None]
        d2 = dt * np.einsum('ak,iak->ik', ut, np.stack([ZD[i] @ vt for i in range(ZD.shape[0])]))
        dz[r] = (d1 + d2) @ kof                                   # entries -> coefficients
    return dz.reshape(nr, nb, 2, 8 * nb)


def _bearing_directions(model, speed: float, nodes, red=None):
    """
    Rank-one pieces of dA / d theta_th: (U (n, ne), v indices (ne,), incidence (ne, 8 nb)).

    dA_k = sum over pieces e with incidence[e, k] = 1 of U[:, e] e_{v[e]}^T; theta_th = [K; Omega C] per bearing
    (:func:`coeffs_to_theta`).  Built from :func:`bearing_id.rotor.assembly.bearing_matrices` with one unit
    coefficient at a time (K and C are linear in the coefficients).  With a ReducedRotor ``red`` the pieces are in
    its coordinates (the bearing DOFs are kept, so T^T e_i = e_(kept index of i)).
    """
    nb = len(nodes)
    nd = model.ndof if red is None else red.nr
    Minv = model.Minv if red is None else red.Minv

    def idx(i):
        return int(i) if red is None else red.kept_index(i)

    cols, vs, ks = [], [], []
    zero = np.zeros((2, 2))
    for b, node in enumerate(nodes):
        for i in range(2):
            for j in range(2):
                unit = np.zeros((2, 2))
                unit[i, j] = 1.0
                for kind in range(2):
                    k = 4 * nb * kind + 4 * b + 2 * i + j
                    Kb, Cb = bearing_matrices(model, {node: (unit, zero) if kind == 0 else (zero, unit / speed)})
                    Mk = Kb if kind == 0 else Cb
                    for rr, cc in zip(*np.nonzero(Mk)):
                        col = np.zeros(2 * nd)
                        col[nd:] = -Minv[:, idx(rr)] * Mk[rr, cc]
                        cols.append(col)
                        vs.append(idx(cc) + nd * kind)
                        ks.append(k)
    inc = np.zeros((len(ks), 8 * nb))
    inc[np.arange(len(ks)), ks] = 1.0
    return np.array(cols).T, np.array(vs, dtype=int), inc


def ls_jacobian(model, speed: float, z_B, forces, rtol=DEFAULT_RTOL, force_map=None):
    """
    Differentiate the eqs 30-37 solution theta (svd_solve) with respect to the bearing-node phasors.

    Returns (theta (8 nb,), J_re, J_im (8 nb, nr nb 2)): d theta = J_re Re(dz) + J_im Im(dz) for dz (nr, nb, 2)
    flattened.  Eqs 30-32 are affine in z_B (f_B = F_b - Sc z_B with the Schur complement Sc of the rotor without
    bearings), eqs 33-36 linear in (z_B, f_B); the least-squares derivative is the Golub-Pereyra formula
    d theta = A+ (dd - dA theta) + A+ A+^T dA^T r + (I - A+ A) dA^T A+^T theta with A+ the rank-truncated
    pseudo-inverse of :func:`svd_solve` (r = d - A theta; exact while the rank stays constant).  ``force_map``: the
    (forces_of, Lin) of :func:`bearing_force_map` if already built.
    """
    z_B = np.asarray(z_B, dtype=complex)
    forces = np.asarray(forces, dtype=complex)
    nr, nb = z_B.shape[:2]
    forces_of, Sc = force_map if force_map is not None else bearing_force_map(model, speed, forces)
    A, d = ls_system(z_B, forces_of(z_B))
    theta, U, s, Vh, r, n = svd_solve(A, d, rtol)
    G, _ = solve_derivatives(A, d, theta, U, s, Vh, r, z_B.shape, Sc)     # (n, nr nb 2, 2): real, imaginary unit
    return theta, G[:, :, 0], G[:, :, 1]


THEORY_FLAG = 0.5       # a coefficient with d(identified)/d(theory) above this follows the KF's theory, not the data
THEORY_STEP = 0.01      # theory perturbation of the finite-difference sensitivity (fraction of each group's size)


def theory_sensitivity(model, speed: float, theory: dict, z_B_of, forces, *, rtol=DEFAULT_RTOL,
                       step: float = THEORY_STEP, force_map=None) -> np.ndarray:
    """
    Scaled Jacobian G (8 nb, 8 nb) of the identified coefficients with respect to the KF's theory (finite differences).

    The route where :func:`kf_phasor_jacobian` does not apply (the RTS smoother's transfer, or an eigenvector basis
    too ill-conditioned to use).
    z_B_of : theory {node: (K, C)} -> bearing-node phasors (nr, nb, 2) (e.g. :func:`kf_bearing_phasors`).
    forces : complex (nr, ndof) 1X phasors [N].  Each theory coefficient k (order of :func:`coeffs_to_theta`) is
    moved by ``step`` x its bearing group's size s_k (:func:`bearing_id.identify.lsq.coefficient_scales`), the KF
    and the eqs 30-37 solve are re-run, and G[i, k] = (d theta_i / s_i) / (d theta_th_k / s_k) (a secant: truncation
    error O(step)).  G = 0: the data alone fix the result; G = I: the method hands back the theory it was given.
    ``force_map``: (forces_of, Lin) of :func:`bearing_force_map` if already built.
    """
    nodes = tuple(model.bearing_nodes)
    nb = len(nodes)
    th0 = coeffs_to_theta(theory, speed, nodes)
    sc = coefficient_scales(theory, speed, nodes)
    forces_of = (force_map or bearing_force_map(model, speed, forces))[0]

    def theta_of(co):
        z = z_B_of(co)
        A, d = ls_system(z, forces_of(z))
        return svd_solve(A, d, rtol)[0]

    base = theta_of(theory)
    G = np.zeros((8 * nb, 8 * nb))
    for k in range(8 * nb):
        th = th0.copy()
        th[k] += step * sc[k]
        K, C = theta_to_KC(th, speed, nb)
        G[:, k] = (theta_of({n: (K[i], C[i]) for i, n in enumerate(nodes)}) - base) / sc / step
    return G


def theory_sensitivity_analytic(model, speed: float, theory: dict, z_B, dz, forces, *, rtol=DEFAULT_RTOL,
                                force_map=None) -> np.ndarray:
    """
    Scaled Jacobian G (8 nb, 8 nb) of :func:`theory_sensitivity` by the chain rule (no Riccati equation re-solved).

    G = diag(1/s) (d theta / d z_B) (d z_B / d theta_th) diag(s): :func:`ls_jacobian` at the KF's bearing-node phasors
    ``z_B`` (nr, nb, 2) times their derivative ``dz`` (nr, nb, 2, 8 nb) from :func:`kf_phasor_jacobian`.
    """
    _, Jre, Jim = ls_jacobian(model, speed, z_B, forces, rtol, force_map=force_map)
    dzf = dz.reshape(-1, dz.shape[-1])
    sc = coefficient_scales(theory, speed, tuple(model.bearing_nodes))
    return (Jre @ dzf.real + Jim @ dzf.imag) * sc[None, :] / sc[:, None]


def theory_fractions(G: np.ndarray) -> tuple[np.ndarray, float]:
    """
    (per-coefficient d(identified)/d(theory) = row 2-norms of the scaled Jacobian, overall theory fraction).

    The overall fraction is ||G||_F^2 / n: 1 when the result is the theory, 0 when it is the data's alone, k/n when
    k of the n directions come from the theory (G an orthogonal projector of rank k).
    """
    G = np.asarray(G, dtype=float)
    return np.linalg.norm(G, axis=1), float(np.sum(G ** 2) / G.shape[0])


def identify_paper(model, rig, data, probes, runs, options=None) -> list[IdentResult]:
    """
    Run the paper's method per speed (see module docstring).

    Signature as in :mod:`bearing_id.identify`.

    options : 'bearing_fn' (theory, default the nominal bearings of ``rig``), 'Q' (default
    ``config.defaults.KF_PROCESS_NOISE``), 'R' (default: the probe residual variance), 'smoother' (the RTS
    smoother's transfer instead of the filter's; default False),
    'rtol' (1e-8), 'max_rel_std' (design threshold, 0.05), 'z_B' (complex (n_runs, n_speeds, nb, 2): bypass the KF
    with given bearing-node phasors, e.g. the exact ones, to test the algebra), 'z_B_std' (same shape, real),
    'z_B_kf' ({'Q': ..., 'R': ..., 'sample_rate': Hz[, 'smoother': bool]}: the given z_B came from a KF with these
    settings and the theory of 'bearing_fn' -- e.g. a time-domain filter run elsewhere -- so the theory-dominance
    check is run on them; without it given z_B are taken as measured and no theory check is made), 'remove_dc'
    (default True: each window's static offset is removed before the KF, see :func:`kf_bearing_vectors`), 'reduce'
    ('auto' (default): the reduction below when the full model has more than :data:`AUTO_REDUCE_STATES` states and the
    data carry a sample rate, else the full model; None / False: the filter on the full FE model; True, an int
    (fixed-interface modes) or {'n_modes': k} / {'cutoff_hz': f}: the filter on a Craig-Bampton reduction keeping the
    bearing, probe and force DOFs (:mod:`bearing_id.rotor.reduction`, default cutoff :data:`REDUCE_CUTOFF_FRACTION` x
    the sample rate), its 1X receptance error per speed in the notes and ``extra['reduction']``; with 'check': True in
    the dict the filter is re-run on the reduction with twice the cutoff and the change of the bearing vectors reported
    as its KF-level truncation error ('kf_truncation'); the eqs 30-37 solve stays on the full model).

    Determined: the one rule of :mod:`bearing_id.identify.determined` (:func:`bearing_id.identify.lsq.build_result`),
    with the KF's d(identified)/d(theory) as the prior pull.
    """
    opts = dict(options or {})
    allowed = {'bearing_fn', 'Q', 'R', 'smoother', 'rtol', 'max_rel_std', 'z_B', 'z_B_std', 'z_B_kf', 'remove_dc',
               'reduce'}
    bad = set(opts) - allowed
    if bad:
        raise ValueError(f'identify_paper: unknown option(s) {sorted(bad)}; allowed {sorted(allowed)}')
    rtol = opts.get('rtol', DEFAULT_RTOL)
    Q, smooth = opts.get('Q', defaults.KF_PROCESS_NOISE), bool(opts.get('smoother', False))
    bfn = opts.get('bearing_fn')
    if bfn is None:
        bfn = bearing_fn(rig)
    spec = opts.get('reduce', 'auto')
    auto_note = None
    if isinstance(spec, str) and spec == 'auto':
        big = 2 * model.ndof > AUTO_REDUCE_STATES and _sample_rate(data, required=False) is not None
        spec = True if big else None
        if big:
            auto_note = (f'the full model has {2 * model.ndof} states (> {AUTO_REDUCE_STATES}): the filter runs on a '
                         'Craig-Bampton reduction, which keeps it fast (reduce=None / `--no-reduce` forces the full '
                         'filter)')
    red, red2 = _reduction(model, data, probes, runs, spec)
    out = []
    for s, w in enumerate(data.speeds):
        w = float(w)
        theory = bfn(w)
        F = forces_at(model, runs, w)
        fmap = bearing_force_map(model, w, F)
        notes = []
        not_det, extra = None, {}
        red_info = None
        if auto_note:
            notes.append(auto_note)
        if red is not None:
            err = receptance_error(red, w, theory)
            red_info = {'states': 2 * red.nr, 'full_states': 2 * model.ndof, 'kept_dofs': int(red.kept.size),
                        'modes': red.n_modes, 'cutoff_hz': red.cutoff_hz, 'receptance_error': err}
            notes.append(f'Kalman filter on a Craig-Bampton reduced model: {2 * red.nr} of {2 * model.ndof} states '
                         f'({red.kept.size} kept DOFs + {red.n_modes} fixed-interface modes'
                         + (f' below {red.cutoff_hz:.4g} Hz' if np.isfinite(red.cutoff_hz) else '')
                         + f'); its 1X receptance between kept DOFs is off the full model by {err:.2e} (relative); '
                         'the filter also drops the process noise on the discarded modes, so its bearing vectors '
                         "differ more (0.2 ... 0.5 % on the paper rig at 40 elements): reduce={..., 'check': True} "
                         'estimates it')
        if opts.get('z_B') is not None:
            zB = np.asarray(opts['z_B'])[:, s]
            zBs = None if opts.get('z_B_std') is None else np.asarray(opts['z_B_std'])[:, s]
            kf = opts.get('z_B_kf')
            if kf is None:
                notes.append('bearing-node displacements given (no Kalman filter)')
            else:
                notes.append(f"bearing-node displacements given by a Kalman filter (Q = {kf['Q']:g})")
                not_det, extra = _theory_check(model, w, theory, probes, data.X[:, s], F, float(kf['sample_rate']),
                                               kf['Q'], kf['R'], bool(kf.get('smoother', False)), rtol, zB, notes,
                                               fmap, kf_rotor=red)
        else:
            det_kf = {}
            zB, zBs, nis, km = kf_bearing_vectors(model, theory, probes, data, s, Q=Q, R=opts.get('R'),
                                                  smoother=smooth, remove_dc=bool(opts.get('remove_dc', True)),
                                                  details=det_kf, jacobian=True, kf_rotor=red)
            dc = det_kf.get('dc')
            if nis is None:
                nis_note = ('; NIS not computed (no time series here: the live identifier holds 1X vectors only; '
                            '`bearing-id identify` on the recording reports it)')
            else:
                band = det_kf['nis_band'][0]
                nis_note = ('; mean NIS per run ' + ', '.join(f'{v:.3g}' for v in nis)
                            + f' (expected {km.m} for a consistent filter; 95 % band {band[0]:.3g} ... {band[1]:.3g})'
                            + (f'; static offset removed before filtering (largest |DC| '
                               f'{1e6 * np.max(np.abs(dc)):.3g} um)' if dc is not None else
                               '; static offset NOT removed'))
            notes.append(f'Kalman filter (theory coefficients, Q = {Q:g}; 1X vectors from its steady-state transfer '
                         "function applied to the probes' plain 1X fits)" + nis_note)
            not_det, extra = _theory_check(model, w, theory, probes, det_kf['X'], F, _sample_rate(data), Q,
                                           list(det_kf['R']), smooth, rtol, zB, notes, fmap, dz=det_kf['dz'],
                                           own=True, kf_rotor=red)
            # how much the KF moved the bearing displacements away from the theory model's prediction
            zth = (km.E @ det_kf['Xp']).T.reshape(zB.shape)
            moved = np.linalg.norm(zB - zth) / max(np.linalg.norm(zth), 1e-300)
            notes.append(f"KF bearing displacements differ from the theory model's prediction by {100 * moved:.1f} %")
            extra.update(nis=None if nis is None else list(nis), nis_band=det_kf['nis_band'], dc_removed=dc)
            if red2 is not None:
                z2 = kf_bearing_phasors(model, theory, probes, w, det_kf['X'], F, _sample_rate(data), Q=Q,
                                        R=list(det_kf['R']), smoother=smooth, kf_rotor=red2)
                dzr = float(np.linalg.norm(zB - z2) / max(np.linalg.norm(z2), 1e-300))
                red_info.update(check_states=2 * red2.nr, kf_truncation=dzr)
                notes.append(f'truncation check: the same filter on {2 * red2.nr} states (twice the cutoff) moves '
                             f'the KF bearing vectors by {100 * dzr:.2g} %')
        if red_info is not None:
            extra['reduction'] = red_info
        sol = solve_coefficients(model, w, zB, F, z_B_std=zBs, rtol=rtol, force_map=fmap)
        out.append(build_result('paper', model, rig, w, sol, probes=probes, forces=list(F),
                                X_std_rel=noise_rel_of(data, s), theory=theory, truth=data.truth_at(w),
                                max_rel_std=opts.get('max_rel_std'), notes=notes, extra={'z_B': zB, **extra},
                                not_determined=not_det, pull=extra.get('theory_sensitivity'),
                                rank_cap=extra.get('data_directions')))
    return out


def _theory_check(model, speed, theory, probes, X, F, sample_rate, Q, R, smoother, rtol, zB_kf, notes, force_map, *,
                  dz=None, own=False, kf_rotor=None):
    """
    Sensitivity of the result to the KF's theory: (mask of theory-dominated coefficients, extra dict); notes.

    X (nr, nch) the probe phasors the transfer is applied to; ``own``: zB_kf is this filter's own output
    (:func:`kf_bearing_vectors`, with ``dz`` = d z_B / d theta_th when it could be formed), else it came from
    elsewhere (a time-domain filter) and its distance from the transfer's z_B is reported.  The analytic derivative
    (:func:`kf_phasor_jacobian`, :func:`theory_sensitivity_analytic`) where it applies, else forward differences
    (:func:`theory_sensitivity`).
    """

    def zb_of(co):
        return kf_bearing_phasors(model, co, probes, speed, X, F, sample_rate, Q=Q, R=R, smoother=smoother,
                                  kf_rotor=kf_rotor)

    if own:
        za = zB_kf
    else:
        kms = _kf_models(model, speed, theory, probes, sample_rate, Q, _per_run(R, len(F)), kf_rotor)
        Ts = {}
        if not smoother:
            dz = kf_phasor_jacobian(model, theory, probes, speed, X, F, sample_rate, Q=Q, R=R, kms=kms,
                                    kf_rotor=kf_rotor, transfers=Ts)
        Xp = forced_states(kms[0].A, kms[0].B, F, speed)
        za = _phasors(kms, Xp, np.asarray(X, dtype=complex), speed, smoother, Ts)[0]
    if dz is not None:
        G = theory_sensitivity_analytic(model, speed, theory, za, dz, F, rtol=rtol, force_map=force_map)
        how = 'analytic derivative'
    else:
        G = theory_sensitivity(model, speed, theory, zb_of, F, rtol=rtol, force_map=force_map)
        how = f"finite differences, theory moved by {100 * THEORY_STEP:g} % of each group's size"
    mism = 0.0 if own else float(np.linalg.norm(za - zB_kf) / max(np.linalg.norm(zB_kf), 1e-300))
    sens, frac = theory_fractions(G)
    flag = sens > THEORY_FLAG
    data_dirs = int(np.count_nonzero(np.linalg.svd(G, compute_uv=False) <= THEORY_FLAG))
    labels = coefficient_labels(model.bearing_nodes)
    notes.append(f"theory fraction {frac:.2f} (||d identified / d theory||_F^2 / {G.shape[0]} of the KF's theory, "
                 f'{how}; 0 = the data alone, 1 = the filter hands '
                 f'back its theory, > 1 = theory errors amplified); d(identified)/d(theory) per coefficient '
                 f'{np.min(sens):.2f} ... {np.max(sens):.2f}; {data_dirs} of {G.shape[0]} directions come from '
                 f'the data (singular values of the sensitivity <= {THEORY_FLAG:g}): rank capped there')
    if flag.any():
        notes.append(f"{int(flag.sum())} of {flag.size} coefficients follow the KF's theory more than the data "
                     f'(d identified / d theory > {THEORY_FLAG:g}): '
                     + ', '.join(lab for lab, f in zip(labels, flag) if f) + ' -- not determined by the data')
    if mism > 0.05:
        notes.append(f"the given KF bearing vectors differ from the filter's steady-state transfer by {100 * mism:.1f} "
                     f'% (a transient in the window): the theory fraction is approximate')
    out = {'theory_sensitivity': sens, 'theory_fraction': frac, 'theory_jacobian': G,
           'kf_transfer_mismatch': mism, 'data_directions': data_dirs}
    return flag, out


REDUCE_CUTOFF_FRACTION = 0.5     # default Craig-Bampton cutoff of the paper route: the Nyquist frequency
AUTO_REDUCE_STATES = 88          # a full filter above this many states is slow (63 s CPU at 448 states): reduce


def _reduction(model, data, probes, runs, spec):
    """Build the ReducedRotors (the filter's, the check's or None) from the 'reduce' option (None: full model)."""
    if spec is None or spec is False:
        return None, None
    if spec is True:
        spec = {}
    elif isinstance(spec, (int, np.integer)) and not isinstance(spec, bool):
        spec = {'n_modes': int(spec)}
    if not isinstance(spec, dict) or set(spec) - {'n_modes', 'cutoff_hz', 'check'}:
        raise ValueError("identify_paper: reduce must be None, True, an int or {'n_modes': k} / {'cutoff_hz': f} "
                         "(and optionally 'check': True)")
    spec = dict(spec)
    check = bool(spec.pop('check', False))
    if 'n_modes' not in spec and 'cutoff_hz' not in spec:
        fs = _sample_rate(data, required=False)
        if fs is None:
            raise ValueError('identify_paper: reduce needs n_modes or cutoff_hz when there is no sample rate')
        spec = {'cutoff_hz': REDUCE_CUTOFF_FRACTION * float(fs)}
    F = forces_at(model, runs, float(np.max(data.speeds)))
    kept = kf_kept_dofs(model, probes, F)
    red = craig_bampton(model, kept, **spec)
    red2 = None
    if check:       # the same reduction with twice the cutoff (or twice the modes): a KF-level truncation estimate
        spec2 = ({'cutoff_hz': 2 * spec['cutoff_hz']} if 'cutoff_hz' in spec
                 else {'n_modes': 2 * spec['n_modes'] + 2})
        red2 = craig_bampton(model, kept, **spec2)
    return red, red2


__all__ = ['bearing_dofs', 'bearing_forces', 'ls_system', 'LSSolution', 'solve_coefficients', 'theta_to_KC',
           'coeffs_to_theta', 'build_result', 'noise_rel_of', 'forces_at', 'kf_bearing_vectors', 'kf_transfer',
           'kf_bearing_phasors', 'kf_phasor_jacobian', 'ls_jacobian', 'theory_sensitivity',
           'theory_sensitivity_analytic', 'theory_fractions', 'identify_paper', 'THEORY_FLAG', 'THEORY_STEP']
