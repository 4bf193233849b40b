"""
Physical plausibility gates on identification results.

A result from data the model cannot describe is not "determined", whatever its rank (issue 10, item 3).  Applied by
:func:`bearing_id.identify.identify`, so the CLI and the identifier node apply the same gates.

Per speed:

* **Stability**: above the nominal model's stability threshold (onset of oil whip,
  :func:`bearing_id.rotor.stability.threshold_speed`) a steady 1X response does not exist in the model; a speed
  there means a wrong speed signal (e.g. doubled) or a machine the model does not describe.
* **Orbit vs clearance**: the journal orbit at each bearing, from the model with the identified coefficients under
  the known excitation, scaled to the measured probe amplitudes, must stay within ``ORBIT_LIMIT`` of the radial
  clearance (the linearised coefficients' range, the rule of :func:`bearing_id.simulation.rig.check_validity`).  Data in
  the wrong unit (micrometres sent as metres) fail this by orders of magnitude.
* **Live channels**: every probe must carry a 1X signal above its noise in at least one run; a dead, constant or
  all-zero channel cannot constrain anything.

A failed gate sets every coefficient of that speed to not determined (std NaN) and says why in ``notes``.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .direct import SPARSE_NDOF
from ..bearings.short import brentq
from ..conventions import dof_index
from ..excitation import harmonic_forces
from ..rotor.assembly import dynamic_stiffness, harmonic_response, probe_matrix, state_space
from ..rotor.stability import FAST_NDOF, max_real_part_fn, threshold_speed
from ..rotor.supports import bearing_fn

ORBIT_LIMIT = 0.30      # fraction of the radial clearance (same rule as rig.check_validity and kf_estimator)
SIGNAL_SIGMA = 3.0      # a channel's 1X amplitude must exceed this many of its 1-sigma in some run


def stability_threshold(model, rig, speed_max: float, method: str = 'auto') -> float:
    """
    Return the nominal model's stability threshold [rad/s].

    ``method``: as :func:`bearing_id.rotor.stability.threshold_speed` ('auto': the reduced-screen, full-refine fast
    path above ``FAST_NDOF`` DOFs, the dense eigenvalues below).

    Searched up to at least 2 x ``speed_max`` (inf when stable there).  Kept on the model object for this rig: a later
    call within the range searched reuses it (the live identifier solves again at every new speed).
    """
    cached = getattr(model, '_plausibility_threshold', None)       # (rig, top of the range searched, threshold)
    if cached is not None and cached[0] is rig and 2.0 * float(speed_max) <= cached[1]:
        return cached[2]
    top = 4.0 * float(speed_max)
    try:
        thr = threshold_speed(model, bearing_fn(rig), top, method=method)
    except ValueError:              # unstable already at the bottom of the range
        thr = 0.0
    try:
        model._plausibility_threshold = (rig, top, thr)
    except AttributeError:          # a model that takes no attributes: no cache
        pass
    return thr


THRESHOLD_GRID = 40        # the geometric grid of :func:`bearing_id.rotor.stability.threshold_speed` (its default)


CAYLEY_STEP = 0.3          # the stability certificate's Cayley step h = CAYLEY_STEP / speed [s]
CERT_SQUARINGS = 30        # squarings of the Cayley transform before the certificate gives up
CERT_NORM = 0.5            # ... proved when the Frobenius norm of its 2^k-th power falls below this


def certified_stable(A: np.ndarray, h: float) -> bool:
    """
    Return True when every eigenvalue of ``A`` (n, n) is proved to lie in the open left half plane; False: not proved.

    The Cayley transform Cy = (I - h A)^-1 (I + h A) (h > 0 [s]) maps the open left half plane onto the open unit
    disc, and rho(Cy) <= ||Cy^(2^k)||^(1 / 2^k) for any norm: a Frobenius norm of a repeated square below
    :data:`CERT_NORM` proves rho < 1, i.e. A stable.  One LU and ~12 matrix products (~1 ms for the 88-state rig)
    instead of the ~2 ms of the dense eigenvalues; an unstable or nearly unstable A is never "proved" (its powers grow
    or do not shrink within :data:`CERT_SQUARINGS` squarings), and the caller computes the eigenvalues then.
    """
    n = A.shape[0]
    hA = h * np.asarray(A, dtype=float)
    Id = np.eye(n)
    try:
        Cy = np.linalg.solve(Id - hA, Id + hA)
    except np.linalg.LinAlgError:
        return False
    with np.errstate(over='ignore', invalid='ignore'):
        for _ in range(CERT_SQUARINGS):
            nf = float(np.sqrt(np.sum(Cy * Cy)))
            if nf < CERT_NORM:
                return True
            if not nf < 1e100:          # growing (or NaN): not provable
                return False
            Cy = Cy @ Cy
    return False


def threshold_for_gate(model, rig, speed_max: float, method: str = 'auto', certify: bool = True) -> float:
    """
    Return what the gate needs of the stability threshold [rad/s] for speeds up to ``speed_max``, scanning less.

    The same search as :func:`stability_threshold` (the geometric grid of
    :func:`bearing_id.rotor.stability.threshold_speed` from 0.2 to 4 x ``speed_max``, the first unstable grid point
    refined with brentq), stopped at the first stable grid point at or above ``speed_max``: when the crossing lies
    before it the value is the one :func:`stability_threshold` returns (same grid, same bracket, same brentq); else
    ``math.inf``, and :func:`stability_threshold` gives a threshold above that grid point, so no speed up to
    ``speed_max`` compares differently (test/test_plausibility_fast.py).  22 eigenvalue problems instead of 40 when
    the rig is stable over the data (the gate's cost in a 1-speed identification was a third of the whole).
    A threshold already on the model (:func:`stability_threshold`, e.g. from the identifier node's ``prepare``) is
    used as it is.  ``method`` as :func:`stability_threshold` (on a 160-element rotor 'auto' takes ~0.1 s per speed
    instead of ~1.3 s; test/test_stability_fast.py ties it to 'full').  ``certify`` (dense models, the default): a
    grid point is first offered to :func:`certified_stable` (a proof of stability at half the cost of the
    eigenvalues); only the points it cannot prove stable get the eigenvalues, so every decision is the eigenvalues'
    (test/test_plausibility_fast.py; both are meaningless only for an eigenvalue within rounding of the axis).
    """
    cached = getattr(model, '_plausibility_threshold', None)       # (rig, top of the range searched, threshold)
    if cached is not None and cached[0] is rig and 2.0 * float(speed_max) <= cached[1]:
        return cached[2]
    bfn = bearing_fn(rig)
    top = 4.0 * float(speed_max)
    grid = np.geomspace(top / 20, top, THRESHOLD_GRID)
    f = max_real_part_fn(model, bfn, top, method)
    dense = method == 'full' or (method == 'auto' and model.ndof <= _fast_ndof())

    def unstable(w):
        if certify and dense:
            if certified_stable(state_space(model, w, bfn(w))[0], CAYLEY_STEP / w):
                return False
        return f(w) > 0

    if unstable(grid[0]):       # unstable already at the bottom of the range (stability_threshold: 0)
        return 0.0
    for prev_w, w in zip(grid[:-1], grid[1:]):
        if unstable(w):
            return float(brentq(f, prev_w, w, xtol=1e-3, rtol=4 * np.finfo(float).eps))
        if w >= speed_max:
            return math.inf
    return math.inf


def _fast_ndof() -> int:
    return FAST_NDOF


def bearing_orbits(result, model, data, s: int, runs, probes, fast: bool = True) -> dict:
    """
    Return {bearing node: largest orbit radius [m] over the runs} at speed index ``s``.

    The model's response with the identified coefficients, scaled by the least-squares ratio of measured to modelled
    probe amplitudes.  ``fast``: every run's response from one factorisation of Z (sparse LU above
    ``direct.SPARSE_NDOF`` DOFs, the FE dynamic stiffness being banded); False: a dense
    :func:`bearing_id.rotor.assembly.harmonic_response` per run (the reference; test/test_direct_fast.py).
    """
    w = float(data.speeds[s])
    co = result.coeffs()
    S = probe_matrix(model, probes)
    out = dict.fromkeys(co, 0.0)
    forced = []
    for r, run in enumerate(runs):
        F = harmonic_forces(run.excitation, w, model.n_nodes, model.ndof).get(1.0)
        if F is not None:
            forced.append((r, F))
    if not forced:
        return out
    try:
        if fast:
            Z = dynamic_stiffness(model, w, w, co)
            Fs = np.stack([np.asarray(F, dtype=complex) for _, F in forced], axis=1)
            if Z.shape[0] > SPARSE_NDOF:
                lu = splu(sp.csc_matrix(Z))
                if not np.all(np.isfinite(lu.U.diagonal())) or np.any(lu.U.diagonal() == 0):
                    raise np.linalg.LinAlgError('singular dynamic stiffness')
                Q = lu.solve(Fs)
            else:
                Q = np.linalg.solve(Z, Fs)
            qs = [Q[:, k] for k in range(len(forced))]
        else:
            qs = [harmonic_response(model, w, w, F, co) for _, F in forced]
    except (np.linalg.LinAlgError, RuntimeError):
        return {n: math.inf for n in co}
    for (r, _), q in zip(forced, qs):
        pred = np.abs(S @ q)
        meas = np.abs(data.X[r, s])
        scale = float(pred @ meas / (pred @ pred)) if pred @ pred > 0 else math.inf
        for n in co:
            qx = q[dof_index(n, 'x', model.n_nodes)]
            qy = q[dof_index(n, 'y', model.n_nodes)]
            out[n] = max(out[n], scale * math.sqrt(abs(qx) ** 2 + abs(qy) ** 2))
    return out


def gate(results, model, rig, data, runs, probes) -> list:
    """
    Apply the gates (module docstring) to ``results`` in place; returns them.

    ``results``: one IdentResult per ``data.speeds`` entry, matched by speed.
    """
    if not results:
        return results
    speeds = np.asarray(data.speeds, dtype=float)
    thr = threshold_for_gate(model, rig, float(np.max(speeds)))
    clearance = {b.node: b.clearance for b in rig.bearings}
    amp = np.abs(data.X)                                   # (nr, ns, nch)
    std = np.asarray(data.X_std, dtype=float)
    for res in results:
        s = int(np.argmin(np.abs(speeds - res.speed)))
        reasons = []
        rpm = res.speed_rpm
        if res.speed >= thr:
            reasons.append(f"{rpm:.0f} rpm is at or above the model's stability threshold "
                           f'({thr * 60 / (2 * math.pi):.0f} rpm, oil whip): no steady 1X response exists there -- a '
                           f'wrong speed signal, or a machine the model does not describe')
        live = np.any(amp[:, s, :] > SIGNAL_SIGMA * np.maximum(std[:, s, :], 0.0), axis=0) & \
            np.any(amp[:, s, :] > 0, axis=0)
        for c in np.nonzero(~live)[0]:
            reasons.append(f'channel {probes[c].name}: no 1X signal above its noise in any run at {rpm:.0f} rpm '
                           f'(dead, constant or all-zero channel)')
        if not reasons:
            for node, r_orb in bearing_orbits(res, model, data, s, runs, probes).items():
                c = clearance.get(node)
                if c and not r_orb <= ORBIT_LIMIT * c:
                    reasons.append(f'the journal orbit at the bearing at node {node} would be {r_orb / c:.3g} x its '
                                   f'radial clearance at {rpm:.0f} rpm (limit {ORBIT_LIMIT:g}): outside the linear '
                                   f"coefficients' range -- or the samples are not in metres")
        if reasons:
            res.K_determined = np.zeros_like(res.K_determined, dtype=bool)
            res.C_determined = np.zeros_like(res.C_determined, dtype=bool)
            res.K_std = np.full_like(res.K, np.nan)
            res.C_std = np.full_like(res.C, np.nan)
            res.notes = list(res.notes) + [f'NOT PLAUSIBLE: {t}; not determined' for t in reasons]
    return results


__all__ = ['ORBIT_LIMIT', 'SIGNAL_SIGMA', 'stability_threshold', 'threshold_for_gate', 'certified_stable',
           'bearing_orbits', 'gate']
