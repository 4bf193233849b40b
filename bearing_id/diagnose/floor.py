"""
Noise-floor check: identify's MODEL MISFIT test inside the diagnosis, and the bearing model form tested where it shows.

Why
    The diagnosis compares hypotheses with a *model tolerance* (``rel_tol``, 2 % of the measured amplitude) added to
    the noise floor, so that generic model imperfection is not reported as a missing effect.  ``bearing-id identify
    --method physical`` judges its fit at the noise floor alone: chi2/dof of the 1X vectors above the 99.9 % point
    of chi-square(dof)/dof is a MODEL MISFIT (:func:`misfit_threshold`, identify's own test).  A short-bearing model
    on a finite-length bearing (L/D = 1) is off by 1-2 % in the response once its viscosity and clearance are
    refitted: far above the noise floor, below the tolerance.  Without this check identify says MODEL MISFIT and the
    diagnosis says "none" on the same recording.

What
    The 1X vectors of :func:`bearing_id.identify.harmonics.from_recordings` (the one route identify uses: joint fit
    of the rotor's decaying modes, stationarity bias bound) are compared, with their 1-sigma only (no tolerance),
    with the diagnosis' final model (its effects re-fitted on these vectors, bearing viscosity/clearance nuisance
    free).  chi2/dof is the number identify reports for the nominal model when no effect was selected.  When it
    exceeds identify's limit, every bearing model form the physics core offers (:func:`predict.model_forms`) is
    fitted in place of the nominal one, jointly with the same effects.  A form is adopted only when it

    * lowers the BIC by more than ``dbic_min``,
    * removes at least ``min_reduction`` (default 50 %) of the noise-floor chi2, and
    * passes held-out validation on these vectors (fit on half the speeds, predict the other half, both ways;
      nothing re-fitted on the held-out half).

    When no form fixes the misfit of the diagnosis' model, the greedy selection is run once more *under* each
    form (every hypothesis holds it; :func:`select.select` with ``start``): a form and an effect can hide each
    other (a soft pedestal on finite-length bearings: neither the pedestal under the short-bearing theory nor the
    finite form without the pedestal validates).  That path is adopted when its form passes the same three tests
    given its own effects (:func:`form_row`), its noise-floor chi2/dof is at most half the first path's, and its
    BIC (with the model tolerance) is not worse.

    Otherwise the misfit is reported as unexplained (the verdict says so; it never says "within the noise floor").

Only the model form is tested at the noise floor: it is the one candidate that changes the bearing theory the
identification itself uses; every other effect must clear the model tolerance (at the noise floor anything a real
machine does differently from its model would pass for an effect).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import types

import numpy as np

from .locate import Observations, Window
from .predict import Problem
from .selection import evaluate, fit, NUIS_BOUND, speed_folds, validate
from ..identify.determined import misfit_threshold as thr
from ..identify.harmonics import from_recordings


def misfit_threshold(dof: int) -> float:
    """
    Return identify's chi2/dof limit for a MODEL MISFIT at ``dof`` degrees of freedom.

    The identify side owns the test (:func:`bearing_id.identify.determined.misfit_threshold`, the 99.9 % point of
    chi-square(dof)/dof); the diagnosis applies the same one, so the two never disagree on the same vectors.
    """
    return float(thr(max(int(dof), 1)))


@dataclass
class FloorCheck:
    """
    Result of :func:`noise_floor_check`.

    chi2_dof_none : chi2/dof of the nominal model with refitted bearing factors alone: what identify --method
    physical reports on these vectors.   chi2_dof : the same under the diagnosis' model (its effects, nominal form).
    misfit : chi2_dof > threshold (identify's MODEL MISFIT).   chi2_dof_after : the same for the final model (the
    form adopted, the 1X effects' parameters refined there).   forms : per tried form {form, chi2_dof, delta_bic,
    explained, validated, heldout_reduction}.   adopted : the BearingModelForm effect adopted, or None.
    n : real residuals.   note : why the check was skipped, if it was.
    """

    chi2_dof: float
    misfit: bool
    threshold: float
    n: int = 0
    forms: list = field(default_factory=list)
    effects_rows: list = field(default_factory=list)
    adopted: object = None
    adopted_row: dict | None = None
    adopted_fit: object = None
    path: str = ''
    chi2_dof_after: float = float('nan')
    chi2_dof_none: float = float('nan')
    threshold_none: float = float('nan')
    refined: str = ''
    note: str = ''

    def as_dict(self) -> dict:
        return {'chi2_dof_nominal': self.chi2_dof_none, 'threshold_nominal': self.threshold_none,
                'misfit_nominal': bool(self.chi2_dof_none > self.threshold_none),
                'chi2_dof': self.chi2_dof, 'misfit': self.misfit, 'threshold': self.threshold, 'n': self.n,
                'forms': self.forms, 'effects_without_form': self.effects_rows,
                'adopted': None if self.adopted is None else self.adopted.where,
                'path': self.path, 'chi2_dof_after': self.chi2_dof_after,
                'misfit_after': bool(self.chi2_dof_after > self.threshold),
                'parameters_fitted_at': self.refined or None,
                'note': self.note}


def identify_vectors(recordings) -> Observations:
    """
    Return the 1X vectors identify uses (:func:`identify.harmonics.from_recordings`) as Observations.

    One window per run and speed, 1-sigma per real/imaginary part; runs whose speeds differ are taken one by one.
    """
    recordings = list(recordings)
    try:
        datas = [from_recordings(recordings)]
    except ValueError:
        datas = [from_recordings([r]) for r in recordings]
    recs, wins = [], []
    for d in datas:
        for r, run in enumerate(d.runs):
            k = len(recs)
            recs.append(types.SimpleNamespace(run=run, probes=tuple(d.probes)))
            for s, W in enumerate(d.speeds):
                X, sd = d.X[r, s], d.X_std[r, s]
                if np.all(np.isfinite(X)) and np.all(np.isfinite(sd)):
                    wins.append(Window(rec=k, i0=0, i1=0, speed=float(W), X=np.asarray(X)[None],
                                       std=np.asarray(sd, float)[None]))
    obs = Observations(recordings=recs, windows=wins, orders=(1,))
    obs.harmonic_data = datas[0] if len(datas) == 1 else None     # reused by diagnose --report / --identify
    return obs


def floor_problem(recordings, rig, *, model=None, nuisance: bool = True):
    """(Problem on identify's 1X vectors with their 1-sigma only, note): the noise-floor problem, or (None, why)."""
    try:
        obs = identify_vectors(recordings)
    except (ValueError, RuntimeError, KeyError, IndexError, np.linalg.LinAlgError) as exc:
        return None, f'noise-floor check skipped: {exc}'
    if len(obs.windows) < 2:
        return None, 'noise-floor check skipped: fewer than two 1X vectors'
    return Problem(obs, rig, model=model, rel_tol=0.0, nuisance=nuisance, floor_tol=0.0), ''


def chi2_dof(f) -> float:
    return float(f.chi2 / max(f.n - f.k, 1))


def form_row(fprob, effects, form, *, dbic_min: float = 10.0, min_reduction: float = 0.5, base=None, folds=None):
    """
    Test whether ``form`` (a BearingModelForm) explains the noise-floor misfit of the hypothesis ``effects``.

    Returns (row dict, fit with the form) -- row: form, chi2_dof (with it), delta_bic, explained (chi2 share
    removed), validated (held-out on these vectors, both ways, nothing re-fitted on the held-out half),
    heldout_reduction.
    """
    effects = [e for e in effects if e is not form]
    base = fit(fprob, effects, uncertainty=False) if base is None else base
    f = fit(fprob, effects + [form], theta0=base.theta, uncertainty=False)
    return {'form': form.where, **_gain(fprob, base, f, effects, dbic_min, min_reduction, True, folds)}, f


def _gain(fprob, base, f, base_effects, dbic_min, min_reduction, allowed, folds) -> dict:
    """
    Row of what fit ``f`` gains over ``base`` (of ``base_effects``) on the noise-floor problem.

    chi2_dof (of ``f``), delta_bic, explained (chi2 share removed), validated (held-out, only tried when the BIC drop
    exceeds ``dbic_min``, the share ``min_reduction`` and ``allowed``), heldout_reduction.
    """
    explained = 1.0 - f.chi2 / max(base.chi2, 1e-300)
    dbic = float(base.bic - f.bic)
    v = None
    if dbic > dbic_min and explained >= min_reduction and allowed:
        v = validate(fprob, list(f.effects), list(base_effects), frac_in=explained,
                     folds=folds if folds is not None else speed_folds(fprob))
    return {'chi2_dof': chi2_dof(f), 'delta_bic': dbic, 'explained': float(explained),
            'validated': bool(v and v['validated']),
            'heldout_reduction': None if v is None else float(v['heldout_reduction'])}


EFFECTS_MIN_REDUCTION = 0.9    # share of the noise-floor chi2 effects found under a form must remove without it


def effects_row(fprob, effects, *, dbic_min: float = 10.0, min_reduction: float = EFFECTS_MIN_REDUCTION,
                folds=None):
    """
    Test whether ``effects`` (found by the selection under a bearing model form) explain the noise-floor misfit alone.

    The selection under a form can find an effect the nominal theory's model tolerance hid (its response change below
    the tolerance), and the form itself may then add nothing at the noise floor (:func:`form_row` not validated).
    The effects are kept on the nominal bearing theory only when, on identify's 1X vectors, they remove at least
    ``min_reduction`` of the nominal model's chi2 (default 90 %: far beyond what a generic model imperfection
    would give), lower the BIC by more than ``dbic_min``, leave every refitted bearing factor within two prior
    sigmas of nominal (a nuisance that moves beyond its prior band may not absorb what the effects leave), and pass
    the held-out validation there (fit on half the speeds, predict the other half, both ways).  Returns (row dict,
    fit): effects, chi2_dof, delta_bic, explained, nuisance_in_band, validated, heldout_reduction.
    """
    base = fit(fprob, [], uncertainty=False)
    f = fit(fprob, list(effects), uncertainty=False)
    in_band = bool(np.all(np.abs(np.asarray(f.theta, float)) <= 2.0 * fprob.prior_sigma))
    return {'effects': [e.label for e in effects], 'nuisance_in_band': in_band,
            **_gain(fprob, base, f, [], dbic_min, min_reduction, in_band, folds)}, f


def noise_floor_check(fprob, effects, form_candidates, *, dbic_min: float = 10.0, min_reduction: float = 0.5,
                      threshold: float | None = None) -> FloorCheck:
    """
    Apply identify's misfit test to the hypothesis ``effects``; try the model forms when it trips.

    ``effects`` are fitted on the noise-floor problem ``fprob`` (:func:`floor_problem`); when the test trips, each of
    ``form_candidates`` (BearingModelForm) is tried in place of the nominal form with the same effects (module
    docstring).  ``threshold`` : chi2/dof limit (default identify's, :func:`misfit_threshold` at this fit's dof).
    """
    base = fit(fprob, list(effects), uncertainty=False)
    thr = misfit_threshold(base.n - base.k) if threshold is None else float(threshold)
    out = FloorCheck(chi2_dof(base), bool(chi2_dof(base) > thr), thr, n=base.n)
    none = fit(fprob, [], uncertainty=False) if effects else base
    out.chi2_dof_none = chi2_dof(none)
    out.threshold_none = misfit_threshold(none.n - none.k)
    if not out.misfit or not form_candidates:
        return out
    best = None
    for c in form_candidates:
        row, f = form_row(fprob, effects, c, dbic_min=dbic_min, min_reduction=min_reduction, base=base)
        out.forms.append(row)
        if row['validated'] and (best is None or f.bic < best[0]):
            best = (f.bic, c, row)
    if best is not None:
        adopt(out, fprob, list(effects) + [best[1]], best[1], best[2])
    return out


def adopt(out: FloorCheck, fprob, effects, form, row, path: str = 'form') -> FloorCheck:
    """
    Record ``form`` as adopted in ``out``, with the noise-floor fit of ``effects`` (which hold it) and its 1-sigma.

    The bearing factors under the form come from these vectors.
    """
    out.adopted, out.adopted_row, out.path = form, row, path
    out.adopted_fit = fit(fprob, list(effects))
    return out


REFINE_MAX = 10.0     # refine at the noise floor while chi2/dof there is within this factor of identify's limit


def refine(prob, fprob, final, threshold: float):
    """
    Return ``final`` with its 1X parameters fitted at the noise floor, where the model allows it.

    Returns (Fit, floor fit, where the parameters come from).  ``final`` is a fit on the diagnosis' data with the
    model tolerance; the parameters of its 1X effects, their 1-sigma and the bearing nuisance are taken from the same
    hypothesis fitted on identify's 1X vectors at the noise floor (``fprob``), the data that determine them best
    (transients modelled, no tolerance; the 1-sigma is scaled by sqrt(chi2/dof) when that fit misfits).  Effects seen
    only off 1X (misalignment, oil whirl) keep their values.  The returned Fit holds the merged parameters evaluated
    on the diagnosis' data.

    Where: 'noise floor', or 'model tolerance' (``final`` returned) when the hypothesis misfits grossly at the noise
    floor (chi2/dof above ``REFINE_MAX`` x ``threshold``) or the floor fit pushes a bearing factor to the bound of its
    range: the model is then not right at that level, and a noise-level fit would bend the parameters to chase what
    it lacks (e.g. a bow of another shape than the fitted one); the tolerance-level values stand, and the misfit is
    reported.
    """
    use = [getattr(e, 'acts_on_1x', True) for e in final.effects]
    ff = fit(fprob, final.effects, theta0=final.theta, nl0=final.nls if final.effects else None)
    if not any(use):
        return final, ff, 'no 1X effect'
    if chi2_dof(ff) > REFINE_MAX * threshold or np.any(np.abs(np.asarray(ff.theta)) >= NUIS_BOUND - 1e-6):
        return final, ff, 'model tolerance'
    nls = [ff.nls[i] if u else final.nls[i] for i, u in enumerate(use)]
    lin, o = [], 0
    for e, u in zip(final.effects, use):
        lin.append((ff.lin if u else final.lin)[o:o + e.n_lin])
        o += e.n_lin
    lin = np.concatenate(lin) if lin else np.zeros(0)
    f = evaluate(prob, final.effects, np.concatenate([ff.theta, *nls]), lin=lin)
    f.phys = [ff.phys[i] if u else final.phys[i] for i, u in enumerate(use)]
    f.std = [ff.std[i] if u else final.std[i] for i, u in enumerate(use)]
    return f, ff, 'noise floor'


__all__ = ['FloorCheck', 'refine', 'floor_problem', 'noise_floor_check', 'form_row', 'effects_row', 'adopt',
           'identify_vectors', 'misfit_threshold']
