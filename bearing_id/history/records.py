"""
What one identification puts into the history: :class:`IdentificationRecord` and its parts (plain data, SI units).

A record's key is a digest of its whole content (machine, times, speed, method, misfit flag, provenance, every
coefficient and parameter, floats by their exact repr), so writing the same result twice stores it once, and two
different results never share a key.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import hashlib
import json
import math
import time

import numpy as np

COEFFICIENT_NAMES = ('Kxx', 'Kxy', 'Kyx', 'Kyy', 'Cxx', 'Cxy', 'Cyx', 'Cyy')


@dataclass(frozen=True)
class Coefficient:
    """One bearing coefficient: ``name`` in COEFFICIENT_NAMES, value and 1-sigma in [N/m] (K) or [N s/m] (C)."""

    bearing: str
    name: str
    value: float
    sigma: float
    determined: bool


@dataclass(frozen=True)
class Parameter:
    """One fitted physical parameter of a bearing, e.g. clearance [m], viscosity [Pa s], k_scale [-]; SI, 1-sigma."""

    bearing: str
    name: str
    value: float
    sigma: float


@dataclass(frozen=True)
class IdentificationRecord:
    """
    One identification result of one machine.

    machine: the machine id (e.g. the node namespace, ``plant/c101``); t_start, t_end: the span of the data it used
    [s since the UNIX epoch]; speed [rad/s]; method ('direct', 'physical', ...); coefficients, parameters: tuples of
    :class:`Coefficient`, :class:`Parameter`; misfit: the model misfits the data (nothing determined); provenance: a
    JSON-able mapping (e.g. ``{'recordings': ['run_A.npz']}``); rig_name: the rig's name (stored with the machine
    when it is first seen).
    """

    machine: str
    t_start: float
    t_end: float
    speed: float
    method: str
    coefficients: tuple = ()
    parameters: tuple = ()
    misfit: bool = False
    provenance: dict = field(default_factory=dict)
    rig_name: str = ''

    def __post_init__(self):
        """Check the fields a database row needs (finite times and speed, known coefficient names)."""
        if not str(self.machine):
            raise ValueError('an identification record needs a machine id')
        for name in ('t_start', 't_end', 'speed'):
            if not math.isfinite(float(getattr(self, name))):
                raise ValueError(f'{name} must be finite, got {getattr(self, name)!r}')
        if float(self.t_end) < float(self.t_start):
            raise ValueError(f't_end ({self.t_end}) is before t_start ({self.t_start})')
        bad = [c.name for c in self.coefficients if c.name not in COEFFICIENT_NAMES]
        if bad:
            raise ValueError(f'unknown coefficient names {bad}; expected {COEFFICIENT_NAMES}')
        json.dumps(self.provenance)          # raises TypeError for what JSON cannot hold

    def key(self) -> str:
        """Return the content digest (hex SHA-256, 64 characters) that makes a second write of this record a no-op."""
        content = [self.machine, _f(self.t_start), _f(self.t_end), _f(self.speed), self.method, bool(self.misfit),
                   json.dumps(self.provenance, sort_keys=True),
                   sorted([c.bearing, c.name, _f(c.value), _f(c.sigma), bool(c.determined)] for c in self.coefficients),
                   sorted([p.bearing, p.name, _f(p.value), _f(p.sigma)] for p in self.parameters)]
        return hashlib.sha256(json.dumps(content).encode()).hexdigest()


def coefficients_from_arrays(bearing: str, K, C, K_sigma, C_sigma, determined) -> tuple[Coefficient, ...]:
    """
    Return the 8 :class:`Coefficient` of one bearing from 2x2 arrays.

    K [N/m], C [N s/m], their 1-sigma (same units), ``determined``: (2, 2) bool for K and C alike, or a pair of them.
    """
    K, C, Ks, Cs = (np.asarray(a, dtype=float).reshape(2, 2) for a in (K, C, K_sigma, C_sigma))
    det = np.asarray(determined, dtype=bool)
    dK, dC = (det[0], det[1]) if det.shape == (2, 2, 2) else (det.reshape(2, 2), det.reshape(2, 2))
    out = []
    for kind, val, sig, d in (('K', K, Ks, dK), ('C', C, Cs, dC)):
        for i, a in enumerate('xy'):
            for j, b in enumerate('xy'):
                out.append(Coefficient(bearing, f'{kind}{a}{b}', float(val[i, j]), float(sig[i, j]), bool(d[i, j])))
    return tuple(out)


def record_from_result(result: dict, machine: str, *, rig_name: str = '', provenance: dict | None = None,
                       stamp: float | None = None) -> IdentificationRecord:
    """
    Return the :class:`IdentificationRecord` of one identification result in its JSON form (``IdentResult.to_dict``).

    ``result['data_span']`` (first, last) [s, UNIX] is the data's time span when the identifier gave it, else
    (``stamp``, ``stamp``) (default: now); coefficients from ``result['bearings']`` (K, C, K_std, C_std 2x2 [SI] and
    ``determined`` {K, C}; None = NaN); parameters from ``result['parameters']`` ({'bearing1.viscosity': {'value',
    'std'}, ...} [SI]); ``misfit``, ``method`` and ``speed_rad_s`` as given.
    """
    span = result.get('data_span')
    if not span:
        t = time.time() if stamp is None else float(stamp)
        span = (t, t)
    coefs = []
    for b in result.get('bearings', []):
        det = b.get('determined') or {}
        coefs += coefficients_from_arrays(str(b['name']), _arr(b['K']), _arr(b['C']), _arr(b['K_std']),
                                          _arr(b['C_std']), [np.broadcast_to(np.asarray(det.get(k, False), bool),
                                                                             (2, 2)) for k in ('K', 'C')])
    pars = []
    for name, p in sorted((result.get('parameters') or {}).items()):
        bearing, _, what = str(name).rpartition('.')
        pars.append(Parameter(bearing, what, _num(p.get('value')), _num(p.get('std'))))
    return IdentificationRecord(machine=str(machine), t_start=float(span[0]), t_end=float(span[1]),
                                speed=float(result['speed_rad_s']), method=str(result['method']),
                                coefficients=tuple(coefs), parameters=tuple(pars), misfit=bool(result.get('misfit')),
                                provenance=dict(provenance or {}), rig_name=str(rig_name))


def _num(v) -> float:
    return math.nan if v is None else float(v)


def _arr(a) -> np.ndarray:
    """Return a 2x2 float array of a JSON matrix (None = NaN)."""
    return np.array([[_num(v) for v in row] for row in a], dtype=float)


def _f(x) -> str:
    return repr(float(x))
