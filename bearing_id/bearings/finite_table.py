"""
Finite-length plain journal bearing from a precomputed dimensionless table (what bearing codes do).

Why a table.  The direct finite-volume solution (:func:`bearing_id.bearings.finite.reynolds`) costs 0.1-0.4 s per
bearing and speed, so a physical fit over 6 speeds with finite-difference Jacobians took 5-10 minutes.  And its
perturbation coefficients are only piecewise smooth: every time the discrete cavitation boundary moves by one cell
the free (full-film) set changes and K, C jump (by up to 1.5 % of the largest entry on the default 96 x 12 grid,
0.6 % on 192 x 24, halving with the cell size) -- a model that jumps is poison for a gradient fit at a noise level of
1e-4.

Similarity.  For an aligned, isoviscous plain bearing of given L/D, the equilibrium eccentricity eps, the attitude
angle phi and the dimensionless coefficients

    k = K c / W,     b = C c speed / W        (2x2, our (x, y) frame, load along -y)

depend on the Sommerfeld number S = mu N L D / W (R/c)^2 alone (N = speed / 2 pi).  The table stores them as cubic
least-squares B-splines in ln S, fitted to ``n_samples`` direct solutions (continuation in S, equilibrium to
relative force error 1e-12) on a finer grid than the default (``TABLE_GRID``); the least-squares fit (knots ~3x
wider than the jump spacing) averages the cell-by-cell jumps, so the table is the smooth grid-converging solution,
not the jumps.  The spline stores k, b divided by sqrt(1 + S) (k, b grow like S for a lightly loaded bearing).

Accuracy (stated, checked in test/test_finite_table.py against the direct solver):
* representation error of the spline (knot spacing, checked on the closed-form short bearing): < 2e-5 of the
  largest entry;
* table vs the direct solution, max |difference| over the largest |entry| of K and of C (measured here at 29
  Sommerfeld numbers between the table's samples; :func:`stated_tolerance` returns the bound a test may use):

      S             eps          table grid 192 x 24: K / C     default grid 96 x 12: K / C
      0.004-0.02    0.97-0.90    1.1 % / 3.0 %                  4 % / 10 %
      0.02-0.05     0.89-0.78    0.7 % / 1.4 %                  1.5 % / 3.6 %
      0.05-0.5      0.76-0.27    0.3 % / 0.4 %                  0.9 % / 0.8 %   (the rig: eps 0.26-0.70)
      0.5-20        0.23-0.01    0.2 % / 0.2 %                  1.3 % / 1.4 %

  What is left on the table's own grid is the jumps the table averages (largest where the film is thinnest); the
  default grid adds its discretisation error.  Eccentricity within 3e-5 on the table's grid, 2e-3 on the default.

Range: S in [``S_MIN``, ``S_MAX``] (eps about 0.97 ... 0.005); outside it :func:`solution` falls back to the direct
solver on the default grid (slow, and says so in ``BearingSolution.force_error``: the direct solver's value).

Shipped tables: L/D = 1 and 0.5, 321 direct solutions each on 192 x 24, for Reynolds (Swift-Stieber) cavitation in
``finite_tables_swift_stieber.json`` and Gumbel (half-Sommerfeld, :func:`bearing_id.bearings.finite.reynolds` with
``cavitation='gumbel'``) in ``finite_tables_gumbel.json`` beside this module (package data, read on first use; written
by ``python -m bearing_id.bearings.finite_table --write [--cavitation gumbel]``, several minutes per table).  Any
other L/D is built on first use (161 solutions on the default grid, about 30-60 s, cached per (L/D, cavitation) for
the process).  The Gumbel direct solution is smooth in S (its positive part is C1, no jumps), so a Gumbel table
agrees with the direct solver on its own grid to 4e-4 of the largest entry (shipped tables, 4 S between samples) and
1.3e-3 (on-demand table, default grid, 15 S from 0.006 to 20).
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass
from importlib.resources import files
import json
import math
from pathlib import Path
import threading
import time

import numpy as np
from scipy.interpolate import BSpline, make_lsq_spline

from .finite import check_cavitation, reynolds
from .short import BearingSolution, check_inputs, journal_position, sommerfeld_number

TABLE_GRID = (192, 24)          # n_theta, n_z of the shipped tables
ONDEMAND_GRID = (96, 12)        # grid of a table built at run time for an L/D not shipped
S_MIN, S_MAX = 4e-3, 25.0
N_SAMPLES = 321                 # direct solutions per table (ln S spacing 0.027)
KNOT_EVERY = 12                 # interior knot every this many samples (ln S spacing 0.33)
TOL_ECC = 0.002                 # eccentricity, table vs direct solver (either grid)


def stated_tolerance(S: float, table_grid: bool = True) -> float:
    """
    Return the stated bound on max |K or C difference| / largest |entry| between the table and the direct solver.

    At Sommerfeld number ``S``, on the table's grid or (``table_grid`` False) the default grid; the bound is the module
    docstring's table, rounded up.
    """
    if S < 0.02:
        return 0.035 if table_grid else 0.10
    if S < 0.05:
        return 0.015 if table_grid else 0.04
    return 0.005 if table_grid else 0.015


LD_MATCH = 1e-9                 # relative L/D agreement to use a shipped table

_COLS = ('eps', 'phi', 'kxx', 'kxy', 'kyx', 'kyy', 'bxx', 'bxy', 'byx', 'byy')


def _norm(S):
    return np.sqrt(1.0 + np.asarray(S, dtype=float))


@dataclass(frozen=True)
class FiniteTable:
    """
    Dimensionless finite-bearing solution vs Sommerfeld number for one L/D (plain 360-degree bearing).

    knots (n + 4,), coef (n, 10): cubic B-spline in ln S of (eps, phi, k (4), b (4)) with k, b divided by
    sqrt(1 + S); columns ``_COLS``; grid = (n_theta, n_z) of the direct solutions it was fitted to;
    fit_rms (10,): RMS of the least-squares residual (the averaged jumps) per column, k, b relative to the
    largest entry.  cavitation: 'swift_stieber' or 'gumbel' (:func:`bearing_id.bearings.finite.reynolds`).
    """

    L_over_D: float
    knots: np.ndarray
    coef: np.ndarray
    s_min: float
    s_max: float
    grid: tuple
    fit_rms: np.ndarray
    cavitation: str = 'swift_stieber'

    def _splines(self):
        sp = getattr(self, '_sp', None)
        if sp is None:
            b = BSpline(np.asarray(self.knots, float), np.asarray(self.coef, float), 3, extrapolate=False)
            sp = (b, b.derivative())
            object.__setattr__(self, '_sp', sp)
        return sp

    def in_range(self, S: float) -> bool:
        return self.s_min <= S <= self.s_max

    def evaluate(self, S: float, derivative: bool = False):
        """(eps, phi, k (2,2), b (2,2)) at Sommerfeld number ``S``; with ``derivative`` also their d / d ln S."""
        if not self.in_range(S):
            raise ValueError(f'Sommerfeld number {S:.4g} outside the table [{self.s_min:g}, {self.s_max:g}]')
        b, db = self._splines()
        x = math.log(S)
        v = b(x)
        n = float(_norm(S))
        out = (float(v[0]), float(v[1]), v[2:6].reshape(2, 2) * n, v[6:10].reshape(2, 2) * n)
        if not derivative:
            return out
        d = db(x)
        dn = 0.5 * S / (1.0 + S) * n        # d sqrt(1 + S) / d ln S
        return out, (float(d[0]), float(d[1]), (d[2:6] * n + v[2:6] * dn).reshape(2, 2),
                     (d[6:10] * n + v[6:10] * dn).reshape(2, 2))


def sample(L_over_D: float, n_theta: int, n_z: int, s_values, cavitation: str = 'swift_stieber') -> np.ndarray:
    """
    Direct solutions (len(s_values), 10) = (eps, phi, k (4), b (4)) at Sommerfeld numbers ``s_values``.

    Dimensionless set-up D = c = mu = speed = 1 (so k = K / W, b = C / W), continuation from the largest S down
    (each start = the previous equilibrium), equilibrium to |F - W| / W <= 1e-12, with ``cavitation``.
    """
    D, L, c, mu, w = 1.0, float(L_over_D), 1.0, 1.0, 1.0
    order = np.argsort(-np.asarray(s_values, float))
    out = np.zeros((len(s_values), 10))
    start = None
    for i in order:
        S = float(s_values[i])
        W = mu * w / (2 * math.pi) * L * D * 0.25 / (c * c * S)
        s = reynolds(D, L, c, mu, W, w, n_theta, n_z, start=start, tol=1e-12, cavitation=cavitation)
        start = s.journal_position
        out[i] = np.r_[s.eccentricity, s.attitude_angle, (s.K * c / W).ravel(), (s.C * c * w / W).ravel()]
    return out


def fit_table(L_over_D: float, s_values, rows, grid, knot_every: int = KNOT_EVERY,
              cavitation: str = 'swift_stieber') -> FiniteTable:
    """Least-squares cubic spline in ln S through sampled rows (see :func:`sample`)."""
    s_values = np.asarray(s_values, float)
    o = np.argsort(s_values)
    x = np.log(s_values[o])
    V = np.asarray(rows, float)[o].copy()
    V[:, 2:] /= _norm(s_values[o])[:, None]
    kn = x[::knot_every][1:-1]
    t = np.r_[[x[0]] * 4, kn, [x[-1]] * 4]
    sp = make_lsq_spline(x, V, t, k=3)
    res = (sp(x) - V) * np.r_[1.0, 1.0, np.ones(8)][None, :]
    scale = np.c_[np.ones((len(x), 2)), np.repeat(np.abs(V[:, 2:6]).max(1, keepdims=True), 4, 1),
                  np.repeat(np.abs(V[:, 6:]).max(1, keepdims=True), 4, 1)]
    fit_rms = np.sqrt(np.mean((res / scale) ** 2, axis=0))
    return FiniteTable(float(L_over_D), np.asarray(sp.t), np.asarray(sp.c), float(s_values.min()),
                       float(s_values.max()), tuple(int(g) for g in grid), fit_rms, cavitation)


def build_table(L_over_D: float, grid=TABLE_GRID, n_samples: int = N_SAMPLES, s_range=(S_MIN, S_MAX),
                knot_every: int = KNOT_EVERY, cavitation: str = 'swift_stieber') -> FiniteTable:
    """Sample the direct solver on a log-spaced S grid and fit the table (minutes on the fine grid)."""
    s = np.geomspace(s_range[0], s_range[1], int(n_samples))
    return fit_table(L_over_D, s, sample(L_over_D, grid[0], grid[1], s, cavitation), grid, knot_every, cavitation)


_TABLES: dict = {}
_SHIPPED: dict = {}             # cavitation -> list of the shipped FiniteTables
_LOCK = threading.Lock()


def _data_file(cavitation: str) -> str:
    """Return the file name of the shipped tables for ``cavitation`` (beside this module)."""
    return f'finite_tables_{cavitation}.json'


def read_tables(text: str) -> list[FiniteTable]:
    """Parse the JSON ``text`` written by :func:`write_tables` into FiniteTables."""
    d = json.loads(text)
    return [FiniteTable(float(t['L_over_D']), np.asarray(t['knots'], dtype=float), np.asarray(t['coef'], dtype=float),
                        float(t['s_min']), float(t['s_max']), tuple(int(g) for g in t['grid']),
                        np.asarray(t['fit_rms'], dtype=float), d['cavitation']) for t in d['tables']]


def _shipped(cavitation: str) -> list[FiniteTable]:
    """Return the shipped tables for ``cavitation`` (read from the package data on first use; called under _LOCK)."""
    tabs = _SHIPPED.get(cavitation)
    if tabs is None:
        tabs = _SHIPPED[cavitation] = read_tables(files(__package__).joinpath(_data_file(cavitation)).read_text())
    return tabs


def table_for(L_over_D: float, *, build: bool = True, cavitation: str = 'swift_stieber') -> FiniteTable | None:
    """
    Return the table for ``L_over_D`` (and ``cavitation``).

    A shipped one when L/D matches (relative 1e-9), else built on first use with the default grid (cached for the
    process), or None when ``build`` is False.
    """
    LD = float(L_over_D)
    check_cavitation(cavitation)
    with _LOCK:
        for (key, cav), tab in _TABLES.items():
            if cav == cavitation and abs(key - LD) <= LD_MATCH * LD:
                return tab
        for tab in _shipped(cavitation):
            if abs(tab.L_over_D - LD) <= LD_MATCH * LD:
                _TABLES[(tab.L_over_D, cavitation)] = tab
                return tab
        if not build:
            return None
        n = max(81, (N_SAMPLES + 1) // 2)
        tab = build_table(LD, grid=ONDEMAND_GRID, n_samples=n, knot_every=max(4, KNOT_EVERY // 2),
                          cavitation=cavitation)
        _TABLES[(LD, cavitation)] = tab
        return tab


def solution(D: float, L: float, c: float, mu: float, W: float, speed: float, *,
             cavitation: str = 'swift_stieber') -> BearingSolution:
    """
    Finite-length bearing equilibrium and K [N/m], C [N s/m] in our (x, y) frame from the table.

    Same arguments and result as :func:`bearing_id.bearings.finite.reynolds` (plain 360-degree bearing, default
    grid otherwise, ``cavitation`` 'swift_stieber' or 'gumbel').  ``force_error`` is NaN for a table value (no
    equilibrium was solved here); outside the table's Sommerfeld range the direct solver's result is returned
    instead.
    """
    check_inputs(D, L, c, mu, W, speed)
    S = sommerfeld_number(D, L, c, mu, W, speed)
    tab = table_for(L / D, cavitation=cavitation)
    if not tab.in_range(S):
        return reynolds(D, L, c, mu, W, speed, cavitation=cavitation)
    eps, phi, k, b = tab.evaluate(S)
    return BearingSolution(eccentricity=eps, attitude_angle=phi, sommerfeld=S, K=k * (W / c),
                           C=b * (W / (c * speed)), journal_position=journal_position(eps, phi, c), model='finite',
                           force_error=math.nan)


def write_tables(tables, path=None, cavitation: str = 'swift_stieber') -> str:
    """
    Write ``tables`` (list of FiniteTable) as JSON; returns the path.

    Default path: the shipped data file for ``cavitation`` beside this module.  Floats are written by Python's
    ``repr`` (shortest string that reads back to the same double), one coefficient row per line.
    """
    path = Path(path) if path is not None else Path(__file__).with_name(_data_file(cavitation))
    cmd = f'python -m bearing_id.bearings.finite_table --write --cavitation {cavitation}'
    parts = []
    for t in tables:
        head = {'L_over_D': float(t.L_over_D), 'grid': [int(g) for g in t.grid], 's_min': float(t.s_min),
                's_max': float(t.s_max)}
        rows = ',\n'.join('     ' + json.dumps(row) for row in np.asarray(t.coef, dtype=float).tolist())
        parts.append(f'  {json.dumps(head)[:-1]},\n'
                     f'   "fit_rms": {json.dumps(np.asarray(t.fit_rms, dtype=float).tolist())},\n'
                     f'   "knots": {json.dumps(np.asarray(t.knots, dtype=float).tolist())},\n'
                     f'   "coef": [\n{rows}\n   ]}}')
    text = (f'{{"cavitation": {json.dumps(cavitation)},\n "generated_by": {json.dumps(cmd)},\n "tables": [\n'
            + ',\n'.join(parts) + '\n ]}\n')
    path.write_text(text)
    return str(path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description='build the shipped finite-bearing tables')
    ap.add_argument('--LD', type=float, nargs='+', default=[1.0, 0.5])
    ap.add_argument('--samples', type=int, default=N_SAMPLES)
    ap.add_argument('--write', action='store_true',
                    help='write the shipped data file bearing_id/bearings/finite_tables_<cavitation>.json')
    ap.add_argument('--out', help='write the JSON tables here instead')
    ap.add_argument('--cavitation', choices=('swift_stieber', 'gumbel'), default='swift_stieber')
    args = ap.parse_args(argv)
    tabs = []
    for LD in args.LD:
        t0 = time.perf_counter()
        tabs.append(build_table(LD, n_samples=args.samples, cavitation=args.cavitation))
        print(f'L/D {LD:g}: {args.samples} direct solutions on {TABLE_GRID} in {time.perf_counter() - t0:.0f} s; '
              f'fit residual RMS (jumps averaged) {np.array2string(tabs[-1].fit_rms, precision=2)}', flush=True)
    if args.write or args.out:
        print(write_tables(tabs, args.out, args.cavitation))
    return 0


__all__ = ['FiniteTable', 'table_for', 'solution', 'build_table', 'fit_table', 'sample', 'TABLE_GRID', 'S_MIN',
           'S_MAX', 'TOL_ECC', 'stated_tolerance', 'read_tables', 'write_tables']


if __name__ == '__main__':  # pragma: no cover
    raise SystemExit(main())
