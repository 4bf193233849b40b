"""
The breathing-crack candidate's physics against closed forms and an independent route.

* The shaft's sag under its own weight on two rigid supports (``rotor.assembly.static_sag``) is the simply supported
  beam's 5 w L^4 / (384 E I) at midspan (Hermite elements are exact at the nodes for a uniform load).
* The sag moment a crack sees (``diagnose.crack.sag_moment``) is w z (L - z) / 2 at the element's middle.
* A unit kink's load on the element is a pure couple +-E I / L (no shear) in each plane, with the FE model's signs.
* The mean softening the candidate adds to the dynamic stiffness is 1/4 of the open hinge's loss in each plane, and
  the compliance it reports from a Mayes kink series is the compliance that made it (the Fourier series computed here).
* The open crack's stiffness loss the candidate uses (Sherman-Morrison on the kink load) equals the element
  stiffness rebuilt from the cantilever flexibility with the hinge compliance added (the flexibility route of
  Papadopoulos & Dimarogonas; written here, not in the package).
* The crack depth law (``diagnose.crack_flexibility``): Papadopoulos & Dimarogonas' published dimensionless c55
  table, scipy's adaptive double quadrature of the same strain-energy integral, and the shallow-crack closed form;
  the depth the candidate reports from a Mayes kink series is the depth whose compliance made it.
"""
from __future__ import annotations

from decimal import Decimal
import math

from bearing_id.conventions import dof_index
from bearing_id.diagnose.crack import BreathingCrack, kink_patterns, sag_moment, unit_kink
from bearing_id.diagnose.crack_flexibility import (crack_depth_ratio, dimensionless_c55, open_crack_compliance,
                                                   strip_factor)
from bearing_id.rotor.assembly import RotorModel, static_sag
from bearing_id.rotor.elements import ShaftElement
from error_bounds import EPS_MACH, solve_tol
import numpy as np
import pytest
from scipy import integrate

E, NU, RHO, G0 = 2.1e11, 0.3, 7850.0, 9.80665
N_EL, LENGTH, D = 10, 1.0, 0.02


@pytest.fixture(scope='module')
def beam():
    els = [ShaftElement(LENGTH / N_EL, D, 0.0, E, E / (2 * (1 + NU)), RHO, shear=False, rotary_inertia=False)
           for _ in range(N_EL)]
    return RotorModel.from_elements(els, bearing_nodes=(1, N_EL + 1))


def test_the_sag_is_the_simply_supported_beam(beam):
    el = beam.elements[0]
    w = RHO * el.area * G0
    q = static_sag(beam)
    mid = q[dof_index(N_EL // 2 + 1, 'y', beam.n_nodes)]
    free = [i for i in range(beam.ndof) if i % 4 in (1, 2) and i not in (1, 4 * N_EL + 1)]
    tol = solve_tol(beam.K[np.ix_(free, free)]) + 16 * EPS_MACH
    assert mid == pytest.approx(-5 * w * LENGTH ** 4 / (384 * E * el.inertia), rel=tol)


@pytest.mark.parametrize('element', [1, 3, 5, 8])
def test_the_sag_moment_is_the_beam_moment_at_the_element_middle(beam, element):
    el = beam.elements[0]
    w = RHO * el.area * G0
    z = (element - 0.5) * LENGTH / N_EL
    exact = w * z * (LENGTH - z) / 2
    # exact at the nodes (Hermite elements, uniform load) and the statics of the half element: rounding only
    assert abs(sag_moment(beam, element)) == pytest.approx(exact, rel=1e-9)


@pytest.mark.parametrize('plane, rows', [('x', (3, 7)), ('y', (2, 6))])
def test_the_kink_load_is_a_pure_couple_of_the_bending_stiffness(beam, plane, rows):
    # a hinge kink of one radian at the middle: the element answers with end moments +-E I / L and no shear
    el = beam.elements[0]
    P = el.K() @ unit_kink(el.length, plane)
    EI_L = E * el.inertia / el.length
    assert np.allclose(np.delete(P, rows), 0.0, atol=1e-9 * EI_L)
    sign = 1.0 if plane == 'x' else -1.0          # ty = +dx/dz, tx = -dy/dz
    assert P[rows[1]] == pytest.approx(sign * EI_L, rel=1e-9)
    assert P[rows[0]] == pytest.approx(-sign * EI_L, rel=1e-9)
    Px, Py = kink_patterns(beam, 4)
    assert np.allclose((Px if plane == 'x' else Py)[12:20], P, rtol=0, atol=1e-12 * EI_L)


@pytest.mark.parametrize('rel_c', [0.01, 0.3, 2.0])
def test_the_hinge_stiffness_loss_is_the_flexibility_route(beam, rel_c):
    el = beam.elements[0]
    L, EI = el.length, E * el.inertia
    c = rel_c * L / EI
    K = el.K()
    y = [1, 2, 5, 6]                  # y-z plane: y1, tx1, y2, tx2 (tx = -dy/dz)
    Kp = K[np.ix_(y, y)]
    # flexibility route: cantilever clamped at node a, tip (y, tx) flexibility, hinge at the middle added
    C0 = np.linalg.inv(Kp[2:, 2:])
    h = np.array([L / 2, -1.0])       # tip (y, tx) motion per unit hinge rotation of the slope dy/dz
    Cc = C0 + c * np.outer(h, h)
    B = np.array([[-1.0, L, 1.0, 0.0], [0.0, -1.0, 0.0, 1.0]])   # tip deformation relative to node a's rigid motion
    assert np.allclose(B.T @ Kp[2:, 2:] @ B, Kp, rtol=1e-9, atol=1e-9 * np.max(np.abs(Kp)))
    loss_flex = Kp - B.T @ np.linalg.inv(Cc) @ B
    # the candidate's form: c P P^T / (1 + c d^T K d) with P = K_e d of the unit kink
    d = unit_kink(L, 'y')
    P = K @ d
    loss_sm = c * np.outer(P, P) / (1 + c * d @ K @ d)
    scale = np.max(np.abs(loss_flex))
    cond = np.linalg.cond(Cc) * np.linalg.cond(Kp[2:, 2:])
    assert np.allclose(loss_sm[np.ix_(y, y)], loss_flex, rtol=0, atol=64 * EPS_MACH * cond * scale)
    assert math.isfinite(scale) and scale > 0


def hinge_loss(K: np.ndarray, L: float, c: float, plane: str) -> np.ndarray:
    """Stiffness loss (8, 8) of an element with a hinge of compliance c at its middle in ``plane`` (flexibility)."""
    idx = [0, 3, 4, 7] if plane == 'x' else [1, 2, 5, 6]
    s = 1.0 if plane == 'x' else -1.0                       # the rotation DOF per unit slope
    Kp = K[np.ix_(idx, idx)]
    Cc = np.linalg.inv(Kp[2:, 2:]) + c * np.outer([L / 2, s], [L / 2, s])
    B = np.array([[-1.0, -s * L, 1.0, 0.0], [0.0, -1.0, 0.0, 1.0]])
    out = np.zeros((8, 8))
    out[np.ix_(idx, idx)] = Kp - B.T @ np.linalg.inv(Cc) @ B
    return out


def test_the_mean_softening_is_a_quarter_of_the_open_hinge_in_each_plane(beam):
    element, rel_c = 4, 0.4
    e = BreathingCrack(beam, element)
    el = beam.elements[element - 1]
    Z = np.zeros((beam.ndof, beam.ndof), complex)
    e.add_dZ(None, Z, 100.0, 100.0, np.array([rel_c]))
    c = rel_c * el.length / (E * el.inertia)
    expect = np.zeros_like(Z)
    sl = slice(4 * (element - 1), 4 * (element + 1))
    expect[sl, sl] = -0.25 * (hinge_loss(el.K(), el.length, c, 'x') + hinge_loss(el.K(), el.length, c, 'y'))
    scale = np.max(np.abs(expect))
    assert np.allclose(Z, expect, rtol=0, atol=1e-9 * scale)


@pytest.mark.parametrize('cross', [True, False])
def test_the_compliance_from_a_mayes_kink_series_is_the_one_that_made_it(beam, cross):
    # the kink of a crack of compliance c opening under the sag moment M (Mayes), over one turn, turned by the
    # crack's angle; its harmonics by FFT here; with the horizontal plane's kink (loss turning with the crack) or
    # without it (direct terms only, as ROSS's Mayes crack)
    element, c, psi = 5, 3e-5, 0.7
    e = BreathingCrack(beam, element)
    M = abs(e.moment)
    a = np.linspace(0.0, 2 * math.pi, 256, endpoint=False) + psi
    g = (1 + np.cos(a)) / 2
    ky = c * M * g * np.cos(a) ** 2
    kx = c * M * g * np.cos(a) * np.sin(a) if cross else 0.0 * a
    th = a - psi
    lin = []
    for r in (1, 2, 3):
        X = 2 * np.mean(kx * np.exp(-1j * r * th))
        Y = 2 * np.mean(ky * np.exp(-1j * r * th))
        lin += [X.real / 1e-6, X.imag / 1e-6, Y.real / 1e-6, Y.imag / 1e-6]
    p = e.physical(np.array([0.0]), np.array(lin))
    assert p['compliance'] == pytest.approx(c, rel=1e-9)
    assert p['kink_3x'] / p['kink_2x'] == pytest.approx(0.5, rel=1e-9)


# Papadopoulos & Dimarogonas' dimensionless local flexibility c55 E R^3 / (1 - nu^2) of a straight-front crack
# against a / R (Papadopoulos & Dimarogonas 1987; the table as distributed with ROSS 2.3.0,
# ross/faults/data/PAPADOPOULOS.csv, as printed there)
PAPADOPOULOS_C55 = {0.01: '9.57316e-05', 0.05: '5.14358e-03', 0.1: '0.0277722', 0.15: '7.32971e-02',
                    0.2: '0.144614', 0.25: '0.243694', 0.4: '0.72488', 0.5: '1.22153', 0.6: '1.8922',
                    0.75: '3.33587', 0.8: '3.97355', 0.9: '5.57764', 0.95: '6.59149', 1.0: '7.79039'}


@pytest.mark.parametrize('a_over_r', sorted(PAPADOPOULOS_C55))
def test_the_crack_compliance_law_is_the_published_table(a_over_r):
    # within the table's rounding (half a unit in its last printed figure) and the quadrature's error (below
    # 1e-10 relative: the next test)
    printed = Decimal(PAPADOPOULOS_C55[a_over_r])
    half_unit = float(Decimal(5).scaleb(printed.as_tuple().exponent - 1))
    assert dimensionless_c55(a_over_r) == pytest.approx(float(printed), abs=half_unit + 1e-10 * float(printed))


def _strip_integrand(alpha: float, x: float) -> float:
    """2 k^2 of the strip at x [R] and crack depth alpha [R] per unit moment (R = 1), written out here."""
    half = math.sqrt(1.0 - x * x)
    lam = math.pi * alpha / (2 * half) / 2
    F = math.sqrt(math.tan(lam) / lam) * (0.923 + 0.199 * (1 - math.sin(lam)) ** 4) / math.cos(lam)
    return 2 * (4 * half / math.pi) ** 2 * math.pi * alpha * F ** 2


@pytest.mark.parametrize('a_over_r', [0.03, 0.3, 0.7, 1.0])
def test_the_crack_compliance_quadrature_is_scipys_adaptive_one(a_over_r):
    b = math.sqrt(1 - (1 - a_over_r) ** 2)
    val, err = integrate.dblquad(_strip_integrand, -b, b, 0.0, lambda x: math.sqrt(1 - x * x) - (1 - a_over_r),
                                 epsabs=0.0, epsrel=1e-11)
    assert dimensionless_c55(a_over_r) == pytest.approx(val, rel=1e-10 + err / val)


@pytest.mark.parametrize('a_over_r', [1e-2, 1e-3, 1e-4])
def test_a_shallow_crack_has_the_edge_crack_closed_form(a_over_r):
    # a shallow crack: every strip is an edge crack in a half-space under the outer fibre's stress 4 M / (pi R^3),
    # F = 1.122, strip depth a - x^2 / 2 over |x| < sqrt(2 a): c55 -> (32 F^2 / pi) (8 / 15) a^2 sqrt(2 a) (R = 1).
    # Its corrections (the strip factor's slope, the section's curvature) are first order in a / R.
    assert float(strip_factor(0.0)) == pytest.approx(1.122, rel=1e-12)
    closed = 32 * 1.122 ** 2 / math.pi * 8 / 15 * a_over_r ** 2 * math.sqrt(2 * a_over_r)
    assert abs(dimensionless_c55(a_over_r) / closed - 1) <= 2 * a_over_r


def test_the_crack_depth_is_the_inverse_of_the_law_and_says_where_the_law_ends():
    d, e, nu = 0.05, 2.0e11, 0.29
    for depth in (0.02, 0.2, 0.45):
        c = open_crack_compliance(depth, d, e, nu)
        assert c == pytest.approx(dimensionless_c55(2 * depth) * (1 - nu ** 2) / (e * (d / 2) ** 3), rel=1e-12)
        assert crack_depth_ratio(c, d, 0.0, e, nu) == pytest.approx(depth, rel=1e-9)
    assert crack_depth_ratio(0.0, d, 0.0, e, nu) == 0.0
    assert math.isnan(crack_depth_ratio(1.01 * open_crack_compliance(0.5, d, e, nu), d, 0.0, e, nu))
    assert math.isnan(crack_depth_ratio(1e-6, d, 0.01, e, nu))           # hollow: the law is for a solid shaft
    with pytest.raises(ValueError):
        dimensionless_c55(1.2)


@pytest.mark.parametrize('depth', [0.1, 0.3])
def test_the_candidate_reports_the_depth_whose_compliance_made_its_kinks(beam, depth):
    element = 5
    e = BreathingCrack(beam, element)
    el = beam.elements[element - 1]
    c = open_crack_compliance(depth, el.outer_d, E, NU)
    M = abs(e.moment)
    a = np.linspace(0.0, 2 * math.pi, 256, endpoint=False)
    ky = c * M * (1 + np.cos(a)) / 2 * np.cos(a) ** 2             # Mayes under the sag, in the sag plane
    lin = []
    for r in (1, 2, 3):
        Y = 2 * np.mean(ky * np.exp(-1j * r * a))
        lin += [0.0, 0.0, Y.real / 1e-6, Y.imag / 1e-6]
    p = e.physical(np.array([0.0]), np.array(lin))
    assert p['depth_ratio'] == pytest.approx(depth, rel=1e-9)
    std = {k: 0.01 * abs(v) for k, v in p.items()}
    assert 'crack depth a/D ≈' in e.sentence(p, std) and e.undetermined(p, std) == []
    std['compliance'] = 0.5 * p['compliance']
    std['depth_ratio'] = 0.2 * p['depth_ratio']
    assert e.undetermined(p, std) == ['compliance', 'depth_ratio']
    assert 'crack depth not determined by these data' in e.sentence(p, std)
