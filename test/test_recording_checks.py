"""
Inputs that must not pass silently (issue 23 item 3): a keyphasor slip and a speed channel that contradicts the angle.

A simulated run saved as npz and changed in one way: `bearing-id identify` exits 2 with one paragraph that names the
slip (where, how large) or the contradiction (the factor); the untouched file identifies.  Also a ramp (the speed
channel follows the angle there) and a recording without a speed channel (all zero) pass.
"""
from __future__ import annotations

from dataclasses import replace
import math
import subprocess
import sys

from bearing_id.config.params import load_rig
from bearing_id.io.recordings import save_npz
from bearing_id.signals.recording import check_recording
from bearing_id.simulation import rig as R
import numpy as np
import pytest


@pytest.fixture(scope='module')
def recs():
    rig = load_rig()
    return [R.simulate_run(rig, run, speeds_rpm=[1200.0, 1800.0], dwell=1.0, ramp=0.3) for run in rig.simulation.runs]


def identify(files, tmp_path):
    return subprocess.run([sys.executable, '-m', 'bearing_id.cli', 'identify', *map(str, files), '--method',
                           'physical'], capture_output=True, text=True, timeout=300, cwd=tmp_path)


def save(recs, tmp_path, tag):
    return [save_npz(r, tmp_path / f'{tag}_{r.run.id}.npz') for r in recs]


def test_the_untouched_runs_ramps_and_a_missing_speed_channel_pass(recs, tmp_path):
    for r in recs:
        check_recording(r)
        check_recording(replace(r, speed=np.zeros_like(r.speed)))     # no speed channel given
    r = identify(save(recs, tmp_path, 'ok'), tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr


def test_a_keyphasor_slip_is_named(recs, tmp_path):
    a = recs[0].angle.copy()
    i = a.size // 3
    a[i:] += 2.5                                       # a 2.5 rad slip (issue 23)
    bad = [replace(recs[0], angle=a), recs[1]]
    r = identify(save(bad, tmp_path, 'slip'), tmp_path)
    assert r.returncode == 2, r.stdout + r.stderr
    assert f'keyphasor angle jumps by +2.5 rad at sample {i}' in r.stderr and 'slip' in r.stderr, r.stderr


@pytest.mark.parametrize('factor', [2.0, 60 / (2 * math.pi)])
def test_a_speed_channel_that_contradicts_the_angle_is_named(recs, tmp_path, factor):
    bad = [replace(recs[0], speed=recs[0].speed * factor), recs[1]]
    r = identify(save(bad, tmp_path, 'speed'), tmp_path)
    assert r.returncode == 2, r.stdout + r.stderr
    assert f'is x{factor:.3g} the speed of the keyphasor angle' in r.stderr, r.stderr


def _with_channel(rec, j, values):
    x = rec.samples.copy()
    x[:, j] = values
    return replace(rec, samples=x)


@pytest.mark.parametrize('fault', ['zeros', 'constant'])
def test_a_dead_channel_is_named_before_any_physics(recs, tmp_path, fault):
    """All-zero samples (issue 24: diagnosed as a probe turned with gains x 0.000) or a stuck value: exit 2, named."""
    value = 0.0 if fault == 'zeros' else 3.2e-5
    bad = [_with_channel(recs[0], 1, value), recs[1]]
    for cmd in ('identify', 'diagnose'):
        r = subprocess.run([sys.executable, '-m', 'bearing_id.cli', cmd, *map(str, save(bad, tmp_path, fault))],
                           capture_output=True, text=True, timeout=300, cwd=tmp_path)
        assert r.returncode == 2, (cmd, r.stdout + r.stderr)
        assert f"channel '{recs[0].probes[1].name}' is dead" in r.stderr, (cmd, r.stderr)


def test_a_clipped_channel_is_named_and_a_finely_quantised_one_passes(recs):
    """
    A probe beyond its range: the channel's top 10 % of values flattened at one value -> refused, named.

    A 16-bit DAQ (the signal spanning ~1000 codes: ~0.6 % of the samples on the peak code, under CLIP_FRACTION)
    passes, as does a coarse 100-code one (~2 %).
    """
    x = recs[0].samples[:, 0]
    top = np.quantile(x, 0.9)
    with pytest.raises(ValueError, match=rf"channel '{recs[0].probes[0].name}' is clipped: .* at its largest value"):
        check_recording(_with_channel(recs[0], 0, np.minimum(x, top)))
    span = x.max() - x.min()
    for codes in (1000, 100):
        q = span / codes
        check_recording(replace(recs[0], samples=np.round(recs[0].samples / q) * q))
