"""
Short-bearing (Ocvirk) theory, the bearings API and the stability threshold.

References are independent of the closed forms under test: direct quadrature of the short-bearing pressure
(static force and its central differences in our frame), similarity laws, rotor statics, eigenvalues.
"""
import math

from bearing_id import bearings
from bearing_id.bearings import short
from bearing_id.config.params import load_rig
from bearing_id.conventions import GRAVITY, rpm_to_rad_s, whirl_direction
from bearing_id.rotor import stability, supports
from bearing_id.rotor.assembly import RotorModel, state_space
from bearing_id.rotor.modal import campbell
from error_bounds import eigen_with_bounds, EPS_MACH, solve_tol
from film_oracle import short_film_force
import numpy as np
import pytest

D = L = 0.01265
C_RAD = 50e-6
MU = 0.03
W = 9.7


@pytest.fixture(scope='module')
def rig():
    return load_rig()


@pytest.mark.parametrize('rpm', [300, 600, 1800, 3000, 10000])
def test_short_equilibrium_force_matches_pressure_quadrature(rpm):
    """The closed-form eccentricity/attitude put the journal where the integrated pi-film pressure carries W (+y)."""
    s = short.ocvirk(D, L, C_RAD, MU, W, rpm_to_rad_s(rpm))
    fx, fy = short_film_force(*s.journal_position, 0.0, 0.0, D, L, C_RAD, MU, rpm_to_rad_s(rpm), n=20000)
    # the quadrature (n = 20000 cells over the pi film, the pressure vanishing at its ends) errs by O((pi / n)^2)
    # ~ 2.5e-8 of the load times the pressure's curvature there: 1e-6 leaves a factor 40 for that factor
    assert abs(fx) < 1e-6 * W and abs(fy - W) < 1e-6 * W
    x, y = s.journal_position
    assert x > 0 and y < 0                       # below the centre, shifted in the spin direction (+x)
    assert math.isclose(math.hypot(x, y), s.eccentricity * C_RAD, rel_tol=8 * EPS_MACH)   # sin^2 + cos^2: 6 roundings


@pytest.mark.parametrize('rpm', [600, 1800, 3000])
def test_short_coefficients_equal_derivatives_of_quadrature_force_in_our_frame(rpm):
    """
    K = -dF/dq and C = -dF/dq' by central differences of the quadrature force, in (x, y): tests lit_to_xy too.

    The coefficients of ocvirk and of ocvirk_batch (the physical method's call: here all three speeds at once).
    """
    w = rpm_to_rad_s(rpm)
    s = short.ocvirk(D, L, C_RAD, MU, W, w)
    speeds = rpm_to_rad_s(np.array([600.0, 1800.0, 3000.0]))
    Kb, Cb = short.ocvirk_batch(D, L, C_RAD, MU, W, speeds)
    i = int(np.argmin(np.abs(speeds - w)))
    x, y = s.journal_position
    Kn, Cn = np.zeros((2, 2)), np.zeros((2, 2))
    for j in range(2):
        d = np.zeros(2)
        d[j] = 1e-5 * C_RAD
        fp = np.array(short_film_force(x + d[0], y + d[1], 0, 0, D, L, C_RAD, MU, w, n=20000))
        fm = np.array(short_film_force(x - d[0], y - d[1], 0, 0, D, L, C_RAD, MU, w, n=20000))
        Kn[:, j] = -(fp - fm) / (2 * d[j])
        v = d * w
        fp = np.array(short_film_force(x, y, v[0], v[1], D, L, C_RAD, MU, w, n=20000))
        fm = np.array(short_film_force(x, y, -v[0], -v[1], D, L, C_RAD, MU, w, n=20000))
        Cn[:, j] = -(fp - fm) / (2 * v[j])
    # tolerance 1e-3 ~ 3 h, h = 2 pi / n = 3.1e-4: the midpoint rule's error for a pressure with a kink at the film
    # rupture, differenced while the rupture moves, is O(h) relative (measured 1e-5 ... 5e-5); the difference steps'
    # own truncation is O(1e-10)
    for K, C in ((s.K, s.C), (Kb[i], Cb[i])):
        assert np.allclose(K, Kn, rtol=0, atol=1e-3 * np.abs(Kn).max()), (K, Kn)
        assert np.allclose(C, Cn, rtol=0, atol=1e-3 * np.abs(Cn).max()), (C, Cn)


def test_short_cross_coupling_drives_forward_whirl():
    """For spin +x -> +y the film's cross-coupled stiffness does positive work on a forward orbit (whirl source)."""
    s = short.ocvirk(D, L, C_RAD, MU, W, rpm_to_rad_s(1800))
    K, C = s.K, s.C
    assert K[0, 1] - K[1, 0] > 0
    t = np.linspace(0, 2 * np.pi, 2001)[:-1]
    for sense, sign in (('forward', +1), ('backward', -1)):
        q = np.array([np.cos(t), sign * np.sin(t)])
        dq = np.array([-np.sin(t), sign * np.cos(t)])
        work = np.mean(np.sum(-(K @ q) * dq, axis=0))
        assert (work > 0) if sense == 'forward' else (work < 0)
    assert np.allclose(C, C.T) and np.all(np.linalg.eigvalsh(C) > 0)   # short-bearing damping: symmetric, dissipative
    assert K[0, 0] > 0 and K[1, 1] > 0


def test_short_attitude_angle_limits():
    """The journal moves at right angles to the load at light load (eps -> 0) and along it at heavy load (eps -> 1)."""
    assert math.isclose(short.short_attitude_angle(1e-9), math.pi / 2, rel_tol=1e-6)
    assert short.short_attitude_angle(0.999999) < 0.01


def test_similarity_law_viscosity_and_speed(rig):
    """Coefficients depend on mu and speed only through S: K(2 mu, w) = K(mu, 2 w); C w is a function of S."""
    b = rig.bearings[0]
    w = rpm_to_rad_s(1200)
    for model in ('short', 'finite'):
        K1, C1 = bearings.coefficients(b, w, W, viscosity=2 * MU, model=model)
        K2, C2 = bearings.coefficients(b, 2 * w, W, viscosity=MU, model=model)
        assert np.allclose(K1, K2, rtol=1e-7, atol=1e-9 * np.abs(K1).max())
        assert np.allclose(C1 * w, C2 * 2 * w, rtol=1e-7, atol=1e-9 * np.abs(C1).max() * w)


def test_speed_must_be_positive(rig):
    b = rig.bearings[0]
    for bad in (0.0, -10.0, float('nan')):
        with pytest.raises(ValueError, match='speed'):
            bearings.coefficients(b, bad, W)
    fn = supports.bearing_fn(rig)
    with pytest.raises(ValueError, match='zero speed'):
        fn(0.0)


def test_default_loads_are_the_rotor_weight_share(rig):
    """Loads from rotor statics: two symmetric bearings share the total weight, about 9.7 N each (paper rig)."""
    fn = supports.bearing_fn(rig)
    model = RotorModel.from_params(rig)
    shaft_mass = rig.shaft.mass + sum(d.mass for d in rig.discs)
    # the statics solve (test_rotor.py::test_static_bearing_loads_lever_rule derives the same bound) against the mass
    n = model.n_nodes
    plane = np.sort(np.concatenate([np.arange(n) * 4 + 1, np.arange(n) * 4 + 2]))
    free = np.setdiff1d(plane, [4 * (b.node - 1) + 1 for b in rig.bearings])
    tol = solve_tol(model.K[np.ix_(free, free)]) + 64 * EPS_MACH
    assert math.isclose(sum(fn.loads.values()), shaft_mass * GRAVITY, rel_tol=tol)
    for v in fn.loads.values():
        assert 9.6 < v < 9.8


def test_bearing_fn_factors_override_and_cache(rig):
    w = rpm_to_rad_s(1800)
    nom = supports.bearing_fn(rig)
    tru = supports.bearing_fn(rig, viscosity_factor=[1.25, 1.0], clearance_factor=0.8, loads={2: 9.7, 10: 9.7})
    assert nom.solutions(w) is nom.solutions(w)                      # cached per speed
    b1, b2 = rig.bearings
    K, C = tru(w)[b1.node]
    Kr, Cr = bearings.coefficients(b1, w, 9.7, viscosity=1.25 * b1.viscosity, clearance=0.8 * b1.clearance)
    assert np.array_equal(K, Kr) and np.array_equal(C, Cr)
    K2, _ = tru(w)[b2.node]
    assert not np.allclose(K, K2)                                    # per-bearing factor applied to bearing 1 only
    with pytest.raises(ValueError, match='viscosity_factor'):
        supports.bearing_fn(rig, viscosity_factor=[1.0, 1.0, 1.0])
    sol = nom.solutions(w)[b1.node]
    assert 0 < sol.eccentricity < 1 and sol.sommerfeld > 0


def test_stability_threshold_short_rig(rig):
    """Ocvirk rig at mu = 0.03 Pa s whips from about 3800 rpm; the crossing is a real sign change of max Re."""
    model = RotorModel.from_params(rig)
    fn = supports.bearing_fn(rig, model='short')
    th = stability.threshold_speed(model, fn, rpm_to_rad_s(10000))
    rpm = th * 60 / (2 * math.pi)
    assert 3600 < rpm < 4000, rpm
    assert stability.max_real_part(model, fn, 0.99 * th) < 0 < stability.max_real_part(model, fn, 1.01 * th)
    assert all(w < th for w in rpm_to_rad_s(np.array(rig.simulation.speeds_rpm)))   # default scenario is stable
    ratio = stability.whirl_ratio(model, fn, 1.001 * th)
    assert 0.3 < ratio < 0.6
    A, _ = state_space(model, 1.001 * th, fn(1.001 * th))
    lam, V = np.linalg.eig(A)
    k = int(np.argmax(lam.real + 1e-9 * (lam.imag > 0)))
    if lam[k].imag < 0:
        V[:, k] = np.conj(V[:, k])
    i = 4 * (6 - 1)
    assert whirl_direction(V[i, k], V[i + 1, k]) == 'forward'
    assert stability.threshold_speed(model, fn, rpm_to_rad_s(3000)) == math.inf


def test_threshold_from_a_campbell_scan_equals_the_dense_search(rig):
    """The threshold bracketed on a Campbell grid (its max real parts) is the geometric-grid search's, to brentq's."""
    model = RotorModel.from_params(rig)
    fn = supports.bearing_fn(rig, model='short')
    hi = rpm_to_rad_s(10000)
    grid = np.linspace(hi / 60, hi, 25)
    cb = campbell(model, grid, fn, 4)
    for i in (0, 12, 24):        # the scan is the largest real part of ALL the eigenvalues at each grid speed
        lam, bound, _ = eigen_with_bounds(state_space(model, grid[i], fn(grid[i]))[0])
        k = int(np.argmax(lam.real))                # (eig with vectors and eigvals: two routes, each within the bound)
        for got in (cb.max_real[i], stability.max_real_part(model, fn, grid[i])):
            assert abs(got - lam[k].real) <= 2 * bound[k]
    ref = stability.threshold_speed(model, fn, hi)
    got = stability.threshold_speed(model, fn, hi, scan=(grid, cb.max_real))
    assert abs(got - ref) < 2e-3, (got, ref)                    # both brentq to 1e-3 rad/s
    assert stability.threshold_speed(model, fn, grid[8], scan=(grid[:9], cb.max_real[:9])) == math.inf
    with pytest.raises(ValueError):
        stability.threshold_speed(model, fn, hi, scan=(grid[::-1], cb.max_real))
