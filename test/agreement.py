"""
How two numerical routes to one quantity must agree in these tests (issue 21): never bit for bit.

* A quantity with a stated 1-sigma (a 1X vector and its ``X_std``, a coefficient and its ``K_std``): within
  :data:`SIGMA_FRACTION` = 0.01 of that 1-sigma.
* A stated 1-sigma itself: relative :data:`STD_RTOL` = 1e-4.  A 1-sigma estimated from residuals is known only to
  about 1/sqrt(2 dof) of itself (>= 1 % for the <= 5,000 degrees of freedom of a window or a fit here); 0.01 of that
  is 1e-4.
* A value without a stated 1-sigma (a coefficient the data do not determine: prior-dominated, NaN std): relative
  ``EPS_COND_FACTOR * eps * condition`` -- a backward-stable least-squares solve of condition ``condition`` moves
  its solution by about eps * condition relative under a relative perturbation of eps of its inputs, and the two
  routes' inputs (the same windows' 1X vectors) differ by rounding of at most ``EPS_COND_FACTOR`` eps.
* A speed [rad/s]: relative :data:`SPEED_RTOL` = 0.01 x the identifier's speed-matching tolerance (0.5 %).
"""
from __future__ import annotations

import numpy as np

SIGMA_FRACTION = 0.01
STD_RTOL = 1e-4
EPS_COND_FACTOR = 1e3
SPEED_RTOL = 0.01 * 0.005


def assert_within_sigma(got, want, sigma, what: str = '') -> None:
    """``|got - want| <= 0.01 sigma`` element by element (complex by modulus); NaN in both places passes."""
    got, want = np.asarray(got), np.asarray(want)
    sigma = np.broadcast_to(np.asarray(sigma, dtype=float), want.shape)
    both_nan = np.isnan(np.abs(got)) & np.isnan(np.abs(want))
    bad = ~both_nan & ~(np.abs(got - want) <= SIGMA_FRACTION * sigma)
    assert not bad.any(), (f'{what}: {int(bad.sum())} of {bad.size} values differ by more than {SIGMA_FRACTION} '
                           f'sigma; worst {np.nanmax(np.abs(got - want)[bad] / sigma[bad]):.3g} sigma')


def assert_std_agree(got, want, what: str = '') -> None:
    """Two stated 1-sigmas agree to :data:`STD_RTOL` relative (NaN in both places passes)."""
    np.testing.assert_allclose(np.asarray(got, dtype=float), np.asarray(want, dtype=float), rtol=STD_RTOL, atol=0,
                               equal_nan=True, err_msg=what)


def assert_speeds_agree(got, want, what: str = '') -> None:
    """Speeds [rad/s] agree to :data:`SPEED_RTOL` relative."""
    np.testing.assert_allclose(np.asarray(got, dtype=float), np.asarray(want, dtype=float), rtol=SPEED_RTOL, atol=0,
                               err_msg=what)


def assert_coefficients_agree(got, want, std, condition: float, what: str = '') -> None:
    """
    Coefficient values of two routes: within 0.01 of ``std`` where it is finite (determined).

    Where it is NaN (not determined by the data), to ``EPS_COND_FACTOR * eps * condition`` relative (module doc).
    """
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    std = np.broadcast_to(np.asarray(std, dtype=float), want.shape)
    det = np.isfinite(std)
    assert_within_sigma(got[det], want[det], std[det], what)
    rtol = EPS_COND_FACTOR * np.finfo(float).eps * max(float(condition), 1.0)
    np.testing.assert_allclose(got[~det], want[~det], rtol=rtol, atol=0, err_msg=f'{what} (undetermined)')


def assert_results_agree(live, ref, what: str = '') -> None:
    """Two lists of IdentResult at the same speeds: values, 1-sigma, determined flags, rank and flags."""
    assert len(live) == len(ref), (what, len(live), len(ref))
    assert_speeds_agree([r.speed for r in live], [r.speed for r in ref], what)
    for a, b in zip(live, ref):
        where = f'{what} at {b.speed_rpm:.0f} rpm'
        for sym in ('K', 'C'):
            assert_coefficients_agree(getattr(a, sym), getattr(b, sym), getattr(b, sym + '_std'), b.condition,
                                      f'{where}: {sym}')
            assert_std_agree(getattr(a, sym + '_std'), getattr(b, sym + '_std'), f'{where}: {sym}_std')
            assert np.array_equal(getattr(a, sym + '_determined'), getattr(b, sym + '_determined')), where
        assert (a.rank, a.flags) == (b.rank, b.flags), where


def floats(v) -> np.ndarray:
    """Return an array of floats from JSON values (None, what the JSON writes for NaN or an unprinted value, as NaN)."""
    return np.array([[np.nan if x is None else x for x in row] for row in v] if np.ndim(v) == 2 else
                    [np.nan if x is None else x for x in v], dtype=float)


def by_speed(live: dict, speeds) -> list:
    """Return ``live[s]`` for each reference speed: the one key within :data:`SPEED_RTOL` of it (exactly one)."""
    keys = np.array(sorted(live), dtype=float)
    assert len(keys) == len(speeds), (sorted(live), list(speeds))
    out = []
    for w in speeds:
        near = [k for k in keys if abs(k - w) <= SPEED_RTOL * abs(w)]
        assert len(near) == 1, (w, sorted(live))
        out.append(live[near[0]])
    return out
