"""
Recordings on disk: the .npz exchange format and a bag's runs as recordings.

:func:`save_npz`, :func:`load_npz`; :func:`recordings_from_bag` (one Recording per excitation run);
:func:`from_npz` / :func:`from_bag` go on to the 1X vectors.

Hostile files are refused before anything large is read (see :func:`load_npz`).
"""
from __future__ import annotations

import contextlib
import dataclasses
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import zipfile
import zlib

import numpy as np

from .bags import read_bag
from .messages import block_from_msg, excitation_from_msg
from ..config.params import ExcitationEntry, Probe, Run
from ..identify.harmonics import from_recordings, HarmonicData
from ..signals.keyphasor import continued_angle
from ..signals.recording import check_recording, Recording, RecordingCheck, RecordingError, split_rows
from ..signals.windows import speed_from_angle


def save_npz(rec: Recording, path: str | Path) -> Path:
    """Write ``rec`` as a self-describing .npz (the DAQ/offline exchange format; SI units)."""
    path = Path(path)
    ex = rec.run.excitation
    truth_speeds, truth_nodes, truth_K, truth_C = _truth_arrays(rec.truth.get('coefficients', {}))
    _savez(
        path, format='bearing_id.recording.v1', sample_rate=rec.sample_rate, t=rec.t, speed=rec.speed,
        angle=rec.angle, samples=rec.samples,
        channels=np.array([p.name for p in rec.probes]), nodes=np.array([p.node for p in rec.probes]),
        directions=np.array([p.direction for p in rec.probes]),
        run_id=rec.run.id,
        ex_kind=np.array([e.kind for e in ex], dtype='U16'), ex_node=np.array([e.node for e in ex], dtype=int),
        ex_magnitude=np.array([e.magnitude for e in ex], dtype=float),
        ex_phase=np.array([e.phase for e in ex], dtype=float),
        ex_direction=np.array([e.direction for e in ex], dtype='U16'),
        ex_frequency_ratio=np.array([e.frequency_ratio for e in ex], dtype=float),
        segments=np.array([(a, b, s, st) for a, b, s, st in rec.segments], dtype=float).reshape(-1, 4),
        truth_speeds=truth_speeds, truth_nodes=truth_nodes, truth_K=truth_K, truth_C=truth_C,
        rig_name=rec.rig_name)
    return path


NPZ_DEFLATE_MIN_SAVING = 0.1    # a member is stored deflated only when that saves at least this fraction ...
NPZ_DEFLATE_ALWAYS_BELOW = 4096  # ... or holds fewer bytes than this (its .npy header, which deflates, dominates)


def _savez(path: Path, **arrays) -> None:
    """
    Write ``arrays`` as an .npz (what ``np.savez_compressed`` writes, read back by ``np.load`` alike).

    Each member is deflated only when that saves at least :data:`NPZ_DEFLATE_MIN_SAVING` of its size (judged on its
    data's first MiB; small members always); a member that does not shrink -- the noisy samples (~4 % smaller
    deflated) -- is stored as it is, so that every later read skips inflating it, for a file 1-4 % larger.  Each
    array is streamed into its member, as numpy does (no second copy in memory); fixed timestamps (reproducible
    files).
    """
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


def _npz_headers(zf, path: Path, small: dict | None = None, streamed=()) -> dict:
    """
    Return {key: (ZipInfo, shape, dtype)} from the .npy headers of every member.

    Nothing else is decompressed, except, with a dict ``small``, the known members (:data:`NPZ_KNOWN`) whose header
    declares at most :data:`NPZ_SMALL_BYTES` of data that agree with the member's size: those are read whole
    (``np.lib.format.read_array``, after rewinding the open member) into ``small[key]``, so that each member is
    opened once.  The members named in ``streamed`` (read piece by piece) do not count against the memory budget.
    """
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
                nbytes = math.prod(shape) * dtype.itemsize
                if (small is not None and key in NPZ_KNOWN and not dtype.hasobject and nbytes <= NPZ_SMALL_BYTES
                        and info.file_size == header_len + nbytes):
                    fh.seek(0)
                    small[key] = fmt.read_array(fh, allow_pickle=False)
                    if fh.read(1):          # reading to the member's end also checks its CRC
                        raise ValueError('data beyond the declared array')
        except Exception as exc:  # BadZipFile (CRC), zlib.error, EOFError, a malformed .npy header, ...
            raise ValueError(f'{path}: member {name} is corrupt or not an .npy array ({type(exc).__name__}: '
                             f'{exc})') from None
        if dtype.hasobject:
            raise ValueError(f'{path}: {key} holds Python objects (pickled data is never loaded)')
        if info.file_size != header_len + nbytes:
            raise ValueError(f'{path}: {key} declares shape {shape} of {dtype} ({nbytes} bytes) but its zip member '
                             f'holds {info.file_size - header_len} bytes of data (corrupt or crafted; refused unread)')
        if nbytes > NPZ_BOMB_MIN_BYTES and info.file_size > NPZ_BOMB_RATIO * max(info.compress_size, 1):
            raise ValueError(f'{path}: {key} would expand {info.compress_size} compressed bytes to {nbytes} '
                             f'(ratio > {NPZ_BOMB_RATIO}: a zip bomb, refused unread)')
        total += 0 if key in streamed else nbytes
        out[key] = (info, tuple(int(s) for s in shape), dtype)
    budget = _npz_memory_budget()
    if total > budget:
        raise ValueError(f'{path}: its arrays declare {total} bytes, more than the {budget} this machine allows '
                         f'(BEARING_ID_NPZ_MAX_BYTES) -- refused unread')
    return out


def _npz_check_layout(h: dict, path: Path) -> None:
    """Shapes and dtypes of a recording, from the headers alone (see :func:`save_npz`)."""
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


def _npz_open(path: Path):
    """Open ``path`` as a zip archive; ValueError when it is none."""
    try:
        return zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise ValueError(f'{path}: not a readable .npz recording (not a zip archive: {exc})') from None


def _npz_getter(zf, h: dict, small: dict, path: Path):
    """Return get(key): a member's array, read whole (once: a small one was read with its header)."""
    def get(key):
        if key in small:            # read with its header (small known members); each member is read once
            return small.pop(key)
        info = h[key][0]
        try:
            with zf.open(info) as fh:
                return np.lib.format.read_array(fh, allow_pickle=False)
        except Exception as exc:  # BadZipFile (CRC), zlib.error, EOFError, ValueError on a damaged member
            raise ValueError(f'{path}: member {info.filename} is corrupt ({type(exc).__name__}: {exc})') from None
    return get


def _npz_meta(h: dict, get, path: Path, n: int) -> dict:
    """Return the recording's description (everything but its per-sample arrays) from the members, checked."""
    def text(key, default):
        return str(get(key).reshape(-1)[0]) if key in h else default

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
    gaps = get('gaps') if 'gaps' in h else np.zeros(0)
    if not np.all(np.isfinite(gaps)) or np.any((gaps < 0) | (gaps > n)):
        raise ValueError(f'{path}: gaps must be sample indices in [0, {n}]')
    return {'sample_rate': fs, 'probes': probes, 'run': Run(text('run_id', '?'), tuple(ex)), 'segments': segs,
            'truth': truth, 'rig_name': text('rig_name', 'rig'), 'gaps': tuple(int(i) for i in gaps)}


def load_npz(path: str | Path) -> Recording:
    """
    Read a recording written by :func:`save_npz`; raises ValueError naming what is wrong.

    Hostile files are refused before anything large is read: the zip directory and every member's .npy header are
    checked first (declared size = the member's size, no zip bomb, total within memory, no pickled objects), then the
    shapes against each other (samples rows = angle = speed = t, channel metadata = sample columns, excitation and
    truth arrays consistent), then the values (:func:`check_recording`).  :func:`open_npz` reads it piece by piece.
    """
    path = Path(path)
    with _npz_open(path) as zf:
        small = {}
        h = _npz_headers(zf, path, small)
        _npz_check_layout(h, path)
        get = _npz_getter(zf, h, small, path)
        samples = np.asarray(get('samples'), dtype=float)
        n = samples.shape[0]
        meta = _npz_meta(h, get, path, n)
        rec = Recording(t=np.asarray(get('t'), dtype=float) if 't' in h else np.arange(n) / meta['sample_rate'],
                        speed=np.asarray(get('speed'), dtype=float), angle=np.asarray(get('angle'), dtype=float),
                        samples=samples, **meta)
    return check_recording(rec, str(path))


NPZ_STREAMED = ('samples', 'angle', 'speed', 't')   # the per-sample members, read piece by piece by open_npz
NPZ_PIECE_BYTES = 4 << 20                          # bytes of samples per piece read (~2 s of 2 channels at 10 kHz)


def open_npz(path: str | Path) -> 'NpzRecording':
    """
    Open a recording written by :func:`save_npz` to be read piece by piece (:meth:`NpzRecording.pieces`).

    The checks of :func:`load_npz` before anything large is read are made here (zip directory, every .npy header,
    the shapes against each other, the description's values); the per-sample arrays' values are checked as they are
    read (:class:`bearing_id.signals.recording.RecordingCheck`).  They do not count against the memory budget
    (``BEARING_ID_NPZ_MAX_BYTES``): they are never held whole.
    """
    path = Path(path)
    with _npz_open(path) as zf:
        small = {}
        h = _npz_headers(zf, path, small, streamed=NPZ_STREAMED)
        _npz_check_layout(h, path)
        n = h['samples'][1][0]
        meta = _npz_meta(h, _npz_getter(zf, h, small, path), path, n)
    fs = meta['sample_rate']
    if not (math.isfinite(fs) and fs > 0):
        raise RecordingError(f'{path}: sample_rate must be a number > 0 Hz, got {fs!r}')
    return NpzRecording(path=path, n_samples=n, members={k: h[k] for k in NPZ_STREAMED if k in h},
                        small={k: small[k] for k in NPZ_STREAMED if k in small}, **meta)


@dataclass
class NpzRecording:
    """
    A .npz recording opened by :func:`open_npz`: its description at once, its samples piece by piece.

    Carries what a :class:`Recording` carries but the per-sample arrays: ``sample_rate``, ``probes``, ``run``,
    ``segments``, ``truth``, ``rig_name``, ``gaps`` and ``n_samples``.  :meth:`pieces` reads the samples and the
    angle in pieces of :data:`NPZ_PIECE_BYTES` (the route :func:`bearing_id.identify.harmonics.from_recordings`
    takes for every recording), checking every value on the way.  ``samples``, ``angle``, ``speed`` and ``t`` read
    the whole recording (:func:`load_npz`) the first time one is asked for: what needs the time series whole (the
    paper method's filter, ``--report``) holds it, nothing else does.
    """

    path: Path
    sample_rate: float
    probes: tuple
    run: Run
    n_samples: int
    members: dict = field(repr=False)
    small: dict = field(repr=False)
    segments: list = field(default_factory=list)
    truth: dict = field(default_factory=dict, repr=False)
    rig_name: str = 'rig'
    gaps: tuple = ()
    _whole: Recording | None = field(default=None, init=False, repr=False, compare=False)

    @property
    def channels(self) -> list[str]:
        return [p.name for p in self.probes]

    def whole(self) -> Recording:
        """Return the recording with its arrays, read once by :func:`load_npz` (with this one's excitation)."""
        if self._whole is None:
            self._whole = dataclasses.replace(load_npz(self.path), run=self.run)
        return self._whole

    samples = property(lambda self: self.whole().samples)
    angle = property(lambda self: self.whole().angle)
    speed = property(lambda self: self.whole().speed)
    t = property(lambda self: self.whole().t)

    def pieces(self, speed: bool = False):
        """
        Yield (samples (n, nch), angle (n,), contiguous) in order, split at ``gaps`` (``contiguous`` False there).

        With ``speed``: (samples, angle, speed (n,) [rad/s], contiguous).

        Every value is checked as it is read; a RecordingError (a ValueError) naming the file is raised after the
        last piece when any is unusable (the message :func:`load_npz` gives), or at once for a corrupt member.
        """
        where = str(self.path)
        check = RecordingCheck(self, where)
        nch = len(self.probes)
        rows = max(1, NPZ_PIECE_BYTES // (8 * nch))
        with _npz_open(self.path) as zf, contextlib.ExitStack() as stack:
            readers = {k: _MemberRows(zf, self.members[k], self.small.get(k), self.path, stack)
                       for k in self.members}
            for a, b, contiguous in split_rows(self.n_samples, self.gaps, rows):
                got = {k: r.read(b - a) for k, r in readers.items()}
                check.feed(got['samples'], got['angle'], got['speed'], got.get('t'))
                if not check.failed:
                    yield ((got['samples'], got['angle'], got['speed'], contiguous) if speed else
                           (got['samples'], got['angle'], contiguous))
            for r in readers.values():
                r.end()
        check.finish()


class _MemberRows:
    """Rows of one .npy member of an open zip, read in order (or of its array, when read with the headers)."""

    def __init__(self, zf, member, array, path: Path, stack):
        self.path, self.info = path, member[0]
        self.shape, self.dtype = member[1], member[2]
        self.array, self.pos, self.fh = array, 0, None
        self.row_bytes = self.dtype.itemsize * math.prod(self.shape[1:])
        if array is not None:
            return
        fmt = np.lib.format
        try:
            fh = stack.enter_context(zf.open(self.info))
            version = fmt.read_magic(fh)
            _, fortran, _ = fmt.read_array_header_1_0(fh) if version == (1, 0) else fmt.read_array_header_2_0(fh)
            if fortran and len(self.shape) > 1:     # its columns one after another: read whole
                fh.seek(0)
                self.array = fmt.read_array(fh, allow_pickle=False)
            else:
                self.fh = fh
        except Exception as exc:  # BadZipFile (CRC), zlib.error, EOFError, a damaged header
            raise self._corrupt(exc) from None

    def _corrupt(self, exc):
        return RecordingError(f'{self.path}: member {self.info.filename} is corrupt ({type(exc).__name__}: {exc})')

    def read(self, n: int) -> np.ndarray:
        i0 = self.pos
        self.pos += n
        if self.array is not None:
            return np.asarray(self.array[i0:i0 + n], dtype=float)
        try:
            buf = self.fh.read(n * self.row_bytes)
        except Exception as exc:  # BadZipFile (CRC), zlib.error, EOFError
            raise self._corrupt(exc) from None
        if len(buf) != n * self.row_bytes:
            raise self._corrupt(EOFError(f'{len(buf)} bytes where {n * self.row_bytes} were declared'))
        return np.frombuffer(buf, dtype=self.dtype).reshape((n,) + tuple(self.shape[1:])).astype(float, copy=False)

    def end(self) -> None:
        """Read what follows the declared rows: nothing may (reading to the member's last byte checks its CRC)."""
        if self.fh is None:
            return
        try:
            rest = self.fh.read(1)
        except Exception as exc:
            raise self._corrupt(exc) from None
        if rest:
            raise self._corrupt(ValueError('data beyond the declared array'))


def from_npz(paths, **kw) -> HarmonicData:
    """Load .npz recordings (:func:`load_npz`; one file per run) and collect their 1X vectors."""
    return from_recordings([load_npz(p) for p in paths], **kw)


def joined_angles(blocks, fs: float) -> np.ndarray:
    """
    Return the keyphasor angle [rad] of every sample of consecutive ``blocks``, continuous across their boundaries.

    A sender may restart its angle in each block (only the first sample's angle, wrapped to [0, 2 pi), as other
    recorders write it): each block is moved by the whole number of turns that puts its first sample where the
    previous block's last one leads by the block timing (:func:`bearing_id.signals.keyphasor.continued_angle`; the
    speed is the two blocks' mean header speed, else the previous block's angle slope).
    """
    out, prev = [], None
    for b in blocks:
        a = np.asarray(b.angles(), dtype=float)
        if prev is not None and a.size:
            pb, pa = prev
            speeds = [w for w in (pb.speed, b.speed) if np.isfinite(w) and w > 0]
            w = float(np.mean(speeds)) if speeds else ((pa[-1] - pa[0]) * fs / (pa.size - 1) if pa.size > 1 else 0.0)
            a = continued_angle(a, b.stamp, pa[-1], pb.stamp + (pb.n_samples - 1) / fs, w, fs)
        if a.size:
            prev = (b, a)
        out.append(a)
    return np.concatenate(out) if out else np.zeros(0)


def recordings_from_bag(path) -> list:
    """
    One Recording per excitation run from a bag (topics /rotor/displacement and /rotor/excitation).

    A block belongs to the run its ``run_id`` names, or (no run_id) to the run of the last /rotor/excitation before
    it; re-sent copies of an excitation are ignored.  The angle of every sample is the block's ``sample_angles``
    (a block without them: first-sample angle + speed * k / sample_rate, which assumes constant speed over the
    block), made continuous across blocks (:func:`joined_angles`).  A break in the blocks' sequence numbers is
    recorded in ``Recording.gaps``.  A block whose channels differ from the run's first block is refused (ValueError).
    """
    runs: dict = {}
    order: list = []
    cur = None
    for topic, _, _, msg in read_bag(path, topics=['/rotor/displacement', '/rotor/excitation']):
        if topic == '/rotor/excitation':
            run = excitation_from_msg(msg)
            if run.id not in runs:
                runs[run.id] = {'run': run, 'blocks': []}
                order.append(run.id)
            cur = run.id
            continue
        b = block_from_msg(msg)
        rid = b.run_id or cur
        if rid is None or rid not in runs:
            continue            # no excitation known for it: not usable for identification
        runs[rid]['blocks'].append(b)
    recs = []
    for rid in order:
        bl = runs[rid]['blocks']
        if not bl:
            continue
        chans = bl[0].probes
        fs = bl[0].sample_rate
        gaps, n = [], 0
        for i, b in enumerate(bl):
            if b.probes != chans:
                raise ValueError(f'{path}: run {rid}: channels change from {chans} to {b.probes}')
            if i and (b.sequence - bl[i - 1].sequence) % 2**32 != 1:
                gaps.append(n)
            n += b.n_samples
        x = np.vstack([b.samples for b in bl])
        angle = joined_angles(bl, fs)
        recs.append(Recording(sample_rate=fs, t=np.arange(x.shape[0]) / fs, speed=speed_from_angle(angle, fs),
                              angle=angle, probes=chans, samples=x, run=runs[rid]['run'], gaps=tuple(gaps)))
    if not recs:
        raise ValueError(f'{path}: no displacement blocks after an excitation message')
    return recs


def from_bag(path, **kw) -> HarmonicData:
    """Read a bag into one Recording per excitation run (:func:`recordings_from_bag`) and collect their 1X vectors."""
    return from_recordings(recordings_from_bag(path), **kw)
