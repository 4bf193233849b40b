"""
Experiment-design check: what can a probe set and an excitation plan determine, per speed, and what to add.

Data-driven information (all methods see the same measurements)
    The measured 1X vectors are X[r, c] = S_c q_r with q_r = Z(beta)^-1 F_r.  Their Jacobian with respect to the 16
    bearing coefficients beta = [K (nb x xx,xy,yx,yy); Omega C (same)] (both in N/m) is, analytically,
    dq_r/dbeta_k = -Z^-1 (dZ/dbeta_k) q_r, with dZ/dK_ij = e_i e_j^T and dZ/d(Omega C)_ij = j e_i e_j^T at 1X.
    Coefficients are scaled by a reference size per bearing and group (the Frobenius size of that bearing's K or
    Omega C block / 2), and each real measurement (Re and Im of X[r, c]) is divided by its noise std, so the singular
    values s_k of the whitened, scaled Jacobian give the 1-sigma of the parameter combination v_k as 1/s_k, relative
    to the coefficient size.

Rank rules (stated)
    * structural rank: singular values above STRUCTURAL_RTOL x s_max (what no amount of averaging can fix);
    * rank (noise-based): directions whose relative 1-sigma 1/s_k <= ``max_rel_std`` (default 0.05, i.e. the
      combination is known to 5 % of the coefficients' size).
    A coefficient is *determined* when at most NULL_FRACTION of its unit vector lies in the undetermined directions.
    ``DesignReport.rule_determined`` applies the identification methods' one rule
    (:mod:`bearing_id.identify.determined`: estimable, |value| >= 3 sigma) at the linearisation point with the
    predicted data-only sigma -- what a direct fit of these data would call determined.

The shared pieces (Jacobian, scales, :func:`analyse`, the eqs 33-37 system, probe pairs) live in :mod:`.lsq` and are
re-exported here; this module imports nothing from paper/conventional (no import circle).

Noise model
    Each real component of X[r, c] has std ``noise_rel`` x RMS over channels of |X[r, :]| (the rig's noise is a
    fraction of each channel's RMS; a harmonic fit over N samples reduces it by sqrt(N/2):
    :func:`harmonic_noise_rel`).
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .determined import judge
from .lsq import (analyse, coefficient_jacobian, coefficient_labels, coefficient_scales, coeffs_to_theta,
                  DEFAULT_MAX_REL_STD, forces_at, Identifiability, ls_system, NULL_FRACTION, probe_pairs,
                  STRUCTURAL_RTOL, whitened_jacobian)
from ..config.params import ExcitationEntry, Probe, Run
from ..conventions import rad_s_to_rpm
from ..rotor.assembly import film_dofs, harmonic_response


def harmonic_noise_rel(sample_noise: float = 0.01, n_samples: int = 20480) -> float:
    """
    Std of Re (or Im) of a fitted 1X vector relative to the amplitude, for sample noise ``sample_noise`` x RMS.

    A sinusoid of amplitude a has RMS a/sqrt(2); the least-squares cos/sin coefficients over N samples have std
    sigma sqrt(2/N); so std / a = sample_noise / sqrt(N).
    """
    return float(sample_noise) / math.sqrt(float(n_samples))


@dataclass
class DesignReport:
    """Design check at one speed.  ``methods`` maps a method name to its Identifiability (or a reason string)."""

    speed: float
    data: Identifiability
    methods: dict
    advice: list
    labels: list
    rule_determined: np.ndarray | None = None     # (8 nb,) the identification rule at the linearisation point

    @property
    def speed_rpm(self) -> float:
        return float(rad_s_to_rpm(self.speed))

    def summary(self) -> str:
        lines = [f'{self.speed_rpm:7.0f} rpm: rank {self.data.structural_rank} of {self.data.unknowns} (numerical, '
                 f'as identify reports it; {self.data.rank} direction(s) known to {100 * DEFAULT_MAX_REL_STD:g} % '
                 f'at this noise), condition {self.data.condition:.3g}']
        for m, v in self.methods.items():
            lines.append(f'    {m:12s}: ' + (v if isinstance(v, str) else
                                             f'rank {v.rank} of {v.unknowns}, condition {v.condition:.3g}'))
        if self.rule_determined is not None:
            nd = int(np.count_nonzero(self.rule_determined))
            lines.append(f'    identification rule (estimable, |value| >= 3 predicted sigma; direct fit, no prior): '
                         f'{nd} of {self.rule_determined.size} determined'
                         + ('' if nd in (0, self.rule_determined.size) else ' -- not: ' + ', '.join(
                             lab for lab, d in zip(self.labels, self.rule_determined) if not d)[:200]))
        if self.data.undetermined_combinations:
            lines.append('    undetermined combinations: ' + '; '.join(self.data.undetermined_combinations[:4])
                         + (' ...' if len(self.data.undetermined_combinations) > 4 else ''))
        for a in self.advice:
            lines.append(f'    advice: {a}')
        return '\n'.join(lines)


def _score(model, speed, coeffs, probes, forces, noise_rel, max_rel_std):
    Jw, _ = whitened_jacobian(model, speed, coeffs, probes, forces, noise_rel)
    a = analyse(Jw, max_rel_std=max_rel_std)
    s = a.singular_values[: a.unknowns]
    logdet = float(np.sum(np.log(np.maximum(s, 1e-300))))
    return a.rank, logdet, a


def advise(model, speed, coeffs, probes, runs, noise_rel, *, max_rel_std=DEFAULT_MAX_REL_STD, max_steps=4,
           force_magnitude=2.0, disc_nodes=None) -> list[str]:
    """
    Greedy advice: add the probe (node, x|y) or directional-force run (disc node, x|y) that raises the rank most.

    Ties on rank are broken by the log-determinant of the information (sum of log singular values).  Stops at full
    rank or after ``max_steps`` additions.  Returns human-readable lines.
    """
    probes, runs = list(probes), list(runs)
    disc_nodes = disc_nodes if disc_nodes is not None else sorted(model.discs)
    have = {(p.node, p.direction) for p in probes}
    out = []
    rank, logdet, a = _score(model, speed, coeffs, probes, forces_at(model, runs, speed), noise_rel,
                             max_rel_std)
    for _ in range(max_steps):
        if rank >= a.unknowns:
            break
        best = None
        cand = [('probe', Probe(f'p{n}{d}', n, d)) for n in range(1, model.n_nodes + 1) for d in ('x', 'y')
                if (n, d) not in have]
        cand += [('force', Run(f'F{n}{d}', (ExcitationEntry('force', n, force_magnitude, 0.0, d, 1.0),)))
                 for n in disc_nodes for d in ('x', 'y')
                 if not any(e.kind == 'force' and e.node == n and e.direction == d for r in runs
                            for e in r.excitation)]
        for kind, c in cand:
            pr = probes + [c] if kind == 'probe' else probes
            rn = runs + [c] if kind == 'force' else runs
            r2, ld2, a2 = _score(model, speed, coeffs, pr, forces_at(model, rn, speed), noise_rel,
                                 max_rel_std)
            key = (r2, ld2)
            if best is None or key > best[0]:
                best = (key, kind, c, a2)
        if best is None or best[0][0] <= rank and best[0][1] <= logdet:
            break
        (rank, logdet), kind, c, a = best
        if kind == 'probe':
            probes.append(c)
            have.add((c.node, c.direction))
            out.append(f'add a probe at node {c.node} direction {c.direction} -> rank {rank} of {a.unknowns}')
        else:
            runs.append(c)
            e = c.excitation[0]
            out.append(f'add a run with a {force_magnitude:g} N synchronous force in {e.direction} at node {e.node} '
                       f'-> rank {rank} of {a.unknowns}')
    return out


def check_design(model, probes, runs, speeds, bearing_fn, *, noise_rel=None, sample_noise=0.01, n_samples=20480,
                 max_rel_std=DEFAULT_MAX_REL_STD, advice=True, max_steps=4) -> list[DesignReport]:
    """
    Rank and condition per speed [rad/s] for ``probes`` (params.Probe) and ``runs`` (params.Run), with advice.

    bearing_fn : speed -> {node: (K, C)}, the coefficients to linearise at (theory, or an identified result).
    noise_rel : std of Re/Im of each 1X vector relative to the run's RMS amplitude (default
        :func:`harmonic_noise_rel` (sample_noise, n_samples)).

    Methods reported: 'direct' (the 16 coefficients from all probes and runs), 'paper' (the same data through the
    KF -- the data cannot carry more than this -- capped by the eqs 33-37 system on bearing displacements),
    'conventional' (needs two probes per bearing and direction).
    """
    noise_rel = harmonic_noise_rel(sample_noise, n_samples) if noise_rel is None else float(noise_rel)
    nodes = list(model.bearing_nodes)
    labels = coefficient_labels(nodes)
    out = []
    for w in np.atleast_1d(speeds):
        w = float(w)
        coeffs = bearing_fn(w)
        forces = forces_at(model, runs, w)
        Jw, scale = whitened_jacobian(model, w, coeffs, probes, forces, noise_rel)
        data = analyse(Jw, labels, max_rel_std=max_rel_std)
        methods = {'direct': data}
        # the eqs 33-37 system itself, on the model's bearing (film) displacements (its own algebraic rank)
        q = harmonic_response(model, w, w, np.asarray(forces, dtype=complex).T, coeffs).T
        zb = np.stack([q[:, i:i + 2] - (q[:, j:j + 2] if j is not None else 0.0)
                       for i, j in (film_dofs(model, n) for n in nodes)], axis=1)
        A, _ = ls_system(zb, np.zeros(zb.shape, dtype=complex))
        s = np.linalg.svd(A * scale[None, :], compute_uv=False)
        ls_rank = int(np.count_nonzero(s > 1e-9 * s[0])) if s.size and s[0] > 0 else 0
        methods['paper'] = (f'rank {min(ls_rank, data.rank)} of {data.unknowns} (eqs 33-37 system rank {ls_rank}; '
                            f'the KF adds no information beyond the data rank {data.rank})')
        try:
            probe_pairs(model, probes)
            methods['conventional'] = methods['paper']
        except ValueError as exc:
            methods['conventional'] = f'not applicable: {exc}'
        adv = advise(model, w, coeffs, probes, runs, noise_rel, max_rel_std=max_rel_std, max_steps=max_steps) \
            if advice and data.rank < data.unknowns else []
        value = coeffs_to_theta(coeffs, w, nodes)
        rule = judge(value, data.data_rel_std * scale, estimable=data.estimable).determined
        out.append(DesignReport(w, data, methods, adv, labels, rule))
    return out


__all__ = ['harmonic_noise_rel', 'coefficient_labels', 'coefficient_scales', 'coefficient_jacobian', 'analyse',
           'whitened_jacobian', 'Identifiability', 'DesignReport', 'advise', 'check_design', 'STRUCTURAL_RTOL',
           'NULL_FRACTION', 'DEFAULT_MAX_REL_STD']
