#!/usr/bin/env python
"""
Fault recordings of the paper rig made with ROSS's own fault models: test/data/ross/faults/*.npz + README.json.

Dev tool only (ROSS is NOT a runtime or CI dependency; the tests read the committed files).  Set-up as for
scripts/ross_reference.py, plus pandas < 3 (ROSS 2.3.0's crack model calls ``pd.eval`` on a Series, which pandas 3
refuses)::

    /tmp/rossenv/bin/pip install "ross-rotordynamics==2.3.0" "plotly<7" pyyaml "pandas<3"
    /tmp/rossenv/bin/python scripts/ross_faults.py --jobs 2          # everything (~20 min of CPU)
    /tmp/rossenv/bin/python scripts/ross_faults.py crack --set nominal   # some (README.json keeps the others)

Two rotors, ``--set`` (both by default):

* ``reference``: scripts/ross_reference.py's paper rig as it is, imported from it (``build_rotor``: params/rig.yaml's
  shaft and discs, Timoshenko elements with Cowper's shear coefficient, proportional damping, and the two constant
  cross-coupled bearings of its ``BEARINGS``; first bending mode 31 Hz, damping ratio 0.8 %).  Those bearings are
  NOT params/rig.yaml's journal bearings: a diagnosis with the packaged nominal params sees them as a mismatch
  of their own (healthy recordings of this rotor are not diagnosed 'none').  Files ``{fault}_{run}.npz``.
* ``nominal``: the same shaft and discs (``build_rotor``'s elements) on the packaged nominal bearings: at each
  speed w, constant bearings with bearing_id's own nominal coefficients ``bearing_fn(rig)(w)`` (short bearing,
  static load from the rotor's weight; first bending mode 33 Hz, damping ratio 0.5-0.9 %).  This is the model
  ``bearing-id diagnose`` starts from, plus the fault.  Files ``{fault}_nominal_{run}.npz``.
README.json gives each set's healthy response (no fault: gravity sag and 1X phasors at the probes, ROSS's linear
model) per run and speed, so that a test can make the healthy recording on the same angle record.

Faults (ROSS 2.3.0, ``ross.faults``), each with the rig's unbalance runs A and B (``simulation.runs``), at
600, 900, ..., 3000 rpm, each speed a separate steady-speed simulation:

* ``crack``: ``Crack`` (Mayes breathing model: the cracked element's stiffness in the rotating frame
  k = (k_open + k_closed)/2 + (k_closed - k_open)/2 cos(angle), a prescribed function of the shaft angle, not of the
  response) in the shaft element between nodes 6 and 7 (1-based; ROSS element 5), gravity on as in ``Crack.run``.
* ``rub``: ``Rubbing`` (penalty contact, ROSS's friction term) on the shaft element whose left node is the probe
  node 6 (ROSS element 5: the contact is checked at node 6), no gravity, as in ``Rubbing.run`` (the clearance is
  centred on the undeflected shaft).
* ``misalignment``: ``MisalignmentFlex`` (hexangular flexible coupling, Xia et al. 2019), parallel misalignment, on
  shaft element 0 (nodes 1-2, the drive end), no gravity, as in ``MisalignmentFlex.run``.  Its force is a function
  of the shaft angle only.

How each speed is simulated (and how that departs from ``Rotor.run_crack`` & co. -- numerically only)
  ROSS's ``newmark`` always starts from rest (y = y' = y'' = 0), and the rig's first bending mode is lightly damped
  (damping ratio < 1 %): the free vibration from that start (gravity alone sets it ringing at +-0.3 mm) lasts
  seconds.  So each speed is integrated as the deviation u from the healthy steady state r(t) (ROSS's own M, C(w),
  G, K(w); static gravity sag + 1X unbalance response, exact for the linear model): q = r + u, u(0) = u'(0) = 0,
  and ROSS's ``run_time_response(method='newmark', add_to_RHS=...)`` integrates M u'' + (C + w G) u' + K u =
  f_fault(q), the fault force computed by the ROSS fault object's own per-step method (``Crack._get_force_in_time``,
  ``Rubbing._get_force_over_time``, ``MisalignmentFlex.compute_reaction_force``) with the arguments its ``run()``
  gives it (the state of the previous step, the angle / speed of the current one).  This is the equation
  ``run_crack`` etc. integrate, started from the healthy orbit instead of from rest; it is checked against ROSS's own
  ``run_crack`` / ``run_rubbing`` / ``run_misalignment`` started from rest and run for ``PLAIN_SECONDS``
  (README.json: ``plain_check``).  Each speed is run for ``settle`` + ``KEEP`` s and the last ``KEEP`` s are kept; a
  speed whose kept 1X amplitude changes by more than ``STEADY_TOL`` between the kept halves (or its 2X or 3X by more
  than that share of the largest of the three) is run again with twice the settling time.  Rub: a speed whose
  healthy orbit stays inside the clearance has no fault force (u = 0 at every step): ``NO_CONTACT_SETTLE`` s at
  ``no_contact_dt``, no step check (the result is the healthy response at any step).
Time step
  ROSS's Newmark loop evaluates a response-dependent fault force (crack, rub) from the state of the previous step:
  one step late, an error of first order in the step.  The step was halved until the harmonic amplitudes at the
  probe changed by less than 1 % (README.json: ``ladder``, at the most sensitive speeds); every speed of every run
  is integrated again at ``check_dt`` (crack, misalignment: 2 dt; rub: dt / 2) and the changes are given per speed
  (``dt_check``: of each order 0.5X ... 5X, relative to the 1X, to the largest order, and to its own amplitude where
  that is above 1 % of the largest; rub: also the strongest non-synchronous line).  The rub needs 1/65536 s: its
  partial-contact speeds are quasi-periodic (a non-synchronous line at 1.2-1.5X), at 1/32768 s a line even locked
  to 1.25X that is not there at finer steps.
Recordings
  One .npz per fault and run in ``bearing_id.io.recordings.save_npz``'s layout (written here with numpy alone):
  probes p6x, p6y (node 6, x and y; metres; the project's axes = ROSS's: x horizontal, y up, gravity along -y, spin
  +x -> +y; ROSS's lateral [x, y, alpha, beta] = the project's [x, y, tx, ty]), samples float32 at ``FS`` Hz,
  noise-free; the keyphasor angle = ROSS's shaft angle (``unbalance_force_over_time``: the unbalance force is
  me w^2 [cos(angle + phase), sin(angle + phase)], the project's convention) plus whole turns, float32 (its largest
  value is ~1700 rad: rounded by < 1e-4 rad), continuous across the speeds (each speed's kept part is shifted back by
  under a revolution so that its angle continues the previous one's); the speed (rad/s, float32) per sample; the
  run's excitation; one steady segment per speed.  Between two speeds the speed steps at once (no ramp) and the
  samples jump (two separate simulations).
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
from pathlib import Path
import sys
import time
import zipfile
import zlib

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'scripts'))

from bearing_id.config.params import load_rig  # noqa: E402, I100
from bearing_id.rotor.supports import bearing_fn  # noqa: E402
import ross as rs  # noqa: E402
from ross.faults import Crack, MisalignmentFlex, Rubbing  # noqa: E402
from ross_reference import BEARINGS, build_rotor, lateral_modes, SHEAR  # noqa: E402  (the paper rig)
from scipy.integrate import cumulative_trapezoid  # noqa: E402

OUT = ROOT / 'test' / 'data' / 'ross' / 'faults'
SPEEDS_RPM = [600, 900, 1200, 1500, 1800, 2100, 2400, 2700, 3000]
FS = 4096.0                 # Hz, output sample rate
KEEP = 1.0                  # s kept per speed (the last KEEP seconds of each simulation)
STEADY_TOL = 0.005          # the kept 1X amplitude may change this much between the kept halves
PROBE_NODE = 6              # 1-based; probes p6x, p6y
PLAIN_SECONDS = 12.0        # s of ROSS's own run_* from rest, for the check of the warm start (or plain_seconds)
NO_CONTACT_SETTLE = 0.5     # s: a rub speed whose healthy orbit stays inside the clearance (the fault force is 0)
REPORT_ORDERS = (0.5, 1, 1.5, 2, 2.5, 3, 4, 5)   # harmonic orders fitted for the README tables and checks

# fault parameters: ROSS element numbers are 0-based (element e joins ROSS nodes e and e + 1 = our nodes e+1, e+2).
# dt: the delivered step; check_dt: the step every speed is integrated at again (the convergence check);
# settle: seconds integrated before the kept part; ladder: the steps of the convergence ladder (README.json).
FAULTS = {
    'crack': {'element': 5, 'depth_ratio': 0.2, 'crack_model': 'Mayes', 'gravity': True,
              'dt': 1.0 / 8192, 'check_dt': 1.0 / 4096, 'settle': 6.0,
              'ladder': [1.0 / 4096, 1.0 / 8192, 1.0 / 16384], 'ladder_cases': [('A', 900), ('A', 1800)],
              'plain_cases': [('A', 900), ('A', 1800)]},
    'rub': {'element': 5, 'distance': 80e-6, 'contact_stiffness': 2.0e5, 'contact_damping': 40.0,
            'friction_coeff': 0.2, 'torque': False, 'gravity': False,
            'dt': 1.0 / 65536, 'check_dt': 1.0 / 131072, 'settle': 3.0, 'no_contact_dt': 1.0 / 8192,
            'ladder': [1.0 / 16384, 1.0 / 32768, 1.0 / 65536, 1.0 / 131072], 'ladder_cases': [('A', 1800)],
            'plain_cases': [('A', 1800)], 'plain_seconds': 8.0},
    'misalignment': {'element': 0, 'mis_type': 'parallel', 'mis_distance_x': 1e-5, 'mis_distance_y': 1e-5,
                     'mis_angle': 0.0, 'radial_stiffness': 4.0e4, 'bending_stiffness': 0.0, 'gravity': False,
                     'dt': 1.0 / 8192, 'check_dt': 1.0 / 4096, 'settle': 6.0,
                     'ladder': [1.0 / 4096, 1.0 / 8192, 1.0 / 16384], 'ladder_cases': [('A', 900)],
                     'plain_cases': [('A', 900)]},
}
# the rotor sets: their faults, changes to FAULTS, whether the step ladder and the from-rest check are run there
SETS = {
    'reference': {'faults': ['crack', 'rub'], 'suffix': '', 'override': {}, 'ladder': True, 'plain': True},
    'nominal': {'faults': ['crack', 'rub', 'misalignment'], 'suffix': '_nominal',
                # the nominal bearings' orbits are larger at 2100-2400 rpm: contact at 1800 and 2100 rpm only
                'override': {'rub': {'distance': 95e-6}},
                'ladder': False, 'plain': False},
}
SETS['nominal']['ladder_faults'] = ['misalignment']      # its only fault not in the reference set
SETS['nominal']['plain_faults'] = ['misalignment']

# what ROSS 2.3.0's fault models do that a reader of these files should know (README.json: ross_notes)
ROSS_NOTES = [
    'newmark (ross.utils) always starts from rest (y = dy/dt = d2y/dt2 = 0): there is no initial-condition argument',
    'newmark evaluates add_to_RHS(step) with the state of step - 1: the crack and rub forces are one step late '
    '(first-order error in dt); the unbalance and misalignment forces are functions of the angle at step (not late)',
    'Crack._get_coefficient calls pd.eval on a pandas Series: pandas >= 3 raises, pandas < 3 works',
    "Crack: the force is (K_elem - K_crack) q with ROSS's 12x12 element stiffness, and K_crack has zero axial and "
    "torsional rows: the crack force also cancels the cracked element's axial and torsional stiffness (harmless "
    'here: nothing excites z or theta)',
    "Crack 'Mayes' in ROSS: the breathing is a prescribed function of the shaft angle (closed at angle 0, open at pi "
    'in the rotating frame), not of the bending state; with gravity the static sag it multiplies gives 1X, 2X and 3X '
    'forces (2X peaks near half, 3X near a third of the first critical speed)',
    'Crack.run adds gravity (g = -9.8065 m/s^2 along y); Rubbing.run and MisalignmentFlex.run do not (the rub '
    'clearance is centred on the undeflected shaft)',
    "Rubbing: contact when sqrt(x^2 + y^2) >= distance at the element's left node; normal force -k (r - distance) "
    'along the radius, contact damping -c times the whole velocity (not its radial part); the friction force is '
    'mu |F_k + F_c| component by component with fixed signs (-x, +y while the surface speed omega r dominates, i.e. '
    'always here), not tangential to the contact',
    'Rubbing: the partial-contact speeds near the critical give a stationary quasi-periodic response (a '
    'non-synchronous line at 1.2-1.5X with combination tones); at steps of 1/32768 s a line even locked to 1.25X, '
    'which finer steps do not show',
    'MisalignmentFlex (parallel): equal and opposite forces on the two nodes of the element; per node a mean force '
    '(0.2 N per axis here) and a backward 2X force (0.566 N; README.json truth) for 10 um misalignment and 40 kN/m '
    'radial stiffness; '
    "run_misalignment integrates with scipy lsim unless method='newmark' is given",
    "The fault objects keep every step's force (ndof x steps floats: 66 x 1e6 for 15 s at 1/65536 s)",
    "ROSS's unbalance convention (unbalance_force_over_time) equals the project's: me w^2 [cos(angle + phase), "
    'sin(angle + phase)], the angle integrated from 0 at t = 0',
]


class _Sink:
    """Stands in for a fault object's per-step force history (ndof x steps floats nobody reads here)."""

    def __setitem__(self, key, value):
        pass


class Setup:
    """One rotor set: the rig, the ROSS rotor at a speed (``rotor_at``), the fault parameters (``params``)."""

    def __init__(self, name, rig=None):
        self.name = name
        self.rig = rig or load_rig(ROOT / 'params' / 'rig.yaml')
        self.base = build_rotor(self.rig)
        self._bf = bearing_fn(self.rig) if name == 'nominal' else None
        self._rotors = {}

    def params(self, fault):
        return dict(FAULTS[fault], **SETS[self.name]['override'].get(fault, {}))

    def bearings_at(self, w):
        """Return {node (1-based): (K, C)} of the set's bearings at speed w [rad/s] (our frame = ROSS's)."""
        if self._bf is None:
            return {n: (np.array(kc['K'], float), np.array(kc['C'], float)) for n, kc in BEARINGS.items()}
        return {n: (np.asarray(K, float), np.asarray(C, float)) for n, (K, C) in self._bf(w).items()}

    def rotor_at(self, w):
        if self._bf is None:
            return self.base
        key = round(float(w), 9)
        if key not in self._rotors:
            brgs = [rs.BearingElement(n=n - 1, kxx=K[0, 0], kxy=K[0, 1], kyx=K[1, 0], kyy=K[1, 1],
                                      cxx=C[0, 0], cxy=C[0, 1], cyx=C[1, 0], cyy=C[1, 1])
                    for n, (K, C) in sorted(self.bearings_at(w).items())]
            self._rotors[key] = rs.Rotor(shaft_elements=self.base.shaft_elements,
                                         disk_elements=self.base.disk_elements, bearing_elements=brgs)
        return self._rotors[key]


def lateral_dofs(rotor):
    nd = rotor.number_dof
    return np.array([i for i in range(rotor.ndof) if i % nd in (0, 1, 3, 4)])


def probe_dofs(rotor):
    return [rotor.number_dof * (PROBE_NODE - 1), rotor.number_dof * (PROBE_NODE - 1) + 1]


def healthy_state(rotor, w, excitation, gravity):
    """Return the static gravity sag (ndof,) and the 1X unbalance phasors (ndof,) of ROSS's model at w [rad/s]."""
    nd = rotor.number_dof
    static = np.zeros(rotor.ndof)
    if gravity:
        lat = lateral_dofs(rotor)
        g = rotor.gravitational_force()
        assert not np.any(np.delete(g, lat)), 'gravity loads a non-lateral DOF'
        K = rotor.K(w)
        static[lat] = np.linalg.solve(K[np.ix_(lat, lat)], g[lat])
    F0 = np.zeros(rotor.ndof, dtype=complex)
    for e in excitation:
        assert e.kind == 'unbalance' and e.direction == 'forward' and e.frequency_ratio == 1.0, e
        n0 = nd * (e.node - 1)
        F0[n0] += e.magnitude * w**2 * np.exp(1j * e.phase)
        F0[n0 + 1] += -1j * e.magnitude * w**2 * np.exp(1j * e.phase)
    Z = rotor.K(w) - w**2 * rotor.M() + 1j * w * (rotor.C(w) + w * rotor.G())
    return static, np.linalg.solve(Z, F0)


def make_fault(rotor, name, p):
    if name == 'crack':
        return Crack(rotor, n=p['element'], depth_ratio=p['depth_ratio'], crack_model=p['crack_model'])
    if name == 'rub':
        return Rubbing(rotor, n=p['element'], distance=p['distance'], contact_stiffness=p['contact_stiffness'],
                       contact_damping=p['contact_damping'], friction_coeff=p['friction_coeff'], torque=p['torque'])
    if name == 'misalignment':
        return MisalignmentFlex(rotor, n=p['element'], mis_type=p['mis_type'], mis_distance_x=p['mis_distance_x'],
                                mis_distance_y=p['mis_distance_y'], mis_angle=p['mis_angle'],
                                radial_stiffness=p['radial_stiffness'], bending_stiffness=p['bending_stiffness'])
    raise ValueError(name)


def simulate(setup, name, rpm, excitation, dt, seconds):
    """
    Integrate one speed from the healthy steady state (see the module docstring).

    Returns (t, theta, q at the probe (n, 2), rub contact flag (n,) or None) at every step (t[k] = k dt).
    """
    p = setup.params(name)
    w = rpm * 2 * math.pi / 60
    rotor = setup.rotor_at(w)
    n = int(round(seconds / dt)) + 1
    t = np.arange(n) * dt
    theta = cumulative_trapezoid(np.full(n, w), t, initial=0)       # as Rotor.unbalance_force_over_time
    static, X = healthy_state(rotor, w, excitation, p['gravity'])
    fault = make_fault(rotor, name, p)
    fault.forces = _Sink()
    dofs = np.asarray(fault.dofs)
    sd, Xd = static[dofs], X[dofs]
    disp = np.zeros(rotor.ndof)
    velc = np.zeros(rotor.ndof)

    if name == 'crack':
        def rhs(step, disp_resp=None, **_):
            z = Xd * np.exp(1j * theta[step - 1])         # the state handed over is that of t[step - 1]
            disp[dofs] = sd + z.real + disp_resp[dofs]
            return fault._get_force_in_time(step, disp, theta[step])
    elif name == 'rub':
        def rhs(step, disp_resp=None, velc_resp=None, **_):
            z = Xd * np.exp(1j * theta[step - 1])
            disp[dofs] = sd + z.real + disp_resp[dofs]
            velc[dofs] = (1j * w * z).real + velc_resp[dofs]
            return fault._get_force_over_time(step, disp, velc, w)
    else:
        def rhs(step, **_):
            return fault.compute_reaction_force(theta[step:step + 1])[:, 0]

    F = np.broadcast_to(np.zeros(rotor.ndof), (n, rotor.ndof))      # the unbalance and gravity are in r(t)
    with contextlib.redirect_stdout(io.StringIO()):
        res = rotor.run_time_response(speed=w, F=F, t=t, method='newmark', add_to_RHS=rhs)
    pdofs = probe_dofs(rotor)
    q = static[pdofs] + np.real(np.outer(np.exp(1j * theta), X[pdofs])) + res.yout[:, pdofs]
    contact = None
    if name == 'rub':
        # the contact test of Rubbing.compute_rubbing_force, at the element's left node (our node 6 = the probe)
        assert pdofs[0] == dofs[0]
        contact = np.hypot(q[:, 0], q[:, 1]) >= p['distance']
    return t, theta, q, contact


def simulate_plain(setup, name, rpm, excitation, dt, seconds):
    """Run ROSS's own ``run_crack`` / ``run_rubbing`` / ``run_misalignment`` from rest: (t, theta, q at the probe)."""
    p = setup.params(name)
    w = rpm * 2 * math.pi / 60
    rotor = setup.rotor_at(w)
    t = np.arange(int(round(seconds / dt)) + 1) * dt
    nodes = [e.node - 1 for e in excitation]
    mags = [e.magnitude for e in excitation]
    phases = [e.phase for e in excitation]
    with contextlib.redirect_stdout(io.StringIO()):
        if name == 'crack':
            res = rotor.run_crack(n=p['element'], depth_ratio=p['depth_ratio'], node=nodes, unbalance_magnitude=mags,
                                  unbalance_phase=phases, speed=w, t=t, crack_model=p['crack_model'])
        elif name == 'rub':
            res = rotor.run_rubbing(n=p['element'], distance=p['distance'], contact_stiffness=p['contact_stiffness'],
                                    contact_damping=p['contact_damping'], friction_coeff=p['friction_coeff'],
                                    node=nodes, unbalance_magnitude=mags, unbalance_phase=phases, speed=w, t=t,
                                    torque=p['torque'])
        else:
            res = rotor.run_misalignment(node=nodes, unbalance_magnitude=mags, unbalance_phase=phases, speed=w, t=t,
                                         coupling='flex', n=p['element'], mis_type=p['mis_type'],
                                         mis_distance_x=p['mis_distance_x'], mis_distance_y=p['mis_distance_y'],
                                         mis_angle=p['mis_angle'], radial_stiffness=p['radial_stiffness'],
                                         bending_stiffness=p['bending_stiffness'], method='newmark')
    theta = cumulative_trapezoid(np.full(t.size, w), t, initial=0)
    return t, theta, np.asarray(res.yout)[:, probe_dofs(rotor)]


def harmonics(x, angle, orders=REPORT_ORDERS, lines=()):
    """
    Fit x = c + sum_k Re{X_k e^(j k angle)} over whole revolutions by least squares: {k: (n_ch,) complex}, key 0 = c.

    ``lines``: ratios (frequency / speed) of non-synchronous lines fitted with the orders (returned under their ratio
    too), so that a line does not leak into the orders.  The window is cut to an even number of revolutions.
    """
    a = np.asarray(angle, float)
    nrev = int((a[-1] - a[0]) // (2 * math.pi))
    nrev -= nrev % 2
    i1 = int(np.searchsorted(a, a[0] + nrev * 2 * math.pi))
    x, a = np.asarray(x, float)[:i1], a[:i1]
    ks = list(orders) + [r for r in lines if r not in orders]
    cols = [np.ones_like(a)]
    for k in ks:
        cols += [np.cos(k * a), np.sin(k * a)]
    D = np.stack(cols, axis=1)
    coef, *_ = np.linalg.lstsq(D, x, rcond=None)
    out = {0: coef[0].astype(complex)}
    for i, k in enumerate(ks):
        out[k] = coef[1 + 2 * i] - 1j * coef[2 + 2 * i]
    return out


def find_lines(x, angle, fs, n_max=3, rel=0.002):
    """
    Return the non-synchronous lines of x: [{'ratio', 'hz', 'amp_um': [x, y]}], strongest first.

    Found one at a time in what the fit of REPORT_ORDERS and the lines found so far leaves (Hann window, peak refined
    by a parabola through the log magnitudes), kept while above ``rel`` of the 1X amplitude and more than 0.02 X from
    every fitted order and line; at most ``n_max``.
    """
    x = np.asarray(x, float)
    a = np.asarray(angle, float)
    w = (a[-1] - a[0]) / (a.size - 1) * fs
    found = []
    for _ in range(n_max):
        h = harmonics(x, a, REPORT_ORDERS, [ln['ratio'] for ln in found])
        a1 = float(np.max(np.abs(h[1])))
        r = x - h[0].real - sum(np.real(np.outer(np.exp(1j * k * a), h[k])) for k in h if k)
        win = np.hanning(r.shape[0])
        nfft = 8 * r.shape[0]
        S = np.sqrt(np.sum(np.abs(np.fft.rfft(r * win[:, None], nfft, axis=0)) ** 2, axis=1)) * 2 / win.sum()
        f = np.fft.rfftfreq(nfft, 1 / fs)
        ratio_f = f * 2 * math.pi / w
        taken = np.array(list(REPORT_ORDERS) + [ln['ratio'] for ln in found])
        ok = (np.min(np.abs(ratio_f[:, None] - taken[None, :]), axis=1) > 0.02) & (ratio_f > 0.02)
        ok[0] = ok[-1] = False
        if not np.any(ok):
            break
        i = int(np.argmax(np.where(ok, S, 0.0)))
        la, lb, lc = np.log(S[i - 1:i + 2] + 1e-300)
        den = la - 2 * lb + lc
        d = 0.5 * (la - lc) / den if den != 0 else 0.0
        ratio = float((f[i] + d * (f[1] - f[0])) * 2 * math.pi / w)
        hl = harmonics(x, a, REPORT_ORDERS, [ln['ratio'] for ln in found] + [ratio])
        amp = np.abs(hl[ratio])
        if np.max(amp) < rel * a1:
            break
        found.append({'ratio': ratio, 'hz': ratio * w / (2 * math.pi), 'amp_um': (amp * 1e6).tolist()})
    return found


def keep_window(t, theta, dt, prev_angle, prev_speed):
    """
    Return the output indices (every dec-th step) and the recorded angle of the kept part.

    The kept part is the last ``KEEP`` s, shifted back by under a revolution so that its first angle continues
    ``prev_angle`` (None: the first speed); the recorded angle is ROSS's plus a whole number of turns.
    """
    dec = int(round(1.0 / (FS * dt)))
    assert abs(dec * dt * FS - 1) < 1e-9, (dt, FS)
    n_keep = int(round(KEEP * FS))
    last = t.size - 1
    start_nom = last - (n_keep - 1) * dec
    w = (theta[-1] - theta[0]) / (t[-1] - t[0])
    if prev_angle is None:
        start = start_nom
        offset = -2 * math.pi * math.floor(theta[start] / (2 * math.pi))
    else:
        target = prev_angle + 0.5 * (prev_speed + w) / FS
        per_rev = int(math.ceil(2 * math.pi / w / (dec * dt))) + 1
        cands = start_nom - dec * np.arange(per_rev + 1)
        cands = cands[cands >= 0]
        err = np.angle(np.exp(1j * (theta[cands] - target)))
        start = int(cands[np.argmin(np.abs(err))])
        offset = target + err[np.argmin(np.abs(err))] - theta[start]
        offset = 2 * math.pi * round(offset / (2 * math.pi))   # a whole number of turns: angle = ROSS's mod 2 pi
    idx = start + dec * np.arange(n_keep)
    assert idx[-1] <= last
    return idx, theta[idx] + offset


def steadiness(q, ang, lines=()):
    """
    Return the largest changes of the 1X, 2X, 3X amplitudes between the halves of the kept part.

    (1X relative to its own amplitude, 2X and 3X relative to the largest of the three); ``lines``: non-synchronous
    ratios fitted with them.
    """
    m = q.shape[0] // 2
    h1, h2 = harmonics(q[:m], ang[:m], (1, 2, 3), lines), harmonics(q[m:], ang[m:], (1, 2, 3), lines)
    a1, a2 = np.abs(h1[1]), np.abs(h2[1])
    own = float(np.max(np.abs(a2 - a1) / np.maximum(a1, a2)))
    big = np.max([np.abs(h1[k]) for k in (1, 2, 3)], axis=0)
    nx = float(max(np.max(np.abs(np.abs(h2[k]) - np.abs(h1[k])) / big) for k in (2, 3)))
    return own, nx


def analyse(q, ang, fs, rub):
    """Return the harmonics of the kept part (with its non-synchronous lines fitted when ``rub``) and the lines."""
    lines = find_lines(q, ang, fs) if rub else []
    return harmonics(q, ang, REPORT_ORDERS, [ln['ratio'] for ln in lines]), lines


def line_change(l1, l2):
    """Return the strongest non-synchronous line at two steps (frequency in Hz, x amplitude) and its change."""
    if not l1 or not l2:
        return None
    a, b = l1[0], l2[0]
    return {'hz': [a['hz'], b['hz']], 'amp_um_x': [a['amp_um'][0], b['amp_um'][0]],
            'amp_rel_change': abs(a['amp_um'][0] - b['amp_um'][0]) / max(a['amp_um'][0], b['amp_um'][0])}


def amplitudes_um(h):
    """Return {channel: {order: amplitude [um]}} of the REPORT_ORDERS (and '0', the mean)."""
    return {ch: {str(k): float(abs(h[k][j]) * 1e6) for k in [0] + list(REPORT_ORDERS)} for j, ch in enumerate('xy')}


def dt_change(h, h2):
    """
    Return the changes of the REPORT_ORDERS amplitudes between two steps.

    ``by_order_um``: |change| [um] per order and channel.  Over the whole orders (1X ... 5X): ``max_rel_to_1x`` /
    ``max_rel_to_largest``, the largest change relative to the 1X / to the largest order of its channel, and
    ``max_rel_own``, relative to its own amplitude over the orders above 1 % of the largest.  ``half_orders_*``: the
    same for 0.5X, 1.5X, 2.5X (in a quasi-periodic rub response a non-synchronous line within ~0.03X of a half order,
    which moves with the step, is not separable from it in a 1 s window).
    """
    a1 = np.abs(h[1])
    big = np.max([np.abs(h[k]) for k in REPORT_ORDERS], axis=0)
    out = {'by_order_um': {}}
    for prefix, orders in (('', [k for k in REPORT_ORDERS if float(k).is_integer()]),
                           ('half_orders_', [k for k in REPORT_ORDERS if not float(k).is_integer()])):
        worst = {'max_rel_to_1x': 0.0, 'max_rel_to_largest': 0.0, 'max_rel_own': 0.0}
        for k in orders:
            d = np.abs(np.abs(h[k]) - np.abs(h2[k]))
            out['by_order_um'][str(k)] = (d * 1e6).tolist()
            worst['max_rel_to_1x'] = max(worst['max_rel_to_1x'], float(np.max(d / a1)))
            worst['max_rel_to_largest'] = max(worst['max_rel_to_largest'], float(np.max(d / big)))
            sel = np.abs(h[k]) > 0.01 * big
            if np.any(sel):
                worst['max_rel_own'] = max(worst['max_rel_own'], float(np.max(d[sel] / np.abs(h[k])[sel])))
        out.update({prefix + k: v for k, v in worst.items()})
    return out


def run_speed(setup, name, run, rpm, prev_angle, prev_speed, log=print):
    """Simulate one speed of one run: the kept piece (q, angle, speed) and its metadata row."""
    p = setup.params(name)
    dt = p['dt']
    w = rpm * 2 * math.pi / 60
    settle = p['settle']
    quiet = False
    if name == 'rub':
        static, X = healthy_state(setup.rotor_at(w), w, run.excitation, False)
        dofs = probe_dofs(setup.rotor_at(w))
        ph = np.exp(1j * np.linspace(0, 2 * math.pi, 3601))
        r0 = float(np.max(np.hypot(np.real(X[dofs[0]] * ph), np.real(X[dofs[1]] * ph))))
        quiet = r0 < p['distance']           # the healthy orbit stays inside the clearance: no contact, u = 0
        if quiet:
            settle, dt = NO_CONTACT_SETTLE, p['no_contact_dt']
    t0 = time.time()
    while True:
        t, theta, q, contact = simulate(setup, name, rpm, run.excitation, dt, settle + KEEP)
        idx, ang = keep_window(t, theta, dt, prev_angle, prev_speed)
        hk, lines = analyse(q[idx], ang, FS, name == 'rub')
        s1, snx = steadiness(q[idx], ang, [ln['ratio'] for ln in lines])
        if (s1 < STEADY_TOL and snx < STEADY_TOL) or settle >= 4 * p['settle']:
            break
        log(f'  {setup.name} {name} {run.id} {rpm} rpm: not steady (1X {100 * s1:.2f} %, 2X/3X {100 * snx:.2f} %); '
            f'settle {settle:g} s -> {2 * settle:g} s')
        settle *= 2
    row = {'run': run.id, 'rpm': rpm, 'dt': dt, 'settle_s': settle,
           'steady_1x_change': s1, 'steady_2x3x_change': snx, 'amp_um': amplitudes_um(hk),
           'phasor_um': {ch: {str(k): [float(hk[k][j].real * 1e6), float(hk[k][j].imag * 1e6)] for k in REPORT_ORDERS}
                         for j, ch in enumerate('xy')}}
    if name == 'rub':
        tail = slice(idx[0], idx[-1] + 1)
        row['healthy_max_radius_um'] = r0 * 1e6
        row['contact_fraction'] = float(np.mean(contact[tail]))
        row['contact_anywhere'] = bool(np.any(contact))
        row['max_radius_um'] = float(np.hypot(q[tail, 0], q[tail, 1]).max() * 1e6)
        row['nonsync_lines'] = lines
    if not quiet:
        cdt = p['check_dt']
        t2, theta2, q2, contact2 = simulate(setup, name, rpm, run.excitation, cdt, settle + KEEP)
        sel2 = np.arange(t2.size)[-int(round(KEEP / cdt)):]
        sel1 = np.arange(t.size)[-int(round(KEEP / dt)):]
        hk1, lines1 = analyse(q[sel1], theta[sel1], 1 / dt, name == 'rub')
        hk2, lines2 = analyse(q2[sel2], theta2[sel2], 1 / cdt, name == 'rub')
        row['dt_check'] = dict(dt_change(hk1, hk2), check_dt=cdt)
        if name == 'rub':
            row['dt_check']['nonsync_line'] = line_change(lines1, lines2)
            row['dt_check']['contact_fraction'] = float(np.mean(contact2[sel2]))
    else:
        assert not row['contact_anywhere'] and row['contact_fraction'] == 0
        row['dt_check'] = {'skipped': 'no contact: the fault force is identically zero, the result is the healthy '
                                      'response at any step'}
    row['seconds'] = time.time() - t0
    chk = row['dt_check']
    log(f"  {setup.name} {name} {run.id} {rpm:4d} rpm: 1X {row['amp_um']['x']['1']:9.3f} 2X "
        f"{row['amp_um']['x']['2']:8.3f} 3X {row['amp_um']['x']['3']:8.3f} um (x); steady {100 * s1:.3f} / "
        f'{100 * snx:.3f} %; '
        + (f"dt check {100 * chk['max_rel_to_largest']:.3f} % of the largest order" if 'skipped' not in chk
           else 'no dt check')
        + (f"; contact {100 * row['contact_fraction']:.1f} % of the time, max r {row['max_radius_um']:.1f} um"
           if name == 'rub' else '') + f" ({row['seconds']:.0f} s)")
    return (q[idx], ang, np.full(idx.size, w)), row


def run_fault(setup, name, log=print):
    """Simulate all speeds of both runs; returns ({run_id: (Run, pieces)}, per-speed metadata rows)."""
    recs, rows = {}, []
    for run in setup.rig.simulation.runs:
        pieces, prev_angle, prev_speed = [], None, None
        for rpm in SPEEDS_RPM:
            piece, row = run_speed(setup, name, run, rpm, prev_angle, prev_speed, log=log)
            pieces.append(piece)
            rows.append(row)
            prev_angle, prev_speed = float(piece[1][-1]), float(piece[2][0])
        recs[run.id] = (run, pieces)
    return recs, rows


def ladder(setup, name, log=print):
    """Halve the step at the cases most sensitive to it: the kept harmonics at each step of the fault's ladder."""
    p = setup.params(name)
    runs = {r.id: r for r in setup.rig.simulation.runs}
    out = []
    for rid, rpm in p['ladder_cases']:
        prev = None
        for dt in p['ladder']:
            t, theta, q, contact = simulate(setup, name, rpm, runs[rid].excitation, dt, p['settle'] + KEEP)
            sel = np.arange(t.size)[-int(round(KEEP / dt)):]
            h, lines = analyse(q[sel], theta[sel], 1 / dt, name == 'rub')
            row = {'run': rid, 'rpm': rpm, 'dt': dt, 'amp_um': amplitudes_um(h)}
            if prev is not None:
                row['change_from_2dt'] = dt_change(h, prev)
            if name == 'rub':
                row['nonsync_lines'] = lines
            prev = h
            out.append(row)
            log(f"  ladder {setup.name} {name} {rid} {rpm} dt 1/{round(1 / dt)}: 1X {row['amp_um']['x']['1']:.4f} "
                f"2X {row['amp_um']['x']['2']:.4f} 3X {row['amp_um']['x']['3']:.4f} um"
                + (f"; change from 2 dt {100 * row['change_from_2dt']['max_rel_to_largest']:.3f} % of the largest "
                   f"order, {100 * row['change_from_2dt']['max_rel_own']:.3f} % own" if 'change_from_2dt' in row
                   else ''))
    return out


def plain_check(setup, name, log=print):
    """Compare ROSS's own run_* from rest (PLAIN_SECONDS) with the warm start: the harmonics of the last KEEP s."""
    p = setup.params(name)
    out = []
    runs = {r.id: r for r in setup.rig.simulation.runs}
    for rid, rpm in p['plain_cases']:
        run = runs[rid]
        seconds = p.get('plain_seconds', PLAIN_SECONDS)
        t, theta, q = simulate_plain(setup, name, rpm, run.excitation, p['dt'], seconds)
        tw, thw, qw, _ = simulate(setup, name, rpm, run.excitation, p['dt'], seconds)
        sel = np.arange(t.size)[-int(round(KEEP / p['dt'])):]
        (hp, lp), (hw, lw) = (analyse(q[sel], theta[sel], 1 / p['dt'], name == 'rub'),
                              analyse(qw[sel], thw[sel], 1 / p['dt'], name == 'rub'))
        row = {'run': rid, 'rpm': rpm, 'seconds': seconds, 'dt': p['dt'],
               'plain_amp_um': amplitudes_um(hp), 'warm_amp_um': amplitudes_um(hw),
               'max_diff_rel_to_1x': float(max(np.max(np.abs(hp[k] - hw[k]) / np.abs(hw[1]))
                                               for k in [0] + list(REPORT_ORDERS)))}
        if name == 'rub':
            row['plain_nonsync_lines'], row['warm_nonsync_lines'] = lp, lw
        log(f'  plain check {setup.name} {name} {rid} {rpm}: max |plain - warm| / |1X| = '
            f"{100 * row['max_diff_rel_to_1x']:.3f} % (phasors of every order, the mean included)")
        out.append(row)
    return out


def write_npz(path, run, pieces, rig_name):
    """Write the layout of bearing_id.io.recordings.save_npz (numpy only; float32 samples, angle and speed)."""
    x = np.concatenate([pc[0] for pc in pieces]).astype(np.float32)
    angle = np.concatenate([pc[1] for pc in pieces]).astype(np.float32)     # < 1e-4 rad off (a few MB saved)
    speed = np.concatenate([pc[2] for pc in pieces]).astype(np.float32)
    segs, i = [], 0
    for pc in pieces:
        segs.append((i, i + pc[0].shape[0], float(pc[2][0]), 1.0))
        i += pc[0].shape[0]
    ex = run.excitation
    arrays = {
        'format': np.array('bearing_id.recording.v1'), 'sample_rate': np.array(FS), 'speed': speed, 'angle': angle,
        'samples': x, 'channels': np.array(['p6x', 'p6y']), 'nodes': np.array([PROBE_NODE, PROBE_NODE]),
        'directions': np.array(['x', 'y']), 'run_id': np.array(run.id),
        'ex_kind': np.array([e.kind for e in ex], dtype='U16'), 'ex_node': np.array([e.node for e in ex], dtype=int),
        'ex_magnitude': np.array([e.magnitude for e in ex], dtype=float),
        'ex_phase': np.array([e.phase for e in ex], dtype=float),
        'ex_direction': np.array([e.direction for e in ex], dtype='U16'),
        'ex_frequency_ratio': np.array([e.frequency_ratio for e in ex], dtype=float),
        'segments': np.array(segs, dtype=float).reshape(-1, 4),
        'truth_speeds': np.zeros(0), 'truth_nodes': np.zeros(0, dtype=int), 'truth_K': np.zeros((0, 0, 2, 2)),
        'truth_C': np.zeros((0, 0, 2, 2)), 'rig_name': np.array(rig_name)}
    with zipfile.ZipFile(path, 'w', allowZip64=True) as zf:
        for key, value in arrays.items():
            arr = np.asanyarray(value)
            raw = arr.tobytes()
            deflate = arr.nbytes < 4096 or len(zlib.compress(raw[:1 << 20], 1)) <= 0.9 * len(raw[:1 << 20])
            info = zipfile.ZipInfo(f'{key}.npy', (1980, 1, 1, 0, 0, 0))
            info.external_attr = 0o644 << 16
            info.compress_type = zipfile.ZIP_DEFLATED if deflate else zipfile.ZIP_STORED
            with zf.open(info, 'w', force_zip64=True) as fh:
                np.lib.format.write_array(fh, arr, allow_pickle=False)
    return path


def healthy_table(setup):
    """Return the healthy (no fault) 1X phasors and gravity sag at the probe per run and speed (ROSS's model)."""
    out = {}
    for run in setup.rig.simulation.runs:
        rows = []
        for rpm in SPEEDS_RPM:
            w = rpm * 2 * math.pi / 60
            rotor = setup.rotor_at(w)
            static, X = healthy_state(rotor, w, run.excitation, True)
            pdofs = probe_dofs(rotor)
            rows.append({'rpm': rpm, 'X_um': {ch: [float(X[d].real * 1e6), float(X[d].imag * 1e6)]
                                              for ch, d in zip('xy', pdofs)},
                         'gravity_sag_um': {ch: float(static[d] * 1e6) for ch, d in zip('xy', pdofs)}})
        out[run.id] = rows
    return out


def set_description(setup):
    """Return the README description of a rotor set: its bearings and its four lowest lateral modes per speed."""
    modes = []
    for rpm in SPEEDS_RPM:
        w = rpm * 2 * math.pi / 60
        lam = lateral_modes(setup.rotor_at(w), w, 4)
        modes.append({'rpm': rpm, 'hz': (lam.imag / 2 / math.pi).tolist(), 'zeta': (-lam.real / np.abs(lam)).tolist()})
    if setup.name == 'reference':
        rotor = ('scripts/ross_reference.py build_rotor as it is: shaft and discs from params/rig.yaml (Timoshenko, '
                 f'{SHEAR} shear coefficient, proportional damping), its constant cross-coupled bearings BEARINGS '
                 '(NOT the journal bearings of params/rig.yaml)')
        brg = {str(k): v for k, v in BEARINGS.items()}
    else:
        rotor = ('the shaft and disc elements of scripts/ross_reference.py build_rotor on constant bearings per speed '
                 'with bearing_id nominal coefficients bearing_fn(load_rig())(w) (params/rig.yaml: short bearing, '
                 'static load from the weight): the model bearing-id diagnose starts from')
        brg = {str(rpm): {str(n): {'K': K.tolist(), 'C': C.tolist()}
                          for n, (K, C) in setup.bearings_at(rpm * 2 * math.pi / 60).items()} for rpm in SPEEDS_RPM}
    return {'rotor': rotor, 'bearings': brg, 'bearings_frame': "our (x, y), force on the shaft -K q - C q'",
            'lateral_modes': modes, 'healthy_1x': healthy_table(setup)}


def fault_job(set_name, name, out, plain=True, do_ladder=True):
    """Simulate one fault on one rotor set, write its .npz files; return its README entry (a worker with --jobs)."""
    setup = Setup(set_name)
    t0 = time.time()

    def log(s):
        print(s, flush=True)

    log(f'{set_name} {name}: {setup.params(name)}')
    recs, rows = run_fault(setup, name, log=log)
    files = {}
    for rid, (run, pieces) in recs.items():
        path = write_npz(Path(out) / f"{name}{SETS[set_name]['suffix']}_{rid}.npz", run, pieces, setup.rig.name)
        files[rid] = {'file': path.name, 'bytes': path.stat().st_size}
    checked = [r['dt_check'] for r in rows if 'skipped' not in r['dt_check']]
    entry = {'parameters': {k: v for k, v in setup.params(name).items()
                            if k not in ('ladder', 'ladder_cases', 'plain_cases')},
             'files': files,
             'dt_check_worst': {k: max((c[k] for c in checked), default=None)
                                for k in ('max_rel_to_1x', 'max_rel_to_largest', 'max_rel_own',
                                          'half_orders_max_rel_to_1x', 'half_orders_max_rel_to_largest',
                                          'half_orders_max_rel_own')},
             'steady_worst': {'1x_change': max(r['steady_1x_change'] for r in rows),
                              '2x3x_change': max(r['steady_2x3x_change'] for r in rows)}}
    if name == 'rub':
        entry['contact_speeds_rpm'] = {rid: [r['rpm'] for r in rows if r['run'] == rid and r['contact_fraction'] > 0]
                                       for rid in recs}
    entry['truth'] = fault_truth(setup, name)
    entry['per_speed'] = rows
    if do_ladder:
        entry['ladder'] = ladder(setup, name, log=log)
    if plain:
        entry['plain_check'] = plain_check(setup, name, log=log)
    entry['seconds'] = time.time() - t0
    log(f'{set_name} {name}: done in {entry["seconds"]:.0f} s')
    return set_name, name, entry


def fault_truth(setup, name):
    """
    Return what ROSS's own fault object says about the fault's size, for the tests to compare diagnose with.

    misalignment: the 2X reaction force of ``MisalignmentFlex._parallel`` on each node of its element, over one
    revolution, split into forward and backward parts [N] (x = Re{X e^(j 2 angle)}, forward: Y = -j X); crack: the
    cracked element (1-based nodes) and ROSS's depth (its depth is not what diagnose reports: it gives the crack's
    compliance); rub: the contact node, clearance [m], contact stiffness [N/m] and friction coefficient.
    """
    p = setup.params(name)
    if name == 'misalignment':
        f = make_fault(setup.rotor_at(100.0), name, p)
        ang = np.linspace(0.0, 2.0 * math.pi, 512, endpoint=False)
        F = f._parallel(ang)
        out = {}
        for label, (ix, iy) in (('node_a', (f.dofs[0], f.dofs[1])), ('node_b', (f.dofs[6], f.dofs[7]))):
            X = 2.0 * np.mean(F[ix] * np.exp(-2j * ang))
            Y = 2.0 * np.mean(F[iy] * np.exp(-2j * ang))
            out[label] = {'forward_N': float(abs(X + 1j * Y) / 2), 'backward_N': float(abs(X - 1j * Y) / 2)}
        return {'element_nodes': [p['element'] + 1, p['element'] + 2], 'force_2x': out}
    if name == 'crack':
        return {'element_nodes': [p['element'] + 1, p['element'] + 2], 'depth_ratio': p['depth_ratio'],
                'crack_model': p['crack_model']}
    if name == 'rub':
        return {'node': p['element'] + 1, 'clearance_m': p['distance'], 'contact_stiffness': p['contact_stiffness'],
                'friction': p['friction_coeff']}
    raise ValueError(name)


def _rounded(v, digits=7):
    """Return ``v`` with every float rounded to ``digits`` significant digits (a compact README)."""
    if isinstance(v, float):
        return float(f'{v:.{digits}g}')
    if isinstance(v, dict):
        return {k: _rounded(x, digits) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_rounded(x, digits) for x in v]
    return v


def readme_header():
    """Return README.json's description of the files (everything but the rotor sets)."""
    return {
        'generator': 'scripts/ross_faults.py',
        'command': '/tmp/rossenv/bin/python scripts/ross_faults.py --jobs 2   (a venv with ross-rotordynamics==2.3.0, '
                   'pandas<3, plotly<7, pyyaml; see the script docstring; ~25 min on 2 busy cores)',
        'ross_version': rs.__version__, 'numpy_version': np.__version__, 'params': 'params/rig.yaml',
        'speeds_rpm': SPEEDS_RPM, 'sample_rate': FS, 'keep_seconds_per_speed': KEEP,
        'samples': 'float32 samples (m), angle (rad; rounded by < 1e-4 rad) and speed (rad/s); noise-free; one steady '
                   'segment per speed, the speed stepping at once between them',
        'probes': {'p6x': [PROBE_NODE, 'x'], 'p6y': [PROBE_NODE, 'y']},
        'units': 'm, rad, rad/s in the npz; um here (amp_um: harmonic amplitudes of the kept part of each speed by '
                 'order, "0" = the mean; phasor_um: x = Re{X e^(j k angle)})',
        'conventions': 'x horizontal, y up, gravity -y, spin +x -> +y; angle = ROSS shaft angle (+ whole turns); '
                       'unbalance force me w^2 [cos(angle + phase), sin(angle + phase)]; 1-based nodes',
        'method': ' '.join(__doc__.split('How each speed is simulated')[1].split('Time step')[0].split()),
        'time_step': ' '.join(__doc__.split('Time step')[1].split('Recordings')[0].split()),
        'ross_notes': ROSS_NOTES,
        'one_step_late': 'ROSS newmark: RHS(step) = F[step] + add_to_RHS(step, state of step - 1); the crack force '
                         '(K_elem - K_crack(angle[step])) q[step - 1], the rub force from q[step - 1] and dq/dt[step '
                         '- 1]; '
                         'the misalignment force is a function of angle[step] only (not late)',
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('faults', nargs='*', default=list(FAULTS), help=f'of {list(FAULTS)} (default: all of a set)')
    ap.add_argument('--set', dest='sets', nargs='+', choices=list(SETS), default=list(SETS), help='rotor sets')
    ap.add_argument('--out', default=str(OUT))
    ap.add_argument('--jobs', type=int, default=1, help='(set, fault) jobs simulated in parallel processes')
    ap.add_argument('--no-plain', action='store_true', help='skip the check against ROSS run_* from rest')
    ap.add_argument('--no-ladder', action='store_true', help='skip the step-halving ladder')
    ap.add_argument('--truth-only', action='store_true',
                    help="only (re)write each fault's 'truth' (what ROSS's fault object says) into README.json")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    meta_path = out / 'README.json'
    meta = json.loads(meta_path.read_text()) if meta_path.exists() else {}
    if args.truth_only:
        for s, entry in meta.get('sets', {}).items():
            for name, fault in entry.get('faults', {}).items():
                fault['truth'] = fault_truth(Setup(s), name)
        meta_path.write_text(json.dumps(_rounded(meta), indent=1) + '\n')
        print(f'wrote the truth of every fault into {meta_path}')
        return
    meta = dict(readme_header(), sets=meta.get('sets', {}))
    meta.setdefault('sets', {})
    jobs = [(s, f, str(out), SETS[s]['plain'] or f in SETS[s].get('plain_faults', []),
             SETS[s]['ladder'] or f in SETS[s].get('ladder_faults', []))
            for s in args.sets for f in SETS[s]['faults'] if f in args.faults]
    jobs = [(s, f, o, pl and not args.no_plain, la and not args.no_ladder) for s, f, o, pl, la in jobs]
    if args.jobs > 1 and len(jobs) > 1:
        import multiprocessing as mp
        with mp.get_context('fork').Pool(min(args.jobs, len(jobs))) as pool:
            done = pool.starmap(fault_job, jobs, chunksize=1)
    else:
        done = [fault_job(*j) for j in jobs]
    for s in {j[0] for j in jobs}:
        entry = meta['sets'].setdefault(s, {})
        entry.update(set_description(Setup(s)))
        entry.setdefault('faults', {})
    for s, name, entry in done:
        meta['sets'][s]['faults'][name] = entry
    for s in meta['sets']:
        meta['sets'][s]['faults'] = {k: meta['sets'][s]['faults'][k] for k in FAULTS if k in meta['sets'][s]['faults']}
    meta['sets'] = {k: meta['sets'][k] for k in SETS if k in meta['sets']}
    meta_path.write_text(json.dumps(_rounded(meta), indent=1) + '\n')
    total = sum(f.stat().st_size for f in out.iterdir())
    print(f'wrote {meta_path} and {sorted(f.name for f in out.glob("*.npz"))}: {total / 1e6:.2f} MB in all')


if __name__ == '__main__':
    main()
