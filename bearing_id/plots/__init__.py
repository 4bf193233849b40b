"""
Figures (matplotlib) for people: one module per figure family, all taking the result objects the CLI prints.

* :mod:`.data` -- the numbers behind every figure (no matplotlib; tested against the model on their own).
* :mod:`.campbell` -- Campbell diagram (0.5X / 1X / 2X, log-decrement colour, critical speeds, stability threshold)
  and mode shapes at the critical speeds.
* :mod:`.response` -- 1X Bode (amplitude, phase) and polar plots per probe: measured +- 1 sigma, the model as a
  continuous curve (identified and theory), rpm labels.
* :mod:`.orbits` -- unfiltered and 1X-filtered orbits with keyphasor marks, equal axes.
* :mod:`.centreline` -- journal centre in the clearance circle vs speed.
* :mod:`.spectrum` -- spectrum cascade (waterfall) per probe with 0.5X / 1X / 2X marks.
* :mod:`.coefficients` -- identified K and C vs speed with 1-sigma bands, theory and truth, determined vs
  undetermined; theory coefficients of ``bearing-id model``; the paper's bearing-node vector plot.
* :mod:`.diagnosis` -- a diagnosis before / after (1X Bode per probe, residual by order).
* :mod:`.html` -- the self-contained HTML report page (images as base64, no network).

Figure functions return :class:`matplotlib.figure.Figure` objects made without pyplot; :func:`save_png` /
:func:`png_bytes` render them; :func:`plot_coefficients` and :func:`plot_bearing_vectors` save one to a path.
"""
from __future__ import annotations

from .coefficients import (bearing_vectors_figure, coefficients_figure, plot_bearing_vectors, plot_coefficients,
                           theory_coefficients_figure)
from .common import DPI, new_figure, png_bytes, save_png

__all__ = ['DPI', 'new_figure', 'png_bytes', 'save_png', 'plot_coefficients', 'plot_bearing_vectors',
           'coefficients_figure', 'theory_coefficients_figure', 'bearing_vectors_figure']
