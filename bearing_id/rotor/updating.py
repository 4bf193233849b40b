"""
Model updating (paper section 2.2, Table 2).

Nelder-Mead on mass (and optionally stiffness) factors so that the free-free modal frequencies of the shaft with discs
match measured ones.

Parameters (multiplicative factors, searched in log space so they stay positive):
    ``disc@N``  mass (and inertias) of the disc at 1-based node N (params.Disc.mass_factor);
    ``discs``   one common factor on every disc;
    ``shaft``   shaft density (translational and rotary inertia);
    ``stiffness`` Young's modulus (and G, so the shear parameter is unchanged) — only with ``stiffness=True``.
Objective: sum over modes of (f_model / f_measured - 1)^2 (scipy.optimize.minimize, method='Nelder-Mead').

Identifiability is reported, not assumed: the Jacobian of log-frequencies with respect to log-factors at the
solution gives its singular values.  Two facts about the paper rig: (1) its discs sit symmetrically (nodes 4 and 8
of 11), so a heavy disc 4 and an equally heavy disc 8 give identical free-free frequencies: per-disc factors are
found only up to that mirror image (and near equal factors, to first order only their sum matters);
(2) a common scale on all masses and on E leaves every
frequency unchanged, so ``stiffness=True`` together with factors on all masses is exactly singular.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import math

import numpy as np
from scipy.optimize import minimize

from .assembly import RotorModel
from .modal import free_free_frequencies
from ..config.params import RigParams

TWO_PI = 2.0 * math.pi


def default_parameters(rig: RigParams) -> tuple[str, ...]:
    """Per-disc mass factors and the shaft mass factor (the paper's 'mass matrix' updating)."""
    return tuple(f'disc@{d.node}' for d in rig.discs) + ('shaft',)


def apply_factors(rig: RigParams, factors: dict) -> RigParams:
    """Return a copy of ``rig`` with the factors applied (disc mass_factor, shaft density, Young's modulus)."""
    discs = []
    for d in rig.discs:
        f = factors.get(f'disc@{d.node}', 1.0) * factors.get('discs', 1.0)
        discs.append(dataclasses.replace(d, mass_factor=d.mass_factor * f))
    sh = dataclasses.replace(rig.shaft, density=rig.shaft.density * factors.get('shaft', 1.0),
                             youngs_modulus=rig.shaft.youngs_modulus * factors.get('stiffness', 1.0))
    return rig.replace(discs=tuple(discs), shaft=sh)


def free_free_hz(rig: RigParams, n: int, factors: dict | None = None) -> np.ndarray:
    """Return the lowest ``n`` free-free bending frequencies [Hz] of ``rig`` with ``factors`` applied."""
    r = apply_factors(rig, factors or {})
    return free_free_frequencies(RotorModel.from_params(r), n) / TWO_PI


@dataclass(frozen=True)
class UpdateResult:
    """
    Outcome of :func:`update_model`.

    parameters : names.   factors : {name: factor}.   initial_hz, measured_hz, updated_hz : (n,) Hz.
    rig : the updated RigParams.   singular_values : of d log f / d log factor at the solution (descending).
    success, iterations, objective : optimiser report.
    """

    parameters: tuple
    factors: dict
    initial_hz: np.ndarray
    measured_hz: np.ndarray
    updated_hz: np.ndarray
    rig: RigParams
    singular_values: np.ndarray
    success: bool
    iterations: int
    objective: float

    @property
    def condition(self) -> float:
        """Condition number of the sensitivity matrix (inf when some factor combination is not determined)."""
        s = self.singular_values
        return float(s[0] / s[-1]) if s.size and s[-1] > 0 else math.inf

    def table(self) -> str:
        """Format the paper's Table 2 layout: order, initial model, measured, updated model [Hz] (+ errors %)."""
        lines = [f"{'Order':>5}  {'Initial model (Hz)':>18}  {'Measured (Hz)':>13}  {'Updated model (Hz)':>18}"
                 f"  {'initial err %':>13}  {'updated err %':>13}"]
        for k, (a, m, u) in enumerate(zip(self.initial_hz, self.measured_hz, self.updated_hz), 1):
            lines.append(f'{k:>5}  {a:>18.2f}  {m:>13.2f}  {u:>18.2f}  {100 * (a / m - 1):>13.2f}'
                         f'  {100 * (u / m - 1):>13.2f}')
        lines.append('factors: ' + ', '.join(f'{k} = {v:.4f}' for k, v in self.factors.items())
                     + f'; sensitivity condition = {self.condition:.3g}')
        return '\n'.join(lines)


def _sensitivity(rig, names, logx, n, h=1e-5):
    J = np.empty((n, len(names)))
    for j in range(len(names)):
        up, dn = logx.copy(), logx.copy()
        up[j] += h
        dn[j] -= h
        fu = free_free_hz(rig, n, dict(zip(names, np.exp(up))))
        fd = free_free_hz(rig, n, dict(zip(names, np.exp(dn))))
        J[:, j] = (np.log(fu) - np.log(fd)) / (2 * h)
    return J


def update_model(rig: RigParams, measured_hz, *, parameters=None, stiffness: bool = False, x0=None,
                 maxiter: int = 4000) -> UpdateResult:
    """
    Fit mass (and optionally stiffness) factors so the free-free frequencies match ``measured_hz`` [Hz].

    Parameters
    ----------
    rig
        the initial model's parameters.
    measured_hz
        measured free-free modal frequencies [Hz], lowest first (one per bending mode).
    parameters : sequence of str
        factor names (see module docstring); default per-disc and shaft mass factors.
    stiffness
        also fit a factor on Young's modulus.
    x0
        starting factors {name: value} (default all 1).
    maxiter
        iteration limit of the Nelder-Mead search (function evaluations: twice that).

    """
    meas = np.asarray(measured_hz, dtype=float)
    if meas.ndim != 1 or meas.size == 0 or np.any(meas <= 0) or np.any(np.diff(meas) <= 0):
        raise ValueError('measured_hz must be increasing positive frequencies [Hz]')
    names = tuple(parameters) if parameters is not None else default_parameters(rig)
    if stiffness and 'stiffness' not in names:
        names = names + ('stiffness',)
    valid = {f'disc@{d.node}' for d in rig.discs} | {'discs', 'shaft', 'stiffness'}
    bad = [p for p in names if p not in valid]
    if bad:
        raise ValueError(f'unknown updating parameter(s) {bad}; valid: {sorted(valid)}')
    n = meas.size
    start = np.log([float((x0 or {}).get(p, 1.0)) for p in names])

    def objective(logx):
        f = free_free_hz(rig, n, dict(zip(names, np.exp(logx))))
        return float(np.sum((f / meas - 1.0) ** 2))

    res = minimize(objective, start, method='Nelder-Mead',
                   options={'xatol': 1e-9, 'fatol': 1e-16, 'maxiter': maxiter, 'maxfev': 2 * maxiter,
                            'adaptive': len(names) > 3})
    factors = {p: float(v) for p, v in zip(names, np.exp(res.x))}
    sv = np.linalg.svd(_sensitivity(rig, names, res.x, n), compute_uv=False)
    return UpdateResult(parameters=names, factors=factors, initial_hz=free_free_hz(rig, n), measured_hz=meas,
                        updated_hz=free_free_hz(rig, n, factors), rig=apply_factors(rig, factors),
                        singular_values=sv, success=bool(res.success), iterations=int(res.nit),
                        objective=float(res.fun))


__all__ = ['update_model', 'UpdateResult', 'apply_factors', 'free_free_hz', 'default_parameters']
