"""
The simulated test rig: what a DAQ on the paper's machine would record, from a truth model that differs from theory.

Physics of the simulation
    At each constant-speed segment the truth system  M q'' + (C + Cb + Omega G) q' + (K + Kb) q = f(t)  is linear and
    time invariant, and every excitation is a sum of sinusoids in the rotor angle phi: f = sum_r Re{F_r exp(j r phi)}.
    The response is computed exactly (no zero-order hold on the force): the particular solution of each harmonic,
    q_r = Z(r Omega)^-1 F_r, plus the homogeneous solution exp(A (t - t0)) x_h(t0) evaluated through the eigen-
    decomposition of A.  The state is continuous across speed changes, so transients after each step are right too.
    A speed ramp is approximated by short constant-speed steps (``ramp_step`` seconds) with a continuous rotor angle.

    The run starts in the steady state of its first segment (the machine was already running).

Truth versus theory
    The truth bearings come from the bearing model with viscosity and clearance scaled by ``simulation.truth``
    factors (default x1.25 and x0.8); the nominal params give the theory the estimator starts from.

Noise
    Gaussian, independent per channel, std = ``noise`` x RMS of that channel's clean signal in that speed segment.

Validity
    :func:`check_validity` flags orbits larger than 30 % of the radial clearance at a bearing and speeds at or above
    the stability threshold; the paper's own unbalance (``scenario('paper_table3')``) trips both at higher speeds.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
import math
from pathlib import Path

import numpy as np

from .conventions import orbit_semi_axes, rpm_to_rad_s
from .excitation import harmonic_forces
from .params import ExcitationEntry, Probe, RigParams, Run

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


# ------------------------------------------------------------------------------------------------- recording
@dataclass
class Recording:
    """
    A DAQ-like record of one excitation run.

    Attributes
    ----------
    sample_rate : Hz.
    t : (N,) s from the start of the run.
    speed : (N,) rad/s.
    angle : (N,) rad, keyphasor rotor angle (unwrapped; 0 at the key mark).
    probes : tuple of params.Probe, one per channel.
    samples : (N, nch) m.
    run : params.Run (the known excitation).
    segments : list of (i0, i1, speed [rad/s], steady) sample ranges of constant speed (truth bookkeeping).
    truth : dict with 'coefficients': {speed_rad_s: {node: (K, C)}} of the truth bearings, and 'description'.
    rig_name : str.
    gaps : sample indices at which the record resumes after lost data (a bag with a missing block); no steady window
        spans a gap.

    """

    sample_rate: float
    t: np.ndarray
    speed: np.ndarray
    angle: np.ndarray
    probes: tuple
    samples: np.ndarray
    run: Run
    segments: list = field(default_factory=list)
    truth: dict = field(default_factory=dict)
    rig_name: str = 'rig'
    gaps: tuple = ()

    @property
    def channels(self) -> list[str]:
        return [p.name for p in self.probes]

    def save_npz(self, path: str | Path) -> Path:
        """Write the recording as a self-describing .npz (the DAQ/offline exchange format; SI units)."""
        path = Path(path)
        ex = self.run.excitation
        truth_speeds, truth_nodes, truth_K, truth_C = _truth_arrays(self.truth.get('coefficients', {}))
        _savez(
            path, format='bearing_id.recording.v1', sample_rate=self.sample_rate, t=self.t, speed=self.speed,
            angle=self.angle, samples=self.samples,
            channels=np.array([p.name for p in self.probes]), nodes=np.array([p.node for p in self.probes]),
            directions=np.array([p.direction for p in self.probes]),
            run_id=self.run.id,
            ex_kind=np.array([e.kind for e in ex], dtype='U16'), ex_node=np.array([e.node for e in ex], dtype=int),
            ex_magnitude=np.array([e.magnitude for e in ex], dtype=float),
            ex_phase=np.array([e.phase for e in ex], dtype=float),
            ex_direction=np.array([e.direction for e in ex], dtype='U16'),
            ex_frequency_ratio=np.array([e.frequency_ratio for e in ex], dtype=float),
            segments=np.array([(a, b, s, st) for a, b, s, st in self.segments], dtype=float).reshape(-1, 4),
            truth_speeds=truth_speeds, truth_nodes=truth_nodes, truth_K=truth_K, truth_C=truth_C,
            rig_name=self.rig_name)
        return path


NPZ_DEFLATE_MIN_SAVING = 0.1    # a member is stored deflated only when that saves at least this fraction ...
NPZ_DEFLATE_ALWAYS_BELOW = 4096  # ... or holds fewer bytes than this (its .npy header, which deflates, dominates)


def _savez(path: Path, **arrays) -> None:
    """
    Write ``arrays`` as an .npz (what ``np.savez_compressed`` writes, read back by ``np.load`` alike).

    Each member is deflated only when that saves at least :data:`NPZ_DEFLATE_MIN_SAVING` of its size (judged on its
    data's first MiB; small members always); a member that does not shrink -- the noisy samples (~4 % smaller
    deflated) -- is stored as it is, so that every later read skips inflating it (0.1 s of a 9-speed load) for a file
    1-4 % larger.  Each array is streamed into its member, as numpy does (no second copy in memory); fixed timestamps
    (reproducible files).
    """
    import zipfile
    import zlib
    with zipfile.ZipFile(path, 'w', allowZip64=True) as zf:
        for key, value in arrays.items():
            arr = np.asanyarray(value)
            head = arr.reshape(-1)[:-(-(1 << 20) // max(arr.itemsize, 1))].tobytes()      # <= 1 MiB
            deflate = (arr.nbytes < NPZ_DEFLATE_ALWAYS_BELOW
                       or len(zlib.compress(head, 1)) <= (1.0 - NPZ_DEFLATE_MIN_SAVING) * len(head))
            info = zipfile.ZipInfo(f'{key}.npy', (1980, 1, 1, 0, 0, 0))
            info.external_attr = 0o644 << 16
            info.compress_type = zipfile.ZIP_DEFLATED if deflate else zipfile.ZIP_STORED
            with zf.open(info, 'w', force_zip64=True) as fh:
                np.lib.format.write_array(fh, arr, allow_pickle=False)


def _truth_arrays(coeffs: dict):
    speeds = sorted(coeffs)
    if not speeds:
        return np.zeros(0), np.zeros(0, dtype=int), np.zeros((0, 0, 2, 2)), np.zeros((0, 0, 2, 2))
    nodes = sorted(coeffs[speeds[0]])
    K = np.array([[coeffs[s][n][0] for n in nodes] for s in speeds])
    C = np.array([[coeffs[s][n][1] for n in nodes] for s in speeds])
    return np.array(speeds), np.array(nodes), K, C


# .npz reading: every member's header is read (a few hundred bytes each) and the arrays' declared shapes, dtypes
# and sizes are checked against each other and against the zip member before any array is read.
NPZ_BOMB_RATIO = 200                 # uncompressed / compressed: float data compresses ~1-3x, zeros ~1000x
NPZ_BOMB_MIN_BYTES = 64 << 20        # ... a member is judged by that ratio only above this size
NPZ_REQUIRED = ('sample_rate', 'speed', 'angle', 'samples', 'channels', 'nodes', 'directions')
NPZ_EXCITATION = ('ex_kind', 'ex_node', 'ex_magnitude', 'ex_phase', 'ex_direction', 'ex_frequency_ratio')
NPZ_SMALL_BYTES = 64 << 10           # a known member this small is read in the header pass (one zip open per member)
NPZ_KNOWN = NPZ_REQUIRED + NPZ_EXCITATION + ('format', 't', 'run_id', 'rig_name', 'segments', 'truth_speeds',
                                             'truth_nodes', 'truth_K', 'truth_C', 'gaps')


def _npz_memory_budget() -> int:
    """
    Return the bytes the arrays of one .npz may declare in total.

    Half the physical memory (at least 1 GiB), or ``BEARING_ID_NPZ_MAX_BYTES``.
    """
    import os
    env = os.environ.get('BEARING_ID_NPZ_MAX_BYTES')
    if env:
        try:
            return int(float(env))
        except ValueError:
            pass
    try:
        return max(1 << 30, os.sysconf('SC_PAGE_SIZE') * os.sysconf('SC_PHYS_PAGES') // 2)
    except (ValueError, OSError, AttributeError):
        return 8 << 30


def _npz_headers(zf, path: Path, small: dict | None = None) -> dict:
    """
    Return {key: (ZipInfo, shape, dtype)} from the .npy headers of every member.

    Nothing else is decompressed, except, with a dict ``small``, the data of the known members (:data:`NPZ_KNOWN`)
    of at most :data:`NPZ_SMALL_BYTES`, read right after their header into ``small[key]`` (what
    ``np.lib.format.read_array`` returns; at most ~1.4 MiB in all), so that each member is opened once.
    """
    import zipfile
    fmt = np.lib.format
    out = {}
    total = 0
    disk = path.stat().st_size
    for info in zf.infolist():
        name = info.filename
        if not name.endswith('.npy'):
            continue            # np.savez writes only .npy members; anything else is ignored
        key = name[:-4]
        if info.flag_bits & 0x1:
            raise ValueError(f'{path}: member {name} is encrypted')
        if info.compress_size > disk:
            raise ValueError(f'{path}: member {name} claims {info.compress_size} stored bytes in a file of {disk} '
                             f'(corrupt or crafted zip directory; refused unread)')
        try:
            with zf.open(info) as fh:
                version = fmt.read_magic(fh)
                if version == (1, 0):
                    shape, fortran, dtype = fmt.read_array_header_1_0(fh)
                elif version in ((2, 0), (3, 0)):
                    shape, fortran, dtype = fmt.read_array_header_2_0(fh)
                else:
                    raise ValueError(f'unsupported .npy version {version}')
                header_len = fh.tell()
                if small is not None and key in NPZ_KNOWN and not dtype.hasobject:
                    _npz_read_small(fh, info, key, shape, fortran, dtype, header_len, small, path)
        except (zipfile.BadZipFile, EOFError, OSError, ValueError, NotImplementedError, RuntimeError,
                SyntaxError, TypeError) as exc:
            raise ValueError(f'{path}: member {name} has no readable array header ({type(exc).__name__}: {exc})') \
                from None
        except Exception as exc:  # zlib.error and the like
            raise ValueError(f'{path}: member {name} is corrupt ({type(exc).__name__}: {exc})') from None
        if dtype.hasobject:
            raise ValueError(f'{path}: {key} holds Python objects (pickled data is never loaded)')
        count = 1
        for s in shape:
            count *= int(s)
        nbytes = count * dtype.itemsize
        if info.file_size != header_len + nbytes:
            raise ValueError(f'{path}: {key} declares shape {shape} of {dtype} ({nbytes} bytes) but its zip member '
                             f'holds {info.file_size - header_len} bytes of data (corrupt or crafted; refused unread)')
        if nbytes > NPZ_BOMB_MIN_BYTES and info.file_size > NPZ_BOMB_RATIO * max(info.compress_size, 1):
            raise ValueError(f'{path}: {key} would expand {info.compress_size} compressed bytes to {nbytes} '
                             f'(ratio > {NPZ_BOMB_RATIO}: a zip bomb, refused unread)')
        total += nbytes
        out[key] = (info, tuple(int(s) for s in shape), dtype)
    budget = _npz_memory_budget()
    if total > budget:
        raise ValueError(f'{path}: its arrays declare {total} bytes, more than the {budget} this machine allows '
                         f'(BEARING_ID_NPZ_MAX_BYTES) -- refused unread')
    return out


def _npz_read_small(fh, info, key, shape, fortran, dtype, header_len, small: dict, path: Path) -> None:
    """Read a small member's data after its header into ``small[key]``, as ``np.lib.format.read_array`` would."""
    count = 1
    for n in shape:
        count *= int(n)
    nbytes = count * dtype.itemsize
    if nbytes > NPZ_SMALL_BYTES or info.file_size != header_len + nbytes:
        return                          # large, or inconsistent (refused by the caller's size check)
    try:
        data = fh.read(nbytes)
        rest = fh.read(1)               # reaches the end of the member: the zip CRC is checked
    except Exception as exc:            # BadZipFile (CRC), zlib.error, EOFError on a damaged member
        raise ValueError(f'{path}: member {info.filename} is corrupt ({type(exc).__name__}: {exc})') from None
    if len(data) != nbytes or rest:
        raise ValueError(f'{path}: member {info.filename} is corrupt (holds {len(data) + len(rest)} data bytes, its '
                         f'header declares {nbytes})')
    arr = np.ndarray(count, dtype=dtype)
    if count:
        arr[:] = np.frombuffer(data, dtype=dtype, count=count)
    if fortran:
        arr.shape = tuple(shape)[::-1]
        arr = arr.transpose()
    else:
        arr.shape = tuple(shape)
    small[key] = arr


def _npz_check_layout(h: dict, path: Path) -> None:
    """Shapes and dtypes of a recording, from the headers alone (see :meth:`Recording.save_npz`)."""
    def kind(key, kinds, what):
        if key in h and h[key][2].kind not in kinds:
            raise ValueError(f'{path}: {key} must be {what}, has dtype {h[key][2]}')

    def shape(key):
        return h[key][1]

    missing = [k for k in NPZ_REQUIRED if k not in h]
    if missing:
        raise ValueError(f'{path}: not a bearing_id recording: lacks {missing} (has {sorted(h)[:12]})')
    num, text, whole = 'fiu', 'US', 'iuf'
    for k in ('samples', 'angle', 'speed', 't', 'sample_rate', 'segments', 'truth_speeds', 'truth_K', 'truth_C',
              'ex_magnitude', 'ex_phase', 'ex_frequency_ratio'):
        kind(k, num, 'real numbers')
    for k in ('nodes', 'ex_node', 'truth_nodes'):
        kind(k, whole, 'node numbers')
    for k in ('channels', 'directions', 'ex_kind', 'ex_direction', 'run_id', 'rig_name', 'format'):
        kind(k, text, 'text')
    s = shape('samples')
    if len(s) != 2 or s[0] < 2 or s[1] < 1:
        raise ValueError(f'{path}: samples must be (N >= 2 samples, n_channels >= 1), has shape {s}')
    n, nch = s
    for k in ('angle', 'speed', 't'):
        if k in h and shape(k) != (n,):
            raise ValueError(f'{path}: {k} has shape {shape(k)} but samples has {n} rows: one {k} per sample needed')
    for k in ('channels', 'nodes', 'directions'):
        if shape(k) != (nch,):
            raise ValueError(f'{path}: {k} has shape {shape(k)} but samples has {nch} column(s): one per channel')
    if shape('sample_rate') not in ((), (1,)):
        raise ValueError(f"{path}: sample_rate must be one number, has shape {shape('sample_rate')}")
    for k in ('run_id', 'rig_name', 'format'):
        if k in h and shape(k) not in ((), (1,)):
            raise ValueError(f'{path}: {k} must be one string, has shape {shape(k)}')
    present = [k for k in NPZ_EXCITATION if k in h]
    if present:
        if len(present) != len(NPZ_EXCITATION):
            raise ValueError(f'{path}: excitation entries incomplete: has {present}, lacks '
                             f'{[k for k in NPZ_EXCITATION if k not in h]}')
        shapes = {shape(k) for k in NPZ_EXCITATION}
        if len(shapes) != 1 or len(next(iter(shapes))) != 1:
            raise ValueError(f'{path}: the ex_* arrays must be 1-D of one length, have shapes '
                             f'{[shape(k) for k in NPZ_EXCITATION]}')
    if 'segments' in h and (len(shape('segments')) != 2 or shape('segments')[1] != 4):
        raise ValueError(f"{path}: segments must be (k, 4), has shape {shape('segments')}")
    truth = [k for k in ('truth_speeds', 'truth_nodes', 'truth_K', 'truth_C') if k in h]
    if truth:
        if len(truth) != 4:
            raise ValueError(f'{path}: truth arrays incomplete (has {truth})')
        ns, nn = shape('truth_speeds'), shape('truth_nodes')
        if len(ns) != 1 or len(nn) != 1 or ns[0] and (shape('truth_K') != (ns[0], nn[0], 2, 2)
                                                      or shape('truth_C') != (ns[0], nn[0], 2, 2)):
            raise ValueError(f'{path}: truth_K/truth_C must be (speeds, nodes, 2, 2) = ({ns}, {nn}, 2, 2), have '
                             f"{shape('truth_K')}, {shape('truth_C')}")
    if 'gaps' in h and len(shape('gaps')) != 1:
        raise ValueError(f"{path}: gaps must be 1-D, has shape {shape('gaps')}")


def _nonfinite(a) -> str:
    bad = ~np.isfinite(a)
    if not bad.any():
        return ''
    idx = np.argwhere(bad)[0]
    return f'{int(bad.sum())} of {a.size} values are NaN/inf (first at index {tuple(int(i) for i in idx)})'


def check_recording(rec: 'Recording', where: str = 'recording') -> 'Recording':
    """
    Refuse a Recording the offline pipeline cannot use (ValueError naming what); returns ``rec``.

    Refused: sizes that disagree, a sample rate that is not > 0, NaN/inf in samples/angle/speed/t, a displacement beyond
    :data:`bearing_id.io.messages.MAX_PLAUSIBLE_DISPLACEMENT` (not metres, or damaged data), probe nodes < 1 or
    directions other than x/y/'<angle>deg', excitation entries of unknown kind.
    """
    fs = rec.sample_rate
    if not (isinstance(fs, (int, float, np.floating, np.integer)) and math.isfinite(float(fs)) and fs > 0):
        raise ValueError(f'{where}: sample_rate must be a number > 0 Hz, got {fs!r}')
    x = np.asarray(rec.samples)
    if x.ndim != 2 or x.shape[0] < 2 or x.shape[1] < 1:
        raise ValueError(f'{where}: samples must be (N >= 2, n_channels >= 1), has shape {x.shape}')
    if x.shape[1] != len(rec.probes):
        raise ValueError(f'{where}: {x.shape[1]} sample column(s) but {len(rec.probes)} channel(s)')
    for name in ('angle', 'speed', 't'):
        a = np.asarray(getattr(rec, name))
        if a.shape != (x.shape[0],):
            raise ValueError(f'{where}: {name} has shape {a.shape}, samples has {x.shape[0]} rows')
    for name in ('samples', 'angle', 'speed', 't'):
        problem = _nonfinite(np.asarray(getattr(rec, name), dtype=float))
        if problem:
            raise ValueError(f'{where}: {name}: {problem}; remove or repair those samples')
    from .io.messages import MAX_PLAUSIBLE_DISPLACEMENT as limit
    peak = max(float(x.max()), -float(x.min()))        # = max |x| (finite: checked above), no (N, nch) temporary
    if peak > limit:
        i, j = np.unravel_index(int(np.argmax(np.abs(x))), x.shape)
        raise ValueError(f'{where}: samples reach {peak:.3g} m (row {i}, channel {j}), beyond the {limit:g} m a shaft '
                         f'displacement can be: not metres (mm or um?) or damaged data')
    from .conventions import parse_probe_direction
    for p in rec.probes:
        try:
            parse_probe_direction(p.direction)
            ok = int(p.node) >= 1
        except (ValueError, TypeError):
            ok = False
        if not ok:
            raise ValueError(f'{where}: channel {p.name!r}: node {p.node} direction {p.direction!r} (need a 1-based '
                             f"node and x, y or an angle such as '45.0deg')")
    for e in rec.run.excitation:
        if e.kind not in ('unbalance', 'force') or e.direction not in ('forward', 'x', 'y') or e.node < 1 \
                or not all(math.isfinite(v) for v in (e.magnitude, e.phase, e.frequency_ratio)):
            raise ValueError(f'{where}: run {rec.run.id}: invalid excitation entry {e}')
    return rec


def load_npz(path: str | Path) -> Recording:
    """
    Read a recording written by :meth:`Recording.save_npz`; raises ValueError naming what is wrong.

    Hostile files are refused before anything large is read: the zip directory and every member's .npy header are
    checked first (declared size = the member's size, no zip bomb, total within memory, no pickled objects), then the
    shapes against each other (samples rows = angle = speed = t, channel metadata = sample columns, excitation and
    truth arrays consistent), then the values (:func:`check_recording`).
    """
    import zipfile
    path = Path(path)
    try:
        zf = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise ValueError(f'{path}: not a readable .npz recording (not a zip archive: {exc})') from None
    with zf:
        small = {}
        h = _npz_headers(zf, path, small)
        _npz_check_layout(h, path)

        def get(key):
            if key in small:            # read with its header (small known members); each member is read once
                return small.pop(key)
            info = h[key][0]
            try:
                with zf.open(info) as fh:
                    return np.lib.format.read_array(fh, allow_pickle=False)
            except Exception as exc:  # BadZipFile (CRC), zlib.error, EOFError, ValueError on a damaged member
                raise ValueError(f'{path}: member {info.filename} is corrupt ({type(exc).__name__}: {exc})') from None

        def text(key, default):
            return str(get(key).reshape(-1)[0]) if key in h else default

        samples = np.asarray(get('samples'), dtype=float)
        n = samples.shape[0]
        fs = float(get('sample_rate').reshape(-1)[0])
        nodes = get('nodes')
        if not np.all(np.isfinite(nodes)) or np.any(nodes != np.round(nodes)) or np.any(nodes < 1):
            raise ValueError(f'{path}: nodes must be 1-based whole numbers, got {nodes.tolist()[:8]}')
        probes = tuple(Probe(str(c), int(nd), str(r)) for c, nd, r in zip(get('channels'), nodes, get('directions')))
        ex = []
        if 'ex_kind' in h:
            cols = [get(k) for k in NPZ_EXCITATION]
            if not np.all(np.isfinite(cols[1])):
                raise ValueError(f'{path}: ex_node must be node numbers')
            for k, nd, m, p, r, f in zip(*cols):
                ex.append(ExcitationEntry(str(k), int(nd), float(m), float(p), str(r), float(f)))
        truth = {}
        if 'truth_speeds' in h and h['truth_speeds'][1][0]:
            ts, tn, tK, tC = (get(k) for k in ('truth_speeds', 'truth_nodes', 'truth_K', 'truth_C'))
            truth['coefficients'] = {float(s): {int(nd): (tK[i, j], tC[i, j]) for j, nd in enumerate(tn)}
                                     for i, s in enumerate(ts)}
        segs = []
        if 'segments' in h:
            for a, b, s, st in get('segments'):
                if not (math.isfinite(a) and math.isfinite(b) and 0 <= a <= b <= n):
                    raise ValueError(f'{path}: segment ({a}, {b}) is outside the {n} samples')
                segs.append((int(a), int(b), float(s), bool(st)))
        extra = {}
        if 'gaps' in h and 'gaps' in {f.name for f in dataclasses.fields(Recording)}:
            g = get('gaps')
            if not np.all(np.isfinite(g)) or np.any((g < 0) | (g > n)):
                raise ValueError(f'{path}: gaps must be sample indices in [0, {n}]')
            extra['gaps'] = tuple(int(i) for i in g)
        rec = Recording(sample_rate=fs, t=np.asarray(get('t'), dtype=float) if 't' in h else np.arange(n) / fs,
                        speed=np.asarray(get('speed'), dtype=float), angle=np.asarray(get('angle'), dtype=float),
                        probes=probes, samples=samples, run=Run(text('run_id', '?'), tuple(ex)),
                        segments=segs, truth=truth, rig_name=text('rig_name', 'rig'), **extra)
    return check_recording(rec, str(path))


# ------------------------------------------------------------------------------------------------- truth model
def truth_bearing_fn(rig: RigParams):
    """Speed -> {node: (K, C)} of the simulated machine's real bearings (truth factors applied)."""
    from . import bearings
    t = rig.simulation.truth
    return bearings.bearing_fn(rig, model=t.bearing_model, viscosity_factor=t.viscosity_factor,
                               clearance_factor=t.clearance_factor, k_factor=t.k_factor or None,
                               c_factor=t.c_factor or None)


def nominal_bearing_fn(rig: RigParams):
    """Speed -> {node: (K, C)} from the nominal params (the theory an estimator starts from)."""
    from . import bearings
    return bearings.bearing_fn(rig)


def system_matrices(model, speed: float, coeffs: dict, effects=()):
    """
    Truth (M, C, K) at ``speed`` [rad/s]: rotor + bearings (+ gyroscopics in C), then each effect's changes.

    Effects may append DOFs; the first ``model.ndof`` DOFs stay the rotor's.  Returned arrays are fresh copies.
    """
    from .rotor.assembly import system_matrices as rotor_system
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
def simulate(rig: RigParams, run: Run, schedule: list[Segment], *, probes=None, noise=None, seed=None,
             bearing_fn=None, effects=(), sample_rate=None, model=None) -> Recording:
    """
    Simulate one excitation run over a speed ``schedule``.

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
        std as a fraction of each channel's RMS per segment (default ``rig.simulation.noise``).
    seed
        noise seed (default ``rig.simulation.seed`` combined with the run id).
    bearing_fn
        speed -> {node: (K, C)} of the real bearings (default :func:`truth_bearing_fn`).
    effects
        truth effects (see docs/ARCHITECTURE.md) hidden from the nominal model.
    sample_rate
        Hz (default ``rig.simulation.sample_rate``).
    model
        the rig's FE rotor model, if already built (default: built from ``rig``).

    Returns
    -------
    Recording with samples (N, nch) in metres.

    """
    from .rotor.assembly import probe_matrix, RotorModel

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
        seed = (sim.seed * 1000003 + sum(map(ord, run.id))) % (2**32)
    rng = np.random.default_rng(seed)
    n_nodes = model.n_nodes
    S0 = probe_matrix(model, probes)       # (nch, model.ndof): probes at any angle, with their gain

    # sample counts from cumulative segment boundaries, so that short ramp steps lose no time to rounding
    edges = np.round(np.cumsum([0.0] + [s.duration for s in schedule]) * fs).astype(int)
    counts = [max(1, int(c)) for c in np.diff(edges)]
    N = int(sum(counts))
    t = np.arange(N) / fs
    speed = np.empty(N)
    angle = np.empty(N)
    clean = np.zeros((N, len(probes)))
    segments = []
    truth_coeffs = {}
    x_prev = None          # state [q; q'] at the first sample of the next segment (continuity)
    phi0 = 0.0
    i0 = 0
    for seg, n in zip(schedule, counts):
        W = seg.speed
        coeffs = bearing_fn(W)
        truth_coeffs.setdefault(float(W), {k: (np.array(v[0]), np.array(v[1])) for k, v in coeffs.items()})
        M, C, K = system_matrices(model, W, coeffs, effects)
        nd = M.shape[0]
        tau = np.arange(n) / fs
        phi = phi0 + W * tau
        forces = _segment_forces(run.excitation, effects, W, n_nodes, nd)
        # particular (steady-state) solution, harmonic by harmonic: state phasor [q; j w q] per ratio
        xph = {}
        y = np.zeros((n, len(probes)))
        for r, f in forces.items():
            w = r * W
            q = np.linalg.solve(K - w * w * M + 1j * w * C, f)
            xph[r] = np.concatenate([q, 1j * w * q])
            y += np.real(np.outer(np.exp(1j * r * phi), S0 @ q[:S0.shape[1]]))

        def particular_state(angle_now):
            return sum((np.real(X * np.exp(1j * r * angle_now)) for r, X in xph.items()), np.zeros(2 * nd))

        xp0 = particular_state(phi0)
        # homogeneous part carrying the transient from the previous segment
        if x_prev is not None:
            xh0 = x_prev[:2 * nd] if x_prev.size >= 2 * nd else np.pad(x_prev, (0, 2 * nd - x_prev.size))
            xh0 = xh0 - xp0
            if np.any(xh0):
                A = _state_matrix(M, C, K)
                lam, V = np.linalg.eig(A)
                c = np.linalg.solve(V, xh0)
                y += np.real((np.exp(np.outer(tau, lam)) * c) @ (S0 @ V[:S0.shape[1], :]).T)
                # state at the first sample of the next segment (exact propagation over the whole segment)
                T = n / fs
                xh_end = np.real(V @ (np.exp(lam * T) * c))
            else:
                xh_end = np.zeros(2 * nd)
        else:
            xh_end = np.zeros(2 * nd)
        phi_end = phi0 + W * n / fs
        x_prev = particular_state(phi_end) + xh_end
        sl = slice(i0, i0 + n)
        clean[sl] = y
        speed[sl] = W
        angle[sl] = phi
        segments.append((i0, i0 + n, float(W), bool(seg.steady)))
        phi0 = phi_end
        i0 += n

    samples = clean.copy()
    for e in effects:
        if hasattr(e, 'measure'):
            samples = e.measure(samples, angle, speed, probes)
    if noise > 0:
        for a, b, _, _ in segments:
            rms = np.sqrt(np.mean(samples[a:b] ** 2, axis=0))
            samples[a:b] += rng.standard_normal((b - a, len(probes))) * (noise * rms)
    return Recording(sample_rate=fs, t=t, speed=speed, angle=angle, probes=probes, samples=samples, run=run,
                     segments=segments, truth={'coefficients': truth_coeffs, 'description': desc,
                                               'effects': [type(e).__name__ for e in effects]},
                     rig_name=rig.name)


def _state_matrix(M, C, K):
    from .rotor.assembly import first_order
    return first_order(np.linalg.inv(M), C, K)


def simulate_run(rig: RigParams, run: Run, speeds_rpm=None, dwell=None, ramp=None, **kw) -> Recording:
    """
    Step through ``speeds_rpm`` (default ``rig.simulation.speeds_rpm``) dwelling ``dwell`` s at each.

    With ``ramp`` s linear speed ramps between dwells (defaults from ``rig.simulation``).
    """
    sim = rig.simulation
    sched = step_schedule(speeds_rpm if speeds_rpm is not None else sim.speeds_rpm,
                          dwell if dwell is not None else sim.dwell,
                          sim.ramp if ramp is None else ramp)
    return simulate(rig, run, sched, **kw)


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
    from .rotor.assembly import film_dofs, RotorModel
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


def with_truth(rig: RigParams, **kw) -> RigParams:
    """Copy of ``rig`` with simulation.truth fields replaced (e.g. bearing_model='finite')."""
    sim = rig.simulation
    return rig.replace(simulation=dataclasses.replace(sim, truth=dataclasses.replace(sim.truth, **kw)))
