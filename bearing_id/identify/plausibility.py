"""
Physical plausibility gates on identification results.

A result from data the model cannot describe is not "determined", whatever its rank.  Applied by
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
* **Table range**: a speed outside the rows of a bearing or seal table is noted (the table's value is held there);
  ``physical`` then leaves that table bearing's coefficients not determined (a scaled held row is not the data's).

A failed gate sets every coefficient of that speed to not determined (std NaN) and says why in ``notes``.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .direct import SPARSE_NDOF
from ..bearings.table import outside as table_outside
from ..conventions import dof_index, rad_s_to_rpm
from ..excitation import harmonic_forces
from ..rotor.assembly import dynamic_stiffness, probe_matrix
from ..rotor.stability import threshold_speed
from ..rotor.supports import bearing_fn

ORBIT_LIMIT = 0.30      # fraction of the radial clearance (same rule as rig.check_validity and kf_estimator)
SIGNAL_SIGMA = 3.0      # a channel's 1X amplitude must exceed this many of its 1-sigma in some run


def stability_threshold(model, rig, speed_max: float) -> float:
    """
    Return the nominal model's stability threshold [rad/s] as far as speeds up to ``speed_max`` [rad/s] need it.

    :func:`bearing_id.rotor.stability.threshold_speed` on its geometric grid from 0.2 to 4 x ``speed_max``, stopped
    at the first stable grid point at or above ``speed_max``: the threshold when the crossing lies before it, else
    ``math.inf`` (the threshold, if any, lies above every speed asked about); 0 when the model is unstable already
    at the bottom of the range.  Kept on the model object for this rig: a later call with a ``speed_max`` the
    answer covers (up to this one for inf, twice it for a threshold) reuses it (the live identifier asks at every
    new speed; its ``prepare`` asks first with the top of the scenario).
    """
    cached = getattr(model, '_plausibility_threshold', None)       # (rig, largest speed_max covered, threshold)
    if cached is not None and cached[0] is rig and float(speed_max) <= cached[1]:
        return cached[2]
    try:
        thr = threshold_speed(model, bearing_fn(rig), 4.0 * float(speed_max), stop_above=float(speed_max))
    except ValueError:              # unstable already at the bottom of the range
        thr = 0.0
    try:
        model._plausibility_threshold = (rig, float(speed_max) * (1.0 if math.isinf(thr) else 2.0), thr)
    except AttributeError:          # a model that takes no attributes: no cache
        pass
    return thr


def bearing_orbits(result, model, data, s: int, runs, probes) -> dict:
    """
    Return {bearing node: largest orbit radius [m] over the runs} at speed index ``s``.

    The model's response with the identified coefficients, scaled by the least-squares ratio of measured to modelled
    probe amplitudes.  Every run's response from one factorisation of the dynamic stiffness Z (a sparse LU above
    ``direct.SPARSE_NDOF`` DOFs, the FE dynamic stiffness being banded; dense below); inf for a singular Z.
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
    Fs = np.stack([np.asarray(F, dtype=complex) for _, F in forced], axis=1)
    try:
        Z = dynamic_stiffness(model, w, w, co)
        if Z.shape[0] > SPARSE_NDOF:
            lu = splu(sp.csc_matrix(Z))
            if not np.all(np.isfinite(lu.U.diagonal())) or np.any(lu.U.diagonal() == 0):
                raise np.linalg.LinAlgError('singular dynamic stiffness')
            Q = lu.solve(Fs)
        else:
            Q = np.linalg.solve(Z, Fs)
    except (np.linalg.LinAlgError, RuntimeError):
        return {n: math.inf for n in co}
    for (r, _), q in zip(forced, Q.T):
        pred = np.abs(S @ q)
        meas = np.abs(data.X[r, s])
        scale = float(pred @ meas / (pred @ pred)) if pred @ pred > 0 else math.inf
        for n in co:
            qx = q[dof_index(n, 'x', model.n_nodes)]
            qy = q[dof_index(n, 'y', model.n_nodes)]
            out[n] = max(out[n], scale * math.sqrt(abs(qx) ** 2 + abs(qy) ** 2))
    return out


def known_clearance(bearing) -> bool:
    """Return True when the bearing's radial clearance [m] is a known positive number (a table may have none)."""
    c = bearing.clearance
    return c is not None and math.isfinite(float(c)) and float(c) > 0


def gate(results, model, rig, data, runs, probes) -> list:
    """
    Apply the gates (module docstring) to ``results`` in place; returns them.

    ``results``: one IdentResult per ``data.speeds`` entry, matched by speed.
    """
    if not results:
        return results
    speeds = np.asarray(data.speeds, dtype=float)
    thr = stability_threshold(model, rig, float(np.max(speeds)))
    known = {b.node: float(b.clearance) for b in rig.bearings if known_clearance(b)}
    names = {b.node: f'{b.name} (node {b.node})' for b in rig.bearings}
    unknown = [names[b.node] for b in rig.bearings if b.identify and not known_clearance(b)]
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
        if not reasons and known:
            for node, r_orb in bearing_orbits(res, model, data, s, runs, probes).items():
                c = known.get(node)
                if c is not None and not r_orb <= ORBIT_LIMIT * c:
                    reasons.append(f'the journal orbit at bearing {names[node]} would be {r_orb / c:.3g} x its '
                                   f'radial clearance at {rpm:.0f} rpm (limit {ORBIT_LIMIT:g}): outside the linear '
                                   f"coefficients' range -- or the samples are not in metres")
        held = [b for b in tuple(rig.bearings) + tuple(rig.known_elements())
                if b.model == 'table' and b.table is not None and table_outside(b.table, res.speed)]
        if held:
            spans = ', '.join(f'{b.name} ({rad_s_to_rpm(b.table.speeds[0]):.0f}-{rad_s_to_rpm(b.table.speeds[-1]):.0f}'
                              ' rpm)' for b in held)
            res.notes = list(res.notes) + [
                f'{rpm:.0f} rpm is outside the rows of the table(s) of {spans}: their coefficients are held '
                f'at the nearest row there (a table says nothing beyond its ends)']
            if res.method == 'physical':      # a fitted table bearing there is a scaled held row: not the data's
                for i, b in enumerate(rig.bearings):
                    if any(b is h for h in held):
                        res.K_determined[i] = False
                        res.C_determined[i] = False
        if unknown and not reasons:
            res.notes = list(res.notes) + [
                f"orbit-vs-clearance check skipped for {', '.join(unknown)}: no radial clearance known (a table "
                f"bearing may declare one: `clearance:` in its params entry); the samples' unit is not checked there"]
        if reasons:
            res.K_determined = np.zeros_like(res.K_determined, dtype=bool)
            res.C_determined = np.zeros_like(res.C_determined, dtype=bool)
            res.K_std = np.full_like(res.K, np.nan)
            res.C_std = np.full_like(res.C, np.nan)
            res.notes = list(res.notes) + [f'NOT PLAUSIBLE: {t}; not determined' for t in reasons]
            res.set_flag('not_plausible')
    return results


__all__ = ['ORBIT_LIMIT', 'SIGNAL_SIGMA', 'stability_threshold', 'bearing_orbits', 'known_clearance', 'gate']
