"""
Build the machine (:class:`.rig.RigParams`) from a validated parameter file (:class:`.schema.RigFile`).

What the schema cannot check alone is checked here, each problem a ParamError naming the field: node numbers
against the shaft's nodes, material names against ``materials``, one truth factor per identified bearing, at least
one bearing to identify and no two on one node.  Defaults that come from elsewhere in the file are filled in: a
section's material from the shaft's, a disc's bore from the shaft's diameter at its node and its density from the
shaft's, a layer's bore from its host's diameter, a bearing's load direction from gravity.  SI units.
"""
from __future__ import annotations

import math

from .errors import ParamError, short
from .rig import (AddedMass, Bearing, BearingTable, Disc, ElementSpec, ExcitationEntry, Layer, Material, ModalTest,
                  PointMass, Probe, RigParams, Run, Shaft, Simulation, Support, Truth)
from .schema import ElementFile, RigFile, ShaftFile, TableFile
from ..conventions import GRAVITY, parse_probe_direction, probe_direction

#: a table bearing's absent geometry (diameter, length, clearance, viscosity): one shared NaN object, so that two
#: RigParams read from equal files compare equal (tuples compare identical objects as equal)
NOT_GIVEN = float('nan')


def node(v: int, where: str, n_nodes: int) -> int:
    """Return ``v`` if it is a node of the shaft (1 ... ``n_nodes``)."""
    if v > n_nodes:
        raise ParamError(f'{where}.node = {v} is not a node of the shaft (1 to {n_nodes})')
    return v


def _material(f, where: str, materials: dict, default=None) -> tuple:
    """Return (E, G, density, material name) of an element or layer: inline values or a named material."""
    if f.inline():
        return f.E, f.G, f.density, ''
    name = f.material if f.material is not None else default
    if name is None:
        raise ParamError(f'{where}.material is missing (a name from materials:, or E/G/nu/density inline)')
    if name not in materials:
        raise ParamError(f'{where}.material = {short(name)} is not one of the materials {sorted(materials)}')
    m = materials[name]
    return m.youngs_modulus, m.shear_modulus, m.density, name


def _elements(f: ElementFile, where: str, materials: dict, default_material) -> list:
    """Return the ElementSpec of one v2 section (``n_elements`` alike) or element."""
    E, G, rho, name = _material(f, where, materials, default_material)
    od = f.outer_diameter
    added = []
    for k, a in enumerate(f.added_mass or ()):
        if a.material is not None and a.material not in materials:
            raise ParamError(f'{where}.added_mass[{k}].material = {short(a.material)} is not one of '
                             f'{sorted(materials)}')
        density = materials[a.material].density if a.material is not None else a.density
        added.append(AddedMass(a.outer_diameter, od if a.inner_diameter is None else a.inner_diameter, density))
    layers = []
    for k, la in enumerate(f.layers or ()):
        wl = f'{where}.layers[{k}]'
        lid = od if la.inner_diameter is None else la.inner_diameter
        if lid >= la.outer_diameter:
            raise ParamError(f'{wl}.inner_diameter = {lid!r} m must be smaller than outer_diameter = '
                             f'{la.outer_diameter!r} m')
        lE, lG, lrho, lname = _material(la, wl, materials)
        layers.append(Layer(la.outer_diameter, lid, lE, lG, lrho, lname, la.shear_coefficient))
    n = getattr(f, 'n_elements', 1)
    return [ElementSpec(f.length / n, od, f.inner_diameter, E, G, rho, tuple(added), name, tuple(layers),
                        f.shear_coefficient)] * n


def shaft(f: ShaftFile, materials: dict) -> Shaft:
    """Return the shaft: uniform (v1) or of elements (v2, E and density scaled by reference values of 1)."""
    damping = {'damping_alpha': f.damping_alpha, 'damping_beta': f.damping_beta,
               'shear_coefficient': f.shear_coefficient}
    key = 'sections' if f.sections is not None else 'elements' if f.elements is not None else None
    if key is None:
        n = f.n_elements
        el = f.element_lengths if f.element_lengths is not None else (f.length / n,) * n
        return Shaft(length=f.length, diameter=f.diameter, inner_diameter=f.inner_diameter, n_elements=n,
                     element_lengths=tuple(el), density=f.density, youngs_modulus=f.youngs_modulus,
                     poisson_ratio=f.poisson_ratio, **damping)
    els = []
    for i, s in enumerate(getattr(f, key)):
        els += _elements(s, f'shaft.{key}[{i}]', materials, f.material)
    e0 = els[0]
    return Shaft(length=sum(e.length for e in els), diameter=max(e.outer_diameter for e in els),
                 inner_diameter=min(e.inner_diameter for e in els), n_elements=len(els),
                 element_lengths=tuple(e.length for e in els), density=e0.density,
                 youngs_modulus=e0.youngs_modulus, poisson_ratio=e0.youngs_modulus / (2 * e0.shear_modulus) - 1,
                 elements=tuple(els), reference_density=e0.density, reference_modulus=e0.youngs_modulus, **damping)


def table(f: TableFile) -> BearingTable:
    """Return a coefficient table: K and C per speed [rad/s], the cross terms 0 where not given."""
    n = len(f.speeds())
    c = {k: getattr(f, k) or (0.0,) * n for k in ('kxx', 'kxy', 'kyx', 'kyy', 'cxx', 'cxy', 'cyx', 'cyy')}
    K = tuple(((c['kxx'][i], c['kxy'][i]), (c['kyx'][i], c['kyy'][i])) for i in range(n))
    C = tuple(((c['cxx'][i], c['cxy'][i]), (c['cyx'][i], c['cyy'][i])) for i in range(n))
    return BearingTable(speeds=tuple(f.speeds()), K=K, C=C)


def bearing(f, where: str, n_nodes: int, default_name: str, gravity: tuple) -> Bearing:
    """Return a bearing or seal; a load vector gives the load and its direction, else gravity gives the direction."""
    load, direction = f.load, None
    if isinstance(load, tuple):
        load = math.hypot(*f.load)
        direction = (f.load[0] / load, f.load[1] / load)
    if direction is None and tuple(gravity) != (0.0, -GRAVITY):
        g = math.hypot(*gravity)
        direction = (-gravity[0] / g, -gravity[1] / g)
    s = f.support
    geo = {k: NOT_GIVEN if getattr(f, k) is None else getattr(f, k)
           for k in ('diameter', 'length', 'clearance', 'viscosity')}
    return Bearing(name=f.name if f.name is not None else default_name, node=node(f.node, where, n_nodes), **geo,
                   load=load, model=f.kind, identify=f.identify, cavitation=f.cavitation, load_direction=direction,
                   support=None if s is None else Support(mass=s.mass, stiffness=s.stiffness, damping=s.damping),
                   table=None if f.table is None else table(f.table))


def probe(f, where: str, n_nodes: int, default_name: str) -> Probe:
    """Return a probe; its direction text carries the angle and the gain (conventions.probe_direction)."""
    if f.angle_deg is not None:
        angle, gain = f.angle_deg, f.gain
    else:
        angle, g0 = parse_probe_direction(f.direction)
        gain = f.gain * g0
    return Probe(name=f.name if f.name is not None else default_name, node=node(f.node, where, n_nodes),
                 direction=probe_direction(angle, gain))


def simulation(f, n_nodes: int, n_bearings: int) -> Simulation:
    """Return the simulated rig; the truth has one factor per identified bearing."""
    def per_bearing(key, default):
        v = getattr(f.truth, key)
        if v is None:
            return default
        if len(v) != n_bearings:
            raise ParamError(f'simulation.truth.{key} must be a list with one factor per identified bearing '
                             f'({n_bearings}), got {short(list(v))}')
        return v

    t = f.truth
    truth = Truth(bearing_model=t.bearing_model, viscosity_factor=per_bearing('viscosity_factor', (1.0,) * n_bearings),
                  clearance_factor=per_bearing('clearance_factor', (1.0,) * n_bearings),
                  k_factor=per_bearing('k_factor', ()), c_factor=per_bearing('c_factor', ()))
    runs = []
    for j, r in enumerate(f.runs):
        ex = []
        for k, e in enumerate(r.excitation):
            phase = e.phase if e.phase is not None else math.radians(e.phase_deg if e.phase_deg is not None else 0.0)
            ex.append(ExcitationEntry(kind=e.kind, node=node(e.node, f'simulation.runs[{j}].excitation[{k}]', n_nodes),
                                      magnitude=e.magnitude, phase=phase, direction=e.direction,
                                      frequency_ratio=e.frequency_ratio))
        runs.append(Run(id=r.run_id if r.run_id is not None else chr(ord('A') + j % 26), excitation=tuple(ex)))
    return Simulation(sample_rate=f.sample_rate, block_size=f.block_size, speeds_rpm=f.speeds_rpm, dwell=f.dwell,
                      ramp=f.ramp, noise=f.noise, seed=f.seed, truth=truth, runs=tuple(runs))


def rig(f: RigFile) -> RigParams:
    """Return the machine of a validated parameter file (ParamError naming the field on a cross-reference)."""
    materials = {name: Material(name, m.E, m.G, m.density) for name, m in (f.materials or {}).items()}
    sh = shaft(f.shaft, materials)
    nn = sh.n_nodes
    gravity = f.gravity if f.gravity is not None else (0.0, -GRAVITY)

    def outer_at(n):
        if not sh.elements:
            return sh.diameter
        return max(e.outer_diameter for e in sh.elements[max(0, n - 2):n])

    discs = []
    for i, d in enumerate(f.discs or ()):
        n = node(d.node, f'discs[{i}]', nn)
        if d.mass is not None:
            discs.append(Disc(node=n, outer_diameter=0.0, inner_diameter=0.0, thickness=0.0, density=0.0,
                              mass_factor=d.mass_factor, given_mass=d.mass, given_Ip=d.Ip, given_Id=d.Id))
        else:
            discs.append(Disc(node=n, outer_diameter=d.outer_diameter,
                              inner_diameter=outer_at(n) if d.inner_diameter is None else d.inner_diameter,
                              thickness=d.thickness, density=sh.density if d.density is None else d.density,
                              mass_factor=d.mass_factor))
    pms = tuple(PointMass(node=node(p.node, f'point_masses[{i}]', nn), mass=p.mass, Ip=p.Ip, Id=p.Id)
                for i, p in enumerate(f.point_masses or ()))
    every = [bearing(b, f'bearings[{i}]', nn, f'bearing{i + 1}', gravity) for i, b in enumerate(f.bearings)]
    bearings = tuple(b for b in every if b.identify)
    if not every:
        raise ParamError('rig.bearings is empty (a rotor needs its bearings)')
    if not bearings:
        raise ParamError('rig.bearings: no bearing to identify (every one has identify: false)')
    if len({b.node for b in bearings}) != len(bearings):
        raise ParamError('bearings: two identified bearings on one node')
    seals = tuple(bearing(s, f'seals[{i}]', nn, f'seal{i + 1}', gravity) for i, s in enumerate(f.seals or ()))
    probes = tuple(probe(p, f'probes[{i}]', nn, f'probe{i}') for i, p in enumerate(f.probes or ()))
    mt = f.modal_test
    return RigParams(
        name=f.name if f.name is not None else 'rig', shaft=sh, discs=tuple(discs), bearings=bearings, probes=probes,
        simulation=None if f.simulation is None else simulation(f.simulation, nn, len(bearings)),
        modal_test=None if mt is None else ModalTest(measured_hz=mt.measured_hz or (),
                                                     paper_initial_hz=mt.paper_initial_hz or (),
                                                     paper_updated_hz=mt.paper_updated_hz or ()),
        extra=dict(f.extra or {}), point_masses=pms, known_bearings=tuple(b for b in every if not b.identify),
        seals=seals, gravity=tuple(gravity), materials=tuple(materials.values()))
