"""
The machine a parameter file describes, as small frozen dataclasses (SI units; node numbers 1-based).

:class:`RigParams` is the whole file: the shaft (a uniform v1 shaft, or a v2 shaft of :class:`ElementSpec`), discs,
point masses, the identified bearings, the known bearings and seals (built into the rotor model), the probes, and
optionally the simulated rig and a modal test.  A file becomes one through ``parse_rig`` / ``load_rig``
(:mod:`.params`: validated by :mod:`.schema`, built by :mod:`.build`); code that knows its values makes a probe,
a run or a variant directly (``dataclasses.replace``, :meth:`RigParams.replace`), unvalidated and at no cost.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
import math
from typing import Any

from ..conventions import GRAVITY, parse_probe_direction


@dataclass(frozen=True)
class Material:
    name: str
    youngs_modulus: float         # Pa
    shear_modulus: float          # Pa
    density: float                # kg/m^3


@dataclass(frozen=True)
class AddedMass:
    """A mass-only layer on a shaft element (sleeve, impeller hub): adds mass and inertia, no stiffness."""

    outer_diameter: float         # m
    inner_diameter: float         # m
    density: float                # kg/m^3

    @property
    def mass_per_length(self) -> float:
        return self.density * math.pi / 4 * (self.outer_diameter**2 - self.inner_diameter**2)

    @property
    def inertia_per_length(self) -> float:
        """Rho I [kg m] (diametral second moment of area times density)."""
        return self.density * math.pi / 64 * (self.outer_diameter**4 - self.inner_diameter**4)


@dataclass(frozen=True)
class Layer:
    """
    A concentric full shaft element on the same two nodes as its host element (ROSS's layers: sleeves, hubs).

    It has its own mass, stiffness and gyroscopics and its own shear parameter (from its E, G and shear coefficient);
    same length as the host, and the shaft's rotor damping alpha/beta applies to it as to every shaft element.
    """

    outer_diameter: float         # m
    inner_diameter: float         # m
    youngs_modulus: float         # Pa
    shear_modulus: float          # Pa
    density: float                # kg/m^3
    material: str = ''
    shear_coefficient: Any = None   # 'hutchinson' | 'cowper' | kappa; None = the shaft's shear_coefficient

    @property
    def mass_per_length(self) -> float:
        """Return rho A [kg/m]."""
        return self.density * math.pi / 4 * (self.outer_diameter**2 - self.inner_diameter**2)


@dataclass(frozen=True)
class ElementSpec:
    """One shaft element of a sectioned / element-wise shaft (schema v2)."""

    length: float                 # m
    outer_diameter: float         # m
    inner_diameter: float         # m
    youngs_modulus: float         # Pa
    shear_modulus: float          # Pa
    density: float                # kg/m^3
    added_mass: tuple = ()        # of AddedMass
    material: str = ''
    layers: tuple = ()            # of Layer (full concentric elements on the same nodes)
    shear_coefficient: Any = None   # 'hutchinson' | 'cowper' | kappa; None = the shaft's shear_coefficient

    @property
    def mass(self) -> float:
        a = math.pi / 4 * (self.outer_diameter**2 - self.inner_diameter**2)
        return (self.density * a + sum(m.mass_per_length for m in self.added_mass)
                + sum(la.mass_per_length for la in self.layers)) * self.length


@dataclass(frozen=True)
class Shaft:
    length: float                 # m
    diameter: float               # m (outer)
    inner_diameter: float         # m (0 for solid)
    n_elements: int
    element_lengths: tuple        # m, one per element, sums to length
    density: float                # kg/m^3
    youngs_modulus: float         # Pa
    poisson_ratio: float          # -
    damping_alpha: float = 0.0    # 1/s  (C_rotor = alpha M + beta K)
    damping_beta: float = 0.0     # s
    shear_coefficient: Any = 'hutchinson'   # 'hutchinson' | 'cowper' | a number (kappa)
    elements: tuple = ()          # of ElementSpec (schema v2 sections/elements); () = uniform shaft (v1 keys)
    reference_density: float | None = None   # v2: density / reference_density scales every element (updating)
    reference_modulus: float | None = None   # v2: youngs_modulus / reference_modulus scales every E and G

    @property
    def n_nodes(self) -> int:
        return self.n_elements + 1

    @property
    def node_z(self) -> tuple:
        """Axial position of each node [m], node 1 at z = 0."""
        z = [0.0]
        for le in self.element_lengths:
            z.append(z[-1] + le)
        return tuple(z)

    @property
    def shear_modulus(self) -> float:
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def mass(self) -> float:
        if self.elements:
            return sum(e.mass for e in self.elements) * self.density / self.reference_density
        a = math.pi / 4 * (self.diameter**2 - self.inner_diameter**2)
        return self.density * a * self.length


@dataclass(frozen=True)
class Disc:
    node: int
    outer_diameter: float         # m
    inner_diameter: float         # m
    thickness: float              # m
    density: float                # kg/m^3
    mass_factor: float = 1.0      # model-updating factor on mass and inertias
    given_mass: float | None = None   # kg: a disc given by inertia (schema v2; geometry fields are then 0)
    given_Ip: float | None = None     # kg m^2
    given_Id: float | None = None     # kg m^2

    @property
    def mass(self) -> float:
        """Disc mass [kg]."""
        if self.given_mass is not None:
            return self.mass_factor * self.given_mass
        return self.mass_factor * self.density * math.pi / 4 * (self.outer_diameter**2 - self.inner_diameter**2) \
            * self.thickness

    @property
    def polar_inertia(self) -> float:
        """Polar moment of inertia Ip [kg m^2] (thick annulus)."""
        if self.given_mass is not None:
            return self.mass_factor * self.given_Ip
        return self.mass * (self.outer_diameter**2 + self.inner_diameter**2) / 8.0

    @property
    def diametral_inertia(self) -> float:
        """Diametral moment of inertia Id [kg m^2] about a diameter through the centre (thick annulus)."""
        if self.given_mass is not None:
            return self.mass_factor * self.given_Id
        return self.mass * ((self.outer_diameter**2 + self.inner_diameter**2) / 16.0 + self.thickness**2 / 12.0)


@dataclass(frozen=True)
class PointMass:
    node: int
    mass: float                   # kg
    Ip: float = 0.0               # kg m^2
    Id: float = 0.0               # kg m^2


@dataclass(frozen=True)
class Support:
    """Pedestal in series with a bearing's film: a mass on a spring and damper to ground, per direction (x, y)."""

    mass: tuple                   # (mx, my) kg
    stiffness: tuple              # (kx, ky) N/m
    damping: tuple                # (cx, cy) N s/m


@dataclass(frozen=True)
class BearingTable:
    """K and C (2x2, our frame) vs speed; interpolated between the rows, held flat outside (bearings.table)."""

    speeds: tuple                 # rad/s, increasing
    K: tuple                      # per speed ((kxx, kxy), (kyx, kyy)) N/m
    C: tuple                      # per speed ((cxx, cxy), (cyx, cyy)) N s/m
    interpolation: str = 'linear'     # between the speeds: 'linear' or 'cubic' (not-a-knot spline through the rows)


@dataclass(frozen=True)
class Bearing:
    name: str
    node: int
    diameter: float               # m, journal diameter D
    length: float                 # m, bearing length L
    clearance: float              # m, radial clearance c
    viscosity: float              # Pa s
    load: float | None            # N static load (None = from the rotor's weight, see rotor.static_bearing_loads)
    model: str = 'short'          # the kind: 'short' | 'finite' | 'table'
    identify: bool = True         # False: a known element (not identified), built into the rotor model
    cavitation: str = 'swift_stieber'   # finite only: 'swift_stieber' | 'gumbel'
    load_direction: tuple | None = None  # unit vector of the film force on the journal; None = +y (gravity -y)
    support: Support | None = None       # pedestal in series with the film
    table: BearingTable | None = None    # kind 'table'


@dataclass(frozen=True)
class Probe:
    name: str
    node: int
    direction: str                # 'x' | 'y' | '<angle>deg[*<gain>]' (conventions.probe_direction)

    @property
    def angle_deg(self) -> float:
        """Probe axis [deg] from +x towards +y."""
        return parse_probe_direction(self.direction)[0]

    @property
    def gain(self) -> float:
        return parse_probe_direction(self.direction)[1]


@dataclass(frozen=True)
class ExcitationEntry:
    kind: str                     # 'unbalance' | 'force'
    node: int
    magnitude: float              # kg m (unbalance) or N (force)
    phase: float                  # rad, relative to the keyphasor
    direction: str                # 'forward' (unbalance) | 'x' | 'y' (force)
    frequency_ratio: float = 1.0  # excitation frequency / rotor speed


@dataclass(frozen=True)
class Run:
    id: str  # noqa: A003  (the run id: public field used by the messages, params files and every caller)
    excitation: tuple             # of ExcitationEntry


@dataclass(frozen=True)
class Truth:
    bearing_model: str            # 'short' | 'finite' (applies to short/finite bearings; a table stays a table)
    viscosity_factor: tuple       # per bearing, true / nominal
    clearance_factor: tuple       # per bearing, true / nominal
    k_factor: tuple = ()          # per bearing, true / nominal scale of a table bearing's K (() = all 1)
    c_factor: tuple = ()          # per bearing, true / nominal scale of a table bearing's C


@dataclass(frozen=True)
class Simulation:
    sample_rate: float            # Hz
    block_size: int
    speeds_rpm: tuple
    dwell: float                  # s
    ramp: float                   # s, linear ramp between dwell speeds (0 = instant steps)
    noise: float                  # fraction of channel RMS
    seed: int
    truth: Truth
    runs: tuple                   # of Run


@dataclass(frozen=True)
class ModalTest:
    measured_hz: tuple
    paper_initial_hz: tuple = ()
    paper_updated_hz: tuple = ()


@dataclass(frozen=True)
class RigParams:
    name: str
    shaft: Shaft
    discs: tuple
    bearings: tuple
    probes: tuple
    simulation: Simulation | None = None
    modal_test: ModalTest | None = None
    extra: dict = field(default_factory=dict, compare=False)   # augmentations written by diagnose
    point_masses: tuple = ()      # of PointMass
    known_bearings: tuple = ()    # of Bearing with identify = False (known supports, in the rotor model)
    seals: tuple = ()             # of Bearing (kind 'table', never identified; in the rotor model)
    gravity: tuple = (0.0, -GRAVITY)   # m/s^2 in (x, y)
    materials: tuple = ()         # of Material (for reference; elements carry their values)

    def replace(self, **kw) -> 'RigParams':
        return dataclasses.replace(self, **kw)

    def bearing_nodes(self) -> tuple:
        """Nodes of the identified bearings (``bearings``), 1-based."""
        return tuple(b.node for b in self.bearings)

    def known_elements(self) -> tuple:
        """Known (not identified) bearings and seals: built into the rotor model at each speed."""
        return tuple(self.known_bearings) + tuple(self.seals)

    def support_nodes(self) -> tuple:
        """Nodes of every bearing (identified and known) that carries the rotor in statics."""
        return tuple(b.node for b in self.bearings) + tuple(b.node for b in self.known_bearings)
