"""
Global FE rotor model: assembly from the rig parameters, bearings, frequency response, state space, statics.

Equation of motion (see :mod:`bearing_id.conventions`)::

    M q'' + (C + Cb + Omega G) q' + (K + Kb) q = f,     q = [x1, y1, tx1, ty1, x2, ...]  (ndof = 4 n_nodes)

M, K, G, C are the rotor's (shaft elements + rigid discs); Kb, Cb the bearings' 2x2 blocks on (x, y) of each bearing
node, from ``coeffs = {node (1-based): (K (2,2) [N/m], C (2,2) [N s/m])}``.  Rotor damping is proportional to the
*shaft* matrices, C = alpha M_shaft + beta K_shaft (shaft.damping_alpha [1/s], shaft.damping_beta [s]); the rigid
discs add no damping (the same definition as ROSS's per-element alpha/beta).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .elements import DiscElement, ShaftElement
from ..conventions import dof_index, DOF_PER_NODE, GRAVITY, LOCAL_DOF, node_index
from ..params import RigParams


@dataclass(eq=False)
class RotorModel:
    """
    Assembled rotor (no bearings).  Arrays are SI; ``ndof = 4 n_nodes``.

    Attributes
    ----------
    n_nodes, ndof : ints.   node_z : (n_nodes,) axial node positions [m].
    M, K, G, C : (ndof, ndof) mass, stiffness, gyroscopic (per rad/s of spin) and rotor damping matrices.
    M_shaft, K_shaft : the shaft-only parts (for proportional damping and model updating).
    bearing_nodes : tuple of 1-based bearing node numbers.   rig : the RigParams it was built from (or None).
    elements : list of ShaftElement.   discs : dict {node: DiscElement}.

    """

    n_nodes: int
    node_z: np.ndarray
    M: np.ndarray
    K: np.ndarray
    G: np.ndarray
    C: np.ndarray
    M_shaft: np.ndarray
    K_shaft: np.ndarray
    bearing_nodes: tuple = ()
    rig: RigParams | None = None
    elements: list = field(default_factory=list)
    discs: dict = field(default_factory=dict)

    @property
    def ndof(self) -> int:
        return DOF_PER_NODE * self.n_nodes

    @cached_property
    def Minv(self) -> np.ndarray:
        """Inverse mass matrix (cached; M is constant)."""
        return np.linalg.inv(self.M)

    @classmethod
    def from_elements(cls, elements, discs=None, *, damping_alpha=0.0, damping_beta=0.0, bearing_nodes=(), rig=None):
        """Assemble ``elements`` (ShaftElement list; element i joins nodes i+1, i+2), ``discs`` {node: DiscElement}."""
        n_nodes = len(elements) + 1
        nd = DOF_PER_NODE * n_nodes
        Ms, Ks, G = np.zeros((nd, nd)), np.zeros((nd, nd)), np.zeros((nd, nd))
        for i, el in enumerate(elements):
            s = slice(DOF_PER_NODE * i, DOF_PER_NODE * i + 8)
            Ms[s, s] += el.M()
            Ks[s, s] += el.K()
            G[s, s] += el.G()
        M = Ms.copy()
        discs = dict(discs or {})
        for node, d in discs.items():
            i = DOF_PER_NODE * node_index(node, n_nodes)
            s = slice(i, i + 4)
            M[s, s] += d.M()
            G[s, s] += d.G()
        z = np.concatenate([[0.0], np.cumsum([el.length for el in elements])])
        C = damping_alpha * Ms + damping_beta * Ks
        return cls(n_nodes=n_nodes, node_z=z, M=M, K=Ks.copy(), G=G, C=C, M_shaft=Ms, K_shaft=Ks,
                   bearing_nodes=tuple(bearing_nodes), rig=rig, elements=list(elements), discs=discs)

    @classmethod
    def from_params(cls, rig: RigParams, *, shaft_mass_factor: float = 1.0, stiffness_factor: float = 1.0,
                    shear_method: str = 'hutchinson') -> 'RotorModel':
        """
        Build the model of ``rig``.

        Discs use ``params.Disc`` mass and inertias (which include the disc's ``mass_factor``).  The optional factors
        are the model-updating hooks: ``shaft_mass_factor`` scales the shaft density (translational and rotary
        inertia), ``stiffness_factor`` scales E (and G, so the shear parameter is unchanged).
        """
        sh = rig.shaft
        E = sh.youngs_modulus * stiffness_factor
        Gm = sh.shear_modulus * stiffness_factor
        rho = sh.density * shaft_mass_factor
        els = [ShaftElement(le, sh.diameter, sh.inner_diameter, E, Gm, rho, shear_method=shear_method)
               for le in sh.element_lengths]
        discs = {}
        for d in rig.discs:
            el = DiscElement(d.mass, d.diametral_inertia, d.polar_inertia)
            if d.node in discs:  # two discs on one node add up
                o = discs[d.node]
                el = DiscElement(o.m + el.m, o.Id + el.Id, o.Ip + el.Ip)
            discs[d.node] = el
        return cls.from_elements(els, discs, damping_alpha=sh.damping_alpha, damping_beta=sh.damping_beta,
                                 bearing_nodes=rig.bearing_nodes(), rig=rig)

    @property
    def mass(self) -> float:
        """Total rotor mass [kg] (shaft + discs)."""
        u = np.zeros(self.ndof)
        u[0::DOF_PER_NODE] = 1.0
        return float(u @ self.M @ u)


# ------------------------------------------------------------------------------------------------- bearings
def _xy_index(model: RotorModel, node: int) -> int:
    return dof_index(node, 'x', model.n_nodes)


def add_bearings(model: RotorModel, K: np.ndarray, C: np.ndarray, coeffs: dict) -> None:
    """Add the bearing blocks of ``coeffs`` {node: (Kb, Cb)} in place to global ``K`` and ``C`` (ndof, ndof)."""
    for node, (kb, cb) in coeffs.items():
        i = _xy_index(model, node)
        K[i:i + 2, i:i + 2] += kb
        C[i:i + 2, i:i + 2] += cb


def bearing_matrices(model: RotorModel, coeffs: dict) -> tuple[np.ndarray, np.ndarray]:
    """Global bearing stiffness and damping (ndof, ndof) [N/m, N s/m] from ``coeffs``."""
    Kb = np.zeros((model.ndof, model.ndof))
    Cb = np.zeros((model.ndof, model.ndof))
    add_bearings(model, Kb, Cb, coeffs)
    return Kb, Cb


def system_matrices(model: RotorModel, speed: float, coeffs: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, C + Cb + speed G, K + Kb) of the rotor on its bearings at ``speed`` [rad/s]."""
    K = model.K.copy()
    C = model.C + speed * model.G
    add_bearings(model, K, C, coeffs)
    return model.M, C, K


# ------------------------------------------------------------------------------------------------- responses
def dynamic_stiffness(model: RotorModel, speed: float, omega: float, coeffs: dict) -> np.ndarray:
    """
    Z = K + Kb - omega^2 M + j omega (C + Cb + speed G), complex (ndof, ndof).

    ``speed`` is the spin speed [rad/s], ``omega`` the excitation frequency [rad/s] (= speed for 1X).
    """
    M, C, K = system_matrices(model, speed, coeffs)
    return K - omega * omega * M + 1j * omega * C


def harmonic_response(model: RotorModel, speed: float, omega: float, F, coeffs: dict) -> np.ndarray:
    """Displacement phasors q = Z^-1 F [m, rad] for force phasors F (ndof,) or (ndof, k) [N] at ``omega`` [rad/s]."""
    return np.linalg.solve(dynamic_stiffness(model, speed, omega, coeffs), np.asarray(F, dtype=complex))


def state_space(model: RotorModel, speed: float, coeffs: dict) -> tuple[np.ndarray, np.ndarray]:
    """Continuous state space x' = A x + B f with x = [q; q'] (2 ndof) and B = [0; M^-1] (2 ndof, ndof)."""
    _, C, K = system_matrices(model, speed, coeffs)
    n = model.ndof
    Mi = model.Minv
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -Mi @ K
    A[n:, n:] = -Mi @ C
    B = np.zeros((2 * n, n))
    B[n:] = Mi
    return A, B


def probe_matrix(model: RotorModel, probes) -> np.ndarray:
    """
    Return the selection matrix (nch, ndof) picking each probe's DOF.

    ``probes`` are params.Probe or (node, direction).
    """
    probes = list(probes)
    S = np.zeros((len(probes), model.ndof))
    for i, p in enumerate(probes):
        node, direction = (p.node, p.direction) if hasattr(p, 'node') else p
        S[i, dof_index(node, direction, model.n_nodes)] = 1.0
    return S


# ------------------------------------------------------------------------------------------------- statics
def static_bearing_loads(model: RotorModel, bearing_nodes=None) -> dict[int, float]:
    """
    Weight carried by each bearing [N] (positive = the bearing pushes the shaft up), gravity along -y.

    The bearings are rigid vertical supports; the statics is solved in the vertical plane (y, tx) with the
    consistent gravity load f = -g M u_y, so the reactions satisfy force and moment balance exactly (two supports:
    the lever rule, independent of the shaft stiffness).
    """
    nodes = tuple(bearing_nodes if bearing_nodes is not None else model.bearing_nodes)
    if len(nodes) < 2:
        raise ValueError('static bearing loads need at least two bearings (the vertical plane must be supported)')
    n = model.n_nodes
    plane = np.sort(np.concatenate([np.arange(n) * DOF_PER_NODE + LOCAL_DOF['y'],
                                    np.arange(n) * DOF_PER_NODE + LOCAL_DOF['tx']]))
    uy = np.zeros(model.ndof)
    uy[LOCAL_DOF['y']::DOF_PER_NODE] = 1.0
    f = -GRAVITY * (model.M @ uy)
    sup = np.array([dof_index(b, 'y', n) for b in nodes])
    free = np.setdiff1d(plane, sup)
    K = model.K
    qf = np.linalg.solve(K[np.ix_(free, free)], f[free])
    r = K[np.ix_(sup, free)] @ qf - f[sup]
    return {int(b): float(v) for b, v in zip(nodes, r)}


__all__ = ['RotorModel', 'add_bearings', 'bearing_matrices', 'system_matrices', 'dynamic_stiffness',
           'harmonic_response', 'state_space', 'probe_matrix', 'static_bearing_loads']
