"""
Campbell diagram and mode shapes.

* :func:`campbell_figure` -- damped natural frequencies vs speed, coloured by logarithmic decrement (red < 0 =
  unstable), forward / backward whirl as up / down triangles, the 0.5X (oil whirl / whip), 1X and 2X lines, each
  synchronous critical speed marked and labelled (speed, frequency, damping ratio, amplification factor), the
  stability threshold with the whirl frequency of the mode that goes unstable, and the measured speeds as ticks.
* :func:`mode_shapes_figure` -- the lowest modes at each critical speed: x- and y-plane shapes along the shaft, the
  orbit envelope, bearings and discs, forward / backward (per mode and, when mixed, per node).

Artists carry ``gid`` strings (``'campbell:forward'``, ``'critical:0'``, ``'order:1X'`` ...) so tests can read the
drawn data back.
"""
from __future__ import annotations

import numpy as np

from .common import new_figure, order_label, ORDER_STYLES
from .data import CampbellData, ORDERS, TWO_PI

LOGDEC_BOUNDS = (-1.0, 0.0, 0.1, 0.3, 1.0, 3.0)
LOGDEC_COLORS = ('#d7191c', '#fdae61', '#e6d800', '#74add1', '#313695')
LOGDEC_LABELS = ('< 0 unstable', "0-0.1 (below API 684's 0.1)", '0.1-0.3', '0.3-1', '> 1')


def _logdec_cmap():
    """Discrete colours for the logarithmic decrement bins: red unstable ... dark blue well damped."""
    from matplotlib.colors import BoundaryNorm, ListedColormap
    cmap = ListedColormap(LOGDEC_COLORS).with_extremes(under=LOGDEC_COLORS[0], over=LOGDEC_COLORS[-1])
    return cmap, BoundaryNorm(LOGDEC_BOUNDS, cmap.N)


def campbell_figure(cd: CampbellData, *, measured_rpm=None, title: str | None = None, fmax_hz: float | None = None,
                    speeds_label: str = 'measured speeds'):
    """
    Plot the Campbell diagram of ``cd`` (see module docstring) -> Figure.

    ``measured_rpm`` are drawn as ticks labelled ``speeds_label``.
    """
    fig, axs = new_figure((9.0, 6.0))
    ax = axs[0, 0]
    rpm = cd.speeds_rpm
    F = cd.frequency_hz
    top = fmax_hz or 1.25 * rpm[-1] / 60.0
    cmap, norm = _logdec_cmap()
    sc = None
    for whirl, marker, gid in (('forward', '^', 'campbell:forward'), ('backward', 'v', 'campbell:backward')):
        m = (cd.whirl == whirl) & np.isfinite(F) & (F <= top * 1.02)
        S = np.broadcast_to(rpm[:, None], F.shape)
        sc = ax.scatter(S[m], F[m], c=cd.log_dec[m], cmap=cmap, norm=norm, marker=marker, s=22,
                        edgecolors='0.3', linewidths=0.3, zorder=3, gid=gid)
    cbar = fig.colorbar(sc, ax=ax, pad=0.02, extend='both', spacing='uniform')
    cbar.set_ticks([(a + b) / 2 for a, b in zip(LOGDEC_BOUNDS[:-1], LOGDEC_BOUNDS[1:])])
    cbar.set_ticklabels(LOGDEC_LABELS, fontsize=8)
    cbar.set_label('logarithmic decrement δ of each mode')
    x = np.array([0.0, rpm[-1]])
    for k in ORDERS:
        st = ORDER_STYLES[k]
        ax.plot(x, k * x / 60.0, zorder=2, gid=f'order:{order_label(k)}', **st)
        xe = min(rpm[-1], 0.93 * top / k * 60.0) * 0.985
        ax.text(xe, k * xe / 60.0, f' {order_label(k)}', ha='right', va='bottom', fontsize=10, color=st['color'],
                fontweight='bold')
    for i, (c, z) in enumerate(zip(cd.critical_rpm, cd.critical_zeta)):
        f = c / 60.0
        ax.plot([c], [f], 'o', ms=13, mfc='none', mec='k', mew=1.8, zorder=4, gid=f'critical:{i}')
        af = 1.0 / (2.0 * z) if z > 0 else np.inf
        ax.annotate(f'critical speed {i + 1}: {c:.0f} rpm\n{f:.1f} Hz, ζ = {z:.3f}'
                    + (f', AF ≈ {af:.0f}' if np.isfinite(af) else ''),
                    xy=(c, f), xytext=(-15, 28), textcoords='offset points', ha='right', fontsize=9,
                    bbox={'boxstyle': 'round', 'fc': 'white', 'ec': '0.5', 'alpha': 0.9},
                    arrowprops={'arrowstyle': '->', 'color': 'k'})
    thr = cd.threshold_rpm
    if thr is not None:
        ax.axvline(thr, color='C3', lw=1.8, zorder=2, gid='threshold')
        txt = f'stability threshold\n{thr:.0f} rpm'
        if cd.threshold_ratio is not None:
            fw = cd.threshold_ratio * thr / 60.0
            txt += f'\nunstable mode whirls\nat {fw:.1f} Hz = {cd.threshold_ratio:.2f}X'
            ax.plot([thr], [fw], '*', ms=15, color='C3', mec='k', zorder=5, gid='threshold:mode')
        right = (rpm[-1] - thr) > 0.3 * rpm[-1]
        ax.text(thr + (0.01 if right else -0.01) * rpm[-1], top * 0.97, txt, ha='left' if right else 'right',
                va='top', fontsize=9, color='C3', bbox={'fc': 'white', 'ec': 'C3', 'alpha': 0.9}, zorder=6)
    elif cd.threshold is not None and not np.isfinite(cd.threshold):
        ax.text(0.02, 0.97, f'stable up to {rpm[-1]:.0f} rpm (no threshold in range)', transform=ax.transAxes,
                va='top', fontsize=9, color='C2')
    if measured_rpm is not None and len(measured_rpm):
        m = np.asarray(measured_rpm, float)
        ax.plot(m, np.zeros_like(m), '|', ms=14, mew=2, color='C2', clip_on=False, zorder=5, gid='measured')
        ax.axvspan(m.min(), m.max(), color='C2', alpha=0.07, zorder=0)
        ax.text(m.mean(), top * 0.015, speeds_label, ha='center', va='bottom', fontsize=8, color='C2')
    from matplotlib.lines import Line2D
    handles = [Line2D([], [], ls='', marker='^', color='0.5', mec='0.3', label='forward whirl'),
               Line2D([], [], ls='', marker='v', color='0.5', mec='0.3', label='backward whirl'),
               Line2D([], [], ls='', marker='o', ms=10, mfc='none', mec='k', mew=1.8, label='critical speed (1X)')]
    ax.legend(handles=handles, loc='upper right', bbox_to_anchor=(0.995, 0.62), fontsize=8, framealpha=0.95)
    ax.set_xlim(0, rpm[-1])
    ax.set_ylim(0, top)
    ax.set_xlabel('rotor speed [rpm]')
    ax.set_ylabel('damped natural frequency [Hz]')
    ax.grid(alpha=0.25)
    ax.set_title(title or f"Campbell diagram{(' - ' + cd.label) if cd.label else ''}", fontsize=11)
    fig.subplots_adjust(left=0.08, right=0.86, bottom=0.09, top=0.93)
    return fig


def mode_shapes_figure(shapes_by_speed, *, bearing_nodes=(), disc_nodes=(), title: str | None = None):
    """
    Plot mode shapes -> Figure with one row per entry and one panel per mode.

    ``shapes_by_speed`` = [(label, [ModeShape, ...], index of the critical mode or None)].
    """
    from matplotlib.patches import Rectangle
    rows = [r for r in shapes_by_speed if r[1]]
    if not rows:
        raise ValueError('no mode shapes to draw')
    ncol = max(len(r[1]) for r in rows)
    fig, axs = new_figure((3.3 * ncol, 2.9 * len(rows) + 1.1), len(rows), ncol)
    for r, (label, shapes, crit) in enumerate(rows):
        for k in range(ncol):
            ax = axs[r, k]
            if k >= len(shapes):
                ax.set_visible(False)
                continue
            m = shapes[k]
            z = m.z * 1e3
            env = m.envelope
            ax.fill_between(z, -env, env, color='0.85', lw=0, label='orbit envelope')
            ax.plot(z, m.x_plane, '-o', ms=3, color='C0', lw=1.5, label='x plane', gid=f'mode:{r}:{k}:x')
            ax.plot(z, m.y_plane, '--s', ms=3, color='C1', lw=1.5, label='y plane', gid=f'mode:{r}:{k}:y')
            ax.axhline(0, color='0.5', lw=0.6)
            idx = {n: i for i, n in enumerate(range(1, z.size + 1))}
            for n in bearing_nodes:
                if n in idx:
                    ax.plot([z[idx[n]]], [-1.18], '^', ms=9, color='k', clip_on=False)
            for n in disc_nodes:
                if n in idx:
                    ax.add_patch(Rectangle((z[idx[n]] - 8, -1.05), 16, 2.1, color='C7', alpha=0.25, lw=0))
            mixed = [i + 1 for i, w in enumerate(m.node_whirl) if w != m.whirl and env[i] > 0.05]
            fb = 'F' if m.whirl == 'forward' else 'B'
            head = f'{m.frequency / TWO_PI:.1f} Hz  {m.whirl} ({fb})  δ {m.log_dec:.2f}'
            if crit is not None and k == crit:
                head = 'critical mode: ' + head
                for s in ax.spines.values():
                    s.set_edgecolor('C3')
                    s.set_linewidth(2)
            ax.set_title(head, fontsize=9)
            if mixed:
                ax.text(0.02, 0.03, 'mixed whirl: node(s) ' + ', '.join(map(str, mixed)) + ' '
                        + ('backward' if m.whirl == 'forward' else 'forward'), transform=ax.transAxes, fontsize=7,
                        color='C3')
            ax.set_ylim(-1.25, 1.25)
            ax.set_xlim(z[0] - 10, z[-1] + 10)
            ax.tick_params(labelsize=7)
            if r == len(rows) - 1:
                ax.set_xlabel('axial position z [mm]', fontsize=8)
            if k == 0:
                ax.set_ylabel(f'{label}\nnormalised shape', fontsize=8)
    h, lab = axs[0, 0].get_legend_handles_labels()
    fig.legend(h, lab, loc='lower center', ncol=3, fontsize=8, frameon=False)
    fig.suptitle(title or 'mode shapes (▲ bearings, grey bands discs; x and y planes, each against its largest '
                          'node; envelope = orbit semi-major axis)', fontsize=9)
    H = fig.get_figheight()
    fig.subplots_adjust(left=0.07, right=0.99, bottom=0.95 / H, top=1 - 0.55 / H, hspace=0.45, wspace=0.25)
    return fig


__all__ = ['campbell_figure', 'mode_shapes_figure']
