"""
Write a diagnosis: its JSON, the augmented params YAML (``extra: {effects: [...]}``) and ``summary.txt``.

``summary.txt`` holds the verdict, the sentences, the residual numbers, the noise-floor check, the located mismatch
and the notes.  The plots of ``bearing-id diagnose --report`` are drawn by :mod:`bearing_id.plots`.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import yaml

from ..config.params import rig_to_dict as params_rig_to_dict


# ------------------------------------------------------------------------------------------------ params YAML
def rig_to_dict(rig) -> dict:
    """
    Return a RigParams as the YAML mapping that :func:`bearing_id.config.params.parse_rig` reads (SI units).

    :func:`bearing_id.config.params.rig_to_dict` (every schema-v2 key: sections, tables, pedestals, seals, angled
    probes), with ``extra`` (the diagnosis' effects) converted to plain Python numbers for YAML.
    """
    d = params_rig_to_dict(rig)
    if rig.extra:
        d['extra'] = _plain(rig.extra)
    return d


def _plain(x):
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    return x


def augmented_rig(diag, rig):
    """``rig`` with ``extra.effects`` = the selected effects (final joint fit) and the refitted bearing factors."""
    effs = []
    final = diag.selection.final
    bearings = rig.bearings
    for e, phys in zip(final.effects, final.phys):
        x = e.to_extra(phys)
        effs += [_plain(v) for v in (x if isinstance(x, list) else [x])]
        form = getattr(e, 'bearing_form', None)
        if form is not None:          # the bearing model form found: the augmented params use it
            bearings = tuple(dataclasses.replace(b, model=form[0], **({'cavitation': form[1]} if form[1] else {}))
                             for b in bearings)
    extra = dict(rig.extra or {})
    extra['effects'] = effs
    extra['diagnose_bearing_factors'] = _plain(diag.bearing_factors)
    return rig.replace(extra=extra, bearings=bearings)


def write_params(diag, rig, path) -> Path:
    """Write the augmented model as a params YAML (loads with :func:`bearing_id.config.params.load_rig`)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = ('# Augmented model written by `bearing-id diagnose`: the nominal params plus the effects found\n'
            '# (extra.effects, SI units; read by bearing_id.diagnose.effects.augmented_dynamic_stiffness).\n'
            + yaml.safe_dump(rig_to_dict(augmented_rig(diag, rig)), sort_keys=False))
    path.write_text(text)
    diag.augmented_params = str(path)
    return path


def write_json(diag, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(_plain(diag.as_json()), indent=2, default=float))
    return path


def write_summary(diag, outdir) -> Path:
    """Write ``outdir/summary.txt`` (verdict, sentences, residuals, noise floor, located mismatch, notes)."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    lines = [f'verdict: {diag.verdict}', *diag.sentences,
             f'residual RMS before: {diag.residual_before:.4g} sigma ({diag.residual_before_m * 1e6:.4g} um)',
             f'residual RMS after:  {diag.residual_after:.4g} sigma ({diag.residual_after_m * 1e6:.4g} um)',
             f'fraction explained (residual power): {diag.explained_fraction:.3f}',
             *([f"noise floor (identify's 1X vectors, no model tolerance): chi2/dof {nf['chi2_dof']:.4g}"
                + (f" -> {nf['chi2_dof_after']:.4g} with {nf['adopted']}" if nf.get('adopted') else '')
                + (' (MODEL MISFIT above ' + f"{nf['threshold']:g})" if nf['misfit'] else '')]
               if (nf := diag.noise_floor) and nf.get('chi2_dof') == nf.get('chi2_dof') else []),
             'located mismatch:'] + [f'  {m.where} {m.order}: {m.size * 1e6:.3g} um, {m.significance:.1f} sigma at '
                                     f"{', '.join(f'{s:.0f}' for s in m.speeds_rpm)} rpm" for m in diag.mismatch]
    lines += ['notes:'] + [f'  {n}' for n in diag.notes]
    f = out / 'summary.txt'
    f.write_text('\n'.join(lines) + '\n')
    return f


__all__ = ['rig_to_dict', 'augmented_rig', 'write_params', 'write_json', 'write_summary']
