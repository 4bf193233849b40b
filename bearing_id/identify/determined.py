"""
One rule for "determined" and one misfit test, shared by every identification method.

What "determined" means
    A coefficient is *determined* -- shown to a person as a plain number with its 1-sigma -- only when the data alone
    fix it.  These conditions, all required (:func:`judge`):

    1. **estimable**: it lies in the row space of the data's information matrix (no combination of coefficients the
       data cannot see leaks into it); otherwise no finite data-only sigma exists.
    2. **significant**: ``|value| >= K_SIGMA x sigma`` with ``sigma`` its data-only 1-sigma (Birge-scaled when the
       model misfits, see below).  K_SIGMA = 3: for a Gaussian estimate the data then exclude zero at 3 sigma
       (two-sided probability 0.27 % that an estimate of a coefficient that is really 0 passes), and the relative
       1-sigma sigma / |value| is at most 1/3 -- the data fix the sign and the size.  A bound relative to the
       *block* scale alone would pass e.g. Kyx = 1.0e4 +- 9.0e4 N/m: a value smaller than its own sigma.
    3. **not the prior's**: the pull of a prior (or of the theory a method starts from) on it is at most
       ``MAX_PRIOR_PULL``.  The pull is d(estimate) / d(prior mean): for a Gaussian prior it is the shrinkage
       1 - var_posterior / var_data-only (the fraction of the way from the data's estimate to the prior mean that the
       reported value moved); for the paper method it is the KF's d(identified) / d(theory), the same quantity.
       MAX_PRIOR_PULL = 0.1: the data carry at least 90 % of the weight (their information is >= 9x the prior's), so
       a theory 30 % off moves the value by <= 3 %.
    4. **no known bias beyond half a sigma**: where a method can estimate its own systematic error (the conventional
       method's straight-line interpolation on the model's noise-free response), it must be at most
       ``MAX_BIAS_SIGMA`` = 0.5 sigma: a Gaussian error shifted by 0.5 sigma still lies within 3 sigma 99.4 % of the
       time (shifted by 1 sigma: 97.7 %; by 2 sigma: 84 %).

    The sigma must describe the interval: a method whose estimator is nonlinear checks the linearised sigma against
    the profile chi-square at value +- 3 sigma and widens it where the profile rises less (the direct method).

Misfit test (:func:`fit_quality`)
    With ``dof`` = equations - estimable unknowns > 0 the weighted residual chi2 of a correct model with correct
    1-sigma is chi-square(dof) distributed.  The fit is a **misfit** when chi2 / dof exceeds the
    ``MISFIT_LEVEL`` = 99.9 % point of chi-square(dof) / dof (1.6 at 68 dof, 3.3 at 8 dof, 10.8 at 1 dof): a 1-in-1000
    false alarm.  A misfit is a warning, never an OK: every 1-sigma is multiplied by the Birge ratio sqrt(chi2 / dof)
    (the noise the residual shows), the rule above is applied to the scaled sigma, the result is flagged ``misfit``
    (``IdentResult.misfit``, ``IdentResult.flags``) and its note says the scaled sigma is still a lower bound (a model
    error is a bias, not noise).  Misfit results stay determined-but-flagged (the identifier node reports them as
    WARN), never plainly determined.

The quantile is scipy's (``scipy.special.chdtri``, the inverse of the chi-square survival function).
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy.special import chdtri

K_SIGMA = 3.0               # |value| >= K_SIGMA x sigma (data exclude zero at 3 sigma; relative 1-sigma <= 1/3)
MAX_PRIOR_PULL = 0.1        # d(estimate)/d(prior mean) <= this (the data carry >= 90 % of the weight)
MAX_BIAS_SIGMA = 0.5        # a method's own estimated bias <= this x sigma
MISFIT_LEVEL = 0.999        # chi2 above this quantile of chi-square(dof) is a model misfit


def misfit_threshold(dof: float, level: float = MISFIT_LEVEL) -> float:
    """chi2 / dof above which a fit with ``dof`` degrees of freedom is a misfit (``level`` quantile / dof)."""
    return float(chdtri(dof, 1.0 - level)) / float(dof)


@dataclass(frozen=True)
class FitQuality:
    """
    Goodness of fit of a weighted least-squares fit.

    chi2 : weighted residual sum of squares.   dof : equations - estimable unknowns (0: no test possible).
    level : quantile of the test.   threshold : chi2/dof limit (NaN when dof <= 0).   misfit : chi2/dof > threshold.
    birge : factor every 1-sigma is multiplied by (sqrt(chi2/dof) on a misfit, else 1).
    """

    chi2: float
    dof: int
    level: float
    threshold: float
    misfit: bool
    birge: float

    @property
    def chi2_dof(self) -> float:
        return self.chi2 / self.dof if self.dof > 0 else math.nan

    @property
    def testable(self) -> bool:
        return self.dof > 0

    def to_dict(self) -> dict:
        def num(v):
            return float(v) if math.isfinite(v) else None
        return {'chi2': num(self.chi2), 'dof': int(self.dof), 'chi2_dof': num(self.chi2_dof),
                'threshold_chi2_dof': num(self.threshold), 'level': float(self.level), 'misfit': bool(self.misfit),
                'sigma_scale': float(self.birge)}

    def summary(self) -> str:
        if not self.testable:
            return f'chi2 = {self.chi2:.3g} with 0 degrees of freedom (no misfit test possible)'
        return (f'chi2/dof = {self.chi2_dof:.3g} at {self.dof} dof (misfit above {self.threshold:.3g}, the '
                f'{100 * self.level:g} % point of chi-square({self.dof})/{self.dof})')

    def misfit_note(self, what: str = 'the model') -> str:
        """Return the note every printer shows for a misfit ('MODEL MISFIT: ...')."""
        return (f'MODEL MISFIT: chi2/dof = {self.chi2_dof:.3g} > {self.threshold:.3g} (the {100 * self.level:g} % '
                f'point at {self.dof} dof): {what} does not reproduce these data within their noise, so the result '
                f'carries a bias no noise-based 1-sigma covers; every 1-sigma shown is scaled by sqrt(chi2/dof) = '
                f'{self.birge:.3g} and is still a LOWER BOUND')


def fit_quality(chi2: float, dof: int, level: float = MISFIT_LEVEL) -> FitQuality:
    """Return the misfit test of the module docstring for a fit with weighted residual ``chi2`` and ``dof`` dof."""
    chi2 = float(chi2)
    dof = int(dof)
    if dof <= 0 or not math.isfinite(chi2):
        return FitQuality(chi2, max(dof, 0), level, math.nan, False, 1.0)
    thr = misfit_threshold(dof, level)
    bad = chi2 / dof > thr
    return FitQuality(chi2, dof, level, thr, bool(bad), math.sqrt(chi2 / dof) if bad else 1.0)


@dataclass
class Verdict:
    """
    Per-coefficient outcome of :func:`judge` (all arrays (n,)).

    determined : the conditions hold.   estimable, significant, data_led, unbiased : each condition.
    z : |value| / sigma (NaN where sigma is not finite).   pull : the prior's pull used (0 without a prior).
    """

    determined: np.ndarray
    estimable: np.ndarray
    significant: np.ndarray
    data_led: np.ndarray
    z: np.ndarray
    pull: np.ndarray
    unbiased: np.ndarray | None = None

    def count(self) -> int:
        return int(np.count_nonzero(self.determined))

    def note(self, labels=None) -> str | None:
        """One line naming why coefficients are not determined (None when all are)."""
        n = self.determined.size
        if self.count() == n:
            return None
        labels = list(labels) if labels is not None else [f'p{k}' for k in range(n)]
        parts = []
        ne = ~self.estimable
        if ne.any():
            parts.append(f"{int(ne.sum())} not estimable from these data (outside the data's row space)")
        ns = self.estimable & ~self.significant
        if ns.any():
            parts.append(f'{int(ns.sum())} with |value| < {K_SIGMA:g} x its 1-sigma ('
                         + ', '.join(f'{labels[k]} {self.z[k]:.2g} sigma' if math.isfinite(self.z[k])
                                     else f'{labels[k]} no sigma' for k in np.nonzero(ns)[0][:6])
                         + (' ...' if ns.sum() > 6 else '') + ')')
        npl = self.estimable & self.significant & ~self.data_led
        if npl.any():
            parts.append(f'{int(npl.sum())} pulled by the prior/theory by more than {MAX_PRIOR_PULL:g} ('
                         + ', '.join(f'{labels[k]} {self.pull[k]:.2f}' for k in np.nonzero(npl)[0][:6])
                         + (' ...' if npl.sum() > 6 else '') + ')')
        if self.unbiased is not None:
            nb = self.estimable & self.significant & self.data_led & ~self.unbiased
            if nb.any():
                parts.append(f'{int(nb.sum())} with a known method bias above {MAX_BIAS_SIGMA:g} sigma ('
                             + ', '.join(labels[k] for k in np.nonzero(nb)[0][:6]) + (' ...' if nb.sum() > 6 else '')
                             + ')')
        rest = self.estimable & self.significant & self.data_led & \
            (self.unbiased if self.unbiased is not None else True) & ~self.determined
        if np.any(rest):
            parts.append(f"{int(np.sum(rest))} vetoed by the method's own check (see the notes)")
        return (f'{n - self.count()} of {n} coefficients not determined by the data (rule: estimable, |value| >= '
                f'{K_SIGMA:g} sigma, prior pull <= {MAX_PRIOR_PULL:g}, known bias <= {MAX_BIAS_SIGMA:g} sigma): '
                + '; '.join(parts))


def judge(value, sigma, *, estimable=None, pull=None, veto=None, bias=None) -> Verdict:
    """
    Apply the rule of the module docstring to coefficients ``value`` with data-only 1-sigma ``sigma``.

    value, sigma : (n,) (sigma NaN/inf where none exists; Birge-scaled by the caller on a misfit).
    estimable : (n,) bool (default: sigma finite).   pull : (n,) prior pull d(estimate)/d(prior mean) (default 0).
    veto : (n,) bool, method-specific reasons the method itself cannot vouch for a coefficient; vetoed coefficients
        are not determined.
    bias : (n,) the method's own estimate of its systematic error |bias| (same unit as value), or None; a bias within
        1e-9 x |value| counts as none (round-off of an exact route).
    """
    v = np.asarray(value, dtype=float).ravel()
    s = np.asarray(sigma, dtype=float).ravel()
    est = np.isfinite(s) if estimable is None else (np.asarray(estimable, bool).ravel() & np.isfinite(s))
    est &= np.isfinite(v)
    with np.errstate(divide='ignore', invalid='ignore'):
        z = np.where(est, np.abs(v) / s, np.nan)
    sig = est & (np.abs(v) >= K_SIGMA * s)
    pl = np.zeros_like(v) if pull is None else np.asarray(pull, dtype=float).ravel()
    led = np.isfinite(pl) & (pl <= MAX_PRIOR_PULL)
    det = est & sig & led
    unb = None
    if bias is not None:
        b = np.abs(np.asarray(bias, dtype=float).ravel())
        unb = np.isfinite(b) & ((b <= MAX_BIAS_SIGMA * s) | (b <= 1e-9 * np.abs(v)))
        det &= unb
    if veto is not None:
        det &= ~np.asarray(veto, bool).ravel()
    return Verdict(det, est, sig, led, z, pl, unb)


def prior_pull(var_post, var_data) -> np.ndarray:
    """Shrinkage 1 - var_post / var_data per coefficient (inf where the data alone give no finite variance)."""
    vp = np.asarray(var_post, dtype=float)
    vd = np.asarray(var_data, dtype=float)
    with np.errstate(divide='ignore', invalid='ignore'):
        out = np.where(np.isfinite(vd) & (vd > 0), 1.0 - vp / vd, np.where(vd == 0, 0.0, np.inf))
    return np.clip(out, 0.0, np.inf)


__all__ = ['K_SIGMA', 'MAX_PRIOR_PULL', 'MAX_BIAS_SIGMA', 'MISFIT_LEVEL', 'misfit_threshold',
           'FitQuality', 'fit_quality', 'Verdict', 'judge', 'prior_pull']
