"""The trend figure: each fitted bearing parameter against time with its 1-sigma band and the change alarms."""
from __future__ import annotations

from .common import new_figure
from ..bearings.viscosity import ZERO_CELSIUS

HOUR = 3600.0


def trend_figure(series, changes=()):
    """
    Return a figure with one axis per series (``Series``: bearing, name, t [s, UNIX], value, sigma [SI]).

    Time in hours from the first point; the value relative to the series' first value (x1.00), the 1-sigma band
    shaded; each change (``Change``: bearing, name, alarm) marked at its onset (dashed) and alarm (solid).  With an
    oil inlet temperature series (``oil`` / ``inlet_temperature`` [K]), every viscosity axis shows it beside, in degC
    on a second y axis: a viscosity that follows it is the temperature, not the bearing.
    """
    n = max(len(series), 1)
    fig, axes = new_figure((9.0, 2.2 * n + 0.6), nrows=n, squeeze=False)
    t0 = min(float(s.t[0]) for s in series) if series else 0.0
    oil = next((s for s in series if (s.bearing, s.name) == ('oil', 'inlet_temperature')), None)
    for ax, s in zip(axes[:, 0], series):
        ref = s.value[0] if s.value[0] else 1.0
        h = (s.t - t0) / HOUR
        ax.fill_between(h, (s.value - s.sigma) / ref, (s.value + s.sigma) / ref, alpha=0.25, lw=0)
        ax.plot(h, s.value / ref, '.-', ms=3, lw=0.8)
        for c in changes:
            if (c.bearing, c.name) == (s.bearing, s.name):
                ax.axvline((c.alarm.onset_time - t0) / HOUR, color='tab:red', ls='--', lw=0.8)
                ax.axvline((c.alarm.time - t0) / HOUR, color='tab:red', lw=1.0)
        ax.set_ylabel(f'{s.bearing}\n{s.name} / first')
        ax.grid(True, alpha=0.3)
        if oil is not None and s.name.startswith('viscosity'):
            tw = ax.twinx()
            tw.plot((oil.t - t0) / HOUR, oil.value - ZERO_CELSIUS, color='tab:orange', lw=0.8)
            tw.set_ylabel('oil inlet [degC]', color='tab:orange')
    axes[-1, 0].set_xlabel('time from the first point [h]')
    return fig


__all__ = ['trend_figure']
