"""
Peak-memory benchmark of the offline route on a long recording: ``bearing-id identify`` on 1-hour runs.

The recordings (the packaged rig, its runs A and B, its two probes at 10,240 Hz, the default speeds at a dwell that
makes each run ``--minutes`` long) are simulated piece by piece (:func:`bearing_id.simulation.rig.simulate_stream`)
and written piece by piece in the format :func:`bearing_id.io.recordings.save_npz` writes (the samples, angle and
speed members stored, the rest as ``save_npz`` writes them), so that making them never holds a run in memory either.
They go to a temporary directory (``--keep DIR``: there, reused when present).

Printed: the samples per run, the MiB their arrays would take once read (both files), and the peak RSS of
``bearing-id identify`` on them (a fresh process, its VmHWM), against the target.

Target: <= 500 MB (issue 23 item 6): the recordings are streamed window by window (at most one steady window of
``MAX_WINDOW`` s and one piece read per run held), so the peak does not grow with the recording.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_offline_memory.py [--minutes 60] [--keep DIR]
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
os.environ.setdefault('OMP_NUM_THREADS', '1')

import argparse  # noqa: E402, I100  (after the thread settings above)
from pathlib import Path  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import zipfile  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import benchlib as bl  # noqa: E402, I100  (after the sys.path insert above)

TARGET_MB = 500.0
COPY_BYTES = 8 << 20


def _member(zf, key: str, compress: bool):
    info = zipfile.ZipInfo(f'{key}.npy', (1980, 1, 1, 0, 0, 0))
    info.external_attr = 0o644 << 16
    info.compress_type = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    return zf.open(info, 'w', force_zip64=True)


def _header(fh, shape) -> None:
    np.lib.format.write_array_header_2_0(fh, {'descr': np.lib.format.dtype_to_descr(np.dtype(float)),
                                              'fortran_order': False, 'shape': tuple(shape)})


def write_long_npz(path: Path, rig, run, schedule) -> int:
    """Simulate one run piece by piece into ``path`` (the ``save_npz`` format) -> samples written."""
    from bearing_id.simulation.rig import simulate_stream
    s = simulate_stream(rig, run, schedule)
    n, nch = s.n_samples, len(s.probes)
    spill = {k: path.with_suffix(f'.{k}.raw') for k in ('angle', 'speed')}
    with zipfile.ZipFile(path, 'w', allowZip64=True) as zf:
        with _member(zf, 'samples', False) as fh, open(spill['angle'], 'wb') as fa, open(spill['speed'], 'wb') as fw:
            _header(fh, (n, nch))
            for _, w, a, y in s.pieces():
                fh.write(np.ascontiguousarray(y, dtype=float).tobytes())
                fa.write(np.asarray(a, dtype=float).tobytes())
                fw.write(np.asarray(w, dtype=float).tobytes())
        for k, f in spill.items():
            with _member(zf, k, False) as fh, open(f, 'rb') as src:
                _header(fh, (n,))
                while True:
                    b = src.read(COPY_BYTES)
                    if not b:
                        break
                    fh.write(b)
            f.unlink()
        speeds = sorted(s.truth_coefficients)
        nodes = sorted(s.truth_coefficients[speeds[0]])
        ex = run.excitation
        small = {
            'format': np.array('bearing_id.recording.v1'), 'sample_rate': np.array(s.sample_rate),
            'channels': np.array([p.name for p in s.probes]), 'nodes': np.array([p.node for p in s.probes]),
            'directions': np.array([p.direction for p in s.probes]), 'run_id': np.array(run.id),
            'ex_kind': np.array([e.kind for e in ex], dtype='U16'),
            'ex_node': np.array([e.node for e in ex], dtype=int),
            'ex_magnitude': np.array([e.magnitude for e in ex], dtype=float),
            'ex_phase': np.array([e.phase for e in ex], dtype=float),
            'ex_direction': np.array([e.direction for e in ex], dtype='U16'),
            'ex_frequency_ratio': np.array([e.frequency_ratio for e in ex], dtype=float),
            'segments': np.array(s.segments, dtype=float).reshape(-1, 4),
            'truth_speeds': np.array(speeds), 'truth_nodes': np.array(nodes),
            'truth_K': np.array([[s.truth_coefficients[w][nd][0] for nd in nodes] for w in speeds]),
            'truth_C': np.array([[s.truth_coefficients[w][nd][1] for nd in nodes] for w in speeds]),
            'rig_name': np.array(s.rig_name)}
        for k, v in small.items():
            with _member(zf, k, True) as fh:
                np.lib.format.write_array(fh, v, allow_pickle=False)
    return n


def long_recordings(directory: Path, minutes: float) -> list:
    """Return the run files (one per run of the packaged rig) of ``minutes`` each, written when not yet there."""
    from bearing_id.config.params import load_rig
    from bearing_id.simulation.rig import run_schedule
    rig = load_rig()
    sim = rig.simulation
    n_speeds = len(sim.speeds_rpm)
    dwell = (60.0 * minutes - (n_speeds - 1) * sim.ramp) / n_speeds
    files = []
    for run in sim.runs:
        f = directory / f'run_{run.id}_{minutes:g}min.npz'
        if not f.exists():
            write_long_npz(f.with_suffix('.part'), rig, run, run_schedule(rig, dwell=dwell))
            f.with_suffix('.part').rename(f)
        files.append(f)
    return files


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--minutes', type=float, default=60.0, help='length of each run (default 60)')
    ap.add_argument('--keep', metavar='DIR', help='write the recordings here and keep them (reused when present)')
    ap.add_argument('--method', help='identify --method (default: none given, the default of the command)')
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix='bench_offline_') as tmp:
        d = Path(args.keep) if args.keep else Path(tmp)
        d.mkdir(parents=True, exist_ok=True)
        files = long_recordings(d, args.minutes)
        n, mib = 0, 0.0
        for f in files:
            with zipfile.ZipFile(f) as zf:
                mib += sum(i.file_size for i in zf.infolist()) / 2**20
                with zf.open('samples.npy') as fh:
                    np.lib.format.read_magic(fh)
                    n = np.lib.format.read_array_header_2_0(fh)[0][0]
        print(f'# peak RSS of `bearing-id identify` on {len(files)} runs of {args.minutes:g} min, {bl.load_note()}')
        argv = bl.cli('identify', *files, *(('--method', args.method) if args.method else ()))
        wall, cpu, rss, rc = bl.run_process(argv, timeout=7200.0)
        mb = rss * 2**20 / 1e6
        print(bl.table(['samples per run', 'arrays MiB (all files)', 'peak RSS MB', 'wall s', 'exit', 'target',
                        'met'],
                       [[f'{n}', f'{mib:.0f}', f'{mb:.0f}', f'{wall:.0f}', f'{rc}', f'<= {TARGET_MB:.0f}',
                         bl.yes(rc in (0, 1) and mb <= TARGET_MB)]]))
    return 0


if __name__ == '__main__':
    sys.exit(main())
