"""
The ``sensor_driver`` node's core (no ROS): its sources and the message stream it publishes.

Sources
    ``sim`` (default): the simulated rig of ``rig_params`` (:func:`bearing_id.simulation.rig.simulate_run`, truth
    bearings != theory), one recording per excitation run of the chosen scenario. ``file``: DAQ exports (CSV or NPZ,
    :mod:`bearing_id.io.daq`), one per run.  :func:`stream_messages` turns them into the node's messages (also
    ``scripts/make_bags.py``'s bags).
"""
from __future__ import annotations

from dataclasses import dataclass

from .specs import ParamSpec
from .topics import TOPIC_DISPLACEMENT, TOPIC_EXCITATION, TOPIC_SPEED
from ..config.params import load_rig, ParamError, parse_probes
from ..io import messages as M
from ..io.daq import read_daq
from ..simulation import rig as rigmod

NAME = 'sensor_driver'

SPECS = [
    ParamSpec('source', 'sim', 'data source: the simulated rig of rig_params, or DAQ export files',
              choices=('sim', 'file')),
    ParamSpec('rig_params', '', 'rig YAML (empty: the packaged params/rig.yaml)'),
    ParamSpec('scenario', 'default', "excitation plan of the sim source: the runs in rig_params, the paper's "
              'unbalance of Table 3 or 4, or the directional-force plan',
              choices=('default', 'paper_table3', 'paper_table4', 'force')),
    ParamSpec('files', None, 'file source: DAQ exports (.csv or .npz), one per excitation run, played in order',
              type_='str[]'),
    ParamSpec('speeds_rpm', None, 'sim source: speed steps (unset: simulation.speeds_rpm of rig_params)', 'rpm',
              lo=1.0, hi=1e5, type_='float[]'),
    ParamSpec('dwell', None, 'sim source: time at each speed (unset: simulation.dwell)', 's', lo=0.01, hi=1e4,
              type_='float'),
    ParamSpec('noise', None, "sim source: noise std as a fraction of each channel's RMS (unset: simulation.noise)",
              '-', lo=0.0, hi=1.0, type_='float'),
    ParamSpec('probes', None, "sim source: probe channels NODE+x|y, e.g. [6x, 6y] (unset: the rig's probes)",
              type_='str[]'),
    ParamSpec('block_size', 1024, 'samples per DisplacementBlock', 'samples', lo=16, hi=1 << 20),
    ParamSpec('rate_factor', 1.0, 'playback speed relative to real time', '-', lo=0.01, hi=1000.0),
    ParamSpec('wait_for_subscribers', 1, 'start once this many subscribers listen to /rotor/displacement '
              '(reliable QoS only protects matched subscribers)', '', lo=0, hi=100),
    ParamSpec('subscriber_timeout', 60.0, 'give up waiting for subscribers after this long and start anyway', 's',
              lo=0.0, hi=3600.0),
    ParamSpec('exit_when_done', False, 'exit after the last block (else stay up, reporting diagnostics)'),
    ParamSpec('frame_id', '', 'header frame_id (empty: the machine id, else the rig name)'),
    ParamSpec('diagnostics_period', 1.0, 'period of /diagnostics', 's', lo=0.05, hi=60.0),
]


@dataclass(frozen=True)
class BlockSpan:
    """One block of a recording: rows [i0, i1) of run ``run_index``; ``t_offset`` [s] of the run in the stream."""

    run_index: int
    i0: int
    i1: int
    t_offset: float


def load_recordings(values: dict):
    """Load the source's recordings (one per run) from validated parameter ``values``; raises ParamError/ValueError."""
    if values['source'] == 'file':
        files = values['files'] or []
        if not files:
            raise ParamError("parameter 'files' must list at least one DAQ export when source is 'file'")
        return [read_daq(f) for f in files]
    rig = load_rig(values['rig_params'] or None)
    if rig.simulation is None:
        raise ParamError(f"parameter 'rig_params': {values['rig_params'] or 'the packaged rig'} has no simulation "
                         f'section')
    runs = rig.simulation.runs if values['scenario'] == 'default' else rigmod.scenario(values['scenario'])
    probes = None
    if values['probes']:
        try:
            probes = parse_probes(','.join(values['probes']))
        except ParamError as exc:
            raise ParamError(f"parameter 'probes': {exc}") from None
    return [rigmod.simulate_run(rig, r, speeds_rpm=values['speeds_rpm'], dwell=values['dwell'],
                                noise=values['noise'], probes=probes) for r in runs]


def block_spans(lengths, sample_rate: float, block_size: int):
    """Blocks over consecutive runs of ``lengths`` samples: the stream's time runs on across runs."""
    out = []
    t_off = 0.0
    for k, n in enumerate(lengths):
        for i0 in range(0, n, block_size):
            out.append(BlockSpan(k, i0, min(n, i0 + block_size), t_off))
        t_off += n / sample_rate
    return out


def stream_messages(recordings, block_size: int, t0_ns: int, frame_id: str, types=None):
    """
    Everything the driver publishes for ``recordings``, in order: yields (topic, stamp_ns, msg, end_ns).

    Per block: an Excitation when the run changes (stamped at the run's first block), a RotorSpeed and the
    DisplacementBlock (stamp = time of the first sample; ``end_ns`` = time one sample after its last; the keyphasor
    angle of every sample in ``sample_angles``; the run in ``run_id``).  ``types``:
    None for rclpy messages, a rosbags typestore for bag writing.
    """
    fs = recordings[0].sample_rate
    prev = None
    for seq, sp in enumerate(block_spans([r.samples.shape[0] for r in recordings], fs, block_size)):
        rec = recordings[sp.run_index]
        t_ns = t0_ns + int(round((sp.t_offset + sp.i0 / fs) * 1e9))
        end_ns = t0_ns + int(round((sp.t_offset + sp.i1 / fs) * 1e9))
        if sp.run_index != prev:
            yield (TOPIC_EXCITATION, t_ns, M.excitation_to_msg(rec.run, stamp=t_ns, frame_id=frame_id, types=types),
                   t_ns)
            prev = sp.run_index
        w, a = float(rec.speed[sp.i0]), float(rec.angle[sp.i0])
        yield TOPIC_SPEED, t_ns, M.speed_to_msg(w, a, stamp=t_ns, frame_id=frame_id, types=types), t_ns
        yield (TOPIC_DISPLACEMENT, t_ns, M.block_to_msg(rec.samples[sp.i0:sp.i1], seq, fs, w, a, rec.probes,
                                                        stamp=t_ns, frame_id=frame_id, types=types,
                                                        sample_angles=rec.angle[sp.i0:sp.i1], run_id=rec.run.id),
               end_ns)
