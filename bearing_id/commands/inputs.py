"""
The recordings the offline commands read (``identify``, ``diagnose``): files or a rosbag2 bag.

``.npz`` files (``bearing-id simulate``, :func:`bearing_id.io.recordings.save_npz`), ``.csv`` DAQ exports
(:mod:`bearing_id.io.daq`) or a rosbag2 bag.

Every way a file can be wrong -- missing, unreadable, truncated, corrupt, hostile (a zip bomb, a crafted header),
inconsistent (array sizes that disagree), unusable (NaN samples, no excitation) -- is a :class:`ParamError` (exit 2)
naming the file and the problem; nothing large is read before the sizes have been checked against each other
(:func:`bearing_id.io.recordings.load_npz`, :func:`bearing_id.io.bags.read_bag`).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
import sys

from ..config.params import ParamError
from ..io.bags import bag_topics, BagError
from ..io.daq import read_csv
from ..io.recordings import load_npz, open_npz, recordings_from_bag
from ..signals.recording import check_recording

BAG_SUFFIXES = ('.mcap', '.db3')


class InputError(ParamError):
    """An input file (recording, bag) cannot be used; the message names the file and the problem (exit 2)."""


def is_bag(path: Path) -> bool:
    return path.is_dir() or path.suffix.lower() in BAG_SUFFIXES


def load_recording_file(path: Path, stream: bool = False):
    """
    One ``.npz`` or ``.csv`` recording -> a checked Recording; ParamError if unusable.

    ``stream``: an .npz is opened to be read piece by piece (:func:`bearing_id.io.recordings.open_npz`: its description
    checked now, its values as its pieces are read); a CSV is read whole either way.
    """
    suffix = path.suffix.lower()
    try:
        if suffix == '.npz':
            return open_npz(path) if stream else load_npz(path)
        if suffix in ('.csv', '.txt'):
            return check_recording(read_csv(path), str(path))
    except ValueError as exc:           # rig / daq errors (DaqError, UnicodeDecodeError are ValueErrors)
        msg = str(exc)
        raise InputError(msg if str(path) in msg else f'{path}: {msg}') from None
    except MemoryError:
        raise InputError(f'{path}: too large to read into memory') from None
    raise InputError(f'{path}: unknown recording format {path.suffix!r} (give .npz, .csv or a bag directory)')


def precheck_bag(path: Path) -> dict:
    """
    Open a bag (metadata, index) and check it has the topics identification needs; ParamError if not.

    Done before the (slower) full read.
    """
    try:
        topics = bag_topics(path)
    except BagError as exc:
        raise InputError(str(exc)) from None
    need = [t for t in ('/rotor/displacement', '/rotor/excitation') if t not in topics]
    if need:
        raise InputError(f"{path}: the bag has no {' and no '.join(need)} (it has {sorted(topics)}); identification "
                         f'needs the displacement blocks and the excitation of each run')
    return topics


def load_bag_recordings(path: Path) -> list:
    """One checked Recording per excitation run of a bag; ParamError if the bag cannot be used."""
    try:
        recs = recordings_from_bag(path)
        return [check_recording(r, f'{path}: run {r.run.id}') for r in recs]
    except (BagError, ValueError) as exc:
        msg = str(exc)
        raise InputError(msg if str(path) in msg else f'{path}: {msg}') from None
    except MemoryError:
        raise InputError(f'{path}: too large to read into memory') from None


def load_recordings(inputs, *, one_bag_only: bool = False, stream: bool = False) -> list:
    """
    Load the recordings from files and bags, in the order given (a bag contributes one per excitation run).

    one_bag_only : a bag must be the only input (``identify``: .npz/.csv files are one run each, a bag holds all).
    stream : .npz files are opened to be read piece by piece (:func:`load_recording_file`); their values are checked
    as they are read, which raises a :class:`bearing_id.signals.recording.RecordingError` naming the file then.
    """
    paths = [Path(s) for s in inputs]
    if not paths:
        raise ParamError('no recordings given')
    for p in paths:
        if not p.exists():
            raise FileNotFoundError(f'no such file or bag: {p}')
    bags = [p for p in paths if is_bag(p)]
    if one_bag_only and bags and len(paths) != 1:
        raise InputError('give recording files (.npz/.csv, one per run) or a single bag, not both / not several bags')
    loaded = {}
    for i, p in enumerate(paths):          # cheap checks of everything first, the full bag reads last
        if is_bag(p):
            precheck_bag(p)
        else:
            loaded[i] = [load_recording_file(p, stream)]
    for i, p in enumerate(paths):
        if i not in loaded:
            loaded[i] = load_bag_recordings(p)
    return [r for i in range(len(paths)) for r in loaded[i]]


def check_probe_nodes(recordings, n_nodes: int) -> None:
    """Every channel's node must exist in the model (1..n_nodes)."""
    for r in recordings:
        for p in r.probes:
            if not 1 <= p.node <= n_nodes:
                raise ParamError(f'run {r.run.id}: probe {p.name} is at node {p.node} but the model has nodes '
                                 f'1..{n_nodes}')
        for e in r.run.excitation:
            if not 1 <= e.node <= n_nodes:
                raise ParamError(f'run {r.run.id}: excitation at node {e.node} but the model has nodes 1..{n_nodes}')


def check_probes_against_params(recordings, rig) -> None:
    """
    Refuse a recording whose probe disagrees with the params file's probe of the same name (node, angle or gain).

    The recording's probes are the ones used (they describe its channels); a params file that places a probe of that
    name elsewhere means one of the two is wrong -- an InputError names both instead of silently using either.
    """
    params = {p.name: p for p in getattr(rig, 'probes', ()) or ()}
    for r in recordings:
        for p in r.probes:
            q = params.get(p.name)
            if q is None:
                continue
            if q.node != p.node or abs(q.angle_deg - p.angle_deg) > 1e-6 or abs(q.gain - p.gain) > 1e-9:
                raise InputError(f'run {r.run.id}: probe {p.name} is at node {p.node}, {p.angle_deg:g} deg (gain '
                                 f'{p.gain:g}) in the recording but at node {q.node}, {q.angle_deg:g} deg (gain '
                                 f'{q.gain:g}) in the params file: correct the one that is wrong (the probes of the '
                                 'recording are the ones used), or rename the probe in the params file')


def attach_excitation(recordings, rig, *, required: bool) -> list:
    """
    Attach the params' excitation to each recording that carries none.

    A recording that carries no excitation (a CSV DAQ export, an npz without ``ex_*``) takes that of the params' run
    with the same id (``simulation.runs[].id``), and says so on stderr (never a silent substitution).  ``required``:
    otherwise refuse it (identification needs the known excitation); else leave it as it is.
    """
    runs = {r.id: r for r in (rig.simulation.runs if rig.simulation is not None else ())}
    out = []
    for rec in recordings:
        if not rec.run.excitation:
            if rec.run.id in runs:
                rec = dataclasses.replace(rec, run=runs[rec.run.id])
                print(f"note: run {rec.run.id!r} carries no excitation; the params file's run {rec.run.id!r} is used: "
                      + '; '.join(f'{e.kind} at node {e.node}, {e.magnitude:g}' for e in rec.run.excitation),
                      file=sys.stderr)
            elif required:
                raise InputError(f'run {rec.run.id!r} carries no excitation (a DAQ export names only the run) and the '
                                 f'params file has no run {rec.run.id!r} to take it from (its runs: '
                                 f"{sorted(runs) or 'none'}): add the run's excitation under simulation.runs")
        out.append(rec)
    return out
