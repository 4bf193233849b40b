"""
Shaft centreline: the journal centre inside the bearing clearance circle vs speed.

From a bearing model (static equilibrium under the static load: eccentricity and attitude angle), drawn per bearing
with x right, y up (load along -y, so the journal sits below the bearing centre and rises towards it as speed
increases; the attitude angle turns it in the spin direction).  Curves from the theory (nominal clearance) and from
the identified bearing model (its own, fitted, clearance) when there is one, with rpm labels at the test speeds.
A third panel gives the eccentricity ratio vs speed.  These positions are computed, not measured: a measured
centreline needs DC-coupled probes at the bearings.
"""
from __future__ import annotations

import numpy as np

from .common import MODEL_STYLE, new_figure, THEORY_STYLE


def centreline_figure(curves, *, label_rpm=(), title=None):
    """
    Plot the shaft centreline of ``curves`` -> Figure (one panel per bearing + eccentricity vs speed).

    ``curves`` = [(label, kind 'identified'|'theory', rpm (ns,), positions {node: journal_positions() entry})],
    ``label_rpm``: speeds to label on the curves.
    """
    from matplotlib.patches import Circle
    nodes = sorted({n for *_, pos in curves for n in pos})
    fig, axs = new_figure((4.9 * (len(nodes) + 1), 5.4), 1, len(nodes) + 1)
    style = {'identified': MODEL_STYLE, 'theory': THEORY_STYLE}
    for b, node in enumerate(nodes):
        ax = axs[0, b]
        R = 0.0
        for label, kind, rpm, pos in curves:
            if node not in pos:
                continue
            d = pos[node]
            c = d['clearance'] * 1e6
            R = max(R, c)
            st = dict(style[kind])
            ax.add_patch(Circle((0, 0), c, fill=False, ec=st['color'], ls=st['ls'], lw=1.2))
            xy = d['xy'] * 1e6
            ax.plot(xy[:, 0], xy[:, 1], marker='.', ms=4, label=f'{label} (clearance {c:.1f} µm)',
                    gid=f'centreline:{kind}:{node}', **st)
            placed = []
            for r0 in label_rpm:
                k = int(np.argmin(np.abs(np.asarray(rpm) - r0)))
                if abs(rpm[k] - r0) < 1e-6 * max(r0, 1):
                    ax.plot([xy[k, 0]], [xy[k, 1]], 'o', ms=4, color=st['color'])
                    far = all(np.hypot(xy[k, 0] - a, xy[k, 1] - b) > 0.07 * c for a, b in placed)
                    if kind == curves[-1][1] and far:
                        placed.append((xy[k, 0], xy[k, 1]))
                        ax.annotate(f'{r0:.0f}', (xy[k, 0], xy[k, 1]), xytext=(6, 0), textcoords='offset points',
                                    fontsize=7, color='0.2', ha='left', va='center')
        ax.plot([0], [0], '+', ms=12, color='k')
        ax.set_xlim(-1.1 * R, 1.1 * R)
        ax.set_ylim(-1.1 * R, 1.1 * R)
        ax.set_aspect('equal')
        ax.set_xlabel('x [µm]')
        ax.set_ylabel('y [µm] (load along -y)')
        ax.grid(alpha=0.25)
        ax.set_title(f'bearing at node {node}: journal centre (labels: rpm)', fontsize=10)
        ax.legend(fontsize=7, loc='upper center')
    ax = axs[0, -1]
    for label, kind, rpm, pos in curves:
        for b, node in enumerate(nodes):
            if node in pos:
                st = dict(style[kind])
                ax.plot(rpm, pos[node]['eps'], label=f'{label}, node {node}',
                        marker='os'[b % 2], ms=3, mfc='none' if b else st['color'], **st)
    ax.set_xlabel('rotor speed [rpm]')
    ax.set_ylabel('eccentricity ratio e/c')
    ax.set_ylim(0, 1)
    ax.grid(alpha=0.25)
    ax.legend(fontsize=7)
    ax.set_title('eccentricity vs speed', fontsize=10)
    fig.suptitle(title or 'shaft centreline in the bearing clearance (computed from the bearing model at the static '
                          'load; not measured)', fontsize=10)
    fig.subplots_adjust(left=0.06, right=0.98, top=0.86, bottom=0.12, wspace=0.35)
    return fig


__all__ = ['centreline_figure']
