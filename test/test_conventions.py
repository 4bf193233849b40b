"""The sign, axis, phasor and numbering rules of bearing_id.conventions, checked against first principles."""
import math

from bearing_id import conventions as cv
import numpy as np
import pytest


def test_phasor_is_cosine_referenced_to_keyphasor():
    # x(t) = A cos(phi + a) must have phasor A e^{j a}; phi = 0 at the key mark
    A, a = 3.0, 0.7
    phi = np.linspace(0, 4 * math.pi, 101)
    assert np.allclose(cv.phasor_to_time(A * np.exp(1j * a), phi), A * np.cos(phi + a), atol=1e-15)


def test_unbalance_force_rotates_forward_with_the_mass():
    me, ph, W = 2e-4, math.radians(30), 200.0
    fx, fy = cv.unbalance_phasors(me, ph, W)
    phi = np.linspace(0, 2 * math.pi, 37)
    # the force points at the mass: direction angle phi + phase, magnitude me W^2
    x, y = cv.phasor_to_time(fx, phi), cv.phasor_to_time(fy, phi)
    assert np.allclose(np.hypot(x, y), me * W**2)
    assert np.allclose(np.unwrap(np.arctan2(y, x)), np.unwrap(phi + ph))
    assert cv.whirl_direction(fx, fy) == 'forward'


@pytest.mark.parametrize('direction,expect', [('x', (1, 0)), ('y', (0, 1))])
def test_directional_force(direction, expect):
    fx, fy = cv.force_phasors(2.0, 0.0, direction)
    assert (abs(fx), abs(fy)) == (2.0 * expect[0], 2.0 * expect[1])


def test_whirl_and_orbit_axes():
    # x = cos, y = sin: counter-clockwise from +x to +y = forward circle of radius 1
    assert cv.whirl_direction(1.0, -1j) == 'forward'
    assert cv.whirl_direction(1.0, 1j) == 'backward'
    # ellipse x = 2 cos, y = 1 sin -> semi-axes 2 and 1
    major, minor = cv.orbit_semi_axes(2.0, -1j)
    assert major == pytest.approx(2.0) and minor == pytest.approx(1.0)
    # a line orbit (x only) has no minor axis
    assert cv.orbit_semi_axes(1.5, 0.0) == pytest.approx((1.5, 0.0))


def test_literature_frame_mapping():
    # a spring acting only along the load direction (X_lit = -y) is a pure vertical spring in (x, y)
    k = 1e5
    Kxy = cv.lit_to_xy(np.array([[k, 0.0], [0.0, 0.0]]))
    assert np.allclose(Kxy, [[0, 0], [0, k]])
    # Y_lit = +x: a spring along Y_lit is horizontal
    assert np.allclose(cv.lit_to_xy(np.array([[0.0, 0.0], [0.0, k]])), [[k, 0], [0, 0]])
    # force from a displacement is frame independent: f = -K q in both frames
    Kl = np.array([[1.0, 2.0], [-3.0, 4.0]])
    q = np.array([0.3, -0.2])
    T = np.array([[0.0, -1.0], [1.0, 0.0]])  # q_lit = T q
    f_lit = -Kl @ (T @ q)
    assert np.allclose(T.T @ f_lit, -cv.lit_to_xy(Kl) @ q)


def test_node_numbers_are_one_based():
    assert cv.node_index(1) == 0
    assert cv.dof_index(2, 'y') == 5
    assert cv.dof_index(10, 'ty', 11) == 39
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError):
            cv.node_index(bad)
    with pytest.raises(ValueError, match='nodes 1..11'):
        cv.node_index(12, 11)


def test_units():
    assert cv.rpm_to_rad_s(60.0) == pytest.approx(2 * math.pi)
    assert cv.rad_s_to_rpm(2 * math.pi) == pytest.approx(60.0)
    assert np.allclose(cv.rpm_to_rad_s([0, 30]), [0, math.pi])
    assert cv.COEFF_ORDER == ('xx', 'xy', 'yx', 'yy')


@pytest.mark.parametrize('direction, words', [('x', 'horizontal (x)'), ('y*1.02', 'vertical (y)'),
                                              (cv.probe_direction(45.0), 'at 45° from +x towards +y'),
                                              (cv.probe_direction(-45.0, 0.98), 'at -45° from +x towards +y')])
def test_a_probe_direction_in_words_names_its_angle(direction, words):
    # a +-45 deg probe was called "vertical (y)" (issue 24): only 0 and 90 deg are horizontal and vertical
    assert cv.direction_words(direction) == words
