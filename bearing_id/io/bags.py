"""
rosbag2 bags (sqlite3 and mcap) without a ROS installation, via ``rosbags``.

The typestore is ROS 2 Jazzy's plus the ``bearing_id_msgs`` types registered from the very ``.msg`` files that
``msg_defs/`` builds, so bags written here read in stock ROS 2 tools (the RIHS01 type hashes match rosidl's) and
bags recorded with ``ros2 bag record`` read here.

* :func:`typestore` -- the shared typestore (cached; do not register into it, make your own with
  :func:`make_typestore` if you need more types).
* :func:`write_bag` (path, messages, storage='mcap', qos=None) -- messages as ``(topic, timestamp_ns, msg)`` or
  ``(topic, msgtype, timestamp_ns, msg_or_raw_bytes)``; msg may be a rosbags dataclass or an rclpy message.
* :class:`BagWriter` -- message-by-message writing, durable every ``flush_period`` s (what ``bearing-id record``
  uses: a kill -9 loses at most that much and leaves a bag stock readers open as it is).
* :func:`read_bag` (path, topics=None, raw=False, salvage=False) -- yields ``(topic, msgtype, timestamp_ns, msg or raw
  bytes)`` in time order.  rclpy's ``Publisher.publish`` accepts the raw bytes, the cleanest way to replay.
* :func:`bag_topics` (path) -- ``{topic: (msgtype, count)}``; :func:`offered_qos` (path) -- ``{topic: [Qos]}``.
* :func:`unfinished`, :func:`salvage_bag`, :func:`recover_bag` -- a recording whose writer was killed (no
  ``metadata.yaml``, or one marked :data:`UNFINISHED_KEY`): what it holds, and a complete bag rebuilt from it
  (``bearing-id record --recover``).

Offered QoS: every topic is written with its ``offered_qos_profiles`` (given, or :func:`default_qos`, the QoS the
bearing_id nodes publish with), which rosbag2 Jazzy's metadata version 9 stores as a YAML list of profiles
(history, depth, reliability, durability, deadline, lifespan, liveliness, liveliness_lease_duration,
avoid_ros_namespace_conventions) and the storage file (mcap channel metadata / sqlite ``topics`` table) as a YAML
string; ``ros2 bag play`` then offers a transient-local topic as transient-local (latched).

Every failure (missing/truncated/corrupt bag, missing topic, unknown type, hostile metadata.yaml, a message whose
arrays disagree) raises :class:`BagError` naming the file; nothing is read before metadata.yaml has passed a bounded
parse (size, nesting, alias expansion: :func:`bearing_id.config.params.load_yaml_bounded`).
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
import functools
import importlib.util
import math
import os
from pathlib import Path
import shutil
import sqlite3
import struct
import sys
import tempfile
import time

from mcap.exceptions import EndOfFile, InvalidMagic
from mcap.records import Channel, Chunk, Message, Schema
from mcap.stream_reader import breakup_chunk, StreamReader
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import Reader, StoragePlugin, Writer, WriterError
from rosbags.rosbag2.metadata import dump_qos_v9, parse_qos
from rosbags.typesys import get_types_from_msg, get_typestore, Stores
import yaml

from ..config.params import load_yaml_bounded, ParamError

PACKAGE = 'bearing_id_msgs'
STORAGES = ('mcap', 'sqlite3')
BAG_VERSION = 9  # rosbag2 metadata version written by ROS 2 Jazzy
UNFINISHED_KEY = 'bearing_id.recording'   # custom_data key of the metadata.yaml a BagWriter keeps before close
# appended to an mcap file at every flush and overwritten by the next chunk: Data End, a Footer without summary (a
# reader scans the data section) and the closing magic -- rosbags' reader refuses a file without them
MCAP_TAIL = b'\x0f' + struct.pack('<QI', 4, 0) + b'\x02' + struct.pack('<QQQI', 20, 0, 0, 0) + b'\x89MCAP0\r\n'


class BagError(RuntimeError):
    """A bag cannot be read or written; the message names the file and the problem."""


# -------------------------------------------------------------------------------------------------- .msg files
def _msg_dir_candidates() -> list[Path]:
    here = Path(__file__).resolve()
    cands = [here.parents[2] / 'msg_defs' / 'msg']                     # source tree (editable install, checkout)
    prefixes = [Path(sys.prefix)]
    prefixes += [Path(p) for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    try:                                                                  # <prefix>/lib/pythonX.Y/site-packages/pkg
        spec = importlib.util.find_spec(PACKAGE)
    except (ImportError, ValueError):
        spec = None
    if spec is not None and spec.submodule_search_locations:
        for loc in spec.submodule_search_locations:
            prefixes.append(Path(loc).resolve().parents[3])
    cands += [p / 'share' / PACKAGE / 'msg' for p in prefixes]
    cands.append(Path(sys.prefix) / 'share' / 'bearing_id' / 'msg')     # `pip install .` (setup.py's data_files)
    return cands


def msg_files() -> dict[str, Path]:
    """
    Return ``{'bearing_id_msgs/msg/Name': path}`` of the interface definitions; ``BagError`` when none are found.

    The source tree first, then the installed ``share/bearing_id_msgs/msg``, then the copy a plain ``pip install``
    puts in ``share/bearing_id/msg``.
    """
    for d in _msg_dir_candidates():
        files = sorted(d.glob('*.msg')) if d.is_dir() else []
        if files:
            return {f'{PACKAGE}/msg/{f.stem}': f for f in files}
    raise BagError(f'no {PACKAGE} .msg files found; looked in: ' + ', '.join(str(d) for d in _msg_dir_candidates()))


def make_typestore():
    """Make a new ROS 2 Jazzy typestore with the bearing_id_msgs types registered from their .msg text."""
    ts = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for name, path in msg_files().items():
        types.update(get_types_from_msg(path.read_text(), name))
    ts.register(types)
    return ts


@functools.lru_cache(maxsize=1)
def typestore():
    """Return the shared typestore, built once per process (ROS 2 Jazzy + bearing_id_msgs)."""
    return make_typestore()


# ---------------------------------------------------------------------------------------------------- QoS
LATCHED_TOPICS = ('/rotor/excitation', '/bearing_id/coefficients')
_INFINITE = (9223372036, 854775807)     # RMW_DURATION_INFINITE as rosbag2 writes it


def _enum(enum_cls, value):
    """Return the rosbags QoS enum member of a name ('transient_local', 'TRANSIENT_LOCAL'), an rclpy enum or an int."""
    name = getattr(value, 'name', value)
    if isinstance(name, str):
        return enum_cls.__members__.get(name.upper(), enum_cls.UNKNOWN)
    try:
        return enum_cls(int(value))
    except (TypeError, ValueError):
        return enum_cls.UNKNOWN


def _qtime(v):
    """
    Convert to (sec, nsec) from a mapping {sec, nsec}, a (sec, nsec) pair, nanoseconds (int) or an rclpy Duration.

    None is unspecified = 0.
    """
    if v is None:
        return QosTime(0, 0)
    if isinstance(v, dict):
        return QosTime(int(v.get('sec', 0)), int(v.get('nsec', 0)))
    if isinstance(v, (tuple, list)):
        return QosTime(int(v[0]), int(v[1]))
    ns = int(getattr(v, 'nanoseconds', v))
    if ns >= _INFINITE[0] * 1_000_000_000 + _INFINITE[1]:
        return QosTime(*_INFINITE)
    return QosTime(ns // 1_000_000_000, ns % 1_000_000_000)


def qos_profile(reliability='reliable', durability='volatile', depth: int = 10, history='keep_last', *,
                deadline=None, lifespan=None, liveliness='automatic', liveliness_lease_duration=None,
                avoid_ros_namespace_conventions: bool = False):
    """
    Make a rosbags ``Qos`` (what rosbag2 stores as one entry of ``offered_qos_profiles``).

    Policies by name ('reliable', 'best_effort', 'transient_local', 'volatile', 'keep_last', 'keep_all', 'automatic',
    ...) or as the rclpy enums; durations as nanoseconds, rclpy Durations, (sec, nsec) or {sec, nsec}; None =
    unspecified.
    """
    return Qos(_enum(QosHistory, history), max(0, int(depth)), _enum(QosReliability, reliability),
               _enum(QosDurability, durability), _qtime(deadline), _qtime(lifespan),
               _enum(QosLiveliness, liveliness), _qtime(liveliness_lease_duration),
               bool(avoid_ros_namespace_conventions))


def qos_from_rclpy(profile):
    """
    Return the rosbags ``Qos`` of an rclpy ``QoSProfile``.

    E.g. ``node.get_publishers_info_by_topic(t)[i].qos_profile``.
    """
    return qos_profile(profile.reliability, profile.durability, profile.depth, profile.history,
                       deadline=profile.deadline, lifespan=profile.lifespan, liveliness=profile.liveliness,
                       liveliness_lease_duration=profile.liveliness_lease_duration,
                       avoid_ros_namespace_conventions=profile.avoid_ros_namespace_conventions)


def default_qos(topic: str) -> list:
    """
    Return what bearing_id's own publishers offer on ``topic`` (:mod:`bearing_id.nodes.qos`).

    RELIABLE + TRANSIENT_LOCAL depth 20 for the latched topics, RELIABLE + VOLATILE otherwise (depth 400 for the
    streams, 50 for /rotor/speed, 10 for the rest).
    """
    if topic in LATCHED_TOPICS:
        return [qos_profile('reliable', 'transient_local', 20)]
    depth = {'/rotor/displacement': 400, '/bearing_id/bearing_displacement': 400, '/bearing_id/innovation': 400,
             '/rotor/speed': 50}.get(topic, 10)
    return [qos_profile('reliable', 'volatile', depth)]


# ---------------------------------------------------------------------------------------------------- writing
def _msgtype_of(msg) -> str:
    mt = getattr(msg, '__msgtype__', None)            # rosbags dataclass
    if mt:
        return mt
    cls = type(msg)                                   # rclpy: module 'pkg.msg._name', class Name
    pkg = cls.__module__.split('.')[0]
    if '.msg' in cls.__module__:
        return f'{pkg}/msg/{cls.__name__}'
    raise BagError(f'cannot tell the ROS message type of {cls.__name__}; pass (topic, msgtype, timestamp_ns, msg)')


def _serialize(ts, msg, msgtype: str) -> bytes:
    if isinstance(msg, (bytes, bytearray, memoryview)):
        return bytes(msg)
    if hasattr(msg, '__msgtype__'):
        return bytes(ts.serialize_cdr(msg, msgtype))
    from rclpy.serialization import serialize_message  # rclpy message object
    return serialize_message(msg)


def _storage_plugin(storage: str):

    s = str(storage).lower()
    if s == 'mcap':
        return StoragePlugin.MCAP
    if s in ('sqlite3', 'sqlite', 'db3'):
        return StoragePlugin.SQLITE3
    raise BagError(f'unknown bag storage {storage!r}; use one of {STORAGES}')


class BagWriter:
    """
    A rosbag2 bag written message by message and made durable every ``flush_period`` seconds.

    Each flush leaves a bag that stock readers open as it is (tested with rosbags' ``Reader``; ``ros2 bag`` is not
    installable here).  mcap: the pending chunk is closed and written (rosbags otherwise keeps up to 1 MiB of messages
    in memory), followed by :data:`MCAP_TAIL` (Data End, a Footer without summary, the magic; the next chunk overwrites
    it); sqlite3: the open transaction is committed (with ``cache_spill`` off, so no uncommitted page reaches the file);
    then ``metadata.yaml`` is replaced by one describing exactly that (written to a temporary file before the storage
    flush, moved over the old one after it; marked :data:`UNFINISHED_KEY` in ``custom_data``), and the files are
    fsync'ed.  A live writer (``flush_period`` set) flushes once on creation, and again at once when rosbags closes a
    full mcap chunk itself.  A process killed with SIGKILL therefore loses at most the last ``flush_period`` seconds and
    leaves a readable bag, unless it died while a flush was writing (microseconds for mcap: the file then ends
    mid-chunk, or holds the flush's messages and metadata.yaml not yet; the milliseconds of a sqlite3 commit's fsyncs: a
    hot journal, metadata.yaml one flush behind): :func:`read_bag` names a bag it cannot open, and :func:`recover_bag`
    (``bearing-id record --recover``) turns any unfinished bag into a complete one (mcap with its summary).
    ``flush_period=None`` never flushes early (batch writing: the bag is written on :meth:`close`).

    ``add_connection(topic, msgtype, qos=None)`` -- qos: list of rosbags ``Qos`` (see :func:`qos_profile`,
    :func:`qos_from_rclpy`), stored as the topic's ``offered_qos_profiles`` so that ``ros2 bag play`` replays a
    latched topic as latched; None = :func:`default_qos`.  ``write(topic, msgtype, stamp_ns, msg_or_bytes)`` adds the
    connection on first use.
    """

    def __init__(self, path, storage: str = 'mcap', *, types=None, overwrite: bool = False,
                 flush_period: float | None = 1.0, fsync: bool = True):
        self.path = Path(path)
        self.storage = 'sqlite3' if str(storage).lower() in ('sqlite3', 'sqlite', 'db3') else str(storage).lower()
        self.types = types if types is not None else typestore()
        self.flush_period = flush_period
        self.fsync = fsync
        plugin = _storage_plugin(storage)
        if self.path.exists():
            if not overwrite:
                raise BagError(f'{self.path}: exists already (pass overwrite=True to replace it)')
            shutil.rmtree(self.path)
        self._w = Writer(self.path, version=BAG_VERSION, storage_plugin=plugin)
        try:
            self._w.open()
        except (WriterError, OSError) as exc:
            raise BagError(f'{self.path}: cannot create bag: {exc}') from exc
        self._conns: dict[str, tuple[str, object]] = {}
        self.counts: dict[str, int] = {}
        self._last_flush = time.monotonic()
        self._tail: int | None = None       # mcap: where the last flush's MCAP_TAIL starts (the next write goes there)
        self._dirty = flush_period is not None  # a live writer's bag is readable from the start
        self.closed = False
        try:
            self.flush()
        except (OSError, sqlite3.Error) as exc:
            raise BagError(f'{self.path}: cannot create bag: {exc}') from exc

    # -- connections and messages
    def add_connection(self, topic: str, msgtype: str, qos=None):
        if topic in self._conns:
            if self._conns[topic][0] != msgtype:
                raise BagError(f'{self.path}: topic {topic} written with two types ({self._conns[topic][0]}, '
                               f'{msgtype})')
            return self._conns[topic][1]
        if msgtype not in self.types.types:
            raise BagError(f'{self.path}: message type {msgtype} (topic {topic}) is not in the typestore')
        profiles = list(qos) if qos else default_qos(topic)
        try:
            conn = self._w.add_connection(topic, msgtype, typestore=self.types, offered_qos_profiles=profiles)
        except Exception as exc:  # WriterError, a bad QoS value
            raise BagError(f'{self.path}: cannot add topic {topic}: {exc}') from exc
        self._conns[topic] = (msgtype, conn)
        self.counts[topic] = 0
        self._dirty = True
        return conn

    def write(self, topic: str, msgtype: str, stamp_ns: int, msg) -> None:
        conn = self.add_connection(topic, msgtype) if topic not in self._conns else self._conns[topic][1]
        if self._conns[topic][0] != msgtype:
            raise BagError(f'{self.path}: topic {topic} written with two types ({self._conns[topic][0]}, {msgtype})')
        self._w.write(conn, int(stamp_ns), _serialize(self.types, msg, msgtype))
        self.counts[topic] += 1
        self._dirty = True
        if self._tail is not None and not self._w.storage.chunk.bio.tell():
            self.flush()                 # rosbags wrote a full chunk itself, over the tail: make the file readable
        elif self.flush_period is not None and time.monotonic() - self._last_flush >= self.flush_period:
            self.flush()

    def maybe_flush(self) -> None:
        """Flush when ``flush_period`` has passed since the last flush (call it from an idle loop too)."""
        if self.flush_period is not None and self._dirty and time.monotonic() - self._last_flush >= self.flush_period:
            self.flush()

    def flush(self) -> None:
        """Make everything written so far durable and readable as it is (see the class docstring)."""
        st = self._w.storage
        self._last_flush = time.monotonic()
        if st is None or not self._dirty:
            return
        meta = self._w.metapath
        tmp = meta.with_suffix('.yaml.tmp')
        with open(tmp, 'w', encoding='utf-8') as fh:
            fh.write(self._metadata_text())
            fh.flush()
            if self.fsync:
                os.fsync(fh.fileno())
        if hasattr(st, 'close_chunk'):                  # rosbags McapWriter, positioned at the last tail
            if st.chunk.bio.tell():
                st.close_chunk()
            self._tail = st.bio.tell()
            st.bio.write(MCAP_TAIL)
            st.bio.flush()
            st.bio.seek(self._tail)
        else:                                           # rosbags Sqlite3Writer
            st.conn.commit()
            st.conn.execute('PRAGMA cache_spill=OFF')
        os.replace(tmp, meta)
        if self.fsync:
            if hasattr(st, 'bio'):
                os.fsync(st.bio.fileno())
            fd = os.open(self.path, os.O_RDONLY)
            try:
                os.fsync(fd)                            # the rename
            finally:
                os.close(fd)
        self._dirty = False

    def _metadata_text(self) -> str:
        """Return metadata.yaml for everything written so far: as rosbags' ``Writer.close`` writes it, but marked."""
        w = self._w
        span = {'starting_time': {'nanoseconds_since_epoch': w.min_timestamp},
                'duration': {'nanoseconds': max(0, w.max_timestamp - w.min_timestamp)},
                'message_count': sum(w.counts.values())}
        info = {'version': w.version, 'storage_identifier': self.storage, 'relative_file_paths': [w.storage.path.name],
                **span,
                'topics_with_message_count': [
                    {'topic_metadata': {'name': c.topic, 'type': c.msgtype,
                                        'serialization_format': c.ext.serialization_format,
                                        'offered_qos_profiles': dump_qos_v9(c.ext.offered_qos_profiles),
                                        'type_description_hash': c.digest},
                     'message_count': w.counts[c.id]} for c in w.connections],
                'compression_format': '', 'compression_mode': '',
                'files': [{'path': w.storage.path.name, **span}],
                'custom_data': {UNFINISHED_KEY: 'unfinished'}, 'ros_distro': 'rosbags'}
        return yaml.safe_dump({'rosbag2_bagfile_information': info}, default_flow_style=False, sort_keys=False)

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())

    def close(self) -> Path:
        """Write the index/summary and ``metadata.yaml``: the bag is complete."""
        if not self.closed:
            self.closed = True
            try:
                self._w.close()
            except Exception as exc:
                raise BagError(f'{self.path}: cannot finish bag: {exc}') from exc
        return self.path

    def abort(self) -> None:
        """Stop without finishing: flush, and leave the bag as a killed writer would (readable, unfinished)."""
        if not self.closed:
            self.closed = True
            try:
                self.flush()
            finally:
                self._w.abort()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *_):
        if exc_type is None:
            self.close()
        else:
            self.abort()
        return False


def write_bag(path, messages: Iterable, storage: str = 'mcap', *, types=None, overwrite: bool = False,
              qos: dict | None = None) -> Path:
    """
    Write a rosbag2 bag directory.

    messages : iterable of ``(topic, timestamp_ns, msg)`` or ``(topic, msgtype, timestamp_ns, msg_or_raw_bytes)``
        (the tuples :func:`read_bag` yields write back unchanged); msg is a rosbags dataclass or an rclpy message.
    storage : 'mcap' (default) or 'sqlite3'.
    types : typestore (default :func:`typestore`).
    overwrite : remove an existing bag directory at ``path`` first (otherwise that is an error).
    qos : ``{topic: [Qos, ...]}`` offered QoS profiles to store (default :func:`default_qos` per topic).
    Returns the bag directory.
    """
    qos = qos or {}
    n = 0
    with BagWriter(path, storage, types=types, overwrite=overwrite, flush_period=None) as w:
        for item in messages:
            if len(item) == 3:
                topic, stamp, msg = item
                msgtype = _msgtype_of(msg)
            elif len(item) == 4:
                topic, msgtype, stamp, msg = item
            else:
                raise BagError(f'{w.path}: message {n} must be (topic, timestamp_ns, msg) or '
                               f'(topic, msgtype, timestamp_ns, msg), got {len(item)} items')
            if topic not in w.counts:
                w.add_connection(topic, msgtype, qos.get(topic))
            w.write(topic, msgtype, stamp, msg)
            n += 1
    return Path(path)


# ---------------------------------------------------------------------------------------------------- reading
METADATA_MAX_BYTES = 16 * 1024 * 1024      # metadata.yaml of a bag with hundreds of topics and files is ~1 MB
MAX_CHUNK_BYTES = 1 << 30                  # an mcap chunk (record) declaring more is refused


def _storage_files(path: Path) -> list[Path]:
    return sorted(p for p in path.iterdir() if p.is_file() and p.suffix in ('.mcap', '.db3'))


def unfinished(path) -> Path | None:
    """
    Return the storage file of an unfinished recording, else None.

    An unfinished recording is a bag directory holding one ``.mcap``/``.db3`` file and either no ``metadata.yaml`` or
    the one a :class:`BagWriter` keeps current until it closes (:data:`UNFINISHED_KEY` in its ``custom_data``): a
    recorder killed before it could finish (or still recording).
    """
    path = Path(path)
    if not path.is_dir():
        return None
    if (path / 'metadata.yaml').exists():
        try:
            custom = _check_metadata(path).get('custom_data')
        except BagError:
            return None
        if not (isinstance(custom, dict) and UNFINISHED_KEY in custom):
            return None
    files = _storage_files(path)
    return files[0] if len(files) == 1 else None


def _check_metadata(path: Path) -> dict:
    """Bounded pre-read of metadata.yaml (size, nesting, alias expansion) before rosbags parses it; its mapping."""
    try:
        data = load_yaml_bounded(path / 'metadata.yaml', 'metadata.yaml', max_bytes=METADATA_MAX_BYTES, max_depth=32,
                                 max_nodes=1_000_000)
    except ParamError as exc:
        raise BagError(f'{path}: {str(exc)[:400]}') from None
    info = data.get('rosbag2_bagfile_information') if isinstance(data, dict) else None
    if not isinstance(info, dict):
        raise BagError(f'{path}: metadata.yaml is not rosbag2 metadata (no rosbag2_bagfile_information mapping)')
    return info


def _recover_hint(path: Path, part: Path) -> str:
    return f'`bearing-id record --recover {path}` salvages the messages written to {part.name} before it stopped'


def _open_reader(path: Path):

    if not path.exists():
        raise BagError(f'{path}: no such bag')
    if path.is_file():  # a bare .mcap/.db3 without metadata.yaml
        raise BagError(f'{path}: is a file; a rosbag2 bag is a directory with metadata.yaml and the storage file(s)')
    if not (path / 'metadata.yaml').exists():
        part = unfinished(path)
        if part is not None:
            raise BagError(f'{path}: metadata.yaml missing: an unfinished recording (the recorder was killed?); '
                           f'{_recover_hint(path, part)}')
        files = [p.name for p in path.iterdir()][:5]
        raise BagError(f'{path}: metadata.yaml missing and no single .mcap/.db3 storage file '
                       f"({'empty directory' if not files else 'has ' + ', '.join(files)}): not a rosbag2 bag")
    _check_metadata(path)
    try:
        reader = Reader(path)
        reader.open()
    except Exception as exc:  # ReaderError, yaml / sqlite / mcap errors on corrupt files
        part = unfinished(path)
        why = ('an unfinished recording whose writer stopped mid-write; ' + _recover_hint(path, part) if part else
               'its storage file is truncated or damaged, or its metadata.yaml does not describe it')
        raise BagError(f'{path}: cannot open bag ({type(exc).__name__}: {exc}): {why}') from exc
    for st in getattr(reader.storage, 'storages', []) or []:
        for ch in getattr(st, 'chunks', []) or []:
            if ch.uncompressed_size > MAX_CHUNK_BYTES or ch.compressed_size > MAX_CHUNK_BYTES:
                reader.close()
                raise BagError(f'{path}: an mcap chunk declares {ch.uncompressed_size} bytes (refused: corrupt or '
                               f'hostile)')
    return reader


def _ensure_types(ts, reader, path: Path, conns) -> None:
    """Register types the bag defines but the typestore lacks (from the bag's embedded .msg definitions)."""
    missing = {c.msgtype: c for c in conns if c.msgtype not in ts.types}
    for msgtype, c in missing.items():
        md = getattr(c, 'msgdef', None)
        data = getattr(md, 'data', '') if md is not None else ''
        fmt = str(getattr(md, 'format', '') or '')
        if data and 'msg' in fmt.lower():
            try:
                ts.register(get_types_from_msg(data, msgtype))
                continue
            except Exception as exc:  # pragma: no cover - depends on the bag's contents
                raise BagError(f"{path}: cannot register type {msgtype} from the bag's definition: {exc}") from exc
        raise BagError(f'{path}: message type {msgtype} (topic {c.topic}) is unknown and the bag carries no '
                       f'definition of it')


def bag_topics(path) -> dict[str, tuple[str, int]]:
    """``{topic: (msgtype, message_count)}`` of a bag."""
    path = Path(path)
    reader = _open_reader(path)
    try:
        return {c.topic: (c.msgtype, int(c.msgcount)) for c in reader.connections}
    finally:
        reader.close()


def offered_qos(path) -> dict[str, list]:
    """``{topic: [Qos, ...]}``: the ``offered_qos_profiles`` a bag stores per topic (empty list when none)."""
    path = Path(path)
    reader = _open_reader(path)
    try:
        return {c.topic: list(getattr(c.ext, 'offered_qos_profiles', []) or []) for c in reader.connections}
    finally:
        reader.close()


# Parallel arrays that must agree in a bearing_id message (field -> how its length relates); checked by read_bag.
def _n(msg, name):
    v = getattr(msg, name, None)
    return None if v is None else len(v)


def check_message(msgtype: str, msg) -> str | None:
    """
    Return what is structurally wrong with a decoded bearing_id message, or None.

    Arrays of inconsistent lengths, a bad sample rate.  Other types are not checked.
    """
    if msgtype.endswith('/DisplacementBlock'):
        nch = _n(msg, 'channels')
        for f in ('nodes', 'directions'):
            if _n(msg, f) is not None and _n(msg, f) != nch:
                return f'{f} has {_n(msg, f)} entries but channels has {nch}'
        ns = _n(msg, 'samples') or 0
        if not nch:
            return 'no channels' if ns else None
        if ns % nch:
            return f'{ns} samples is not a multiple of {nch} channels'
        na = _n(msg, 'sample_angles')
        if na not in (None, 0, ns // nch):
            return f'{na} sample_angles for {ns // nch} sample rows'
        fs = float(getattr(msg, 'sample_rate', 1.0))
        if not (math.isfinite(fs) and fs > 0):
            return f'sample_rate {fs!r} is not > 0'
    elif msgtype.endswith('/Excitation'):
        lens = {f: _n(msg, f) for f in ('kind', 'node', 'magnitude', 'phase', 'direction', 'frequency_ratio')}
        if len({v for v in lens.values() if v is not None}) > 1:
            return 'parallel arrays of different lengths: ' + ', '.join(f'{k} {v}' for k, v in lens.items())
    elif msgtype.endswith('/BearingCoefficients'):
        nb = _n(msg, 'bearings')
        if _n(msg, 'nodes') not in (None, nb):
            return f"nodes has {_n(msg, 'nodes')} entries but bearings has {nb}"
        for f in ('stiffness', 'damping', 'stiffness_std', 'damping_std', 'stiffness_determined',
                  'damping_determined'):
            if _n(msg, f) not in (None, 4 * nb):
                return f'{f} has {_n(msg, f)} entries, not 4 per bearing ({4 * nb})'
    return None


def read_bag(path, topics: Iterable[str] | None = None, *, raw: bool = False, types=None,
             salvage: bool = False) -> Iterator[tuple]:
    """
    Yield ``(topic, msgtype, timestamp_ns, msg)`` in time order.

    ``msg`` is a rosbags dataclass, or the raw CDR bytes when ``raw``.

    topics : only these topics (each must be in the bag, else ``BagError`` listing the ones present).
    types : typestore (default: a copy-free use of :func:`typestore` for known types; types the bag defines that
        it lacks are registered into a fresh typestore).
    salvage : read an unfinished recording (see :func:`unfinished`) up to where its storage file ends or breaks, in
        file order; without it such a bag reads as its metadata.yaml describes it (a killed :class:`BagWriter`'s
        does), and one without metadata.yaml or that does not open is a ``BagError`` pointing at ``--recover``.

    A decoded bearing_id message whose arrays disagree (:func:`check_message`) is a ``BagError`` naming it.
    """
    path = Path(path)
    if salvage and unfinished(path) is not None:
        yield from _read_salvaged(path, topics, raw=raw, types=types)
        return
    reader = _open_reader(path)
    try:
        conns = list(reader.connections)
        if topics is not None:
            want = [topics] if isinstance(topics, str) else list(topics)
            present = {c.topic for c in conns}
            absent = [t for t in want if t not in present]
            if absent:
                raise BagError(f'{path}: topic(s) {absent} not in the bag; it has {sorted(present)}')
            conns = [c for c in conns if c.topic in want]
        ts = types if types is not None else typestore()
        if not raw and any(c.msgtype not in ts.types for c in conns):
            if types is None:
                ts = make_typestore()
            _ensure_types(ts, reader, path, conns)
        if not conns:
            return
        n = 0
        try:
            for conn, stamp, data in reader.messages(connections=conns):
                if raw:
                    yield conn.topic, conn.msgtype, int(stamp), bytes(data)
                else:
                    yield conn.topic, conn.msgtype, int(stamp), _decode(ts, path, n, conn.topic, conn.msgtype, data)
                n += 1
        except BagError:
            raise
        except Exception as exc:  # truncated / corrupt storage file
            raise BagError(f'{path}: bag is truncated or corrupt after {n} message(s): '
                           f'{type(exc).__name__}: {exc}') from exc
    finally:
        reader.close()


def _decode(ts, path, n, topic, msgtype, data):
    try:
        msg = ts.deserialize_cdr(data, msgtype)
    except Exception as exc:
        raise BagError(f'{path}: message {n} on {topic} ({msgtype}) does not deserialize: '
                       f'{type(exc).__name__}: {exc}') from exc
    problem = check_message(msgtype, msg)
    if problem:
        raise BagError(f'{path}: message {n} on {topic} ({msgtype}) is malformed: {problem}')
    return msg


# ---------------------------------------------------------------------------------------------------- salvage
@dataclass
class SalvagedTopic:
    topic: str
    msgtype: str
    msgdef: str                 # the .msg text the recording embedded ('' if none)
    qos: list                   # offered_qos_profiles (rosbags Qos)
    count: int = 0


@dataclass
class Salvage:
    """
    What an unfinished recording holds.

    Its topics and (via :meth:`messages`) every complete message, in file order, up to ``valid_bytes`` of the
    ``total_bytes`` storage file; ``stopped`` says why the scan ended there.
    """

    path: Path
    storage_file: Path
    storage: str                # 'mcap' | 'sqlite3'
    topics: dict = field(default_factory=dict)      # topic -> SalvagedTopic
    valid_bytes: int = 0
    total_bytes: int = 0
    stopped: str = ''

    @property
    def message_count(self) -> int:
        return sum(t.count for t in self.topics.values())

    def messages(self, topics=None) -> Iterator[tuple]:
        """``(topic, msgtype, timestamp_ns, raw bytes)`` of every salvaged message (of ``topics`` if given)."""
        want = None if topics is None else set([topics] if isinstance(topics, str) else topics)
        if self.storage == 'mcap':
            for kind, *rest in _mcap_events(self.storage_file):
                if kind == 'msg':
                    topic, msgtype, stamp, data = rest
                    if want is None or topic in want:
                        yield topic, msgtype, stamp, data
        else:
            con = sqlite3.connect(str(self.storage_file))
            try:
                names = {tid: (name, typ) for tid, name, typ in con.execute('SELECT id, name, type FROM topics')}
                for tid, stamp, data in con.execute('SELECT topic_id, timestamp, data FROM messages '
                                                    'ORDER BY timestamp, id'):
                    if tid in names and (want is None or names[tid][0] in want):
                        yield names[tid][0], names[tid][1], int(stamp), bytes(data)
            finally:
                con.close()


def _mcap_events(path: Path):
    """
    Read an mcap file front to back with the ``mcap`` package's StreamReader (no index, no footer needed).

    Yields ('topic', SalvagedTopic) and ('msg', topic, msgtype, stamp, bytes), and last ('end',
    valid_bytes, reason): the bytes read up to the last complete record and why reading stopped there (the footer,
    or the first incomplete or damaged record: a recorder killed mid-write).  Chunk CRCs are checked; a chunk
    declaring more than :data:`MAX_CHUNK_BYTES` uncompressed is refused before it is decompressed.
    """
    schemas: dict[int, Schema] = {}
    channels: dict[int, tuple[str, str]] = {}
    valid, reason = 0, 'end of file'
    with open(path, 'rb') as fh:
        records = iter(StreamReader(fh, emit_chunks=True, validate_crcs=True,
                                    record_size_limit=MAX_CHUNK_BYTES).records)
        while True:
            try:
                rec = next(records)
                if isinstance(rec, Chunk) and rec.uncompressed_size > MAX_CHUNK_BYTES:
                    raise ValueError(f'a chunk declares {rec.uncompressed_size} bytes uncompressed (refused)')
                inner = breakup_chunk(rec, validate_crc=True) if isinstance(rec, Chunk) else [rec]
            except StopIteration:
                reason = 'footer'
                break
            except InvalidMagic:
                reason = 'not an mcap file (bad magic)'
                break
            except EndOfFile:
                reason = f'incomplete record after byte {valid} (the last write was cut off)'
                break
            except Exception as exc:     # struct / unicode / CRC / a decompressor's own error type
                reason = f'damaged record after byte {valid}: {type(exc).__name__}: {exc}'
                break
            for r in inner:
                if isinstance(r, Schema):
                    schemas[r.id] = r
                elif isinstance(r, Channel) and r.id not in channels:
                    sc = schemas.get(r.schema_id)
                    name, msgdef = (sc.name, sc.data.decode('utf-8', 'replace')) if sc is not None else ('', '')
                    channels[r.id] = (r.topic, name)
                    try:
                        qos = parse_qos(r.metadata.get('offered_qos_profiles', '')) if r.metadata else []
                    except Exception:    # a damaged profile string: the messages are still worth having
                        qos = []
                    yield 'topic', SalvagedTopic(r.topic, name, msgdef, qos or [])
                elif isinstance(r, Message) and r.channel_id in channels:
                    yield ('msg', *channels[r.channel_id], r.log_time, bytes(r.data))
            valid = fh.tell()
    yield 'end', valid, reason


def salvage_bag(path) -> Salvage:
    """
    Inspect an unfinished recording (see :func:`unfinished`).

    Topics, message counts, and how much of its storage file is usable.  ``BagError`` when ``path`` is not one.
    """
    path = Path(path)
    part = unfinished(path)
    if part is None:
        if (path / 'metadata.yaml').exists():
            raise BagError(f'{path}: has metadata.yaml: a finished bag, nothing to recover')
        raise BagError(f'{path}: not an unfinished recording (no directory holding exactly one .mcap/.db3 file)')
    sv = Salvage(path, part, 'mcap' if part.suffix == '.mcap' else 'sqlite3', total_bytes=part.stat().st_size)
    if sv.storage == 'mcap':
        for ev in _mcap_events(part):
            if ev[0] == 'topic':
                sv.topics.setdefault(ev[1].topic, ev[1])
            elif ev[0] == 'msg':
                sv.topics[ev[1]].count += 1
            else:
                _, sv.valid_bytes, sv.stopped = ev
        if sv.valid_bytes < 8:
            raise BagError(f'{path}: {part.name} is not a readable mcap file ({sv.stopped})')
        return sv

    try:
        con = sqlite3.connect(str(part))        # read-write: a hot journal of the killed transaction is rolled back
        try:
            defs = {}
            try:
                defs = dict(con.execute('SELECT topic_type, encoded_message_definition '
                                        'FROM message_definitions'))
            except sqlite3.Error:
                pass
            counts = dict(con.execute('SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id'))
            for tid, name, typ, qos in con.execute('SELECT id, name, type, offered_qos_profiles FROM topics'):
                try:
                    profiles = parse_qos(qos) if qos else []
                except Exception:
                    profiles = []
                sv.topics[name] = SalvagedTopic(name, typ, defs.get(typ, ''), profiles, int(counts.get(tid, 0)))
        finally:
            con.close()
    except sqlite3.Error as exc:
        raise BagError(f'{path}: {part.name} is not a readable sqlite3 bag: {exc}') from exc
    sv.valid_bytes = sv.total_bytes = part.stat().st_size
    sv.stopped = 'committed transactions'
    return sv


def _salvage_typestore(sv: Salvage, types=None):
    ts = types if types is not None else typestore()
    missing = [t for t in sv.topics.values() if t.msgtype not in ts.types]
    if missing and types is None:
        ts = make_typestore()
    for t in missing:
        if not t.msgdef:
            raise BagError(f'{sv.path}: message type {t.msgtype} (topic {t.topic}) is unknown and the recording '
                           f'carries no definition of it')
        try:
            ts.register(get_types_from_msg(t.msgdef, t.msgtype))
        except Exception as exc:
            raise BagError(f'{sv.path}: cannot register type {t.msgtype}: {exc}') from exc
    return ts


def _read_salvaged(path: Path, topics, *, raw: bool, types):
    sv = salvage_bag(path)
    if topics is not None:
        want = [topics] if isinstance(topics, str) else list(topics)
        absent = [t for t in want if t not in sv.topics]
        if absent:
            raise BagError(f'{path}: topic(s) {absent} not in the unfinished recording; it has {sorted(sv.topics)}')
    else:
        want = None
    ts = None if raw else _salvage_typestore(sv, types)
    for n, (topic, msgtype, stamp, data) in enumerate(sv.messages(want)):
        yield topic, msgtype, stamp, (data if raw else _decode(ts, path, n, topic, msgtype, data))


def recover_bag(path, *, types=None) -> tuple[Path, Salvage, Path]:
    """
    Turn an unfinished recording into a complete bag in place.

    Same storage, same topics, their offered QoS and every salvaged message; the unfinished original is kept next to it
    as ``<path>.unfinished``.

    Returns ``(path, salvage, backup)``.  ``BagError`` if ``path`` is not an unfinished recording or nothing in it
    can be read; the original is left untouched on any failure.
    """
    path = Path(path)
    sv = salvage_bag(path)
    ts = _salvage_typestore(sv, types)
    tmp = Path(tempfile.mkdtemp(prefix=f'.{path.name}.recover-', dir=path.parent))
    try:
        new = tmp / path.name
        with BagWriter(new, sv.storage, types=ts, flush_period=None) as w:
            for t in sv.topics.values():
                w.add_connection(t.topic, t.msgtype, t.qos or None)
            for topic, msgtype, stamp, data in sv.messages():
                w.write(topic, msgtype, stamp, data)
        backup = path.with_name(path.name + '.unfinished')
        k = 1
        while backup.exists():
            backup = path.with_name(f'{path.name}.unfinished{k}')
            k += 1
        os.rename(path, backup)
        os.rename(new, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return path, sv, backup


__all__ = ['BagError', 'BagWriter', 'STORAGES', 'LATCHED_TOPICS', 'msg_files', 'make_typestore', 'typestore',
           'write_bag', 'read_bag', 'bag_topics', 'offered_qos', 'qos_profile', 'qos_from_rclpy',
           'default_qos', 'check_message', 'unfinished', 'salvage_bag', 'recover_bag', 'Salvage']
