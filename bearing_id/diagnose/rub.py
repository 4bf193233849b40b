"""
A rotor-to-stator rub at a probe station: contact where the measured orbit reaches a clearance.

Where the shaft's orbit at a node exceeds the radial clearance ``delta`` to a stator (seal, casing, a loose guard),
the contact pushes back along the radius and rubs along the surface (Muszynska, *Rotordynamics*, 2005, ch. 6;
Childs 1993)::

    f = -k (r - delta)_+ (e_r + mu e_t)             [N] on the shaft at the node, r = |q|, e_r = q / r,

with e_t the direction of the surface speed (the spin: +x -> +y), k the contact stiffness [N/m] and mu the friction
coefficient.  The force is periodic with the orbit; its 1X, 2X and 3X phasors are computed from the orbit *as
measured* at the node (its x/y probe pair, the window's samples about their mean, the force projected on e^{-j r
angle}: a quasi-periodic contact response counts with its true peaks), so for a clearance ``delta`` the force is
linear in (k, k mu): the candidate's two linear parameters, with
``delta`` its one nonlinear parameter.  Contact happens only at the speeds whose orbit reaches ``delta`` -- the rub's
signature: speed-local changes of 1X (and harmonics) where the orbit is largest, none elsewhere.

Only nodes with an x/y probe pair are tried (the orbit must be measured there; ``effects.candidates`` finds the
pairs).  Units SI; phasors as in :mod:`bearing_id.conventions` (x = Re{X e^{j r angle}}).
"""
from __future__ import annotations

import math

import numpy as np

from .effect import determined, Effect, pm
from ..conventions import dof_index, rad_s_to_rpm

MAX_SAMPLES = 4096        # samples per window the contact force's harmonics are computed from (every k-th)
ORDERS = (1.0, 2.0, 3.0)
SIGNATURE_SIGMA = 4.0     # the contact stiffness must exceed this many sigma


class Rub(Effect):
    """
    Rub at the x/y probe pair ``px``, ``py`` (one node).  ``obs``: the problem's observations (the measured orbits).

    Linear parameters: k [N/m] and k mu [N/m]; nonlinear: the clearance delta [m].
    """

    name = 'rub'
    only_1x = False           # its DC push, harmonics and sub-harmonics
    n_lin = 2
    key = 'clearance'
    nl_names = ('clearance',)

    def __init__(self, obs, px, py):
        super().__init__()
        self.px, self.py, self.node = px, py, px.node
        self.where = f'node {px.node} (probes {px.name}/{py.name})'
        self._orbits = {}                     # window -> (x, y, angle) as measured [m, m, rad], (n,) each
        self._rpm = {}
        for k, w in enumerate(obs.windows):
            names = [p.name for p in obs.probes(w.rec)]
            if px.name not in names or py.name not in names:
                continue
            cx, cy = names.index(px.name), names.index(py.name)
            rec = obs.recordings[w.rec]
            step = max(1, (w.i1 - w.i0) // MAX_SAMPLES)
            xy = np.asarray(rec.samples[w.i0:w.i1:step][:, [cx, cy]], dtype=float)
            ang = np.asarray(rec.angle[w.i0:w.i1:step], dtype=float)
            ok = np.all(np.isfinite(xy), axis=1) & np.isfinite(ang)
            if ok.sum() < 16:
                continue
            xy = xy[ok] - np.mean(xy[ok], axis=0)           # about the mean position (the probes' gaps unknown)
            self._orbits[k] = (xy[:, 0], xy[:, 1], ang[ok])
            self._rpm[k] = rad_s_to_rpm(w.speed)
        self._peak = {k: float(np.max(np.hypot(x, y))) for k, (x, y, _) in self._orbits.items()}   # [m]
        self.r_max = max(self._peak.values(), default=0.0)
        self.nl_lo = (0.2 * self.r_max,)
        self.nl_hi = (max(self.r_max, 1e-12),)
        self._cache: dict = {}

    @property
    def starts(self):
        return [np.array([f * self.r_max]) for f in (0.7, 0.9)]

    def contact_forces(self, k: int, delta: float) -> dict:
        """
        Return {ratio: (F_n, F_t)} [N per N/m]: the 1X-3X phasors (x, y) of -(r - delta)_+ e_r and of -(...) e_t.

        Per unit contact stiffness; window ``k``'s measured orbit at the node.
        """
        key = (k, float(delta))
        out = self._cache.get(key)
        if out is None:
            x, y, ang = self._orbits[k]
            r = np.maximum(np.hypot(x, y), 1e-300)
            pen = np.maximum(r - delta, 0.0)
            fn = -pen * np.array([x / r, y / r])              # (2, n) normal push, per unit k
            ft = -pen * np.array([-y / r, x / r])             # friction against the spin, per unit k mu
            out = {}
            for ratio in ORDERS:
                e = np.exp(-1j * ratio * ang)
                out[ratio] = (2.0 * np.mean(fn * e, axis=1), 2.0 * np.mean(ft * e, axis=1))
            if len(self._cache) > 4096:
                self._cache.clear()
            self._cache[key] = out
        return out

    def force_columns(self, prob, k, ratio, nl):
        if k not in self._orbits or float(ratio) not in ORDERS:
            return None
        Fn, Ft = self.contact_forces(k, float(nl[0]))[float(ratio)]
        n = prob.model.n_nodes
        ix, iy = dof_index(self.node, 'x', n), dof_index(self.node, 'y', n)
        cols = np.zeros((prob.model.ndof, 2), complex)
        cols[ix, 0], cols[iy, 0] = Fn
        cols[ix, 1], cols[iy, 1] = Ft
        return cols

    def contact_speeds(self, delta: float) -> list[float]:
        """Return the speeds [rpm] whose measured orbit at the node reaches ``delta`` [m]."""
        return sorted({round(self._rpm[k]) for k, peak in self._peak.items() if peak > delta})

    def physical(self, nl, lin):
        """Return the clearance [m], contact stiffness [N/m], friction [-] and the contact speed range [rpm]."""
        delta, k, kmu = float(nl[0]), float(lin[0]), float(lin[1])
        sp = self.contact_speeds(delta)
        return {'clearance': delta, 'contact_stiffness': k, 'friction': kmu / k if k else math.nan,
                'contact_from_rpm': float(sp[0]) if sp else math.nan,
                'contact_to_rpm': float(sp[-1]) if sp else math.nan}

    def missing_signature(self, phys, std):
        """Return why the fit is not a rub: no contact, contact at every speed, or no significant contact force."""
        sp = self.contact_speeds(phys['clearance'])
        if not sp:
            return 'the fitted clearance is beyond every measured orbit: no contact'
        if len(sp) == len({round(v) for v in self._rpm.values()}):
            return 'contact at every speed: a stiffness the model lacks, not an intermittent rub'
        k, s = phys['contact_stiffness'], std.get('contact_stiffness', math.inf)
        if not k > SIGNATURE_SIGMA * s:
            return f'no significant contact stiffness ({k:.3g} ± {s:.2g} N/m, or pulling instead of pushing)'
        return None

    def undetermined(self, phys, std):
        return [p for p in ('clearance', 'contact_stiffness', 'friction') if not determined(phys[p], std.get(p))]

    def sentence(self, phys, std):
        und = set(self.undetermined(phys, std))
        sp = self.contact_speeds(phys['clearance'])

        def num(p, fmt, scale=1.0, unit=''):
            if p in und:
                return 'not determined'
            return f'{phys[p] * scale:{fmt}}{unit}{pm(phys[p], std.get(p))}'

        return (f"rub at {self.where}: radial clearance {num('clearance', '.3g', 1e6, ' µm')}, contact at "
                f"{', '.join(f'{v:.0f}' for v in sp)} rpm (where the measured orbit, up to "
                f'{self.r_max * 1e6:.3g} µm, reaches it); contact stiffness '
                f"{num('contact_stiffness', '.3g', 1.0, ' N/m')}, friction {num('friction', '.2g')}")


__all__ = ['Rub']
