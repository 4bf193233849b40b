"""
The oil viscosity-temperature law (bearing_id/bearings/viscosity.py) against published numbers and its own inverse.

Published numbers: Shell's technical data sheets of two ISO VG hydraulic oils give the kinematic viscosity at 0, 40
and 100 degC; the Walther relation through the 40 and 100 degC values must give the 0 degC value within what the
sheets' rounding allows (the last printed digit: +-0.5 of it for each of the three numbers, propagated through the
relation by evaluating it at the corners of the rounding box: the relation is monotonic in both references).
"""
from __future__ import annotations

import itertools

from bearing_id.bearings.viscosity import (celsius, CST, density, dln_mu_dT, dynamic, kinematic, Oil,
                                           temperature_for_dynamic, temperature_for_kinematic)
from error_bounds import EPS_MACH, P_N, richardson_check
import numpy as np
import pytest

# (name, nu at 40 degC [cSt], its half rounding unit, nu at 100 degC [cSt], half unit, nu at 0 degC [cSt], half unit,
#  density at 15 degC [kg/m^3]) -- typical values from Shell's technical data sheets:
# Shell Tellus S2 M 32 TDS (https://perma-tec.com/_Resources/Lubricants/Shell/Shell_Tellus_S2_M_32_TDS_de.pdf):
#   0 degC 338 mm^2/s, 40 degC 32, 100 degC 5.4, density at 15 degC 875 kg/m^3;
# Shell Tellus S2 M 46 TDS (Shell LiveDocs): 0 degC 580 mm^2/s, 40 degC 46, 100 degC 6.8, 879 kg/m^3.
# "580" may be rounded to tens: its half unit is taken as 5.
DATASHEETS = [
    ('Tellus S2 M 32', 32.0, 0.5, 5.4, 0.05, 338.0, 0.5, 875.0),
    ('Tellus S2 M 46', 46.0, 0.5, 6.8, 0.05, 580.0, 5.0, 879.0),
]


def _oil(nu40, nu100, rho15=875.0):
    return Oil(nu40 * CST, float(celsius(40.0)), nu100 * CST, float(celsius(100.0)), rho15)


def _eval_abs_err_ln_nu(oil, T):
    """
    Bound on the absolute rounding error of ln(nu(T)) as evaluated (derived in the module's notation).

    W = A - B log10 T is off by ~eps (|A| + |B log10 T|); L = 10^W then by ln10 L dW, Z = 10^L relatively by
    ln10 dL = ln10^2 L dW, and nu_cSt = Z - 0.7 relatively by Z / nu_cSt times that.  P_N for the few operations.
    """
    A, B = oil.walther
    L = 10.0 ** (A - B * np.log10(T))
    Z = 10.0 ** L
    return P_N * EPS_MACH * (abs(A) + abs(B * np.log10(T))) * np.log(10.0) ** 2 * L * Z / (Z - 0.7) + P_N * EPS_MACH


@pytest.mark.parametrize('name, nu40, d40, nu100, d100, nu0, d0, rho15', DATASHEETS)
def test_walther_gives_the_datasheet_viscosity_at_0C(name, nu40, d40, nu100, d100, nu0, d0, rho15):
    T0 = celsius(0.0)
    got = float(kinematic(_oil(nu40, nu100, rho15), T0)) / CST
    corners = [float(kinematic(_oil(nu40 + s1 * d40, nu100 + s2 * d100), T0)) / CST
               for s1, s2 in itertools.product((-1, 1), (-1, 1))]
    tol = max(abs(c - got) for c in corners) + d0
    print(f'{name}: Walther {got:.1f} cSt at 0 degC, datasheet {nu0}, allowed +-{tol:.1f} (rounding)')
    assert abs(got - nu0) <= tol, (name, got, nu0, tol)
    # and a relation with a wrong slope would not pass: constant-B check at a third point is not a tautology
    assert abs(float(kinematic(_oil(nu40, nu100 * 1.1), T0)) / CST - nu0) > tol


def test_references_are_reproduced_and_shapes_broadcast():
    oil = _oil(32.0, 5.4)
    T = celsius(np.array([[40.0, 100.0]]))
    nu = kinematic(oil, T)
    assert nu.shape == (1, 2)
    assert np.allclose(nu[0] / CST, [32.0, 5.4], rtol=1e-12, atol=0)
    assert float(density(oil, celsius(15.0))) == 875.0
    assert np.isclose(float(dynamic(oil, celsius(40.0))), 32e-6 * (875.0 - 0.65 * 25.0), rtol=1e-12)
    assert np.ndim(kinematic(oil, 300.0)) == 0


def test_inverses_round_trip_within_the_evaluation_error():
    oil = _oil(32.0, 5.4)
    T = celsius(np.linspace(0.0, 120.0, 25))
    slope = np.abs(dln_mu_dT(oil, T))
    err_ln = _eval_abs_err_ln_nu(oil, T)
    # forward then inverse: each off by the evaluation error of ln nu, mapped to T by the slope; plus Newton's stop
    tol = 2 * err_ln / slope + 2 * 1e-13 * T
    back_k = temperature_for_kinematic(oil, kinematic(oil, T))
    back_d = temperature_for_dynamic(oil, dynamic(oil, T))
    print(f'round trip: kinematic max {np.abs(back_k - T).max():.2e} K, dynamic {np.abs(back_d - T).max():.2e} K, '
          f'allowed {tol.min():.1e}..{tol.max():.1e} K')
    assert np.all(np.abs(back_k - T) <= tol)
    assert np.all(np.abs(back_d - T) <= tol)


@pytest.mark.parametrize('t_c', [10.0, 45.0, 90.0])
def test_dln_mu_dT_is_the_central_difference(t_c):
    oil = _oil(32.0, 5.4)
    T = float(celsius(t_c))

    def fd(h):
        return (np.log(dynamic(oil, T + h)) - np.log(dynamic(oil, T - h))) / (2 * h)

    err, tol = richardson_check(fd, 0.5, float(dln_mu_dT(oil, T)), acc=float(_eval_abs_err_ln_nu(oil, T)), scale=1.0)
    print(f'{t_c} degC: d ln mu/dT {float(dln_mu_dT(oil, T)):.5f} 1/K, error {err:.1e}, allowed {tol:.1e}')


@pytest.mark.parametrize('kwargs, match', [
    ({'nu1': 32e-6, 'T1': 313.15, 'nu2': 5.4e-6, 'T2': 313.15}, 'different'),
    ({'nu1': 1e-6, 'T1': 313.15, 'nu2': 5.4e-7, 'T2': 373.15}, '2 cSt'),
    ({'nu1': 5.4e-6, 'T1': 313.15, 'nu2': 32e-6, 'T2': 373.15}, 'fall'),
])
def test_bad_references_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Oil(rho_ref=875.0, **kwargs)


def test_bad_temperatures_and_viscosities_are_refused():
    oil = _oil(32.0, 5.4)
    with pytest.raises(ValueError, match='> 0 K'):
        kinematic(oil, -1.0)
    with pytest.raises(ValueError, match='2 cSt'):
        temperature_for_kinematic(oil, 1e-7)
    with pytest.raises(ValueError, match='> 0 Pa s'):
        temperature_for_dynamic(oil, 0.0)
