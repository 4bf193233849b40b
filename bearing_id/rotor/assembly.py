"""
Global FE rotor model: assembly from the rig parameters, bearings, frequency response, state space, statics.

Equation of motion (see :mod:`bearing_id.conventions`)::

    M q'' + (C + Cb + Omega G) q' + (K + Kb) q = f,     q = [x1, y1, tx1, ty1, x2, ...]  (ndof = 4 n_nodes)

M, K, G, C are the rotor's (shaft elements + rigid discs); Kb, Cb the bearings' 2x2 blocks on (x, y) of each bearing
node, from ``coeffs = {node (1-based): (K (2,2) [N/m], C (2,2) [N s/m])}``.  Rotor damping is proportional to the
*shaft* matrices, C = alpha M_shaft + beta K_shaft (shaft.damping_alpha [1/s], shaft.damping_beta [s]); the rigid
discs add no damping (the same definition as ROSS's per-element alpha/beta).

Model contents
    * shaft elements per section (own E, G, density, mass-only added layers, full concentric ``layers`` with their
      own phi, a per-element shear coefficient), the shear coefficient option, discs by
      m/Ip/Id and point masses (rigid :class:`DiscElement` at their node);
    * known elements -- seals and bearings with ``identify: false`` -- are part of the model: their speed-dependent
      K, C are added by :func:`system_matrices` (so ``coeffs`` carries only the identified bearings);
    * a bearing's ``support`` (pedestal) adds two DOFs (x, y of the pedestal mass) after the rotor's 4 n_nodes DOFs,
      in the order of ``model.pedestals``; the film then acts between the shaft node and the pedestal (in series),
      the pedestal sits on its spring and damper to ground.  ``ndof = 4 n_nodes + 2 n_pedestals``.
    * probes at any angle: :func:`probe_matrix` rows from :func:`bearing_id.conventions.probe_row`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .elements import DiscElement, ShaftElement
from ..bearings import solution
from ..config.params import RigParams
from ..conventions import dof_index, DOF_PER_NODE, GRAVITY, LOCAL_DOF, node_index, probe_row


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
    pedestals: dict = field(default_factory=dict)      # {key: global index of the pedestal's x DOF}; key = node of
    #                                                     an identified bearing or ('known', i) of known element i
    known: tuple = ()                                  # known elements (params.Bearing: seals, identify=false)
    n_extra: int = 0                                   # pedestal DOFs after the rotor's 4 n_nodes
    support_nodes: tuple = ()                          # every load-carrying bearing node (statics)
    gravity: float = GRAVITY                           # |g| [m/s^2] for statics

    @property
    def ndof(self) -> int:
        return DOF_PER_NODE * self.n_nodes + self.n_extra

    @property
    def rotor_ndof(self) -> int:
        """Return the number of the rotor's own DOFs (4 n_nodes); pedestal DOFs follow them."""
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
                    shear_method=None) -> 'RotorModel':
        """
        Build the model of ``rig``.

        Discs use ``params.Disc`` mass and inertias (which include the disc's ``mass_factor``); point masses are rigid
        discs.  The optional factors are the model-updating hooks: ``shaft_mass_factor`` scales the shaft density
        (translational and rotary inertia, added layers too), ``stiffness_factor`` scales E (and G, so the shear
        parameter is unchanged).  ``shear_method`` overrides ``rig.shaft.shear_coefficient`` and every element's and
        layer's own ``shear_coefficient``.  An element's ``layers`` are full concentric elements on its two nodes
        (:class:`ShaftElement` ``layers``): their M, K, G are added, and the rotor damping C = alpha M_shaft + beta
        K_shaft includes them.
        """
        sh = rig.shaft
        shear = sh.shear_coefficient if shear_method is None else shear_method
        if not sh.elements:
            E = sh.youngs_modulus * stiffness_factor
            Gm = sh.shear_modulus * stiffness_factor
            rho = sh.density * shaft_mass_factor
            els = [ShaftElement(le, sh.diameter, sh.inner_diameter, E, Gm, rho, shear_method=shear)
                   for le in sh.element_lengths]
        else:
            fm = shaft_mass_factor * sh.density / sh.reference_density
            fe = stiffness_factor * sh.youngs_modulus / sh.reference_modulus

            def own(x):       # an element's or layer's shear coefficient: its own, else the shaft's (or the override)
                return x.shear_coefficient if shear_method is None and x.shear_coefficient is not None else shear

            els = [ShaftElement(e.length, e.outer_diameter, e.inner_diameter, e.youngs_modulus * fe,
                                e.shear_modulus * fe, e.density * fm, shear_method=own(e),
                                added_mass=[(a.mass_per_length * fm, a.inertia_per_length * fm) for a in e.added_mass],
                                layers=[ShaftElement(e.length, la.outer_diameter, la.inner_diameter,
                                                     la.youngs_modulus * fe, la.shear_modulus * fe, la.density * fm,
                                                     shear_method=own(la)) for la in e.layers])
                   for e in sh.elements]
        discs = {}
        rigid = [(d.node, DiscElement(d.mass, d.diametral_inertia, d.polar_inertia)) for d in rig.discs]
        rigid += [(p.node, DiscElement(p.mass, p.Id, p.Ip)) for p in getattr(rig, 'point_masses', ())]
        for node, el in rigid:
            if node in discs:  # two discs on one node add up
                o = discs[node]
                el = DiscElement(o.m + el.m, o.Id + el.Id, o.Ip + el.Ip)
            discs[node] = el
        model = cls.from_elements(els, discs, damping_alpha=sh.damping_alpha, damping_beta=sh.damping_beta,
                                  bearing_nodes=rig.bearing_nodes(), rig=rig)
        known = tuple(rig.known_elements()) if hasattr(rig, 'known_elements') else ()
        model.known = known
        model.support_nodes = tuple(rig.support_nodes()) if hasattr(rig, 'support_nodes') else rig.bearing_nodes()
        g = getattr(rig, 'gravity', None)
        model.gravity = GRAVITY if g is None or tuple(g) == (0.0, -GRAVITY) else float(np.hypot(*g))
        peds = [(b.node, b.support) for b in rig.bearings if b.support is not None]
        peds += [(('known', i), b.support) for i, b in enumerate(known) if b.support is not None]
        if peds:
            model._add_pedestals(peds)
        return model

    def _add_pedestals(self, peds) -> None:
        """Append 2 DOFs (x, y) per pedestal: mass on M, spring to ground on K, damper to ground on C."""
        n0 = self.ndof
        nd = n0 + 2 * len(peds)

        def grow(a):
            out = np.zeros((nd, nd))
            out[:n0, :n0] = a
            return out

        self.M, self.K, self.G, self.C = grow(self.M), grow(self.K), grow(self.G), grow(self.C)
        self.M_shaft, self.K_shaft = grow(self.M_shaft), grow(self.K_shaft)
        for k, (key, sup) in enumerate(peds):
            j = n0 + 2 * k
            self.pedestals[key] = j
            for a in range(2):
                self.M[j + a, j + a] += sup.mass[a]
                self.K[j + a, j + a] += sup.stiffness[a]
                self.C[j + a, j + a] += sup.damping[a]
        self.n_extra = nd - DOF_PER_NODE * self.n_nodes
        self.__dict__.pop('Minv', None)

    def known_coefficients(self, speed: float) -> list:
        """
        Return the known elements' coefficients at ``speed`` [rad/s]: [(node, pedestal index or None, K, C)].

        Seals and ``identify: false`` bearings (table, short or finite), evaluated with :mod:`bearing_id.bearings`.
        """
        if not self.known:
            return []
        fn = self.__dict__.get('_known_fn')
        if fn is None:
            fn = self.__dict__['_known_fn'] = known_fn(self)
        return [(b.node, self.pedestals.get(('known', i)), K, C) for i, (b, (K, C)) in enumerate(zip(self.known,
                                                                                                     fn(speed)))]

    @property
    def mass(self) -> float:
        """Total rotor mass [kg] (shaft + discs)."""
        u = np.zeros(self.ndof)
        u[0:self.rotor_ndof:DOF_PER_NODE] = 1.0
        return float(u @ self.M @ u)


# ------------------------------------------------------------------------------------------------- bearings
def _xy_index(model: RotorModel, node: int) -> int:
    return dof_index(node, 'x', model.n_nodes)


def _add_between(X, i, j, B) -> None:
    """Add a 2x2 block ``B`` (..., 2, 2) in place to ``X`` (..., n, n) between DOF pairs i and j (None = ground)."""
    X[..., i:i + 2, i:i + 2] += B
    if j is not None:
        X[..., j:j + 2, j:j + 2] += B
        X[..., i:i + 2, j:j + 2] -= B
        X[..., j:j + 2, i:i + 2] -= B


def _add_film(K, C, i, j, kb, cb) -> None:
    """Add a film (kb, cb) between DOF pair i (shaft x, y) and j (pedestal x, y; None = ground)."""
    _add_between(K, i, j, kb)
    _add_between(C, i, j, cb)


def film_dofs(model: RotorModel, node: int) -> tuple:
    """
    Return (i, j) of an identified bearing's film: i = x DOF of the shaft node, j = x DOF of its pedestal or None.

    The film force acts on the relative displacement q[i:i+2] - q[j:j+2] (q[i:i+2] without a pedestal).
    """
    return _xy_index(model, node), (model.pedestals.get(node) if model.pedestals else None)


def add_film_impedance(model: RotorModel, Z: np.ndarray, node: int, Zb: np.ndarray) -> None:
    """
    Add a bearing's complex 2x2 impedance ``Zb`` = K + j omega C in place to a dynamic stiffness ``Z``.

    At the shaft node's (x, y), or between the shaft node and its pedestal when the bearing has one (``film_dofs``).
    Stacks work alike: ``Z`` (..., ndof, ndof) with ``Zb`` (..., 2, 2).
    """
    _add_between(Z, *film_dofs(model, node), Zb)


def add_bearings(model: RotorModel, K: np.ndarray, C: np.ndarray, coeffs: dict) -> None:
    """
    Add the bearing blocks of ``coeffs`` {node: (Kb, Cb)} in place to global ``K`` and ``C`` (ndof, ndof).

    A bearing on a pedestal (``model.pedestals``) acts between the shaft node and the pedestal mass.
    """
    peds = model.pedestals
    for node, (kb, cb) in coeffs.items():
        _add_film(K, C, _xy_index(model, node), peds.get(node) if peds else None, kb, cb)


def add_known(model: RotorModel, K: np.ndarray, C: np.ndarray, speed: float) -> None:
    """Add the known elements (seals, identify=false bearings) at ``speed`` [rad/s] in place to ``K`` and ``C``."""
    for node, j, kb, cb in model.known_coefficients(speed):
        _add_film(K, C, _xy_index(model, node), j, kb, cb)


def bearing_matrices(model: RotorModel, coeffs: dict) -> tuple[np.ndarray, np.ndarray]:
    """Global bearing stiffness and damping (ndof, ndof) [N/m, N s/m] from ``coeffs``."""
    Kb = np.zeros((model.ndof, model.ndof))
    Cb = np.zeros((model.ndof, model.ndof))
    add_bearings(model, Kb, Cb, coeffs)
    return Kb, Cb


def system_matrices(model: RotorModel, speed: float, coeffs: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, C + Cb + speed G, K + Kb) of the rotor on its bearings (and known elements) at ``speed`` [rad/s]."""
    K = model.K.copy()
    C = model.C + speed * model.G
    add_bearings(model, K, C, coeffs)
    if model.known:
        add_known(model, K, C, speed)
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


def first_order(Minv: np.ndarray, C: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Return A = [[0, I], [-M^-1 K, -M^-1 C]] (2n, 2n) of M q'' + C q' + K q = f, from M^-1, C, K (n, n)."""
    n = Minv.shape[0]
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -Minv @ K
    A[n:, n:] = -Minv @ C
    return A


def state_space(model: RotorModel, speed: float, coeffs: dict) -> tuple[np.ndarray, np.ndarray]:
    """Continuous state space x' = A x + B f with x = [q; q'] (2 ndof) and B = [0; M^-1] (2 ndof, ndof)."""
    _, C, K = system_matrices(model, speed, coeffs)
    n = model.ndof
    B = np.zeros((2 * n, n))
    B[n:] = model.Minv
    return first_order(model.Minv, C, K), B


def measurement_row(model: RotorModel, node: int, direction) -> np.ndarray:
    """
    Return the measurement row (ndof,) of one probe: it reads row @ q [m].

    ``direction`` is 'x', 'y', 'tx', 'ty' (one DOF) or a probe direction text / angle [deg] (see
    :func:`bearing_id.conventions.probe_row`: gain (cos a, sin a) on (x, y) of ``node``).
    """
    row = np.zeros(model.ndof)
    if direction in ('tx', 'ty'):
        row[dof_index(node, direction, model.n_nodes)] = 1.0
        return row
    cx, cy = probe_row(direction)
    i = dof_index(node, 'x', model.n_nodes)
    row[i] = cx
    row[i + 1] = cy
    return row


def probe_matrix(model: RotorModel, probes) -> np.ndarray:
    """
    Return the measurement matrix (nch, ndof): row i reads probe i (:func:`measurement_row`).

    ``probes`` are params.Probe or (node, direction); an x or y probe's row picks its DOF exactly (1.0).
    """
    probes = list(probes)
    S = np.zeros((len(probes), model.ndof))
    for i, p in enumerate(probes):
        node, direction = (p.node, p.direction) if hasattr(p, 'node') else p
        S[i] = measurement_row(model, node, direction)
    return S


# ------------------------------------------------------------------------------------------------- statics
def _gravity_statics(model: RotorModel, bearing_nodes=None) -> tuple:
    """Return (q (ndof,) [m, rad], supports, reactions [N]) of the shaft under its weight on rigid supports."""
    nodes = tuple(bearing_nodes if bearing_nodes is not None else model.bearing_nodes)
    nodes += tuple(n for n in model.support_nodes if n not in nodes)
    if len(nodes) < 2:
        raise ValueError('the statics needs at least two bearings (the vertical plane must be supported)')
    n = model.n_nodes
    plane = np.sort(np.concatenate([np.arange(n) * DOF_PER_NODE + LOCAL_DOF['y'],
                                    np.arange(n) * DOF_PER_NODE + LOCAL_DOF['tx']]))
    uy = np.zeros(model.ndof)
    uy[LOCAL_DOF['y']:model.rotor_ndof:DOF_PER_NODE] = 1.0
    f = -model.gravity * (model.M @ uy)
    sup = np.array([dof_index(b, 'y', n) for b in nodes])
    free = np.setdiff1d(plane, sup)
    K = model.K
    q = np.zeros(model.ndof)
    q[free] = np.linalg.solve(K[np.ix_(free, free)], f[free])
    r = K[np.ix_(sup, free)] @ q[free] - f[sup]
    return q, nodes, r


def static_bearing_loads(model: RotorModel, bearing_nodes=None) -> dict[int, float]:
    """
    Weight carried by each bearing [N] (positive = the bearing pushes the shaft against gravity).

    The bearings are rigid supports; the statics is solved in one bending plane (y, tx) with the consistent gravity
    load f = -|g| M u_y, so the reactions satisfy force and moment balance exactly (two supports: the lever rule,
    independent of the shaft stiffness).  The reactions act along -gravity (the planes are alike).  Known bearings
    (``identify: false``) are supports too: ``model.support_nodes`` are added to ``bearing_nodes``.
    """
    _, nodes, r = _gravity_statics(model, bearing_nodes)
    return {int(b): float(v) for b, v in zip(nodes, r)}


def static_sag(model: RotorModel, bearing_nodes=None) -> np.ndarray:
    """
    Return the shaft's static deflection under its own weight, q (ndof,) [m, rad], on rigid supports.

    Zero at the bearings.  The shaft's bending (what a crack sees) does not depend on the support stiffness when two
    bearings carry it (statically determinate); with more, rigid supports are the approximation.
    """
    return _gravity_statics(model, bearing_nodes)[0]


def known_fn(model):
    """
    Return ``fn(speed [rad/s]) -> [(K, C), ...]`` of ``model.known`` (seals, ``identify: false`` bearings), cached.

    Short/finite known bearings carry their ``load`` or their share of the weight (statics with every support).
    """
    known = tuple(model.known)
    loads = {}
    if any(b.model != 'table' and b.load is None for b in known):
        loads = static_bearing_loads(model)
    cache: dict = {}

    def fn(speed):
        key = float(speed)
        out = cache.get(key)
        if out is None:
            out = []
            for b in known:
                if b.model == 'table':
                    s = solution(b, key, 0.0)
                else:
                    s = solution(b, key, b.load if b.load is not None else loads[b.node])
                out.append((s.K, s.C))
            if len(cache) > 4096:
                cache.clear()
            cache[key] = out
        return out
    return fn


__all__ = ['RotorModel', 'film_dofs', 'add_film_impedance', 'add_bearings', 'add_known', 'bearing_matrices',
           'system_matrices', 'dynamic_stiffness', 'harmonic_response', 'state_space', 'measurement_row',
           'probe_matrix', 'static_bearing_loads', 'static_sag', 'known_fn']
