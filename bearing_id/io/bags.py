"""rosbag2 bags (sqlite3 and mcap) without a ROS installation, via ``rosbags``.

The typestore is ROS 2 Jazzy's plus the ``bearing_id_msgs`` types registered from the very ``.msg`` files that
``msg_defs/`` builds, so bags written here read in stock ROS 2 tools (the RIHS01 type hashes match rosidl's) and
bags recorded with ``ros2 bag record`` read here.

* :func:`typestore` -- the shared typestore (cached; do not register into it, make your own with
  :func:`make_typestore` if you need more types).
* :func:`write_bag` (path, messages, storage='mcap') -- messages as ``(topic, timestamp_ns, msg)`` or
  ``(topic, msgtype, timestamp_ns, msg_or_raw_bytes)``; msg may be a rosbags dataclass or an rclpy message.
* :func:`read_bag` (path, topics=None, raw=False) -- yields ``(topic, msgtype, timestamp_ns, msg or raw bytes)`` in
  time order.  rclpy's ``Publisher.publish`` accepts the raw bytes, the cleanest way to replay.
* :func:`bag_topics` (path) -- ``{topic: (msgtype, count)}``.

Every failure (missing/truncated/corrupt bag, missing topic, unknown type) raises :class:`BagError` naming the file.
"""
from __future__ import annotations

import functools
import importlib.util
import os
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path

PACKAGE = "bearing_id_msgs"
STORAGES = ("mcap", "sqlite3")
BAG_VERSION = 9  # rosbag2 metadata version written by ROS 2 Jazzy


class BagError(RuntimeError):
    """A bag cannot be read or written; the message names the file and the problem."""


# -------------------------------------------------------------------------------------------------- .msg files
def _msg_dir_candidates() -> list[Path]:
    here = Path(__file__).resolve()
    cands = [here.parents[2] / "msg_defs" / "msg"]                     # source tree (editable install, checkout)
    prefixes = [Path(sys.prefix)]
    prefixes += [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    try:                                                                  # <prefix>/lib/pythonX.Y/site-packages/pkg
        spec = importlib.util.find_spec(PACKAGE)
    except (ImportError, ValueError):
        spec = None
    if spec is not None and spec.submodule_search_locations:
        for loc in spec.submodule_search_locations:
            prefixes.append(Path(loc).resolve().parents[3])
    cands += [p / "share" / PACKAGE / "msg" for p in prefixes]
    return cands


def msg_files() -> dict[str, Path]:
    """``{'bearing_id_msgs/msg/Name': path}`` of the interface definitions (source tree first, then installed
    ``share/bearing_id_msgs/msg``); ``BagError`` when none are found."""
    for d in _msg_dir_candidates():
        files = sorted(d.glob("*.msg")) if d.is_dir() else []
        if files:
            return {f"{PACKAGE}/msg/{f.stem}": f for f in files}
    raise BagError(f"no {PACKAGE} .msg files found; looked in: " + ", ".join(str(d) for d in _msg_dir_candidates()))


def make_typestore():
    """A new ROS 2 Jazzy typestore with the bearing_id_msgs types registered from their .msg text."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for name, path in msg_files().items():
        types.update(get_types_from_msg(path.read_text(), name))
    ts.register(types)
    return ts


@functools.lru_cache(maxsize=1)
def typestore():
    """The shared typestore (ROS 2 Jazzy + bearing_id_msgs), built once per process."""
    return make_typestore()


# ---------------------------------------------------------------------------------------------------- writing
def _msgtype_of(msg) -> str:
    mt = getattr(msg, "__msgtype__", None)            # rosbags dataclass
    if mt:
        return mt
    cls = type(msg)                                   # rclpy: module 'pkg.msg._name', class Name
    pkg = cls.__module__.split(".")[0]
    if ".msg" in cls.__module__:
        return f"{pkg}/msg/{cls.__name__}"
    raise BagError(f"cannot tell the ROS message type of {cls.__name__}; pass (topic, msgtype, timestamp_ns, msg)")


def _serialize(ts, msg, msgtype: str) -> bytes:
    if isinstance(msg, (bytes, bytearray, memoryview)):
        return bytes(msg)
    if hasattr(msg, "__msgtype__"):
        return bytes(ts.serialize_cdr(msg, msgtype))
    from rclpy.serialization import serialize_message  # rclpy message object
    return serialize_message(msg)


def _storage_plugin(storage: str):
    from rosbags.rosbag2 import StoragePlugin

    s = str(storage).lower()
    if s == "mcap":
        return StoragePlugin.MCAP
    if s in ("sqlite3", "sqlite", "db3"):
        return StoragePlugin.SQLITE3
    raise BagError(f"unknown bag storage {storage!r}; use one of {STORAGES}")


def write_bag(path, messages: Iterable, storage: str = "mcap", *, types=None, overwrite: bool = False) -> Path:
    """Write a rosbag2 bag directory.

    messages : iterable of ``(topic, timestamp_ns, msg)`` or ``(topic, msgtype, timestamp_ns, msg_or_raw_bytes)``
        (the tuples :func:`read_bag` yields write back unchanged); msg is a rosbags dataclass or an rclpy message.
    storage : 'mcap' (default) or 'sqlite3'.
    types : typestore (default :func:`typestore`).
    overwrite : remove an existing bag directory at ``path`` first (otherwise that is an error).
    Returns the bag directory.
    """
    from rosbags.rosbag2 import Writer, WriterError

    path = Path(path)
    ts = types if types is not None else typestore()
    plugin = _storage_plugin(storage)
    if path.exists():
        if not overwrite:
            raise BagError(f"{path}: exists already (pass overwrite=True to replace it)")
        import shutil
        shutil.rmtree(path)
    conns: dict[tuple[str, str], object] = {}
    n = 0
    try:
        with Writer(path, version=BAG_VERSION, storage_plugin=plugin) as w:
            for item in messages:
                if len(item) == 3:
                    topic, stamp, msg = item
                    msgtype = _msgtype_of(msg)
                elif len(item) == 4:
                    topic, msgtype, stamp, msg = item
                else:
                    raise BagError(f"{path}: message {n} must be (topic, timestamp_ns, msg) or "
                                   f"(topic, msgtype, timestamp_ns, msg), got {len(item)} items")
                key = (topic, msgtype)
                if key not in conns:
                    if msgtype not in ts.types:
                        raise BagError(f"{path}: message type {msgtype} (topic {topic}) is not in the typestore")
                    if any(t == topic for t, _ in conns):
                        raise BagError(f"{path}: topic {topic} written with two types")
                    conns[key] = w.add_connection(topic, msgtype, typestore=ts)
                w.write(conns[key], int(stamp), _serialize(ts, msg, msgtype))
                n += 1
    except WriterError as exc:
        raise BagError(f"{path}: cannot write bag: {exc}") from exc
    return path


# ---------------------------------------------------------------------------------------------------- reading
def _open_reader(path: Path):
    from rosbags.rosbag2 import Reader

    if not path.exists():
        raise BagError(f"{path}: no such bag")
    if path.is_file():  # a bare .mcap/.db3 without metadata.yaml
        raise BagError(f"{path}: is a file; a rosbag2 bag is a directory with metadata.yaml and the storage file(s)")
    if not (path / "metadata.yaml").exists():
        raise BagError(f"{path}: metadata.yaml missing (recording interrupted? `ros2 bag reindex` can rebuild it)")
    try:
        reader = Reader(path)
        reader.open()
    except Exception as exc:  # ReaderError, yaml / sqlite / mcap errors on corrupt files
        raise BagError(f"{path}: cannot open bag: {type(exc).__name__}: {exc}") from exc
    return reader


def _ensure_types(ts, reader, path: Path, conns) -> None:
    """Register types the bag defines but the typestore lacks (from the bag's embedded .msg definitions)."""
    from rosbags.typesys import get_types_from_msg

    missing = {c.msgtype: c for c in conns if c.msgtype not in ts.types}
    for msgtype, c in missing.items():
        md = getattr(c, "msgdef", None)
        data = getattr(md, "data", "") if md is not None else ""
        fmt = str(getattr(md, "format", "") or "")
        if data and "msg" in fmt.lower():
            try:
                ts.register(get_types_from_msg(data, msgtype))
                continue
            except Exception as exc:  # pragma: no cover - depends on the bag's contents
                raise BagError(f"{path}: cannot register type {msgtype} from the bag's definition: {exc}") from exc
        raise BagError(f"{path}: message type {msgtype} (topic {c.topic}) is unknown and the bag carries no "
                       f"definition of it")


def bag_topics(path) -> dict[str, tuple[str, int]]:
    """``{topic: (msgtype, message_count)}`` of a bag."""
    path = Path(path)
    reader = _open_reader(path)
    try:
        return {c.topic: (c.msgtype, int(c.msgcount)) for c in reader.connections}
    finally:
        reader.close()


def read_bag(path, topics: Iterable[str] | None = None, *, raw: bool = False, types=None) -> Iterator[tuple]:
    """Yield ``(topic, msgtype, timestamp_ns, msg)`` in time order; ``msg`` is a rosbags dataclass, or the raw CDR
    bytes when ``raw``.

    topics : only these topics (each must be in the bag, else ``BagError`` listing the ones present).
    types : typestore (default: a copy-free use of :func:`typestore` for known types; types the bag defines that
        it lacks are registered into a fresh typestore).
    """
    path = Path(path)
    reader = _open_reader(path)
    try:
        conns = list(reader.connections)
        if topics is not None:
            want = [topics] if isinstance(topics, str) else list(topics)
            present = {c.topic for c in conns}
            absent = [t for t in want if t not in present]
            if absent:
                raise BagError(f"{path}: topic(s) {absent} not in the bag; it has {sorted(present)}")
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
                    try:
                        msg = ts.deserialize_cdr(data, conn.msgtype)
                    except Exception as exc:
                        raise BagError(f"{path}: message {n} on {conn.topic} ({conn.msgtype}) does not "
                                       f"deserialize: {type(exc).__name__}: {exc}") from exc
                    yield conn.topic, conn.msgtype, int(stamp), msg
                n += 1
        except BagError:
            raise
        except Exception as exc:  # truncated / corrupt storage file
            raise BagError(f"{path}: bag is truncated or corrupt after {n} message(s): "
                           f"{type(exc).__name__}: {exc}") from exc
    finally:
        reader.close()


__all__ = ["BagError", "STORAGES", "msg_files", "make_typestore", "typestore", "write_bag", "read_bag",
           "bag_topics"]
