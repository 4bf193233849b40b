"""
Bearing coefficients vs speed.

* :func:`coefficients_figure` -- like the paper's Figures 7-8 and 12-15, one panel per coefficient and bearing
  (rows K and C of each bearing; columns xx, xy, yx, yy): identified values with 1-sigma error bars and a shaded
  +-1-sigma band (filled markers = determined by the data), coefficients the data do NOT determine as hollow grey
  markers (their value is the prior's, never a result), the theory (nominal params) and, for a simulated recording,
  the truth as lines.  A misfit (chi-square test failed) is written on the figure.  K in N/m, C in N s/m.
* :func:`plot_coefficients` -- the same, saved to a PNG (``bearing-id identify --plot``).
* :func:`theory_coefficients_figure` -- the theory's K and C vs speed of ``bearing-id model``, one panel per
  coefficient with each bearing in its own colour, line style and marker (coinciding bearings stay visible).
* :func:`bearing_vectors_figure` -- like Figures 5-6 / 10-11: amplitude [um] and phase [deg] of the bearing-node 1X
  displacement, estimated vs true; :func:`plot_bearing_vectors` saves it (``bearing-id identify --plot``).
"""
from __future__ import annotations

import numpy as np

from .common import BEARING_STYLES, new_figure, save_png, THEORY_STYLE, TRUTH_STYLE
from ..conventions import COEFF_ORDER, rad_s_to_rpm

UNIT = {'K': 'N/m', 'C': 'N s/m'}


def _runs(mask):
    """Contiguous True runs of a bool array as (start, stop) index pairs."""
    out, start = [], None
    for i, v in enumerate(list(mask) + [False]):
        if v and start is None:
            start = i
        elif not v and start is not None:
            out.append((start, i))
            start = None
    return out


def coefficients_figure(results, *, truth_fn=None, theory_fn=None, title=None):
    """
    Plot identified coefficients vs speed -> Figure (see module docstring).

    results : list of IdentResult, or {label: list of IdentResult} to compare methods.
    truth_fn, theory_fn : speed [rad/s] -> {node: (K, C)} (optional lines); ``truth_fn`` may instead be a dict
    {speed [rad/s]: {node: (K, C)}} (the truth a simulated recording carries at its speeds), drawn as crosses.
    """
    truth_pts = truth_fn if isinstance(truth_fn, dict) else None
    if truth_pts is not None:
        truth_fn = None
    from matplotlib.ticker import EngFormatter
    sets = results if isinstance(results, dict) else {results[0].method if results else '': results}
    first = next(iter(sets.values()))
    if not first:
        raise ValueError('no results to plot')
    nodes, names = first[0].nodes, first[0].bearings
    nb = len(nodes)
    fig, axes = new_figure((14, 2.7 * nb * 2 + 0.9), 2 * nb, 4)
    speeds_all = sorted({r.speed for rs in sets.values() for r in rs})
    wline = np.linspace(min(speeds_all), max(speeds_all), 60) if len(speeds_all) > 1 else np.array(speeds_all)
    lines = {}
    for fn, style, lab in ((truth_fn, TRUTH_STYLE, 'truth (simulated rig)'),
                           (theory_fn, THEORY_STYLE, 'theory (nominal params)')):
        if fn is not None:
            lines[lab] = (style, [fn(w) for w in wline])
    handles = {}
    misfit = any(r.misfit for rs in sets.values() for r in rs)
    for b in range(nb):
        for si, sym in enumerate(('K', 'C')):
            for k, lab in enumerate(COEFF_ORDER):
                ax = axes[2 * b + si, k]
                i, j = divmod(k, 2)
                for n_set, (label, rs) in enumerate(sets.items()):
                    rs = sorted(rs, key=lambda r: r.speed)
                    col = f'C{n_set}' if n_set else 'C0'
                    rpm = np.array([r.speed_rpm for r in rs])
                    val = np.array([getattr(r, sym)[b, i, j] for r in rs], float)
                    std = np.array([getattr(r, sym + '_std')[b, i, j] for r in rs], float)
                    det = np.array([getattr(r, sym + '_determined')[b, i, j] for r in rs], dtype=bool)
                    band = det & np.isfinite(std)
                    for a, z in _runs(band):
                        if z - a >= 2:
                            h = ax.fill_between(rpm[a:z], (val - std)[a:z], (val + std)[a:z], color=col, alpha=0.25,
                                                lw=0, gid=f'band:{label}')
                            handles.setdefault(f'{label} ±1σ band', h)
                    if det.any():
                        h = ax.errorbar(rpm[det], val[det], yerr=np.nan_to_num(std[det]), fmt='o', ms=4, capsize=2,
                                        color=col, gid=f'identified:{label}')
                        handles.setdefault(f'{label} (determined, ±1σ)', h)
                    if (~det).any() and np.isfinite(val[~det]).any():
                        h, = ax.plot(rpm[~det], val[~det], 'o', mfc='none', color='0.55', ms=6,
                                     gid=f'undetermined:{label}')
                        handles.setdefault(f'{label}: NOT determined by the data (prior value)', h)
                if truth_pts:
                    lo_s, hi_s = min(speeds_all), max(speeds_all)
                    ts = [t for t in sorted(truth_pts) if lo_s * 0.995 <= t <= hi_s * 1.005]
                    dense = len(ts) > 3 * len(speeds_all)      # a record's truth at every ramp step: a line
                    h, = ax.plot(rad_s_to_rpm(np.array(ts)), [truth_pts[t][nodes[b]][si][i, j] for t in ts],
                                 **(TRUTH_STYLE if dense else {'ls': '', 'marker': 'x', 'color': TRUTH_STYLE['color'],
                                                               'ms': 7, 'mew': 1.5}), gid='truth')
                    handles.setdefault('truth (simulated rig)', h)
                for lab2, (style, ys) in lines.items():
                    h, = ax.plot(rad_s_to_rpm(wline), [y[nodes[b]][si][i, j] for y in ys], gid=f'line:{lab2}',
                                 **style)
                    handles.setdefault(lab2, h)
                ax.set_title(f'{names[b]} {sym}{lab} [{UNIT[sym]}]', fontsize=9)
                ax.yaxis.set_major_formatter(EngFormatter(sep=''))
                ax.tick_params(labelsize=7)
                ax.grid(alpha=0.25)
                if 2 * b + si == 2 * nb - 1:
                    ax.set_xlabel('speed [rpm]', fontsize=8)
    if handles:
        fig.legend(list(handles.values()), list(handles.keys()), loc='lower center', ncol=min(4, len(handles)),
                   fontsize=8, frameon=False)
    head = title or ''
    if misfit:
        head += ('; ' if head else '') + 'MISFIT: the model does not fit the data within their noise, 1σ is a ' \
                                         'lower bound'
    if head:
        fig.suptitle(head, fontsize=11, color='C3' if misfit else 'k')
    fig.subplots_adjust(left=0.05, right=0.99, top=1 - 0.75 / fig.get_figheight(),
                        bottom=0.75 / fig.get_figheight() + 0.02, hspace=0.45, wspace=0.28)
    return fig


def plot_coefficients(results, path, *, truth_fn=None, theory_fn=None, title=None):
    """Save :func:`coefficients_figure` to ``path`` (PNG, 90 dpi); returns the path."""
    return save_png(coefficients_figure(results, truth_fn=truth_fn, theory_fn=theory_fn, title=title), path)


def theory_coefficients_figure(speeds_rpm, coeffs, names=None, *, title=None):
    """
    Plot theory K and C vs speed -> Figure with 2 x 4 panels (K row, C row; xx xy yx yy).

    ``coeffs`` = {node: (K (ns, 2, 2), C (ns, 2, 2))}; each bearing in its own style; bearings that coincide are said
    to.
    """
    from matplotlib.ticker import EngFormatter
    nodes = list(coeffs)
    names = names or {n: f'node {n}' for n in nodes}
    rpm = np.asarray(speeds_rpm, float)
    fig, axes = new_figure((14, 6.4), 2, 4)
    same_all = True
    for si, sym in enumerate(('K', 'C')):
        for k, lab in enumerate(COEFF_ORDER):
            ax = axes[si, k]
            i, j = divmod(k, 2)
            ref = None
            for b, n in enumerate(nodes):
                y = np.asarray(coeffs[n][si])[:, i, j]
                st = BEARING_STYLES[b % len(BEARING_STYLES)]
                ax.plot(rpm, y, label=f'{names[n]} (node {n})', gid=f'theory:{n}:{sym}{lab}', **st)
                if ref is None:
                    ref = y
                elif not np.allclose(y, ref, rtol=1e-9, atol=0):
                    same_all = False
            lo, hi = ax.get_ylim()
            if lo < 0 < hi:
                ax.axhline(0, color='0.6', lw=0.6)
            ax.set_title(f'{sym}{lab} [{UNIT[sym]}]', fontsize=10)
            ax.yaxis.set_major_formatter(EngFormatter(sep=''))
            ax.tick_params(labelsize=8)
            ax.grid(alpha=0.25)
            if si == 1:
                ax.set_xlabel('rotor speed [rpm]', fontsize=9)
    axes[0, 0].legend(fontsize=8)
    head = title or 'bearing coefficients vs speed (theory, nominal params)'
    if same_all and len(nodes) > 1:
        head += (f'\nall bearings coincide here (same geometry, oil and load): {names[nodes[-1]]} lies on '
                 f'{names[nodes[0]]}')
    fig.suptitle(head, fontsize=11)
    fig.subplots_adjust(left=0.06, right=0.99, top=0.86 if '\n' in head else 0.9, bottom=0.09, hspace=0.38,
                        wspace=0.3)
    return fig


def bearing_vectors_figure(speeds, estimated, *, true=None, nodes=None, labels=('estimated', 'true'),
                           run_labels=None, title=None):
    """
    Plot amplitude [um] and phase [deg] of bearing-node 1X vectors vs speed [rpm] -> Figure (the paper's Figures 5-6).

    speeds (ns,) rad/s; estimated, true complex (ns, nb, 2) or (nr, ns, nb, 2) [m] (x, y per bearing; one line per
    excitation run, labelled by ``run_labels``); nodes (nb,) for titles.  Columns: bearing x direction; rows:
    amplitude, phase.
    """
    est = np.asarray(estimated)
    if est.ndim == 3:
        est = est[None]
        true = None if true is None else np.asarray(true)[None]
    nr, ns, nb, _ = est.shape
    if true is not None and np.asarray(true).shape != est.shape:
        raise ValueError(f'true has shape {np.asarray(true).shape}, estimated {est.shape}')
    run_labels = list(run_labels) if run_labels is not None else ([''] if nr == 1 else [f'run {i}' for i in range(nr)])
    nodes = nodes or tuple(range(1, nb + 1))
    rpm = rad_s_to_rpm(np.asarray(speeds, float))
    fig, axes = new_figure((4 * nb * 2, 6), 2, 2 * nb)
    for b in range(nb):
        for d, dn in enumerate(('x', 'y')):
            c = 2 * b + d
            for r in range(nr):
                col = f'C{r % 10}'
                rl = f' {run_labels[r]}' if run_labels[r] else ''
                for arr, style, lab in ((est, 'o-', labels[0]), (true, '--', labels[1])):
                    if arr is None:
                        continue
                    v = np.asarray(arr)[r, :, b, d]
                    kw = {'color': col} if style == 'o-' else {'color': col, 'lw': 1}
                    axes[0, c].plot(rpm, np.abs(v) * 1e6, style, ms=3, label=f'{lab}{rl}', **kw)
                    axes[1, c].plot(rpm, np.degrees(np.angle(v)), style, ms=3, label=f'{lab}{rl}', **kw)
            axes[0, c].set_title(f'node {nodes[b]} {dn}: amplitude [um]', fontsize=9)
            axes[1, c].set_title(f'node {nodes[b]} {dn}: phase [deg]', fontsize=9)
            axes[1, c].set_xlabel('speed [rpm]')
    axes[0, 0].legend(fontsize=6)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_bearing_vectors(speeds, estimated, path, **kw):
    """Save :func:`bearing_vectors_figure` (same keywords) to ``path`` (PNG, 90 dpi); returns the path."""
    return save_png(bearing_vectors_figure(speeds, estimated, **kw), path)


__all__ = ['coefficients_figure', 'plot_coefficients', 'theory_coefficients_figure', 'bearing_vectors_figure',
           'plot_bearing_vectors']
