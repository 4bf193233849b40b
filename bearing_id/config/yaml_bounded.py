"""
Bounded YAML reading for parameter files and bag metadata: a hostile file costs milliseconds, not memory.

Files larger than ``YAML_MAX_BYTES`` are refused before reading; nesting deeper than ``YAML_MAX_DEPTH`` and documents
whose anchors and aliases would expand to more than ``YAML_MAX_NODES`` nodes (a "billion laughs") are refused from
the parser's event stream before anything is built.  Only PyYAML's safe loader builds objects (no Python tags).
"""
from __future__ import annotations

from pathlib import Path

import yaml

from .errors import ParamError

YAML_MAX_BYTES = 4 * 1024 * 1024    # a rig file is ~4 kB; an augmented one ~10 kB
YAML_MAX_DEPTH = 64                 # nesting of mappings/sequences (rig files use 4)
YAML_MAX_NODES = 200_000            # nodes after expanding every alias (rig files have ~300)


def _yaml_loader():
    return getattr(yaml, 'CSafeLoader', yaml.SafeLoader)


def check_yaml_events(text: str, what: str, *, max_depth: int = YAML_MAX_DEPTH,
                      max_nodes: int = YAML_MAX_NODES) -> None:
    """
    Walk the parser's event stream (no objects are built) and refuse too deep or too large a document.

    Refuses nesting deeper than ``max_depth`` or a document whose aliases would expand to more than ``max_nodes`` nodes;
    raises ParamError (or yaml.YAMLError for a syntax error).  Linear in the size of the text; a billion-laughs file is
    refused after a few hundred events.
    """
    depth = 0
    total = 0                           # nodes so far, every alias counted as the size of what it refers to
    open_anchors: list = []             # (anchor or None, total at its start), one per open collection
    sizes: dict = {}                    # anchor -> expanded size of its node
    for ev in yaml.parse(text, Loader=_yaml_loader()):
        if isinstance(ev, yaml.AliasEvent):
            n = sizes.get(ev.anchor)
            if n is None:               # an alias to an anchor still open (recursive) or undefined
                raise ParamError(f'{what}: alias *{ev.anchor} refers to an undefined or enclosing anchor')
            total += n
        elif isinstance(ev, yaml.ScalarEvent):
            total += 1
            if ev.anchor is not None:
                sizes[ev.anchor] = 1
        elif isinstance(ev, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            depth += 1
            total += 1
            if depth > max_depth:
                raise ParamError(f'{what}: nested deeper than {max_depth} levels (refused; a parameter file needs '
                                 f'a handful)')
            open_anchors.append((ev.anchor, total - 1))
        elif isinstance(ev, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            depth -= 1
            anchor, start = open_anchors.pop()
            if anchor is not None:
                sizes[anchor] = total - start
        if total > max_nodes:
            raise ParamError(f'{what}: more than {max_nodes} values once its anchors/aliases are expanded (refused: '
                             f"an alias bomb such as 'billion laughs')")


def load_yaml_bounded(path: str | Path, what: str | None = None, *, max_bytes: int = YAML_MAX_BYTES,
                      max_depth: int = YAML_MAX_DEPTH, max_nodes: int = YAML_MAX_NODES):
    """
    Run ``yaml.safe_load`` on a file with bounds on its size, nesting and nodes.

    Size <= ``max_bytes`` (checked before reading), nesting <= ``max_depth``, nodes after alias expansion <=
    ``max_nodes`` (checked on the event stream before anything is constructed).  Every failure -- unreadable, too big,
    not UTF-8, not YAML, over a bound -- is a ParamError naming the file.
    """
    path = Path(path)
    what = what or str(path)
    try:
        size = path.stat().st_size
        if size > max_bytes:
            raise ParamError(f'{what}: {size} bytes, more than the {max_bytes} allowed (refused unread)')
        with open(path, 'rb') as fh:
            raw = fh.read(max_bytes + 1)
    except OSError as exc:
        raise ParamError(f'cannot read {what}: {exc}') from exc
    if len(raw) > max_bytes:            # grew since stat, or a device
        raise ParamError(f'{what}: more than {max_bytes} bytes (refused)')
    try:
        text = raw.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise ParamError(f'{what} is not UTF-8 text ({exc.reason} at byte {exc.start})') from None
    try:
        check_yaml_events(text, what, max_depth=max_depth, max_nodes=max_nodes)
        return yaml.load(text, Loader=_yaml_loader())   # noqa: S506 - a SafeLoader (C or Python)
    except yaml.YAMLError as exc:
        text = ' '.join(str(exc).replace('"<unicode string>"', path.name).split())
        raise ParamError(f'{what} is not valid YAML: {text}') from None
    except RecursionError:              # unreachable with the depth bound; kept as a last line
        raise ParamError(f'{what}: nested too deeply') from None
