"""
The default method, ``auto``: the method these data can carry, chosen by the design check on the data themselves.

``direct`` (the 16 coefficients per speed, no bearing model) when the recording's probes, runs and measured noise
determine every coefficient at every speed -- the design check (:func:`bearing_id.identify.design.check_design`) at
each speed with that speed's measured noise, linearised at the theory, judged by the one rule of
:mod:`bearing_id.identify.determined`; otherwise ``physical`` (the bearings' viscosity and clearance, or a table
bearing's scales, fitted across all speeds), which unbalance runs at one probe station do determine -- unless its
model cannot describe the data (the misfit test fails): then ``direct``, if it determines any coefficient (a misfit
determines none).  Every result carries the choice and its reason (``extra['auto']`` and the first note).
"""
from __future__ import annotations

import numpy as np

from .design import check_design
from .direct import identify_direct
from .lsq import DEFAULT_MAX_REL_STD
from .physical import identify_physical
from .result import IdentResult
from ..rotor.supports import bearing_fn

CHOICES = {'direct': identify_direct, 'physical': identify_physical}


def noise_rel_per_speed(data) -> np.ndarray:
    """
    Return the 1X vectors' noise relative to their amplitude at each speed (ns,), as the design check takes it.

    Per run and speed: the mean 1-sigma of Re and Im over the channels [m] divided by the RMS amplitude of the
    channels [m]; the median over the runs.
    """
    amp = np.sqrt(np.mean(np.abs(data.X) ** 2, axis=-1))
    with np.errstate(divide='ignore', invalid='ignore'):
        rel = np.where(amp > 0, np.mean(data.X_std, axis=-1) / amp, np.nan)
    out = np.nanmedian(np.where(np.isfinite(rel), rel, np.nan), axis=0) if rel.size else np.zeros(0)
    if not out.size or not np.all(np.isfinite(out)):
        raise ValueError('auto: the 1X vectors carry no finite noise estimate at every speed to judge the design by')
    return out


def choose_method(model, rig, data, probes, runs) -> tuple[str, str]:
    """Return (method, reason): 'direct' when these data determine every coefficient at every speed, else 'physical'."""
    theory = bearing_fn(rig)
    reports = [check_design(model, probes, runs, [w], theory, noise_rel=nr, advice=False)[0]
               for w, nr in zip(data.speeds, noise_rel_per_speed(data))]
    n = reports[0].data.unknowns if reports else 0
    counts = [int(np.count_nonzero(r.rule_determined)) if r.rule_determined is not None else 0 for r in reports]
    short = [(r, c) for r, c in zip(reports, counts) if c < n]
    if reports and not short:
        return 'direct', (f'the design check on these data (each speed at its measured noise) determines all {n} '
                          f'coefficients at every speed (design-check condition up to '
                          f'{max(r.data.condition for r in reports):.3g})')
    if not reports:
        return 'physical', 'no speed to judge the design by'
    r, c = min(short, key=lambda rc: rc[1])
    return 'physical', (f'the design check on these data determines {c} of {n} coefficients at {r.speed_rpm:.0f} rpm '
                        f'(rank {r.data.structural_rank} of {r.data.unknowns}, {r.data.rank} direction(s) known to '
                        f'{100 * DEFAULT_MAX_REL_STD:g} % at this noise; {len(short)} of {len(reports)} speeds short); '
                        "physical fits the bearings' parameters across all speeds")


def identify_auto(model, rig, data, probes, runs, options=None) -> list[IdentResult]:
    """
    Choose the method (:func:`choose_method`) and run it; each result names the method that ran and why.

    ``options``: {method name: that method's options} (e.g. {'physical': {'p0': ...}}); only the chosen one is used.
    """
    opts = dict(options or {})
    unknown = set(opts) - set(CHOICES)
    if unknown:
        raise ValueError(f'auto: options are given per method ({sorted(CHOICES)}), got {sorted(unknown)}')
    method, reason = choose_method(model, rig, data, probes, runs)
    results = CHOICES[method](model, rig, data, probes, runs, opts.get(method))
    if method == 'physical' and any(r.misfit for r in results):
        # the bearing model cannot describe these data: per speed without a model, where the plan determines it
        alt = identify_direct(model, rig, data, probes, runs, opts.get('direct'))
        n_alt = sum(int(np.count_nonzero(r.K_determined) + np.count_nonzero(r.C_determined))
                    for r in alt if not r.misfit)
        if n_alt:
            fq = next((r.extra.get('fit_quality') for r in results if r.extra.get('fit_quality') is not None), None)
            method, results = 'direct', alt
            reason += ('; but the physical fit misfits these data'
                       + (f' (chi2/dof {fq.chi2_dof:.3g} > {fq.threshold:.3g})' if fq is not None else '')
                       + f', so direct ran: it determines {n_alt} coefficient(s) without a bearing model')
    for r in results:
        r.extra['auto'] = {'method': method, 'reason': reason}
        r.notes.insert(0, f'method auto chose {method}: {reason}')
    return results


__all__ = ['choose_method', 'identify_auto', 'noise_rel_per_speed', 'CHOICES']
