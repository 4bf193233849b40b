"""
The oil's viscosity law as node parameters: one set of ``oil_*`` parameters for sensor_driver and the identifier.

sensor_driver's sim source moves the true viscosity with its oil inlet temperature by this law; the identifier
compares each physical fit's viscosity with it at the measured inlet temperature.  No ROS here.
"""
from __future__ import annotations

from .specs import ParamSpec
from ..bearings.viscosity import Oil

OIL_SPECS = [
    ParamSpec('oil_viscosities', None, "the oil's kinematic viscosity at its two reference temperatures (datasheet, "
              'e.g. ISO VG 32: 32e-6 and 5.4e-6), for the Walther law: the sim source moves the true viscosity with '
              'the oil inlet temperature by it, the identifier compares each physical fit with it at the inlet '
              'temperature (rotor/oil_temperature, sensor_msgs/Temperature); unset: no law', 'm^2/s', lo=2e-6,
              hi=1.0, type_='float[]'),
    ParamSpec('oil_reference_temperatures', [313.15, 373.15], 'the temperatures of oil_viscosities (40 and 100 degC)',
              'K', lo=200.0, hi=600.0, type_='float[]'),
    ParamSpec('oil_density', 870.0, "the oil's density at 15 degC", 'kg/m^3', lo=500.0, hi=1500.0),
]


def oil_law(viscosities, temperatures, density: float):
    """
    Return the oil's viscosity law (:class:`bearing_id.bearings.viscosity.Oil`) from the ``oil_*`` parameters.

    None when ``viscosities`` is unset or empty; ValueError (naming the parameters) when they are not two viscosities
    at two temperatures the Walther relation can pass through.
    """
    if not viscosities:
        return None
    if len(viscosities) != 2 or len(temperatures or ()) != 2:
        raise ValueError(f'oil_viscosities and oil_reference_temperatures need two values each, got '
                         f'{list(viscosities)} and {list(temperatures or ())}')
    try:
        return Oil(nu1=float(viscosities[0]), T1=float(temperatures[0]), nu2=float(viscosities[1]),
                   T2=float(temperatures[1]), rho_ref=float(density))
    except ValueError as exc:
        raise ValueError(f'oil_viscosities / oil_reference_temperatures: {exc}') from None
