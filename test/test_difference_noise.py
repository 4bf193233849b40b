"""
:func:`bearing_id.signals.noise.difference_noise` against Monte-Carlo truth.

White noise under a slow signal (a 1X, and a free vibration 100 times the noise: what a speed ramp leaves ringing).
The mean of the blocks' estimates must match the noise variance drawn here plus the signal's share that passes the
differences, in closed form ((2 sin(pi f / fs))^(2k) A^2 / 2 / C(2k, k) per component), within 4 of the mean's
Monte-Carlo 1-sigma.  On noise alone the spread of the estimates must match the stated degrees of freedom (relative
variance 2 / dof), within 4 of the sample variance's own 1-sigma (sqrt(2 / (trials - 1)), near-normal estimates).
"""
from __future__ import annotations

from math import comb, pi, sin, sqrt

from bearing_id.signals.noise import DIFF_ORDER, difference_noise
import numpy as np
import pytest

FS = 10240.0
N = 1024
COMPONENTS = ((207.0, 100.0), (50.0, 150.0))      # (frequency [Hz], amplitude [noise std]): a ringing, a 1X


def slow_signal(rng) -> np.ndarray:
    t = np.arange(N)[:, None] / FS
    return sum(a * np.cos(2 * pi * f * t + rng.uniform(0, 2 * pi, size=2)) for f, a in COMPONENTS)


@pytest.mark.parametrize('order', [2, 3])
def test_the_mean_is_the_noise_plus_the_closed_form_leak(order):
    rng = np.random.default_rng(11)
    est = np.array([difference_noise(slow_signal(rng) + rng.standard_normal((N, 2)), order)[0]
                    for _ in range(400)]).ravel()
    leak = sum((2 * sin(pi * f / FS)) ** (2 * order) * a * a / 2 for f, a in COMPONENTS) / comb(2 * order, order)
    if order == DIFF_ORDER:
        assert leak < 0.002                    # the ringing (5e3 x the noise variance) hardly passes
    mc_sigma = np.std(est, ddof=1) / sqrt(est.size)
    assert abs(np.mean(est) - (1.0 + leak)) <= 4 * mc_sigma, (np.mean(est), 1.0 + leak, mc_sigma)


@pytest.mark.parametrize('order', [1, 2, 3])
def test_the_spread_is_the_stated_degrees_of_freedom(order):
    rng = np.random.default_rng(12)
    out = [difference_noise(rng.standard_normal((N, 2)), order) for _ in range(2000)]
    est, dof = np.array([v for v, _ in out]).ravel(), out[0][1]
    assert abs(np.mean(est) - 1.0) <= 4 * np.std(est, ddof=1) / sqrt(est.size)
    assert abs(np.var(est, ddof=1) / (2 / dof) - 1) <= 4 * sqrt(2 / (est.size - 1)), (np.var(est, ddof=1), 2 / dof)


def test_too_few_samples_are_refused():
    with pytest.raises(ValueError, match='cannot give a noise variance'):
        difference_noise(np.zeros((4, 2)), 3)
