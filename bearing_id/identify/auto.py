"""
The default method, ``auto``: the method these data can carry, chosen by the design check on the data themselves.

``direct`` (the 16 coefficients per speed, no bearing model) when the recording's probes, runs and measured noise
determine every coefficient at every speed -- the design check (:func:`bearing_id.identify.design.check_design`)
linearised at the theory, judged by the one rule of :mod:`bearing_id.identify.determined`; otherwise ``physical``
(the bearings' viscosity and clearance, or a table bearing's scales, fitted across all speeds), which unbalance runs at
one probe station do determine. The choice and its reason lead every result's notes.
"""
from __future__ import annotations

import numpy as np

from .design import check_design
from .direct import identify_direct
from .physical import identify_physical
from .result import IdentResult
from ..rotor.supports import bearing_fn

CHOICES = {'direct': identify_direct, 'physical': identify_physical}


def data_noise_rel(data) -> float:
    """
    Return the 1X vectors' noise relative to their amplitude, as the design check takes it (median over runs, speeds).

    Per run and speed: the mean 1-sigma of Re and Im over the channels [m] divided by the RMS amplitude of the
    channels [m].
    """
    amp = np.sqrt(np.mean(np.abs(data.X) ** 2, axis=-1))
    rel = np.mean(data.X_std, axis=-1) / np.where(amp > 0, amp, np.nan)
    rel = rel[np.isfinite(rel)]
    if not rel.size:
        raise ValueError('auto: the 1X vectors carry no finite noise estimate to judge the design by')
    return float(np.median(rel))


def choose_method(model, rig, data, probes, runs) -> tuple[str, str]:
    """Return (method, reason): 'direct' when these data determine every coefficient at every speed, else 'physical'."""
    reports = check_design(model, probes, runs, data.speeds, bearing_fn(rig), noise_rel=data_noise_rel(data),
                           advice=False)
    short = [r for r in reports if r.rule_determined is None or not np.all(r.rule_determined)]
    n = reports[0].data.unknowns if reports else 0
    if reports and not short:
        worst = max(reports, key=lambda r: r.data.condition)
        return 'direct', (f'the design check on these data determines all {n} coefficients at every speed (rank '
                          f'{worst.data.rank} of {n}, condition up to {worst.data.condition:.3g})')
    r = short[0] if short else None
    where = (f'rank {r.data.rank} of {r.data.unknowns} at {r.speed_rpm:.0f} rpm, {len(short)} of {len(reports)} '
             f'speeds short' if r is not None else 'no speed to judge')
    return 'physical', (f'the design check on these data does not determine the {n} coefficients per speed ({where}); '
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
    for r in results:
        r.notes.insert(0, f'method auto chose {method}: {reason}')
    return results


__all__ = ['choose_method', 'identify_auto', 'data_noise_rel', 'CHOICES']
