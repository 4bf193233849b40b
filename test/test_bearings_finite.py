"""
Finite-length Reynolds bearing.

Perturbation vs central differences, converged equilibrium independent of the start, the short-bearing limit, the
equilibrium-locus consistency, and Someya's databook table (L/D = 1).
"""
import json
import math
from pathlib import Path
import time

from bearing_id.bearings import finite, short
from bearing_id.conventions import lit_to_xy
import numpy as np
import pytest

D = 0.01
C_RAD = 1e-5
MU = 0.01
W = 100.0
TABLES = json.loads((Path(__file__).parent / 'data' / 'bearing_tables.json').read_text())


def speed_for(S, L):
    """Speed [rad/s] giving Sommerfeld number S = mu N L D / W (R/c)^2."""
    return S * 2 * math.pi * W / (MU * L * D * (D / 2 / C_RAD) ** 2)


def to_lit(B):
    """Inverse of conventions.lit_to_xy (a 90-degree rotation: applying it three more times)."""
    return lit_to_xy(lit_to_xy(lit_to_xy(B)))


@pytest.mark.parametrize('grooves', [(), ((math.pi / 2, math.radians(20)), (-math.pi / 2, math.radians(20)))])
def test_perturbation_equals_central_differences(grooves):
    """Route 1 (linearised Reynolds) = route 2 (central differences of the nonlinear cavitating film force)."""
    L = D
    w = speed_for(0.3, L)
    s = finite.reynolds(D, L, C_RAD, MU, W, w, 96, 12, grooves=grooves)
    x, y = s.journal_position
    Kn, Cn = np.zeros((2, 2)), np.zeros((2, 2))
    for j in range(2):
        d = np.zeros(2)
        d[j] = 1e-4 * C_RAD
        fp = finite.film_force(D, L, C_RAD, MU, w, x + d[0], y + d[1], 0, 0, 96, 12, grooves)
        fm = finite.film_force(D, L, C_RAD, MU, w, x - d[0], y - d[1], 0, 0, 96, 12, grooves)
        Kn[:, j] = -(fp - fm) / (2 * d[j])
        v = d * w
        fp = finite.film_force(D, L, C_RAD, MU, w, x, y, v[0], v[1], 96, 12, grooves)
        fm = finite.film_force(D, L, C_RAD, MU, w, x, y, -v[0], -v[1], 96, 12, grooves)
        Cn[:, j] = -(fp - fm) / (2 * v[j])
    assert np.allclose(s.K, Kn, rtol=0, atol=5e-3 * np.abs(Kn).max()), (s.K, Kn)
    assert np.allclose(s.C, Cn, rtol=0, atol=5e-3 * np.abs(Cn).max()), (s.C, Cn)


def test_equilibrium_converged_independent_of_start():
    """|F - W|/W <= 1e-8 from four different starts, all landing on the same position and coefficients."""
    L = D
    w = speed_for(0.08, L)
    starts = [None, (0.0, -0.9 * C_RAD), (0.5 * C_RAD, 0.5 * C_RAD), (-0.3 * C_RAD, 0.2 * C_RAD)]
    sols = [finite.reynolds(D, L, C_RAD, MU, W, w, 72, 10, start=s0, tol=1e-10) for s0 in starts]
    for s in sols:
        assert s.force_error <= 1e-8
        fx, fy = finite.film_force(D, L, C_RAD, MU, w, *s.journal_position, 0, 0, 72, 10)
        assert math.hypot(fx, fy - W) <= 1e-8 * W
        assert np.allclose(s.journal_position, sols[0].journal_position, rtol=0, atol=1e-9 * C_RAD)
        assert np.allclose(s.K, sols[0].K, rtol=1e-7, atol=0)
        assert np.allclose(s.C, sols[0].C, rtol=1e-7, atol=0)


@pytest.mark.parametrize('model', ['short', 'finite'])
def test_stiffness_reproduces_equilibrium_locus(model):
    """-K dq = dW: the journal displacement between the equilibria at W and W (1 + 1e-4), times K, is the load step."""
    L = 0.5 * D
    w = speed_for(0.2, L)
    fn = short.ocvirk if model == 'short' else (lambda *a: finite.reynolds(*a, 96, 12))
    s0 = fn(D, L, C_RAD, MU, W, w)
    s1 = fn(D, L, C_RAD, MU, W * (1 + 1e-4), w)
    dq = np.subtract(s1.journal_position, s0.journal_position)
    df = -s0.K @ dq                                       # film force change predicted by K
    assert np.allclose(df, [0.0, 1e-4 * W], rtol=0, atol=2e-3 * 1e-4 * W), df


def test_short_bearing_limit_as_L_over_D_shrinks():
    """
    At fixed short-bearing eccentricity, the finite bearing tends to the short one as L/D shrinks.

    L/D = 0.25: |d eps| <= 0.02, |d phi| <= 1 deg, K and C within 3 % of their largest entry; L/D = 0.125 cuts the
    eccentricity gap by >= 3x (O((L/D)^2) end-leakage correction).
    """
    for eps in (0.3, 0.5, 0.7):
        gaps = []
        for LD in (0.25, 0.125):
            L = LD * D
            S = float(short.short_load_parameter(eps)) / (math.pi * LD**2)
            w = speed_for(S, L)
            s = short.ocvirk(D, L, C_RAD, MU, W, w)
            f = finite.reynolds(D, L, C_RAD, MU, W, w, 96, 12)
            gaps.append(abs(f.eccentricity - s.eccentricity))
            if LD == 0.25:
                assert gaps[-1] <= 0.02
                assert abs(math.degrees(f.attitude_angle - s.attitude_angle)) <= 1.0
                assert np.abs(f.K - s.K).max() <= 0.03 * np.abs(s.K).max()
                assert np.abs(f.C - s.C).max() <= 0.03 * np.abs(s.C).max()
        assert gaps[1] <= gaps[0] / 3, gaps


# Stated tolerances against Someya's table (L/D = 1, two axial grooves, ASSUMED 10 deg wide at ambient pressure):
# eccentricity and attitude angle tight; damping within 16 %; the stiffness terms looser (the table's direct
# stiffnesses are 6-30 % above ours, most at low eccentricity, while ours pass the locus check above).
TOL = {'E': 0.005, 'Phi_deg': 1.5, 'Kxx': 0.32, 'Kxy': 0.12, 'Kyy': 0.26, 'Bxx': 0.08, 'Bxy': 0.16, 'Byx': 0.16,
       'Byy': 0.16}


def test_matches_someya_table_L_over_D_1():
    tab = TABLES['someya_two_axial_groove_LD1']
    cols = tab['columns']
    grooves = ((math.pi / 2, math.radians(10)), (-math.pi / 2, math.radians(10)))
    n_checked = 0
    for row in tab['rows']:
        r = dict(zip(cols, row))
        if not 0.3 <= r['E'] <= 0.9:
            continue
        w = speed_for(r['S'], D)
        s = finite.reynolds(D, D, C_RAD, MU, W, w, 180, 16, grooves=grooves)
        k = to_lit(s.K) * C_RAD / W
        b = to_lit(s.C) * C_RAD * w / W
        ours = {'E': s.eccentricity, 'Phi_deg': math.degrees(s.attitude_angle), 'Kxx': k[0, 0], 'Kxy': k[0, 1],
                'Kyx': k[1, 0], 'Kyy': k[1, 1], 'Bxx': b[0, 0], 'Bxy': b[0, 1], 'Byx': b[1, 0], 'Byy': b[1, 1]}
        assert abs(ours['E'] - r['E']) <= TOL['E'], (r, ours)
        assert abs(ours['Phi_deg'] - r['Phi_deg']) <= TOL['Phi_deg'], (r, ours)
        for key in ('Kxx', 'Kxy', 'Kyy', 'Bxx', 'Bxy', 'Byx', 'Byy'):
            assert abs(ours[key] / r[key] - 1) <= TOL[key], (key, r, ours)
        # Kyx crosses zero near E = 0.7: compare against the row's largest stiffness
        assert abs(ours['Kyx'] - r['Kyx']) <= 0.25 * max(abs(r[c]) for c in ('Kxx', 'Kxy', 'Kyy')), (r, ours)
        n_checked += 1
    assert n_checked == 7


def test_one_coefficient_set_is_fast():
    L = D
    w = speed_for(0.2, L)
    finite.grid_for.cache_clear()
    t0 = time.perf_counter()
    finite.reynolds(D, L, C_RAD, MU, W, w)
    assert time.perf_counter() - t0 < 1.0
