"""
Mismatch discovery: locate where recordings and the model disagree, name the physics that was left out, model it.

Library call::

    from bearing_id.diagnose import diagnose
    d = diagnose(recordings, rig)          # recordings: rig.Recording-like objects, rig: nominal RigParams
    d.verdict                              # 'none' | 'unexplained' | NAME | [NAME, NAME]
    d.sentences                            # plain words
    d.as_json()                            # the JSON report (``bearing-id diagnose --json``)

Pipeline: :mod:`.locate` (harmonic vectors, residuals, significance) -> :mod:`.predict` (model prediction with the
bearing nuisance) -> :mod:`.effects` (candidate physics) -> :mod:`.selection` (fit, BIC, held-out validation, greedy
selection) -> :mod:`.floor` (identify's noise-floor misfit test on the result; the bearing model form tried there)
-> :mod:`.bearings` (the bearings identify gives on its vectors, judged there against the model with effects: the
``bearing_mismatch`` verdict) -> :mod:`.signature` (where an unexplained residual lives, what it resembles, what to
measure next) -> :mod:`.report` (JSON, augmented params YAML, plots).

Bearing uncertainty: the nominal bearing theory is not trusted blindly.  Every hypothesis, "none" included, refits a
viscosity and a clearance factor per bearing (a Gaussian prior of 0.3 in log units around nominal, bounded to
x0.33 .. x3), so a bearing theory that is 25 % off is reported as refitted nuisance ("bearing factors"), not as a
missing effect; a factor beyond two prior sigmas or at the bound is reported as possibly standing in for missing
physics.  Pass ``nuisance=False`` to trust the nominal bearings as they are.

Bearing model form: a default candidate (``bearing_model_form``: the short bearing, the finite-length Reynolds
bearing under each cavitation condition the physics core offers: Swift-Stieber and Gumbel, each from its table).
It competes with the other effects at the model tolerance, and it is tried at the noise floor whenever identify's
MODEL MISFIT test trips on the diagnosis' model (:mod:`.floor`), so that ``bearing-id identify`` and ``bearing-id
diagnose`` never contradict each other.

Honest numbers: a parameter is given as a number only when its 1-sigma is within 7.5 % (2 sigma within 15 %);
otherwise it is reported undetermined with what the data do fix (for a pedestal, the dynamic stiffness k - m w^2 at
the lowest and highest running speed).  Held-out validation learns nothing from the held-out windows.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .bearings import bearing_mismatch
from .effects import candidates, EFFECT_NAMES, SupportFlexibility
from .floor import (adopt, chi2_dof, effects_row, floor_problem, form_row, misfit_threshold, noise_floor_check,
                    refine)
from .locate import locate_mismatch, Mismatch, Observations, observe
from .predict import Problem
from .selection import conflicts, fit, NUIS_BOUND, run_folds, select, Selection, speed_folds
from .signature import residual_signature


MIN_EXPLAINED = 0.5      # share of the residual power the named effects must explain when the model still misfits


@dataclass
class Diagnosis:
    """
    Result of :func:`diagnose`.

    verdict : 'none', 'unexplained' (no candidate explains a located mismatch or the noise-floor misfit), an effect
    name, or a list of names.   effects : selected effects with their parameters
    (final joint fit): list of dicts {effect, where, parameters, std, sentence}.   mismatch : located mismatches
    (against the nominal model with refitted bearing factors).   hypotheses : ranked candidate rows (as in the JSON).
    sentences : plain-words verdict.   residual_before / residual_after : RMS normalised residual (units of the
    effective sigma) of "none" and of the selected model over all entries.   residual_before_m / residual_after_m :
    RMS [m] of the *located* mismatch (the entries >= 3 sigma off under "none") before and after.
    bearing_factors : refitted nuisance factors.   effects[i]['undetermined'] : parameter names the data do not
    determine (reported as such).   noise_floor : identify's misfit test on the result (:class:`floor.FloorCheck`
    as a dict: chi2_dof before / chi2_dof_after, threshold, misfit, the forms tried, the one adopted).
    harmonic_data : the :class:`bearing_id.identify.harmonics.HarmonicData` of the recordings that the noise-floor
    check built (identify's route), or None: ``--report`` and ``--identify`` reuse it instead of refitting.
    signature : where the unexplained residual lives, what it resembles and what to measure next
    (:meth:`bearing_id.diagnose.signature.Signature.as_dict`), when the verdict is 'unexplained' or the final model
    still misfits; else None.
    """

    verdict: object
    effects: list
    mismatch: list
    hypotheses: list
    sentences: list
    residual_before: float
    residual_after: float
    residual_before_m: float
    residual_after_m: float
    bearing_factors: dict
    problem: Problem = field(repr=False)
    selection: Selection = field(repr=False)
    augmented_params: str | None = None
    notes: list = field(default_factory=list)
    noise_floor: dict | None = None
    harmonic_data: object = field(default=None, repr=False)
    signature: dict | None = None

    @property
    def explained_fraction(self) -> float:
        """1 - chi2_after / chi2_before (share of the residual power the selected effects explain)."""
        return float(1.0 - (self.residual_after / max(self.residual_before, 1e-300)) ** 2)

    def as_json(self) -> dict:
        return {'mismatch': [m.as_dict() for m in self.mismatch], 'hypotheses': self.hypotheses,
                'verdict': self.verdict, 'augmented_params': self.augmented_params,
                'selected': [dict(e.items()) for e in self.effects],
                'sentences': self.sentences, 'residual_before': self.residual_before,
                'residual_after': self.residual_after, 'residual_before_m': self.residual_before_m,
                'residual_after_m': self.residual_after_m, 'explained_fraction': self.explained_fraction,
                'bearing_factors': self.bearing_factors, 'notes': self.notes, 'noise_floor': self.noise_floor,
                'signature': self.signature}


def _hyp_row(before, f, v, step):
    e = f.effects[-1]
    i = len(f.effects) - 1
    return {'effect': e.name, 'where': e.where, 'step': step, 'with': [x.name for x in f.effects[:-1]],
            'parameters': f.phys[i], 'std': f.std[i], 'key_parameter': e.key,
            'residual_before': before.rms, 'residual_after': f.rms,
            'explained_fraction': float(1.0 - f.chi2 / max(before.chi2, 1e-300)),
            'bic': f.bic, 'delta_bic': float(before.bic - f.bic),
            'validated': bool(v and v.get('validated')),
            'heldout_reduction': None if v is None or v.get('heldout_reduction') is None
            else float(v['heldout_reduction'])}


def _entry_residuals(prob, f):
    """(residual complex [m], sigma [m]) over every nX entry and sub-synchronous entry for fit ``f``."""
    pred = prob.prediction_by_window(f.theta, f.effects, f.nls, f.lin)
    res, sig = [prob.y - np.concatenate([p.reshape(-1) for p in pred])], [prob.sig]
    for k, w in enumerate(prob.windows):
        if prob.has_sub and w.X_sub is not None:
            res.append(w.X_sub - f.sub_pred.get(k, 0.0))
            sig.append(np.maximum(w.std_sub, 1e-15))
    return np.concatenate(res), np.concatenate(sig)


def _nuisance_words(prob, theta) -> list:
    """
    Return sentences flagging refitted bearing factors far from nominal (beyond 2 prior sigma) or at the bound.

    There the nuisance may be standing in for missing physics.
    """
    if not prob.n_nuis:
        return []
    th = np.asarray(theta, float)
    out = []
    for i, v in enumerate(th):
        what = f'{prob.factor_words(i % prob.nb)[i // prob.nb]} of bearing {i % prob.nb + 1}'
        if abs(v) >= NUIS_BOUND - 1e-6:
            out.append(f'the {what} was refitted to x{np.exp(v):.2f}, the bound of the nuisance range '
                       f'(x{np.exp(-NUIS_BOUND):.2f} .. x{np.exp(NUIS_BOUND):.2f}): it is standing in for physics the '
                       f'model lacks; the effect parameters above are conditional on it')
        elif abs(v) > 2 * prob.prior_sigma:
            out.append(f'the {what} was refitted to x{np.exp(v):.2f}, beyond two prior sigmas of the nominal '
                       f'(x{np.exp(-2 * prob.prior_sigma):.2f} .. x{np.exp(2 * prob.prior_sigma):.2f}): '
                       f'check the oil temperature / clearance, or missing physics it may absorb')
    return out


def _mismatch_left(prob, f, pred, rel_tol, threshold) -> list:
    """Return the mismatch located against fit ``f``, ``pred`` its per-window prediction (sub-synchronous: its own)."""
    sub = [f.sub_pred.get(k) for k in range(len(prob.obs.windows))] if prob.has_sub else None
    return locate_mismatch(prob.obs, pred, sub, rel_tol=rel_tol, threshold=threshold)


def _keep_best_at_floor(prob, fprob, s, chosen, alts, dbic_min):
    """
    Keep whichever of ``chosen`` (a selected effect) and ``alts`` has the lowest BIC on identify's 1X vectors.

    Each is fitted there with the other selected effects.  When the best is ``dbic_min`` or more ahead of every other
    one, the tolerance-level ambiguity of ``chosen`` is dropped and, if the best is another, the selection's final fit
    is re-made with it; otherwise ``s`` is left as it is.
    """
    rest = [e for e in s.final.effects if e is not chosen]
    alts = [c for c in alts if c.label != chosen.label and not any(conflicts(c, e) for e in rest)]
    if not alts:
        return s
    bic = {c.label: fit(fprob, rest + [c], uncertainty=False).bic for c in [chosen] + alts}
    best = min([chosen] + alts, key=lambda c: bic[c.label])
    gap = min(abs(bic[c.label] - bic[best.label]) for c in [chosen] + alts if c is not best)
    if gap <= dbic_min:
        return s
    s.ambiguous.pop(chosen.label, None)
    if best is not chosen:
        effs = [best if e is chosen else e for e in s.final.effects]
        s.final = fit(prob, effs, theta0=s.final.theta)
        s.selected = list(effs)
    return s


def _settle_form(prob, fprob, s, cands, dbic_min):
    """
    Tell the bearing model form the selection took from the other forms at the noise floor.

    At the model tolerance two forms can fit about as well (e.g. the short and the finite bearing, each with its
    factors refitted); on identify's 1X vectors they separate.  The form with the lowest BIC there is kept (the
    selection's final fit is re-made with it when it is another one) and the tolerance-level ambiguity between forms
    is dropped when the noise floor resolves it (BIC difference above ``dbic_min``).
    """
    chosen = next(e for e in s.final.effects if e.name == 'bearing_model_form')
    return _keep_best_at_floor(prob, fprob, s, chosen, [c for c in cands if c.name == 'bearing_model_form'],
                               dbic_min)


def _rivals(s, chosen) -> list:
    """
    Return the other effects that validated in the selection round that took ``chosen``, when both are 1X-only.

    At the model tolerance two kinds of effect can both explain a mismatch and validate (a pedestal and a disc mass
    error both change the 1X response near a critical speed); the greedy step takes the lower BIC there.  Only
    effects whose whole signature is their 1X response (``only_1x``) are returned: identify's 1X vectors cannot judge
    a crack's 2X, a rub's harmonics or a misalignment's 2X force.
    """
    if not chosen.only_1x:
        return []
    for _, rows in s.rounds:
        if any(f.effects[-1].label == chosen.label for f, _ in rows):
            return [f.effects[-1] for f, v in rows if v and v.get('validated') and f.effects[-1].only_1x
                    and f.effects[-1].name not in (chosen.name, 'bearing_model_form')]
    return []


def _settle_location(prob, fprob, s, cands, dbic_min):
    """
    Tell the location (or kind) of a selected effect from the ones that fit about as well, at the noise floor.

    At the model tolerance two placements of one effect can fit about as well (a pedestal under one bearing or the
    other; a crack in one element or the next); on identify's 1X vectors they can separate.  For each selected
    effect with such alternatives (``s.ambiguous``), each placement is fitted there with the other effects; the one
    with the lowest BIC is kept (the selection's final fit re-made with it when it is another) and the ambiguity is
    dropped when the noise floor resolves it (BIC difference above ``dbic_min``).  A pedestal selected flexible in
    one direction is also tried flexible in both there (the selection screens one direction at a time: a pedestal
    soft in both is found by its softer direction).  When the selection misfits identify's vectors (identify's MODEL
    MISFIT test), the other kinds of effect that validated in the same round are tried there too (:func:`_rivals`):
    a wrong kind that fits at the tolerance is no answer when a rival fits at the noise floor.  Bearing model forms
    are :func:`_settle_form`'s.
    """
    f0 = fit(fprob, list(s.final.effects), uncertainty=False)
    misfit = chi2_dof(f0) > misfit_threshold(f0.n - f0.k)
    for chosen in [e for e in s.final.effects if e.name != 'bearing_model_form']:
        wheres = {w for w, _ in s.ambiguous.get(chosen.label, [])}
        alts = [c for c in cands if c.name == chosen.name and c.where in wheres] + (
            _rivals(s, chosen) if misfit else [])
        for c in [chosen] + alts:
            if isinstance(c, SupportFlexibility) and len(c.directions) == 1:
                alts.append(SupportFlexibility(c.bearing_index, c.node, 'xy', c.mass, c.speeds))
        s = _keep_best_at_floor(prob, fprob, s, chosen, alts, dbic_min)
    return s


def diagnose(recordings, rig, *, held_out: str = 'speeds', rel_tol: float = 0.02, nuisance: bool = True,
             effects=EFFECT_NAMES, max_effects: int = 3, dbic_min: float = 10.0, threshold: float = 5.0,
             chi2_floor: float = 1.5, unbalance_planes=None, model=None, noise_floor: bool = True) -> Diagnosis:
    """
    Diagnose what physics the nominal model ``rig`` (RigParams) misses in ``recordings``.

    recordings : list of recordings (``samples`` (N, nch) m, ``angle`` rad, ``speed`` rad/s, ``t`` s, ``probes``,
        ``run.excitation`` the known excitation), e.g. :class:`bearing_id.signals.recording.Recording` or from
        ``rig.load_npz``.
    held_out : 'speeds' (fit on every other recorded speed, predict the rest, both ways) or 'runs' (alternate
        recordings; needs >= 2).
    rel_tol : model tolerance added to the noise floor (fraction of the measured amplitude).
    nuisance : refit bearing viscosity/clearance factors in every hypothesis (see module docstring).
    effects : candidate effect names (default all of :data:`EFFECT_NAMES`, the bearing model form included).
    noise_floor : run the noise-floor check (:mod:`.floor`: identify's MODEL MISFIT criterion on identify's 1X
        vectors, and the bearing model forms tried there when it trips).
    """
    recordings = list(recordings)
    obs = observe(recordings)
    if not obs.windows:
        raise ValueError('no steady-speed window with at least one revolution in the recordings')
    prob = Problem(obs, rig, model=model, rel_tol=rel_tol, nuisance=nuisance)
    if held_out == 'runs':
        if len(recordings) < 2:
            raise ValueError("held_out='runs' needs at least two recordings")
        folds = run_folds(prob)
    elif held_out == 'speeds':
        folds = speed_folds(prob)
    else:
        raise ValueError(f"held_out must be 'speeds' or 'runs', got {held_out!r}")
    base0 = fit(prob, [])
    if 'rub' in effects and not residual_signature(prob, base0, threshold=3.0).speed_local:
        effects = tuple(n for n in effects if n != 'rub')      # a rub acts where the orbit is largest: speed-local
    cands = candidates(prob, unbalance_planes=unbalance_planes, names=effects)
    fprob, fnote = (floor_problem(recordings, rig, model=prob.model, nuisance=nuisance) if noise_floor
                    else (None, ''))
    # the bearings first: when the nominal model misfits identify's vectors and the bearings identify gives on them
    # reproduce them, one effect at most is tried against the bearings (a greedy selection would otherwise spread
    # the bearings' mismatch over several invented effects while the model still misfits)
    bcheck = pre = None
    if fprob is not None:
        f0 = fit(fprob, [], uncertainty=False)
        thr0 = misfit_threshold(f0.n - f0.k)
        if chi2_dof(f0) > thr0:
            pre = bearing_mismatch(fprob, rig, prob.model, [], thr0, model_fit=f0)
            if pre.wins:
                max_effects = 1
    s = select(prob, cands, max_effects=max_effects, dbic_min=dbic_min, chi2_floor=chi2_floor, peak_sigma=threshold,
               folds=folds, base=base0)
    # noise-floor check: the same test identify applies; the bearing model form tried there when it trips
    fc = None
    if fprob is not None:
        s = _settle_location(prob, fprob, s, cands, dbic_min)
        have_form = any(e.name == 'bearing_model_form' for e in s.final.effects)
        if have_form:
            s = _settle_form(prob, fprob, s, cands, dbic_min)
        forms = [] if have_form or 'bearing_model_form' not in effects else \
            [c for c in cands if c.name == 'bearing_model_form']
        fc = noise_floor_check(fprob, s.final.effects, forms, dbic_min=dbic_min)
        if fc.misfit and fc.adopted is None and forms:
            # a form and an effect may hide each other: run the selection under each form
            others = [c for c in cands if c.name != 'bearing_model_form']
            best, bare = None, None
            for form in forms:
                s2 = select(prob, others, max_effects=max_effects, dbic_min=dbic_min, chi2_floor=chi2_floor,
                            peak_sigma=threshold, folds=folds, start=[form], base=s.base)
                s2 = _settle_location(prob, fprob, s2, others, dbic_min)
                row, f2 = form_row(fprob, s2.final.effects, form, dbic_min=dbic_min)
                ok = (row['validated'] and row['chi2_dof'] <= 0.5 * fc.chi2_dof
                      and s2.final.bic <= s.final.bic + dbic_min)
                fc.forms.append({**row, 'path': 'selection under this form',
                                 'effects': [e.label for e in s2.final.effects if e is not form]})
                if ok and (best is None or row['chi2_dof'] < best[2]['chi2_dof']):
                    best = (form, s2, row)
                kept = [e for e in s2.final.effects if e is not form]
                if not row['validated'] and kept:
                    # the form adds nothing to the effects found under it once they are placed at the noise floor:
                    # those effects may explain the misfit on the nominal bearing theory
                    erow, _ = effects_row(fprob, kept, dbic_min=dbic_min)
                    fc.effects_rows.append({**erow, 'found_under': form.where})
                    if erow['validated'] and (bare is None or erow['chi2_dof'] < bare[1]['chi2_dof']):
                        bare = (kept, erow, s2)
            if best is not None:
                form, s2, row = best
                adopt(fc, fprob, s2.final.effects, form, row, path='selection under this form')
                s = s2
            elif bare is not None:
                kept, erow, s2 = bare
                f = fit(prob, kept)
                # ... and only when they leave no located mismatch at the model tolerance on the nominal theory
                left = _mismatch_left(prob, f, prob.prediction_by_window(f.theta, f.effects, f.nls, f.lin),
                                      rel_tol, threshold)
                erow['mismatch_left'] = bool(left)
                if not left:
                    v = {'validated': True, 'heldout_reduction': erow['heldout_reduction'], 'noise_floor': True,
                         'row': erow, 'chi2_dof_before': fc.chi2_dof}
                    s = Selection(base=s.base, final=f, rounds=[(s.base, [(f, v)])], selected=list(kept),
                                  ambiguous={k: a for k, a in s2.ambiguous.items() if any(e.label == k for e in kept)})
                    fc.path = 'effects found under a bearing model form, kept without it'
        if fc.adopted is not None:
            # the form and the bearing factors under it come from the noise-floor fit (the data that determine
            # them); the other effects are re-fitted on the diagnosis' data with those bearings
            ff = fc.adopted_fit
            before = s.final
            f = fit(prob, ff.effects, theta0=ff.theta, free_nuisance=False)
            i = next(n for n, e in enumerate(ff.effects) if e is fc.adopted)
            f.phys[i], f.std[i] = ff.phys[i], ff.std[i]
            v = {'validated': True, 'heldout_reduction': fc.adopted_row['heldout_reduction'], 'noise_floor': True,
                 'row': fc.adopted_row, 'chi2_dof_before': fc.chi2_dof}
            if fc.path == 'form':
                s.rounds.append((before, [(f, v)]))
            else:           # the selection ran under the form: report the form as the first step
                s.rounds.insert(0, (s.base, [(fit(prob, [fc.adopted], theta0=ff.theta, free_nuisance=False), v)]))
            s.selected = list(f.effects)
            s.final = f
        # the parameters of the 1X effects (and the bearing nuisance) from identify's vectors at the noise floor;
        # the final model's chi2/dof there is what identify would say about it
        fc.chi2_dof_after = fc.chi2_dof
        if s.final.effects:
            s.final, ff, fc.refined = refine(prob, fprob, s.final, fc.threshold)
            fc.chi2_dof_after = chi2_dof(ff)
        if fc.chi2_dof_after > fc.threshold and fc.adopted is None:
            # the bearings identified speed by speed, where the data determine them, against the model with effects
            bcheck = bearing_mismatch(fprob, rig, prob.model, s.final.effects, fc.threshold,
                                      results=None if pre is None else pre.results,
                                      model_fit=None if s.final.effects else f0)
            if bcheck.wins:
                kept = [e for e in s.final.effects if not e.only_1x]
                before = s.final
                f = fit(prob, [bcheck.effect] + kept)
                row = {'chi2_dof': bcheck.chi2_dof, 'delta_bic': bcheck.bic_model - bcheck.bic,
                       'explained': 1.0 - bcheck.chi2_dof / max(bcheck.chi2_dof_model, 1e-300),
                       'heldout_reduction': None}
                s.rounds.append((before, [(f, {'validated': True, 'noise_floor': True, 'row': row,
                                               'chi2_dof_before': fc.chi2_dof_after})]))
                s.final, s.selected = f, list(f.effects)
                s.ambiguous = {k: a for k, a in s.ambiguous.items() if any(e.label == k for e in kept)}
                fc.chi2_dof_after, fc.refined = bcheck.chi2_dof, 'noise floor'
    base, final = s.base, s.final
    pred_base = prob.prediction_by_window(base.theta, [], [], np.zeros(0))
    mism = locate_mismatch(obs, pred_base, None, rel_tol=rel_tol, threshold=threshold)
    hyps = []
    for step, (before, rows) in enumerate(s.rounds):
        for f, v in rows:
            row = _hyp_row(before, f, v, step)
            if v and v.get('noise_floor'):
                r = v['row']
                row.update(tested_at="noise floor (identify's 1X vectors, no model tolerance)",
                           delta_bic=r['delta_bic'], explained_fraction=r['explained'],
                           chi2_dof_before=v['chi2_dof_before'], chi2_dof_after=r['chi2_dof'])
            hyps.append(row)
    # a model that misfits shows no number its misfit disowns: parameters fitted at the model tolerance while the
    # final model misfits identify's vectors at the noise floor have their 1-sigma scaled by the Birge ratio there
    # (sqrt(chi2/dof)); the noise-floor refit has it already
    birge = 1.0
    if (fc is not None and np.isfinite(fc.chi2_dof_after) and fc.chi2_dof_after > fc.threshold
            and fc.refined != 'noise floor'):
        birge = float(np.sqrt(fc.chi2_dof_after))
        final.std = [{k: v * birge for k, v in sd.items()} for sd in final.std]
    chosen = []
    for i, e in enumerate(final.effects):
        sent = e.sentence(final.phys[i], final.std[i])
        alts = s.ambiguous.get(e.label, [])
        if alts:
            form = e.name == 'bearing_model_form'
            sent += (('; the bearing model form is not resolved: ' if form else '; the location is not resolved: ')
                     + ', '.join(f'{w} fits about as well (screening BIC difference {d:+.1f})' for w, d in alts)
                     + (' -- more speeds or runs tell them apart' if form else
                        ' -- measure at another station to tell them apart'))
        chosen.append({'effect': e.name, 'where': e.where, 'parameters': final.phys[i], 'std': final.std[i],
                       'key_parameter': e.key, 'sentence': sent,
                       'undetermined': e.undetermined(final.phys[i], final.std[i]),
                       'alternatives': [{'where': w, 'delta_bic': d} for w, d in alts]})
    names = [e.name for e in final.effects]
    sentences = []
    misfit_after = fc is not None and np.isfinite(fc.chi2_dof_after) and fc.chi2_dof_after > fc.threshold
    # no confident wrong name: effects that explain less than MIN_EXPLAINED of the residual power while the model
    # still misfits at the noise floor are a partial fit to something else (a mispredicted response, a fault the
    # library lacks), not the answer
    partial, frac_partial = [], 1.0 - final.chi2 / max(base.chi2, 1e-300)
    if not mism and fc is not None and np.isfinite(fc.chi2_dof) and np.isfinite(fc.chi2_dof_after):
        # nothing located at the model tolerance: the effects were found at the noise floor, judged there
        frac_partial = 1.0 - fc.chi2_dof_after / max(fc.chi2_dof, 1e-300)
    if names and misfit_after and frac_partial < MIN_EXPLAINED:
        partial, chosen, names = chosen, [], []
        final = s.final = base
        misfit_after = bool(fc.misfit)
    vf, cf = prob.nuisance_factors(final.theta)
    # no candidate explains a located mismatch or the noise-floor misfit: "unexplained", with where it lives
    unexplained = not names and (bool(mism) or (fc is not None and fc.misfit))
    remaining = []        # located mismatch the selected effects leave (against the final model)
    pred_final = (pred_base if final is base else
                  prob.prediction_by_window(final.theta, final.effects, final.nls, final.lin))
    if names:
        remaining = _mismatch_left(prob, final, pred_final, rel_tol, threshold)
    sig = None
    if unexplained or misfit_after or remaining:
        sig = residual_signature(prob, final, threshold=3.0, pred=pred_final)
        if not sig.significant and fprob is not None:       # below the model tolerance: at the noise floor
            sig = residual_signature(fprob, fit(fprob, list(final.effects), uncertainty=False), threshold=3.0)
    verdict = ('unexplained' if unexplained else 'none') if not names else (names[0] if len(names) == 1 else names)
    if not names:
        if unexplained and not (fc is not None and fc.misfit):
            top = mism[0]
            sentences.append(f'none of the candidate effects explains the located mismatch ({top.order} at '
                             f'{top.where}, {top.significance:.0f} sigma, {len(mism)} group(s) beyond '
                             f'{threshold:g} sigma): it is not physics this diagnosis models')
        elif fc is not None and fc.misfit:
            best = min(fc.forms, key=lambda r: r['chi2_dof'], default=None)
            sentences.append(
                f'none of the candidate effects explains a mismatch above the {rel_tol:.0%} model tolerance '
                f'(residual {base.rms:.2f} sigma), but the model does NOT reproduce the 1X vectors at the noise floor: '
                f'chi2/dof = {fc.chi2_dof:.3g} > {fc.threshold:.3g} (what `bearing-id identify --method physical` '
                f'reports as MODEL MISFIT)'
                + (f"; no bearing model form explains it either (best: {best['form']}, chi2/dof "
                   f"{best['chi2_dof']:.3g}, {'validated' if best['validated'] else 'not validated'})" if best else '')
                + ' -- the missing physics is below what this diagnosis can attribute; identified coefficients carry '
                  'a model-form bias')
        else:
            floor = (f"the noise floor (1X chi2/dof {fc.chi2_dof:.3g} <= {fc.threshold:.3g} on identify's vectors) "
                     f'and ' if fc is not None and np.isfinite(fc.chi2_dof) else 'the noise floor and ')
            sentences.append(f'none: the nominal model explains the recordings within {floor}'
                             f'the {rel_tol:.0%} model tolerance (residual {base.rms:.2f} sigma)')
        for c in partial:
            sentences.append(f"partly fitted, not named: {c['effect']} at {c['where']} (with the others here "
                             f'{frac_partial:.0%} of the residual power, and the model still misfits at the noise '
                             f'floor; a name needs {MIN_EXPLAINED:.0%})')
        if sig is not None:
            sentences += sig.sentences()
        if bcheck is not None and bcheck.note:
            sentences.append(f'not a bearing mismatch alone: the bearings `bearing-id identify` gives on these data: '
                             f'{bcheck.note}')
    else:
        frac = 1.0 - final.chi2 / max(base.chi2, 1e-300)
        for c in chosen:
            sentences.append(c['sentence'])
        if bcheck is not None and bcheck.wins:
            sentences.append(bcheck.sentence())
        tol_names = [e.name for e in final.effects if (fc is None or e is not fc.adopted)
                     and e.name != 'bearing_mismatch']
        if tol_names:
            sentences.append(f"{'together they explain' if len(tol_names) > 1 else 'explains'} {frac:.0%} of the "
                             f'residual power (RMS {base.rms:.3g} -> {final.rms:.3g} sigma), validated on held-out '
                             f"{'speeds' if held_out != 'runs' else 'runs'}")
        if fc is not None and fc.adopted is not None:
            sentences.append(f"the bearing model form was found at the noise floor (identify's 1X vectors): chi2/dof "
                             f"{fc.chi2_dof:.3g} -> {fc.adopted_row['chi2_dof']:.3g}, held-out reduction "
                             f"{fc.adopted_row['heldout_reduction']:.0%} (`bearing-id identify --method physical` "
                             f'flags the nominal form as MODEL MISFIT)')
        if fc is not None and np.isfinite(fc.chi2_dof_after):
            if misfit_after:
                sentences.append(f"at the noise floor the final model still misfits identify's 1X vectors: chi2/dof "
                                 f"{fc.chi2_dof_after:.3g} > {fc.threshold:.3g} (identify's MODEL MISFIT test): "
                                 f'physics below the {rel_tol:.0%} model tolerance remains unexplained, and the '
                                 f'parameters above carry a bias their 1-sigma does not cover')
                if sig is not None:
                    sentences += sig.sentences('what remains unexplained')
            else:
                sentences.append(f"at the noise floor the final model reproduces identify's 1X vectors: chi2/dof "
                                 f'{fc.chi2_dof_after:.3g} <= {fc.threshold:.3g}')
            if fc.refined == 'noise floor':
                sentences.append("the parameters above are fitted on identify's 1X vectors at the noise floor"
                                 + (' (1-sigma scaled by sqrt(chi2/dof))' if misfit_after else ''))
            elif fc.refined == 'model tolerance':
                sentences.append('the parameters above are fitted with the model tolerance (the model misfits too '
                                 'much at the noise floor for a fit there)'
                                 + (f'; their 1-sigma is scaled by sqrt(chi2/dof) = {birge:.3g} of that misfit'
                                    if birge > 1 else ''))
        if remaining and not misfit_after and sig is not None:
            top = remaining[0]
            sentences.append(f'the selected effects leave a located mismatch ({top.order} at {top.where}, '
                             f'{top.significance:.0f} sigma): the names above may be part of a source they do not '
                             f'model')
            sentences += sig.sentences('what remains unexplained')
    # significant hypotheses that did not validate: say so (a whirl seen at one speed, a fit to noise)
    sel_labels = {e.label for e in final.effects}
    failed = [(f, v) for _, rows in s.rounds for f, v in rows
              if v is not None and not v.get('validated') and f.effects[-1].label not in sel_labels]
    shown = set()
    for f, v in failed:
        e = f.effects[-1]
        if e.name in shown or e.name in names:
            continue
        shown.add(e.name)
        red = v.get('heldout_reduction')
        if v.get('signature_missing'):
            sentences.append(f"fits but not accepted: {e.name} at {e.where} -- {v['signature_missing']}")
            continue
        sentences.append(f'tested but not validated on held-out data: {e.name} at {e.where} (in-sample it lowers the '
                         f'BIC, held-out chi2 change {-red:+.0%} where a drop of at least '
                         f"{v.get('required_reduction', 0.2):.0%} was needed)" if red is not None else
                         f"tested but not validated on held-out data: {e.name} at {e.where} ({v.get('reason', '')})")
    if nuisance:
        words = [prob.factor_words(i) for i in range(prob.nb)]
        sentences.append('bearing theory refitted as nuisance: ' + '; '.join(
            f'bearing {i + 1} {w[0]} x{vf[i]:.2f}, {w[1]} x{cf[i]:.2f}' for i, w in enumerate(words))
            + ' (nuisance values, held near nominal by their prior where the data do not fix them: `bearing-id '
              'identify` gives the bearings with their 1-sigma)')
        sentences += _nuisance_words(prob, final.theta)
    # the located mismatch: entries significant (>= 3 sigma) against "none"; their RMS before and after [m]
    rb, sg = _entry_residuals(prob, base)
    ra, _ = _entry_residuals(prob, final)
    mask = np.abs(rb) >= 3.0 * sg
    if not mask.any():
        mask = np.ones_like(mask)
    notes = list(obs.notes) + ([fnote] if fnote else [])
    return Diagnosis(verdict=verdict, effects=chosen, mismatch=mism, hypotheses=hyps, sentences=sentences,
                     residual_before=base.rms, residual_after=final.rms,
                     residual_before_m=float(np.sqrt(np.mean(np.abs(rb[mask]) ** 2))),
                     residual_after_m=float(np.sqrt(np.mean(np.abs(ra[mask]) ** 2))),
                     bearing_factors={'viscosity_factor': list(vf), 'clearance_factor': list(cf)},
                     problem=prob, selection=s, notes=notes,
                     noise_floor=None if fc is None else {**fc.as_dict(), 'bearing_mismatch': (
                         None if bcheck is None else bcheck.as_dict())},
                     signature=None if sig is None else sig.as_dict(),
                     harmonic_data=getattr(fprob.obs, 'harmonic_data', None) if fprob is not None else None)


__all__ = ['diagnose', 'Diagnosis', 'EFFECT_NAMES', 'observe', 'locate_mismatch', 'Observations', 'Mismatch']
