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
"""
from __future__ import annotations

import math

from bearing_id.conventions import dof_index
from bearing_id.diagnose.crack import BreathingCrack, kink_patterns, sag_moment, unit_kink
from bearing_id.rotor.assembly import RotorModel, static_sag
from bearing_id.rotor.elements import ShaftElement
from error_bounds import EPS_MACH, solve_tol
import numpy as np
import pytest

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
