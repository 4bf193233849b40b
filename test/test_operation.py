"""
The long-run simulation (issue 25 item 5): an oil temperature cycle and a wearing bearing, streamed by sensor_driver.

References: the oil's datasheet (ISO VG 46: 46 cSt at 40 degC, 6.8 cSt at 100 degC, density linear in T) for the
viscosity at the cycle's peak; the wear ramp's closed form; the simulator's machine after the profile checked against
:func:`changed_truth` with the same factors (the bearings a segment is computed with); the published readings'
stamps and degC against the profile.
"""
from __future__ import annotations

import math

from bearing_id.bearings import viscosity as V
from bearing_id.config.params import load_rig, ParamError
from bearing_id.nodes import sensor_driver_core as core
from bearing_id.nodes.topics import TOPIC_DISPLACEMENT, TOPIC_OIL_TEMPERATURE
from bearing_id.simulation import rig as R
from bearing_id.simulation.operation import Operation
import numpy as np
import pytest

VG46 = V.Oil(nu1=46e-6, T1=V.celsius(40.0), nu2=6.8e-6, T2=V.celsius(100.0), rho_ref=870.0)


def values(**kw):
    v = {s.name: s.default for s in core.SPECS}
    v.update(speeds_rpm=[900.0, 1500.0], dwell=1.0, noise=0.0)
    v.update(kw)
    return v


def test_the_profile_against_the_datasheet_and_the_wear_ramp():
    op = Operation(oil=VG46, T_mean=V.celsius(40.0), T_amplitude=60.0, T_period=4000.0, wear_bearing=1,
                   wear_onset=100.0, wear_end=300.0, wear_clearance=1.08)
    assert op.temperature(1000.0) == pytest.approx(V.celsius(100.0), abs=1e-9)       # the peak: 100 degC
    rho = lambda T: 870.0 - 0.65 * (T - V.celsius(15.0))                              # noqa: E731
    expected = 6.8 * rho(V.celsius(100.0)) / (46.0 * rho(V.celsius(40.0)))
    assert op.viscosity_factor(1000.0) == pytest.approx(expected, rel=1e-9)
    assert op.clearance_factors(50.0, 2) == (1.0, 1.0)
    assert op.clearance_factors(200.0, 2) == pytest.approx((1.0, 1.04))
    assert op.clearance_factors(1e6, 2) == pytest.approx((1.0, 1.08))
    worn = Operation(wear_bearing=3, wear_onset=0.0, wear_end=1.0, wear_clearance=1.1)
    with pytest.raises(ValueError, match='not one of the 2 bearings'):
        worn.clearance_factors(0.0, 2)
    assert worn.viscosity_factor(5.0) == 1.0                    # no oil temperature: the viscosity stays


def test_the_stream_follows_the_profile_and_publishes_the_temperature():
    rig = load_rig()
    name = rig.bearings[1].name
    v = values(oil_temperature_mean=318.15, oil_temperature_amplitude=5.0, oil_temperature_period=8.0,
               oil_viscosities=[46e-6, 6.8e-6], wear_bearing=name, wear_onset=0.0, wear_end=0.5,
               wear_clearance=1.08, oil_temperature_interval=0.25)
    sources = core.load_sources(v)[:1]          # the first run, streamed below (it fills in its truth)
    temperature = core.sim_temperature(v)
    msgs = list(core.stream_messages(sources, 1024, 0, 'rig', temperature=temperature,
                                     temperature_interval=0.25))
    temps = [(t_ns, m) for topic, t_ns, m, _ in msgs if topic == TOPIC_OIL_TEMPERATURE]
    blocks = [t_ns for topic, t_ns, _, _ in msgs if topic == TOPIC_DISPLACEMENT]
    assert [t for t, _ in temps] == [int(round(0.25e9 * k)) for k in range(len(temps))]
    assert (len(temps) - 1) * 0.25 <= blocks[-1] * 1e-9 < len(temps) * 0.25
    for t_ns, m in temps:
        T = 318.15 + 5.0 * math.sin(2 * math.pi * t_ns * 1e-9 / 8.0)
        assert m.temperature == pytest.approx(T - 273.15, abs=1e-9) and m.header.frame_id == 'rig'
    # every reading goes out before the first block at or after its time
    order = [topic for topic, *_ in msgs if topic in (TOPIC_OIL_TEMPERATURE, TOPIC_DISPLACEMENT)]
    assert order[0] == TOPIC_OIL_TEMPERATURE
    # the machine of the second dwell (it starts after the wear ended): bearing 2's clearance x1.08, the viscosity
    # the oil law gives at that moment, bearing 1 unworn
    run = sources[0]
    seg = run.segments[-1]
    t_seg = seg[0] / run.sample_rate
    op = core.operation_of(v, rig)
    ref = R.changed_truth(rig, clearance=(1.0, 1.08), viscosity=float(op.viscosity_factor(t_seg)))(seg[2])
    got = run.truth_coefficients[seg[2]]
    for node, (K, C) in ref.items():
        assert np.allclose(got[node][0], K, rtol=1e-12) and np.allclose(got[node][1], C, rtol=1e-12)


@pytest.mark.parametrize('kw, words', [
    ({'oil_temperature_mean': 318.0}, "'oil_viscosities' needs"),
    ({'wear_bearing': 'nope'}, "'wear_bearing': 'nope' is not a bearing"),
    ({'wear_bearing': 'bearing1', 'wear_onset': 5.0, 'wear_end': 1.0}, 'onset 5.0 s must come before'),
    ({'oil_temperature_mean': 318.0, 'oil_viscosities': [46e-6, 6.8e-6], 'truth_change_after': 1.0}, 'give one'),
])
def test_a_profile_that_is_not_one_is_a_parameter_error(kw, words):
    with pytest.raises(ParamError, match=words):
        core.load_sources(values(**kw))
