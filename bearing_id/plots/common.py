"""
Shared figure plumbing: figures without pyplot state, PNG bytes, the styles every figure family uses.

Figures are :class:`matplotlib.figure.Figure` objects made without ``pyplot`` (no global state, nothing to close,
Agg rendering on save).
"""
from __future__ import annotations

import io
from pathlib import Path

from ..conventions import direction_words

DPI = 90                       # report figures: readable at 100 % zoom, small enough to embed
PNG_COMPRESS_LEVEL = 3         # zlib level: a little larger than the default 6, cheaper to encode
RUN_COLORS = ('C0', 'C1', 'C2', 'C4', 'C5', 'C6', 'C8', 'C9')
BEARING_STYLES = ({'color': 'C0', 'ls': '-', 'marker': 'o', 'mfc': 'C0', 'ms': 4},
                  {'color': 'C3', 'ls': '--', 'marker': 's', 'mfc': 'none', 'ms': 7},
                  {'color': 'C2', 'ls': ':', 'marker': '^', 'mfc': 'none', 'ms': 7},
                  {'color': 'C4', 'ls': '-.', 'marker': 'D', 'mfc': 'none', 'ms': 6})
ORDER_STYLES = {0.5: {'color': '0.25', 'ls': '--', 'lw': 1.0}, 1.0: {'color': 'k', 'ls': '-', 'lw': 1.2},
                2.0: {'color': '0.25', 'ls': ':', 'lw': 1.2}}
MODEL_STYLE = {'color': 'C3', 'ls': '-', 'lw': 1.6}        # identified model
THEORY_STYLE = {'color': '0.35', 'ls': '--', 'lw': 1.2}    # nominal theory
TRUTH_STYLE = {'color': 'C2', 'ls': '-.', 'lw': 1.2}       # truth of a simulated recording


def order_label(k: float) -> str:
    return f'{k:g}X'


def run_color(i: int) -> str:
    return RUN_COLORS[i % len(RUN_COLORS)]


def probe_text(p) -> str:
    return f'{p.name} (node {p.node}, {direction_words(p.direction)})'


def new_figure(figsize, nrows: int = 1, ncols: int = 1, **kw):
    """(Figure, axes) without pyplot; ``axes`` as from ``Figure.subplots`` (squeeze=False unless given)."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=figsize)
    kw.setdefault('squeeze', False)
    axes = fig.subplots(nrows, ncols, **kw)
    return fig, axes


MAX_TICKS = 5                  # major ticks per linear axis (matplotlib's automatic choice draws up to ~10)


def fewer_ticks(fig):
    """
    Give every axis that still has matplotlib's automatic linear locator at most ``MAX_TICKS`` nice major ticks.

    Each tick is four artists laid out and drawn one by one.  Axes whose locator a figure function chose (log axes,
    fixed ticks) are left alone.
    """
    from matplotlib.ticker import AutoLocator, MaxNLocator
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if type(axis.get_major_locator()) is AutoLocator:
                axis.set_major_locator(MaxNLocator(nbins=MAX_TICKS, steps=[1, 2, 2.5, 5, 10]))
    return fig


def png_bytes(fig, dpi: int = DPI) -> bytes:
    """Return the figure as PNG bytes (Agg), with :func:`fewer_ticks`."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    FigureCanvasAgg(fewer_ticks(fig))
    buf = io.BytesIO()
    fig.savefig(buf, format='png', dpi=dpi, pil_kwargs={'compress_level': PNG_COMPRESS_LEVEL})
    return buf.getvalue()


def save_png(fig, path, dpi: int = DPI) -> Path:
    """Write the figure as PNG to ``path``; returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(png_bytes(fig, dpi))
    return path
