"""
The parameter file (``params/rig.yaml``, schema v1 and v2) as pydantic models: keys, types, units, ranges.

One model per mapping of the file; each field says its unit and range (:mod:`.fields`), each model the rules among
its own keys (give material or E/G/nu inline, not both; a disc by mass or by geometry; a table's speeds increase).
What needs the rest of the file -- node numbers against the shaft, material names, defaults taken from the shaft or
from gravity, one truth factor per identified bearing -- is checked where the machine is built
(:mod:`.build`).  A table may come from a CSV file beside the params file (``table: {csv: file}``; the validation
context's ``base_dir``).  SI units; speeds in rpm where the key says so.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Annotated, Any, ClassVar

from pydantic import Field, field_validator, model_validator, ValidationError, ValidationInfo

from .errors import got, problem, short, split
from .fields import Choice, Direction, Flag, Load, Num, Numbers, Pair, Section, Shear, Text

Node = Annotated[int, Num('', 1, None, whole=True)]
Name = Annotated[Any, Text()]
Length = Annotated[float, Num('m', 1e-4, 10)]
Diameter = Annotated[float, Num('m', 0, 10)]       # an inner diameter (0: solid)
Density = Annotated[float, Num('kg/m^3', 100, 30000)]
Modulus = Annotated[float, Num('Pa', 0.0, 1e13, positive=True)]
Poisson = Annotated[float, Num('-', -0.99, 0.5)]
KINDS = ('short', 'finite', 'table')
TABLE_COEFFS = ('kxx', 'kxy', 'kyx', 'kyy', 'cxx', 'cxy', 'cyx', 'cyy')
TABLE_CSV_MAX_BYTES = 1 << 20
MAX_ELEMENTS = 2000            # shaft elements of a v2 shaft (plant models have 30-150)


# ------------------------------------------------------------------------------------------------ materials
class Elastic(Section):
    """E [Pa], G [Pa], Poisson's ratio nu [-] (two of the three) and density [kg/m^3]; E and G filled in."""

    E: Modulus = None
    G: Modulus = None
    nu: Poisson = None
    density: Density = None

    def inline(self) -> list:
        """Return the elastic keys given inline."""
        return self.given('E', 'G', 'nu', 'density')

    def resolve(self) -> None:
        """Check two of E, G, nu and density; fill in E and G (the third from the other two)."""
        have = self.given('E', 'G', 'nu')
        if len(have) != 2:
            raise problem(f' needs density and exactly two of E [Pa], G [Pa], nu [-], got {have or "none"}')
        if self.E is None:
            self.E = 2.0 * self.G * (1.0 + self.nu)
        elif self.G is None:
            self.G = self.E / (2.0 * (1.0 + self.nu))
        nu = self.E / (2.0 * self.G) - 1.0
        if not -0.99 <= nu <= 0.5:
            raise problem(f': E = {self.E!r} Pa and G = {self.G!r} Pa give Poisson ratio {nu:.3g}, outside '
                          f'[-0.99, 0.5]')
        if self.density is None:
            raise self.missing('density')


class MaterialFile(Elastic):
    """A named material (``materials.NAME``)."""

    @model_validator(mode='after')
    def _check(self):
        self.resolve()
        return self


class MaterialOrInline(Elastic):
    """A part made of a named ``material`` or of E/G/nu/density given inline (not both)."""

    material: Name = None

    def check_material(self) -> None:
        if self.inline():
            if self.material is not None:
                raise problem(': give material or E/G/nu/density inline, not both')
            self.resolve()


# ------------------------------------------------------------------------------------------------ shaft
class AddedMassFile(Section):
    """A mass-only layer on an element: diameters [m] and a density [kg/m^3] or a material's."""

    outer_diameter: Length
    inner_diameter: Diameter = None     # default: the host element's outer diameter
    density: Annotated[float, Num('kg/m^3', 1e-3, 30000)] = None
    material: Name = None

    @model_validator(mode='after')
    def _check(self):
        if self.inner_diameter is not None and self.inner_diameter > self.outer_diameter:
            raise problem(f' = {self.inner_diameter!r} [m] is larger than outer_diameter', '.inner_diameter')
        if self.given('density', 'material') == ['density', 'material']:
            raise problem(': give density or material, not both')
        if self.material is None and self.density is None:
            raise self.missing('density', 'or a material')
        return self


class LayerFile(MaterialOrInline):
    """A concentric full element on its host's nodes (a sleeve, a hub): diameters [m], material, shear."""

    outer_diameter: Length
    inner_diameter: Diameter = None     # default: the host element's outer diameter
    shear_coefficient: Annotated[Any, Shear()] = None

    @model_validator(mode='after')
    def _check(self):
        self.check_material()
        return self


class ElementFile(MaterialOrInline):
    """One shaft element of a v2 shaft: length and diameters [m], material, layers, its own shear coefficient."""

    name: Name = None
    length: Annotated[float, Num('m', 1e-5, 100)]
    outer_diameter: Length
    inner_diameter: Diameter = 0.0
    added_mass: list[AddedMassFile] | None = None
    layers: list[LayerFile] | None = None
    shear_coefficient: Annotated[Any, Shear()] = None

    @model_validator(mode='after')
    def _check(self):
        if self.inner_diameter >= self.outer_diameter:
            raise problem(f' = {self.inner_diameter!r} m must be smaller than outer_diameter = '
                          f'{self.outer_diameter!r} m', '.inner_diameter')
        self.check_material()
        return self


class SectionFile(ElementFile):
    """A section of a v2 shaft: ``n_elements`` equal elements alike."""

    n_elements: Annotated[int, Num('', 1, 500, whole=True)] = 1


class ShaftFile(Section):
    """
    The shaft: v1 (uniform: length, diameter, n_elements, E, nu, density) or v2 (``sections`` or ``elements``).

    Rotor damping C = alpha M + beta K (alpha [1/s], beta [s]) and the shear coefficient apply to both.
    """

    damping_alpha: Annotated[float, Num('1/s', 0, 1e4)] = 0.0
    damping_beta: Annotated[float, Num('s', 0, 1)] = 0.0
    shear_coefficient: Annotated[Any, Shear()] = 'hutchinson'
    # v1
    length: Annotated[float, Num('m', 1e-3, 100)] = None
    diameter: Length = None
    inner_diameter: Diameter = 0.0
    n_elements: Annotated[int, Num('', 1, 500, whole=True)] = None
    element_lengths: Annotated[tuple, Numbers('m', 1e-5, 100)] | None = None
    density: Density = None
    youngs_modulus: Annotated[float, Num('Pa', 1e6, 1e13)] = None
    poisson_ratio: Annotated[float, Num('-', 0, 0.5)] = None
    # v2
    sections: list[SectionFile] | None = None
    elements: list[ElementFile] | None = None
    material: Name = None          # the default material of the sections

    COMMON: ClassVar[tuple] = ('damping_alpha', 'damping_beta', 'shear_coefficient')
    V1: ClassVar[tuple] = ('length', 'diameter', 'inner_diameter', 'n_elements', 'element_lengths', 'density',
                           'youngs_modulus', 'poisson_ratio')

    @staticmethod
    def is_v2(d) -> bool:
        return 'sections' in d or 'elements' in d

    @classmethod
    def _keys(cls, d):
        return cls.COMMON + (('sections', 'elements', 'material') if cls.is_v2(d) else cls.V1)

    @classmethod
    def _required(cls, d):
        return () if cls.is_v2(d) else ('length', 'n_elements', 'diameter', 'density', 'youngs_modulus',
                                        'poisson_ratio')

    @model_validator(mode='after')
    def _check(self):
        v2 = self.given('sections', 'elements')
        if len(v2) == 2:
            raise problem(': give sections or elements, not both')
        if v2:
            parts = getattr(self, v2[0])
            if parts is None:
                raise self.missing(v2[0])
            if not parts:
                raise problem(' is empty', f'.{v2[0]}')
            if sum(getattr(p, 'n_elements', 1) for p in parts) > MAX_ELEMENTS:
                raise problem(f': more than {MAX_ELEMENTS} elements', f'.{v2[0]}')
        elif self.element_lengths is not None:
            el, n = self.element_lengths, self.n_elements
            if len(el) != n:
                raise problem(f' must be a list of {n} lengths [m] or null, got {short(list(el))}', '.element_lengths')
            if abs(sum(el) - self.length) > 1e-9 * max(1.0, self.length):
                raise problem(f' sum to {sum(el)!r} m, not shaft.length = {self.length!r} m', '.element_lengths')
        return self


# ------------------------------------------------------------------------------------------------ masses
class DiscFile(Section):
    """A disc by geometry (diameters, thickness [m], density) or by mass [kg], Ip and Id [kg m^2]."""

    name: Name = None
    node: Node
    outer_diameter: Length = None
    inner_diameter: Diameter = None    # default: the shaft's outer diameter at the node
    thickness: Annotated[float, Num('m', 1e-5, 10)] = None
    density: Density = None            # default: the shaft's
    mass_factor: Annotated[float, Num('-', 0.01, 100)] = 1.0
    mass: Annotated[float, Num('kg', 0, 1e6)] = None
    Ip: Annotated[float, Num('kg m^2', 0, 1e6)] = 0.0
    Id: Annotated[float, Num('kg m^2', 0, 1e6)] = 0.0

    @model_validator(mode='after')
    def _check(self):
        if 'mass' in self.model_fields_set:
            geo = self.given('outer_diameter', 'inner_diameter', 'thickness', 'density')
            if geo:
                raise problem(f': give the disc by mass/Ip/Id or by geometry, not both (has {geo})')
            return self
        for k in self.given('Ip', 'Id'):
            raise problem(f': a disc given by geometry has no {k} (give mass, Ip and Id instead)', f'.{k}')
        for k in ('outer_diameter', 'thickness'):
            if getattr(self, k) is None:
                raise self.missing(k, 'or give the mass, Ip and Id')
        if self.inner_diameter is not None and self.inner_diameter > self.outer_diameter:
            raise problem(f' = {self.inner_diameter!r} [m] is larger than outer_diameter', '.inner_diameter')
        return self


class PointMassFile(Section):
    """A point mass [kg] with inertias Ip, Id [kg m^2] on a node."""

    name: Name = None
    node: Node
    mass: Annotated[float, Num('kg', 0, 1e6)]
    Ip: Annotated[float, Num('kg m^2', 0, 1e6)] = 0.0
    Id: Annotated[float, Num('kg m^2', 0, 1e6)] = 0.0


# ------------------------------------------------------------------------------------------------ bearings
class SupportFile(Section):
    """A pedestal in series with the film: mass [kg], stiffness [N/m], damping [N s/m], each one value or [x, y]."""

    mass: Annotated[tuple, Pair('kg', 1e-6, 1e7)]
    stiffness: Annotated[tuple, Pair('N/m', 1.0, 1e13)]
    damping: Annotated[tuple, Pair('N s/m', 0.0, 1e10)] = (0.0, 0.0)


K_COLUMN = Annotated[tuple, Numbers('N/m', -1e13, 1e13)]
C_COLUMN = Annotated[tuple, Numbers('N s/m', -1e13, 1e13)]


class TableFile(Section):
    """
    K [N/m] and C [N s/m] (our frame) per speed: speeds in rpm (``speed_rpm``) or rad/s (``speed``), increasing.

    kxx, kyy, cxx, cyy are required, the cross terms default to 0; or ``{csv: FILE}``, a CSV with a header row naming
    these columns (relative to the params file's folder).
    """

    speed_rpm: Annotated[tuple, Numbers('rpm', 0, 1e7)] = None
    speed: Annotated[tuple, Numbers('rad/s', 0, 1e6)] = None
    kxx: K_COLUMN = None
    kxy: K_COLUMN = None
    kyx: K_COLUMN = None
    kyy: K_COLUMN = None
    cxx: C_COLUMN = None
    cxy: C_COLUMN = None
    cyx: C_COLUMN = None
    cyy: C_COLUMN = None

    @classmethod
    def _prepare(cls, d, info):
        if 'csv' not in d:
            return d
        if len(d) > 1:
            raise problem(': a table from csv has no other key', '.' + next(k for k in d if k != 'csv'))
        cols = read_csv(d['csv'], (info.context or {}).get('base_dir'))
        try:
            return cls.model_validate(cols)
        except ValidationError as exc:
            where, tail = split(exc.errors(include_url=False)[0])
            raise problem(tail, '.csv' + ('.' if where[:1] not in ('', '.', '[') else '') + where) from None

    @model_validator(mode='after')
    def _check(self):
        if (self.speed_rpm is None) == (self.speed is None):
            raise problem(': give speed_rpm [rpm] or speed [rad/s] (one of them)')
        n = len(self.speeds())
        if n < 1:
            raise problem(': the table has no speeds')
        if any(b <= a for a, b in zip(self.speeds(), self.speeds()[1:])):
            raise problem(': speeds must increase strictly')
        for k in TABLE_COEFFS:
            unit = 'N/m' if k[0] == 'k' else 'N s/m'
            v = getattr(self, k)
            if v is None and k[1] == k[2]:
                raise problem(f' is missing ({unit}, one per speed)', f'.{k}')
            if v is not None and len(v) != n:
                raise problem(f' must be a list of {n} values [{unit}] (one per speed), got {short(list(v))}',
                              f'.{k}')
        return self

    def speeds(self) -> tuple:
        """Return the speeds [rad/s]."""
        return self.speed if self.speed is not None else tuple(s * 2.0 * math.pi / 60.0 for s in self.speed_rpm)


def read_csv(name, base_dir) -> dict:
    """Read a coefficient table CSV (header row naming the columns; '#' comment lines) into {column: [text]}."""
    if not isinstance(name, str):
        raise problem(f' must be a file name, got {got(name)}', '.csv')
    p = Path(name)
    if not p.is_absolute():
        p = Path(base_dir or '.') / p
    try:
        if p.stat().st_size > TABLE_CSV_MAX_BYTES:
            raise problem(f': {p} is larger than {TABLE_CSV_MAX_BYTES} bytes', '.csv')
        text = p.read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as exc:
        raise problem(f': cannot read {p}: {exc}', '.csv') from None
    rows = list(csv.reader(line for line in text.splitlines() if line.strip() and not line.startswith('#')))
    if len(rows) < 2:
        raise problem(f': {p} needs a header row and at least one row of values', '.csv')
    head = [h.strip() for h in rows[0]]
    for i, r in enumerate(rows[1:]):
        if len(r) != len(head):
            raise problem(f': {p} row {i + 2} has {len(r)} values, the header {len(head)}', '.csv')
    return {h: [r[j].strip() for r in rows[1:]] for j, h in enumerate(head)}


class BearingFile(Section):
    """
    A bearing: the kind ('short', 'finite' film; 'table' of K and C vs speed), its node and geometry [m, Pa s].

    ``model`` is the v1 name of ``kind``; ``identify: false`` makes it a known element of the rotor model; ``load``
    [N] is a number, null (from statics) or the film force [Fx, Fy]; ``support`` a pedestal in series.
    """

    name: Name = None
    node: Node
    kind: Annotated[str, Choice(*KINDS)] = None
    model: Annotated[str, Choice(*KINDS)] = None
    identify: Annotated[bool, Flag()] = None
    diameter: Length = None
    length: Annotated[float, Num('m', 1e-5, 10)] = None
    clearance: Annotated[float, Num('m', 1e-7, 1e-2)] = None
    viscosity: Annotated[float, Num('Pa s', 1e-5, 10)] = None
    cavitation: Annotated[str, Choice('swift_stieber', 'gumbel')] = 'swift_stieber'
    load: Annotated[Any, Load()] = None
    support: SupportFile | None = None
    table: TableFile | None = None

    SEAL: ClassVar[bool] = False

    @model_validator(mode='after')
    def _check(self):
        if 'kind' in self.model_fields_set and 'model' in self.model_fields_set and self.kind != self.model:
            raise problem(f': kind and model (its v1 name) disagree: {short(self.kind)} vs {short(self.model)}')
        kinds = ('table',) if self.SEAL else KINDS
        key = 'kind' if self.kind is not None else 'model'
        self.kind = self.kind or self.model or kinds[0]
        if self.kind not in kinds:
            raise problem(f' must be one of {kinds}, got {short(self.kind)}', f'.{key}')
        if self.identify is None:
            self.identify = not self.SEAL
        elif self.SEAL and self.identify:
            raise problem(': seals are known elements (never identified)', '.identify')
        if self.kind != 'table':
            for k in ('diameter', 'length', 'clearance', 'viscosity'):
                if getattr(self, k) is None:
                    raise self.missing(k)
        if self.kind == 'table' and self.table is None:
            raise self.missing('table')
        if self.kind != 'table' and 'table' in self.model_fields_set:
            raise problem(f": only a bearing of kind 'table' has a table (this one is {self.kind!r})", '.table')
        if 'cavitation' in self.model_fields_set and self.kind != 'finite':
            raise problem(f": only a 'finite' bearing has a cavitation condition (this one is {self.kind!r}; "
                          f"'short' is the half-Sommerfeld film already)", '.cavitation')
        return self


class SealFile(BearingFile):
    """A seal: a known table element, never identified."""

    SEAL: ClassVar[bool] = True


# ------------------------------------------------------------------------------------------------ probes, runs
class ProbeFile(Section):
    """A displacement probe on a node: ``direction`` (x, y, '45deg') or ``angle_deg`` [deg], and a gain [-]."""

    name: Name = None
    node: Node
    direction: Annotated[str, Direction()] = None
    angle_deg: Annotated[float, Num('deg', -360, 360)] = None
    gain: Annotated[float, Num('-', 1e-3, 1e3)] = 1.0

    @model_validator(mode='after')
    def _check(self):
        if self.given('direction', 'angle_deg') == ['direction', 'angle_deg']:
            raise problem(': give direction (x, y) or angle_deg, not both')
        if self.direction is None and self.angle_deg is None:
            raise problem(' is missing (x or y; or give angle_deg)', '.direction')
        return self


class ExcitationFile(Section):
    """An unbalance [kg m] (forward) or a force [N] along x or y, on a node, at a phase and a frequency ratio."""

    kind: Annotated[str, Choice('unbalance', 'force')]
    node: Node
    magnitude: float
    EXPECT: ClassVar[dict] = {'magnitude': 'kg m for an unbalance, N for a force'}
    phase: Annotated[float, Num('rad', -1e3, 1e3)] = None
    phase_deg: Annotated[float, Num('deg', -1e5, 1e5)] = None
    direction: Annotated[str, Choice('forward', 'x', 'y')] = None
    frequency_ratio: Annotated[float, Num('-', 1e-3, 20)] = 1.0

    @field_validator('magnitude', mode='plain')
    @classmethod
    def _magnitude(cls, v, info: ValidationInfo):
        return Num('kg m' if info.data.get('kind') == 'unbalance' else 'N', 0, 1e6).check(v)

    @model_validator(mode='after')
    def _check(self):
        if self.kind == 'unbalance' and self.direction not in (None, 'forward'):
            raise problem(f" must be one of ('forward',), got {short(self.direction)}", '.direction')
        if self.kind == 'force' and self.direction is None:
            raise problem(" is missing (one of ('forward', 'x', 'y'))", '.direction')
        self.direction = self.direction or 'forward'
        if self.given('phase', 'phase_deg') == ['phase', 'phase_deg']:
            raise problem(': give phase [rad] or phase_deg [deg], not both')
        return self


class RunFile(Section):
    """An excitation run: its id and what excites the rotor."""

    run_id: Name = Field(None, alias='id')
    excitation: list[ExcitationFile]


class TruthFile(Section):
    """The simulated machine's real bearings: film model and per identified bearing true / nominal factors."""

    bearing_model: Annotated[str, Choice('short', 'finite')] = 'short'
    viscosity_factor: Annotated[tuple, Numbers('-', 0.05, 20)] = None
    clearance_factor: Annotated[tuple, Numbers('-', 0.05, 20)] = None
    k_factor: Annotated[tuple, Numbers('-', 0.05, 20)] = None
    c_factor: Annotated[tuple, Numbers('-', 0.05, 20)] = None


class SimulationFile(Section):
    """The simulated rig: DAQ rate [Hz] and block, speed steps [rpm], dwell and ramp [s], noise, seed, truth, runs."""

    sample_rate: Annotated[float, Num('Hz', 10, 1e7)]
    block_size: Annotated[int, Num('', 16, 1 << 20, whole=True)] = 1024
    speeds_rpm: Annotated[tuple, Numbers('rpm', 0, 1e6)]
    dwell: Annotated[float, Num('s', 1e-3, 1e5)]
    ramp: Annotated[float, Num('s', 0, 1e4)] = 0.0
    noise: Annotated[float, Num('-', 0, 1)] = 0.0
    seed: Annotated[int, Num('', 0, 2**31, whole=True)] = 0
    truth: TruthFile
    runs: list[RunFile]


class ModalTestFile(Section):
    """Measured (and the paper's) free-free natural frequencies [Hz]."""

    measured_hz: Annotated[tuple, Numbers('Hz', 0, 1e7)] | None = None
    paper_initial_hz: Annotated[tuple, Numbers('Hz', 0, 1e7)] | None = None
    paper_updated_hz: Annotated[tuple, Numbers('Hz', 0, 1e7)] | None = None


class RigFile(Section):
    """The whole parameter file."""

    name: Name = None
    materials: dict[Annotated[str, Text()], MaterialFile] | None = None
    shaft: ShaftFile
    discs: list[DiscFile] | None = None
    point_masses: list[PointMassFile] | None = None
    gravity: Annotated[tuple, Numbers('m/s^2', -1e3, 1e3)] | None = None
    bearings: list[BearingFile]
    seals: list[SealFile] | None = None
    probes: list[ProbeFile] | None = None
    simulation: SimulationFile | None = None
    modal_test: ModalTestFile | None = None
    extra: dict | None = None

    @model_validator(mode='after')
    def _check(self):
        g = self.gravity
        if g is not None and (len(g) != 2 or g[0] == g[1] == 0.0):
            raise problem(f' must be a non-zero vector [gx, gy] [m/s^2], got {short(list(g))}', '.gravity')
        return self
