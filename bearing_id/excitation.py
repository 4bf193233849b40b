"""
Known excitation (unbalance masses, directional shakers) as force phasors on the FE degrees of freedom.

Conventions (see :mod:`bearing_id.conventions`): f(t) = Re{F exp(j r phi(t))} with phi the keyphasor rotor angle and
r the frequency ratio (excitation frequency / rotor speed).  An unbalance is always synchronous (r = 1) and its force
grows with speed^2; a shaker force has a fixed amplitude in N.
"""
from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from .config.params import ExcitationEntry
from .conventions import dof_index, DOF_PER_NODE, force_phasors, unbalance_phasors


def harmonic_forces(entries: Iterable[ExcitationEntry], speed: float, n_nodes: int,
                    ndof: int | None = None) -> dict[float, np.ndarray]:
    """
    Force phasors per frequency ratio.

    Parameters
    ----------
    entries
        excitation entries (params.ExcitationEntry); node numbers 1-based.
    speed
        rotor speed [rad/s].
    n_nodes
        number of FE nodes (4 n_nodes rotor DOFs).
    ndof
        length of the force vectors (default 4 n_nodes; a model with pedestal DOFs passes ``model.ndof``).

    Returns
    -------
    dict mapping frequency ratio r -> complex force vector (ndof,) [N] at frequency r * speed [rad/s].

    """
    out: dict[float, np.ndarray] = {}
    for e in entries:
        if e.kind == 'unbalance':
            if e.frequency_ratio != 1.0:
                raise ValueError('an unbalance is synchronous: frequency_ratio must be 1')
            fx, fy = unbalance_phasors(e.magnitude, e.phase, speed)
        elif e.kind == 'force':
            fx, fy = force_phasors(e.magnitude, e.phase, e.direction)
        else:
            raise ValueError(f'unknown excitation kind {e.kind!r}')
        r = float(e.frequency_ratio)
        f = out.setdefault(r, np.zeros(ndof or DOF_PER_NODE * n_nodes, dtype=complex))
        f[dof_index(e.node, 'x', n_nodes)] += fx
        f[dof_index(e.node, 'y', n_nodes)] += fy
    return out
