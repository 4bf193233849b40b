"""
The conventional two-probe method (De Santiago & San Andres 2007, as used by Kang et al. 2020 for comparison).

For each bearing and direction, the shaft displacement at the bearing node is the straight-line interpolation (or
extrapolation) along the shaft axis of two probes in that direction:
    z_B = X_1 + (X_2 - X_1) (z_bearing - z_1) / (z_2 - z_1)      (z = axial position [m])
then the same eqs 30-37 solve as the paper method (:func:`bearing_id.identify.paper.solve_coefficients`).
Probe choice (default): the nearest probe node on each side of the bearing when there is one, otherwise the two
nearest probe nodes on the same side; ``options['pairs'] = {bearing_node: (node_a, node_b)}`` overrides it.
The straight line ignores the shaft's curvature: that bias is the method's, not the data's, and is not in the std.

Interpolation-bias check (stated rules)
    * Model route: the method is run on the theory model's own noise-free probe response (:func:`interpolation_bias`);
      its error against that theory, per coefficient and relative to the bearing group's size, is the bias the
      straight line alone causes near this operating point.  Above ``max_rel_std`` (default 0.05, the design
      threshold) the coefficient is flagged: determined=False, named in the notes ("interpolation bias"); and, by the
      one rule, a bias above half the coefficient's 1-sigma also leaves it undetermined; for that the bias is evaluated
      at the theory AND at the identified coefficients, the larger (it depends on the mode shapes, which the
      coefficients change: at the theory it can be a small fraction of what it is at the truth).
    * Data route (only with more equations than unknowns, i.e. more than two runs): the eqs 33-37 residual is a
      chi-square test against the propagated noise of the interpolated displacements
      (:func:`bearing_id.identify.lsq.solve_coefficients`, :func:`bearing_id.identify.determined.fit_quality`); a
      misfit (the straight line does not fit the data within their noise) Birge-scales every std and flags the
      result ``misfit``.

Determined: the one rule of :mod:`bearing_id.identify.determined` (in :func:`bearing_id.identify.lsq.build_result`),
with the interpolation-bias flags as the method's own veto.  ``probe_pairs`` lives in :mod:`.lsq` (re-exported here).
"""
from __future__ import annotations

import numpy as np

from .lsq import (bearing_dofs, bearing_force_map, build_result, coefficient_labels, coefficient_scales,
                  coeffs_to_theta, DEFAULT_MAX_REL_STD, DEFAULT_RTOL, forces_at, noise_rel_of, probe_pairs,
                  solve_coefficients, theta_to_KC)
from .result import IdentResult
from ..rotor.assembly import dynamic_stiffness, probe_matrix
from ..rotor.supports import bearing_fn


def interpolate(model, probes, X, X_std=None, pairs=None):
    """Bearing-node phasors z_B (..., nb, 2) from probe phasors X (..., nch); and their Re/Im 1-sigma if X_std given."""
    pp = probe_pairs(model, probes, pairs)
    X = np.asarray(X)
    nb = len(model.bearing_nodes)
    z = np.zeros(X.shape[:-1] + (nb, 2), dtype=complex)
    zs = np.zeros(X.shape[:-1] + (nb, 2))
    for b, n in enumerate(model.bearing_nodes):
        for i, d in enumerate(('x', 'y')):
            terms = pp[(n, d)]              # (channel, weight) pairs: two x/y probes, or more for +-45 deg pairs
            z[..., b, i] = sum((w * X[..., c] for c, w in terms), 0)
            if X_std is not None:
                zs[..., b, i] = np.sqrt(sum(((w * X_std[..., c]) ** 2 for c, w in terms), 0))
    return z, (zs if X_std is not None else None)


def interpolation_bias(model, probes, speed: float, theory: dict, forces, pairs=None, *, rtol=DEFAULT_RTOL,
                       force_map=None):
    """
    (bias (8 nb,), z_B error): the method's own error on the theory model's noise-free response at ``speed``.

    bias = |theta_conventional - theta_theory| / group size (:func:`bearing_id.identify.design.coefficient_scales`),
    theta = [K; Omega C] as in :func:`bearing_id.identify.paper.coeffs_to_theta`; z_B error = ||z_interp - z_B|| /
    ||z_B|| of the interpolated bearing displacements.  forces complex (nr, ndof) [N]; ``force_map`` as in
    :func:`bearing_id.identify.lsq.solve_coefficients`.
    """
    nodes = tuple(model.bearing_nodes)
    S = probe_matrix(model, probes)
    forces = np.asarray(forces, dtype=complex)
    q = np.linalg.solve(dynamic_stiffness(model, speed, speed, theory), forces.T).T      # every run, one solve
    z_true = q[:, bearing_dofs(model)].reshape(len(q), len(nodes), 2)
    z_int, _ = interpolate(model, probes, q @ S.T, None, pairs)
    sol = solve_coefficients(model, speed, z_int, forces, rtol=rtol, force_map=force_map)
    bias = np.abs(sol.theta - coeffs_to_theta(theory, speed, nodes)) / coefficient_scales(theory, speed, nodes)
    return bias, float(np.linalg.norm(z_int - z_true) / max(np.linalg.norm(z_true), 1e-300))


def identify_conventional(model, rig, data, probes, runs, options=None) -> list[IdentResult]:
    """
    Two probes per bearing and direction, interpolated to the bearing node, then the paper's solve.

    options : 'pairs' ({bearing_node: (node_a, node_b)}), 'bearing_fn' (theory for the data check; default the
    nominal bearings), 'rtol', 'max_rel_std'.
    """
    opts = dict(options or {})
    bad = set(opts) - {'pairs', 'bearing_fn', 'rtol', 'max_rel_std'}
    if bad:
        raise ValueError(f'identify_conventional: unknown option(s) {sorted(bad)}')
    bfn = opts.get('bearing_fn')
    if bfn is None:
        bfn = bearing_fn(rig)
    pp = probe_pairs(model, probes, opts.get('pairs'))
    used = sorted({probes[c].node for v in pp.values() for c, _ in v})
    zB_all, zs_all = interpolate(model, probes, data.X, data.X_std, opts.get('pairs'))
    out = []
    for s, w in enumerate(data.speeds):
        w = float(w)
        F = forces_at(model, runs, w)
        fmap = bearing_force_map(model, w, F)
        sol = solve_coefficients(model, w, zB_all[:, s], F, z_B_std=zs_all[:, s],
                                 rtol=opts.get('rtol', DEFAULT_RTOL), force_map=fmap)
        notes = [f'bearing displacements interpolated from probe nodes {used} (straight line along the shaft)']
        theory = bfn(w)
        thr = opts.get('max_rel_std') or DEFAULT_MAX_REL_STD
        bias, zerr = interpolation_bias(model, probes, w, theory, F, opts.get('pairs'),
                                        rtol=opts.get('rtol', DEFAULT_RTOL), force_map=fmap)
        flag = bias > thr
        # the bias depends on the coefficients (mode shapes): evaluated at the theory AND at the estimate, the larger
        bias_abs = bias * coefficient_scales(theory, w, model.bearing_nodes)
        try:
            K_e, C_e = theta_to_KC(sol.theta, w, len(model.bearing_nodes))
            est = {n: (K_e[i], C_e[i]) for i, n in enumerate(model.bearing_nodes)}
            b_e, _ = interpolation_bias(model, probes, w, est, F, opts.get('pairs'),
                                        rtol=opts.get('rtol', DEFAULT_RTOL), force_map=fmap)
            bias_abs = np.fmax(bias_abs, b_e * coefficient_scales(est, w, model.bearing_nodes))
        except (np.linalg.LinAlgError, ValueError):
            pass
        labels = coefficient_labels(model.bearing_nodes)
        notes.append(f"interpolation bias (the method on the theory model's noise-free response): bearing "
                     f'displacements off by {100 * zerr:.1f} %, coefficients by {100 * np.min(bias):.1f} ... '
                     f'{100 * np.max(bias):.0f} % of their group size')
        if flag.any():
            notes.append(f'{int(flag.sum())} of {flag.size} coefficients carry an interpolation bias above '
                         f'{100 * thr:g} % -- not determined: ' + ', '.join(lab for lab, f in zip(labels, flag) if f))
        if np.isfinite(sol.consistency):
            notes.append(f'consistency: residual-based std / noise-propagated std = {sol.consistency:.2f}')
        out.append(build_result('conventional', model, rig, w, sol, probes=probes, forces=list(F),
                                X_std_rel=noise_rel_of(data, s), theory=theory, truth=data.truth_at(w),
                                max_rel_std=opts.get('max_rel_std'), notes=notes,
                                extra={'z_B': zB_all[:, s], 'interpolation_bias': bias, 'z_B_interp_error': zerr,
                                       'consistency': sol.consistency}, not_determined=flag,
                                bias=bias_abs))
    return out


__all__ = ['probe_pairs', 'interpolate', 'interpolation_bias', 'identify_conventional']
