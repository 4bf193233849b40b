"""
Bearing-coefficient identification: four methods, one result type, one experiment-design check.

Every method returns ``list[IdentResult]`` (one per speed, :mod:`bearing_id.identify.result`), with K, C (nb, 2, 2)
in N/m and N s/m, 1-sigma std, ``K_determined`` / ``C_determined`` masks, rank, unknowns, condition and residual.

Methods and the agreed call signature (every method takes the same positional arguments)::

    identify_<method>(model, rig, data, probes, runs, options=None) -> list[IdentResult]

    model   : rotor.assembly.RotorModel (the FE rotor WITHOUT bearings; nominal/updated).
    rig     : params.RigParams (bearing geometry and nominal oil for the theory/prior).
    data    : harmonics.HarmonicData -- measured 1X phasors per run and speed:
              data.speeds (ns,) rad/s, data.X complex (nr, ns, nch) [m], data.X_std (nr, ns, nch) [m] (1-sigma of the
              real and of the imaginary part), data.probes, data.runs; data.plain (each window's plain 1X fit)
              or data.recordings (the raw Recording list) for the paper method's Kalman filter, the recordings
              also for its NIS.
    probes  : tuple of params.Probe, one per channel of data.X (same order).
    runs    : tuple of params.Run, one per run of data.X (the known excitation).
    options : dict of method options (None = defaults); unknown keys are an error.

* ``paper``        (paper.py)        -- KF bearing-node estimates, then eqs 19-37 least squares (Kang et al. 2020).
* ``conventional`` (conventional.py) -- two probes per bearing interpolated to the bearing node, same solve.
* ``direct``       (direct.py)       -- output-error fit of the impedances to all probes/runs through the FE model.
* ``physical``     (physical.py)     -- viscosity/clearance per bearing fitted over all speeds at once.
* ``auto``         (auto.py)         -- the default: ``direct`` where the data determine every coefficient at every
  speed (the design check on the data's own probes, runs and noise), else ``physical``.

The experiment-design check is :func:`bearing_id.identify.design.check_design`.
"""
from __future__ import annotations

import importlib

import numpy as np

from .plausibility import gate
from .result import eq38_error, IdentResult

METHODS = ('auto', 'paper', 'conventional', 'direct', 'physical')


def get_method(name: str):
    """Return the identification function ``identify_<name>`` (see the module docstring for its signature)."""
    if name not in METHODS:
        raise ValueError(f'unknown identification method {name!r}: one of {METHODS}')
    mod = importlib.import_module(f'bearing_id.identify.{name}')
    return getattr(mod, f'identify_{name}')


def identify(method: str, model, rig, data, probes=None, runs=None, options=None) -> list[IdentResult]:
    """
    Run ``method`` on harmonic ``data``, then the physical plausibility gates.

    Probes and runs default to the data's own.  The gates (:mod:`bearing_id.identify.plausibility`: stability threshold,
    orbit vs clearance, live channels): a speed that fails one is returned not determined, with the reason in its notes;
    a speed whose model misfits (:func:`misfit_gate`) too.
    """
    fn = get_method(method)
    probes = tuple(probes if probes is not None else data.probes)
    runs = tuple(runs if runs is not None else data.runs)
    return misfit_gate(gate(fn(model, rig, data, probes, runs, options), model, rig, data, runs, probes))


def misfit_gate(results: list[IdentResult]) -> list[IdentResult]:
    """
    Clear every determined flag of each result flagged ``misfit`` (in place): a misfit is never a determined number.

    The model did not reproduce the data within their noise (the chi-square test of
    :func:`bearing_id.identify.determined.fit_quality`), so its coefficients carry a bias no 1-sigma covers.  The
    values and their (Birge-scaled) 1-sigma stay for a printer that is asked to show them flagged ``(misfit)``;
    ``extra['determined_if_fit']`` keeps what the rule would have determined had the model fitted.
    """
    for r in results:
        if r.misfit and (np.any(r.K_determined) or np.any(r.C_determined)):
            r.extra['determined_if_fit'] = (np.array(r.K_determined, bool), np.array(r.C_determined, bool))
            r.K_determined = np.zeros_like(r.K_determined, dtype=bool)
            r.C_determined = np.zeros_like(r.C_determined, dtype=bool)
            r.notes = list(r.notes) + ['MODEL MISFIT, so no coefficient is determined: the values are those of a '
                                       'model that does not reproduce the data (shown only flagged (misfit), '
                                       'e.g. `bearing-id identify --allow-misfit`)']
    return results


__all__ = ['IdentResult', 'eq38_error', 'METHODS', 'get_method', 'identify', 'misfit_gate']
