"""
Read a DAQ export (CSV or NPZ) into a Recording for the sensor_driver's ``file`` source.

The Recording is :class:`bearing_id.signals.recording.Recording`.  NPZ: the self-describing format of
:func:`bearing_id.io.recordings.save_npz` (``bearing-id simulate`` writes it).

CSV (one row per sample, comma separated, ``#`` lines are metadata)::

    # sample_rate: 10240          Hz, required
    # units: um                   unit of the displacement columns: m (default), mm or um
    # channels: p6x@6x, p6y@6y    name@<node><x|y> per displacement column (node 1-based), or at any angle
                                  name@<node>:<angle>deg[*<gain>], e.g. p9a@9:45deg, p9b@9:135deg (from +x to +y)
    # run: A                      optional run id
    t,angle,speed,p6x,p6y         or t,keyphasor,p6x,p6y   or t,speed_rpm,angle,...

The rotor angle comes from an ``angle`` column [rad, keyphasor angle] or is rebuilt from a ``keyphasor`` column (a
once-per-revolution pulse train) by :mod:`bearing_id.signals.keyphasor`: angle = 0 (mod 2 pi) where the rising edge
crosses half its swing (a square pulse is high while the angle mod 2 pi is in [0, width)), sub-sample key marks (sharp
or finite-rise edges, whole or fractional samples per revolution), linear between marks.  Speed: ``speed`` [rad/s],
``speed_rpm`` [rpm], the keyphasor's revolution durations, or the derivative of the angle.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .recordings import load_npz, open_npz
from ..config.params import Probe, Run
from ..conventions import parse_probe_direction, probe_direction
from ..signals import keyphasor as _kp
from ..signals.recording import Recording

UNIT_SCALE = {'m': 1.0, 'mm': 1e-3, 'um': 1e-6, 'µm': 1e-6}


class DaqError(ValueError):
    """The DAQ file cannot be used; the message says what is wrong and where."""


class KeyphasorDaqError(DaqError, _kp.KeyphasorError):
    """A keyphasor column that gives no rotor angle (both a DaqError and a keyphasor.KeyphasorError)."""


def angle_from_keyphasor(pulses: np.ndarray, sample_rate: float, **kw) -> tuple[np.ndarray, np.ndarray]:
    """
    Return rotor angle [rad] and speed [rad/s] per sample (N,) from a once-per-revolution pulse train (N,).

    Computed by :func:`bearing_id.signals.keyphasor.angle_from_keyphasor` (same keywords), raising
    :class:`KeyphasorDaqError`.
    """
    try:
        return _kp.angle_from_keyphasor(pulses, sample_rate, **kw)
    except _kp.KeyphasorError as exc:
        raise KeyphasorDaqError(str(exc)) from None


def _parse_channels(text: str) -> tuple[Probe, ...]:
    out = []
    for tok in filter(None, (s.strip() for s in text.split(','))):
        if '@' not in tok:
            raise DaqError(f"channels: '{tok}' must be name@<node><x|y> or name@<node>:<angle>deg, e.g. p6x@6x, "
                           'p9a@9:45deg')
        name, loc = tok.split('@', 1)
        if ':' in loc:
            node, direction = (s.strip() for s in loc.split(':', 1))
            try:
                direction = probe_direction(*parse_probe_direction(direction))
            except ValueError:
                raise DaqError(f"channels: '{tok}': the direction after ':' must be x, y or <angle>deg[*<gain>]") \
                    from None
        else:
            node, direction = loc[:-1], loc[-1:]
            if direction not in ('x', 'y'):
                raise DaqError(f"channels: '{tok}': location must be a 1-based node followed by x or y, or "
                               '<node>:<angle>deg')
        if not node.isdigit() or int(node) < 1:
            raise DaqError(f"channels: '{tok}': the node must be a 1-based whole number")
        out.append(Probe(name.strip(), int(node), direction))
    return tuple(out)


def read_csv(path: str | Path):
    """Read a CSV DAQ export (format in the module docstring) -> Recording (samples in metres)."""
    path = Path(path)
    meta = {}
    header, lineno = None, 0
    with open(path, encoding='utf-8') as fh:
        for lineno, line in enumerate(fh, 1):
            s = line.strip()
            if not s:
                continue
            if s.startswith('#'):
                if ':' in s:
                    k, v = s[1:].split(':', 1)
                    meta[k.strip().lower()] = v.split('  ')[0].strip()
                continue
            header = [h.strip() for h in s.split(',')]
            break
    if header is None:
        raise DaqError(f'{path}: no header row')
    if 'sample_rate' not in meta:
        raise DaqError(f"{path}: missing '# sample_rate: <Hz>' line")
    try:
        fs = float(meta['sample_rate'])
    except ValueError:
        raise DaqError(f"{path}: sample_rate {meta['sample_rate']!r} is not a number [Hz]") from None
    if not fs > 0:
        raise DaqError(f'{path}: sample_rate must be > 0 Hz')
    units = meta.get('units', 'm')
    if units not in UNIT_SCALE:
        raise DaqError(f'{path}: units {units!r} must be one of {sorted(UNIT_SCALE)}')
    if 'channels' not in meta:
        raise DaqError(f"{path}: missing '# channels: name@<node><x|y>, ...' line")
    probes = _parse_channels(meta['channels'])
    missing = [p.name for p in probes if p.name not in header]
    if missing:
        raise DaqError(f'{path}: channel column(s) {missing} not in the header {header}')
    try:
        data = np.loadtxt(path, delimiter=',', comments='#', skiprows=lineno, ndmin=2)
    except ValueError as exc:
        raise DaqError(f'{path}: unreadable numbers ({exc})') from None
    if data.shape[1] != len(header):
        raise DaqError(f'{path}: {data.shape[1]} columns but {len(header)} header names')
    col = {h: data[:, i] for i, h in enumerate(header)}
    n = data.shape[0]
    kp_speed = None
    if 'angle' in col:
        angle = col['angle'].astype(float)
    elif 'keyphasor' in col:
        try:
            angle, kp_speed = angle_from_keyphasor(col['keyphasor'], fs)
        except KeyphasorDaqError as exc:
            raise KeyphasorDaqError(f"{path}: column 'keyphasor': {exc}") from None
    else:
        raise DaqError(f"{path}: need an 'angle' [rad] or a 'keyphasor' column")
    if 'speed' in col:
        speed = col['speed'].astype(float)
    elif 'speed_rpm' in col:
        speed = col['speed_rpm'] * (2 * math.pi / 60.0)
    elif kp_speed is not None:
        speed = kp_speed
    else:
        speed = np.gradient(angle) * fs
    samples = np.column_stack([col[p.name] for p in probes]) * UNIT_SCALE[units]
    t = col['t'] if 't' in col else np.arange(n) / fs
    return Recording(sample_rate=fs, t=t, speed=speed, angle=angle, probes=probes, samples=samples,
                     run=Run(meta.get('run', '?'), ()), rig_name=meta.get('rig', 'daq'))


def write_csv(rec, path: str | Path, units: str = 'm', keyphasor: bool = False, *,
              pulse_width: float = _kp.DEFAULT_WIDTH, rise_time: float = 0.0) -> Path:
    """
    Write a Recording as a CSV DAQ export (the format :func:`read_csv` reads).

    ``keyphasor``: write a once-per-revolution pulse column (0..1) instead of the angle, by the key-mark convention
    (:func:`bearing_id.signals.keyphasor.pulse_from_angle`): high while angle mod 2 pi is in [0, ``pulse_width``) [rad],
    with linear edges of ``rise_time`` [s] centred on the mark when > 0 (a sampled analog keyphasor).
    """
    path = Path(path)
    s = UNIT_SCALE[units]
    ch = ', '.join(f'{p.name}@{p.node}' + (p.direction if p.direction in ('x', 'y') else f':{p.direction}')
                   for p in rec.probes)
    lines = [f'# sample_rate: {rec.sample_rate!r}', f'# units: {units}', f'# channels: {ch}',
             f'# run: {rec.run.id}', f'# rig: {rec.rig_name}']
    if keyphasor:
        pulse = _kp.pulse_from_angle(rec.angle, rec.speed, width=pulse_width, rise_time=rise_time)
        cols = [rec.t, pulse, rec.speed]
        names = ['t', 'keyphasor', 'speed']
    else:
        cols = [rec.t, rec.angle, rec.speed]
        names = ['t', 'angle', 'speed']
    cols += [rec.samples[:, j] / s for j in range(rec.samples.shape[1])]
    names += [p.name for p in rec.probes]
    with open(path, 'w', encoding='utf-8') as fh:
        fh.write('\n'.join(lines) + '\n' + ','.join(names) + '\n')
        np.savetxt(fh, np.column_stack(cols), delimiter=',', fmt='%.12g')
    return path


def read_daq(path: str | Path, stream: bool = False):
    """
    Read a DAQ export by extension (.csv or .npz) -> Recording; raises DaqError (a ValueError) with the reason.

    ``stream``: a .npz is only opened, to be read piece by piece (:func:`bearing_id.io.recordings.open_npz`: never
    whole in memory, its values checked as they are read); a .csv is read whole either way.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f'DAQ file {path} does not exist')
    if path.suffix.lower() == '.npz':
        try:
            return open_npz(path) if stream else load_npz(path)
        except ValueError as exc:
            raise DaqError(str(exc)) from None
    if path.suffix.lower() in ('.csv', '.txt'):
        return read_csv(path)
    raise DaqError(f'{path}: unknown DAQ format (use .csv or .npz)')
