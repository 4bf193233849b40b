"""
Simulator-side physics that the nominal model leaves out: concealed effects for the simulated rig.

These objects are passed to :func:`bearing_id.simulation.rig.simulate` as ``effects=[...]`` (see docs/ARCHITECTURE.md,
"rig.py truth effects").  They are written *independently* of the fitting-side models in
:mod:`bearing_id.diagnose.effects` (different routes to the same physics), so that a diagnosis that recovers their
parameters is evidence, not an echo:

=====================  ==============================================  =============================================
effect                 here (truth, simulator side)                    diagnose/effects.py (fitting side)
=====================  ==============================================  =============================================
support flexibility    pedestal masses appended as real DOFs, the      series impedance (Zb^-1 + Zs^-1)^-1 condensed
                       oil film joining journal and pedestal           onto the journal DOFs
residual unbalance     rotating force m r Omega^2 written out here     excitation.harmonic_forces of an extra entry
shaft bow              sine-shaped bow, force K_shaft b rotating       parabolic bow shape, same elastic force
probe runout           additive 1X term in the sampled signal          constant 1X vector in the harmonic domain
probe orientation      rotated/gained probe reading, time domain       mixing of predicted x/y phasors
misalignment           2X force at the coupling end node               2X force phasors through the FE model
oil whirl              forward rotating sub-synchronous force at a     forced response at the measured ratio, per
                       bearing above an onset speed                    window phase-aligned
disc mass error        disc mass, inertias and gyroscopics rescaled    DiscElement matrices scaled
=====================  ==============================================  =============================================

Units: SI (m, kg, N, rad, rad/s).  Node numbers 1-based.  Force phasor convention of :mod:`bearing_id.conventions`:
f(t) = Re{F exp(j r phi)}; a forward rotating vector has F_y = -j F_x.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from ..conventions import dof_index, parse_probe_direction, probe_row
from ..rotor.assembly import RotorModel


# --------------------------------------------------------------------------------------------- system effects
@dataclass
class SupportFlexibility:
    """
    Flexible pedestal under a bearing (truth: pedestal DOFs appended).

    Under the bearing at ``bearing_node``: mass ``mass`` [kg], stiffness ``k`` [N/m], damping ``c`` [N s/m] per
    direction, ``None`` for a rigid direction, e.g. ``k=(None, 3e5)`` = vertical only.

    Truth route: one DOF is appended per flexible direction; the oil film (the bearing block that the rig already
    put on the journal DOFs) is re-routed to act on the *relative* journal-pedestal displacement, and the pedestal
    is tied to ground by k and c.  Put this effect before others that change the same bearing block.
    """

    bearing_node: int
    k: tuple = (None, 3e5)
    c: tuple = (0.0, 0.0)
    mass: tuple = (0.0, 0.0)

    def modify_system(self, M, C, K, speed, model):
        n = model.n_nodes
        i = dof_index(self.bearing_node, 'x', n)
        ii = slice(i, i + 2)
        # the film blocks the simulator added on the journal DOFs (rotor-only part subtracted)
        Kb = K[ii, ii] - model.K[ii, ii]
        Cb = C[ii, ii] - (model.C[ii, ii] + speed * model.G[ii, ii])
        flex = [d for d in range(2) if self.k[d] is not None]
        if not flex:
            return M, C, K
        nd = M.shape[0]
        m = len(flex)
        T = np.zeros((2, m))                       # journal-direction -> pedestal DOF map
        for a, d in enumerate(flex):
            T[d, a] = 1.0

        def grow(A):
            B = np.zeros((nd + m, nd + m))
            B[:nd, :nd] = A
            return B

        M2, C2, K2 = grow(M), grow(C), grow(K)
        p = slice(nd, nd + m)
        for A2, blk in ((K2, Kb), (C2, Cb)):
            A2[ii, p] -= blk @ T
            A2[p, ii] -= T.T @ blk
            A2[p, p] += T.T @ blk @ T
        for a, d in enumerate(flex):
            K2[nd + a, nd + a] += float(self.k[d])
            C2[nd + a, nd + a] += float(self.c[d] or 0.0)
            # a massless pedestal would make M singular for the transient solution: keep a tiny mass floor
            M2[nd + a, nd + a] += max(float(self.mass[d] or 0.0), 1e-4)
        return M2, C2, K2


@dataclass
class DiscMassError:
    """
    The disc at ``node`` is ``factor`` times as heavy as the model says (mass, diametral and polar inertia).

    Truth route: the disc's own m, Id, Ip are recomputed from the rig geometry (thick annulus) and the extra
    ``(factor - 1)`` share is written into M (x, y, theta) and into the gyroscopic term speed * Ip of C.
    """

    rig: object
    node: int
    factor: float = 1.2

    def modify_system(self, M, C, K, speed, model):
        discs = [d for d in self.rig.discs if d.node == self.node]
        if not discs:
            raise ValueError(f'no disc at node {self.node}')
        m = sum(d.mass for d in discs)
        ro2 = [((d.outer_diameter / 2) ** 2, (d.inner_diameter / 2) ** 2, d.thickness, d.mass) for d in discs]
        Ip = sum(mm * (a + b) / 2 for a, b, _, mm in ro2)
        Id = sum(mm * ((a + b) / 4 + t * t / 12) for a, b, t, mm in ro2)
        f = self.factor - 1.0
        i = dof_index(self.node, 'x', model.n_nodes)
        M = M.copy()
        C = C.copy()
        M[i, i] += f * m
        M[i + 1, i + 1] += f * m
        M[i + 2, i + 2] += f * Id
        M[i + 3, i + 3] += f * Id
        # gyroscopic moment of the spinning disc, conventions: +Ip at (tx, ty), -Ip at (ty, tx)
        C[i + 2, i + 3] += speed * f * Ip
        C[i + 3, i + 2] -= speed * f * Ip
        return M, C, K


# --------------------------------------------------------------------------------------------- force effects
@dataclass
class ResidualUnbalance:
    """An unbalance ``me`` [kg m] at ``node``, ``phase`` [rad] from the key mark, that the model does not know."""

    node: int
    me: float
    phase: float = 0.0

    def forces(self, speed, ndof):
        F = np.zeros(ndof, dtype=complex)       # rotor DOFs first; appended DOFs (pedestals) carry no force
        i = 4 * (self.node - 1)
        F[i] = self.me * speed * speed * complex(math.cos(self.phase), math.sin(self.phase))
        F[i + 1] = -1j * F[i]
        return {1.0: F}


@dataclass
class ShaftBow:
    """
    A permanently bent shaft (truth: a half-sine bow).

    Bow ``amplitude`` [m] at its crest, at ``phase`` [rad] from the key mark, shaped as a half sine over the whole
    shaft (zero at both shaft ends).

    Truth route: the unstressed shaft is bent, so the elastic force is K_shaft (q - b) and the bow acts as the
    rotating force K_shaft b (1X, forward; constant amplitude with speed, unlike an unbalance).
    """

    rig: object
    amplitude: float
    phase: float = 0.0
    _Kb: np.ndarray | None = field(default=None, repr=False)

    def _force(self):
        if self._Kb is None:
            model = RotorModel.from_params(self.rig)
            z = np.asarray(model.node_z)
            L = z[-1]
            B = self.amplitude * complex(math.cos(self.phase), math.sin(self.phase))
            b = np.zeros(model.ndof, dtype=complex)
            s = np.sin(math.pi * z / L)
            ds = math.pi / L * np.cos(math.pi * z / L)
            bx, by = B, -1j * B                      # forward rotating bow vector
            n4 = 4 * model.n_nodes                  # rotor DOFs (pedestal DOFs, if any, follow)
            b[0:n4:4] = bx * s
            b[1:n4:4] = by * s
            b[2:n4:4] = -by * ds                     # theta_x = -dy/dz
            b[3:n4:4] = bx * ds                      # theta_y = +dx/dz
            self._Kb = model.K_shaft @ b
        return self._Kb

    def forces(self, speed, ndof):
        f = np.zeros(ndof, dtype=complex)
        kb = self._force()
        f[:kb.size] = kb
        return {1.0: f}


@dataclass
class Misalignment:
    """
    Coupling misalignment: a 2X force at the coupling end.

    ``magnitude`` [N] at ``node``, ``phase`` [rad], ``direction`` 'x', 'y' or 'forward' (rotating at 2X).
    """

    node: int = 1
    magnitude: float = 2.0
    phase: float = 0.0
    direction: str = 'forward'

    def forces(self, speed, ndof):
        F = np.zeros(ndof, dtype=complex)
        i = 4 * (self.node - 1)
        f = self.magnitude * complex(math.cos(self.phase), math.sin(self.phase))
        if self.direction in ('x', 'forward'):
            F[i] = f
        if self.direction == 'y':
            F[i + 1] = f
        if self.direction == 'forward':
            F[i + 1] = -1j * f
        return {2.0: F}


@dataclass
class OilWhirl:
    """
    Oil whirl above an onset speed (truth: a forward sub-synchronous force).

    Above ``onset_rpm`` the film at ``bearing_node`` drives a forward whirl at ``ratio`` x speed, simulated as a
    forward rotating force of ``magnitude`` [N] at that frequency (a linear stand-in for the limit cycle).
    """

    bearing_node: int = 2
    onset_rpm: float = 2000.0
    ratio: float = 0.45
    magnitude: float = 0.5

    def forces(self, speed, ndof):
        if speed * 60.0 / (2 * math.pi) < self.onset_rpm:
            return {}
        F = np.zeros(ndof, dtype=complex)
        i = 4 * (self.bearing_node - 1)
        F[i] = self.magnitude
        F[i + 1] = -1j * self.magnitude
        return {float(self.ratio): F}


# --------------------------------------------------------------------------------------------- measurement effects
@dataclass
class ProbeRunout:
    """
    Runout on one probe: a 1X reading locked to the rotor angle.

    Electrical/mechanical runout on probe ``probe`` (channel name): an extra reading ``amplitude cos(phi + phase)``
    [m] locked to the rotor angle, the same at every speed (slow roll included).
    """

    probe: str
    amplitude: float
    phase: float = 0.0

    def measure(self, samples, angle, speed, probes):
        names = [p.name for p in probes]
        if self.probe not in names:
            raise ValueError(f'runout probe {self.probe!r} is not recorded ({names})')
        out = np.array(samples, dtype=float, copy=True)
        out[:, names.index(self.probe)] += self.amplitude * np.cos(np.asarray(angle, dtype=float) + self.phase)
        return out


@dataclass
class ProbeOrientation:
    """
    One probe turned and gained.

    Probe ``probe`` is turned by ``angle`` [rad] (from its nominal axis towards the other axis, +x -> +y) and
    reads with ``gain`` [-]: reading = gain (cos a * u_nominal + sin a * u_perp) where u_perp is the displacement
    along the nominal axis turned by +90 deg.  Needs the perpendicular probe at the same node in the recording
    (its *clean* signal supplies the perpendicular displacement).
    """

    probe: str
    angle: float = math.radians(8.0)
    gain: float = 1.0

    def measure(self, samples, angle, speed, probes):
        names = [p.name for p in probes]
        i = names.index(self.probe)
        p = probes[i]
        if p.direction not in ('x', 'y'):      # a probe at any angle: turn its axis, from the node's (x, y)
            x, y = _clean_xy(samples, probes, p.node)
            a0, g0 = parse_probe_direction(p.direction)
            a = math.radians(a0) + self.angle
            out = np.array(samples, dtype=float, copy=True)
            out[:, i] = self.gain * g0 * (math.cos(a) * x + math.sin(a) * y)
            return out
        other = 'y' if p.direction == 'x' else 'x'
        j = next((k for k, q in enumerate(probes) if q.node == p.node and q.direction == other), None)
        if j is None:
            raise ValueError(f'probe orientation needs a {other} probe at node {p.node} in the recording')
        # perpendicular direction turned +90 deg from nominal: x -> +y, y -> -x
        perp = samples[:, j] if p.direction == 'x' else -samples[:, j]
        out = np.array(samples, dtype=float, copy=True)
        out[:, i] = self.gain * (math.cos(self.angle) * samples[:, i] + math.sin(self.angle) * perp)
        return out


@dataclass
class ProbePairOrientation:
    """
    An x/y probe pair mounted turned as a rigid pair, each probe with its own gain.

    The x/y probe pair at ``node`` is mounted turned by ``angle`` [rad] as a rigid pair (from +x towards +y), and
    each probe reads with its own gain: the x probe's axis is (cos a, sin a), the y probe's (-sin a, cos a), so

        reading_x = gain_x (cos a * x + sin a * y),     reading_y = gain_y (-sin a * x + cos a * y)

    with (x, y) the true (clean) displacement.  Both readings come from the clean signals of the pair (unlike two
    :class:`ProbeOrientation` in a row, where the second would see the first one's turned reading).
    """

    node: int
    angle: float = math.radians(10.0)
    gain_x: float = 1.0
    gain_y: float = 1.0

    def measure(self, samples, angle, speed, probes):
        ix = next((k for k, p in enumerate(probes) if p.node == self.node and p.direction == 'x'), None)
        iy = next((k for k, p in enumerate(probes) if p.node == self.node and p.direction == 'y'), None)
        if ix is None or iy is None:
            at = [k for k, p in enumerate(probes) if p.node == self.node]
            if len(at) < 2:
                raise ValueError(f'probe pair orientation needs two probes at node {self.node}')
            # any two non-parallel probes (e.g. +-45 deg): gain_x for the first, gain_y for the second
            x, y = _clean_xy(samples, probes, self.node)
            out = np.array(samples, dtype=float, copy=True)
            for k, g in zip(at[:2], (self.gain_x, self.gain_y)):
                a0, g0 = parse_probe_direction(probes[k].direction)
                a = math.radians(a0) + self.angle
                out[:, k] = g * g0 * (math.cos(a) * x + math.sin(a) * y)
            return out
        x, y = samples[:, ix].copy(), samples[:, iy].copy()
        ca, sa = math.cos(self.angle), math.sin(self.angle)
        out = np.array(samples, dtype=float, copy=True)
        out[:, ix] = self.gain_x * (ca * x + sa * y)
        out[:, iy] = self.gain_y * (-sa * x + ca * y)
        return out


def _clean_xy(samples, probes, node):
    """
    Return the clean (x, y) displacement (N,) each [m] of ``node`` from two non-parallel probes there.

    Solves the 2x2 system of their measurement rows (:func:`bearing_id.conventions.probe_row`).
    """
    at = [k for k, p in enumerate(probes) if p.node == node]
    for a in range(len(at)):
        for b in range(a + 1, len(at)):
            R = np.array([probe_row(probes[at[a]].direction), probe_row(probes[at[b]].direction)])
            if abs(np.linalg.det(R)) > 1e-6 * np.abs(R).max() ** 2:
                xy = np.linalg.solve(R, np.vstack([samples[:, at[a]], samples[:, at[b]]]))
                return xy[0], xy[1]
    raise ValueError(f'needs two non-parallel probes at node {node} to know its (x, y) displacement')


__all__ = ['SupportFlexibility', 'DiscMassError', 'ResidualUnbalance', 'ShaftBow', 'Misalignment', 'OilWhirl',
           'ProbeRunout', 'ProbeOrientation', 'ProbePairOrientation']
