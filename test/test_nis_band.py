"""
The NIS band of a filter whose measurement noise is estimated, against Monte-Carlo truth.

* :func:`bearing_id.estimation.kalman.nis_band` with ``rel_std``: the mean NIS of N steps of m channels, each
  normalised by a noise variance estimated with relative 1-sigma ``rel_std`` (drawn here), falls inside the band in
  95 % of trials, within 4 binomial 1-sigma.
"""
from __future__ import annotations

from math import sqrt

from bearing_id.estimation.kalman import nis_band
import numpy as np
import pytest


@pytest.mark.parametrize('n,m,u', [(2048, 2, 0.02), (20480, 2, 0.02), (204800, 2, 0.01), (20480, 4, 0.0)])
def test_nis_band_with_an_estimated_noise_covers_95_percent(n, m, u):
    rng = np.random.default_rng(5)
    trials = 20000
    lo, hi = nis_band(n, m, rel_std=u)
    nis = rng.chisquare(n * m, size=trials) / n                # the mean NIS with the noise known
    nis = nis / (1.0 + u * rng.standard_normal(trials))         # normalised by an estimated noise instead
    cover = np.mean((nis >= lo) & (nis <= hi))
    assert abs(cover - 0.95) <= 4 * sqrt(0.95 * 0.05 / trials), cover
