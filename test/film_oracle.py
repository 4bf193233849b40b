"""
Independent short-bearing oracle for the tests: the film force by direct quadrature of the short-bearing pressure.

An independent route to the closed forms of :mod:`bearing_id.bearings.short` (equilibrium, and K, C through central
differences of the force): no closed-form integral, only the pressure of the short-bearing Reynolds equation summed
around the journal.
"""
import math

import numpy as np


def short_film_force(x, y, vx, vy, D, L, c, mu, speed, n=4000):
    """
    Film force (Fx, Fy) [N] on the journal at position (x, y) [m] and velocity (vx, vy) [m/s], pi film.

    Midpoint rule with ``n`` points around the journal.  h = c - x cos t - y sin t, t from +x towards +y (the spin
    direction); the axially integrated pressure is -mu L^3 (speed dh/dt + 2 dh/dtime) / (2 h^3), clipped at 0.
    D, L, c [m]; mu [Pa s]; speed [rad/s].
    """
    R = D / 2
    t = (np.arange(n) + 0.5) * (2 * math.pi / n)
    ct, st = np.cos(t), np.sin(t)
    h = c - x * ct - y * st
    src = speed * (x * st - y * ct) - 2 * (vx * ct + vy * st)
    pbar = np.maximum(-mu * L**3 * src / (2 * h**3), 0.0)
    w = R * 2 * math.pi / n
    return -w * np.sum(pbar * ct), -w * np.sum(pbar * st)
