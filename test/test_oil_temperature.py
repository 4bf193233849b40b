"""
Oil inlet temperature beside the identified bearings (issue 25 item 2): a warm day is not wear, a wrong oil is a change.

The oil law is Walther's through an ISO VG 46 datasheet (46 cSt at 40 degC, 6.8 cSt at 100 degC; bearings/viscosity.py,
tested against datasheets in test_viscosity.py).  (1) A history written here: three days of solves, the inlet
temperature cycling daily by +-3.5 K (the viscosity by about +-15 %), each fitted viscosity the law's at that
temperature with 0.3 % noise, clearances constant: no alarm at ARL0 = 1e4 -- while the raw viscosity alone would alarm
(the CUSUM on it is run here too, so the test can fail) -- and from day two an oil 10 % more viscous than its law: one
alarm, on the ratio, sized within 3 sigma.  (2) The identifier core with temperature readings over its data: the mean
inlet temperature and each bearing's fitted viscosity over the law's are parameters of its results; a law that
matches the simulator's true viscosity at the readings' temperature gives a ratio within 3 sigma of 1, readings 5 K
warmer a ratio off by far more than its sigma.
"""
from __future__ import annotations

import math
import time

from bearing_id.bearings import viscosity as V
from bearing_id.config.params import load_rig
from bearing_id.history import HistoryStore, IdentificationRecord, Parameter, sqlite_url
from bearing_id.history.oil_temperature import compensated, TemperatureLog, viscosity_factors
from bearing_id.history.trend import changes, parameter_series
from bearing_id.io.record import Record
from bearing_id.monitor.cusum import detect
from bearing_id.nodes.identifier_core import IdentifierCore
from bearing_id.nodes.oil import oil_law
from bearing_id.plots.trend import trend_figure
import numpy as np
import pytest
import rosutil
from test_identifier_tracking import feed, passes  # noqa: F401  (the fixture)

VG46 = V.Oil(nu1=46e-6, T1=V.celsius(40.0), nu2=6.8e-6, T2=V.celsius(100.0), rho_ref=870.0)
T0 = 1.8e9
DAY = 86400.0


def three_days(path, wrong_oil_from: float | None, seed: int):
    rng = np.random.default_rng(seed)
    with HistoryStore(sqlite_url(path)) as store:
        for i in range(int(3 * DAY / 1800)):
            t = T0 + 1800.0 * i
            T = float(V.celsius(45.0) + 3.5 * math.sin(2 * math.pi * (t - T0) / DAY))
            mu = float(V.dynamic(VG46, T)) * (1.1 if wrong_oil_from is not None and t - T0 >= wrong_oil_from else 1.0)
            fit = {'bearing1.viscosity': {'value': mu * (1 + 0.003 * rng.standard_normal()), 'std': 0.003 * mu},
                   'bearing1.clearance': {'value': 100e-6 * (1 + 0.005 * rng.standard_normal()), 'std': 0.5e-6}}
            pars = {**fit, **compensated(fit, T, 0.05, VG46)}
            store.write(IdentificationRecord(
                machine='m', t_start=t, t_end=t + 600.0, speed=100.0, method='physical',
                parameters=tuple(Parameter(*k.rsplit('.', 1), p['value'], p['std']) for k, p in pars.items())))


def test_a_temperature_cycle_is_no_change_and_a_wrong_oil_is(tmp_path):
    three_days(tmp_path / 'ok.db', None, 1)
    three_days(tmp_path / 'wrong.db', DAY, 2)
    with HistoryStore(sqlite_url(tmp_path / 'ok.db')) as store:
        series = parameter_series(store, 'm')
    names = {(s.bearing, s.name) for s in series}
    assert names == {('bearing1', 'viscosity'), ('bearing1', 'clearance'), ('bearing1', 'viscosity_vs_oil'),
                     ('oil', 'inlet_temperature')}
    assert changes(series, arl0=1e4, delta=2.0, n_reference=10) == []
    raw = [s for s in series if s.name == 'viscosity'][0]
    assert np.ptp(raw.value) / np.mean(raw.value) > 0.25           # +-15 %: the cycle is there ...
    assert detect(raw.value, raw.sigma, arl0=1e4, delta=2.0, n_reference=10)    # ... and would alarm on its own
    with HistoryStore(sqlite_url(tmp_path / 'wrong.db')) as store:
        (c,) = changes(parameter_series(store, 'm'), arl0=1e4, delta=2.0, n_reference=10)
    assert (c.bearing, c.name, c.alarm.direction) == ('bearing1', 'viscosity_vs_oil', 1)
    assert abs(c.alarm.size - 0.1) <= 3 * math.hypot(c.alarm.size_sigma, c.alarm.reference_sigma), c.alarm
    assert T0 + DAY <= c.alarm.onset_time <= T0 + DAY + 6 * 3600.0


def test_the_identifier_compares_its_viscosity_with_the_oil_law(passes, tmp_path):  # noqa: F811
    rig, _, first, _ = passes
    mu_true = rig.bearings[0].viscosity * rig.simulation.truth.viscosity_factor[0]
    T_star = float(V.temperature_for_dynamic(VG46, mu_true))
    ratios = {}
    for offset in (0.0, 5.0):
        core = IdentifierCore(rig, 'physical', tmp_path / f'rec{offset}', oil=VG46)
        rng = np.random.default_rng(3)
        for t in np.arange(0.0, 400.0, 0.5):
            assert core.add_temperature(t, T_star + offset + 0.05 * rng.standard_normal()) == ''
        feed(core, first, 0.0)
        results, _ = core.solve()
        core.close()
        p = results[0].extra['parameters']
        assert all(r.extra['parameters'] == p for r in results)           # one global fit: one set for all speeds
        assert p['oil.inlet_temperature']['value'] == pytest.approx(T_star + offset, abs=0.02)
        ratios[offset] = p['bearing1.viscosity_vs_oil'], p['bearing2.viscosity_vs_oil']
        assert any(n.startswith('oil inlet ') for n in results[0].notes)
    for r in ratios[0.0]:
        assert abs(r['value'] - 1.0) <= 3 * r['std'], r
    expected = float(V.dynamic(VG46, T_star) / V.dynamic(VG46, T_star + 5.0))     # the law's fall over 5 K
    for r in ratios[5.0]:
        assert abs(r['value'] - 1.0) > 10 * r['std'] and abs(r['value'] / expected - 1) < 0.01, (r, expected)


def test_bad_readings_and_parameters_are_named():
    log = TemperatureLog()
    assert 'outside' in log.add(1.0, 45.0)                  # degC where kelvin is expected
    assert 'not finite' in log.add(1.0, math.nan)
    assert log.add(1.0, 318.0) == '' and len(log) == 1
    assert oil_law(None, [313.15, 373.15], 870.0) is None
    with pytest.raises(ValueError, match='oil_viscosities'):
        oil_law([46e-6], [313.15, 373.15], 870.0)
    with pytest.raises(ValueError, match='must fall as the temperature rises'):
        oil_law([6.8e-6, 46e-6], [313.15, 373.15], 870.0)


@pytest.mark.ros
def test_sensor_driver_s_oil_temperature_reaches_the_identifier_s_results(tmp_path):
    """
    The driver's published oil temperature ends in the identifier's results, the viscosity on the oil's law.

    sensor_driver's sim source with an oil temperature (constant here: the law's temperature for the rig's true
    viscosity) and the identifier with the same oil law: its recorded results carry the mean inlet temperature the
    driver published, and each bearing's viscosity over the law's within 3 sigma of 1.
    """
    rig = load_rig()
    mu_true = rig.bearings[0].viscosity * rig.simulation.truth.viscosity_factor[0]
    T_star = float(V.temperature_for_dynamic(VG46, mu_true))
    oil = ['-p', 'oil_viscosities:=[4.6e-05,6.8e-06]', '-p', 'oil_density:=870.0']
    env = rosutil.ros_env()
    rec_dir = tmp_path / 'rec'
    ident = rosutil.RosProcess([rosutil.script('identifier'), '--ros-args', '-p', 'method:=physical',
                                '-p', f'record_dir:={rec_dir}', '-p', 'runs:=[A,B]', *oil], env=env, hard_timeout=120)
    drv = rosutil.RosProcess([rosutil.script('sensor_driver'), '--ros-args', '-p', 'speeds_rpm:=[1200.0,2400.0]',
                              '-p', 'dwell:=1.5', '-p', 'rate_factor:=4.0', '-p', 'exit_when_done:=true',
                              '-p', f'oil_temperature_mean:={T_star}', *oil], env=env, hard_timeout=120)
    try:
        assert drv.wait(90) == 0, drv.output()
        t_end, res = time.monotonic() + 30, []
        while time.monotonic() < t_end and len({round(r['speed_rad_s'], 6) for r in res}) < 2:
            res = [e['result'] for e in Record(rec_dir, fsync=False).entries('result')]
            time.sleep(0.25)
        assert ident.alive(), ident.output()
        ident.interrupt()
        assert 'Traceback' not in ident.stderr + drv.stderr, ident.output() + drv.output()
    finally:
        ident.close()
        drv.close()
    p = res[-1]['parameters']
    assert p['oil.inlet_temperature']['value'] == pytest.approx(T_star, abs=1e-6)
    for b in ('bearing1', 'bearing2'):
        r = p[f'{b}.viscosity_vs_oil']
        assert abs(r['value'] - 1.0) <= 3 * r['std'], r


def test_the_trend_page_shows_the_temperature_beside_each_viscosity(tmp_path):
    """The figure: every viscosity axis (raw and compensated) carries the inlet temperature in degC on a twin axis."""
    three_days(tmp_path / 'ok.db', None, 1)
    with HistoryStore(sqlite_url(tmp_path / 'ok.db')) as store:
        series = parameter_series(store, 'm')
    fig = trend_figure(series)
    oil = [s for s in series if s.bearing == 'oil'][0]
    twins = [ax for ax in fig.axes if ax.get_ylabel() == 'oil inlet [degC]']
    assert len(twins) == sum(s.name.startswith('viscosity') for s in series) == 2
    for ax in twins:
        (line,) = ax.get_lines()
        assert np.allclose(line.get_ydata(), oil.value - 273.15)


def test_each_vector_s_temperature_and_viscosity_factor_from_the_readings():
    # readings every 10 s on a ramp of 0.01 K/s, one arriving late; a span holding readings gets their mean, a span
    # between two readings the ramp at its middle (linear interpolation is exact on a ramp), a span outside them none
    log = TemperatureLog()
    stamps = list(np.arange(0.0, 1000.0, 10.0))
    stamps[5], stamps[6] = stamps[6], stamps[5]
    for t in stamps:
        assert log.add(1000.0 + t, 318.0 + 0.01 * t) == ''
    assert log.mean_at(1100.0, 1200.0) == pytest.approx(318.0 + 0.01 * 150.0, abs=1e-9)
    assert log.mean_at(1101.0, 1103.0) == pytest.approx(318.0 + 0.01 * 102.0, abs=1e-9)
    assert math.isnan(log.mean_at(3000.0, 3001.0))
    oil = VG46
    spans = [[(1000.0, 1300.0), (1500.0, 1990.0)], [(1300.0, 1500.0), (1201.0, 1203.0)]]
    f = viscosity_factors(log, spans, oil)
    T_ref = np.mean([318.0 + 0.01 * t for t in stamps])      # every reading is within the spans' union
    T = np.array([[318.0 + 0.01 * 150.0, 318.0 + 0.01 * 745.0], [318.0 + 0.01 * 400.0, 318.0 + 0.01 * 202.0]])
    assert f.shape == (2, 2)
    assert np.allclose(f, V.dynamic(oil, T) / V.dynamic(oil, T_ref), rtol=1e-12)
    assert f[0, 0] > 1 > f[0, 1]                           # warmer oil is thinner
    assert viscosity_factors(log, [[(1000.0, 1300.0), None]], oil) is None
    assert viscosity_factors(log, spans, None) is None
    assert viscosity_factors(log, [[(3000.0, 3001.0)]], oil) is None


def test_the_log_answers_as_a_scan_of_all_readings_in_and_out_of_order():
    """
    The log's searches (O(log n) per query) against a scan of every reading kept (the oracle, here).

    Readings mostly in time order with some late ones, a ``keep`` that drops the oldest: the mean, std and count over
    spans, and the temperature between readings, as the scan gives them (within 1e-12 K; the count exactly).
    """
    rng = np.random.default_rng(7)
    keep = 500.0
    log = TemperatureLog(keep=keep)
    kept = []
    t = 0.0
    for i in range(3000):
        t += rng.uniform(0.5, 1.5)
        stamp = t - (rng.uniform(0, 20) if i % 37 == 0 else 0.0)        # now and then a late reading
        T = 318.0 + 3.0 * np.sin(t / 300.0) + 0.01 * rng.standard_normal()
        assert log.add(stamp, T) == ''
        kept.append((stamp, T))
        newest = max(s for s, _ in kept)
        kept = [(s, v) for s, v in kept if s >= newest - keep]
        if i % 97 == 0 or i == 2999:
            ts, vs = (np.array(x) for x in zip(*sorted(kept, key=lambda p: p[0])))
            assert len(log) == ts.size
            for _ in range(5):
                t0 = rng.uniform(ts[0] - 10, ts[-1])
                t1 = t0 + rng.uniform(0, 30)
                sel = (ts >= t0) & (ts <= t1)
                m, sd, n = log.over(t0, t1)
                assert n == int(sel.sum())
                if n:
                    assert abs(m - vs[sel].mean()) < 1e-12 and abs(sd - vs[sel].std()) < 1e-12
                else:
                    assert math.isnan(m)
                mid = 0.5 * (t0 + t1)
                want = vs[sel].mean() if n else (float(np.interp(mid, ts, vs)) if ts[0] <= mid <= ts[-1]
                                                 else math.nan)
                got = log.mean_at(t0, t1)
                assert (math.isnan(got) and math.isnan(want)) or abs(got - want) < 1e-12, (got, want)
