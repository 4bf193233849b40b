"""
FE rotor model against closed forms and against other computation routes.

References (independent of bearing_id.rotor):
* pinned-pinned Timoshenko beam: the exact frequency equation of the Timoshenko equations for sin/cos modes
  (shear + rotary inertia), solved here as a quadratic in omega^2;
* free-free Euler-Bernoulli beam: roots of cos(bL) cosh(bL) = 1, bL = 4.730040745, 7.853204624, ... (Blevins);
* statics: force and moment balance (lever rule) with the centre of gravity computed here from the geometry;
* rigid-body kinetics: element mass rho A L, translational rigid modes carry no strain energy;
* harmonic response: the state-space route (j w I - A)^-1 B F versus the direct solve;
* critical speed: the peak of the 1X unbalance response on a fine speed grid.

Tolerances of rounding-level comparisons come from test/error_bounds.py (a sum within n eps sum |terms|, two linear
solves within 8 n eps cond ||q|| each, eigenvalues within LAPACK's bound) and are written out where used.
"""
import math

from bearing_id.conventions import dof_index, rpm_to_rad_s, unbalance_phasors
from bearing_id.rotor.assembly import (dynamic_stiffness, harmonic_response, probe_matrix, RotorModel, state_space,
                                       static_bearing_loads)
from bearing_id.rotor.elements import DiscElement, ShaftElement, shear_coefficient
from bearing_id.rotor.modal import campbell, critical_speeds, damped_modes, free_free_frequencies
from error_bounds import EPS_MACH, solve_tol, state_backward_error, sum_tol
import numpy as np
import pytest
from scipy.linalg import eigh, matrix_balance

E, NU, RHO = 2.1e11, 0.3, 7850.0
GMOD = E / (2 * (1 + NU))


def beam(n_el, length, d, **kw):
    els = [ShaftElement(length / n_el, d, 0.0, E, GMOD, RHO, **kw) for _ in range(n_el)]
    return RotorModel.from_elements(els)


def xz_plane(model):
    idx = np.sort(np.concatenate([np.arange(model.n_nodes) * 4, np.arange(model.n_nodes) * 4 + 3]))
    return idx


def pinned_pinned_fe(model, n):
    idx = xz_plane(model)
    # drop x at both ends (pinned), keep the end rotations free
    drop = {0, 4 * (model.n_nodes - 1)}
    idx = np.array([i for i in idx if i not in drop])
    w2 = eigh(model.K[np.ix_(idx, idx)], model.M[np.ix_(idx, idx)], eigvals_only=True)
    return np.sqrt(w2[:n])


def timoshenko_pinned_exact(length, d, mode, kappa):
    A = math.pi * d**2 / 4
    inertia = math.pi * d**4 / 64
    k = mode * math.pi / length
    kga = kappa * GMOD * A
    a = RHO * A * RHO * inertia
    b = -(RHO * A * (E * inertia * k**2 + kga) + RHO * inertia * kga * k**2)
    c = kga * E * inertia * k**4
    w2 = (-b - math.sqrt(b * b - 4 * a * c)) / (2 * a)
    return math.sqrt(w2)


def test_shear_coefficients_solid_section():
    # Hutchinson (2001) solid circle 6(1+nu)^2/(7+12nu+4nu^2); Cowper (1966) 6(1+nu)/(7+6nu): sums and products of
    # positive terms, under 16 roundings on either side
    assert shear_coefficient(1.0, 0.0, 0.3) == pytest.approx(6 * 1.3**2 / (7 + 3.6 + 0.36), rel=32 * EPS_MACH)
    assert shear_coefficient(1.0, 0.0, 0.3, 'cowper') == pytest.approx(6 * 1.3 / (7 + 1.8), rel=32 * EPS_MACH)


def test_element_matrix_properties():
    el = ShaftElement(0.1, 0.04, 0.01, E, GMOD, RHO)
    M, K, G = el.M(), el.K(), el.G()
    assert np.allclose(M, M.T, atol=0) and np.allclose(K, K.T, atol=0)
    assert np.allclose(G, -G.T, atol=0)
    assert np.all(np.linalg.eigvalsh(M) > 0)
    # rigid translation in x: kinetic energy of the element mass, no strain energy
    u = np.zeros(8)
    u[[0, 4]] = 1.0
    mass = RHO * math.pi / 4 * (0.04**2 - 0.01**2) * 0.1
    assert abs(u @ M @ u - mass) <= sum_tol(M[np.ix_([0, 4], [0, 4])]) + 16 * EPS_MACH * mass

    # K v of a rigid-body motion v is a sum of 8 terms that cancel exactly: its rounding is at most 8 eps sum |K_ij v_j|
    def rigid_tol(v):
        return 8 * EPS_MACH * (np.abs(K) @ np.abs(v)).max()
    assert np.abs(K @ u).max() <= rigid_tol(u)
    # rigid tilt in the x-z plane: x = z, ty = 1 -> no strain energy
    t = np.zeros(8)
    t[[3, 7]] = 1.0
    t[4] = 0.1
    assert np.abs(K @ t).max() <= rigid_tol(t)
    # rigid tilt in y-z: y = z, tx = -dy/dz = -1
    s = np.zeros(8)
    s[[2, 6]] = -1.0
    s[5] = 0.1
    assert np.abs(K @ s).max() <= rigid_tol(s)


def test_element_matrices_from_nelson_shape_functions():
    """Planar M, rotary R and K equal the integrals of Nelson's (1980) interdependent shape functions."""
    el = ShaftElement(0.07, 0.03, 0.0, E, GMOD, RHO)
    L, p = el.length, el.phi
    xi, wq = np.polynomial.legendre.leggauss(8)
    xi, wq = (xi + 1) / 2, wq / 2 * L
    c = 1 / (1 + p)
    N = c * np.array([1 - 3 * xi**2 + 2 * xi**3 + p * (1 - xi), L * (xi - 2 * xi**2 + xi**3 + p / 2 * (xi - xi**2)),
                      3 * xi**2 - 2 * xi**3 + p * xi, L * (-xi**2 + xi**3 + p / 2 * (-xi + xi**2))])
    dN = c / L * np.array([-6 * xi + 6 * xi**2 - p, L * (1 - 4 * xi + 3 * xi**2 + p / 2 * (1 - 2 * xi)),
                           6 * xi - 6 * xi**2 + p, L * (-2 * xi + 3 * xi**2 + p / 2 * (-1 + 2 * xi))])
    Psi = c * np.array([6 / L * (-xi + xi**2), 1 - 4 * xi + 3 * xi**2 + p * (1 - xi), 6 / L * (xi - xi**2),
                        -2 * xi + 3 * xi**2 + p * xi])
    dPsi = c / L * np.array([6 / L * (-1 + 2 * xi), -4 + 6 * xi - p, 6 / L * (1 - 2 * xi), -2 + 6 * xi + p])
    A, inertia = el.area, el.inertia
    Mt = RHO * A * (N * wq) @ N.T
    R = (Psi * wq) @ Psi.T
    gam = dN - Psi
    K = E * inertia * (dPsi * wq) @ dPsi.T + el.kappa * GMOD * A * (gam * wq) @ gam.T
    # Gauss-Legendre with 8 points integrates these degree <= 6 polynomials exactly: the two differ by rounding only,
    # bounded by that of the quadrature sums (8 points, each a product of ~10 roundings: 32 eps sum of |terms|) plus
    # the closed forms' own (a few dozen roundings of terms no larger than those |terms|)
    aN, adN, aPsi, adPsi, agam = (np.abs(v) for v in (N, dN, Psi, dPsi, gam))
    for got, ref, absolute in ((el._planar_mass(), Mt, RHO * A * (aN * wq) @ aN.T),
                               (el._rotation_integral(), R, (aPsi * wq) @ aPsi.T),
                               (el._planar_stiffness(), K, E * inertia * (adPsi * wq) @ adPsi.T
                                + el.kappa * GMOD * A * (agam * wq) @ agam.T)):
        assert np.all(np.abs(got - ref) <= 64 * EPS_MACH * absolute)


def test_pinned_pinned_timoshenko_closed_form():
    L, d = 0.5, 0.05        # L/D = 10: shear and rotary inertia lower mode 3 by several %
    kappa = shear_coefficient(d, 0.0, NU)
    exact = np.array([timoshenko_pinned_exact(L, d, m, kappa) for m in (1, 2, 3)])
    fe = pinned_pinned_fe(beam(80, L, d), 3)
    assert np.allclose(fe, exact, rtol=1e-4), fe / exact - 1
    # the effect being tested is real: Euler-Bernoulli is >4 % off for mode 3
    eb = np.array([(m * math.pi / L) ** 2 * math.sqrt(E * d**2 / 16 / RHO) for m in (1, 2, 3)])
    assert abs(eb[2] / exact[2] - 1) > 0.04


def test_mesh_convergence_pinned_pinned():
    """
    Monotone convergence from above.

    Once elements are shorter than the diameter (phi >> 1) the interdependent-interpolation element converges as h^2
    (error / 4 per halving); with slender elements and no shear (Rayleigh beam) as h^4.
    """
    L, d = 0.5, 0.05
    kappa = shear_coefficient(d, 0.0, NU)
    exact = timoshenko_pinned_exact(L, d, 3, kappa)
    errs = [pinned_pinned_fe(beam(n, L, d), 3)[2] / exact - 1 for n in (10, 20, 40)]
    assert all(e > 0 for e in errs)
    assert 3.5 < errs[0] / errs[1] < 4.6 and 3.5 < errs[1] / errs[2] < 4.6
    A, inertia = math.pi * d**2 / 4, math.pi * d**4 / 64
    k = 3 * math.pi / L
    rayleigh = math.sqrt(E * inertia * k**4 / (RHO * A + RHO * inertia * k**2))
    er = [pinned_pinned_fe(beam(n, L, d, shear=False), 3)[2] / rayleigh - 1 for n in (10, 20)]
    assert er[0] / er[1] > 14


def test_free_free_euler_bernoulli_limit():
    L, d = 1.0, 0.02
    m = beam(40, L, d, shear=False, rotary_inertia=False)
    w = free_free_frequencies(m, 4)
    bl = np.array([4.730040745, 7.853204624, 10.995607838, 14.137165491])
    ref = bl**2 * math.sqrt(E * (math.pi * d**4 / 64) / (RHO * math.pi * d**2 / 4 * L**4))
    assert np.allclose(w, ref, rtol=2e-5), w / ref - 1   # 40 cubic elements
    w80 = free_free_frequencies(beam(80, L, d, shear=False, rotary_inertia=False), 4)
    assert np.all(np.abs(w80 / ref - 1) < np.abs(w / ref - 1) / 10)


def test_rig_model_shape_and_mass(rig, model):
    assert model.n_nodes == 11 and model.ndof == 44
    assert model.M.shape == (44, 44)
    assert model.bearing_nodes == (2, 10)
    assert model.node_z[-1] == pytest.approx(0.85)
    # shaft 12.65 mm x 0.85 m steel + two 80 x 15 mm discs on the shaft bore
    shaft = RHO / 7850 * 7800 * math.pi / 4 * 0.01265**2 * 0.85
    disc = 7800 * math.pi / 4 * (0.08**2 - 0.01265**2) * 0.015
    assert model.mass == pytest.approx(shaft + 2 * disc, rel=64 * EPS_MACH)   # ~24 positive terms, a few roundings


def test_static_bearing_loads_lever_rule(rig):
    # move a disc off centre so the two reactions differ; centre of gravity from the geometry here
    discs = (rig.discs[0], rig.discs[1].__class__(**{**rig.discs[1].__dict__, 'node': 9}))
    r2 = rig.replace(discs=discs)
    m = RotorModel.from_params(r2)
    loads = static_bearing_loads(m)
    z = np.array(r2.shaft.node_z)
    ms = rig.shaft.mass
    md = [d.mass for d in discs]
    zd = [z[d.node - 1] for d in discs]
    W = 9.80665 * (ms + sum(md))
    zcg = (ms * 0.85 / 2 + sum(a * b for a, b in zip(md, zd))) / (ms + sum(md))
    z1, z2 = z[1], z[9]
    R1 = W * (z2 - zcg) / (z2 - z1)
    # the statics solve against the lever rule: a linear solve on the free DOFs of the vertical plane (solve_tol)
    n = m.n_nodes
    plane = np.sort(np.concatenate([np.arange(n) * 4 + 1, np.arange(n) * 4 + 2]))
    free = np.setdiff1d(plane, [dof_index(2, 'y', n), dof_index(10, 'y', n)])
    tol = solve_tol(m.K[np.ix_(free, free)]) + 16 * EPS_MACH
    assert loads[2] == pytest.approx(R1, rel=tol)
    assert loads[10] == pytest.approx(W - R1, rel=tol)
    assert loads[2] > 0 and loads[10] > 0


ISO = {2: (np.diag([3e5, 3e5]), np.diag([50.0, 50.0])), 10: (np.diag([3e5, 3e5]), np.diag([50.0, 50.0]))}
ANISO = {2: (np.array([[2e5, 9e4], [-4e4, 3e5]]), np.array([[300.0, 20.0], [30.0, 500.0]])),
         10: (np.array([[1.5e5, 6e4], [-2e4, 2.5e5]]), np.array([[250.0, 10.0], [15.0, 400.0]]))}


def test_harmonic_response_equals_state_space_route(model):
    W = rpm_to_rad_s(2000.0)
    A, B = state_space(model, W, ANISO)
    F = np.zeros((model.ndof, 2), complex)
    F[dof_index(4, 'x'), 0] = 1.0
    F[dof_index(8, 'y'), 1] = 1.0 - 0.5j
    for w in (W, 0.43 * W, 2 * W):   # synchronous and not
        q = harmonic_response(model, W, w, F, ANISO)
        Sb, T = matrix_balance(1j * w * np.eye(2 * model.ndof) - A, permute=False)     # cond ~1e6, not ~1e13
        x = T @ np.linalg.solve(Sb, np.linalg.solve(T, B @ F))
        assert q.shape == (model.ndof, 2)
        Z = dynamic_stiffness(model, W, w, ANISO)
        for j in range(2):
            assert np.linalg.norm(q[:, j] - x[:model.ndof, j]) <= solve_tol(Z, Sb) * np.linalg.norm(q[:, j])
        one = harmonic_response(model, W, w, F[:, 0], ANISO)         # one right-hand side: the same system
        assert np.linalg.norm(q[:, 0] - one) <= solve_tol(Z, Z) * np.linalg.norm(one)


def test_damped_modes_are_eigenpairs_and_gyroscopic_sign(model):
    W = rpm_to_rad_s(3000.0)
    m = damped_modes(model, W, ANISO, 6)
    M, K = model.M, model.K.copy()
    C = model.C + W * model.G
    for node, (k, c) in ANISO.items():
        i = dof_index(node, 'x')
        K[i:i + 2, i:i + 2] += k
        C[i:i + 2, i:i + 2] += c
    for lam, v in zip(m.eigenvalues, m.shapes.T):
        r = (lam**2 * M + lam * C + K) @ v
        assert np.linalg.norm(r) < 1e-6 * np.linalg.norm(K @ v)       # an eigenpair at all (K v dominates r)
        # ... and as accurate as a backward-stable eigensolver's (test/error_bounds.py: below n eps, n = 2 ndof)
        assert state_backward_error(model, W, ANISO, lam, v) <= 2 * model.ndof * EPS_MACH
    assert np.all(np.diff(m.frequency) >= 0)
    # the same numbers through the identity log_dec = 2 pi zeta / sqrt(1 - zeta^2): about 8 roundings, the last
    # ones amplified by 1 / (1 - zeta^2) through 1 - zeta^2
    z = m.damping_ratio
    assert np.all(np.abs(m.log_dec / (2 * np.pi * z / np.sqrt(1 - z**2)) - 1) <= 16 * EPS_MACH / (1 - z**2))
    # isotropic bearings: each pair splits, forward up and backward down as speed rises
    lo = damped_modes(model, 10.0, ISO, 6)
    hi = damped_modes(model, rpm_to_rad_s(6000.0), ISO, 6)
    for k in range(0, 6, 2):
        fw_hi = [f for f, w in zip(hi.frequency[k:k + 2], hi.whirl[k:k + 2]) if w == 'forward']
        bw_hi = [f for f, w in zip(hi.frequency[k:k + 2], hi.whirl[k:k + 2]) if w == 'backward']
        assert len(fw_hi) == 1 and len(bw_hi) == 1
        assert fw_hi[0] > bw_hi[0]
        assert fw_hi[0] > max(lo.frequency[k:k + 2]) * (1 + 1e-6) or k == 0 and fw_hi[0] > min(lo.frequency[k:k + 2])


def test_critical_speeds_from_a_campbell_on_the_same_grid_are_the_same_numbers(model):
    """
    Check critical_speeds(campbell_grid=...) against computing the modes again: the same crossings.

    Each crossing is refined by brentq to 1e-9 x the bracket's end (and rtol 1e-12): two runs agree within twice that.
    """
    co = {2: (np.diag([2e5, 3e5]), np.array([[5.0, 1.0], [1.0, 6.0]])),
          10: (np.diag([2e5, 2.5e5]), np.diag([5.0, 5.0]))}
    grid = np.linspace(50.0, 900.0, 25)
    cb = campbell(model, grid, lambda s: co, 8)
    fresh = critical_speeds(model, lambda s: co, (50.0, 900.0), n_grid=25, n_modes=8)
    reused = critical_speeds(model, lambda s: co, (50.0, 900.0), n_grid=25, n_modes=8, campbell_grid=cb)
    assert fresh.size >= 1
    tol = 2 * (1e-9 + 1e-12) * fresh
    assert reused.shape == fresh.shape and np.all(np.abs(reused - fresh) <= tol)
    other = campbell(model, np.linspace(50.0, 900.0, 24), lambda s: co, 8)      # another grid: not reused
    again = critical_speeds(model, lambda s: co, (50.0, 900.0), n_grid=25, n_modes=8, campbell_grid=other)
    assert again.shape == fresh.shape and np.all(np.abs(again - fresh) <= tol)


def test_critical_speed_matches_unbalance_peak(model):
    # light, isotropic bearings: the 1X response peaks at the forward critical speed
    co = {2: (np.diag([2e5, 2e5]), np.diag([5.0, 5.0])), 10: (np.diag([2e5, 2e5]), np.diag([5.0, 5.0]))}
    crit = critical_speeds(model, lambda s: co, (50.0, 900.0), n_grid=25)
    assert crit.size >= 1
    c1 = crit[0]
    speeds = np.linspace(0.8 * c1, 1.2 * c1, 801)
    amp = []
    for W in speeds:
        F = np.zeros(model.ndof, complex)
        fx, fy = unbalance_phasors(1e-5, 0.0, W)
        F[dof_index(8, 'x')], F[dof_index(8, 'y')] = fx, fy
        q = harmonic_response(model, W, W, F, co)
        amp.append(abs(q[dof_index(6, 'x')]))
    peak = speeds[int(np.argmax(amp))]
    # the response peak of a mode with damping ratio zeta lies within ~zeta^2 of its 1X crossing (zeta = 0.03 here:
    # 9e-4), plus half the grid step (0.4 c1 / 800 / 2 = 2.5e-4 c1)
    assert peak == pytest.approx(c1, rel=2e-3)
    # the crossing really is on the 1X line: forward frequency there equals the speed
    m = damped_modes(model, c1, co, 4)
    fw = [f for f, w in zip(m.frequency, m.whirl) if w == 'forward']
    assert min(abs(np.array(fw) - c1)) < 1e-6 * c1


def test_campbell_shapes(model):
    cb = campbell(model, np.array([100.0, 300.0]), lambda s: ANISO, 4)
    assert cb.frequency.shape == (2, 4) and cb.whirl.shape == (2, 4)
    assert set(cb.whirl.ravel()) <= {'forward', 'backward'}


def test_probe_matrix_and_dynamic_stiffness(rig, model):
    S = probe_matrix(model, rig.probes)
    assert S.shape == (2, 44)
    assert S[0, dof_index(6, 'x')] == 1 and S[1, dof_index(6, 'y')] == 1 and S.sum() == 2
    W = 300.0
    Z = dynamic_stiffness(model, W, W, ANISO)
    i = dof_index(2, 'x')
    terms = [model.K[i, i + 1], ANISO[2][0][0, 1], -W**2 * model.M[i, i + 1],
             1j * W * model.C[i, i + 1], 1j * W * ANISO[2][1][0, 1], 1j * W * W * model.G[i, i + 1]]
    assert abs(Z[i, i + 1] - sum(terms)) <= 4 * sum_tol(terms)       # the package's sum and this one, products too


def test_disc_element():
    d = DiscElement(2.0, 0.01, 0.02)
    assert np.allclose(d.M(), np.diag([2.0, 2.0, 0.01, 0.01]))
    assert d.G()[2, 3] == 0.02 and d.G()[3, 2] == -0.02
