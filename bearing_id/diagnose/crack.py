"""
A breathing transverse crack under gravity: the candidate effect and its physics.

A crack in a shaft element is a local rotational compliance that acts only while the crack is open.  The cracked
element's internal force is that of the healthy element with an imposed kink (relative rotation) ``phi`` at the crack
(Dimarogonas & Papadopoulos 1983; the equivalent-load form of the breathing crack models in Gasch 1993 and Mayes &
Davies 1984)::

    phi(t) = c  g(t)  M(t)                 the kink [rad] in the crack's bending direction,
    F_crack = K_e d(phi)                    the equivalent nodal load [N, N m] on the element's DOFs,

with ``c`` the open crack's rotational compliance [rad/(N m)], ``M`` the bending moment at the crack and ``g`` the
breathing function (Mayes: g = (1 + cos(angle from fully open)) / 2).  When the shaft's weight dominates (the static
sag moment M_s is larger than the dynamic one: "gravity dominated"), M is the static moment seen from the rotating
crack, so the kink -- and the force -- are periodic in the shaft angle with orders 1X, 2X and 3X of *constant
amplitude*: independent of the speed (a force spectrum fixed to the key mark, not ``m r Omega^2``) and of the
unbalance (the same in every run).  Through the rotor's receptance at 2 Omega and 3 Omega the response grows near
half and a third of a critical speed -- the crack's classic signature.

Fit (:class:`BreathingCrack`): at the element, the kink's x- and y-plane components at 1X, 2X and 3X are free complex
numbers (12 linear parameters [urad]); the breathing model is used for the *size*: with Mayes breathing and a crack
bending in one direction, the kink in the plane of the static moment has a 2X component of c M_s / 4 (the Fourier
coefficient of g(a) cos^2(a) at 2a), so ``c = 4 |phi_2X| / |M_s|`` with M_s from the shaft's sag on rigid supports.
(The horizontal plane's 2X kink is c M_s / 4 too when the crack's stiffness loss turns with it -- a circular 2X --
and zero in models that keep only the direct terms, as ROSS's Mayes crack does; the sag plane's is the same in both.)
Other breathing laws (a switching crack, Gasch) give another factor; the breathing law is not identified from 1X-3X
alone, so the compliance is stated for the Mayes law.  The crack also softens the shaft on average (the open crack's
stiffness loss, averaged over a turn, acts on every response: a lower critical speed); that mean compliance is the
effect's one nonlinear parameter, ``c_mean`` in units of the element's L/(E I), entering the dynamic stiffness as
(Sherman-Morrison for a hinge of compliance c in each bending plane, Mayes average 1/4 of the open loss)::

    Z -= 1/4 sum_planes c P P^T / (1 + c P^T d),      P = K_e d (the kink's load), d the unit kink's displacement

Its agreement with the compliance from the 2X kink is a check of the crack model (both are printed).  The crack depth
a / D is the one whose open-crack compliance c55 (Papadopoulos & Dimarogonas' law for a straight-front crack in a
solid round shaft, :mod:`bearing_id.diagnose.crack_flexibility`) is the compliance from the 2X kink; with its
1-sigma propagated from the kinks' it is reported not determined with the compliance, and not at all on a hollow
shaft.  Element nodes are 1-based; phasors as in :mod:`bearing_id.conventions`.
"""
from __future__ import annotations

import math

import numpy as np

from .crack_flexibility import crack_depth_ratio
from .effect import determined, Effect, pm
from ..conventions import DOF_PER_NODE
from ..rotor.assembly import RotorModel, static_sag

ORDERS = (1.0, 2.0, 3.0)
UNIT = 1e-6               # the linear parameters are kinks in micro-radians (the numerical Jacobians well scaled)
SIGNATURE_SIGMA = 4.0     # the 2X and 3X kinks must both exceed this many sigma ...
SIGNATURE_3X = (0.1, 2.0)  # ... and the 3X be this fraction of the 2X (Mayes 0.5; a switching crack 2/3 ... 1)
MAYES_2X = 0.25           # 2X Fourier coefficient of (1 + cos a)/2 cos^2 a: the 2X kink per c M_s (Mayes breathing)


def unit_kink(length: float, plane: str) -> np.ndarray:
    """
    Return the element's nodal displacement (8,) [m, rad] of a rigid unit kink [rad] at its middle.

    Node a still, node b displaced by L/2 and turned by one radian of slope dx/dz (``plane`` 'x') or dy/dz ('y');
    tx = -dy/dz and ty = dx/dz as in the FE model.
    """
    d = np.zeros(2 * DOF_PER_NODE)
    if plane == 'x':
        d[DOF_PER_NODE + 0], d[DOF_PER_NODE + 3] = 0.5 * length, 1.0
    else:
        d[DOF_PER_NODE + 1], d[DOF_PER_NODE + 2] = 0.5 * length, -1.0
    return d


def kink_patterns(model, element: int) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the equivalent nodal loads (ndof,) [N, N m] of a unit kink [rad] at the middle of ``element`` (1-based).

    (P_x, P_y) = K_e d for the kink turning dx/dz or dy/dz (:func:`unit_kink`); they do not depend on where the
    element sits (K_e d is the same for any rigid motion added to d).
    """
    el = model.elements[element - 1]
    Ke = el.K()
    i0 = DOF_PER_NODE * (element - 1)
    out = []
    for plane in ('x', 'y'):
        P = np.zeros(model.ndof)
        P[i0:i0 + 2 * DOF_PER_NODE] = Ke @ unit_kink(el.length, plane)
        out.append(P)
    return out[0], out[1]


def sag_moment(model, element: int, sag: np.ndarray | None = None) -> float:
    """
    Return the static bending moment [N m] at the middle of ``element`` from the shaft's weight (y-z plane).

    The load conjugate to a unit y-plane kink there (the virtual work of the element's end forces and of its own
    weight on the kinked element): d . (K_e q_e - f_e) + W, with q_e the element's part of the sag (``sag``, (ndof,)
    [m, rad]: :func:`bearing_id.rotor.assembly.static_sag`, computed when not given), f_e the element's consistent
    weight load (K_e q_e - f_e are the end forces) and W = -g m' L^2 / 8 the work of the weight of the half beyond
    the kink.  Its sign is that of the kink that would lower the sag.
    """
    el = model.elements[element - 1]
    q = static_sag(model) if sag is None else sag
    i0 = DOF_PER_NODE * (element - 1)
    u_y = np.zeros(2 * DOF_PER_NODE)
    u_y[[1, DOF_PER_NODE + 1]] = 1.0
    f_e = -model.gravity * (el.M() @ u_y)
    d = unit_kink(el.length, 'y')
    W = -model.gravity * el.mass_per_length * el.length ** 2 / 8
    return float(d @ (el.K() @ q[i0:i0 + 2 * DOF_PER_NODE] - f_e) + W)


class BreathingCrack(Effect):
    """
    A breathing crack in shaft ``element`` (1-based; between nodes ``element`` and ``element + 1``), gravity dominated.

    Linear parameters: the kink at the crack [urad] per order (1X, 2X, 3X) and plane (x, y), complex -- 12 reals.
    ``physical`` gives the kinks per order in the sag plane (``kink_2x``) and across it (``kink_2x_cross``) [rad],
    the open crack's rotational compliance for Mayes breathing [rad/(N m)] (see the module docstring), its ratio
    to the element's own bending compliance L/(E I) and the crack depth a / D it means (``depth_ratio``; NaN on a
    hollow shaft or beyond the law's range).
    """

    name = 'breathing_crack'
    n_lin = 4 * len(ORDERS)
    acts_on_1x = True
    only_1x = False           # its 2X and 3X
    key = 'compliance'
    nl_names = ('c_mean',)
    nl_lo = (0.0,)
    nl_hi = (5.0,)

    def __init__(self, model, element: int, sag: np.ndarray | None = None):
        super().__init__()
        self.element = int(element)
        self.where = f'shaft element {element} (nodes {element}-{element + 1})'
        Px, Py = kink_patterns(model, self.element)
        self.moment = sag_moment(model, self.element, sag)          # N m
        el = model.elements[self.element - 1]
        self.element_compliance = el.length / (el.E * el.inertia)          # rad/(N m)
        self._section = (el.outer_d, el.inner_d, el.E, el.E / (2.0 * el.G_mod) - 1.0)   # m, m, Pa, Poisson's ratio
        i0 = DOF_PER_NODE * (self.element - 1)
        self._span = slice(i0, i0 + 2 * DOF_PER_NODE)
        self._PPt = sum(np.outer(P[self._span], P[self._span]) for P in (Px, Py))      # (8, 8)
        d = unit_kink(el.length, 'y')
        self._kink_stiffness = float(d @ el.K() @ d)       # P^T d [N m/rad]: the element's own stiffness to a kink
        self._cols = {}
        for o, r in enumerate(ORDERS):
            C = np.zeros((model.ndof, self.n_lin), complex)
            C[:, 4 * o:4 * o + 4] = UNIT * np.column_stack([Px, 1j * Px, Py, 1j * Py])
            self._cols[r] = C

    @property
    def starts(self):
        return [np.array([0.0])]

    def add_dZ(self, prob, Z, speed, omega, nl):
        """Subtract the mean softening (``nl[0]`` x L/(E I) of compliance, Mayes average) from Z (ndof, ndof)."""
        c = float(nl[0]) * self.element_compliance
        if c > 0:
            Z[self._span, self._span] -= 0.25 * c / (1.0 + c * self._kink_stiffness) * self._PPt

    def force_columns(self, prob, k, ratio, nl):
        return self._cols.get(float(ratio))

    def physical(self, nl, lin):
        """Return the kinks [rad] per order and plane, the compliance [rad/(N m)] and its ratios to L/(E I)."""
        lin = np.asarray(lin, float)
        out = {}
        for o, r in enumerate(ORDERS):
            kx = UNIT * complex(lin[4 * o], lin[4 * o + 1])
            ky = UNIT * complex(lin[4 * o + 2], lin[4 * o + 3])
            out[f'kink_{r:g}x'] = abs(ky)              # in the sag plane (y-z): Mayes 2X = c M_s / 4 with or
            out[f'kink_{r:g}x_cross'] = abs(kx)        # without the cross-plane term (a circular or a line 2X)
            out[f'x{r:g}_re'], out[f'x{r:g}_im'] = kx.real, kx.imag
            out[f'y{r:g}_re'], out[f'y{r:g}_im'] = ky.real, ky.imag
        c = out['kink_2x'] / (MAYES_2X * abs(self.moment)) if self.moment else math.inf
        out['compliance'] = c
        out['relative_compliance'] = c / self.element_compliance
        out['mean_relative_compliance'] = float(nl[0])
        out['depth_ratio'] = crack_depth_ratio(c, *self._section)
        return out

    def missing_signature(self, phys, std):
        """Return why the fit is not a crack: under its sag a crack has a 3X beside its 2X (Mayes: half of it)."""
        k2, k3 = phys['kink_2x'], phys['kink_3x']
        s2, s3 = std.get('kink_2x', math.inf), std.get('kink_3x', math.inf)
        if not (k2 > SIGNATURE_SIGMA * s2 and k3 > SIGNATURE_SIGMA * s3):      # (a magnitude of 2 normal reals:
            #                                                      beyond 4 sigma by chance with probability e^-8)
            return (f'no significant 2X and 3X kink (2X {k2 * 1e6:.3g} ± {s2 * 1e6:.2g} µrad, 3X {k3 * 1e6:.3g} ± '
                    f'{s3 * 1e6:.2g} µrad): a crack under its own weight shows both')
        if not SIGNATURE_3X[0] <= k3 / k2 <= SIGNATURE_3X[1]:
            return (f'its 3X kink is {k3 / k2:.2g} of the 2X one, outside {SIGNATURE_3X[0]:g}-{SIGNATURE_3X[1]:g} '
                    f'(a breathing crack: about 0.5): a 2X source of another kind')
        return None

    def undetermined(self, phys, std):
        names = ('compliance',) if self._section[1] > 0 else ('compliance', 'depth_ratio')
        return [p for p in names if not determined(phys[p], std.get(p))]

    def _depth_words(self, phys, std) -> str:
        """Return the crack depth clause of the sentence (not determined, or outside the law, said so)."""
        a = phys['depth_ratio']
        if self._section[1] > 0:
            return 'crack depth not given (the compliance law is for a solid shaft)'
        if not math.isfinite(a):
            return 'crack depth beyond the compliance law (deeper than the shaft centre, a/D > 0.5)'
        law = "Papadopoulos & Dimarogonas' c55 for a straight-front crack"
        if 'depth_ratio' in self.undetermined(phys, std):
            sd = std.get('depth_ratio', math.inf)
            fit = f' (fit a/D {a:.3g}, 1σ {sd:.2g})' if math.isfinite(sd) else ''
            return f'crack depth not determined by these data{fit}; {law}'
        return f"crack depth a/D ≈ {a:.3g}{pm(a, std.get('depth_ratio'))} of the diameter ({law})"

    def sentence(self, phys, std):
        k = '/'.join(f"{phys[f'kink_{r:g}x'] * 1e6:.3g}" for r in ORDERS)
        c, cm = phys['compliance'], phys['mean_relative_compliance']
        return (f'breathing crack in {self.where}: open-crack rotational compliance {c:.3g} rad/(N·m)'
                f"{pm(c, std.get('compliance'))} ({phys['relative_compliance']:.3g} of the element's L/EI; Mayes "
                f'breathing under the static sag moment {abs(self.moment):.3g} N·m; from the mean softening {cm:.3g}'
                f"{pm(cm, std.get('mean_relative_compliance'))} of L/EI); {self._depth_words(phys, std)}; sag-plane "
                f'kink 1X/2X/3X {k} µrad, fixed to the key mark at every speed and in every run (a slow roll would '
                f'show it: the sag is there at any speed)')

    def to_extra(self, phys):
        keys = [f'{p}{r:g}_{c}' for r in ORDERS for p in 'xy' for c in ('re', 'im')]
        return {'effect': self.name, 'element': self.element, 'c_mean': float(phys['mean_relative_compliance']),
                **{k: float(phys[k]) for k in keys}}

    @classmethod
    def from_extra(cls, d, rig):
        lin = np.array([d[f'{p}{r:g}_{c}'] / UNIT for r in ORDERS for p in 'xy' for c in ('re', 'im')])
        return (cls(RotorModel.from_params(rig), int(d['element'])), np.array([float(d.get('c_mean', 0.0))]), lin)


def crack_elements(model) -> list[int]:
    """Return the shaft elements (1-based) between the outermost bearings (an overhang's sag moment is not tried)."""
    b = sorted(model.bearing_nodes)
    if len(b) < 2:
        return []
    return list(range(b[0], b[-1]))


__all__ = ['BreathingCrack', 'unit_kink', 'kink_patterns', 'sag_moment', 'crack_elements', 'ORDERS', 'MAYES_2X']
