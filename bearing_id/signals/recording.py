"""
A recording: what a DAQ gives for one excitation run (samples, keyphasor angle, speed, probes, the known excitation).

The one in-memory form every route shares: the simulator makes it (:mod:`bearing_id.simulation.rig`), the readers
of .npz, CSV and bag files return it (:mod:`bearing_id.io`), the 1X fits take it (:mod:`bearing_id.identify`).
:func:`check_recording` refuses one the pipeline cannot use.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from ..config.params import Run
from ..conventions import parse_probe_direction

#: |displacement| above this [m] is not a plausible shaft vibration in metres (mm or µm sent by mistake?)
MAX_PLAUSIBLE_DISPLACEMENT = 1e-2


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
    :data:`MAX_PLAUSIBLE_DISPLACEMENT` (not metres, or damaged data), probe nodes < 1 or
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
    limit = MAX_PLAUSIBLE_DISPLACEMENT
    peak = max(float(x.max()), -float(x.min()))        # = max |x| (finite: checked above), no (N, nch) temporary
    if peak > limit:
        i, j = np.unravel_index(int(np.argmax(np.abs(x))), x.shape)
        raise ValueError(f'{where}: samples reach {peak:.3g} m (row {i}, channel {j}), beyond the {limit:g} m a shaft '
                         f'displacement can be: not metres (mm or um?) or damaged data')
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
    _check_angle_and_speed(np.asarray(rec.angle, float), np.asarray(rec.speed, float), float(fs), where)
    return rec


# rad: an angle step this far from its neighbours' within one sample is a keyphasor slip.  Blocks that carry only their
# first sample's angle are joined with a constant speed per block: on a speed ramp that is off by up to alpha T^2 / 2
# at a join (0.79 rad on the shipped bag's ramps), which must pass; a quarter turn is beyond any such join.
SLIP_RAD = math.pi / 2
SPEED_MISMATCH = 0.05    # relative: a speed channel this far from the angle's speed (median) contradicts it


def _check_angle_and_speed(angle: np.ndarray, speed: np.ndarray, fs: float, where: str) -> None:
    """
    Refuse a keyphasor slip and a speed channel that contradicts the angle (ValueError naming where and how much).

    Slip: one sample's angle step differs from the median step of its 64 neighbours by more than ``SLIP_RAD`` (a quarter
    turn: no rotor accelerates so within one sample; a lost or extra key mark, or a wrapped angle).  Contradiction: the
    speed channel, where given (not all zero), differs from the angle's speed by more than ``SPEED_MISMATCH`` (the
    median of their ratio over the samples; a speed in rpm or Hz instead of rad/s, a multi-pulse keyphasor).  The
    pipeline takes the speed from the angle; these are named instead of passing silently.
    """
    d = np.diff(angle)
    k = 64
    for i in np.flatnonzero(np.abs(np.diff(d)) > SLIP_RAD)[:100] + 1:      # candidates: a step in the step (O(N))
        i = int(min(i, d.size - 1))
        local = float(np.median(d[max(0, i - k):i + k + 1]))
        if abs(d[i] - local) > SLIP_RAD:
            raise ValueError(f'{where}: keyphasor angle jumps by {d[i] - local:+.3g} rad at sample {i + 1} '
                             f'(t = {(i + 1) / fs:.4g} s) against its neighbours: a keyphasor slip (a lost or extra '
                             'key mark) or a wrapped angle; repair the angle there or split the recording')
    turning = d > 0
    if np.any(speed != 0) and np.any(turning):
        w_angle = d[turning] * fs
        ratio = float(np.median(speed[:-1][turning] / w_angle))
        if abs(ratio - 1) > SPEED_MISMATCH:
            raise ValueError(f'{where}: the speed channel is x{ratio:.3g} the speed of the keyphasor angle (median '
                             f'over the samples; e.g. {float(np.median(speed)):.6g} against '
                             f'{float(np.median(w_angle)):.6g} rad/s): a speed in rpm or Hz instead of rad/s, or a '
                             'keyphasor with more than one mark per revolution?')
