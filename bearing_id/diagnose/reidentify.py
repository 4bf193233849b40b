"""
Identification re-run on the augmented model: the step after a diagnosis (``bearing-id diagnose --identify``).

The same identification method is run twice on the same recordings: on the nominal model (what ``bearing-id
identify`` does) and on the augmented model of the diagnosis (:class:`augmented.AugmentedModel`: measurement effects
removed from the 1X phasors, force effects added to the known excitation, model effects in the dynamic stiffness).
When the recordings carry the truth (simulated rig) both are scored with the paper's eq. 38 error.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .augmented import AugmentedModel
from ..identify import get_method
from ..identify.harmonics import from_recordings
from ..identify.result import eq38_error
from ..rotor.assembly import RotorModel

HOOK_METHODS = ('physical', 'direct')     # methods that accept the augmented-model hook


@dataclass
class Reidentification:
    """
    Before/after identification.

    before, after : list[IdentResult] (one per speed).   truth : list of {node: (K, C)} per speed or None.
    error_before / error_after : eq. 38 error dicts [%] or None.   effects : names of the augmentations used.
    """

    method: str
    before: list
    after: list
    truth: list | None
    error_before: dict | None
    error_after: dict | None
    effects: list = field(default_factory=list)

    def as_json(self) -> dict:
        keys = ('K_direct', 'K_cross', 'C_direct', 'C_cross', 'K', 'C', 'all')
        return {'method': self.method, 'effects': self.effects,
                'before': [r.to_dict() for r in self.before], 'after': [r.to_dict() for r in self.after],
                'error_before_pct': None if self.error_before is None else {k: self.error_before[k] for k in keys},
                'error_after_pct': None if self.error_after is None else {k: self.error_after[k] for k in keys}}


def refitted_bearings(rig):
    """
    Return ``rig`` with each bearing's viscosity and clearance scaled by the factors the diagnosis refitted.

    The factors are ``extra['diagnose_bearing_factors']`` (``rig`` unchanged without them): the start / theory of
    the re-run.
    """
    f = (rig.extra or {}).get('diagnose_bearing_factors') or {}
    vf, cf = f.get('viscosity_factor'), f.get('clearance_factor')
    if not vf or not cf:
        return rig
    return rig.replace(bearings=tuple(dataclasses.replace(b, viscosity=b.viscosity * float(v),
                                                          clearance=b.clearance * float(c))
                                      for b, v, c in zip(rig.bearings, vf, cf)))


def reidentify(recordings, rig, augmented_rig, method: str = 'physical', options=None,
               data=None) -> Reidentification:
    """
    Run ``method`` on the nominal model ``rig`` and on the augmented model ``augmented_rig``.

    ``augmented_rig``: a params set with ``extra.effects``, e.g. :func:`report.augmented_rig` of a diagnosis or a
    loaded augmented params file.  The augmented run starts from the bearing theory with the diagnosis' refitted
    factors (:func:`refitted_bearings`), the nominal run from the nominal theory.

    recordings : rig.Recording list (one per excitation run, same probes).   options : method options (both runs).
    data : their :func:`harmonics.from_recordings` when already computed (e.g. :attr:`Diagnosis.harmonic_data`).
    """
    if method not in HOOK_METHODS:
        raise ValueError(f'identification on the augmented model supports {HOOK_METHODS}, not {method!r}')
    data = from_recordings(recordings) if data is None else data
    model = RotorModel.from_params(rig)
    fn = get_method(method)
    aug = AugmentedModel(model, augmented_rig)
    opts_before = dict(options or {})
    own = {b.model for b in rig.bearings}
    if method == 'physical' and 'bearing_model' not in opts_before and len(own) == 1 and own <= {'short', 'finite'}:
        opts_before['bearing_model'] = next(iter(own))      # the nominal model as the params file has it
    before = fn(model, rig, data, data.probes, data.runs, opts_before)
    opts_after = {**(options or {}), 'augment': aug}
    names = list(aug.names)
    forms = {b.model for b in augmented_rig.bearings}
    if forms != {b.model for b in rig.bearings} and len(forms) == 1:
        # the diagnosis found the bearing model form: the physical method fits that form on the augmented model
        form = next(iter(forms))
        if method == 'physical' and 'bearing_model' not in (options or {}):
            opts_after['bearing_model'] = form
        names.append(f'bearing_model_form ({form})')
    after = fn(model, refitted_bearings(augmented_rig), aug.correct_data(data), data.probes, data.runs, opts_after)
    truth = None
    eb = ea = None
    if data.truth:
        truth = [data.truth_at(r.speed) for r in before]
        if all(t is not None for t in truth):
            eb, ea = eq38_error(before, truth), eq38_error(after, truth)
        else:
            truth = None
    return Reidentification(method=method, before=before, after=after, truth=truth, error_before=eb,
                            error_after=ea, effects=names)


def format_table(r: Reidentification) -> list[str]:
    """Printable lines: per speed and bearing K [MN/m] and C [N s/m] before / after (/ truth), then eq. 38 errors."""
    lines = [f'identification ({r.method}) on the nominal model vs the augmented model '
             f"[{', '.join(r.effects) or 'no model-side effects'}]:",
             f"  {'rpm':>6s} {'bearing':8s} {'model':9s} {'Kxx':>8s} {'Kxy':>8s} {'Kyx':>8s} {'Kyy':>8s}   [MN/m]"
             f" {'Cxx':>8s} {'Cxy':>8s} {'Cyx':>8s} {'Cyy':>8s}   [N s/m]"]
    for s, (b, a) in enumerate(zip(r.before, r.after)):
        for i, name in enumerate(b.bearings):
            rows = [('nominal', b.K[i], b.C[i]), ('augmented', a.K[i], a.C[i])]
            if r.truth is not None:
                n = b.nodes[i]
                rows.append(('truth', np.asarray(r.truth[s][n][0]), np.asarray(r.truth[s][n][1])))
            for label, K, C in rows:
                lines.append(f'  {b.speed_rpm:6.0f} {name:8s} {label:9s} '
                             + ' '.join(f'{v / 1e6:8.4f}' for v in np.asarray(K, float).reshape(4)) + '         '
                             + ' '.join(f'{v:8.2f}' for v in np.asarray(C, float).reshape(4)))
    if r.error_before is not None:
        keys = ('K_direct', 'K_cross', 'C_direct', 'C_cross', 'all')
        lines.append('  eq. 38 error vs truth [%]    ' + '  '.join(f'{k:>8s}' for k in keys))
        for label, e in (('nominal model', r.error_before), ('augmented model', r.error_after)):
            lines.append(f'  {label:28s} ' + '  '.join(f'{e[k]:8.2f}' for k in keys))
    return lines


__all__ = ['reidentify', 'Reidentification', 'format_table', 'HOOK_METHODS']
