"""
Bearing mismatch: the bearings differ from the model's, and nothing else is needed to explain the 1X vectors.

Why
    Every hypothesis in the diagnosis refits the bearings only through a few factors (viscosity and clearance, or a
    table bearing's K and C scales).  When a machine's real bearings differ from its model coefficient by coefficient
    (a table bearing's rows x0.74 .. x1.37 each), those factors cannot follow; the mismatch is left at the noise
    floor and the greedy selection hangs it on whatever effect fits best at the model tolerance (a probe turned by
    2 degrees, a runout of 0.01 um, a residual unbalance), each "validated", while the model still misfits.

What
    When the diagnosis' model misfits identify's 1X vectors at the noise floor, the bearings ``bearing-id identify``
    gives with its default method on the same vectors (:func:`bearing_id.identify.identify`, ``auto``: ``direct``,
    every coefficient at every speed, where the data determine them; else ``physical``, e.g. a scale per table
    coefficient at the ends of the speed range) are put in place of the model's bearings (:class:`IdentifiedBearings`)
    and judged there like every hypothesis: their chi2 and a BIC whose parameter count is identify's (16 per speed for
    two bearings under ``direct``; the global count under ``physical``).  The bearing mismatch is the answer when
    identify flags no misfit and that BIC is lower than the diagnosis' own model's: the effects that act only on 1X
    are then not named (the bearings explain what they fitted); effects with a signature elsewhere (2X, 3X, DC,
    sub-synchronous) stay.  A pedestal or a disc error that fits at the noise floor with a handful of parameters
    keeps its lower BIC and its name; a physical fit with no more freedom than the diagnosis' bearing nuisance
    cannot win over it.

Identify and diagnose then agree on the same recording: the coefficients are identify's, with its 1-sigma and its
determined flags.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .effect import determined, Effect
from .floor import chi2_dof, misfit_threshold
from .selection import fit
from ..conventions import COEFF_ORDER
from ..identify import identify
from ..rotor.supports import bearing_fn


class IdentifiedBearings(Effect):
    """
    The identified bearings' K + j w C [N/m] (2, 2) at each identified speed in place of the model's.

    results : identify's :class:`bearing_id.identify.result.IdentResult` per speed (their bearing nodes, 1-based).
    No free parameter: the coefficients are fixed (identify fitted them on the same vectors); a speed more than 0.5 %
    from every identified one keeps the model's bearings.
    """

    name = 'bearing_mismatch'
    key = ''

    def __init__(self, results, ratios=None):
        super().__init__()
        self.results = list(results)
        self.ratios = ratios or {}
        self.speeds = np.array([r.speed for r in self.results])
        self.method = self.results[0].method if self.results else ''
        self.where = 'the bearings (' + ', '.join(self.results[0].bearings) + ')' if self.results else 'the bearings'

    def _at(self, speed):
        if not self.results:
            return None
        i = int(np.argmin(np.abs(self.speeds - speed)))
        return self.results[i] if abs(self.speeds[i] - speed) <= 0.005 * abs(speed) else None

    def bearing_impedance(self, prob, node, Zb, speed, omega, nl):
        r = self._at(speed)
        if r is None or node not in r.nodes:
            return Zb
        i = list(r.nodes).index(node)
        return np.asarray(r.K[i], float) + 1j * omega * np.asarray(r.C[i], float)

    def physical(self, nl, lin):
        return {}

    def to_extra(self, phys: dict) -> dict:
        """Return the identified coefficients per bearing and speed (SI), for the augmented params (not read back)."""
        out = {'effect': self.name, 'method': self.method, 'speeds_rpm': [float(r.speed_rpm) for r in self.results],
               'bearings': {}}
        for r in self.results:
            for i, name in enumerate(r.bearings):
                d = out['bearings'].setdefault(name, {'node': int(r.nodes[i])})
                for sym in ('k', 'c'):
                    vals = np.asarray(getattr(r, sym.upper())[i], float).reshape(4)
                    for lab, v in zip(COEFF_ORDER, vals):
                        d.setdefault(f'{sym}{lab}', []).append(float(v))
        return out

    def undetermined(self, phys, std):
        return []

    def sentence(self, phys, std):
        parts = []
        for name, rat in self.ratios.items():
            terms = []
            for k, v in rat.items():
                v = np.asarray(v, float)
                if np.any(np.isfinite(v)):
                    lo, hi = f'{np.nanmin(v):.2f}', f'{np.nanmax(v):.2f}'
                    terms.append(f'{k} x{lo}' + (f'..{hi}' if hi != lo else ''))
            parts.append(f"{name}: {', '.join(terms) if terms else 'none'}")
        return (f'bearing mismatch: the bearings differ from the model coefficient by coefficient, identified speed by '
                f'speed by `bearing-id identify` ({self.method}; identified / model over the speeds, for the '
                f"coefficients determined within 7.5 %: {'; '.join(parts)})")


@dataclass
class BearingCheck:
    """
    Result of :func:`bearing_mismatch`.

    method : the method identify chose ('direct' or 'physical').   misfit : identify flags a misfit at some speed.
    chi2_dof / bic : the identified bearings on the noise-floor vectors; limit : identify's chi2/dof limit at their
    degrees of freedom.   bic_model : the diagnosis' model there.
    wins : the bearing mismatch is the answer.   effect : the :class:`IdentifiedBearings` (its ``ratios``: per
    bearing name, the identified / model coefficient per speed, None where not determined within 7.5 %).
    note : why the check did not apply, if it did not.
    """

    method: str = ''
    misfit: bool = True
    chi2_dof: float = float('nan')
    limit: float = float('nan')
    bic: float = float('nan')
    bic_model: float = float('nan')
    chi2_dof_model: float = float('nan')
    wins: bool = False
    effect: IdentifiedBearings | None = None
    results: list | None = None
    note: str = ''

    def as_dict(self) -> dict:
        return {'method': self.method, 'misfit': self.misfit, 'chi2_dof': self.chi2_dof, 'limit': self.limit,
                'bic': self.bic, 'bic_model': self.bic_model, 'chi2_dof_model': self.chi2_dof_model, 'wins': self.wins,
                'ratios': None if self.effect is None else self.effect.ratios, 'note': self.note}

    def sentence(self) -> str:
        """Return the noise-floor line of a bearing-mismatch verdict."""
        return (f"the identified bearings reproduce identify's 1X vectors at the noise floor (chi2/dof "
                f'{self.chi2_dof:.3g}, limit {self.limit:.3g}; identify flags no misfit at any speed), with no other '
                f'1X effect (BIC {self.bic:.4g} against {self.bic_model:.4g} for the best model with effects, '
                f'{self.chi2_dof_model:.3g} chi2/dof): `bearing-id identify` gives the coefficients with their '
                f'1-sigma')


def _ratios(results, rig) -> dict:
    """
    Return per bearing name the identified / model coefficient per speed ('Kxx' .. 'Cyy' -> list).

    None where identify does not determine the coefficient or its 1-sigma exceeds 7.5 % of it
    (:func:`effect.determined`: a small cross term can be determined against the bearing's scale and still be a
    loose number on its own).
    """
    theory = bearing_fn(rig)
    out = {}
    for r in results:
        t = theory(r.speed)
        for i, (name, node) in enumerate(zip(r.bearings, r.nodes)):
            d = out.setdefault(name, {})
            for sym, k in (('K', 0), ('C', 1)):
                val, std, det, nom = (np.asarray(x).reshape(4) for x in (
                    getattr(r, sym)[i], getattr(r, sym + '_std')[i], getattr(r, sym + '_determined')[i], t[node][k]))
                for j, lab in enumerate(COEFF_ORDER):
                    ok = bool(det[j]) and nom[j] != 0.0 and determined(float(val[j]), float(std[j]))
                    d.setdefault(f'{sym}{lab}', []).append(float(val[j]) / float(nom[j]) if ok else None)
    return out


def bearing_mismatch(fprob, rig, model, effects, threshold: float, results=None, model_fit=None) -> BearingCheck:
    """
    Judge the bearing mismatch against the diagnosis' model ``effects`` on the noise-floor problem ``fprob``.

    ``fprob`` : :func:`floor.floor_problem` (its ``obs.harmonic_data``: identify's vectors).   ``model`` : the
    RotorModel of ``rig`` (nominal).   ``threshold`` : identify's chi2/dof limit on these vectors.   ``results`` :
    identify's results on these vectors when already computed (an earlier check's ``results``).   ``model_fit`` :
    ``fit(fprob, effects, uncertainty=False)`` when already made.
    """
    data = getattr(fprob.obs, 'harmonic_data', None)
    if data is None:
        return BearingCheck(note='the runs have different speeds: no joint 1X vectors for identify')
    try:
        res = identify('auto', model, rig, data) if results is None else list(results)
    except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:
        return BearingCheck(note=f'identify failed: {exc}')
    out = BearingCheck(method=res[0].method if res else '', misfit=any(r.misfit for r in res), results=res)
    if out.misfit:
        out.note = 'the bearings identified speed by speed misfit too: not a bearing mismatch alone'
        return out
    forms = {(r.extra.get('model_form') or {}).get('used') for r in res} - {None}
    if forms:
        out.note = (f"identify fits the bearings with another model form ({', '.join(sorted(forms))}): the bearing "
                    'model form candidate judges that')
        return out
    eff = IdentifiedBearings(res, _ratios(res, rig))
    fb = fit(fprob, [eff], free_nuisance=False, uncertainty=False)
    # parameters: per speed for direct; fitted across all speeds (the same count on every result) for physical
    k = sum(int(r.unknowns) for r in res) if out.method == 'direct' else int(res[0].unknowns)
    dof = fb.n - k
    out.chi2_dof = float(fb.chi2 / max(dof, 1))
    out.bic = float(fb.chi2 + k * np.log(max(fb.n, 1)))
    fm = fit(fprob, list(effects), uncertainty=False) if model_fit is None else model_fit
    out.bic_model, out.chi2_dof_model = float(fm.bic), chi2_dof(fm)
    if dof < 1:
        out.note = (f'identify fits {k} parameters to {fb.n} numbers: no degree of freedom is left to test the '
                    'bearings with (more speeds or runs)')
        return out
    # the data must test the bearings: identify's misfit limit at their own degrees of freedom
    out.limit = misfit_threshold(dof)
    out.wins = bool(out.chi2_dof <= out.limit and out.bic < out.bic_model and out.chi2_dof_model > threshold)
    if not out.wins:
        out.note = (f'identified ({out.method}) they give chi2/dof {out.chi2_dof:.3g} at the noise floor (limit '
                    f'{out.limit:.3g}), BIC {out.bic:.4g} against {out.bic_model:.4g} for the model '
                    'with effects')
    out.effect = eff
    return out


__all__ = ['bearing_mismatch', 'BearingCheck', 'IdentifiedBearings']
