"""
The breathing-crack candidate's physics against closed forms and an independent route.

* The shaft's sag under its own weight on two rigid supports (``rotor.assembly.static_sag``) is the simply supported
  beam's 5 w L^4 / (384 E I) at midspan (Hermite elements are exact at the nodes for a uniform load).
* The sag moment a crack sees (``diagnose.crack.sag_moment``) is w z (L - z) / 2 at the element's middle, within the
  share of the element's own load the nodal statics leaves out (at most w Le^2 / 8).
* The open crack's stiffness loss the candidate uses (Sherman-Morrison on the kink load) equals the element
  stiffness rebuilt from the cantilever flexibility with the hinge compliance added (the flexibility route of
  Papadopoulos & Dimarogonas; written here, not in the package).
"""
from __future__ import annotations

import math

from bearing_id.conventions import dof_index
from bearing_id.diagnose.crack import kink_patterns, sag_moment, unit_kink
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
    assert abs(abs(sag_moment(beam, element)) - exact) <= w * el.length ** 2 / 8


def test_the_kink_load_is_self_equilibrated_and_conjugate_to_the_kink(beam):
    el = beam.elements[0]
    for P in kink_patterns(beam, 4):
        assert np.sum(P[0::4]) == pytest.approx(0.0, abs=1e-9 * np.max(np.abs(P)))
        assert np.sum(P[1::4]) == pytest.approx(0.0, abs=1e-9 * np.max(np.abs(P)))
    # a rigid rotation of the element's nodes does no work against it (K_e annihilates rigid motion)
    d = unit_kink(el.length, 'y')
    assert d @ el.K() @ d > 0


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
