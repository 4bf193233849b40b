"""
Predicted harmonic vectors of the (augmented) model for the measured windows: the engine every hypothesis uses.

For window k at speed Omega and harmonic order r the model's probe readings are

    y = P q + (measurement terms),   q = Z(r Omega)^-1 F,
    Z = K - w^2 M + j w (C + Omega G)  [rotor, :func:`rotor.assembly.dynamic_stiffness` with no bearings]
        + sum_bearings Zb (possibly replaced by an effect, e.g. a flexible support in series)
        + effect terms (e.g. a heavier disc),

with F the known excitation at ratio r (:func:`excitation.harmonic_forces`).  Effects that are *linear* in their
parameters (unbalance, bow, 2X forcing, runout, probe gain/angle) add columns A so that y = y0 + A p, p real; the
hypothesis fit profiles p out by weighted least squares.  Effects with nonlinear parameters change Z.

Bearing uncertainty (nuisance)
    The nominal bearing theory is itself uncertain (the default rig's truth differs from theory by ~25 %).  Every
    hypothesis, "none" included, refits a viscosity factor and a clearance factor per bearing (log-parametrised,
    Gaussian prior of ``prior_sigma`` in log units around the nominal), so that a wrong bearing theory is not
    mistaken for a missing effect; a table bearing (no viscosity, no clearance) has its damping C and stiffness K
    scaled by the pair instead (:meth:`Problem.factor_words`), so that it can move too.  ``nuisance=False`` keeps the
    nominal bearings fixed.
"""
from __future__ import annotations

import copy
import dataclasses

import numpy as np

from .effect import Effect
from .locate import FLOOR_TOL, Observations, sigma
from .. import bearings as bearings_mod
from ..conventions import dof_index, parse_probe_direction, probe_direction
from ..excitation import harmonic_forces
from ..rotor import supports
from ..rotor.assembly import add_film_impedance, dynamic_stiffness, measurement_row, RotorModel
from ..rotor.banded import solve_stack


# ------------------------------------------------------------------------------------------------ bearing model forms
def model_forms() -> list[tuple[str, str | None]]:
    """
    Return every bearing model form the physics core offers, as (model, cavitation) pairs.

    The short bearing (Ocvirk, pi film: no cavitation choice, None) and the finite-length Reynolds bearing under each
    cavitation condition it offers (Swift-Stieber / Reynolds, Gumbel / half-Sommerfeld; :data:`bearing_id.bearings.
    CAVITATION`), each from its precomputed table.
    """
    return [(m, cav) for m in bearings_mod.MODELS for cav in bearings_mod.CAVITATION[m]]


def bearing_form(bearing) -> tuple[str, str | None]:
    """Return a bearing's own (model, cavitation) form (None for a table or a short bearing's cavitation)."""
    model = getattr(bearing, 'model', None)
    if model not in bearings_mod.CAVITATION:
        return (model, None)
    cav = getattr(bearing, 'cavitation', None) or 'swift_stieber'
    return (model, cav if cav in bearings_mod.CAVITATION[model] else None)


def with_form(bearing, form):
    """Return ``bearing`` under (model, cavitation) ``form`` (None: as it is): the model's cavitation set on it."""
    if form is None or form[1] is None or getattr(bearing, 'cavitation', None) == form[1]:
        return bearing
    return dataclasses.replace(bearing, cavitation=form[1])


def form_label(form) -> str:
    """Plain words for a (model, cavitation) form."""
    model, cav = form
    if model == 'short':
        return 'short bearing (Ocvirk, pi film)'
    if model == 'finite':
        words = {'swift_stieber': 'Swift-Stieber (Reynolds) cavitation', 'gumbel': 'Gumbel (half-Sommerfeld) film'}
        return f"finite-length bearing (Reynolds equation, {words.get(cav, 'each bearing its own cavitation')})"
    return f'{model} bearing' + (f' ({cav} cavitation)' if cav else '')


class Problem:
    """
    Measured data + nominal model for hypothesis fits.

    Attributes
    ----------
    obs : Observations.   rig : RigParams (nominal).   model : RotorModel.
    y, sig : flat complex measured vectors and their effective sigma [m] over all (window, order, channel) entries;
    ``slices[k]`` the entries of window k.   n_nuis : number of nuisance parameters (2 per bearing, or 0).

    """

    def __init__(self, obs: Observations, rig, *, model=None, rel_tol: float = 0.02, nuisance: bool = True,
                 prior_sigma: float = 0.3, floor_tol: float = FLOOR_TOL):
        self.obs = obs
        self.rig = rig
        self.model = model or RotorModel.from_params(rig)
        self.rel_tol = float(rel_tol)
        self.floor_tol = float(floor_tol)
        self.nuisance = bool(nuisance)
        self.prior_sigma = float(prior_sigma)
        self.nb = len(rig.bearings)
        self.n_nuis = 2 * self.nb if nuisance else 0
        self.orders = tuple(float(o) for o in obs.orders)
        n = self.model.n_nodes
        self.P = []          # per recording: probe selection (nch, ndof)
        self.Pperp = []      # per recording: reading of the perpendicular direction turned +90 deg
        for rec in obs.recordings:
            P = np.zeros((len(rec.probes), self.model.ndof))
            Q = np.zeros_like(P)
            for c, p in enumerate(rec.probes):
                # measurement rows (probes at any angle); Q reads the axis turned +90 deg (x -> y, y -> -x)
                a, g = parse_probe_direction(p.direction)
                P[c] = measurement_row(self.model, p.node, p.direction)
                Q[c] = measurement_row(self.model, p.node, probe_direction(a + 90.0, g))
            self.P.append(P)
            self.Pperp.append(Q)
        ys, ss = [], []
        self.slices = []
        i = 0
        for w in obs.windows:
            no, nch = w.X.shape
            ys.append(w.X.reshape(-1))
            ss.append(sigma(w.X, w.std, rel_tol, floor_tol).reshape(-1))
            self.slices.append(slice(i, i + no * nch))
            i += no * nch
        self.y = np.concatenate(ys) if ys else np.zeros(0, complex)
        self.sig = np.concatenate(ss) if ss else np.zeros(0)
        self.has_sub = bool(obs.sub_present)
        self.known = [harmonic_forces(obs.recordings[w.rec].run.excitation, w.speed, n, self.model.ndof)
                      for w in obs.windows]
        self._Z0 = {}
        self._Z0_stacks = {}
        self._coeff_cache = {}
        self._bearing_cache = {}
        self._factor_memo = {}
        self._loads = None

    # ----------------------------------------------------------------------------------------- helpers
    def for_fold(self, train) -> 'Problem':
        """
        Return this problem as a fit on the windows ``train`` sees it.

        Its sub-synchronous data assigned from the windows ``train`` only (:meth:`locate.Observations.assign_sub`):
        all that a fit on ``train`` may know about a whirl.
        """
        p = copy.copy(self)
        p.obs = self.obs.assign_sub(train)
        p.has_sub = bool(p.obs.sub_present)
        return p

    @property
    def windows(self):
        return self.obs.windows

    def rec_of(self, k: int) -> int:
        return self.obs.windows[k].rec

    def channel(self, k: int, name: str) -> int | None:
        """Return the channel index of probe ``name`` in window ``k``'s recording, or None when it has no such probe."""
        names = [p.name for p in self.obs.probes(self.rec_of(k))]
        return names.index(name) if name in names else None

    def Z0(self, k: int, ratio: float) -> np.ndarray:
        """Rotor-only dynamic stiffness (no bearings) of window k at ``ratio`` x speed (cached)."""
        key = (k, float(ratio))
        Z = self._Z0.get(key)
        if Z is None:
            W = self.obs.windows[k].speed
            Z = dynamic_stiffness(self.model, W, ratio * W, {})
            self._Z0[key] = Z
        return Z

    def factor_words(self, i: int) -> tuple[str, str]:
        """
        Return what bearing ``i``'s nuisance pair scales: ('viscosity', 'clearance') or ('damping C', 'stiffness K').

        A table bearing has no viscosity and no clearance: the pair scales its C and K (the table's scales,
        :func:`bearing_id.bearings.solution`).
        """
        return ('damping C', 'stiffness K') if self.rig.bearings[i].model == 'table' else ('viscosity', 'clearance')

    def nuisance_factors(self, theta) -> tuple[tuple, tuple]:
        """(viscosity factors, clearance factors) per bearing from the log nuisance vector ``theta``."""
        if not self.n_nuis:
            return (1.0,) * self.nb, (1.0,) * self.nb
        th = np.asarray(theta, dtype=float)
        return tuple(np.exp(th[:self.nb])), tuple(np.exp(th[self.nb:2 * self.nb]))

    def coeffs(self, theta, speeds, factors=None, form=None) -> list:
        """
        Bearing coefficients [{node: (K, C)}, ...] at each of ``speeds`` [rad/s] for nuisance ``theta`` (cached).

        ``factors`` : optional (viscosity factors, clearance factors) per bearing multiplying the nuisance ones
        (an effect that re-fits the bearing theory, :class:`effects.BearingModelForm`).   ``form`` : optional
        (model, cavitation) replacing every bearing's model form (default: each bearing's ``model``).  Through
        :func:`bearing_id.bearings.coefficients_at`, all missing speeds of a bearing in one call (the short bearing
        in one batch, the finite bearing from its precomputed Sommerfeld table).
        """
        # the factors and their rounded logs once per (theta, factors): every window of a prediction asks for them
        fkey = (np.asarray(theta, dtype=float).tobytes(),
                None if factors is None else tuple(tuple(float(v) for v in f) for f in factors))
        memo = self._factor_memo.get(fkey)
        if memo is None:
            vf, cf = self.nuisance_factors(theta)
            if factors is not None:
                vf = tuple(a * b for a, b in zip(vf, factors[0]))
                cf = tuple(a * b for a, b in zip(cf, factors[1]))
            lf = np.round(np.log(np.concatenate([vf, cf])), 13)
            if len(self._factor_memo) > 1000:
                self._factor_memo.clear()
            memo = self._factor_memo[fkey] = (vf, cf, lf, tuple(lf))
        vf, cf, lf, lf_key = memo
        if len(self._coeff_cache) > 20000:
            self._coeff_cache.clear()
            self._bearing_cache.clear()
        keys = [(lf_key, float(W), form) for W in speeds]
        todo = [k[1] for k in keys if k not in self._coeff_cache]
        if todo:
            if self._loads is None:
                self._loads = supports.static_loads(self.rig)
            per_bearing = []
            for i, b in enumerate(self.rig.bearings):
                # per bearing: a nuisance step on one bearing's factors (a Jacobian column) leaves the others cached
                bkeys = [(i, float(lf[i]), float(lf[self.nb + i]), W, form) for W in todo]
                miss = [k for k in bkeys if k not in self._bearing_cache]
                if miss:
                    if b.model == 'table':      # a table: its C and K scaled (the nuisance pair's meaning there)
                        scaled = {'c_scale': vf[i], 'k_scale': cf[i]}
                    else:
                        scaled = {'viscosity': b.viscosity * vf[i], 'clearance': b.clearance * cf[i],
                                  'model': form[0] if form is not None else b.model}
                    K, C = bearings_mod.coefficients_at(with_form(b, form), [k[3] for k in miss], self._loads[b.node],
                                                        **scaled)
                    for k, Kk, Ck in zip(miss, K, C):
                        self._bearing_cache[k] = (Kk, Ck)
                per_bearing.append([self._bearing_cache[k] for k in bkeys])
            for j, W in enumerate(todo):
                self._coeff_cache[(lf_key, W, form)] = {b.node: per_bearing[i][j]
                                                        for i, b in enumerate(self.rig.bearings)}
        return [self._coeff_cache[k] for k in keys]

    # ----------------------------------------------------------------------------------------- prediction
    def _bearing_setup(self, effects, nls):
        """Return (factors, form): what the effects apply to the bearing theory, composed in effect order."""
        factors, form = None, None
        for e, nl in zip(effects, nls):
            f = e.bearing_factors(nl)
            if f is not None:
                factors = f if factors is None else (tuple(a * b for a, b in zip(factors[0], f[0])),
                                                     tuple(a * b for a, b in zip(factors[1], f[1])))
            form = getattr(e, 'bearing_form', None) or form
        return factors, form

    def _Z0_stack(self, keys) -> np.ndarray:
        """Rotor-only dynamic stiffnesses (n, N, N) of the (window, ratio) ``keys`` stacked (cached per key list)."""
        key = tuple(keys)
        Z = self._Z0_stacks.get(key)
        if Z is None:
            if len(self._Z0_stacks) > 16:
                self._Z0_stacks.clear()
            Z = self._Z0_stacks[key] = np.stack([self.Z0(k, r) for k, r in keys])
        return Z

    def systems(self, keys, theta, effects, nls) -> np.ndarray:
        """
        Return the full dynamic stiffness Z (n, N, N) of every (window, ratio) of ``keys`` with bearings and effects.

        Per entry at w = ratio x the window's speed: the rotor-only Z (:meth:`Z0`), each bearing's K + j w C (at the
        nuisance ``theta`` and the effects' bearing factors and form) through the effects' bearing hooks, added at
        its film DOFs (or in series with its pedestal), then the effects' dZ; vectorised over the entries.
        """
        n = len(keys)
        Z = self._Z0_stack(keys).copy()
        if not n:
            return Z
        factors, form = self._bearing_setup(effects, nls)
        Ws = [self.obs.windows[k].speed for k, _ in keys]
        ws = [ratio * W for (_, ratio), W in zip(keys, Ws)]
        w = np.array(ws)
        speeds = list(dict.fromkeys(Ws))
        per_speed = self.coeffs(theta, speeds, factors, form)
        pos = {W: i for i, W in enumerate(speeds)}
        at = np.array([pos[W] for W in Ws])
        b_hooks = [(e, nl) for e, nl in zip(effects, nls) if type(e).bearing_impedance is not Effect.bearing_impedance]
        z_hooks = [(e, nl) for e, nl in zip(effects, nls) if type(e).add_dZ is not Effect.add_dZ]
        jw = 1j * w[:, None, None]
        for node in per_speed[0]:
            Kb = np.stack([c[node][0] for c in per_speed])[at]
            Cb = np.stack([c[node][1] for c in per_speed])[at]
            Zb = np.asarray(Kb, float) + jw * np.asarray(Cb, float)
            for e, nl in b_hooks:
                for j in range(n):
                    Zb[j] = e.bearing_impedance(self, node, Zb[j], Ws[j], ws[j], nl)
            add_film_impedance(self.model, Z, node, Zb)       # every entry at once
        for e, nl in z_hooks:
            for j in range(n):
                e.add_dZ(self, Z[j], Ws[j], ws[j], nl)
        return Z

    def predict(self, theta, effects, nls, windows=None):
        """
        Model prediction over the entries of ``windows`` (default all).

        Returns (y0, A, idx) with y0 complex (n_sel,) the readings from the known excitation, A complex
        (n_sel, n_lin) the columns of the effects' linear parameters (concatenated in effect order), and idx (n_sel,)
        the selected entries' indices into ``y``.  ``nls`` holds each effect's nonlinear parameter vector.  The
        dynamic stiffness of every (window, order) is assembled at once (:meth:`systems`), and the systems with
        right-hand sides of equal shape are solved as one stack (:func:`bearing_id.rotor.banded.solve_stack`).
        """
        windows = range(len(self.obs.windows)) if windows is None else windows
        nlin = [e.n_lin for e in effects]
        off = np.concatenate([[0], np.cumsum(nlin)]).astype(int)
        ndof = self.model.ndof
        zero_rhs = np.zeros((ndof, 1), complex)
        jobs = []               # (window, order, ratio, cols, solved?, R) window by window, order by order
        for k in windows:
            for o, ratio in enumerate(self.orders):
                F0 = self.known[k].get(ratio)
                rhs = [F0[:, None] if F0 is not None else zero_rhs]
                cols = []
                for j, (e, nl) in enumerate(zip(effects, nls)):
                    fc = e.force_columns(self, k, ratio, nl)
                    if fc is not None:
                        cols.append((j, fc.shape[1]))
                        rhs.append(fc)
                if F0 is None and not cols:
                    jobs.append((k, o, ratio, cols, None, None))
                else:
                    jobs.append((k, o, ratio, cols, True, rhs[0] if len(rhs) == 1 else np.hstack(rhs)))
        solved = [i for i, job in enumerate(jobs) if job[4] is not None]
        Zs = self.systems([(jobs[i][0], jobs[i][2]) for i in solved], theta, effects, nls)
        groups = {}
        for p, i in enumerate(solved):
            groups.setdefault(jobs[i][5].shape, []).append(p)
        Qs = [None] * len(jobs)
        for members in groups.values():
            Zg = Zs if len(members) == len(solved) else Zs[members]
            Q = solve_stack(Zg, np.stack([jobs[solved[p]][5] for p in members]))
            for p, q in zip(members, Q):
                Qs[solved[p]] = q[:ndof]
        idx, y0s, As = [], [], []
        n_ord = len(self.orders)
        for start in range(0, len(jobs), n_ord):
            k = jobs[start][0]
            wdw = self.obs.windows[k]
            r_ = self.rec_of(k)
            P, Pp = self.P[r_], self.Pperp[r_]
            no, nch = wdw.X.shape
            y0 = np.zeros((no, nch), complex)
            A = np.zeros((no, nch, off[-1]), complex)
            for i in range(start, start + n_ord):
                _, o, ratio, cols, _, _ = jobs[i]
                Q = Qs[i]
                q0 = Q[:, 0] if Q is not None else np.zeros(ndof, complex)
                y_nom = P @ q0
                y0[o] = y_nom
                c0 = 1
                for j, m in cols:
                    A[o, :, off[j]:off[j] + m] += P @ Q[:, c0:c0 + m]
                    c0 += m
                if effects:
                    y_perp = Pp @ q0
                    for j, (e, nl) in enumerate(zip(effects, nls)):
                        mc = e.measure_columns(self, k, o, ratio, y_nom, y_perp)
                        if mc is not None:
                            A[o, :, off[j]:off[j + 1]] += mc
            sl = self.slices[k]
            idx.append(np.arange(sl.start, sl.stop))
            y0s.append(y0.reshape(-1))
            As.append(A.reshape(no * nch, off[-1]))
        if not idx:
            return np.zeros(0, complex), np.zeros((0, off[-1]), complex), np.zeros(0, int)
        return np.concatenate(y0s), np.vstack(As), np.concatenate(idx)

    def prediction_by_window(self, theta, effects, nls, lin):
        """Predicted harmonic vectors per window, complex (n_orders, nch) each, with linear parameters ``lin``."""
        y0, A, idx = self.predict(theta, effects, nls)
        y = y0 + (A @ lin if A.shape[1] else 0)
        out = []
        for k, w in enumerate(self.obs.windows):
            sl = self.slices[k]
            out.append(y[sl].reshape(w.X.shape))
        return out

    def prior_residual(self, theta) -> np.ndarray:
        """Gaussian prior of the log nuisance factors (units of prior sigma)."""
        if not self.n_nuis:
            return np.zeros(0)
        return np.asarray(theta, dtype=float) / self.prior_sigma


def forward_force(ndof: int, node: int, n_nodes: int, value: complex = 1.0) -> np.ndarray:
    """Force phasor vector (ndof,) of a forward rotating force ``value`` [N] at ``node`` (F_y = -j F_x)."""
    F = np.zeros(ndof, dtype=complex)
    i = dof_index(node, 'x', n_nodes)
    F[i] = value
    F[i + 1] = -1j * value
    return F


__all__ = ['Problem', 'forward_force', 'model_forms', 'form_label']
