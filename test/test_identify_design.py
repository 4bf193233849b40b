"""Experiment-design check (identify/design.py): ranks per speed, the analytic Jacobian, and the advice."""
from bearing_id.config.params import ExcitationEntry, load_rig, Probe, Run
from bearing_id.conventions import rpm_to_rad_s
from bearing_id.excitation import harmonic_forces
from bearing_id.identify.design import analyse, check_design, coefficient_jacobian
from bearing_id.rotor.assembly import dynamic_stiffness, harmonic_response, probe_matrix, RotorModel
from bearing_id.simulation.rig import scenario
from error_bounds import richardson_check, solve_tol
import numpy as np
import pytest


def bearing_fn(w):
    K = np.array([[2.5e5, 1.5e5], [-0.75e5, 3.75e5]]) * (1 + w / 300)
    C = np.array([[375.0, 75.0], [75.0, 625.0]])
    return {2: (K, C), 10: (1.1 * K, 0.9 * C)}


SPEEDS = [float(rpm_to_rad_s(s)) for s in (900, 1800, 2700)]


@pytest.fixture(scope='module')
def setup():
    rig = load_rig()
    return rig, RotorModel.from_params(rig)


def unbalance_runs(rig):
    # the rig's runs A, B plus the paper's Table 3 and Table 4 unbalances and one more distribution
    extra = Run('U', (ExcitationEntry('unbalance', 4, 3e-5, 2.0, 'forward'),
                      ExcitationEntry('unbalance', 8, 1e-5, -1.0, 'forward')))
    return list(rig.simulation.runs) + scenario('paper_table3') + scenario('paper_table4') + [extra]


def test_unbalance_with_midspan_probe_is_rank_8_of_16_however_many_runs(setup):
    rig, model = setup
    for runs in (list(rig.simulation.runs), unbalance_runs(rig)):
        for rep in check_design(model, rig.probes, runs, SPEEDS, bearing_fn, advice=False):
            assert rep.data.unknowns == 16
            assert rep.data.structural_rank == 8
            assert rep.data.rank == 8
            assert not rep.data.determined.all()
            assert len(rep.data.undetermined_combinations) == 8


def test_one_unbalance_run_is_rank_4(setup):
    rig, model = setup
    for rep in check_design(model, rig.probes, list(rig.simulation.runs[:1]), SPEEDS, bearing_fn, advice=False):
        assert rep.data.structural_rank == 4   # 2 complex measurements = 4 real numbers


def test_directional_forces_at_the_discs_determine_all_16(setup):
    rig, model = setup
    for rep in check_design(model, rig.probes, scenario('force'), SPEEDS, bearing_fn, advice=False):
        assert rep.data.rank == 16 and rep.data.determined.all()
        assert np.isfinite(rep.data.condition)


def test_probes_near_the_bearings_with_unbalance_structurally_16_but_noise_limited(setup):
    # Probes either side of the bearings lift the structural rank to 16, but the two unbalance runs make nearly the
    # same orbits: at 1 % sample noise over 20480 samples the weakest combination is known only to >= 30 % of the
    # coefficients' size (measured 36 % ... 1400 %), so the noise-based rank stays below 16.
    rig, model = setup
    probes = tuple(Probe(f'p{n}{d}', n, d) for n in (2, 3, 9, 10) for d in ('x', 'y'))
    for rep in check_design(model, probes, list(rig.simulation.runs), SPEEDS, bearing_fn, advice=False):
        assert rep.data.structural_rank == 16
        assert rep.data.rank < 16
        assert 1.0 / rep.data.singular_values[15] > 0.3
        assert rep.methods['conventional'].startswith('rank')       # two probe nodes per bearing: applicable
    # the same probes with the directional-force plan: determined
    for rep in check_design(model, probes, scenario('force'), SPEEDS, bearing_fn, advice=False):
        assert rep.data.rank == 16


def test_advice_reaches_full_rank(setup):
    rig, model = setup
    rep = check_design(model, rig.probes, list(rig.simulation.runs), SPEEDS[1:2], bearing_fn, max_steps=4)[0]
    assert rep.advice, 'an undetermined plan must come with advice'
    assert rep.advice[-1].endswith('rank 16 of 16')


def test_jacobian_matches_finite_differences(setup):
    # independent route: re-solve the forced response with each coefficient perturbed (central differences).
    # Tolerances: X against a dense solve of the same dynamic stiffness, two backward-stable solves' bound of the
    # largest entry (test/error_bounds.py solve_tol); the derivative by Richardson's error estimate plus the solves'
    # rounding over the step (test/error_bounds.py richardson_check).
    rig, model = setup
    w = SPEEDS[1]
    co = bearing_fn(w)
    runs = scenario('force')[:2] + list(rig.simulation.runs[:1])
    forces = [harmonic_forces(r.excitation, w, model.n_nodes)[1.0] for r in runs]
    probes = (Probe('a', 6, 'x'), Probe('b', 3, 'y'))
    J, X = coefficient_jacobian(model, w, co, probes, forces)
    S = probe_matrix(model, probes)

    def meas(c):
        return np.concatenate([S @ harmonic_response(model, w, w, f, c) for f in forces])

    acc = solve_tol(dynamic_stiffness(model, w, w, co))        # one backward-stable solve, relative
    assert np.abs(X - meas(co)).max() <= 2 * acc * np.abs(X).max()
    for k in range(16):
        b, rest = divmod(k % 8, 4)
        node = model.bearing_nodes[b]
        which = 0 if k < 8 else 1
        i, j = divmod(rest, 2)

        def fd(h):
            cp = {n: (K.copy(), C.copy()) for n, (K, C) in co.items()}
            cm = {n: (K.copy(), C.copy()) for n, (K, C) in co.items()}
            cp[node][which][i, j] += h
            cm[node][which][i, j] -= h
            return (meas(cp) - meas(cm)) / (2 * h)

        h = 1e-3 * np.abs(co[node][which]).max()
        col = J[:, k] if which == 0 else J[:, k] * w     # J is per unit of Omega C
        _, tol = richardson_check(fd, h, col, acc, np.abs(X).max())
        assert tol <= 2e-3 * np.abs(col).max()      # the check has teeth: a wrong column is off by O(1)


def test_analyse_on_a_known_matrix():
    # columns 0, 1 measured with unit information, column 2 never: rank 2, third coefficient undetermined
    J = np.array([[100.0, 0, 0], [0, 100.0, 0], [0, 0, 0]])
    a = analyse(J, ['a', 'b', 'c'], max_rel_std=0.05)
    assert a.rank == 2 and a.structural_rank == 2
    assert a.determined.tolist() == [True, True, False]
    np.testing.assert_allclose(a.rel_std[:2], [0.01, 0.01])
    # a direction known only to 10 % is not determined at the 5 % threshold
    a = analyse(np.diag([100.0, 100.0, 10.0]), max_rel_std=0.05)
    assert a.rank == 2 and a.structural_rank == 3
