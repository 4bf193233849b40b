"""
Build the machine (:class:`.rig.RigParams`) from a validated parameter file (:class:`.schema.RigFile`).

Here is checked what needs the whole file, each problem a ParamError naming the field: nodes against the shaft,
material names, one truth factor per identified bearing, a bearing to identify and no two on one node.  Defaults
from elsewhere in the file are filled in: a section's material (the shaft's), a layer's or added mass's bore (its
host's diameter), a disc's bore (the shaft's diameter at its node) and density (the shaft's), a bearing's load
direction (against gravity), names and run ids.  SI units.
"""
from __future__ import annotations

import math

from .errors import ParamError, short
from .rig import (AddedMass, Bearing, BearingTable, Disc, ElementSpec, ExcitationEntry, Layer, Material, ModalTest,
                  PointMass, Probe, RigParams, Run, Shaft, Simulation, Support, Truth)
from .schema import RigFile, TABLE_COEFFS
from ..conventions import GRAVITY, parse_probe_direction, probe_direction

#: a table bearing's absent geometry: one shared NaN object, so that RigParams from equal files compare equal
NOT_GIVEN = float('nan')


def node(v: int, where: str, n_nodes: int) -> int:
    """Return ``v`` if it is a node of the shaft (1 ... ``n_nodes``)."""
    if v > n_nodes:
        raise ParamError(f'{where}.node = {v} is not a node of the shaft (1 to {n_nodes})')
    return v


def elastic(f, where: str, materials: dict, default=None) -> tuple:
    """Return (E, G, density, material name) of an element or a layer: given inline or a named material."""
    if f.given('E', 'G', 'nu', 'density'):
        return f.E, f.G, f.density, ''
    name = f.material if f.material is not None else default
    if name is None:
        raise ParamError(f'{where}.material is missing (a name from materials:, or E/G/nu/density inline)')
    if name not in materials:
        raise ParamError(f'{where}.material = {short(name)} is not one of the materials {sorted(materials)}')
    m = materials[name]
    return m.youngs_modulus, m.shear_modulus, m.density, name


def elements(f, where: str, materials: dict, default_material) -> list:
    """Return the ElementSpec of a v2 section (``n_elements`` alike) or element."""
    E, G, rho, name = elastic(f, where, materials, default_material)
    od = f.outer_diameter
    added = []
    for k, a in enumerate(f.added_mass or ()):
        if a.material is not None and a.material not in materials:
            raise ParamError(f'{where}.added_mass[{k}].material = {short(a.material)} is not one of '
                             f'{sorted(materials)}')
        added.append(AddedMass(a.outer_diameter, od if a.inner_diameter is None else a.inner_diameter,
                               a.density if a.material is None else materials[a.material].density))
    layers = []
    for k, la in enumerate(f.layers or ()):
        if la.inner_diameter is None and od >= la.outer_diameter:
            raise ParamError(f"{where}.layers[{k}].inner_diameter = {od!r} m (the host's diameter) must be "
                             f'smaller than outer_diameter = {la.outer_diameter!r} m')
        layers.append(Layer(la.outer_diameter, od if la.inner_diameter is None else la.inner_diameter,
                            *elastic(la, f'{where}.layers[{k}]', materials), la.shear_coefficient))
    n = getattr(f, 'n_elements', 1)
    return [ElementSpec(f.length / n, od, f.inner_diameter, E, G, rho, tuple(added), name, tuple(layers),
                        f.shear_coefficient)] * n


def shaft(f, materials: dict) -> Shaft:
    """Return a uniform (v1) shaft, or a v2 shaft of elements (density and modulus scaled by references of 1)."""
    damping = {'damping_alpha': f.damping_alpha, 'damping_beta': f.damping_beta,
               'shear_coefficient': f.shear_coefficient}
    key = 'sections' if f.sections is not None else 'elements' if f.elements is not None else None
    if key is None:
        n = f.n_elements
        return Shaft(length=f.length, diameter=f.diameter, inner_diameter=f.inner_diameter, n_elements=n,
                     element_lengths=tuple(f.element_lengths or (f.length / n,) * n), density=f.density,
                     youngs_modulus=f.youngs_modulus, poisson_ratio=f.poisson_ratio, **damping)
    els = [e for i, s in enumerate(getattr(f, key)) for e in elements(s, f'shaft.{key}[{i}]', materials, f.material)]
    e0 = els[0]
    return Shaft(length=sum(e.length for e in els), diameter=max(e.outer_diameter for e in els),
                 inner_diameter=min(e.inner_diameter for e in els), n_elements=len(els),
                 element_lengths=tuple(e.length for e in els), density=e0.density,
                 youngs_modulus=e0.youngs_modulus, poisson_ratio=e0.youngs_modulus / (2 * e0.shear_modulus) - 1,
                 elements=tuple(els), reference_density=e0.density, reference_modulus=e0.youngs_modulus, **damping)


def bearing(f, where: str, n_nodes: int, name: str, gravity: tuple) -> Bearing:
    """Return a bearing or a seal; its load direction is a load vector's, else against gravity (None: -y)."""
    load, direction = f.load, None
    if isinstance(load, tuple):
        load = math.hypot(*f.load)
        direction = (f.load[0] / load, f.load[1] / load)
    if direction is None and tuple(gravity) != (0.0, -GRAVITY):
        direction = (-gravity[0] / math.hypot(*gravity), -gravity[1] / math.hypot(*gravity))
    s, t = f.support, f.table
    if t is not None:
        c = {k: getattr(t, k) or (0.0,) * len(t.speeds()) for k in TABLE_COEFFS}
        t = BearingTable(speeds=tuple(t.speeds()),
                         K=tuple(((a, b), (c_, d)) for a, b, c_, d in zip(c['kxx'], c['kxy'], c['kyx'], c['kyy'])),
                         C=tuple(((a, b), (c_, d)) for a, b, c_, d in zip(c['cxx'], c['cxy'], c['cyx'], c['cyy'])),
                         interpolation=t.interpolation)
    geo = {k: NOT_GIVEN if getattr(f, k) is None else getattr(f, k)
           for k in ('diameter', 'length', 'clearance', 'viscosity')}
    return Bearing(name=name if f.name is None else f.name, node=node(f.node, where, n_nodes), **geo, load=load,
                   model=f.kind, identify=f.identify, cavitation=f.cavitation, load_direction=direction,
                   support=None if s is None else Support(mass=s.mass, stiffness=s.stiffness, damping=s.damping),
                   table=t)


def probe(f, where: str, n_nodes: int, name: str) -> Probe:
    """Return a probe; its direction text carries the angle and the gain (conventions.probe_direction)."""
    angle, gain = (f.angle_deg, 1.0) if f.angle_deg is not None else parse_probe_direction(f.direction)
    return Probe(name=name if f.name is None else f.name, node=node(f.node, where, n_nodes),
                 direction=probe_direction(angle, f.gain * gain))


def simulation(f, n_nodes: int, n_bearings: int) -> Simulation:
    """Return the simulated rig; the truth has one factor per identified bearing (viscosity, clearance: 1)."""
    def per_bearing(key, default):
        v = getattr(f.truth, key)
        if v is not None and len(v) != n_bearings:
            raise ParamError(f'simulation.truth.{key} must be a list with one factor per identified bearing '
                             f'({n_bearings}), got {short(list(v))}')
        return default if v is None else v

    truth = Truth(f.truth.bearing_model, per_bearing('viscosity_factor', (1.0,) * n_bearings),
                  per_bearing('clearance_factor', (1.0,) * n_bearings), per_bearing('k_factor', ()),
                  per_bearing('c_factor', ()))
    runs = []
    for j, r in enumerate(f.runs):
        ex = []
        for k, e in enumerate(r.excitation):
            phase = e.phase if e.phase is not None else math.radians(e.phase_deg if e.phase_deg is not None else 0.0)
            ex.append(ExcitationEntry(e.kind, node(e.node, f'simulation.runs[{j}].excitation[{k}]', n_nodes),
                                      e.magnitude, phase, e.direction, e.frequency_ratio))
        runs.append(Run(id=chr(ord('A') + j % 26) if r.run_id is None else r.run_id, excitation=tuple(ex)))
    return Simulation(f.sample_rate, f.block_size, f.speeds_rpm, f.dwell, f.ramp, f.noise, f.seed, truth, tuple(runs))


def rig(f: RigFile) -> RigParams:
    """Return the machine of a validated parameter file."""
    materials = {name: Material(name, m.E, m.G, m.density) for name, m in (f.materials or {}).items()}
    sh = shaft(f.shaft, materials)
    nn = sh.n_nodes
    gravity = f.gravity if f.gravity is not None else (0.0, -GRAVITY)
    discs = []
    for i, d in enumerate(f.discs or ()):
        n = node(d.node, f'discs[{i}]', nn)
        if d.mass is not None:
            discs.append(Disc(n, 0.0, 0.0, 0.0, 0.0, d.mass_factor, d.mass, d.Ip, d.Id))
            continue
        bore = sh.diameter if not sh.elements else max(e.outer_diameter for e in sh.elements[max(0, n - 2):n])
        discs.append(Disc(n, d.outer_diameter, bore if d.inner_diameter is None else d.inner_diameter, d.thickness,
                          sh.density if d.density is None else d.density, d.mass_factor))
    every = [bearing(b, f'bearings[{i}]', nn, f'bearing{i + 1}', gravity) for i, b in enumerate(f.bearings)]
    bearings = tuple(b for b in every if b.identify)
    if not every:
        raise ParamError('rig.bearings is empty (a rotor needs its bearings)')
    if not bearings:
        raise ParamError('rig.bearings: no bearing to identify (every one has identify: false)')
    if len({b.node for b in bearings}) != len(bearings):
        raise ParamError('bearings: two identified bearings on one node')
    mt = f.modal_test
    return RigParams(
        name='rig' if f.name is None else f.name, shaft=sh, discs=tuple(discs), bearings=bearings,
        probes=tuple(probe(p, f'probes[{i}]', nn, f'probe{i}') for i, p in enumerate(f.probes or ())),
        simulation=None if f.simulation is None else simulation(f.simulation, nn, len(bearings)),
        modal_test=None if mt is None else ModalTest(mt.measured_hz or (), mt.paper_initial_hz or (),
                                                     mt.paper_updated_hz or ()),
        extra=dict(f.extra or {}),
        point_masses=tuple(PointMass(node(p.node, f'point_masses[{i}]', nn), p.mass, p.Ip, p.Id)
                           for i, p in enumerate(f.point_masses or ())),
        known_bearings=tuple(b for b in every if not b.identify),
        seals=tuple(bearing(s, f'seals[{i}]', nn, f'seal{i + 1}', gravity) for i, s in enumerate(f.seals or ())),
        gravity=tuple(gravity), materials=tuple(materials.values()))
