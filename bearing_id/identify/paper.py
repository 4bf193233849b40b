"""
The paper's method (Kang et al., Sensors 2020, sections 3.1-3.2, eqs 5-37), done faithfully, reported honestly.

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

Static offset: a probe's DC (its gap) is no state of the model; each window's DC is removed before the KF
(:func:`kf_bearing_vectors`), and the mean NIS is reported against its chi-square band.

Rank and uncertainty (stated rules; the shared solve and result are in :mod:`.lsq`)
    * LS rank: singular values above ``rtol`` (default 1e-8) x the largest.
    * Std: the 1-sigma of z_B propagated through the whole solve (finite differences); without it the residual-based
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
      The steady-state filter is LTI, so its 1X bearing estimate is z_B = E Xp + T(Omega) (X - H Xp)
      (:func:`kf_bearing_phasors`; equal to the time-domain filter's fitted 1X up to its start transient, the
      difference is reported).  Each theory coefficient is moved by THEORY_STEP (1 %) of its bearing group's size,
      the KF + eqs 30-37 re-run, giving the scaled Jacobian G = d identified / d theory
      (:func:`theory_sensitivity`).  Per coefficient d(identified)/d(theory) = its row norm of G = the pull of the
      theory on it (determined only when <= 0.1); above THEORY_FLAG = 0.5 the coefficient follows the KF's theory
      more than the data, named in the notes.  The theory fraction ||G||_F^2 / 16 (0 = the data alone, 1 = the
      theory handed back, > 1 theory errors amplified) is in the notes and ``extra['theory_fraction']``; the reported
      rank is capped by the number of directions the data fix (singular values of G <= THEORY_FLAG).
"""
from __future__ import annotations

import numpy as np

from .lsq import _svd_solve  # noqa: F401  (old private name, kept for callers)
from .lsq import (bearing_dofs, bearing_forces, build_result, coeffs_to_theta, DEFAULT_RTOL, forces_at, ls_system,
                  LSSolution, noise_rel_of, solve_coefficients, svd_solve, theta_to_KC)
from .result import IdentResult

DEFAULT_Q = 1e-16


# ------------------------------------------------------------------------------------------------ KF route
def kf_bearing_vectors(model, theory, probes, data, s: int, *, Q=DEFAULT_Q, R=None, smoother=False,
                       remove_dc: bool = True, details: dict | None = None):
    """
    KF (theory coefficients) bearing-node 1X vectors at speed index ``s``.

    Returns (z_B (nr, nb, 2), z_B_std (nr, nb, 2), NIS means (nr,), the KalmanModel of the first run).
    R default: each probe's residual variance around its 1X fit, per run [m^2] (the rig's and a real probe's noise
    differ between runs; one R for all runs put the NIS of the louder run outside its band).

    Static offset: a displacement probe reads gap + vibration; the gap (DC) is no state of the rotor model, so a
    filter fed it sees a constant innovation the size of the gap (NIS 1e5 instead of ~m).  With ``remove_dc`` (default)
    each window's DC is estimated by the 1X-plus-offset least-squares fit over whole revolutions
    (:func:`bearing_id.signals.harmonic_vectors`, unbiased by the 1X) and subtracted from the samples before filtering.
    ``details`` (a dict, optional) receives 'dc' (nr, nch) [m] removed, 'nis_band' and 'R' (m, m) per run.
    """
    from ..excitation import harmonic_forces
    from ..kalman import fast_filter, rotor_kalman_model, rts_smoother
    from ..signals import harmonic_vectors
    if not data.recordings:
        raise ValueError("the paper method's Kalman filter needs the time series (recordings), not only 1X vectors")
    w = float(data.speeds[s])
    nb = len(model.bearing_nodes)
    zs, zsd, nis, dcs, bands, Rs = [], [], [], [], [], []
    km = km0 = None
    for r, run in enumerate(data.runs):
        rec = data.recordings[r]
        i0, i1 = data.windows[r][s]
        y, a = np.asarray(rec.samples[i0:i1], dtype=float), rec.angle[i0:i1]
        fit0 = harmonic_vectors(y, a) if remove_dc else None
        if remove_dc:
            dc = np.asarray(fit0.offset, dtype=float)
            y = y - dc[None, :]
            dcs.append(dc)
        forces = harmonic_forces(run.excitation, w, model.n_nodes)
        if R is None:      # each run's own probe noise (the noise is a fraction of each run's signal)
            if fit0 is None:
                fit0 = harmonic_vectors(y, a)
            km = rotor_kalman_model(model, w, theory, probes, rec.sample_rate, forces=forces, Q=Q,
                                    R=np.maximum(fit0.residual_rms ** 2, 1e-30))
            km0 = km0 or km
        elif km is None:
            km = km0 = rotor_kalman_model(model, w, theory, probes, rec.sample_rate, forces=forces, Q=Q, R=R)
        else:
            km = km.with_forces(forces, w)
        Rs.append(km.R)
        out = (rts_smoother if smoother else fast_filter)(km, y, a)
        fit = harmonic_vectors(out.estimates, a)
        zs.append(fit.X[0].reshape(nb, 2))
        zsd.append(np.maximum(fit.std_re[0], fit.std_im[0]).reshape(nb, 2))
        nis.append(out.nis_mean)
        bands.append(tuple(out.nis_band))
    if details is not None:
        details['dc'] = np.array(dcs) if dcs else None
        details['nis_band'] = bands
        details['R'] = Rs
    return np.array(zs), np.array(zsd), nis, km0


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


def kf_bearing_phasors(model, theory, probes, speed: float, X, forces, sample_rate: float, *, Q=DEFAULT_Q, R,
                       smoother: bool = False) -> np.ndarray:
    """
    Bearing-node 1X phasors (nr, nb, 2) of the steady-state KF, in the frequency domain (no time series).

    z_B,r = E Xp_r + T (X_r - H Xp_r): Xp_r the theory model's forced state response to run r, T
    :func:`kf_transfer`, X (nr, nch) the measured probe phasors [m], forces complex (nr, ndof) 1X phasors [N]
    (:func:`forces_at`).  R: the probe noise (one for all runs, or a list with one per run).
    Equals the time-domain filter's fitted 1X (:func:`kf_bearing_vectors`) up to the filter's start transient; it is
    the route used for the sensitivity to the theory (:func:`theory_sensitivity`).
    """
    from ..kalman import rotor_kalman_model
    nb = len(model.bearing_nodes)
    X = np.asarray(X, dtype=complex)
    forces = np.asarray(forces, dtype=complex)
    per_run = isinstance(R, (list, tuple))
    out = np.zeros((len(forces), nb, 2), dtype=complex)
    km = T = None
    for r, F1 in enumerate(forces):
        if km is None or per_run:
            km = rotor_kalman_model(model, speed, theory, probes, sample_rate, forces=None, Q=Q,
                                    R=R[r] if per_run else R)
            T = kf_transfer(km, speed, smoother=smoother)
        Xp = km.with_forces({1.0: F1}, speed).Xp[1.0]
        out[r] = (km.E @ Xp + T @ (X[r] - km.H @ Xp)).reshape(nb, 2)
    return out


THEORY_FLAG = 0.5       # a coefficient with d(identified)/d(theory) above this follows the KF's theory, not the data
THEORY_STEP = 0.01      # theory perturbation of the sensitivity (fraction of each bearing group's size)


def theory_sensitivity(model, speed: float, theory: dict, z_B_of, forces, *, rtol=DEFAULT_RTOL,
                       step: float = THEORY_STEP) -> np.ndarray:
    """
    Scaled Jacobian G (8 nb, 8 nb) of the identified coefficients with respect to the theory fed to the KF.

    z_B_of : theory {node: (K, C)} -> bearing-node phasors (nr, nb, 2) (e.g. :func:`kf_bearing_phasors`).
    forces : complex (nr, ndof) 1X phasors [N].  Each theory coefficient k (order of :func:`coeffs_to_theta`) is
    moved by ``step`` x its bearing group's size s_k (:func:`bearing_id.identify.design.coefficient_scales`), the
    KF and the eqs 30-37 solve are re-run, and G[i, k] = (d theta_i / s_i) / (d theta_th_k / s_k).
    G = 0: the data alone fix the result; G = I: the method hands back the theory it was given.
    """
    from .lsq import coefficient_scales
    nodes = tuple(model.bearing_nodes)
    nb = len(nodes)
    th0 = coeffs_to_theta(theory, speed, nodes)
    sc = coefficient_scales(theory, speed, nodes)

    def theta_of(co):
        z = z_B_of(co)
        A, d = ls_system(z, bearing_forces(model, speed, z, forces))
        return svd_solve(A, d, rtol)[0]

    base = theta_of(theory)
    G = np.zeros((8 * nb, 8 * nb))
    for k in range(8 * nb):
        th = th0.copy()
        th[k] += step * sc[k]
        K, C = theta_to_KC(th, speed, nb)
        G[:, k] = (theta_of({n: (K[i], C[i]) for i, n in enumerate(nodes)}) - base) / sc / step
    return G


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

    options : 'bearing_fn' (theory, default the nominal bearings of ``rig``), 'Q' (default 1e-16), 'R' (default:
    the probe residual variance), 'smoother' (RTS instead of the filter; default False), 'rtol' (1e-8),
    'max_rel_std' (design threshold, 0.05), 'z_B' (complex (n_runs, n_speeds, nb, 2): bypass the KF with given
    bearing-node phasors, e.g. the exact ones, to test the algebra), 'z_B_std' (same shape, real), 'z_B_kf'
    ({'Q': ..., 'R': ..., 'sample_rate': Hz[, 'smoother': bool]}: the given z_B came from a KF with these settings
    and the theory of 'bearing_fn' -- e.g. the kf_estimator node's -- so the theory-dominance check is run on them;
    without it given z_B are taken as measured and no theory check is made), 'remove_dc' (default True: each
    window's static offset is removed before the KF, see :func:`kf_bearing_vectors`).

    Determined: the one rule of :mod:`bearing_id.identify.determined` (:func:`bearing_id.identify.lsq.build_result`),
    with the KF's d(identified)/d(theory) as the prior pull.
    """
    opts = dict(options or {})
    allowed = {'bearing_fn', 'Q', 'R', 'smoother', 'rtol', 'max_rel_std', 'z_B', 'z_B_std', 'z_B_kf', 'remove_dc'}
    bad = set(opts) - allowed
    if bad:
        raise ValueError(f'identify_paper: unknown option(s) {sorted(bad)}; allowed {sorted(allowed)}')
    bfn = opts.get('bearing_fn')
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
        if opts.get('z_B') is not None:
            zB = np.asarray(opts['z_B'])[:, s]
            zBs = None if opts.get('z_B_std') is None else np.asarray(opts['z_B_std'])[:, s]
            kf = opts.get('z_B_kf')
            if kf is None:
                notes.append('bearing-node displacements given (no Kalman filter)')
            else:
                notes.append(f"bearing-node displacements given by a Kalman filter (Q = {kf['Q']:g})")
                not_det, extra = _theory_check(model, w, theory, probes, data.X[:, s], F, float(kf['sample_rate']),
                                               kf['Q'], kf['R'], bool(kf.get('smoother', False)),
                                               opts.get('rtol', DEFAULT_RTOL), zB, notes)
        else:
            Q, smooth = opts.get('Q', DEFAULT_Q), bool(opts.get('smoother', False))
            det_kf = {}
            zB, zBs, nis, km = kf_bearing_vectors(model, theory, probes, data, s, Q=Q, R=opts.get('R'),
                                                  smoother=smooth, remove_dc=bool(opts.get('remove_dc', True)),
                                                  details=det_kf)
            band = det_kf['nis_band'][0]
            dc = det_kf.get('dc')
            notes.append(f'Kalman filter (theory coefficients, Q = {Q:g}); mean NIS per run '
                         + ', '.join(f'{v:.3g}' for v in nis) + f' (expected {km.m} for a consistent filter; 95 % '
                         f'band {band[0]:.3g} ... {band[1]:.3g})'
                         + (f'; static offset removed before filtering (largest |DC| {1e6 * np.max(np.abs(dc)):.3g} '
                            'um)' if dc is not None else '; static offset NOT removed'))
            not_det, extra = _theory_check(model, w, theory, probes, data.X[:, s], F, data.recordings[0].sample_rate,
                                           Q, list(det_kf['R']), smooth, opts.get('rtol', DEFAULT_RTOL), zB, notes)
            # how much the KF moved the bearing displacements away from the theory model's prediction
            from ..rotor.assembly import harmonic_response
            zth = np.array([harmonic_response(model, w, w, f, theory)[_bdofs(model)].reshape(-1, 2) for f in F])
            dz = np.linalg.norm(zB - zth) / max(np.linalg.norm(zth), 1e-300)
            notes.append(f"KF bearing displacements differ from the theory model's prediction by {100 * dz:.1f} %")
            extra.update(nis=list(nis), nis_band=det_kf['nis_band'], dc_removed=dc)
        sol = solve_coefficients(model, w, zB, F, z_B_std=zBs, rtol=opts.get('rtol', DEFAULT_RTOL))
        out.append(build_result('paper', model, rig, w, sol, probes=probes, forces=list(F),
                                X_std_rel=noise_rel_of(data, s), theory=theory, truth=data.truth_at(w),
                                max_rel_std=opts.get('max_rel_std'), notes=notes, extra={'z_B': zB, **extra},
                                not_determined=not_det, pull=extra.get('theory_sensitivity'),
                                rank_cap=extra.get('data_directions')))
    return out


def _theory_check(model, speed, theory, probes, X, F, sample_rate, Q, R, smoother, rtol, zB_kf, notes):
    """Sensitivity of the result to the KF's theory: (mask of theory-dominated coefficients, extra dict); notes."""
    from .lsq import coefficient_labels

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
                 f'back its theory, > 1 = theory errors amplified); d(identified)/d(theory) per coefficient '
                 f'{np.min(sens):.2f} ... {np.max(sens):.2f}; {data_dirs} of {G.shape[0]} directions come from '
                 f'the data (singular values of the sensitivity <= {THEORY_FLAG:g}): rank capped there')
    if flag.any():
        notes.append(f"{int(flag.sum())} of {flag.size} coefficients follow the KF's theory more than the data "
                     f'(d identified / d theory > {THEORY_FLAG:g}): '
                     + ', '.join(lab for lab, f in zip(labels, flag) if f) + ' -- not determined by the data')
    if mism > 0.05:
        notes.append(f"the KF's fitted 1X differs from its steady-state transfer by {100 * mism:.1f} % (a transient "
                     f'in the window): the theory fraction is approximate')
    return flag, {'theory_sensitivity': sens, 'theory_fraction': frac, 'theory_jacobian': G,
                  'kf_transfer_mismatch': mism, 'data_directions': data_dirs}


def _bdofs(model):
    return bearing_dofs(model)


__all__ = ['bearing_dofs', 'bearing_forces', 'ls_system', 'LSSolution', 'solve_coefficients', 'theta_to_KC',
           'coeffs_to_theta', 'build_result', 'noise_rel_of', 'forces_at', 'kf_bearing_vectors', 'kf_transfer',
           'kf_bearing_phasors', 'theory_sensitivity', 'theory_fractions', 'identify_paper', 'THEORY_FLAG',
           'THEORY_STEP']
