"""Shared plotting helpers (matplotlib, Agg backend): coefficients vs speed and bearing-node vectors.

* :func:`plot_coefficients` -- like the paper's Figures 7-8 and 12-15: each of the 8 coefficients of each bearing vs
  speed [rpm], identified values with 1-sigma error bars (filled = determined by the data, hollow grey = prior /
  undetermined), truth and theory as lines when given.  K in N/m, C in N s/m.
* :func:`plot_bearing_vectors` -- like Figures 5-6 / 10-11: amplitude [um] and phase [deg] of the bearing-node
  1X displacement, estimated vs true.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .conventions import COEFF_ORDER, rad_s_to_rpm


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def plot_coefficients(results, path, *, truth_fn=None, theory_fn=None, title=None):
    """Save a 2 nb x 4 grid (rows: K and C of each bearing; cols: xx, xy, yx, yy) to ``path``.

    results : list of IdentResult, or {label: list of IdentResult} to compare methods.
    truth_fn, theory_fn : speed [rad/s] -> {node: (K, C)} (optional lines).
    """
    plt = _plt()
    sets = results if isinstance(results, dict) else {results[0].method if results else "": results}
    first = next(iter(sets.values()))
    if not first:
        raise ValueError("no results to plot")
    nodes, names = first[0].nodes, first[0].bearings
    nb = len(nodes)
    fig, axes = plt.subplots(2 * nb, 4, figsize=(14, 3 * nb * 2), squeeze=False)
    speeds_all = sorted({r.speed for rs in sets.values() for r in rs})
    wline = np.linspace(min(speeds_all), max(speeds_all), 60) if len(speeds_all) > 1 else np.array(speeds_all)
    for b in range(nb):
        for si, sym in enumerate(("K", "C")):
            for k, lab in enumerate(COEFF_ORDER):
                ax = axes[2 * b + si, k]
                i, j = divmod(k, 2)
                for label, rs in sets.items():
                    rpm = np.array([r.speed_rpm for r in rs])
                    val = np.array([getattr(r, sym)[b, i, j] for r in rs])
                    std = np.array([getattr(r, sym + "_std")[b, i, j] for r in rs])
                    det = np.array([getattr(r, sym + "_determined")[b, i, j] for r in rs], dtype=bool)
                    if det.any():
                        ax.errorbar(rpm[det], val[det], yerr=np.nan_to_num(std[det]), fmt="o", ms=4, capsize=2,
                                    label=f"{label}")
                    if (~det).any():
                        ax.plot(rpm[~det], val[~det], "o", mfc="none", color="grey", ms=5,
                                label=f"{label} (prior/undetermined)")
                for fn, style, lab2 in ((truth_fn, "k-", "truth"), (theory_fn, "k--", "theory")):
                    if fn is not None:
                        ys = [fn(w)[nodes[b]][si][i, j] for w in wline]
                        ax.plot(rad_s_to_rpm(wline), ys, style, lw=1, label=lab2)
                ax.set_title(f"{names[b]} {sym}{lab}", fontsize=9)
                ax.set_xlabel("speed [rpm]", fontsize=8)
                ax.set_ylabel("N/m" if sym == "K" else "N s/m", fontsize=8)
                ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7)
    return _finish(plt, fig, path, title)


def plot_bearing_vectors(speeds, estimated, path, *, true=None, nodes=None, labels=("estimated", "true"),
                         run_labels=None, title=None):
    """Amplitude [um] and phase [deg] of bearing-node 1X vectors vs speed [rpm] (the paper's Figures 5-6 style).

    speeds (ns,) rad/s; estimated, true complex (ns, nb, 2) or (nr, ns, nb, 2) [m] (x, y per bearing; one line per
    excitation run, labelled by ``run_labels``); nodes (nb,) for titles.  Columns: bearing x direction; rows:
    amplitude, phase.
    """
    plt = _plt()
    est = np.asarray(estimated)
    if est.ndim == 3:
        est = est[None]
        true = None if true is None else np.asarray(true)[None]
    nr, ns, nb, _ = est.shape
    if true is not None and np.asarray(true).shape != est.shape:
        raise ValueError(f"true has shape {np.asarray(true).shape}, estimated {est.shape}")
    run_labels = list(run_labels) if run_labels is not None else ([""] if nr == 1 else [f"run {i}" for i in range(nr)])
    nodes = nodes or tuple(range(1, nb + 1))
    rpm = rad_s_to_rpm(np.asarray(speeds, float))
    fig, axes = plt.subplots(2, 2 * nb, figsize=(4 * nb * 2, 6), squeeze=False)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for b in range(nb):
        for d, dn in enumerate(("x", "y")):
            c = 2 * b + d
            for r in range(nr):
                col = colors[r % len(colors)]
                rl = f" {run_labels[r]}" if run_labels[r] else ""
                for arr, style, lab in ((est, "o-", labels[0]), (true, "--", labels[1])):
                    if arr is None:
                        continue
                    v = np.asarray(arr)[r, :, b, d]
                    kw = {"color": col} if style == "o-" else {"color": col, "lw": 1}
                    axes[0, c].plot(rpm, np.abs(v) * 1e6, style, ms=3, label=f"{lab}{rl}", **kw)
                    axes[1, c].plot(rpm, np.degrees(np.angle(v)), style, ms=3, label=f"{lab}{rl}", **kw)
            axes[0, c].set_title(f"node {nodes[b]} {dn}: amplitude [um]", fontsize=9)
            axes[1, c].set_title(f"node {nodes[b]} {dn}: phase [deg]", fontsize=9)
            axes[1, c].set_xlabel("speed [rpm]")
    axes[0, 0].legend(fontsize=6)
    return _finish(plt, fig, path, title)


def _finish(plt, fig, path, title=None) -> Path:
    """Title, layout, save as PNG (90 dpi) and close ``fig``; returns the path."""
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


__all__ = ["plot_coefficients", "plot_bearing_vectors"]
