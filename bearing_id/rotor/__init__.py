"""
FE rotor model: Nelson (1980) Timoshenko shaft elements, rigid discs, bearings as 2x2 K and C at nodes.

* :mod:`.elements` — ShaftElement, DiscElement (element matrices).
* :mod:`.assembly` — RotorModel.from_params, dynamic stiffness, harmonic response, state space, static bearing loads.
* :mod:`.modal` — damped modes (frequency, log dec, whirl), free-free frequencies, Campbell data, critical speeds.
"""
from .assembly import (bearing_matrices, dynamic_stiffness, harmonic_response, probe_matrix, RotorModel, state_space,
                       static_bearing_loads, system_matrices)
from .elements import DiscElement, ShaftElement

__all__ = ['RotorModel', 'ShaftElement', 'DiscElement', 'dynamic_stiffness', 'harmonic_response', 'state_space',
           'static_bearing_loads', 'probe_matrix', 'bearing_matrices', 'system_matrices']
