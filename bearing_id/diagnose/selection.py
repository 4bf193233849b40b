"""
Fit hypotheses (nominal + candidate effects), compare them, validate on held-out speeds, select greedily.

Fit (:func:`fit`)
    Residual vector = measured minus predicted harmonic vectors divided by their effective sigma (noise floor and
    model tolerance, :func:`locate.sigma`), real and imaginary parts stacked, plus the sub-synchronous vectors, plus
    the Gaussian prior of the bearing nuisance factors.  Linear effect parameters are profiled out by weighted least
    squares inside the residual (variable projection); nonlinear ones (and the nuisance) go to
    ``scipy.optimize.least_squares`` (trf, bounds, several starts).  Parameter covariance = (J^T J)^-1 of the full
    residual (linear parameters explicit) scaled by max(1, chi2 / dof).

Compare
    BIC = chi2 + k ln n (n real data residuals, k fitted parameters, nuisance included); an effect is worth adding
    when it lowers the BIC by more than ``dbic_min``.

Held-out validation (:func:`validate`)
    The recorded speeds are split into two interleaved halves (or the runs, ``run_folds``); the hypothesis and its
    base are fitted on one half and predict the other, both ways.  Nothing is re-fitted on the held-out half: the
    bearing nuisance, every effect parameter and, for an oil whirl, the force, onset and ratio come from the
    training half (the held-out windows' sub-synchronous vectors are taken at the training ratio; their unknown
    whirl phase is not fitted either: the comparison there is phase-free, on amplitudes).  The effect is
    *validated* when it lowers the held-out chi2 and the held-out reduction fraction is at least half of the
    in-sample one: a model that only fits what it was tuned on fails.

Selection (:func:`select`)
    Greedy forward selection: start from "none" (nuisance only); at each step fit every remaining candidate added to
    the current set (everything re-fitted jointly; any effect may repeat at another location -- another bearing,
    plane, probe, disc or coupling end -- unless the two cannot be held together, :func:`conflicts`), take the best
    BIC that is also validated, stop when the BIC gain
    falls below ``dbic_min``, validation fails, or the current residual is no longer significant: chi2 per residual
    below ``chi2_floor`` (with the model tolerance in sigma a clean recording sits near 1 or below) *and* no single
    entry off by ``peak_sigma`` or more (the threshold of :func:`bearing_id.diagnose.locate.locate_mismatch`).  The
    second condition keeps a mismatch that is highly significant but confined to a few entries (a weak whirl at the
    top speeds, a runout seen on one probe of many) from being averaged away by the many entries the model already
    fits.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import itertools
import math

import numpy as np
from scipy.optimize import least_squares

from .effects import OilWhirl
from .predict import Problem
from ..conventions import rpm_to_rad_s

AMBIGUOUS_DBIC = 6.0  # screening BIC difference below which two variants of one effect are not told apart
# |ln factor| <= ln 3 (x0.33 .. x3) for viscosity and clearance factors: a nuisance, not a free parameter that can
# absorb a missing effect (the prior sigma is 0.3)
NUIS_BOUND = math.log(3.0)


@dataclass
class Fit:
    """Result of fitting one hypothesis (list of effects) on a set of windows."""

    effects: list
    theta: np.ndarray
    nls: list
    lin: np.ndarray
    chi2: float                 # data part (no prior)
    chi2_total: float           # with the nuisance prior
    n: int                      # real data residuals
    k: int                      # fitted parameters
    windows: list
    sub_pred: dict = field(default_factory=dict)
    sub_info: dict = field(default_factory=dict)
    phys: list = field(default_factory=list)     # per effect: dict of physical parameters
    std: list = field(default_factory=list)      # per effect: dict of their 1-sigma

    @property
    def bic(self) -> float:
        return self.chi2_total + self.k * np.log(max(self.n, 1))

    @property
    def rms(self) -> float:
        """RMS normalised residual (units of sigma)."""
        return float(np.sqrt(self.chi2 / max(self.n, 1)))

    @property
    def names(self) -> list:
        return [e.name for e in self.effects]


def _split(prob: Problem, effects, z):
    th = z[:prob.n_nuis]
    nls, i = [], prob.n_nuis
    for e in effects:
        m = len(e.nl_names)
        nls.append(np.asarray(z[i:i + m]))
        i += m
    return th, nls


def _sub_windows(prob, windows):
    return [k for k in windows if prob.windows[k].X_sub is not None] if prob.has_sub else []


def _sub_residual(prob, effects, th, nls, windows):
    ws = _sub_windows(prob, windows)
    if not ws:
        return np.zeros(0), {}, {}, 0
    whirl = [e for e in effects if isinstance(e, OilWhirl)]
    pred, info, kk = {}, {}, 0
    if whirl:
        pred, info, kk = whirl[0].sub_fit(prob, th, effects, nls, ws)
    r = []
    for k in ws:
        w = prob.windows[k]
        d = (w.X_sub - pred.get(k, 0.0)) / np.maximum(w.std_sub, 1e-15)
        r += [d.real, d.imag]
    return np.concatenate(r), pred, info, kk


def _residual(prob, effects, z, windows, lin=None):
    """(residual vector, lin, extra) for parameters z; ``lin`` None = profiled."""
    th, nls = _split(prob, effects, z)
    y0, A, idx = prob.predict(th, effects, nls, windows)
    s = prob.sig[idx]
    r0 = (prob.y[idx] - y0) / s
    b = np.concatenate([r0.real, r0.imag])
    if A.shape[1]:
        Aw = A / s[:, None]
        Mr = np.vstack([Aw.real, Aw.imag])
        if lin is None:
            lin = np.linalg.lstsq(Mr, b, rcond=None)[0]
        b = b - Mr @ lin
    else:
        lin = np.zeros(0)
    rs, pred, info, kk = _sub_residual(prob, effects, th, nls, windows)
    return np.concatenate([b, rs, prob.prior_residual(th)]), lin, (pred, info, kk, b.size + rs.size, y0, A, idx)


def fit(prob: Problem, effects: list, *, windows=None, theta0=None, max_nfev: int = 60,
        free_nuisance: bool = True, uncertainty: bool = True, nl0=None, hold_nl=None) -> Fit:
    """
    Fit nuisance + effect parameters of the hypothesis ``effects`` on ``windows`` (default all).

    ``free_nuisance=False`` keeps the bearing nuisance at ``theta0`` (fast screening: linear effects then need no
    iteration at all).  ``nl0`` : per effect, nonlinear parameters to start from as well (e.g. another fit's).
    ``hold_nl`` : per effect, nonlinear parameters to keep fixed (None: fitted) -- screening a new candidate beside
    effects already selected keeps theirs (their linear parameters are refitted).
    """
    windows = list(range(len(prob.windows))) if windows is None else list(windows)
    th0 = np.zeros(prob.n_nuis) if theta0 is None else np.asarray(theta0, float)[:prob.n_nuis]
    nn = prob.n_nuis if free_nuisance else 0
    held = list(hold_nl) if hold_nl is not None else [None] * len(effects)
    free_e = [e for e, h in zip(effects, held) if h is None]
    lo = [-NUIS_BOUND] * nn + [v for e in free_e for v in e.nl_lo]
    hi = [NUIS_BOUND] * nn + [v for e in free_e for v in e.nl_hi]
    head = th0[:nn]
    fixed = th0 if not free_nuisance else np.zeros(0)
    starts = [np.concatenate([head, *combo]) for combo in itertools.product(*[e.starts for e in free_e])] \
        if free_e else [head]
    if nl0 is not None and free_e:
        starts.insert(0, np.concatenate([head, *[np.asarray(v, float) for v, h in zip(nl0, held) if h is None]]))

    def full(z):
        out, i = [fixed, z[:nn]], nn
        for e, h in zip(effects, held):
            m = len(e.nl_names)
            if h is None:
                out.append(z[i:i + m])
                i += m
            else:
                out.append(np.asarray(h, float).reshape(m))
        return np.concatenate(out)

    best = None
    nz = len(lo)
    for z0 in starts:
        if nz:
            z0 = np.clip(z0, lo, hi)
            res = least_squares(lambda z: _residual(prob, effects, full(z), windows)[0], z0, bounds=(lo, hi),
                                x_scale='jac', max_nfev=max_nfev, method='trf')
            z, cost = res.x, 2 * res.cost
        else:
            z = z0
            cost = float(np.sum(_residual(prob, effects, full(z), windows)[0] ** 2))
        if best is None or cost < best[1]:
            best = (z, cost)
    f = evaluate(prob, effects, full(best[0]), windows)
    if uncertainty:
        _uncertainty(prob, f, full(best[0]))
    return f


def evaluate(prob: Problem, effects: list, z, windows=None, lin=None) -> Fit:
    """
    Return the Fit of ``effects`` at given parameters, without optimising (no 1-sigma).

    ``z`` = [nuisance, nonlinear per effect], linear ``lin`` (profiled when None), on ``windows`` (default all).
    """
    windows = list(range(len(prob.windows))) if windows is None else list(windows)
    z = np.asarray(z, float)
    r, lin, (pred, info, kk, ndata, *_) = _residual(prob, effects, z, windows,
                                                    lin=None if lin is None or not len(lin) else lin)
    th, nls = _split(prob, effects, z)
    chi2 = float(np.sum(r[:ndata] ** 2))
    k = prob.n_nuis + sum(len(e.nl_names) + getattr(e, 'k_extra', 0) for e in effects) + lin.size + kk
    return Fit(effects=list(effects), theta=th, nls=nls, lin=lin, chi2=chi2, chi2_total=float(np.sum(r ** 2)),
               n=int(ndata), k=int(k), windows=windows, sub_pred=pred, sub_info=info)


NULL_RCOND = 1e-9     # singular values of the column-scaled Jacobian below this x the largest: not determined


def covariance(J: np.ndarray) -> np.ndarray:
    """
    Return (J^T J)^-1 of a residual Jacobian, robust to parameter scales and null directions.

    Computed on the column-scaled J (parameters of very different scales -- a runout in metres next to a log
    stiffness -- must not lose their variance to a pseudo-inverse cut-off).  A parameter with a component along a
    null direction of J gets an infinite variance (NaN covariances): the data do not determine it, and every quantity
    derived from it inherits that.
    """
    n = J.shape[1]
    if n == 0:
        return np.zeros((0, 0))
    d = np.linalg.norm(J, axis=0)
    d = np.where(d > 0, d, 1.0)
    try:
        _, sv, Vt = np.linalg.svd(J / d, full_matrices=False)
    except np.linalg.LinAlgError:
        return np.full((n, n), np.nan)
    keep = sv > NULL_RCOND * (sv[0] if sv.size else 1.0)
    V = Vt[keep].T
    cov = (V / sv[keep] ** 2) @ V.T / np.outer(d, d)
    if not keep.all() or sv.size < n:
        null = Vt[~keep] if sv.size == n else np.vstack([Vt[~keep], np.linalg.svd(J / d)[2][sv.size:]])
        bad = np.linalg.norm(null, axis=0) > 1e-6
        cov[bad, :] = np.nan
        cov[:, bad] = np.nan
        cov[bad, bad] = np.inf
    return cov


def _uncertainty(prob: Problem, f: Fit, z):
    """Physical parameters of each effect and their 1-sigma from the full-residual Jacobian (delta method)."""
    nz, nl_ = z.size, f.lin.size
    r0, _, extra = _residual(prob, f.effects, z, f.windows, lin=f.lin)
    J = np.zeros((r0.size, nz + nl_))
    for i in range(nz):
        h = 1e-6 * max(1.0, abs(z[i]))
        zp = z.copy()
        zp[i] += h
        J[:, i] = (_residual(prob, f.effects, zp, f.windows, lin=f.lin)[0] - r0) / h
    if nl_:
        _, _, _, ndata, _, A, idx = extra
        s = prob.sig[idx]
        Aw = A / s[:, None]
        Mr = np.vstack([Aw.real, Aw.imag])
        J[:Mr.shape[0], nz:] = -Mr
    dof = max(f.n - f.k, 1)
    scale = max(1.0, f.chi2 / dof)
    cov = covariance(J) * scale
    i_nl, i_lin = prob.n_nuis, nz
    for e, nl in zip(f.effects, f.nls):
        m, q = len(e.nl_names), e.n_lin
        lin = f.lin[i_lin - nz:i_lin - nz + q]
        if isinstance(e, OilWhirl):
            f.phys.append(dict(f.sub_info))
            f.std.append({})
            i_nl += m
            i_lin += q
            continue
        phys = e.physical(nl, lin)
        extra_val, extra_std = {}, {}
        if hasattr(e, 'nuisance_physical'):
            extra_val, extra_std = e.nuisance_physical(prob, f.theta, cov[:prob.n_nuis, :prob.n_nuis])
        keys = list(phys)
        idx = list(range(i_nl, i_nl + m)) + list(range(i_lin, i_lin + q))
        G = np.zeros((len(keys), len(idx)))
        for j, ii in enumerate(idx):
            h = 1e-6 * max(1.0, abs((list(nl) + list(lin))[j]))
            nl2, lin2 = np.array(nl, float), np.array(lin, float)
            if j < m:
                nl2[j] += h
            else:
                lin2[j - m] += h
            p2 = e.physical(nl2, lin2)
            G[:, j] = [(p2[kk] - phys[kk]) / h for kk in keys]
        C = cov[np.ix_(idx, idx)] if idx else np.zeros((0, 0))
        sd = np.zeros(len(keys))
        for j in range(len(keys) if idx else 0):
            on = G[j] != 0
            Cj = C[np.ix_(on, on)]
            sd[j] = math.inf if not np.all(np.isfinite(Cj)) else math.sqrt(max(float(G[j, on] @ Cj @ G[j, on]), 0.0))
        f.phys.append({**phys, **extra_val})
        f.std.append({**{kk: float(v) for kk, v in zip(keys, sd)}, **extra_std})
        i_nl += m
        i_lin += q


# ------------------------------------------------------------------------------------------------ validation
def run_folds(prob: Problem) -> tuple[list, list]:
    """Windows of even-numbered recordings vs odd-numbered ones (hold out whole runs)."""
    return ([k for k, w in enumerate(prob.windows) if w.rec % 2 == 0],
            [k for k, w in enumerate(prob.windows) if w.rec % 2 == 1])


def speed_folds(prob: Problem) -> tuple[list, list]:
    """Two interleaved halves of the windows by recorded speed (sorted distinct speeds alternate)."""
    speeds = sorted({round(w.speed, 3) for w in prob.windows})
    a = {s for i, s in enumerate(speeds) if i % 2 == 0}
    A = [k for k, w in enumerate(prob.windows) if round(w.speed, 3) in a]
    B = [k for k, w in enumerate(prob.windows) if round(w.speed, 3) not in a]
    return A, B


def heldout_chi2(prob: Problem, f: Fit, windows) -> float:
    """
    Return the data chi2 of fit ``f`` on the held-out ``windows``, nothing re-fitted there.

    ``f`` was fitted on the training windows of the fold problem ``prob`` (:meth:`Problem.for_fold`); *every*
    quantity is frozen at its training value: bearing nuisance, nonlinear and linear effect parameters, and for an
    oil whirl its force, onset and ratio (the held-out windows' sub-synchronous vectors are taken at the training
    ratio).

    nX entries: complex residuals over their effective sigma.  Sub-synchronous entries: a whirl is not locked to the
    key mark, so its phase in a window the fit has not seen is unknown; the held-out comparison uses the phase-free
    amplitude residual sum_c ((|X_c| - |p_c|) / sigma_c)^2 (p = 0 without a whirl, or below the training onset) --
    no per-window phase is fitted on held-out data either.
    """
    windows = list(windows)
    if not windows:
        return 0.0
    y0, A, idx = prob.predict(f.theta, f.effects, f.nls, windows)
    y = y0 + (A @ f.lin if A.shape[1] and f.lin.size else 0)
    r = (prob.y[idx] - y) / prob.sig[idx]
    chi = float(np.sum(r.real ** 2 + r.imag ** 2))
    if not prob.has_sub:
        return chi
    whirl = [e for e in f.effects if isinstance(e, OilWhirl)]
    F = float(f.sub_info.get('force', 0.0)) if whirl else 0.0
    onset = rpm_to_rad_s(f.sub_info.get('onset_rpm', float('nan'))) if whirl else float('nan')
    for k in windows:
        w = prob.windows[k]
        if w.X_sub is None:
            continue
        p = np.zeros(w.X_sub.size)
        if F > 0 and np.isfinite(onset) and w.speed > onset:
            p = F * np.abs(whirl[0].unit_response(prob, k, f.theta, f.effects, f.nls))
        chi += float(np.sum(((np.abs(w.X_sub) - p) / np.maximum(w.std_sub, 1e-15)) ** 2))
    return chi


def validate(prob: Problem, effects: list, base: list, *, cache: dict | None = None, frac_in: float = 0.0,
             folds=None) -> dict:
    """
    Held-out check of ``effects`` against ``base`` (both ways between the two folds, default the speed halves).

    For each direction the problem is first restricted to what the training windows know (:meth:`Problem.for_fold`:
    the whirl ratio assigned to every window comes from the training whirl windows), both hypotheses are fitted on
    the training windows, and :func:`heldout_chi2` scores them on the held-out windows with every parameter frozen.
    Validated when the held-out chi2 drops by at least max(20 %, half the in-sample reduction ``frac_in``).
    """
    A, B = folds if folds is not None else speed_folds(prob)
    if len(A) == 0 or len(B) == 0:
        return {'validated': False, 'reason': 'one recorded speed: nothing to hold out'}
    cache = {} if cache is None else cache
    out_h, out_b = 0.0, 0.0
    for tr, te in ((A, B), (B, A)):
        pf = prob.for_fold(tr)
        key = (tuple(e.label for e in base), tuple(tr), id(prob))
        if key not in cache:
            cache[key] = fit(pf, base, windows=tr, uncertainty=False)
        fb = cache[key]
        fh = fit(pf, effects, windows=tr, theta0=fb.theta, uncertainty=False)
        out_b += heldout_chi2(pf, fb, te)
        out_h += heldout_chi2(pf, fh, te)
    frac_out = 1.0 - out_h / max(out_b, 1e-300)
    need = max(0.2, 0.5 * frac_in)
    return {'validated': bool(frac_out >= need), 'heldout_chi2_base': out_b, 'heldout_chi2': out_h,
            'heldout_reduction': frac_out, 'required_reduction': need}


# ------------------------------------------------------------------------------------------------ selection
@dataclass
class Selection:
    base: Fit                     # "none" (nuisance only)
    final: Fit                    # the selected hypothesis
    rounds: list                  # per greedy step: list of (Fit, validation dict | None), best first
    selected: list                # effects accepted
    # per accepted effect label: [(where, delta BIC)] of other variants of the same family (another bearing, plane
    # or probe) that fit about as well in the screening (delta BIC < AMBIGUOUS_DBIC): the data do not tell them apart
    ambiguous: dict = field(default_factory=dict)


def conflicts(a, b) -> bool:
    """
    Return True when candidate ``a`` cannot be added to a hypothesis holding ``b``.

    The same variant, or two variants the data cannot hold together (:meth:`effects.Effect.conflicts`, e.g. two
    orientations of one probe).  Any other effect may repeat at another location (another bearing, plane, probe, disc
    or coupling end).
    """
    return a.label == b.label or bool(a.conflicts(b)) or bool(b.conflicts(a))


def peak_significance(prob: Problem, f: Fit) -> float:
    """Largest |measured - predicted| / sigma over the complex entries (nX and sub-synchronous) of fit ``f``."""
    th_nl = np.concatenate([f.theta, *f.nls]) if f.nls else np.asarray(f.theta)
    r, _, extra = _residual(prob, f.effects, th_nl, f.windows, lin=f.lin if f.lin.size else None)
    n_nx = extra[6].size                       # nX entries: re parts then im parts
    b = r[:2 * n_nx]
    peak = float(np.max(np.hypot(b[:n_nx], b[n_nx:]))) if n_nx else 0.0
    rs = r[2 * n_nx:extra[3]]
    if rs.size:                                # per window: nch re parts then nch im parts
        out, i = [], 0
        for k in _sub_windows(prob, f.windows):
            m = prob.windows[k].X_sub.size
            out.append(np.hypot(rs[i:i + m], rs[i + m:i + 2 * m]))
            i += 2 * m
        peak = max(peak, float(np.max(np.concatenate(out))))
    return peak


def select(prob: Problem, cands: list, *, max_effects: int = 3, dbic_min: float = 10.0, chi2_floor: float = 1.5,
           peak_sigma: float = 5.0, n_validate: int = 4, n_refine: int = 4, folds=None, start=(), base=None
           ) -> Selection:
    """
    Greedy forward selection (see module docstring).

    ``start`` : effects every hypothesis holds (e.g. another bearing model form: the selection then runs under that
    form); ``base`` : the "none" fit, when already made (reported as the residual before).
    """
    base = fit(prob, []) if base is None else base
    selected = list(start)
    current = fit(prob, selected) if selected else base
    rounds = []
    max_effects += len(selected)
    vcache: dict = {}
    ambiguous: dict = {}
    while len(selected) < max_effects:
        if current.chi2 / max(current.n, 1) < chi2_floor and peak_significance(prob, current) < peak_sigma:
            break
        screen = []
        for c in cands:
            if any(conflicts(c, e) for e in selected):
                continue
            hold = list(current.nls) + [None] if len(current.nls) == len(selected) else None
            screen.append(fit(prob, selected + [c], theta0=current.theta,
                              free_nuisance=bool(getattr(c, 'screen_free_nuisance', False)), uncertainty=False,
                              hold_nl=hold))
        if not screen:
            break
        screen.sort(key=lambda f: f.bic)
        # refine the best variant of each of the leading families with the bearing nuisance free
        # (the two best variants of each of the n_refine best families: e.g. mirror-image planes on a symmetric
        # rotor are close in the screening and only separate once the nuisance is free)
        trials, fams = [], []
        count: dict = {}
        for f in screen:
            nm = f.effects[-1].name
            if nm not in fams:
                fams.append(nm)
            count[nm] = count.get(nm, 0) + 1
            if fams.index(nm) < n_refine and count[nm] <= 2:
                trials.append(fit(prob, f.effects, theta0=current.theta))
            elif count[nm] == 1:
                _uncertainty(prob, f, np.concatenate([f.theta, *f.nls]) if f.nls else np.asarray(f.theta))
                trials.append(f)
        trials.sort(key=lambda f: f.bic)
        # best variant per family, validated (families in BIC order)
        fam_best, seen = [], set()
        for f in trials:
            nm = f.effects[-1].name
            if nm not in seen:
                seen.add(nm)
                fam_best.append(f)
        round_rows = []
        accepted = None
        for i, f in enumerate(fam_best):
            v = None
            if i < n_validate and current.bic - f.bic > dbic_min:
                v = validate(prob, f.effects, selected, cache=vcache, frac_in=1.0 - f.chi2 / max(current.chi2, 1e-300),
                             folds=folds)
                if accepted is None and v['validated']:
                    why = (f.effects[-1].missing_signature(f.phys[-1], f.std[-1]) if f.phys else
                           'no uncertainty to judge its signature by')
                    if why:            # it fits, but its own signature is absent: no name it cannot stand behind
                        v = {**v, 'validated': False, 'signature_missing': why}
                    else:
                        accepted = f
            round_rows.append((f, v))
        rounds.append((current, round_rows))
        if accepted is None:
            break
        e_acc = accepted.effects[-1]
        same = [f for f in screen if f.effects[-1].name == e_acc.name]
        ref = min((f.bic for f in same if f.effects[-1].label == e_acc.label), default=None)
        if ref is not None:
            alt = sorted((f.bic - ref, f.effects[-1].where) for f in same if f.effects[-1].label != e_acc.label)
            alt = [(w, float(d)) for d, w in alt if d < AMBIGUOUS_DBIC]
            if alt:
                ambiguous[e_acc.label] = alt
        selected = list(accepted.effects)
        current = accepted
    return Selection(base=base, final=current, rounds=rounds, selected=selected, ambiguous=ambiguous)


__all__ = ['Fit', 'fit', 'evaluate', 'peak_significance', 'validate', 'speed_folds', 'run_folds', 'heldout_chi2',
           'Selection', 'select', 'conflicts', 'NUIS_BOUND']
