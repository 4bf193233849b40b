"""
The simulated test rig: what a DAQ on the paper's machine would record, from a truth model that differs from theory.

Physics of the simulation
    At each constant-speed segment the truth system  M q'' + (C + Cb + Omega G) q' + (K + Kb) q = f(t)  is linear and
    time invariant, and every excitation is a sum of sinusoids in the rotor angle phi: f = sum_r Re{F_r exp(j r phi)}.
    The response is computed exactly (no zero-order hold on the force): the particular solution of each harmonic,
    q_r = Z(r Omega)^-1 F_r, plus the homogeneous solution exp(A (t - t0)) x_h(t0) evaluated through the eigen-
    decomposition of A.  The state is continuous across speed changes, so transients after each step are right too.
    A mode of the transient is evaluated until its largest contribution to a probe has decayed below
    :data:`TRANSIENT_FLOOR` times the steady response (all the modes left out together stay below that bound).
    A speed ramp is approximated by short constant-speed steps (``ramp_step`` seconds) with a continuous rotor angle.

    The run starts in the steady state of its first segment (the machine was already running).

Truth versus theory
    The truth bearings come from the bearing model with viscosity and clearance scaled by ``simulation.truth``
    factors (default x1.25 and x0.8); the nominal params give the theory the estimator starts from.

Noise
    Gaussian, independent per channel, std = ``noise`` x RMS of that channel's clean signal in that speed segment
    (in each piece of :data:`PIECE_SAMPLES` of a longer segment).

Streaming
    :func:`simulate_stream` computes a run piece by piece as it is consumed (the sensor_driver's sim source: the first
    block goes out at once and memory stays bounded for any length); :func:`simulate` collects it into a Recording.

Validity
    :func:`check_validity` flags orbits larger than 30 % of the radial clearance at a bearing and speeds at or above
    the stability threshold; the paper's own unbalance (``scenario('paper_table3')``) trips both at higher speeds.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import math

import numpy as np

from ..config.params import ExcitationEntry, RigParams, Run
from ..conventions import orbit_semi_axes, rpm_to_rad_s
from ..excitation import harmonic_forces
from ..identify.harmonics import HarmonicData
from ..rotor import supports
from ..rotor.assembly import (film_dofs, first_order, harmonic_response, probe_matrix, RotorModel,
                              system_matrices as rotor_system)
from ..signals.recording import Recording

ORBIT_LIMIT = 0.30          # fraction of radial clearance the linear bearing model is trusted to
DEFAULT_RAMP_STEP = 0.01    # s, constant-speed step length used to approximate a speed ramp


# ------------------------------------------------------------------------------------------------- schedules
@dataclass(frozen=True)
class Segment:
    """One constant-speed piece of a schedule: ``speed`` [rad/s] for ``duration`` [s]."""

    speed: float
    duration: float
    steady: bool = True      # False for the short steps that approximate a ramp


def step_schedule(speeds_rpm, dwell: float, ramp: float = 0.0) -> list[Segment]:
    """
    Dwell at each speed [rpm] for ``dwell`` [s], moving between speeds by linear ramps of ``ramp`` [s].

    ``ramp = 0`` gives instant steps (which ring lightly damped modes well into the next dwell).
    """
    out: list[Segment] = []
    for i, s in enumerate(speeds_rpm):
        if i and ramp > 0:
            out += ramp_schedule(speeds_rpm[i - 1], s, ramp)
        out.append(Segment(float(rpm_to_rad_s(s)), float(dwell)))
    return out


def ramp_schedule(rpm0: float, rpm1: float, duration: float, step: float = DEFAULT_RAMP_STEP) -> list[Segment]:
    """Linear speed ramp from ``rpm0`` to ``rpm1`` over ``duration`` [s], as constant steps of ``step`` [s]."""
    n = max(1, int(round(duration / step)))
    mids = np.linspace(rpm0, rpm1, n + 1)
    mids = 0.5 * (mids[:-1] + mids[1:])
    return [Segment(float(rpm_to_rad_s(s)), duration / n, steady=False) for s in mids]


# ------------------------------------------------------------------------------------------------- truth model
def truth_bearing_fn(rig: RigParams, loads=None):
    """
    Speed -> {node: (K, C)} of the simulated machine's real bearings (truth factors applied).

    ``loads`` {node: N}: the static loads when already known (default: :func:`bearing_id.rotor.supports.static_loads`).
    """
    t = rig.simulation.truth
    return supports.bearing_fn(rig, model=t.bearing_model, viscosity_factor=t.viscosity_factor,
                               clearance_factor=t.clearance_factor, k_factor=t.k_factor or None,
                               c_factor=t.c_factor or None, loads=loads)


def system_matrices(model, speed: float, coeffs: dict, effects=()):
    """
    Truth (M, C, K) at ``speed`` [rad/s]: rotor + bearings (+ gyroscopics in C), then each effect's changes.

    Effects may append DOFs; the first ``model.ndof`` DOFs stay the rotor's.  Returned arrays are fresh copies.
    """
    M, C, K = (a.copy() for a in rotor_system(model, speed, coeffs))
    for e in effects:
        if hasattr(e, 'modify_system'):
            M, C, K = e.modify_system(M, C, K, speed, model)
    return M, C, K


def _segment_forces(entries, effects, speed, n_nodes, ndof):
    forces = harmonic_forces(entries, speed, n_nodes)
    out = {}   # padded to the truth system's DOFs (pedestals, effects)
    for r, f in forces.items():
        g = np.zeros(ndof, dtype=complex)
        g[:f.size] = f
        out[r] = g
    for e in effects:
        if hasattr(e, 'forces'):
            for r, f in e.forces(speed, ndof).items():
                g = out.setdefault(float(r), np.zeros(ndof, dtype=complex))
                g[:len(f)] += f
    return out


def steady_state_response(model, speed, coeffs, entries, effects=()):
    """Steady-state displacement phasors {ratio: q (ndof_total,)} [m] of the truth system at ``speed`` [rad/s]."""
    M, C, K = system_matrices(model, speed, coeffs, effects)
    out = {}
    for r, f in _segment_forces(entries, effects, speed, model.n_nodes, M.shape[0]).items():
        w = r * speed
        out[r] = np.linalg.solve(K - w * w * M + 1j * w * C, f)
    return out


# ------------------------------------------------------------------------------------------------- simulation
PIECE_SAMPLES = 1 << 16     # samples a simulated run is computed in at most (6.4 s at 10,240 Hz): bounds memory
TRANSIENT_ROWS = 4096       # samples per evaluation of the transient (rows x 2 ndof complex exponentials in memory)
TRANSIENT_FLOOR = 1e-12     # [-] modes of the transient left out, together, below this times the steady response


def transient_ends(lam, amplitude, floor: float):
    """
    Return [s] how long each mode of a transient matters: until ``amplitude`` exp(Re(lam) t) < floor / n_modes.

    lam (n,) eigenvalues [1/s], amplitude (n,) each mode's largest contribution to a probe at t = 0 [m]; so the modes
    left out at any time sum to less than ``floor`` [m].  Modes that do not decay (Re lam >= 0) last for ever.
    """
    eps = floor / max(1, lam.size)
    decay = -np.real(lam)
    with np.errstate(divide='ignore'):
        ratio = np.log(np.maximum(amplitude, 1e-300) / eps)
    out = np.where(ratio > 0, ratio / np.where(decay > 0, decay, 1.0), 0.0)
    return np.where((decay <= 0) & (amplitude > eps), np.inf, out)


@dataclass
class SimulatedRun:
    """
    One excitation run over a speed schedule, simulated piece by piece on demand (see :func:`simulate_stream`).

    Known at once (no physics computed): ``sample_rate`` [Hz], ``probes``, ``run``, ``rig_name``, ``n_samples`` and
    ``segments`` [(i0, i1, speed [rad/s], steady)].  :meth:`pieces` computes the samples in order, at most
    :data:`PIECE_SAMPLES` at a time; ``truth_coefficients`` {speed: {node: (K, C)}} fills in as segments are computed.
    """

    sample_rate: float
    probes: tuple
    run: Run
    rig_name: str
    segments: list
    description: str
    effects: tuple
    _solve: object = dataclasses.field(repr=False, default=None)
    truth_coefficients: dict = dataclasses.field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        return self.segments[-1][1] if self.segments else 0

    def pieces(self):
        """Yield (i0, speed (n,) [rad/s], angle (n,) [rad], samples (n, nch) [m]) in order; restarts on each call."""
        return self._solve(self)


def run_seed(seed: int, run_id: str, pass_index: int = 0) -> int:
    """Return the noise seed of run ``run_id`` (pass ``pass_index`` of a repeated plan) from the rig's ``seed``."""
    return (seed * 1000003 + sum(map(ord, run_id)) + 104729 * pass_index) % (2**32)


def simulate_stream(rig: RigParams, run: Run, schedule: list[Segment], *, probes=None, noise=None, seed=None,
                    bearing_fn=None, effects=(), sample_rate=None, model=None, t0: float = 0.0,
                    truth_changes=(), truth_at=None) -> SimulatedRun:
    """
    Simulate one excitation run over a speed ``schedule``, lazily.

    Returns a :class:`SimulatedRun` whose pieces are computed when iterated, so a stream of any length starts at once
    in bounded memory.

    Parameters
    ----------
    rig
        the rig parameters (geometry, probes, simulation defaults).
    run
        the known excitation (unbalance masses and/or shaker forces).
    schedule
        list of :class:`Segment` (constant speed pieces).
    probes
        channels to record (default ``rig.probes``).
    noise
        std as a fraction of each channel's RMS per segment (per piece of a longer segment; default
        ``rig.simulation.noise``).
    seed
        noise seed (default :func:`run_seed` of ``rig.simulation.seed`` and the run id).
    bearing_fn
        speed -> {node: (K, C)} of the real bearings (default :func:`truth_bearing_fn`).
    effects
        truth effects (see docs/ARCHITECTURE.md) hidden from the nominal model.
    sample_rate
        Hz (default ``rig.simulation.sample_rate``).
    model
        the rig's FE rotor model, if already built (default: built from ``rig``).
    t0
        [s] the run's first sample in the time of a longer stream (for ``truth_changes``).
    truth_changes
        [(t [s], bearing_fn)] the machine changing while it runs (wear, oil temperature): from the first segment that
        starts at or after stream time t, the bearings are that ``bearing_fn``'s (:func:`changed_truth`); the state
        carries over as at any segment boundary.
    truth_at
        stream time t [s] -> bearing_fn: the machine at every segment's start (an operating profile,
        :meth:`bearing_id.simulation.operation.Operation.truth_at`); replaces ``bearing_fn`` and ``truth_changes``.

    """
    sim = rig.simulation
    model = model or RotorModel.from_params(rig)
    probes = tuple(probes if probes is not None else rig.probes)
    fs = float(sample_rate or sim.sample_rate)
    noise = sim.noise if noise is None else float(noise)
    desc = 'truth bearings: ' + ('custom bearing_fn' if bearing_fn is not None else
                                 f'{sim.truth.bearing_model} model, viscosity x{sim.truth.viscosity_factor}, '
                                 f'clearance x{sim.truth.clearance_factor}')
    bearing_fn = bearing_fn or truth_bearing_fn(rig)
    if seed is None:
        seed = run_seed(sim.seed, run.id)
    S0 = probe_matrix(model, probes)       # (nch, model.ndof): probes at any angle, with their gain
    changes = sorted(((float(t), fn) for t, fn in truth_changes), key=lambda c: c[0])
    # sample counts from cumulative segment boundaries, so that short ramp steps lose no time to rounding
    edges = np.round(np.cumsum([0.0] + [s.duration for s in schedule]) * fs).astype(int)
    counts = [max(1, int(c)) for c in np.diff(edges)]
    starts = np.cumsum([0] + counts)
    segments = [(int(a), int(a + n), float(s.speed), bool(s.steady)) for a, n, s in zip(starts, counts, schedule)]

    def solve(out: SimulatedRun):
        rng = np.random.default_rng(seed)
        x_prev = None          # state [q; q'] at the first sample of the next segment (continuity)
        phi0 = 0.0
        for i0, i1, W, _ in out.segments:
            n = i1 - i0
            fn = bearing_fn
            for t_change, changed in changes:
                if t0 + i0 / fs >= t_change:
                    fn = changed
            if truth_at is not None:
                fn = truth_at(t0 + i0 / fs)
            coeffs = fn(W)
            out.truth_coefficients.setdefault(W, {k: (np.array(v[0]), np.array(v[1])) for k, v in coeffs.items()})
            M, C, K = system_matrices(model, W, coeffs, effects)
            nd = M.shape[0]
            forces = _segment_forces(run.excitation, effects, W, model.n_nodes, nd)
            # particular (steady-state) solution, harmonic by harmonic: state phasor [q; j w q] per ratio
            xph, yph = {}, {}
            for r, f in forces.items():
                w = r * W
                q = np.linalg.solve(K - w * w * M + 1j * w * C, f)
                xph[r] = np.concatenate([q, 1j * w * q])
                yph[r] = S0 @ q[:S0.shape[1]]

            def particular_state(angle_now):
                return sum((np.real(X * np.exp(1j * r * angle_now)) for r, X in xph.items()), np.zeros(2 * nd))

            # homogeneous part carrying the transient from the previous segment
            lam = None
            if x_prev is not None:
                xh0 = x_prev[:2 * nd] if x_prev.size >= 2 * nd else np.pad(x_prev, (0, 2 * nd - x_prev.size))
                xh0 = xh0 - particular_state(phi0)
                if np.any(xh0):
                    lam, V = np.linalg.eig(_state_matrix(M, C, K))
                    c = np.linalg.solve(V, xh0)
                    yV = S0 @ V[:S0.shape[1], :]
                    steady = sum((np.abs(v) for v in yph.values()), np.zeros(S0.shape[0]))
                    amp = np.abs(c) * np.max(np.abs(yV), axis=0)
                    floor = TRANSIENT_FLOOR * (np.max(steady) if np.max(steady) > 0 else np.sum(amp))
                    t_end = transient_ends(lam, amp, floor)
            for a in range(0, n, PIECE_SAMPLES):
                tau = np.arange(a, min(n, a + PIECE_SAMPLES)) / fs
                phi = phi0 + W * tau
                y = np.zeros((tau.size, len(probes)))
                for r, yr in yph.items():
                    y += np.real(np.outer(np.exp(1j * r * phi), yr))
                for k in range(0, tau.size if lam is not None else 0, TRANSIENT_ROWS):
                    tk = tau[k:k + TRANSIENT_ROWS]
                    live = np.flatnonzero(t_end > tk[0])
                    if live.size == 0:
                        break
                    y[k:k + tk.size] += np.real((np.exp(np.outer(tk, lam[live])) * c[live]) @ yV[:, live].T)
                speed = np.full(tau.size, W)
                for e in effects:
                    if hasattr(e, 'measure'):
                        y = e.measure(y, phi, speed, probes)
                if noise > 0:
                    rms = np.sqrt(np.mean(y ** 2, axis=0))
                    y = y + rng.standard_normal(y.shape) * (noise * rms)
                yield i0 + a, speed, phi, y
            # state at the first sample of the next segment (exact propagation over the whole segment)
            phi_end = phi0 + W * n / fs
            xh_end = np.real(V @ (np.exp(lam * (n / fs)) * c)) if lam is not None else np.zeros(2 * nd)
            x_prev = particular_state(phi_end) + xh_end
            phi0 = phi_end

    return SimulatedRun(sample_rate=fs, probes=probes, run=run, rig_name=rig.name, segments=segments,
                        description=desc, effects=tuple(type(e).__name__ for e in effects), _solve=solve)


def simulate(rig: RigParams, run: Run, schedule: list[Segment], **kw) -> Recording:
    """
    Simulate one excitation run over a speed ``schedule`` into a Recording (samples (N, nch) in metres).

    Keywords as :func:`simulate_stream`, which computes it piece by piece.
    """
    s = simulate_stream(rig, run, schedule, **kw)
    N = s.n_samples
    speed, angle, samples = np.empty(N), np.empty(N), np.empty((N, len(s.probes)))
    for i0, w, a, y in s.pieces():
        sl = slice(i0, i0 + w.size)
        speed[sl], angle[sl], samples[sl] = w, a, y
    return Recording(sample_rate=s.sample_rate, t=np.arange(N) / s.sample_rate, speed=speed, angle=angle,
                     probes=s.probes, samples=samples, run=run, segments=list(s.segments),
                     truth={'coefficients': s.truth_coefficients, 'description': s.description,
                            'effects': list(s.effects)},
                     rig_name=rig.name)


def _state_matrix(M, C, K):
    return first_order(np.linalg.inv(M), C, K)


def run_schedule(rig: RigParams, speeds_rpm=None, dwell=None, ramp=None) -> list[Segment]:
    """Return the step schedule through ``speeds_rpm``: ``dwell`` s each, ``ramp`` s ramps (default: the rig's)."""
    sim = rig.simulation
    return step_schedule(speeds_rpm if speeds_rpm is not None else sim.speeds_rpm,
                         dwell if dwell is not None else sim.dwell, sim.ramp if ramp is None else ramp)


def simulate_run(rig: RigParams, run: Run, speeds_rpm=None, dwell=None, ramp=None, **kw) -> Recording:
    """
    Step through ``speeds_rpm`` (default ``rig.simulation.speeds_rpm``) dwelling ``dwell`` s at each.

    With ``ramp`` s linear speed ramps between dwells (defaults from ``rig.simulation``); :func:`run_schedule`.
    """
    return simulate(rig, run, run_schedule(rig, speeds_rpm, dwell, ramp), **kw)


def simulate_plan(rig: RigParams, runs=None, **kw) -> list[Recording]:
    """One recording per excitation run (default: ``rig.simulation.runs``)."""
    return [simulate_run(rig, r, **kw) for r in (runs if runs is not None else rig.simulation.runs)]


# ------------------------------------------------------------------------------------------------- scenarios
def scenario(name: str) -> list[Run]:
    """
    Named excitation plans.

    * ``paper_table3``: the paper's simulation, 4 g x 63 mm at node 8, 90 deg (orbits reach the clearance near 1800 rpm
      on this rig: trips the validity warnings on purpose).
    * ``paper_table4``: the paper's experiment, 2.5 g x 63 mm at node 4 (0 deg) and 5 g x 63 mm at node 8 (90 deg).
    * ``force``: a directional shaker (2 N, synchronous) in x, then in y, at each disc (nodes 4 and 8): 4 runs.
    """
    def ub(node, grams, deg):
        return ExcitationEntry('unbalance', node, grams * 1e-3 * 0.063, math.radians(deg), 'forward', 1.0)

    def sh(node, direction, amp=2.0):
        return ExcitationEntry('force', node, amp, 0.0, direction, 1.0)

    if name == 'paper_table3':
        return [Run('T3', (ub(8, 4.0, 90.0),))]
    if name == 'paper_table4':
        return [Run('T4', (ub(4, 2.5, 0.0), ub(8, 5.0, 90.0)))]
    if name == 'force':
        return [Run(f'F{n}{d}', (sh(n, d),)) for n in (4, 8) for d in ('x', 'y')]
    raise ValueError(f'unknown scenario {name!r}: paper_table3, paper_table4, force')


# ------------------------------------------------------------------------------------------------- validity
@dataclass(frozen=True)
class ValidityIssue:
    kind: str            # 'orbit' | 'stability'
    speed: float         # rad/s
    where: str
    value: float
    limit: float
    message: str


def check_validity(rig: RigParams, runs, speeds, *, bearing_fn=None, threshold=None, model=None) -> list[ValidityIssue]:
    """
    Flag speeds where the linear bearing model is not to be trusted.

    Orbit: the 1X orbit's semi-major axis at a bearing node > ORBIT_LIMIT x radial clearance (true clearance when the
    truth factors are used).  Stability: speed >= ``threshold`` [rad/s] (pass the stability threshold; None skips).
    """
    model = model or RotorModel.from_params(rig)
    bearing_fn = bearing_fn or truth_bearing_fn(rig)
    cfac = rig.simulation.truth.clearance_factor if rig.simulation else (1.0,) * len(rig.bearings)
    out = []
    for W in speeds:
        coeffs = bearing_fn(W)
        for run in runs:
            resp = steady_state_response(model, W, coeffs, run.excitation)
            q = resp.get(1.0)
            if q is None:
                continue
            for b, cf in zip(rig.bearings, cfac):
                ix, jp = film_dofs(model, b.node)          # the journal in its bearing (minus the pedestal, if any)
                dx, dy = (q[ix], q[ix + 1]) if jp is None else (q[ix] - q[jp], q[ix + 1] - q[jp + 1])
                major, _ = orbit_semi_axes(dx, dy)
                lim = ORBIT_LIMIT * b.clearance * cf
                if major > lim:
                    out.append(ValidityIssue('orbit', float(W), f'run {run.id}, {b.name} (node {b.node})', major, lim,
                                             f'orbit {major * 1e6:.1f} um > {ORBIT_LIMIT:.0%} of clearance '
                                             f'({b.clearance * cf * 1e6:.1f} um) at {W * 60 / (2 * math.pi):.0f} rpm'))
        if threshold is not None and W >= threshold:
            out.append(ValidityIssue('stability', float(W), 'rotor-bearing system', W, threshold,
                                     f'{W * 60 / (2 * math.pi):.0f} rpm is at or above the stability threshold '
                                     f'{threshold * 60 / (2 * math.pi):.0f} rpm (oil whip)'))
    return out


def changed_truth(rig: RigParams, clearance=1.0, viscosity=1.0):
    """
    Return the bearing_fn of ``rig``'s truth bearings with clearance and viscosity multiplied.

    ``clearance``, ``viscosity``: one factor for every bearing, or one per bearing.  The machine after a change: wear
    opens the clearance, the oil temperature moves the viscosity (for :func:`simulate_stream`'s ``truth_changes`` and
    ``truth_at``).
    """
    t = rig.simulation.truth
    n = len(rig.bearings)

    def scaled(factors, by):
        base = factors if isinstance(factors, (tuple, list)) else (1.0 if factors is None else factors,) * n
        by = tuple(by) if isinstance(by, (tuple, list)) else (by,) * n
        if len(by) != n:
            raise ValueError(f'{len(by)} factors for {n} bearings')
        return tuple(float(f) * float(b) for f, b in zip(base, by))
    # the statics (rigid supports) do not depend on clearance or viscosity: solved once per rig object
    return truth_bearing_fn(with_truth(rig, clearance_factor=scaled(t.clearance_factor, clearance),
                                       viscosity_factor=scaled(t.viscosity_factor, viscosity)),
                            loads=supports.static_loads(rig))


def with_truth(rig: RigParams, **kw) -> RigParams:
    """Copy of ``rig`` with simulation.truth fields replaced (e.g. bearing_model='finite')."""
    sim = rig.simulation
    return rig.replace(simulation=dataclasses.replace(sim, truth=dataclasses.replace(sim.truth, **kw)))


def simulate_data(rig, runs, speeds_rpm, *, probes=None, noise=0.0, bearing_fn=None, model=None) -> HarmonicData:
    """
    Noise-free (or analytic-noise) 1X phasors straight from the truth system -- no time series (tests, design).

    X[r, s] = S q with q = Z(speed)^-1 F_r the steady response of the truth bearings ``bearing_fn`` (default the rig's
    truth); with ``noise`` > 0 a complex Gaussian error of std ``noise * |X| / sqrt(2)`` per Re/Im is NOT added here
    (the caller adds it with its own seed) but recorded in X_std.
    """
    model = model or RotorModel.from_params(rig)
    probes = tuple(probes if probes is not None else rig.probes)
    bearing_fn = bearing_fn or truth_bearing_fn(rig)
    speeds = np.array([float(rpm_to_rad_s(s)) for s in speeds_rpm])
    S = probe_matrix(model, probes)
    X = np.zeros((len(runs), len(speeds), len(probes)), dtype=complex)
    truth = {}
    for j, w in enumerate(speeds):
        co = bearing_fn(w)
        truth[float(w)] = co
        for i, run in enumerate(runs):
            F = harmonic_forces(run.excitation, w, model.n_nodes, model.ndof).get(1.0)
            if F is not None:
                X[i, j] = S @ harmonic_response(model, w, w, F, co)
    Xs = noise * np.abs(X) / math.sqrt(2)
    return HarmonicData(speeds, probes, tuple(runs), X, Xs, [], [], truth)
