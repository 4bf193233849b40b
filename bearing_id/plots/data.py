"""
The numbers behind the report's figures -- plain numpy/scipy, no matplotlib (so they can be tested on their own).

Every figure module in :mod:`bearing_id.plots` draws what these functions return; every number comes from the same
physics modules the CLI prints from (:mod:`bearing_id.rotor.modal`, :mod:`bearing_id.rotor.stability`,
:func:`bearing_id.rotor.assembly.harmonic_response`, the identification results), never from a second copy.
SI units inside (rad/s, m, N/m, N s/m); the ``*_rpm`` / ``*_hz`` / ``*_um`` properties are for people.

* :func:`campbell_data` -- damped frequencies, log decrements and whirl vs speed, the synchronous critical speeds
  (:func:`bearing_id.rotor.modal.critical_speeds`, the same call as ``bearing-id model``) and the stability threshold
  with the whirl ratio of the mode that goes unstable.
* :func:`mode_shapes` -- complex mode shapes along the shaft (x and y planes, envelope, whirl per node).
* :func:`identified_bearing_fn` -- a continuous bearing model from identification results: the ``physical`` fit's
  bearing model with the fitted parameters (exactly the coefficients the results hold), or a monotone cubic
  (PCHIP) interpolation of fully determined coefficients between the test speeds (exact at them).
* :func:`response_curves` -- the model's 1X response at the probes over a speed grid (the continuous Bode / polar
  curve); :func:`curve_speeds` makes a grid that contains the test speeds.
* :func:`journal_positions` -- journal centre in the clearance circle vs speed from a bearing model.
* :func:`amplitude_spectrum`, :func:`waterfall_data` -- amplitude spectra of each steady window.
* :func:`orbit_data` -- unfiltered and 1X-filtered orbits with keyphasor marks.
* :func:`diagnosis_curves` -- measured / nominal / refitted / augmented 1X of a :class:`bearing_id.diagnose.Diagnosis`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np
from scipy.interpolate import PchipInterpolator

from ..conventions import DOF_PER_NODE, LOCAL_DOF, orbit_semi_axes, probe_row, RPM_PER_RAD_S, whirl_direction
from ..excitation import harmonic_forces
from ..rotor import stability, supports
from ..rotor.assembly import dynamic_stiffness, probe_matrix
from ..rotor.modal import campbell, critical_speeds, modes_solver

TWO_PI = 2.0 * math.pi
ORDERS = (0.5, 1.0, 2.0)          # the order lines of the Campbell diagram and the spectra


# ------------------------------------------------------------------------------------------------ Campbell
CRITICALLY_DAMPED = 0.2    # damping ratio above which a 1X crossing is critically damped (API 684: amplification < 2.5)


@dataclass
class CampbellData:
    """
    Campbell diagram of one rotor-bearing model.

    speeds (ns,) rad/s; frequency, log_dec, damping_ratio (ns, n) [rad/s, -, -] (NaN where fewer modes); whirl (ns, n)
    'forward'/'backward'; critical (nc,) rad/s synchronous critical speeds (a forward mode = 1X with damping ratio <=
    :data:`CRITICALLY_DAMPED`); critical_zeta (nc,) damping ratio of that mode there; damped_crossings,
    damped_crossings_zeta: the 1X crossings of more heavily damped forward modes (API 684: no resonance to speak of, not
    critical speeds) and their damping ratios; threshold rad/s (inf: stable over the range, None: not computed / already
    unstable at the low end); threshold_ratio: whirl frequency / speed of the mode that goes unstable; label: which
    bearings (for titles); notes: what could not be computed.
    """

    speeds: np.ndarray
    frequency: np.ndarray
    log_dec: np.ndarray
    damping_ratio: np.ndarray
    whirl: np.ndarray
    critical: np.ndarray
    critical_zeta: np.ndarray
    threshold: float | None
    threshold_ratio: float | None
    label: str = ''
    notes: list = field(default_factory=list)
    damped_crossings: np.ndarray = field(default_factory=lambda: np.zeros(0))
    damped_crossings_zeta: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def speeds_rpm(self) -> np.ndarray:
        return self.speeds * RPM_PER_RAD_S

    @property
    def frequency_hz(self) -> np.ndarray:
        return self.frequency / TWO_PI

    @property
    def critical_rpm(self) -> np.ndarray:
        return self.critical * RPM_PER_RAD_S

    @property
    def damped_crossings_rpm(self) -> np.ndarray:
        return self.damped_crossings * RPM_PER_RAD_S

    @property
    def threshold_rpm(self) -> float | None:
        if self.threshold is None or not np.isfinite(self.threshold):
            return None
        return float(self.threshold * RPM_PER_RAD_S)


def campbell_data(model, bearing_fn, max_speed: float, *, min_speed: float | None = None, n_modes: int = 8,
                  n_grid: int = 40, label: str = '', solver=None) -> CampbellData:
    """
    Campbell data of ``model`` on ``bearing_fn`` over (min_speed, max_speed] [rad/s].

    Critical speeds: :func:`bearing_id.rotor.modal.critical_speeds` on (lo, max_speed) with 40 grid points and
    ``n_modes`` modes (the ``bearing-id model`` call), split by the damping ratio of the crossing mode at
    :data:`CRITICALLY_DAMPED` into critical speeds and critically damped crossings; stability threshold:
    :func:`rotor.stability.threshold_speed` on (lo, max_speed), scanned on the Campbell grid (whose eigenvalues are
    computed anyway; the crossing refined by brentq) and :func:`rotor.stability.whirl_ratio` at it.  The modes by
    :func:`bearing_id.rotor.modal.modes_solver` (the reduced screen with full refinement on large models), or ``solver``
    (one from it, for these bearings).
    """
    hi = float(max_speed)
    lo = float(min_speed) if min_speed is not None else max(50.0 / RPM_PER_RAD_S, hi / 60.0)
    grid = np.linspace(lo, hi, int(n_grid))
    modes = solver or modes_solver(model, hi, bearing_fn, n_modes)
    cb = campbell(model, grid, bearing_fn, n_modes, solver=modes)
    notes = []
    crit = critical_speeds(model, bearing_fn, (lo, hi), n_grid=40, n_modes=n_modes, campbell_grid=cb, solver=modes)
    zc = []
    for c in crit:
        m = modes(c, bearing_fn(c), n_modes)
        k = int(np.argmin([abs(f - c) if w == 'forward' else np.inf for f, w in zip(m.frequency, m.whirl)]))
        zc.append(float(m.damping_ratio[k]))
    thr, ratio = None, None
    try:
        thr = stability.threshold_speed(model, bearing_fn, hi, scan=(grid, cb.max_real))
        if np.isfinite(thr):
            ratio = stability.whirl_ratio(model, bearing_fn, thr * (1 + 1e-6))
    except ValueError as exc:
        notes.append(f'stability threshold not computed: {exc}')
    crit, zc = np.asarray(crit, float), np.asarray(zc, float)
    keep = zc <= CRITICALLY_DAMPED
    return CampbellData(speeds=grid, frequency=cb.frequency, log_dec=cb.log_dec, damping_ratio=cb.damping_ratio,
                        whirl=cb.whirl, critical=crit[keep], critical_zeta=zc[keep], threshold=thr,
                        threshold_ratio=ratio, label=label, notes=notes, damped_crossings=crit[~keep],
                        damped_crossings_zeta=zc[~keep])


# ------------------------------------------------------------------------------------------------ mode shapes
@dataclass
class ModeShape:
    """
    One damped mode at one speed.

    z (n_nodes,) m; x, y complex (n_nodes,) normalised so that the largest |component| is 1; frequency rad/s; log_dec,
    damping_ratio; whirl 'forward'/'backward' (orbit-size vote); node_whirl per node; speed rad/s.
    """

    speed: float
    frequency: float
    log_dec: float
    damping_ratio: float
    whirl: str
    z: np.ndarray
    x: np.ndarray
    y: np.ndarray
    node_whirl: tuple

    @staticmethod
    def _plane(v: np.ndarray) -> np.ndarray:
        """Deflected shape of one plane: |v| with the sign of its phase relative to the largest component."""
        ref = v[int(np.argmax(np.abs(v)))]
        if abs(ref) == 0:
            return np.zeros(v.size)
        return np.real(v * np.conj(ref) / abs(ref))

    @property
    def x_plane(self) -> np.ndarray:
        return self._plane(self.x)

    @property
    def y_plane(self) -> np.ndarray:
        return self._plane(self.y)

    @property
    def envelope(self) -> np.ndarray:
        """Semi-major axis of the orbit at each node (same normalisation)."""
        return np.array([orbit_semi_axes(a, b)[0] for a, b in zip(self.x, self.y)])


def mode_shapes(model, bearing_fn, speed: float, n: int = 4, solver=None) -> list[ModeShape]:
    """
    Return the lowest ``n`` damped modes at ``speed`` [rad/s] as :class:`ModeShape` (ordered by frequency).

    The modes by :func:`bearing_id.rotor.modal.modes_solver` (dense on small models) or ``solver`` (one from it).
    """
    m = (solver or modes_solver(model, speed, bearing_fn, n))(speed, bearing_fn(speed), n)
    out = []
    for k in range(m.frequency.size):
        v = m.shapes[:, k]
        x = v[LOCAL_DOF['x']::DOF_PER_NODE].copy()
        y = v[LOCAL_DOF['y']::DOF_PER_NODE].copy()
        both = np.concatenate([x, y])
        ref = both[int(np.argmax(np.abs(both)))]
        x, y = x / ref, y / ref
        nw = tuple(whirl_direction(a, b) for a, b in zip(x, y))
        out.append(ModeShape(speed=float(speed), frequency=float(m.frequency[k]), log_dec=float(m.log_dec[k]),
                             damping_ratio=float(m.damping_ratio[k]), whirl=m.whirl[k],
                             z=np.asarray(model.node_z, float), x=x, y=y, node_whirl=nw))
    return out


def critical_mode_index(shapes, speed: float) -> int | None:
    """
    Return the index of the forward mode whose damped frequency is nearest ``speed`` [rad/s].

    That is the mode a critical speed excites.  Return None when there is no forward mode.
    """
    c = [(abs(m.frequency - speed), k) for k, m in enumerate(shapes) if m.whirl == 'forward']
    return min(c)[1] if c else None


# ------------------------------------------------------------------------------------------------ bearing models
class InterpolatedBearings:
    """
    ``speed -> {node: (K, C)}`` by monotone cubic (PCHIP) interpolation of identified coefficients in speed.

    Exact at the identification speeds; defined only on [min, max] of them (ValueError outside).
    """

    def __init__(self, results):
        rs = sorted(results, key=lambda r: r.speed)
        if len(rs) < 2:
            raise ValueError('interpolation needs results at two speeds at least')
        self.nodes = tuple(int(n) for n in rs[0].nodes)
        self.speeds = np.array([r.speed for r in rs])
        self.lo, self.hi = float(self.speeds[0]), float(self.speeds[-1])
        nb = len(self.nodes)
        Y = np.array([np.concatenate([np.asarray(r.K, float).reshape(nb, 4), np.asarray(r.C, float).reshape(nb, 4)],
                                     axis=1).reshape(-1) for r in rs])
        self._f = PchipInterpolator(self.speeds, Y, axis=0, extrapolate=False)
        self._exact = {float(r.speed): r.coeffs() for r in rs}

    def __call__(self, speed: float) -> dict:
        s = float(speed)
        if s in self._exact:
            return {n: (K.copy(), C.copy()) for n, (K, C) in self._exact[s].items()}
        if not self.lo <= s <= self.hi:
            raise ValueError(f'speed {s:.4g} rad/s outside the identified range {self.lo:.4g}..{self.hi:.4g}')
        y = self._f(s).reshape(len(self.nodes), 8)
        return {n: (y[i, :4].reshape(2, 2), y[i, 4:].reshape(2, 2)) for i, n in enumerate(self.nodes)}


@dataclass
class IdentifiedModel:
    """
    A continuous bearing model from identification.

    fn: ``speed -> {node: (K, C)}``; speed_range (lo, hi) rad/s where it is defined (None: any speed > 0); label for
    legends; kind 'physical' | 'interpolated'.
    """

    fn: object
    speed_range: tuple | None
    label: str
    kind: str


def identified_bearing_fn(results, rig) -> tuple[IdentifiedModel | None, str]:
    """
    (model, why): the identified bearings as a continuous function of speed, or (None, the reason there is none).

    * method ``physical``: the bearing model with the fitted viscosity / clearance (/ load) per bearing -- the same
      call the fit made, so it reproduces every result's K, C exactly, and it is defined at every speed;
    * any other method with every coefficient determined at 3 or more speeds: PCHIP interpolation between them;
    * otherwise None: undetermined coefficients are never drawn as a model.
    """
    if not results:
        return None, 'no identification results'
    fit = results[0].extra.get('fit') if isinstance(results[0].extra, dict) else None
    if fit is not None and hasattr(fit, 'names') and hasattr(fit, 'values'):
        if not np.all(fit.determined):
            return None, 'the physical fit leaves some bearing parameters undetermined'
        if fit.misfit:
            return None, 'the physical fit misfits the data: no identified model is drawn'
        vals = dict(zip(fit.names, np.asarray(fit.values, float)))
        if getattr(fit, 'table_form', 2) == 2:   # the bearing function's parameters: viscosity, clearance, K/C scales
            vf, cf, kf, ccf, loads = [], [], [], [], {}
            for b in rig.bearings:
                table = b.model == 'table'
                vf.append(1.0 if table else vals.get(f'{b.name}.viscosity', b.viscosity) / b.viscosity)
                cf.append(1.0 if table else vals.get(f'{b.name}.clearance', b.clearance) / b.clearance)
                kf.append(vals.get(f'{b.name}.k_scale', 1.0))
                ccf.append(vals.get(f'{b.name}.c_scale', 1.0))
                loads[b.node] = vals.get(f'{b.name}.load', fit.loads[b.node])
            fn = supports.bearing_fn(rig, model=fit.bearing_model, viscosity_factor=vf, clearance_factor=cf,
                                     loads=loads, k_factor=kf, c_factor=ccf)
            return IdentifiedModel(fn, None, f'identified ({fit.form or fit.bearing_model} bearing, fitted '
                                             'parameters)', 'physical'), ''
    if not all(r.fully_determined for r in results):
        return None, 'some coefficients are not determined by the data: no identified model is drawn'
    if len(results) < 3:
        return None, f'{len(results)} speed(s) only: too few to interpolate the coefficients between them'
    ib = InterpolatedBearings(results)
    return IdentifiedModel(ib, (ib.lo, ib.hi), 'identified (interpolated between test speeds)', 'interpolated'), ''


# ------------------------------------------------------------------------------------------------ 1X response
def curve_speeds(test_speeds, lo: float, hi: float, n: int = 160) -> np.ndarray:
    """Return a speed grid [rad/s] of ``n`` points on [lo, hi] that also contains every test speed inside it."""
    t = np.asarray(test_speeds, float)
    g = np.concatenate([np.linspace(lo, hi, n), t[(t >= lo) & (t <= hi)]])
    return np.unique(g)


def response_curves(model, bearing_fn, runs, probes, speeds) -> np.ndarray:
    """Model 1X phasors at the probes, complex (n_runs, n_speeds, n_probes) [m]: q = Z(speed)^-1 F_1X(run)."""
    S = probe_matrix(model, probes)
    speeds = np.asarray(speeds, float)
    out = np.zeros((len(runs), speeds.size, S.shape[0]), complex)
    for j, w in enumerate(speeds):
        F = np.zeros((model.ndof, len(runs)), complex)
        for i, run in enumerate(runs):
            f = harmonic_forces(run.excitation, w, model.n_nodes, model.ndof).get(1.0)
            if f is not None:
                F[:, i] = f
        if not np.any(F):
            continue
        Z = dynamic_stiffness(model, w, w, bearing_fn(w))
        out[:, j, :] = (S @ np.linalg.solve(Z, F)).T
    return out


def response_curves_adaptive(model, bearing_fn, runs, probes, test_speeds, lo: float, hi: float, *, n0: int = 120,
                             tol: float = 0.02, max_points: int = 800):
    """
    Return (speeds (ng,), Y (n_runs, ng, n_probes)) of :func:`response_curves` on an adaptively refined speed grid.

    The grid is :func:`curve_speeds` ``(test_speeds, lo, hi, n0)``, refined by bisection wherever the phasor moves by
    more than ``tol`` x its largest value between neighbouring speeds (a resonance loop is drawn round, not as a
    polygon).  The test speeds stay on the grid.
    """
    g = curve_speeds(test_speeds, lo, hi, n0)
    Y = response_curves(model, bearing_fn, runs, probes, g)
    for _ in range(6):
        scale = np.max(np.abs(Y), axis=1, keepdims=True)
        scale[scale == 0] = 1.0
        d = np.max(np.abs(np.diff(Y, axis=1)) / scale, axis=(0, 2))
        bad = np.nonzero(d > tol)[0]
        if not bad.size or g.size + bad.size > max_points:
            break
        mid = 0.5 * (g[bad] + g[bad + 1])
        Ym = response_curves(model, bearing_fn, runs, probes, mid)
        g = np.concatenate([g, mid])
        Y = np.concatenate([Y, Ym], axis=1)
        order = np.argsort(g)
        g, Y = g[order], Y[:, order]
    return g, Y


def align_phase(measured_deg, reference_deg):
    """Measured phases moved by whole turns onto the branch of the (unwrapped) reference curve [deg]."""
    m, r = np.asarray(measured_deg, float), np.asarray(reference_deg, float)
    return r + (m - r + 180.0) % 360.0 - 180.0


# ------------------------------------------------------------------------------------------------ centreline
def journal_positions(bearing_fn, speeds) -> dict | None:
    """
    Return {node: {'xy' (ns, 2) m, 'clearance' m, 'eps' (ns,), 'attitude' (ns,) rad}} from a bearing model.

    The model needs ``solutions(speed)`` (:class:`bearing_id.rotor.supports.BearingFunction`); None for a model
    without one.  Only film bearings with a known clearance have a journal position (a table bearing has none).
    """
    sol = getattr(bearing_fn, 'solutions', None)
    if sol is None:
        return None
    clearance = getattr(bearing_fn, 'clearance', {})
    out: dict = {}
    for s in speeds:
        for n, b in sol(float(s)).items():
            c = clearance.get(n)
            if c is None or not np.isfinite(c) or not np.all(np.isfinite(b.journal_position)):
                continue
            d = out.setdefault(n, {'xy': [], 'eps': [], 'attitude': []})
            d['xy'].append(np.asarray(b.journal_position, float))
            d['eps'].append(float(b.eccentricity))
            d['attitude'].append(float(b.attitude_angle))
    for n, d in out.items():
        d['xy'] = np.array(d['xy'])
        d['eps'] = np.array(d['eps'])
        d['attitude'] = np.array(d['attitude'])
        d['clearance'] = float(clearance[n])
    return out or None


# ------------------------------------------------------------------------------------------------ spectra
def amplitude_spectrum(x, sample_rate: float, fmax: float | None = None):
    """(f [Hz], amplitude) of ``x`` (N,): mean removed, Hann window, scaled so a sinusoid of amplitude A shows A."""
    x = np.asarray(x, float)
    x = x - x.mean()
    w = np.hanning(x.size)
    a = 2.0 * np.abs(np.fft.rfft(x * w)) / np.sum(w)
    f = np.fft.rfftfreq(x.size, 1.0 / sample_rate)
    if fmax is not None:
        keep = f <= fmax
        f, a = f[keep], a[keep]
    return f, a


def waterfall_data(data, run: int, channel: int, fmax: float) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """[(speed rad/s, f Hz, amplitude m)] per steady window of run ``run`` (the windows the 1X vectors used)."""
    if not data.windows or not data.recordings:
        return []
    rec = data.recordings[run]
    out = []
    for s, w in enumerate(data.windows[run]):
        if w is None:
            continue
        i0, i1 = w
        f, a = amplitude_spectrum(rec.samples[i0:i1, channel], rec.sample_rate, fmax)
        out.append((float(data.speeds[s]), f, a))
    return out


# ------------------------------------------------------------------------------------------------ orbits
@dataclass
class OrbitData:
    """
    One orbit panel.

    speed rad/s; raw (M, 2) m unfiltered x, y over the last revolutions, window mean removed; raw_key (k, 2) m keyphasor
    positions on it (angle = 0 mod 2 pi, interpolated); filt (P, 2) m the 1X ellipse; filt_key (2,) m its keyphasor
    point (angle 0); whirl of the 1X orbit; pk_pk (2,) m of the 1X x and y.
    """

    speed: float
    raw: np.ndarray
    raw_key: np.ndarray
    filt: np.ndarray
    filt_key: np.ndarray
    whirl: str
    pk_pk: np.ndarray


def orbit_data(rec, i0: int, i1: int, ix: int, iy: int, Xx: complex, Xy: complex, speed: float,
               n_rev: int = 3, to_xy=None) -> OrbitData:
    """
    Return the orbit of channels (ix, iy) of ``rec`` in samples [i0, i1).

    The last ``n_rev`` revolutions unfiltered (mean of the window removed: the DC is the centreline, not the orbit) and
    the 1X ellipse Re{X exp(j phi)}.  ``to_xy`` (2, 2): the matrix taking the two channels' readings (and their 1X
    vectors ``Xx``, ``Xy``) to the node's x and y (:func:`probe_stations`; None: the channels ARE x and y).
    """
    a = np.asarray(rec.angle[i0:i1], float)
    xy = np.asarray(rec.samples[i0:i1][:, [ix, iy]], float)
    if to_xy is not None:
        T = np.asarray(to_xy, float)
        xy = xy @ T.T
        Xx, Xy = T @ np.array([Xx, Xy], complex)
    xy = xy - xy.mean(axis=0)
    start = int(np.searchsorted(a, a[-1] - n_rev * TWO_PI))
    a, xy = a[start:], xy[start:]
    ks = np.arange(math.ceil(a[0] / TWO_PI), math.floor(a[-1] / TWO_PI) + 1) * TWO_PI
    key = np.column_stack([np.interp(ks, a, xy[:, 0]), np.interp(ks, a, xy[:, 1])]) if ks.size else np.zeros((0, 2))
    th = np.linspace(0.0, TWO_PI, 121)
    filt = np.column_stack([np.real(Xx * np.exp(1j * th)), np.real(Xy * np.exp(1j * th))])
    return OrbitData(speed=float(speed), raw=xy, raw_key=key, filt=filt,
                     filt_key=np.array([np.real(Xx), np.real(Xy)]), whirl=whirl_direction(Xx, Xy),
                     pk_pk=2.0 * np.abs([Xx, Xy]))


MIN_PAIR_SINE = 0.5       # two probes at a node give x and y when their directions are >= 30 deg from parallel


def probe_stations(probes) -> list[tuple[int, int, np.ndarray | None]]:
    """
    Return the probe stations: (i_a, i_b, to_xy) per node with two probes that together give the node's x and y.

    In node order.  An x and a y probe: ``to_xy`` None (the channels are x and y).  Otherwise (e.g. API 670 pairs at
    +-45 deg from vertical) the first two probes at the node whose measurement rows (:func:`bearing_id.conventions.
    probe_row`, gains included) are at least 30 deg from parallel, and ``to_xy`` (2, 2) the inverse of those rows:
    (x, y) = to_xy @ (reading_a, reading_b).
    """
    out = []
    for n in sorted({p.node for p in probes}):
        idx = [i for i, p in enumerate(probes) if p.node == n]
        ix = [i for i in idx if probes[i].direction == 'x']
        iy = [i for i in idx if probes[i].direction == 'y']
        if ix and iy:
            out.append((ix[0], iy[0], None))
            continue
        rows = {i: np.array(probe_row(probes[i].direction), float) for i in idx}
        for k, i in enumerate(idx):
            j = next((j for j in idx[k + 1:] if abs(rows[i][0] * rows[j][1] - rows[i][1] * rows[j][0])
                      >= MIN_PAIR_SINE * np.linalg.norm(rows[i]) * np.linalg.norm(rows[j])), None)
            if j is not None:
                out.append((i, j, np.linalg.inv(np.vstack([rows[i], rows[j]]))))
                break
    return out


# ------------------------------------------------------------------------------------------------ diagnosis
def diagnosis_curves(diag) -> dict:
    """
    Return the before/after 1X of a diagnosis, as ``diagnose --report`` draws.

    {'panels': [{'run', 'probe', 'rpm' (n,), 'measured', 'std', 'nominal', 'refitted', 'augmented' (complex (n,) m)}],
    'orders': [...], 'residual_before'/'residual_after' (per order, RMS m)} -- from the diagnosis' own predictions
    (``Problem.prediction_by_window``).
    """
    prob, sel = diag.problem, diag.selection
    base, final = sel.base, sel.final
    nom = prob.prediction_by_window(np.zeros(prob.n_nuis), [], [], np.zeros(0))
    bef = prob.prediction_by_window(base.theta, [], [], np.zeros(0))
    aft = prob.prediction_by_window(final.theta, final.effects, final.nls, final.lin)
    panels = []
    for r, rec in enumerate(prob.obs.recordings):
        ks = sorted((k for k, w in enumerate(prob.windows) if w.rec == r), key=lambda k: prob.windows[k].speed)
        if not ks:
            continue
        for c, p in enumerate(rec.probes):
            panels.append({'run': str(rec.run.id), 'probe': p,
                           'rpm': np.array([prob.windows[k].speed * RPM_PER_RAD_S for k in ks]),
                           'measured': np.array([prob.windows[k].X[0, c] for k in ks]),
                           'std': np.array([np.asarray(prob.windows[k].std)[0, c] for k in ks]),
                           'nominal': np.array([nom[k][0, c] for k in ks]),
                           'refitted': np.array([bef[k][0, c] for k in ks]),
                           'augmented': np.array([aft[k][0, c] for k in ks])})
    orders = [float(o) for o in prob.obs.orders]
    rb, ra = [], []
    for o in range(len(orders)):
        rb.append(float(np.sqrt(np.mean([np.mean(np.abs(w.X[o] - bef[k][o]) ** 2)
                                         for k, w in enumerate(prob.windows)]))))
        ra.append(float(np.sqrt(np.mean([np.mean(np.abs(w.X[o] - aft[k][o]) ** 2)
                                         for k, w in enumerate(prob.windows)]))))
    return {'panels': panels, 'orders': orders, 'residual_before': np.array(rb), 'residual_after': np.array(ra)}


__all__ = ['ORDERS', 'CRITICALLY_DAMPED', 'CampbellData', 'campbell_data', 'ModeShape', 'mode_shapes',
           'critical_mode_index', 'InterpolatedBearings', 'IdentifiedModel', 'identified_bearing_fn',
           'curve_speeds', 'response_curves', 'response_curves_adaptive', 'align_phase',
           'journal_positions', 'amplitude_spectrum', 'waterfall_data', 'OrbitData', 'orbit_data',
           'probe_stations', 'diagnosis_curves']
