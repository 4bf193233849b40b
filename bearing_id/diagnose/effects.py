"""
Candidate physics the nominal model may have left out, as parametric augmentations (the fitting side).

Each class is one small piece of physics with its parameters.  Linear parameters (``n_lin``, real) enter the
prediction as columns (y = y0 + A p); nonlinear ones (``nl_*``) change the dynamic stiffness.  The simulator-side
versions used to make concealed-effect recordings live in :mod:`bearing_id.simulation.effects` and are written along a
different route.  Units SI; node numbers 1-based; phasors as in :mod:`bearing_id.conventions`.

Any effect may apply at any location the data allow (another bearing, plane, probe, disc, coupling end); variants
that cannot be held together say so (:meth:`Effect.conflicts`: two orientations of one probe, two bearing model
forms, two whirl forces on one sub-synchronous line).  Probe orientation comes per probe and per x/y pair (both axes
turned and gained: :class:`ProbePairOrientation`).

The augmented model is stored in a params file under ``extra: {effects: [{effect: NAME, ...parameters}]}``;
:func:`effects_from_extra` rebuilds the effects from it, :func:`augmented_dynamic_stiffness` and
:func:`augmented_forces` give identification the augmented system, :func:`measurement_corrections` the probe
entries.
"""
from __future__ import annotations

import math
import types

import numpy as np

from .crack import BreathingCrack, crack_elements
from .effect import determined, DETERMINED_REL, Effect, pm as _pm
from .predict import bearing_form, form_label, forward_force, model_forms
from .rub import Rub
from ..config.params import ExcitationEntry
from ..conventions import direction_words, dof_index, rad_s_to_rpm
from ..excitation import harmonic_forces
from ..rotor.assembly import add_film_impedance, dynamic_stiffness, RotorModel, static_sag

SLOW_ROLL_RPM = 400.0     # windows below this speed are slow roll (as locate.locate)

EFFECT_NAMES = ('support_flexibility', 'residual_unbalance', 'shaft_bow', 'probe_runout', 'misalignment',
                'oil_whirl', 'probe_orientation', 'disc_mass_error', 'bearing_model_form', 'breathing_crack', 'rub')


def _complex_lin(lin) -> complex:
    return complex(lin[0], lin[1])


# ------------------------------------------------------------------------------------------------ system
class SupportFlexibility(Effect):
    """
    Flexible pedestal (mass-spring-damper) in series with the oil film at one bearing, in x or y.

    Pedestal impedance per flexible direction d: zs = k_d - w^2 m_d + j w c_d; the journal sees
    Zeff = (Zb^-1 + diag(1/zs))^-1 (a rigid direction contributes 0 to the compliance).  Nonlinear parameters per
    flexible direction: ln k [ln N/m], c [N s/m], m [kg] (>= 0).  A ``mass`` given in the params file
    (``from_extra``) is the fixed pedestal mass when m is absent.

    Reporting: over a limited speed range k and m trade off (only k - m w^2 is seen) and c is often weakly
    determined; each of k, c, m is given as a number only when its 1-sigma (joint with the bearing nuisance) is
    within ``DETERMINED_REL``; otherwise it is reported undetermined together with what the data do fix: the dynamic
    stiffness k - m w^2 at the lowest and the highest measured running speed (``speeds``, rad/s), with its 1-sigma.
    """

    name = 'support_flexibility'

    def __init__(self, bearing_index: int, node: int, directions: str, mass: float = 0.0, speeds=None):
        super().__init__()
        self.bearing_index, self.node, self.directions, self.mass = bearing_index, node, directions, float(mass)
        self.where = (f'bearing {bearing_index + 1} (node {node}), '
                      + ' and '.join(direction_words(d) for d in directions))
        self.nl_names = tuple(f'{p}_{d}' for d in directions for p in ('lnk', 'c', 'm'))
        self.nl_lo = tuple(v for _ in directions for v in (math.log(1e3), 0.0, 0.0))
        self.nl_hi = tuple(v for _ in directions for v in (math.log(1e10), 1e5, 50.0))
        self.key = f'k_{directions[0]}'
        self.speeds = tuple(sorted(float(v) for v in speeds)) if speeds else ()

    @property
    def starts(self):
        return [np.array([v for _ in self.directions for v in (math.log(k), 10.0, 0.01)]) for k in (2e5, 2e6)]

    def bearing_impedance(self, prob, node, Zb, speed, omega, nl):
        if node != self.node:
            return Zb
        comp = np.zeros((2, 2), complex)
        for a, d in enumerate(self.directions):
            lnk, c, m = nl[3 * a:3 * a + 3]
            zs = math.exp(lnk) - omega * omega * m + 1j * omega * c
            i = 0 if d == 'x' else 1
            comp[i, i] = 1.0 / zs
        return np.linalg.inv(np.linalg.inv(Zb) + comp)

    def physical(self, nl, lin):
        out = {}
        for a, d in enumerate(self.directions):
            k, c, m = math.exp(nl[3 * a]), float(nl[3 * a + 1]), float(nl[3 * a + 2])
            out[f'k_{d}'], out[f'c_{d}'], out[f'm_{d}'] = k, c, m
            if self.speeds:
                out[f'kdyn_{d}_low'] = k - m * self.speeds[0] ** 2
                out[f'kdyn_{d}_high'] = k - m * self.speeds[-1] ** 2
        return out

    def undetermined(self, phys, std):
        return [f'{p}_{d}' for d in self.directions for p in ('k', 'c', 'm')
                if not determined(phys[f'{p}_{d}'], std.get(f'{p}_{d}'))]

    def sentence(self, phys, std):
        und = set(self.undetermined(phys, std))
        parts = []
        for d in self.directions:
            words = []
            for p, unit, what in (('k', 'N/m', 'stiffness'), ('c', 'N·s/m', 'damping'), ('m', 'kg', 'mass')):
                v, sd = phys[f'{p}_{d}'], std.get(f'{p}_{d}', np.nan)
                if f'{p}_{d}' in und:
                    words.append(f'pedestal {what} not determined by these data' +
                                 (f' (fit {v:.3g} {unit}, 1σ {sd:.2g} {unit})' if np.isfinite(sd) else ''))
                else:
                    words.append(f'{p} ≈ {v:.3g} {unit}{_pm(v, sd)}')
            if self.speeds and ({f'k_{d}', f'm_{d}'} & und):
                lo, hi = phys[f'kdyn_{d}_low'], phys[f'kdyn_{d}_high']
                words.append(f'what the data fix is the dynamic stiffness k - m ω² ≈ {lo:.3g} N/m'
                             f"{_pm(lo, std.get(f'kdyn_{d}_low'))}"
                             f' at {rad_s_to_rpm(self.speeds[0]):.0f} rpm and {hi:.3g} N/m'
                             f"{_pm(hi, std.get(f'kdyn_{d}_high'))} at {rad_s_to_rpm(self.speeds[-1]):.0f} rpm")
            parts.append(', '.join(words))
        return f'support flexibility at {self.where}: ' + '; '.join(parts) + ' (in series with the oil film)'

    def to_extra(self, phys):
        return {'effect': self.name, 'bearing_node': self.node, 'directions': self.directions,
                **{k: float(v) for k, v in phys.items() if not k.startswith('kdyn_')}}

    @classmethod
    def from_extra(cls, d, rig):
        idx = [b.node for b in rig.bearings].index(int(d['bearing_node']))
        e = cls(idx, int(d['bearing_node']), str(d['directions']), float(d.get('mass', 0.0)))
        nl = np.array([v for dd in e.directions for v in (math.log(d[f'k_{dd}']), d.get(f'c_{dd}', 0.0),
                                                          d.get(f'm_{dd}', e.mass))])
        return e, nl, np.zeros(0)


class BearingModelForm(Effect):
    """
    The oil-film theory itself is off: the bearings follow another model *form* over all speeds.

    ``form`` = (model, cavitation) from :func:`predict.model_forms` (the short bearing, the finite-length Reynolds
    bearing).  With the bearing nuisance refitted (the default) the viscosity and clearance factors stay the
    nuisance and this effect only swaps the form: no continuous parameter, counted as one parameter in the BIC (a
    discrete choice), and the refitted factors are reported with it.  With ``with_factors``
    (``diagnose(..., nuisance=False)``) it also carries ln viscosity and ln clearance factors per bearing; then the
    nominal form with refitted factors is a variant too (a theory that is
    off in its constants: oil temperature, worn clearance).
    """

    name = 'bearing_model_form'
    k_extra = 1                   # the discrete choice of form
    screen_free_nuisance = True   # a form is only comparable once viscosity and clearance are refitted under it

    def __init__(self, nb: int, form=('finite', None), with_factors: bool = False, nominal=None):
        super().__init__()
        self.nb, self.bearing_form, self.with_factors = nb, tuple(form), bool(with_factors)
        self.nominal = tuple(nominal) if nominal is not None else None
        self.form_words = form_label(self.bearing_form)
        self.where = ('oil film of ' + ('both bearings' if nb == 2 else f'{nb} bearings') + ': ' + self.form_words
                      + (' (factors refitted)' if with_factors and self.bearing_form == self.nominal else ''))
        if with_factors:
            self.nl_names = tuple(f'ln{p}_{i + 1}' for p in ('v', 'c') for i in range(nb))
            self.nl_lo = (-2.0,) * (2 * nb)
            self.nl_hi = (2.0,) * (2 * nb)
            self.key = 'clearance_factor_1'
        else:
            self.key = ''

    @property
    def starts(self):
        return [np.zeros(2 * self.nb if self.with_factors else 0)]

    def bearing_factors(self, nl):
        if not self.with_factors:
            return None
        e = np.exp(np.asarray(nl, float))
        return tuple(e[:self.nb]), tuple(e[self.nb:])

    def physical(self, nl, lin):
        if not self.with_factors:
            return {}
        e = np.exp(np.asarray(nl, float))
        return {**{f'viscosity_factor_{i + 1}': float(e[i]) for i in range(self.nb)},
                **{f'clearance_factor_{i + 1}': float(e[self.nb + i]) for i in range(self.nb)}}

    def sentence(self, phys, std):
        parts = [f"bearing {i + 1}: viscosity x{phys[f'viscosity_factor_{i + 1}']:.2f}, clearance "
                 f"x{phys[f'clearance_factor_{i + 1}']:.2f}" for i in range(self.nb)
                 if f'viscosity_factor_{i + 1}' in phys]
        same = self.nominal is not None and self.bearing_form == self.nominal
        head = ('bearing model form: the oil-film coefficients differ from the nominal bearing theory' if same else
                f'bearing model form: the bearings behave as a {self.form_words}, not as the nominal '
                + (form_label(self.nominal) if self.nominal else 'bearing model'))
        cmd = '' if same else f' --bearing-model {self.bearing_form[0]}'
        return (head + (' (' + '; '.join(parts) + ')' if parts else '') +
                f' -- the bearings, not a missing effect; identify them with `bearing-id identify{cmd}`')

    def to_extra(self, phys):
        out = {'effect': self.name, 'model': self.bearing_form[0]}
        if self.bearing_form[1] is not None:
            out['cavitation'] = self.bearing_form[1]
        if all(f'viscosity_factor_{i + 1}' in phys for i in range(self.nb)):
            out['viscosity_factor'] = [float(phys[f'viscosity_factor_{i + 1}']) for i in range(self.nb)]
            out['clearance_factor'] = [float(phys[f'clearance_factor_{i + 1}']) for i in range(self.nb)]
        return out

    def conflicts(self, other) -> bool:
        return other.name == self.name            # one bearing theory at a time

    def nuisance_physical(self, prob, theta, cov_theta) -> tuple[dict, dict]:
        """(values, 1-sigma) of the bearing factors the nuisance refitted under this form (reported with it)."""
        if self.with_factors or not prob.n_nuis:
            return {}, {}
        vf, cf = prob.nuisance_factors(theta)
        sd = np.sqrt(np.clip(np.diag(cov_theta), 0, None)) if cov_theta is not None else np.full(prob.n_nuis, np.nan)
        val, std = {}, {}
        for i in range(self.nb):
            val[f'viscosity_factor_{i + 1}'], std[f'viscosity_factor_{i + 1}'] = float(vf[i]), float(vf[i] * sd[i])
            val[f'clearance_factor_{i + 1}'] = float(cf[i])
            std[f'clearance_factor_{i + 1}'] = float(cf[i] * sd[self.nb + i])
        return val, std


class DiscMassError(Effect):
    """The disc at ``node`` weighs ``factor`` x the model's (mass, diametral and polar inertia scaled alike)."""

    name = 'disc_mass_error'
    nl_names = ('factor',)
    nl_lo = (0.2,)
    nl_hi = (5.0,)
    key = 'mass_factor'

    def __init__(self, node: int, disc):
        super().__init__()
        self.node, self.disc = node, disc
        self.where = f'disc at node {node}'

    @property
    def starts(self):
        return [np.array([1.0])]

    def add_dZ(self, prob, Z, speed, omega, nl):
        f = float(nl[0]) - 1.0
        i = dof_index(self.node, 'x', prob.model.n_nodes)
        Z[i:i + 4, i:i + 4] += f * (-omega * omega * self.disc.M() + 1j * omega * speed * self.disc.G())

    def physical(self, nl, lin):
        return {'mass_factor': float(nl[0]), 'mass_error_kg': (float(nl[0]) - 1.0) * self.disc.m}

    def sentence(self, phys, std):
        return (f"disc mass error at node {self.node}: mass x{phys['mass_factor']:.3f}"
                f"{_pm(phys['mass_factor'] - 1 if phys['mass_factor'] != 1 else 1, std.get('mass_factor'))} "
                f"({phys['mass_error_kg'] * 1e3:+.0f} g)")

    def to_extra(self, phys):
        return {'effect': self.name, 'node': self.node, 'mass_factor': phys['mass_factor']}

    @classmethod
    def from_extra(cls, d, rig):
        node = int(d['node'])
        disc = RotorModel.from_params(rig).discs[node]
        return cls(node, disc), np.array([float(d['mass_factor'])]), np.zeros(0)


# ------------------------------------------------------------------------------------------------ forces (linear)
class ResidualUnbalance(Effect):
    """Unknown unbalance U = m r e^{j phase} [kg m] at a plane (node): 1X force U Omega^2 (forward)."""

    name = 'residual_unbalance'
    n_lin = 2
    key = 'me'

    def __init__(self, node: int):
        super().__init__()
        self.node = node
        self.where = f'plane at node {node}'

    def force_columns(self, prob, k, ratio, nl):
        if ratio != 1.0:
            return None
        W = prob.windows[k].speed
        F = harmonic_forces([ExcitationEntry('unbalance', self.node, 1.0, 0.0, 'forward', 1.0)], W,
                            prob.model.n_nodes, prob.model.ndof)[1.0]
        return np.column_stack([F, 1j * F])

    def physical(self, nl, lin):
        U = _complex_lin(lin)
        return {'me': abs(U), 'phase_deg': math.degrees(math.atan2(U.imag, U.real)), 're': U.real, 'im': U.imag}

    def sentence(self, phys, std):
        return (f"residual unbalance at node {self.node}: m·r ≈ {phys['me'] * 1e6:.3g} g·mm"
                f"{_pm(phys['me'], std.get('me'))} at {phys['phase_deg']:.0f}° from the key mark (1X response growing "
                f'with speed², absent at slow roll)')

    def to_extra(self, phys):
        return {'effect': self.name, 'node': self.node, 'me': phys['me'], 'phase_deg': phys['phase_deg']}

    @classmethod
    def from_extra(cls, d, rig):
        U = d['me'] * np.exp(1j * math.radians(d.get('phase_deg', 0.0)))
        return cls(int(d['node'])), np.zeros(0), np.array([U.real, U.imag])


def bow_shape(model, z_a: float, z_b: float) -> np.ndarray:
    """
    Return the parabolic bow DOF vector (ndof,) complex of a unit forward bow midway between ``z_a`` and ``z_b`` [m].

    Zero at both (the bearing line): x = s(z), y = -j s(z), theta_x = -dy/dz, theta_y = dx/dz.
    """
    z = np.asarray(model.node_z, dtype=float)
    span = z_b - z_a
    s = 4.0 * (z - z_a) * (z_b - z) / span**2
    ds = 4.0 * (z_a + z_b - 2.0 * z) / span**2
    b = np.zeros(model.ndof, dtype=complex)
    n4 = 4 * model.n_nodes                          # rotor DOFs (pedestal DOFs, if any, follow)
    b[0:n4:4] = s
    b[1:n4:4] = -1j * s
    b[2:n4:4] = 1j * ds
    b[3:n4:4] = ds
    return b


class ShaftBow(Effect):
    """
    A bent shaft: parabolic bow B [m] midway between the bearings, relative to their centre line.

    At ``phase`` from the key mark; elastic force K_shaft b (1X, forward, constant with speed: present at slow roll).
    """

    name = 'shaft_bow'
    n_lin = 2
    key = 'bow'

    def __init__(self, model):
        super().__init__()
        zb = [model.node_z[n - 1] for n in model.bearing_nodes]
        self.force = model.K_shaft @ bow_shape(model, min(zb), max(zb))
        self.where = 'between the bearings'

    def force_columns(self, prob, k, ratio, nl):
        if ratio != 1.0:
            return None
        return np.column_stack([self.force, 1j * self.force])

    def physical(self, nl, lin):
        B = _complex_lin(lin)
        return {'bow': abs(B), 'phase_deg': math.degrees(math.atan2(B.imag, B.real)), 're': B.real, 'im': B.imag}

    def sentence(self, phys, std):
        return (f"shaft bow: {phys['bow'] * 1e6:.3g} µm{_pm(phys['bow'], std.get('bow'))} at midspan relative to the "
                f"bearing line, {phys['phase_deg']:.0f}° from the key mark (1X present at slow roll, "
                f'amplified through the critical)')

    def to_extra(self, phys):
        return {'effect': self.name, 'bow': phys['bow'], 'phase_deg': phys['phase_deg']}

    @classmethod
    def from_extra(cls, d, rig):
        B = d['bow'] * np.exp(1j * math.radians(d.get('phase_deg', 0.0)))
        return cls(RotorModel.from_params(rig)), np.zeros(0), np.array([B.real, B.imag])


class Misalignment(Effect):
    """
    Coupling misalignment: a 2X force at the shaft end ``node`` or on a coupling element (``node``, ``pair``).

    A flexible coupling inside the model (the element between ``node`` and ``pair``) takes equal and opposite 2X
    forces on its two nodes (the coupling's reaction on both halves).

    Forward + backward rotating parts (complex); the peak force is |F_f| + |F_b| [N] (on each node of a pair).  (The
    static bearing-load part of misalignment is not modelled.)
    """

    name = 'misalignment'
    n_lin = 4
    acts_on_1x = False
    only_1x = False
    key = 'force_2x'

    def __init__(self, node: int, pair: int | None = None):
        super().__init__()
        self.node, self.pair = node, pair
        self.where = f'coupling end, node {node}' if pair is None else f'coupling between nodes {node} and {pair}'

    def force_columns(self, prob, k, ratio, nl):
        if ratio != 2.0:
            return None
        n = prob.model.n_nodes
        Ff = forward_force(prob.model.ndof, self.node, n)
        if self.pair is not None:
            Ff = Ff - forward_force(prob.model.ndof, self.pair, n)
        Fb = np.conj(Ff)
        return np.column_stack([Ff, 1j * Ff, Fb, 1j * Fb])

    def physical(self, nl, lin):
        Ff, Fb = complex(lin[0], lin[1]), complex(lin[2], lin[3])
        return {'force_2x': abs(Ff) + abs(Fb), 'forward': abs(Ff), 'backward': abs(Fb),
                'f_re': Ff.real, 'f_im': Ff.imag, 'b_re': Fb.real, 'b_im': Fb.imag}

    def sentence(self, phys, std):
        return (f"misalignment at the {self.where}: 2X force ≈ {phys['force_2x']:.3g} N"
                f"{_pm(phys['force_2x'], std.get('force_2x'))} (forward {phys['forward']:.3g} N, backward "
                f"{phys['backward']:.3g} N)")

    def conflicts(self, other) -> bool:
        """Return True for another misalignment sharing a node (one coupling, one force model)."""
        mine = {self.node, self.pair} - {None}
        return other.name == self.name and bool(mine & ({other.node, getattr(other, 'pair', None)} - {None}))

    def to_extra(self, phys):
        return {'effect': self.name, 'node': self.node, **({'pair': self.pair} if self.pair is not None else {}),
                **{k: float(phys[k]) for k in ('f_re', 'f_im', 'b_re', 'b_im')}}

    @classmethod
    def from_extra(cls, d, rig):
        pair = int(d['pair']) if d.get('pair') is not None else None
        return cls(int(d['node']), pair), np.zeros(0), np.array([d['f_re'], d['f_im'], d['b_re'], d['b_im']])


# ------------------------------------------------------------------------------------------------ measurement
class ProbeRunout(Effect):
    """Electrical/mechanical runout on one probe: a constant 1X reading R [m] added at every speed."""

    name = 'probe_runout'
    n_lin = 2
    key = 'runout'

    def __init__(self, channel: int, probe):
        super().__init__()
        self.channel, self.probe = channel, probe
        self.where = f'probe {probe.name} (node {probe.node}, {direction_words(probe.direction)})'

    def measure_columns(self, prob, k, o, ratio, y_nom, y_perp):
        if ratio != 1.0:
            return None
        c = prob.channel(k, self.probe.name)
        if c is None:
            return None
        col = np.zeros((y_nom.size, 2), complex)
        col[c, 0], col[c, 1] = 1.0, 1j
        return col

    def physical(self, nl, lin):
        R = _complex_lin(lin)
        return {'runout': abs(R), 'phase_deg': math.degrees(math.atan2(R.imag, R.real)), 're': R.real, 'im': R.imag}

    def sentence(self, phys, std):
        return (f"probe runout on {self.where}: {phys['runout'] * 1e6:.3g} µm{_pm(phys['runout'], std.get('runout'))}"
                f" at {phys['phase_deg']:.0f}° (one constant 1X vector at every speed -- a measurement, not a motion; "
                f'a slow-roll run would show it too)')

    def to_extra(self, phys):
        return {'effect': self.name, 'probe': self.probe.name, 'runout': phys['runout'],
                'phase_deg': phys['phase_deg']}


class _Orientation(Effect):
    """Base of the probe orientation variants (one probe, an x/y pair): two of them cannot share a probe."""

    name = 'probe_orientation'
    key = 'angle_deg'
    probe_names: tuple = ()

    def conflicts(self, other) -> bool:
        return other.name == self.name and bool(set(self.probe_names) & set(getattr(other, 'probe_names', ())))


class ProbeOrientation(_Orientation):
    """
    One probe turned by an angle a (towards +90 deg from its axis) with gain g.

    Reading = (1 + p0) u + p1 u_perp, g = |1 + p0 + j p1|, a = atan2(p1, 1 + p0).
    """

    n_lin = 2

    def __init__(self, channel: int, probe):
        super().__init__()
        self.channel, self.probe = channel, probe
        self.probe_names = (probe.name,)
        self.where = f'probe {probe.name} (node {probe.node}, {direction_words(probe.direction)})'

    def measure_columns(self, prob, k, o, ratio, y_nom, y_perp):
        c = prob.channel(k, self.probe.name)
        if c is None:
            return None
        col = np.zeros((y_nom.size, 2), complex)
        col[c, 0], col[c, 1] = y_nom[c], y_perp[c]
        return col

    def physical(self, nl, lin):
        a, b = 1.0 + lin[0], lin[1]
        return {'angle_deg': math.degrees(math.atan2(b, a)), 'gain': math.hypot(a, b)}

    def sentence(self, phys, std):
        return (f"probe orientation error on {self.where}: turned {phys['angle_deg']:.1f}°"
                f"{_pm(phys['angle_deg'], std.get('angle_deg'))}, gain {phys['gain']:.3f}")

    def to_extra(self, phys):
        return {'effect': self.name, 'probe': self.probe.name, **phys}


class ProbePairOrientation(_Orientation):
    """
    The x/y probe pair at one node turned and gained (both axes).

    Each probe i of the pair reads (1 + a_i) u_i + b_i u_perp_i (u_perp_i: the displacement along its axis turned
    +90 deg), i.e. it is turned by atan2(b_i, 1 + a_i) with gain |1 + a_i + j b_i|.  Four linear parameters (per
    probe an angle and a gain); a pair turned as a rigid body has equal angles: ``angle_deg`` is their mean (the
    pair's rotation) and ``skew_deg`` their difference (non-orthogonality; ~0 for a rigid pair).
    """

    n_lin = 4

    def __init__(self, px, py):
        super().__init__()
        self.px, self.py = px, py
        self.probe_names = (px.name, py.name)
        self.where = f'probe pair {px.name}/{py.name} (node {px.node}, x and y)'

    def measure_columns(self, prob, k, o, ratio, y_nom, y_perp):
        cx, cy = prob.channel(k, self.px.name), prob.channel(k, self.py.name)
        if cx is None or cy is None:
            return None
        col = np.zeros((y_nom.size, 4), complex)
        col[cx, 0], col[cx, 1] = y_nom[cx], y_perp[cx]
        col[cy, 2], col[cy, 3] = y_nom[cy], y_perp[cy]
        return col

    def physical(self, nl, lin):
        ax, bx, ay, by = 1.0 + lin[0], lin[1], 1.0 + lin[2], lin[3]
        tx, ty = math.atan2(bx, ax), math.atan2(by, ay)
        return {'angle_deg': math.degrees(0.5 * (tx + ty)), 'gain_x': math.hypot(ax, bx), 'gain_y': math.hypot(ay, by),
                'angle_x_deg': math.degrees(tx), 'angle_y_deg': math.degrees(ty), 'skew_deg': math.degrees(tx - ty)}

    def sentence(self, phys, std):
        sk = std.get('skew_deg', np.nan)
        rigid = np.isfinite(sk) and abs(phys['skew_deg']) <= max(2 * sk, 0.5)
        return (f"probe orientation error on the {self.where}: the pair is turned {phys['angle_deg']:.1f}°"
                f"{_pm(phys['angle_deg'], std.get('angle_deg'))}"
                + (' as a rigid pair' if rigid else
                   f" (x {phys['angle_x_deg']:.1f}°, y {phys['angle_y_deg']:.1f}°: not orthogonal by "
                   f"{phys['skew_deg']:.1f}°)")
                + f"; gains x {phys['gain_x']:.3f}{_pm(phys['gain_x'], std.get('gain_x'))}, "
                  f"y {phys['gain_y']:.3f}{_pm(phys['gain_y'], std.get('gain_y'))}")

    def to_extra(self, phys):
        return [{'effect': self.name, 'probe': self.px.name, 'angle_deg': phys['angle_x_deg'], 'gain': phys['gain_x']},
                {'effect': self.name, 'probe': self.py.name, 'angle_deg': phys['angle_y_deg'], 'gain': phys['gain_y']}]


# ------------------------------------------------------------------------------------------------ oil whirl
class OilWhirl(Effect):
    """
    Sub-synchronous forward whirl driven at a bearing above an onset speed.

    Prediction for window k above the onset: X_sub = F e^{j alpha_k} u_k, u_k = P Z(r_k Omega)^-1 f_fwd(bearing),
    r_k the measured ratio; F >= 0 and the per-window phases alpha_k (the whirl is not locked to the key mark)
    are profiled out; the onset is searched between the recorded speeds.
    """

    name = 'oil_whirl'
    key = 'ratio'
    acts_on_1x = False
    only_1x = False

    def __init__(self, bearing_index: int, node: int):
        super().__init__()
        self.bearing_index, self.node = bearing_index, node
        self.where = f'bearing {bearing_index + 1} (node {node})'

    def conflicts(self, other) -> bool:
        # one sub-synchronous line is fitted with one driving force: a second whirl source at the other bearing
        # would be a second force on the same line, which one probe station cannot separate from the first
        return other.name == self.name

    def unit_response(self, prob, k, theta, effects, nls) -> np.ndarray:
        """Probe readings (nch,) of window k for a unit forward force at this bearing at the window's sub ratio."""
        w = prob.windows[k]
        Z = prob.systems([(k, w.sub_ratio)], theta, effects, nls)[0]
        q = np.linalg.solve(Z, np.pad(forward_force(prob.model.ndof, self.node, prob.model.n_nodes),
                                      (0, Z.shape[0] - prob.model.ndof)))[:prob.model.ndof]
        return prob.P[w.rec] @ q

    def sub_fit(self, prob, theta, effects, nls, windows):
        """(pred {k: (nch,)}, info dict, n_params) for the sub-synchronous entries of ``windows``."""
        ws = [k for k in windows if prob.windows[k].X_sub is not None]
        if not ws:
            return {}, {'ratio': float('nan'), 'onset_rpm': float('nan'), 'force': 0.0}, 3
        U = {k: self.unit_response(prob, k, theta, effects, nls) for k in ws}
        speeds = sorted({prob.windows[k].speed for k in ws})
        cands = [speeds[0] * 0.5] + [0.5 * (a + b) for a, b in zip(speeds[:-1], speeds[1:])]
        best = None
        for on in cands:
            above = [k for k in ws if prob.windows[k].speed > on]
            num = sum(abs(np.vdot(U[k] / prob.windows[k].std_sub ** 2, prob.windows[k].X_sub)) for k in above)
            den = sum(np.sum(np.abs(U[k]) ** 2 / prob.windows[k].std_sub ** 2) for k in above)
            F = num / den if den > 0 else 0.0
            pred = {}
            chi = 0.0
            for k in ws:
                w = prob.windows[k]
                if k in above:
                    alpha = np.angle(np.vdot(U[k] / w.std_sub ** 2, w.X_sub))
                    pred[k] = F * np.exp(1j * alpha) * U[k]
                else:
                    pred[k] = np.zeros_like(w.X_sub)
                chi += float(np.sum(np.abs((w.X_sub - pred[k]) / w.std_sub) ** 2))
            if best is None or chi < best[0]:
                best = (chi, on, F, pred, above)
        _, on, F, pred, above = best
        ratio = float(np.median([prob.windows[k].sub_ratio for k in above])) if above else float('nan')
        return pred, {'ratio': ratio, 'onset_rpm': float(rad_s_to_rpm(on)), 'force': float(F)}, 3 + len(above)

    def sentence(self, phys, std):
        return (f"oil whirl at {self.where}: forward sub-synchronous whirl at {phys['ratio']:.3f}X from about "
                f"{phys['onset_rpm']:.0f} rpm (equivalent driving force {phys['force']:.3g} N)")

    def to_extra(self, phys):
        return {'effect': self.name, 'bearing_node': self.node, **{k: float(v) for k, v in phys.items()}}


# ------------------------------------------------------------------------------------------------ library
def candidates(prob, *, unbalance_planes=None, misalignment_nodes=None, names=EFFECT_NAMES) -> list[Effect]:
    """Every variant of every candidate effect for the problem's rig and probes."""
    model, rig = prob.model, prob.rig
    out: list[Effect] = []
    if 'support_flexibility' in names:
        run = [w.speed for w in prob.windows if rad_s_to_rpm(w.speed) >= SLOW_ROLL_RPM] or \
            [w.speed for w in prob.windows]
        speeds = (min(run), max(run)) if run else None
        for i, b in enumerate(rig.bearings):
            for dirs in ('x', 'y'):
                out.append(SupportFlexibility(i, b.node, dirs, speeds=speeds))
    if 'residual_unbalance' in names:
        planes = unbalance_planes or sorted(model.discs) or [model.n_nodes // 2 + 1]
        out += [ResidualUnbalance(n) for n in planes]
    if 'shaft_bow' in names:
        out.append(ShaftBow(model))
    probes = []
    for r in range(len(prob.obs.recordings)):
        for p in prob.obs.probes(r):
            if p.name not in [q.name for q in probes]:
                probes.append(p)
    pairs = []                     # every x/y probe pair at one node
    for px in probes:
        py = next((q for q in probes if q.node == px.node and q.direction == 'y'), None)
        if px.direction == 'x' and py is not None:
            pairs.append((px, py))
    if 'probe_runout' in names:
        out += [ProbeRunout(c, p) for c, p in enumerate(probes)]
    if 'probe_orientation' in names:
        out += [ProbeOrientation(c, p) for c, p in enumerate(probes)]
        out += [ProbePairOrientation(px, py) for px, py in pairs]     # the pair turned (both axes), one effect
    if 'misalignment' in names and 2 in prob.obs.orders:
        ends = misalignment_nodes or (1, model.n_nodes)
        out += [Misalignment(n) for n in ends]
        # a flexible coupling modelled as the shaft element at an end (both halves in the model)
        out += [Misalignment(a, b) for a, b in ((1, 2), (model.n_nodes - 1, model.n_nodes)) if a in ends or b in ends]
    if 'breathing_crack' in names and {2, 3} <= set(prob.obs.orders):
        sag = static_sag(model)
        out += [BreathingCrack(model, e, sag) for e in crack_elements(model)]
    if 'rub' in names:             # at a pair whose orbit was measured
        out += [r for r in (Rub(prob.obs, px, py) for px, py in pairs) if r.r_max > 0]
    if 'disc_mass_error' in names:
        out += [DiscMassError(n, d) for n, d in sorted(model.discs.items())]
    if 'bearing_model_form' in names and not any(b.model == 'table' for b in rig.bearings):
        # (a table has no form to swap: its coefficients are scaled by the nuisance)
        nominal = {bearing_form(b) for b in rig.bearings}
        nom = next(iter(nominal)) if len(nominal) == 1 else None
        for form in model_forms():
            if form in nominal and prob.nuisance:
                continue          # the nominal form with refitted viscosity/clearance is the "none" hypothesis
            out.append(BearingModelForm(len(rig.bearings), form, with_factors=not prob.nuisance, nominal=nom))
    if 'oil_whirl' in names and prob.has_sub:
        out += [OilWhirl(i, b.node) for i, b in enumerate(rig.bearings)]
    return out


# ------------------------------------------------------------------------------------------------ augmented model
_FROM_EXTRA = {'support_flexibility': SupportFlexibility, 'disc_mass_error': DiscMassError,
               'residual_unbalance': ResidualUnbalance, 'shaft_bow': ShaftBow, 'misalignment': Misalignment,
               'breathing_crack': BreathingCrack}


def effects_from_extra(rig) -> list[tuple]:
    """
    Return [(effect, nl, lin)] of the model-side augmentations stored in ``rig.extra['effects']``.

    Measurement-side entries such as probe runout are returned by :func:`measurement_corrections`.
    """
    out = []
    for d in (rig.extra or {}).get('effects', []) or []:
        cls = _FROM_EXTRA.get(d.get('effect'))
        if cls is not None:
            out.append(cls.from_extra(d, rig))
    return out


def measurement_corrections(rig) -> list[dict]:
    """Return the measurement-model entries (probe_runout, probe_orientation) of ``rig.extra['effects']``."""
    return [d for d in (rig.extra or {}).get('effects', []) or []
            if d.get('effect') in ('probe_runout', 'probe_orientation')]


def augmented_dynamic_stiffness(model, rig, speed: float, omega: float, coeffs: dict, effects=None) -> np.ndarray:
    """
    Return Z (ndof, ndof) of the rotor on ``coeffs`` bearings with the augmentations in ``rig.extra``.

    Flexible supports condensed onto the journal DOFs, disc mass corrections; at spin ``speed`` and frequency
    ``omega`` [rad/s].  ``effects`` : the :func:`effects_from_extra` list, when already built.
    """
    p = types.SimpleNamespace(model=model)      # the minimal context the hooks read
    Z = dynamic_stiffness(model, speed, omega, {})
    effs = effects_from_extra(rig) if effects is None else effects
    for node, (Kb, Cb) in coeffs.items():
        Zb = np.asarray(Kb) + 1j * omega * np.asarray(Cb)
        for e, nl, _ in effs:
            Zb = e.bearing_impedance(p, node, Zb, speed, omega, nl)
        add_film_impedance(model, Z, node, Zb)               # at the node, or in series with its pedestal
    for e, nl, _ in effs:
        e.add_dZ(p, Z, speed, omega, nl)
    return Z


def augmented_forces(model, rig, speed: float, effects=None) -> dict:
    """Extra force phasors {ratio: (ndof,)} [N] of the augmentations (residual unbalance, bow, misalignment, crack)."""
    out: dict = {}
    for e, nl, lin in (effects_from_extra(rig) if effects is None else effects):
        if not e.n_lin:
            continue
        for ratio in (1.0, 2.0, 3.0):
            cols = _force_cols(e, model, speed, ratio)
            if cols is not None:
                out.setdefault(ratio, np.zeros(model.ndof, complex))
                out[ratio] += cols @ lin
    return out


def _force_cols(e, model, speed, ratio):
    p = types.SimpleNamespace(model=model, windows=[types.SimpleNamespace(speed=speed)])   # what force_columns reads
    return e.force_columns(p, 0, ratio, np.zeros(0))


__all__ = ['EFFECT_NAMES', 'Effect', 'SupportFlexibility', 'DiscMassError', 'ResidualUnbalance', 'ShaftBow',
           'Misalignment', 'BreathingCrack', 'ProbeRunout', 'BearingModelForm', 'ProbeOrientation',
           'ProbePairOrientation', 'OilWhirl',
           'candidates', 'bow_shape', 'effects_from_extra', 'measurement_corrections', 'augmented_dynamic_stiffness',
           'augmented_forces', 'determined', 'DETERMINED_REL']
