"""
1X response per probe: Bode (amplitude and phase vs speed) and polar (the phasor in the complex plane).

Measured 1X vectors are drawn as points with +-1-sigma (error bars on the Bode plot, circles on the polar plot); the
model as continuous curves over a fine speed grid (identified bearings solid, theory dashed), one colour per
excitation run.  Phase is arg X [deg] of x(t) = Re{X exp(j phi)} with phi the keyphasor angle
(:mod:`bearing_id.conventions`), drawn unwrapped along the model curve; a measured phase is moved by whole turns onto
the branch of that curve.  Legends sit outside the axes, so they hide no data.

``curves`` arguments are lists of :class:`Curve`.  Artists carry ``gid`` strings (``'model:<label>:<run>'``,
``'measured:<run>'``) for tests.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .common import MODEL_STYLE, new_figure, probe_text, run_color, THEORY_STYLE, TRUTH_STYLE
from .data import align_phase


@dataclass
class Curve:
    """
    A model curve.

    ``label``, ``rpm`` (ng,), ``Y`` complex (n_runs, ng) [m], ``kind`` 'identified' | 'theory' | 'truth' (line style).
    """

    label: str
    rpm: np.ndarray
    Y: np.ndarray
    kind: str = 'identified'


_STYLE = {'identified': MODEL_STYLE, 'theory': THEORY_STYLE, 'truth': TRUTH_STYLE}


def _ref_phase(curves, r, rpm):
    """Unwrapped phase [deg] of the first curve at ``rpm`` (for aligning measured phases), or None."""
    for c in curves:
        if c.Y.shape[0] > r:
            ph = np.degrees(np.unwrap(np.angle(c.Y[r])))
            return np.interp(rpm, c.rpm, ph, left=np.nan, right=np.nan)
    return None


def _legend(fig, run_labels, curves):
    from matplotlib.lines import Line2D
    hs = [Line2D([], [], color=run_color(i), lw=6, alpha=0.6, label=f'run {lab}') for i, lab in enumerate(run_labels)]
    hs.append(Line2D([], [], ls='', marker='o', color='0.2', label='measured 1X ±1σ'))
    seen = set()
    for c in curves:
        if c.label in seen:
            continue
        seen.add(c.label)
        st = dict(_STYLE[c.kind])
        st['color'] = '0.2'
        hs.append(Line2D([], [], label=c.label, **st))
    fig.legend(handles=hs, loc='lower center', ncol=min(len(hs), 5), fontsize=8, frameon=False)


def bode_figure(probe, rpm, X, X_std, run_labels, curves=(), *, critical_rpm=(), title=None):
    """
    Bode plot of one probe -> Figure.

    rpm (ns,); X complex (n_runs, ns) [m]; X_std (n_runs, ns) [m] (1-sigma of Re and of Im each); run_labels (n_runs,);
    curves: list of Curve; critical_rpm: model critical speeds to mark.
    """
    X = np.atleast_2d(np.asarray(X))
    S = np.atleast_2d(np.asarray(X_std, float))
    rpm = np.asarray(rpm, float)
    fig, axs = new_figure((8.5, 6.6), 2, 1, sharex=True)
    a_amp, a_ph = axs[0, 0], axs[1, 0]
    for r, lab in enumerate(run_labels):
        col = run_color(r)
        for c in curves:
            st = dict(_STYLE[c.kind])
            st['color'] = col
            y = c.Y[r]
            a_amp.plot(c.rpm, np.abs(y) * 1e6, gid=f'model:{c.label}:{lab}', **st)
            a_ph.plot(c.rpm, np.degrees(np.unwrap(np.angle(y))), gid=f'model-phase:{c.label}:{lab}', **st)
        amp = np.abs(X[r]) * 1e6
        a_amp.errorbar(rpm, amp, yerr=S[r] * 1e6, fmt='o', ms=5, color=col, mec='k', mew=0.5, capsize=3,
                       zorder=4, gid=f'measured:{lab}')
        ph = np.degrees(np.angle(X[r]))
        ref = _ref_phase(curves, r, rpm)
        if ref is not None:
            ph = np.where(np.isfinite(ref), align_phase(ph, np.nan_to_num(ref)), ph)
        else:
            ph = np.degrees(np.unwrap(np.angle(X[r])))
        sph = np.degrees(np.minimum(S[r] / np.maximum(np.abs(X[r]), 1e-300), np.pi / 2))
        a_ph.errorbar(rpm, ph, yerr=sph, fmt='o', ms=5, color=col, mec='k', mew=0.5, capsize=3, zorder=4,
                      gid=f'measured-phase:{lab}')
    lo = min([rpm.min()] + [c.rpm.min() for c in curves])
    hi = max([rpm.max()] + [c.rpm.max() for c in curves])
    for i, c in enumerate(critical_rpm):
        if lo <= c <= hi:
            for a in (a_amp, a_ph):
                a.axvline(c, color='0.4', ls=':', lw=1.2, gid=f'critical:{i}')
            a_amp.text(c, 0.98, f' critical {c:.0f} rpm (model)',
                       transform=a_amp.get_xaxis_transform(), va='top', ha='left', fontsize=8, color='0.3')
    a_amp.set_ylabel('1X amplitude [µm]')
    a_amp.set_ylim(bottom=0)
    a_ph.set_ylabel('1X phase arg X [deg]')
    a_ph.set_xlabel('rotor speed [rpm]')
    for a in (a_amp, a_ph):
        a.grid(alpha=0.3)
    a_amp.set_title(title or f'1X Bode plot, probe {probe_text(probe)}', fontsize=10)
    _legend(fig, run_labels, curves)
    fig.subplots_adjust(left=0.1, right=0.98, top=0.95, bottom=0.16, hspace=0.08)
    return fig


def _label_points(ax, x, y, texts, span):
    """Put rpm labels beside points, radially outward, skipping labels that would sit on an earlier one."""
    placed = []
    for xi, yi, t in zip(x, y, texts):
        if any(np.hypot(xi - a, yi - b) < 0.045 * span for a, b in placed):
            continue
        placed.append((xi, yi))
        ang = np.arctan2(yi, xi)
        ax.annotate(t, (xi, yi), xytext=(9 * np.cos(ang), 9 * np.sin(ang)), textcoords='offset points',
                    ha='left' if np.cos(ang) >= 0 else 'right', va='bottom' if np.sin(ang) >= 0 else 'top',
                    fontsize=7, color='0.15')


def polar_figure(probe, rpm, X, X_std, run_labels, curves=(), *, title=None):
    """Polar plot of one probe, one panel per run -> Figure (see :func:`bode_figure` for the arguments)."""
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Circle
    X = np.atleast_2d(np.asarray(X))
    S = np.atleast_2d(np.asarray(X_std, float))
    rpm = np.asarray(rpm, float)
    nr = len(run_labels)
    fig, axs = new_figure((4.6 * nr + 0.4, 5.4), 1, nr)
    for r, lab in enumerate(run_labels):
        ax = axs[0, r]
        col = run_color(r)
        pts = [X[r] * 1e6]
        for c in curves:
            st = dict(_STYLE[c.kind])
            st['color'] = col
            y = c.Y[r] * 1e6
            ax.plot(y.real, y.imag, gid=f'polar:{c.label}:{lab}', **st)
            pts.append(y)
        m = X[r] * 1e6
        R = float(np.nanmax(np.abs(m) + S[r] * 1e6)) * 1.3 if m.size else 0.0
        if not R > 0:
            R = float(np.nanmax(np.abs(np.concatenate(pts)))) * 1.2 or 1.0
        for c in curves:                        # arrow: direction of increasing speed, inside the frame
            y = c.Y[r] * 1e6
            inside = np.nonzero(np.abs(y) < 0.8 * R)[0]
            if c.kind == 'identified' and inside.size > 4:
                k = int(inside[int(0.6 * inside.size)])
                k = min(max(k, 1), y.size - 2)
                ax.annotate('', xy=(y[k + 1].real, y[k + 1].imag), xytext=(y[k - 1].real, y[k - 1].imag),
                            arrowprops={'arrowstyle': '-|>', 'color': col, 'lw': 1.5, 'mutation_scale': 14})
        m = X[r] * 1e6
        ax.add_collection(PatchCollection([Circle((xi.real, xi.imag), si) for xi, si in zip(m, S[r] * 1e6)],
                                          fc=col, ec=col, alpha=0.25, lw=0.8, gid=f'polar-sigma:{lab}'))
        ax.plot(m.real, m.imag, 'o', ms=5, color=col, mec='k', mew=0.5, zorder=4, gid=f'polar-measured:{lab}')
        for c in curves:                        # a model curve that leaves the frame is said to, with its peak
            if c.kind != 'identified':
                continue
            y = np.abs(c.Y[r]) * 1e6
            k = int(np.argmax(y))
            if y[k] > R:
                ax.text(0.02, 0.02, f"{c.label.split(' (')[0]} model leaves the frame:\npeak {y[k]:.0f} µm at "
                        f'{c.rpm[k]:.0f} rpm (see the Bode plot)', transform=ax.transAxes, fontsize=7, color='0.3')
        _label_points(ax, m.real, m.imag, [f'{v:.0f}' for v in rpm], 2 * R)
        ax.axhline(0, color='0.5', lw=0.7)
        ax.axvline(0, color='0.5', lw=0.7)
        ax.add_collection(PatchCollection([Circle((0, 0), frac * R / 1.3) for frac in (0.25, 0.5, 0.75, 1.0)],
                                          fc='none', ec='0.85', lw=0.7, zorder=0))
        ax.set_xlim(-R, R)
        ax.set_ylim(-R, R)
        ax.set_aspect('equal')
        ax.set_xlabel('Re X [µm]  (0°)', fontsize=9)
        ax.set_ylabel('Im X [µm]  (90°)', fontsize=9)
        ax.tick_params(labelsize=8)
        ax.set_title(f'run {lab}', fontsize=10)
    fig.suptitle(title or f'1X polar plot, probe {probe_text(probe)} (labels: rpm; phase counter-clockwise)',
                 fontsize=10)
    _legend(fig, run_labels, curves)
    fig.subplots_adjust(left=0.08, right=0.98, top=0.88, bottom=0.2, wspace=0.3)
    return fig


__all__ = ['Curve', 'bode_figure', 'polar_figure']
