"""
The result every identification method returns: bearing coefficients at one speed, with what the data determine.

One :class:`IdentResult` per speed.  Arrays are indexed ``[bearing, row, col]`` with rows/cols (x, y) of
:mod:`bearing_id.conventions` (force on the shaft ``-K q - C q'``).  SI units: K [N/m], C [N s/m], speed [rad/s].

``determined`` masks say, per coefficient, whether the data fix it (True) or a prior / the theory / nothing does
(False), by the one rule of :mod:`bearing_id.identify.determined` (estimable, |value| >= 3 sigma, prior pull <= 0.1).
A coefficient with ``determined == False`` must never be shown to a person as a plain number; its std is NaN when no
uncertainty can be given, and its value (when not NaN) is the prior's or the minimum-norm solution's.

``flags`` carry what every printer must show next to the numbers: ``'misfit'`` (the model does not reproduce the data
within their noise: the chi-square test of :func:`bearing_id.identify.determined.fit_quality` failed; the 1-sigma are
Birge-scaled and still a lower bound; nothing is determined, :func:`bearing_id.identify.misfit_gate`) and
``'not_plausible'`` (a plausibility gate failed, :mod:`bearing_id.identify.plausibility`).
``extra['fit_quality']`` (a :class:`~bearing_id.identify.determined.FitQuality`) and ``extra['parameters']`` (fitted
physical parameters with their 1-sigma, method ``physical``) are serialised by :meth:`IdentResult.to_dict`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from ..conventions import COEFF_ORDER, RPM_PER_RAD_S


@dataclass
class IdentResult:
    """
    Identified bearing coefficients at one speed.

    Attributes
    ----------
    speed : rotor speed [rad/s].
    method : 'paper' | 'conventional' | 'direct' | 'physical'.
    bearings : bearing names, one per bearing (nb,).
    nodes : 1-based bearing nodes (nb,).
    K, C : (nb, 2, 2) stiffness [N/m] and damping [N s/m].
    K_std, C_std : (nb, 2, 2) 1-sigma standard deviations (NaN where the data do not determine the coefficient).
    K_determined, C_determined : (nb, 2, 2) bool, True = fixed by the data.
    rank : numerical rank of the information (or least-squares) matrix.
    unknowns : number of unknowns solved for (16 for two bearings' K and C; fewer for parametric methods).
    condition : condition number of that matrix (largest / smallest singular value; inf when rank deficient).
    residual : relative residual norm ||A x - b|| / ||b|| of the fit (dimensionless).
    notes : free-text remarks for people (what was done, warnings, how much the prior dominates).
    extra : method-specific data (e.g. the KF bearing-node estimates, the theory used) -- not serialised, except
        ``extra['fit_quality']``, ``extra['parameters']`` (see the module docstring) and ``extra['auto']`` (the
        method ``auto`` chose and why).
    flags : machine-readable warnings every printer must show: 'misfit' (see the module docstring).

    """

    speed: float
    method: str
    bearings: tuple
    nodes: tuple
    K: np.ndarray
    C: np.ndarray
    K_std: np.ndarray
    C_std: np.ndarray
    K_determined: np.ndarray
    C_determined: np.ndarray
    rank: int
    unknowns: int
    condition: float
    residual: float
    notes: list = field(default_factory=list)
    extra: dict = field(default_factory=dict, repr=False)
    flags: list = field(default_factory=list)

    @property
    def misfit(self) -> bool:
        """
        Return True when the model does not fit the data within their noise (chi-square test).

        A warning, never an OK.
        """
        return 'misfit' in self.flags

    @property
    def plainly_determined(self) -> bool:
        """Every coefficient determined AND no misfit: the only state a printer may show as a plain OK."""
        return self.fully_determined and not self.misfit

    def set_flag(self, name: str) -> None:
        if name not in self.flags:
            self.flags.append(name)

    @property
    def speed_rpm(self) -> float:
        return self.speed * RPM_PER_RAD_S

    @property
    def fully_determined(self) -> bool:
        """Return True when every coefficient is fixed by the data."""
        return bool(np.all(self.K_determined) and np.all(self.C_determined))

    def undetermined_names(self) -> list[str]:
        """Names like 'bearing1.Kxy' of the coefficients not determined by the data."""
        out = []
        for i, name in enumerate(self.bearings):
            for sym, mask in (('K', self.K_determined), ('C', self.C_determined)):
                for k, lab in enumerate(COEFF_ORDER):
                    if not mask[i].reshape(4)[k]:
                        out.append(f'{name}.{sym}{lab}')
        return out

    def coeffs(self) -> dict:
        """Return the shared shape ``{node: (K, C)}`` (2x2 arrays, SI)."""
        return {int(n): (self.K[i].copy(), self.C[i].copy()) for i, n in enumerate(self.nodes)}

    def to_dict(self) -> dict:
        """JSON-ready mapping (SI units: K N/m, C N s/m; speed in rpm and rad/s; NaN -> None)."""
        def arr(a):
            return [[_num(v) for v in row] for row in np.asarray(a, dtype=float)]

        out = {
            'speed_rpm': float(self.speed_rpm),
            'speed_rad_s': float(self.speed),
            'method': self.method,
            'rank': int(self.rank),
            'unknowns': int(self.unknowns),
            'condition': _num(self.condition),
            'residual': _num(self.residual),
            'fully_determined': self.fully_determined,
            'plainly_determined': self.plainly_determined,
            'bearings': [
                {'name': str(name), 'node': int(self.nodes[i]),
                 'K': arr(self.K[i]), 'C': arr(self.C[i]),
                 'K_std': arr(self.K_std[i]), 'C_std': arr(self.C_std[i]),
                 'determined': {'K': np.asarray(self.K_determined[i], bool).tolist(),
                                'C': np.asarray(self.C_determined[i], bool).tolist()}}
                for i, name in enumerate(self.bearings)],
            'units': {'K': 'N/m', 'C': 'N s/m', 'speed': 'rpm'},
            'flags': list(self.flags),
            'misfit': self.misfit,
            'notes': list(self.notes),
        }
        if self.extra.get('data_span') is not None:      # (first, last) stamp [s] of the data behind it (live)
            out['data_span'] = [float(t) for t in self.extra['data_span']]
        fq = self.extra.get('fit_quality')
        if fq is not None:
            out['fit_quality'] = fq.to_dict() if hasattr(fq, 'to_dict') else dict(fq)
        if self.extra.get('parameters'):
            out['parameters'] = _jsonable(self.extra['parameters'])
        if self.extra.get('auto'):                       # method auto: the method it chose and why
            out['auto'] = dict(self.extra['auto'])
        return out


def _num(v):
    v = float(v)
    return v if math.isfinite(v) else None


def _jsonable(v):
    """Nested dict/list/number/str/bool -> JSON-ready (NaN/inf -> None)."""
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return _num(v)
    if isinstance(v, np.ndarray):
        return _jsonable(v.tolist())
    return v if isinstance(v, str) or v is None else str(v)


def empty_result(speed: float, method: str, bearings, nodes) -> IdentResult:
    """Return a result with every coefficient NaN and undetermined (fill it in)."""
    nb = len(nodes)
    nan = np.full((nb, 2, 2), np.nan)
    no = np.zeros((nb, 2, 2), dtype=bool)
    return IdentResult(speed=float(speed), method=method, bearings=tuple(bearings), nodes=tuple(int(n) for n in nodes),
                       K=nan.copy(), C=nan.copy(), K_std=nan.copy(), C_std=nan.copy(), K_determined=no.copy(),
                       C_determined=no.copy(), rank=0, unknowns=8 * nb, condition=math.inf, residual=math.nan)


def eq38_error(identified, truth) -> dict:
    """
    Paper eq. 38 error [%]: mean over speeds of |(actual - estimated) / actual| x 100, per coefficient and group.

    Parameters
    ----------
    identified
        IdentResult or a list of them (one per speed).
    truth
        for each identified speed the true coefficients: a callable ``bearing_fn(speed) -> {node: (K, C)}``,
        or one ``{node: (K, C)}`` / IdentResult (single speed), or a list of those aligned with ``identified``.

    Returns
    -------
    dict with per-coefficient errors keyed like ``'node2.Kxy'`` and group errors (the mean over the coefficients of
    both bearings in the group): ``'K_direct'`` (Kxx, Kyy), ``'K_cross'`` (Kxy, Kyx), ``'C_direct'``, ``'C_cross'``,
    ``'K'``, ``'C'`` (all four entries), ``'all'``.  NaN identified values give NaN.

    """
    ids = list(identified) if isinstance(identified, (list, tuple)) else [identified]
    if callable(truth):
        truths = [truth(r.speed) for r in ids]
    elif isinstance(truth, (list, tuple)):
        truths = list(truth)
    else:
        truths = [truth]
    if len(truths) != len(ids):
        raise ValueError(f'eq38_error: {len(ids)} identified speeds but {len(truths)} truths')
    per = {}
    for r, t in zip(ids, truths):
        a = r.coeffs() if isinstance(r, IdentResult) else r
        b = t.coeffs() if isinstance(t, IdentResult) else t
        if sorted(a) != sorted(b):
            raise ValueError(f"eq38_error: identified bearings {sorted(a)} differ from the truth's {sorted(b)}")
        for n in sorted(b):
            for si, sym in enumerate(('K', 'C')):
                x, y = np.asarray(a[n][si], float), np.asarray(b[n][si], float)
                for k, lab in enumerate(COEFF_ORDER):
                    e = abs((y.reshape(4)[k] - x.reshape(4)[k]) / y.reshape(4)[k]) * 100.0
                    per.setdefault(f'node{n}.{sym}{lab}', []).append(e)
    out = {k: float(np.mean(v)) for k, v in per.items()}
    groups = {'K_direct': ('Kxx', 'Kyy'), 'K_cross': ('Kxy', 'Kyx'), 'C_direct': ('Cxx', 'Cyy'),
              'C_cross': ('Cxy', 'Cyx'), 'K': ('Kxx', 'Kxy', 'Kyx', 'Kyy'), 'C': ('Cxx', 'Cxy', 'Cyx', 'Cyy')}
    for g, labs in groups.items():
        out[g] = float(np.mean([v for k, v in out.items() if '.' in k and k.split('.')[1] in labs]))
    out['all'] = float(np.mean([v for k, v in out.items() if '.' in k]))
    return out


UNITS = {'K': 'N/m', 'C': 'N s/m'}


def _fmt(v):
    return 'nan' if not math.isfinite(v) else f'{v:.4g}'


def undetermined_label(r) -> str:
    """Return why a result's undetermined values are not the data's: 'misfit', 'not plausible' or 'prior'."""
    return 'misfit' if r.misfit else 'not plausible' if 'not_plausible' in r.flags else 'prior'


def format_results(results, allow_undetermined: bool, allow_misfit: bool = False) -> str:
    """
    Table per speed: rpm, bearing, coefficient, value, 1-sigma, unit; undetermined values hidden or flagged.

    An undetermined value is printed only when asked: flagged ``(prior)`` with ``allow_undetermined``; on a speed whose
    model misfits (every value undetermined, :func:`bearing_id.identify.misfit_gate`) flagged ``(misfit)`` with its
    Birge-scaled 1-sigma (a lower bound) with ``allow_misfit``.
    """
    lines = []
    for r in results:
        fit_det = r.extra.get('determined_if_fit') if r.misfit else None
        lines.append(f'speed {r.speed_rpm:.0f} rpm  method {r.method}  rank {r.rank} of {r.unknowns}  '
                     f'condition {_fmt(r.condition)}  residual {_fmt(r.residual)}')
        lines.append(f"  {'bearing':10s} {'coeff':5s} {'value':>12s} {'1-sigma':>12s}  unit")
        for b, name in enumerate(r.bearings):
            for sym in ('K', 'C'):
                val, std, det = getattr(r, sym), getattr(r, sym + '_std'), getattr(r, sym + '_determined')
                for k, lab in enumerate(('xx', 'xy', 'yx', 'yy')):
                    i, j = divmod(k, 2)
                    if det[b, i, j]:
                        lines.append(f'  {name:10s} {sym}{lab:4s} {_fmt(val[b, i, j]):>12s} '
                                     f'{_fmt(std[b, i, j]):>12s}  {UNITS[sym]}')
                    elif allow_misfit and fit_det is not None and fit_det['KC'.index(sym)][b, i, j]:
                        lines.append(f'  {name:10s} {sym}{lab:4s} {_fmt(val[b, i, j]):>12s} '
                                     f'{_fmt(std[b, i, j]):>12s}  {UNITS[sym]} (misfit)')
                    elif allow_undetermined:
                        lines.append(f"  {name:10s} {sym}{lab:4s} {_fmt(val[b, i, j]):>12s} {'-':>12s}  "
                                     f'{UNITS[sym]} ({undetermined_label(r)})')
                    else:
                        lines.append(f"  {name:10s} {sym}{lab:4s} {'undetermined':>12s} {'-':>12s}  {UNITS[sym]}")
        for n in r.notes:
            lines.append(f'  note: {n}')
    return '\n'.join(lines)


__all__ = ['format_results', 'IdentResult', 'empty_result', 'eq38_error', 'undetermined_label']
