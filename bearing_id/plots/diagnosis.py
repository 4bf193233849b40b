"""
A diagnosis before / after.

Measured 1X per probe against the nominal model, the model with refitted bearings only ("none": no effect added) and the
augmented model (the effects found), and the residual by harmonic order.

Takes the dict of :func:`bearing_id.plots.data.diagnosis_curves`.
"""
from __future__ import annotations

import numpy as np

from .common import new_figure, probe_text
from .data import align_phase

_CURVES = (('nominal', 'nominal model', {'color': '0.5', 'ls': ':', 'lw': 1.0, 'marker': 's', 'ms': 5,
                                         'mfc': 'none'}),
           ('refitted', 'bearings refitted, no effect', {'color': 'C0', 'ls': '-', 'lw': 3.5, 'alpha': 0.45,
                                                         'marker': 'o', 'ms': 9}),
           ('augmented', 'augmented model (effects found)', {'color': 'C3', 'ls': '-', 'lw': 1.0, 'marker': '^',
                                                             'ms': 6}))


def diagnosis_bode_figure(panel, *, title=None):
    """
    One (run, probe) panel of :func:`~bearing_id.plots.data.diagnosis_curves` -> Figure (amplitude and phase).

    The diagnosis predicts at the test speeds only: its predictions are markers there, joined by thin lines that are not
    a model curve (the continuous curves are in the Bode section).
    """
    fig, axs = new_figure((8.0, 5.8), 2, 1, sharex=True)
    a, p = axs[0, 0], axs[1, 0]
    rpm = panel['rpm']
    ref = np.degrees(np.unwrap(np.angle(panel['augmented'])))
    for key, lab, st in _CURVES:
        y = panel[key]
        a.plot(rpm, np.abs(y) * 1e6, label=lab, gid=f'diag:{key}', **st)
        p.plot(rpm, np.degrees(np.unwrap(np.angle(y))), **st)
    m = panel['measured']
    s = panel['std']
    a.errorbar(rpm, np.abs(m) * 1e6, yerr=s * 1e6, fmt='o', color='k', ms=5, capsize=3, label='measured ±1σ',
               zorder=5)
    p.errorbar(rpm, align_phase(np.degrees(np.angle(m)), ref),
               yerr=np.degrees(np.minimum(s / np.maximum(np.abs(m), 1e-300), np.pi / 2)), fmt='o', color='k', ms=5,
               capsize=3, zorder=5)
    a.set_ylabel('1X amplitude [µm]')
    a.set_ylim(bottom=0)
    p.set_ylabel('1X phase [deg]')
    p.set_xlabel('rotor speed [rpm]')
    for ax in (a, p):
        ax.grid(alpha=0.3)
    a.set_title(title or f"before / after, run {panel['run']}, probe {probe_text(panel['probe'])}", fontsize=10)
    h, lab = a.get_legend_handles_labels()
    fig.legend(h, lab, loc='lower center', ncol=4, fontsize=8, frameon=False)
    fig.subplots_adjust(left=0.1, right=0.98, top=0.94, bottom=0.15, hspace=0.08)
    return fig


def residual_orders_figure(curves, *, title=None):
    """RMS residual by harmonic order before (refitted bearings, no effect) and after (augmented) -> Figure."""
    fig, axs = new_figure((6.5, 3.6))
    ax = axs[0, 0]
    o = np.asarray(curves['orders'], float)
    ax.bar(o - 0.12, np.asarray(curves['residual_before']) * 1e6, width=0.24, color='C0',
           label='before (bearings refitted, no effect)')
    ax.bar(o + 0.12, np.asarray(curves['residual_after']) * 1e6, width=0.24, color='C3', label='after (augmented)')
    ax.set_xticks(o)
    ax.set_xticklabels([f'{v:g}X' for v in o])
    ax.set_yscale('log')
    ax.set_ylabel('RMS residual [µm]')
    ax.set_title(title or 'residual (measured - model) by harmonic order, all probes and speeds', fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis='y')
    fig.subplots_adjust(left=0.13, right=0.98, top=0.9, bottom=0.12)
    return fig


__all__ = ['diagnosis_bode_figure', 'residual_orders_figure']
