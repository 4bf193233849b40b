"""
``physical`` method: a few bearing-model parameters per bearing, fitted across all speeds at once.

Instead of 16 free coefficients per speed, each bearing's K and C at every speed come from the bearing model
(:func:`bearing_id.bearings.coefficients`, short/Ocvirk or finite Reynolds) with unknown effective viscosity mu [Pa s]
and radial clearance c [m] (and, as an option, static load W [N]).  The unknowns are p = log(mu_i), log(c_i)
(, log(W_i)) -- positive by construction, and the std of a log-parameter is the relative std of the parameter.

Fit: weighted output-error least squares of the predicted probe phasors P Z(beta(p, Omega))^-1 F_r to the measured
1X phasors of every run and speed (sigma = their 1-sigma), scipy.optimize.least_squares (trust region, bounds a factor
10 either side of the nominal).  Jacobian: d y / d p = (d y / d beta)(d beta / d p) with d y / d beta exact
(:class:`bearing_id.identify.direct.SpeedResponse`) and d beta / d p by central differences through the
bearing model (relative step 1e-4).

Uncertainty: parameter covariance (J^T J)^+ (J weighted, in log p) at the solution; rank and condition from its SVD
(:func:`bearing_id.identify.direct.information_analysis`).  The coefficients at each speed follow by the delta method,
cov_beta = G cov_p G^T with G = d beta / d p.  A coefficient is ``determined`` when its gradient G_k lies in the row
space of J (relative leakage into the null space < 1e-4), so it stays determined even when the parameters themselves
are not (e.g. with ``load=True``: in a Reynolds bearing model of fixed geometry K = (W/c) k(eps), C = W/(c Omega)
c(eps) and eps depends on mu Omega / (W c^2) only, so (mu, c, W) enter through two combinations: rank 2 per bearing).

Augmented model (``augment``): an object with ``dynamic_stiffness(speed, omega, coeffs) -> Z (ndof, ndof)`` and
``extra_forces(speed) -> {ratio: F (ndof,)}`` (e.g. :class:`bearing_id.diagnose.augmented.AugmentedModel`, built
from the augmented params file that ``bearing-id diagnose`` writes).  The prediction is then P Z_aug(beta(p))^-1
(F_r + F_extra): flexible supports in series with the film, a corrected disc, a residual unbalance or bow added to
the known excitation.  d y / d p is then taken by central differences in p (step ``FD_STEP``), the rest unchanged.

Misfit: the weighted chi2 over all speeds is tested against the 99.9 % point of chi-square(dof), dof = equations -
rank (:func:`bearing_id.identify.determined.fit_quality`; 1.6 x dof at 68 dof).  On a misfit every covariance is
multiplied by chi2/dof (Birge), every result is flagged ``misfit`` and the note says the std is a lower bound (a
model-form error is a bias, not noise).

Determined: the one rule of :mod:`bearing_id.identify.determined` -- per coefficient (delta-method sigma) and per
parameter (|value| >= 3 sigma, i.e. relative 1-sigma <= 1/3, and estimable).

Fitted parameters: every result carries ``extra['parameters']`` = {'bearing1.viscosity': {'value' [SI], 'std' [SI],
'rel_std', 'nominal', 'factor' (value / nominal), 'factor_std', 'unit', 'determined', 'bearing_model'}, ...}
(serialised by ``IdentResult.to_dict()`` as ``parameters``) and a note line with them; ``extra['fit']`` is the
:class:`PhysicalFit`.

Model form: the result is only as good as the bearing model; a short-bearing estimator on a finite bearing is
biased.  ``bearing_model='finite'`` uses the tabulated finite-length Reynolds solution
(:mod:`bearing_id.bearings.finite_table`: smooth and cheap to evaluate, Swift-Stieber or Gumbel cavitation as the
bearing says).  The 1-sigma come from the data alone; whether the table's accuracy against the direct solver
(0.9-1.5 % of each block in the usual range) matters for these data is the misfit test's to say -- a misfit
determines nothing.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np
from scipy.optimize import least_squares

from .determined import fit_quality, FitQuality, judge
from .direct import augmented_response, cases_from_data, information_analysis, SpeedResponse, Weighting
from .result import empty_result, IdentResult
from .. import bearings as bearing_models
from ..conventions import COEFF_ORDER, RPM_PER_RAD_S
from ..rotor.assembly import static_bearing_loads

FD_STEP = 1e-4               # central-difference step in log-parameter
BOUND_FACTOR = 10.0          # parameters are kept within [nominal / 10, nominal x 10]
LEAK_TOL = 1e-4              # relative leakage of a coefficient gradient into the parameter null space
UNITS = {'viscosity': 'Pa s', 'clearance': 'm', 'load': 'N'}


@dataclass
class PhysicalFit:
    """
    Fitted bearing-model parameters.

    names : ('bearing1.viscosity', ...).   values : (np,) SI [Pa s, m, N].   nominal : (np,) starting values.
    rel_std : (np,) 1-sigma of log(value) = relative std (NaN where undetermined).   cov_log : (np, np).
    determined : (np,) bool.   rank, unknowns, condition, residual (relative, all data), chi2, dof.
    bearing_model : the film model override, 'short' | 'finite' | None (each bearing's own, from the params file).
    form : what was fitted, for people ('short', 'finite/table', ...).   table_form : scales per table bearing.
    loads : {node: W [N]} used for bearings whose load is not fitted.
    quality : the misfit test (:class:`bearing_id.identify.determined.FitQuality`); on a misfit ``rel_std`` and
    ``cov_log`` are already Birge-scaled.
    """

    names: tuple
    values: np.ndarray
    nominal: np.ndarray
    rel_std: np.ndarray
    cov_log: np.ndarray
    determined: np.ndarray
    rank: int
    unknowns: int
    condition: float
    residual: float
    chi2: float
    dof: int
    bearing_model: str
    loads: dict
    notes: list = field(default_factory=list)
    quality: FitQuality | None = None
    form: str = ''
    table_form: int = 2

    @property
    def std(self) -> np.ndarray:
        """Absolute 1-sigma [SI] (first order: value x rel_std)."""
        return self.values * self.rel_std

    @property
    def misfit(self) -> bool:
        return bool(self.quality is not None and self.quality.misfit)

    def as_dict(self) -> dict:
        """
        Return the fitted parameters as a dict (SI; NaN std where not determined).

        {name: {'value', 'std', 'rel_std', 'nominal', 'factor', 'factor_std', 'unit', 'determined', 'bearing_model'}}.
        """
        out = {}
        for n, v, s, d, nom in zip(self.names, self.values, self.rel_std, self.determined, self.nominal):
            kind = n.rsplit('.', 1)[-1]
            out[n] = {'value': float(v), 'std': float(v * s), 'rel_std': float(s), 'nominal': float(nom),
                      'factor': float(v / nom), 'factor_std': float(v / nom * s), 'unit': UNITS.get(kind, ''),
                      'determined': bool(d), 'bearing_model': self.bearing_model}
        return out

    def note(self) -> str:
        """One line with the fitted parameters for people (value, 1-sigma, factor of nominal)."""
        parts = []
        for n, v, s, d, nom in zip(self.names, self.values, self.rel_std, self.determined, self.nominal):
            b, kind = n.rsplit('.', 1)
            if kind == 'viscosity':
                val = f'{v:.4g} Pa s'
            elif kind == 'clearance':
                val = f'{v * 1e6:.4g} um'
            elif kind.endswith('_scale'):   # a table bearing: scale factors on its table (TABLE_FORMS)
                val = f'{v:.4g}'
            else:
                val = f'{v:.4g} N'
            sd = f' +- {100 * s:.2g} %' if d and np.isfinite(s) else ' (not determined)'
            parts.append(f'{b} {kind} {val}{sd} (x{v / nom:.3f} nominal)')
        return (f'fitted parameters ({self.form or self.bearing_model} bearing model'
                + (', 1-sigma Birge-scaled, a lower bound' if self.misfit else '') + '): ' + '; '.join(parts))


# a table bearing's scale forms: which scale multiplies each of (Kxx, Kxy, Kyx, Kyy, Cxx, Cxy, Cyx, Cyy), simplest first
TABLE_FORMS = {
    2: (('k_scale', 'c_scale'), (0, 0, 0, 0, 1, 1, 1, 1)),
    4: (('k_direct_scale', 'k_cross_scale', 'c_direct_scale', 'c_cross_scale'), (0, 1, 1, 0, 2, 3, 3, 2)),
    8: (tuple(f'{s}{c}_scale' for s in 'kc' for c in COEFF_ORDER), tuple(range(8))),
    # one scale per coefficient at the lowest and one at the highest fitted speed, log-linear in log(speed) between
    16: (tuple(f'{s}{c}_scale_{e}' for e in ('lo', 'hi') for s in 'kc' for c in COEFF_ORDER), tuple(range(16))),
}


@dataclass
class _OneRun:
    """One run's harmonic data (speeds (ns,), X and X_std (1, ns, nch)), for its cases alone."""

    speeds: np.ndarray
    X: np.ndarray
    X_std: np.ndarray


class _Parametrisation:
    """
    log-parameters p <-> per-bearing parameters, and the coefficients they give.

    A film bearing (short/finite): the fitted ones of (viscosity, clearance, load).  A table bearing: the scale factors
    of its ``table_form`` (:data:`TABLE_FORMS`: 2 = one on K and one on C, 4 = direct and cross of each, 8 = one per
    coefficient, 16 = one per coefficient at the lowest and at the highest fitted speed with the log-scale linear in
    log(speed) between), K(speed) = scale x K_table(speed) entry by entry.
    """

    def __init__(self, model, rig, params, load, bearing_model, table_form=2, speeds=()):
        self._bm = bearing_models
        for p in params:
            if p not in ('viscosity', 'clearance'):
                raise ValueError(f"physical: params must be among ('viscosity', 'clearance'), got {p!r}")
        self.fitted = tuple(params) + (('load',) if load else ())
        if not self.fitted:
            raise ValueError('physical: nothing to fit')
        if table_form not in TABLE_FORMS:
            raise ValueError(f'physical: table_form must be one of {sorted(TABLE_FORMS)}, got {table_form!r}')
        self.rig = rig
        self.bearings = tuple(rig.bearings)
        self.nodes = tuple(b.node for b in self.bearings)
        self.table_form = table_form
        w = [float(x) for x in speeds if x > 0]
        self.span = (min(w), max(w)) if w else (1.0, 1.0)
        statics = None
        self.loads = {}
        for b in self.bearings:
            if b.model == 'table':
                self.loads[b.node] = float('nan')
            elif b.load is not None:
                self.loads[b.node] = float(b.load)
            else:
                statics = statics or static_bearing_loads(model, self.nodes)
                self.loads[b.node] = float(statics[b.node])
        self.table = tuple(b.model == 'table' for b in self.bearings)
        if table_form == 16 and any(self.table) and not self.span[1] > self.span[0]:
            raise ValueError('physical: table_form 16 (scales at the lowest and highest speed) needs two speeds')
        # the film model of each film bearing: bearing_model overrides the params file's (None: the file's own)
        self.film_model = tuple(None if t else (bearing_model or b.model) for b, t in zip(self.bearings, self.table))
        if any(self.table) and load:
            raise ValueError('physical: a table bearing has no load to fit (fit without load)')
        self.kinds = tuple(TABLE_FORMS[table_form][0] if t else self.fitted for t in self.table)
        offsets = np.cumsum([0] + [len(k) for k in self.kinds])
        self.slices = tuple(slice(int(a), int(b)) for a, b in zip(offsets[:-1], offsets[1:]))
        self.names = tuple(f'{b.name}.{k}' for b, kinds in zip(self.bearings, self.kinds) for k in kinds)
        nom = []
        for b, kinds in zip(self.bearings, self.kinds):
            base = {'viscosity': b.viscosity, 'clearance': b.clearance, 'load': self.loads[b.node]}
            nom += [base.get(k, 1.0) for k in kinds]
        self.nominal = np.asarray(nom, float)

    def models(self) -> list[str]:
        """Return each film bearing model used ('short', 'finite') once, and 'table' when a table is fitted."""
        return list(dict.fromkeys([m or 'table' for m in self.film_model]))

    def describe(self) -> str:
        """Return what is fitted, for the notes: the film bearings' parameters and the table bearings' scales."""
        parts = []
        for m in dict.fromkeys(m for m in self.film_model if m):
            who = ', '.join(b.name for b, mm in zip(self.bearings, self.film_model) if mm == m)
            parts.append(f"{', '.join(self.fitted)} of the {m} bearing model ({who})")
        tab = [b.name for b, t in zip(self.bearings, self.table) if t]
        if tab:
            what = {2: 'one scale on K and one on C', 4: 'a scale on the direct and on the cross terms of K and of C',
                    8: 'a scale per coefficient',
                    16: f'a scale per coefficient at {self.span[0] * RPM_PER_RAD_S:.0f} and at '
                        f'{self.span[1] * RPM_PER_RAD_S:.0f} rpm, log-linear in log(speed) between'}[self.table_form]
            parts.append(f"{self.table_form} scales per table ({what}) of {', '.join(tab)}")
        return '; '.join(parts)

    def bearing_values(self, p: np.ndarray, i: int) -> dict:
        b = self.bearings[i]
        v = {'viscosity': b.viscosity, 'clearance': b.clearance, 'load': self.loads[b.node]}
        v.update(zip(self.kinds[i], np.exp(p[self.slices[i]]).tolist()))
        return v

    def bearing_beta(self, p, i, speed, factor: float = 1.0) -> np.ndarray:
        """Bearing i's (K, C) entries (8,) at ``speed`` [rad/s], its viscosity times a known ``factor``."""
        if self.table[i]:
            K, C = self._bm.coefficients(self.bearings[i], speed, 0.0)
            q = p[self.slices[i]]
            if self.table_form == 16:          # log-scale linear in log(speed) between the lowest and highest speed
                t = math.log(speed / self.span[0]) / math.log(self.span[1] / self.span[0])
                scale = np.exp((1.0 - t) * q[:8] + t * q[8:])
            else:
                scale = np.exp(q)[list(TABLE_FORMS[self.table_form][1])]
            return scale * np.concatenate([np.asarray(K, float).reshape(4), np.asarray(C, float).reshape(4)])
        v = self.bearing_values(p, i)
        K, C = self._bm.coefficients(self.bearings[i], speed, v['load'],
                                     viscosity=v['viscosity'] * factor,
                                     clearance=v['clearance'], model=self.film_model[i])
        return np.concatenate([np.asarray(K, float).reshape(4), np.asarray(C, float).reshape(4)])

    def beta(self, p, speed, factor: float = 1.0) -> np.ndarray:
        return np.concatenate([self.bearing_beta(p, i, speed, factor) for i in range(len(self.bearings))])

    def beta_and_grad(self, p, speed, factor: float = 1.0):
        """Return beta (8 nb,) and d beta / d p (8 nb, np), central differences (each bearing depends on its own p)."""
        nb = len(self.bearings)
        beta = np.zeros(8 * nb)
        G = np.zeros((8 * nb, p.size))
        for i in range(nb):
            beta[8 * i:8 * i + 8] = self.bearing_beta(p, i, speed, factor)
            for j in range(self.slices[i].start, self.slices[i].stop):
                dp = np.zeros_like(p)
                dp[j] = FD_STEP
                G[8 * i:8 * i + 8, j] = (self.bearing_beta(p + dp, i, speed, factor)
                                         - self.bearing_beta(p - dp, i, speed, factor)) / (2 * FD_STEP)
        return beta, G

    def coeffs(self, p, speed, factor: float = 1.0) -> dict:
        beta = self.beta(p, speed, factor)
        return {n: (beta[8 * i:8 * i + 4].reshape(2, 2), beta[8 * i + 4:8 * i + 8].reshape(2, 2))
                for i, n in enumerate(self.nodes)}


def fit_physical(model, rig, data, *, params=('viscosity', 'clearance'), load=False, bearing_model='short',
                 probes=None, runs=None, max_nfev: int = 100, augment=None, p0=None, table_form: int = 2,
                 viscosity_factors=None):
    """
    Fit bearing-model parameters per bearing to the 1X phasors of all runs and speeds of ``data``.

    Parameters
    ----------
    model
        rotor.assembly.RotorModel (no bearings).
    rig
        params.RigParams (bearing geometry, nominal oil).
    data
        harmonic data (``speeds`` (ns,) rad/s, ``X`` complex (nr, ns, nch) [m], ``X_std`` (nr, ns, nch) [m]).
    params
        which of ('viscosity', 'clearance') to fit per bearing.
    load
        also fit the static load per bearing.
    bearing_model
        'short' (Ocvirk) or 'finite' (Reynolds) -- the estimator's model of the bearing.
    probes, runs
        override data.probes / data.runs.
    max_nfev
        evaluation limit of the least-squares fit.
    augment
        augmented-model hook (module docstring) or None (nominal model).
    p0
        starting parameter values [SI] (np,) in the order of the fitted names (e.g. the ``values`` of a previous
        :class:`PhysicalFit` on fewer speeds: a warm start), clipped into the bounds; default None = the nominal
        values.  The fit converges to the same solution to the solver's tolerance (xtol = ftol = gtol = 1e-12;
        test/test_identify_physical.py checks warm against cold).
    table_form
        a table bearing's scale form (:data:`TABLE_FORMS`: 2, 4, 8 or 16 scales per bearing).
    viscosity_factors
        a known factor on every film bearing's viscosity for each speed (ns,) or each run and speed (nr, ns) of
        ``data`` (the oil inlet temperature of those data through the oil's law, relative to a reference
        temperature); the fitted viscosity is then the one at factor 1, and the coefficients of each speed are
        given at the mean factor of its runs.  Runs at one speed with different factors are fitted each with its own
        coefficients.  Default None: one viscosity at every speed.

    Returns
    -------
    (PhysicalFit, list[IdentResult]) -- the parameters, and K, C per speed with delta-method std (method 'physical').

    """
    probes = tuple(probes if probes is not None else data.probes)
    runs = tuple(runs if runs is not None else data.runs)
    par = _Parametrisation(model, rig, params, load, bearing_model, table_form, np.asarray(data.speeds, float))
    speeds = [float(w) for w in np.asarray(data.speeds, float)]
    vf = np.ones((len(runs), len(speeds)))
    if viscosity_factors is not None:
        v = np.asarray(viscosity_factors, dtype=float)
        if v.shape not in ((len(speeds),), vf.shape) or not np.all(np.isfinite(v) & (v > 0)):
            raise ValueError(f'physical: viscosity_factors must hold positive values per speed ({len(speeds)},) or '
                             f'per run and speed {vf.shape}, got shape {v.shape}')
        vf = np.broadcast_to(v, vf.shape).copy()
    # the fitted entries: (speed index, its cases, viscosity factor) -- a speed's runs together, or each run on its
    # own where the runs at a speed saw different viscosities
    entries = []
    for i in range(len(speeds)):
        if np.ptp(vf[:, i]) == 0:
            entries.append((i, cases_from_data(model, data, probes, runs, i, augment=augment), float(vf[0, i])))
            continue
        for r, run in enumerate(runs):
            one = _OneRun(data.speeds, data.X[r:r + 1], data.X_std[r:r + 1])
            entries.append((i, cases_from_data(model, one, probes, (run,), i, augment=augment), float(vf[r, i])))
    entries = [e for e in entries if e[1]]
    if not entries:
        raise ValueError('physical: no finite synchronous measurements at any speed')
    keep = sorted({e[0] for e in entries})
    nb = len(par.nodes)
    weigh = [Weighting(c, np.ones(8 * nb)) for _, c, _ in entries]
    responses = {}                 # entry -> direct.SpeedResponse (one factorisation per entry, built lazily)

    def rj_weighted(k, beta):
        """Weighted residual and d r / d beta of entry k."""
        if k not in responses:
            responses[k] = SpeedResponse(model, speeds[entries[k][0]], entries[k][1], par.nodes, beta)
        return weigh[k](*responses[k](beta))

    def predicted(k, p):
        """Return the augmented model's prediction of entry k's phasors."""
        i, c, fk = entries[k]
        return augmented_response(model, speeds[i], c, par.coeffs(p, speeds[i], fk), augment)

    def residual_jac_aug(p, want_jac=True):
        r = np.concatenate([weigh[k].residual(predicted(k, p)) for k in range(len(entries))])
        if not want_jac:
            return r, None
        J = np.zeros((r.size, p.size))
        for j in range(p.size):
            dp = np.zeros_like(p)
            dp[j] = FD_STEP
            J[:, j] = (residual_jac_aug(p + dp, False)[0] - residual_jac_aug(p - dp, False)[0]) / (2 * FD_STEP)
        return r, J

    def residual_jac(p, want_jac=True):
        if augment is not None:
            return residual_jac_aug(p, want_jac)
        rs, Js = [], []
        for k, (i, _, fk) in enumerate(entries):
            beta, G = par.beta_and_grad(p, speeds[i], fk) if want_jac else (par.beta(p, speeds[i], fk), None)
            r, Jb = rj_weighted(k, beta)
            rs.append(r)
            if want_jac:
                Js.append(Jb @ G)
        return np.concatenate(rs), (np.vstack(Js) if want_jac else None)

    cache = {}

    def f(p):
        try:
            return residual_jac(p, want_jac=False)[0]
        except (ValueError, np.linalg.LinAlgError, FloatingPointError):
            return np.full(cache.get('m', 1), 1e10)

    def jac(p):
        return residual_jac(p)[1]

    def kept(p):
        last = cache.get('last')
        return last if last is not None and last[0] == p.tobytes() else None

    def f_keep(p):
        """Return f(p), computing (and keeping) the Jacobian too: the solver asks for it next at the same p."""
        if kept(p) is not None:
            return kept(p)[1].copy()
        try:
            r, J = residual_jac(p)
        except (ValueError, np.linalg.LinAlgError, FloatingPointError):
            return f(p)
        cache['last'] = (p.tobytes(), r, J)
        return r.copy()

    def jac_kept(p):
        return kept(p)[2].copy() if kept(p) is not None else jac(p)

    p_nom = np.log(par.nominal)
    lb, ub = p_nom - math.log(BOUND_FACTOR), p_nom + math.log(BOUND_FACTOR)
    if p0 is None:
        x0 = p_nom
    else:
        v0 = np.asarray(p0, dtype=float).reshape(-1)
        if v0.size != p_nom.size or not np.all(np.isfinite(v0) & (v0 > 0)):
            raise ValueError(f'physical: p0 must hold {p_nom.size} positive values ({", ".join(par.names)}), '
                             f'got {v0}')
        x0 = np.clip(np.log(v0), lb, ub)
    # f_keep / jac_kept: the residual and Jacobian of one p computed once (the same numbers as f and jac); not with
    # an augmented model, whose Jacobian is 2 np extra evaluations (wasted on a rejected step)
    fun, fun_jac = (f_keep, jac_kept) if augment is None else (f, jac)
    cache['m'] = fun(x0).size
    sol = least_squares(fun, x0, jac=fun_jac, bounds=(lb, ub), method='trf', x_scale=1.0, xtol=1e-12, ftol=1e-12,
                        gtol=1e-12, max_nfev=max_nfev)
    p = sol.x
    r, J = kept(p)[1:] if kept(p) is not None else residual_jac(p)
    info = information_analysis(J)
    cov = info['cov_pinv']
    pleak = info['leakage'] < LEAK_TOL
    chi2 = float(r @ r)
    dof = max(r.size - info['rank'], 1)
    fq = fit_quality(chi2, r.size - info['rank'])
    misfit = fq.misfit
    if misfit:   # Birge ratio: the noise alone does not explain the residual, so widen every 1-sigma
        cov = cov * fq.birge ** 2
    rel_std = np.where(pleak, np.sqrt(np.clip(np.diag(cov), 0, None)), np.nan)
    pdet = judge(np.exp(p), np.exp(p) * rel_std, estimable=pleak).determined
    rel_std = np.where(pdet, rel_std, np.nan)
    notes = ([f"augmented model: {', '.join(getattr(augment, 'names', []) or ['hook'])}"] if augment is not None
             else [])
    notes += [f"physical fit of {par.describe()} over {len(keep)} speed(s): rank {info['rank']} of {p.size}, "
              + fq.summary()]
    if viscosity_factors is not None:
        fs = [e[2] for e in entries]
        notes.append(f'the viscosity of each speed and run is the fitted one times a known factor (x{min(fs):.4g} '
                     f'to x{max(fs):.4g}: the oil inlet temperature of its data through the oil law); the fitted '
                     "viscosity is the one at the reference temperature, each speed's coefficients at its data's")
    if misfit:
        if all(par.table):
            hint = ("the table's speed dependence does not match the data's: `--method direct` identifies each speed "
                    'without a bearing model where the plan determines it (`bearing-id design` says so), or look for '
                    'the missing physics with `bearing-id diagnose`')
        elif 'short' not in par.film_model:
            hint = ('look for the physics the aligned, isoviscous finite-length plain-bearing model leaves out '
                    '(groove geometry, thermal viscosity change, misalignment, flexible supports, rotor model '
                    'errors) with `bearing-id diagnose`')
        else:
            hint = ('a finite-length bearing is a common cause -- refit with --bearing-model finite -- or look for '
                    'the missing physics with `bearing-id diagnose`')
        what = 'the bearing tables' if all(par.table) else f"the {'/'.join(par.models())} bearing model"
        notes.append(fq.misfit_note(f'{what} (or the rotor model around it)') + '; ' + hint)
    if np.any(p <= lb + 1e-9) or np.any(p >= ub - 1e-9):
        notes.append(f'a parameter reached its bound (x{BOUND_FACTOR:g} / {BOUND_FACTOR:g} of nominal): '
                     'the bearing model may not fit these data')
    if not sol.success:
        notes.append(f'least_squares did not converge: {sol.message}')
    if not np.all(pdet):
        notes.append('parameters not separately determined: ' + ', '.join(n for n, d in zip(par.names, pdet) if not d))
    if 'finite' in par.film_model:
        notes.append('finite bearing model (the tabulated Reynolds solution, '
                     + '/'.join(sorted({b.cavitation for b, m in zip(par.bearings, par.film_model) if m == 'finite'}))
                     + ' cavitation; within 0.9-1.5 % of the direct solver in the usual range, bearings/'
                     'finite_table.py): the 1-sigma come from the data; the misfit test says whether the table is '
                     'accurate enough for them')
    fit = PhysicalFit(names=par.names, values=np.exp(p), nominal=par.nominal, rel_std=rel_std, cov_log=cov,
                      determined=pdet, rank=info['rank'], unknowns=p.size, condition=info['condition'],
                      residual=math.nan, chi2=chi2, dof=dof, bearing_model=bearing_model, loads=dict(par.loads),
                      notes=notes, quality=fq, form='/'.join(par.models()), table_form=table_form)
    notes.append(fit.note())
    params_dict = fit.as_dict()

    # residual per speed and overall (unweighted, relative)
    results, num_all, den_all = [], 0.0, 0.0
    V0 = np.linalg.svd(J, full_matrices=True)[2].T[:, info['rank']:]
    names = tuple(b.name for b in par.bearings)
    for i in keep:
        W = speeds[i]
        mine = [k for k, e in enumerate(entries) if e[0] == i]
        beta, G = par.beta_and_grad(p, W, float(np.mean([entries[k][2] for k in mine])))
        num = den = 0.0
        for k in mine:
            y = predicted(k, p) if augment is not None else responses[k](par.beta(p, W, entries[k][2]))[0]
            num += float(np.sum(np.abs(y - weigh[k].X) ** 2))
            den += float(np.sum(np.abs(weigh[k].X) ** 2))
        num_all += num
        den_all += den
        cov_b = G @ cov @ G.T
        gnorm = np.linalg.norm(G, axis=1)
        leak = np.linalg.norm(G @ V0, axis=1) / np.where(gnorm > 0, gnorm, 1.0) if V0.size else np.zeros(8 * nb)
        est = leak < LEAK_TOL
        std = np.where(est, np.sqrt(np.clip(np.diag(cov_b), 0, None)), np.nan)
        verdict = judge(beta, std, estimable=est)
        det = verdict.determined
        std = np.where(det, std, np.nan)
        res = empty_result(W, 'physical', names, par.nodes)
        for b in range(nb):
            s = slice(8 * b, 8 * b + 4)
            t = slice(8 * b + 4, 8 * b + 8)
            res.K[b], res.C[b] = beta[s].reshape(2, 2), beta[t].reshape(2, 2)
            res.K_std[b], res.C_std[b] = std[s].reshape(2, 2), std[t].reshape(2, 2)
            res.K_determined[b], res.C_determined[b] = det[s].reshape(2, 2), det[t].reshape(2, 2)
        res.rank, res.unknowns, res.condition = info['rank'], p.size, info['condition']
        res.residual = math.sqrt(num / den) if den > 0 else math.nan
        res.notes += notes
        vn = verdict.note([f'{names[j]}.{sym}{lab}' for j in range(nb) for sym in ('K', 'C') for lab in COEFF_ORDER])
        if vn:
            res.notes.append(vn)
        res.extra.update(cov_beta=cov_b, params=dict(zip(par.names, np.exp(p))), misfit=bool(misfit),
                         parameters=params_dict, fit_quality=fq, verdict=verdict, bearing_model=bearing_model)
        if misfit:
            res.set_flag('misfit')
        results.append(res)
    fit.residual = math.sqrt(num_all / den_all) if den_all > 0 else math.nan
    for res in results:
        res.extra['fit'] = fit
    return fit, results


OPTIONS = {'params': ('viscosity', 'clearance'), 'load': False, 'bearing_model': None, 'max_nfev': 100,
           'augment': None, 'p0': None, 'table_form': 'auto', 'viscosity_factors': None}


def identify_physical(model, rig, data, probes=None, runs=None, options=None, **kw) -> list[IdentResult]:
    """
    ``physical`` identification with the common method signature (see :mod:`bearing_id.identify`).

    Options / keywords: ``params`` (default ('viscosity', 'clearance')), ``load`` (False), ``bearing_model`` (None:
    each bearing's model from the params file; 'short' or 'finite' overrides it), ``max_nfev``, ``p0`` (None: start
    at the nominal parameters; SI values: a warm start, see :func:`fit_physical`), ``table_form`` (the scales per
    table bearing, :data:`TABLE_FORMS`; 'auto' = 16, a scale per coefficient at the lowest and at the highest speed,
    log-linear in between -- with one speed 8), ``viscosity_factors`` (None; see :func:`fit_physical`).  'auto'
    takes the most flexible form on purpose: a simpler one (2 or 4 scales, even 8) can pass the misfit test on weak
    data and still be biased by its assumed shape, so its coefficients would look determined and be wrong; the
    flexible form leaves undetermined what the data do not fix.
    A model form that misfits is never the answer: when the params file's film model (no ``bearing_model`` given)
    misfits, the other film model is fitted and used if it fits, its note naming it and the option that selects it.
    Returns the per-speed IdentResult list; the fitted parameters are in each result's ``extra['fit']`` (a
    :class:`PhysicalFit`) -- or call :func:`fit_physical` for ``(fit, results)``.
    """
    opts = dict(OPTIONS)
    for k, v in {**(options or {}), **kw}.items():
        if k not in OPTIONS:
            raise ValueError(f'physical: unknown option {k!r} (known: {sorted(OPTIONS)})')
        opts[k] = v
    form = opts['table_form']
    if not any(b.model == 'table' for b in rig.bearings):
        form = 2                    # no table: the form is not used
    elif form == 'auto':            # the most flexible form the speeds allow: values from the data, not a shape
        form = 16 if len({round(float(w), 9) for w in np.asarray(data.speeds, float)}) > 1 else 8

    def fit(bearing_model):
        return fit_physical(model, rig, data, params=tuple(opts['params']), load=bool(opts['load']),
                            bearing_model=bearing_model, probes=probes, runs=runs, max_nfev=int(opts['max_nfev']),
                            augment=opts['augment'], p0=opts['p0'], table_form=int(form),
                            viscosity_factors=opts['viscosity_factors'])

    first, results = fit(opts['bearing_model'])
    films = {b.model for b in rig.bearings if b.model != 'table'}
    if first.misfit and opts['bearing_model'] is None and opts['augment'] is None and len(films) == 1:
        # the params file's film model misfits: the other one is tried, and used when it fits (named, with the
        # command that selects it); a misfit of both determines nothing
        own = films.pop()
        alt = next(m for m in bearing_models.MODELS if m != own)
        try:
            second, alt_results = fit(alt)
        except (RuntimeError, ValueError, np.linalg.LinAlgError) as exc:    # e.g. no film equilibrium there
            for r in results:
                r.notes.append(f'the {alt} bearing model could not be fitted to these data either ({exc})')
            return results
        if not second.misfit:
            note = (f"the params file's {own} bearing model misfits these data (chi2/dof {first.quality.chi2_dof:.3g} "
                    f'> {first.quality.threshold:.3g}); the {alt} bearing model fits them (chi2/dof '
                    f'{second.quality.chi2_dof:.3g}) and is used: `bearing-id identify ... --method physical '
                    f'--bearing-model {alt}` (or set kind: {alt} for the bearings in the params file)')
            for r in alt_results:
                r.notes.insert(0, note)
                r.extra['model_form'] = {'params': own, 'used': alt}
            return alt_results
        for r in results:
            r.notes.append(f'the {alt} bearing model misfits too (chi2/dof {second.quality.chi2_dof:.3g})')
    return results


__all__ = ['PhysicalFit', 'fit_physical', 'identify_physical']
