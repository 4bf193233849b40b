"""
Write a machine (:class:`.rig.RigParams`) back as the parameter-file mapping (schema v2, SI numbers).

``parse_rig(rig_to_dict(rig)) == rig``: every float is written as it is (YAML keeps a float's repr), so the round
trip is exact.  ``diagnose`` writes its augmented model this way.
"""
from __future__ import annotations

from dataclasses import asdict
import math

from .rig import RigParams
from ..conventions import GRAVITY


def _plain(x):
    """Return ``x`` with every tuple a list (what YAML's safe dumper writes)."""
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    return {k: _plain(v) for k, v in x.items()} if isinstance(x, dict) else x


def rig_to_dict(rig: RigParams) -> dict:
    """
    Return ``rig`` as the YAML mapping :func:`parse_rig` reads back to an equal RigParams (SI numbers, schema v2).

    A v1 (uniform) shaft is written with the v1 keys, a sectioned one as ``elements`` with E, G and density inline;
    known bearings follow the identified ones; tables inline with ``speed`` [rad/s].
    """
    sh = rig.shaft
    shaft: dict = {'damping_alpha': sh.damping_alpha, 'damping_beta': sh.damping_beta,
                   'shear_coefficient': sh.shear_coefficient}
    if sh.elements:
        f_rho = sh.density / sh.reference_density
        f_e = sh.youngs_modulus / sh.reference_modulus
        mats = {m.name: m for m in rig.materials}

        def elastic(e):
            m = mats.get(e.material)
            if m is not None and f_rho == 1.0 and f_e == 1.0 and (m.youngs_modulus, m.shear_modulus, m.density) == (
                    e.youngs_modulus, e.shear_modulus, e.density):
                return {'material': e.material}
            return {'E': e.youngs_modulus * f_e, 'G': e.shear_modulus * f_e, 'density': e.density * f_rho}

        def shear(e):
            return {} if e.shear_coefficient is None else {'shear_coefficient': e.shear_coefficient}

        def element(e):
            out = {'length': e.length, 'outer_diameter': e.outer_diameter, 'inner_diameter': e.inner_diameter,
                   **elastic(e), **shear(e)}
            if e.added_mass:
                out['added_mass'] = _plain([asdict(a) for a in e.added_mass])
            if e.layers:
                out['layers'] = [{'outer_diameter': la.outer_diameter, 'inner_diameter': la.inner_diameter,
                                  **elastic(la), **shear(la)} for la in e.layers]
            return out

        shaft['elements'] = [element(e) for e in sh.elements]
    else:
        shaft.update(length=sh.length, diameter=sh.diameter, inner_diameter=sh.inner_diameter,
                     n_elements=sh.n_elements, element_lengths=list(sh.element_lengths), density=sh.density,
                     youngs_modulus=sh.youngs_modulus, poisson_ratio=sh.poisson_ratio)
    d: dict = {'name': rig.name}
    if rig.materials:
        d['materials'] = {m.name: {'E': m.youngs_modulus, 'G': m.shear_modulus, 'density': m.density}
                          for m in rig.materials}
    d['shaft'] = shaft
    discs = []
    for x in rig.discs:
        if x.given_mass is not None:
            discs.append({'node': x.node, 'mass': x.given_mass, 'Ip': x.given_Ip, 'Id': x.given_Id,
                          'mass_factor': x.mass_factor})
        else:
            discs.append({'node': x.node, 'outer_diameter': x.outer_diameter, 'inner_diameter': x.inner_diameter,
                          'thickness': x.thickness, 'density': x.density, 'mass_factor': x.mass_factor})
    d['discs'] = discs
    if rig.point_masses:
        d['point_masses'] = _plain([asdict(p) for p in rig.point_masses])
    if tuple(rig.gravity) != (0.0, -GRAVITY):
        d['gravity'] = list(rig.gravity)

    def table(t):
        out = {'speed': list(t.speeds)}
        for i, a in enumerate('xy'):
            for j, b in enumerate('xy'):
                out[f'k{a}{b}'] = [float(k[i][j]) for k in t.K]
                out[f'c{a}{b}'] = [float(c[i][j]) for c in t.C]
        if t.interpolation != 'linear':
            out['interpolation'] = t.interpolation
        return out

    def bearing(b, seal=False):
        o: dict = {'name': b.name, 'node': b.node}
        if not seal:
            o['kind'] = b.model
            if not b.identify:
                o['identify'] = False
        for k in ('diameter', 'length', 'clearance', 'viscosity'):
            v = getattr(b, k)
            if v is not None and math.isfinite(v):
                o[k] = v
        if b.model == 'finite':
            o['cavitation'] = b.cavitation
        if b.model != 'table' or b.load is not None:
            g = rig.gravity
            gdir = None if tuple(g) == (0.0, -GRAVITY) else (-g[0] / math.hypot(*g), -g[1] / math.hypot(*g))
            if b.load is not None and b.load_direction is not None and tuple(b.load_direction) != gdir:
                o['load'] = [b.load * b.load_direction[0], b.load * b.load_direction[1]]
            else:
                o['load'] = b.load
        if b.support is not None:
            o['support'] = _plain(asdict(b.support))
        if b.table is not None:
            o['table'] = table(b.table)
        return o

    d['bearings'] = [bearing(b) for b in rig.bearings] + [bearing(b) for b in rig.known_bearings]
    if rig.seals:
        d['seals'] = [bearing(b, seal=True) for b in rig.seals]
    d['probes'] = [asdict(p) for p in rig.probes]
    if rig.modal_test is not None:
        d['modal_test'] = _plain(asdict(rig.modal_test))
    if rig.simulation is not None:        # the keys of Simulation, Truth, Run and ExcitationEntry are the file's
        d['simulation'] = _plain(asdict(rig.simulation))
        d['simulation']['truth'] = {k: v for k, v in d['simulation']['truth'].items() if v != []}
    if rig.extra:
        d['extra'] = dict(rig.extra)
    return d
