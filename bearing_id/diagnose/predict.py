"""Predicted harmonic vectors of the (augmented) model for the measured windows: the engine every hypothesis uses.

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
    mistaken for a missing effect.  ``nuisance=False`` keeps the nominal bearings fixed.
"""
from __future__ import annotations

import numpy as np

from .. import bearings as bearings_mod
from ..conventions import dof_index
from ..excitation import harmonic_forces
from ..rotor.assembly import RotorModel, dynamic_stiffness
from .locate import Observations, sigma


class Problem:
    """Measured data + nominal model for hypothesis fits.

    Attributes
    ----------
    obs : Observations.   rig : RigParams (nominal).   model : RotorModel.
    y, sig : flat complex measured vectors and their effective sigma [m] over all (window, order, channel) entries.
    win_of : (n_entries,) window index of each entry.   sub_y, sub_sig : per window (nch,) sub-synchronous data.
    n_nuis : number of nuisance parameters (2 per bearing, or 0).
    """

    def __init__(self, obs: Observations, rig, *, model=None, rel_tol: float = 0.02, nuisance: bool = True,
                 prior_sigma: float = 0.3):
        self.obs = obs
        self.rig = rig
        self.model = model or RotorModel.from_params(rig)
        self.rel_tol = float(rel_tol)
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
                P[c, dof_index(p.node, p.direction, n)] = 1.0
                if p.direction == "x":
                    Q[c, dof_index(p.node, "y", n)] = 1.0
                else:
                    Q[c, dof_index(p.node, "x", n)] = -1.0
            self.P.append(P)
            self.Pperp.append(Q)
        ys, ss, wk, ok, ck = [], [], [], [], []
        self.slices = []
        i = 0
        for k, w in enumerate(obs.windows):
            no, nch = w.X.shape
            ys.append(w.X.reshape(-1))
            ss.append(sigma(w.X, w.std, rel_tol).reshape(-1))
            wk += [k] * (no * nch)
            ok += [o for o in range(no) for _ in range(nch)]
            ck += [c for _ in range(no) for c in range(nch)]
            self.slices.append(slice(i, i + no * nch))
            i += no * nch
        self.y = np.concatenate(ys) if ys else np.zeros(0, complex)
        self.sig = np.concatenate(ss) if ss else np.zeros(0)
        self.win_of = np.array(wk, dtype=int)
        self.order_of = np.array(ok, dtype=int)
        self.chan_of = np.array(ck, dtype=int)
        self.has_sub = bool(obs.sub_present)
        self.known = [harmonic_forces(obs.recordings[w.rec].run.excitation, w.speed, n) for w in obs.windows]
        self._Z0 = {}
        self._coeff_cache = {}
        self._loads = None

    # ----------------------------------------------------------------------------------------- helpers
    @property
    def windows(self):
        return self.obs.windows

    def rec_of(self, k: int) -> int:
        return self.obs.windows[k].rec

    def Z0(self, k: int, ratio: float) -> np.ndarray:
        """Rotor-only dynamic stiffness (no bearings) of window k at ``ratio`` x speed (cached)."""
        key = (k, float(ratio))
        Z = self._Z0.get(key)
        if Z is None:
            W = self.obs.windows[k].speed
            Z = dynamic_stiffness(self.model, W, ratio * W, {})
            self._Z0[key] = Z
        return Z

    def nuisance_factors(self, theta) -> tuple[tuple, tuple]:
        """(viscosity factors, clearance factors) per bearing from the log nuisance vector ``theta``."""
        if not self.n_nuis:
            return (1.0,) * self.nb, (1.0,) * self.nb
        th = np.asarray(theta, dtype=float)
        return tuple(np.exp(th[:self.nb])), tuple(np.exp(th[self.nb:2 * self.nb]))

    def coeffs(self, theta, speed: float, factors=None) -> dict:
        """Bearing coefficients {node: (K, C)} at ``speed`` [rad/s] for nuisance ``theta`` (cached).

        ``factors`` : optional (viscosity factors, clearance factors) per bearing multiplying the nuisance ones
        (an effect that re-fits the bearing theory, :class:`effects.BearingModelForm`)."""
        vf, cf = self.nuisance_factors(theta)
        if factors is not None:
            vf = tuple(a * b for a, b in zip(vf, factors[0]))
            cf = tuple(a * b for a, b in zip(cf, factors[1]))
        key = (tuple(np.round(np.log(np.concatenate([vf, cf])), 13)), float(speed))
        c = self._coeff_cache.get(key)
        if c is None:
            if self._loads is None:
                self._loads = bearings_mod.static_loads(self.rig)
            fn = bearings_mod.bearing_fn(self.rig, viscosity_factor=vf, clearance_factor=cf, loads=self._loads)
            c = fn(speed)
            if len(self._coeff_cache) > 20000:
                self._coeff_cache.clear()
            self._coeff_cache[key] = c
        return c

    # ----------------------------------------------------------------------------------------- prediction
    def system(self, k: int, ratio: float, theta, effects, nls) -> np.ndarray:
        """Full dynamic stiffness Z (ndof, ndof) of window k at ratio x speed with bearings and effects."""
        W = self.obs.windows[k].speed
        w = ratio * W
        Z = self.Z0(k, ratio).copy()
        n = self.model.n_nodes
        factors = None
        for e, nl in zip(effects, nls):
            f = e.bearing_factors(nl)
            if f is not None:
                factors = f if factors is None else (tuple(a * b for a, b in zip(factors[0], f[0])),
                                                     tuple(a * b for a, b in zip(factors[1], f[1])))
        for node, (Kb, Cb) in self.coeffs(theta, W, factors).items():
            Zb = np.asarray(Kb) + 1j * w * np.asarray(Cb)
            for e, nl in zip(effects, nls):
                Zb = e.bearing_impedance(self, node, Zb, W, w, nl)
            i = dof_index(node, "x", n)
            Z[i:i + 2, i:i + 2] += Zb
        for e, nl in zip(effects, nls):
            e.add_dZ(self, Z, W, w, nl)
        return Z

    def predict(self, theta, effects, nls, windows=None):
        """Model prediction over the entries of ``windows`` (default all).

        Returns (y0, A, q_by_window) with y0 complex (n_sel,) the readings from the known excitation, A complex
        (n_sel, n_lin) the columns of the effects' linear parameters (concatenated in effect order), and the
        selected entry indices.  ``nls`` holds each effect's nonlinear parameter vector.
        """
        windows = range(len(self.obs.windows)) if windows is None else windows
        nlin = [e.n_lin for e in effects]
        off = np.concatenate([[0], np.cumsum(nlin)]).astype(int)
        idx, y0s, As = [], [], []
        for k in windows:
            wdw = self.obs.windows[k]
            r_ = self.rec_of(k)
            P, Pp = self.P[r_], self.Pperp[r_]
            no, nch = wdw.X.shape
            y0 = np.zeros((no, nch), complex)
            A = np.zeros((no, nch, off[-1]), complex)
            for o, ratio in enumerate(self.orders):
                F0 = self.known[k].get(ratio)
                rhs = [F0[:, None] if F0 is not None else np.zeros((self.model.ndof, 1), complex)]
                cols = []
                for j, (e, nl) in enumerate(zip(effects, nls)):
                    fc = e.force_columns(self, k, ratio, nl)
                    if fc is not None:
                        cols.append((j, fc.shape[1]))
                        rhs.append(fc)
                if F0 is None and not cols:
                    q0 = np.zeros(self.model.ndof, complex)
                    Q = None
                else:
                    Z = self.system(k, ratio, theta, effects, nls)
                    R = np.hstack(rhs)
                    Q = np.linalg.solve(Z, R)[:self.model.ndof]
                    q0 = Q[:, 0]
                y0[o] = P @ q0
                c0 = 1
                for j, m in cols:
                    A[o, :, off[j]:off[j] + m] += P @ Q[:, c0:c0 + m]
                    c0 += m
                for j, (e, nl) in enumerate(zip(effects, nls)):
                    mc = e.measure_columns(self, k, o, ratio, P @ q0, Pp @ q0)
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
    i = dof_index(node, "x", n_nodes)
    F[i] = value
    F[i + 1] = -1j * value
    return F


__all__ = ["Problem", "forward_force"]
