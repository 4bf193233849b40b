"""
The parameter file (``params/rig.yaml``; schema v1 and v2) as pydantic models: its keys, types, units and ranges.

One model per mapping of the file.  A field's type says its unit and range (:mod:`.fields`); a model's validator
checks the rules among its own keys (material or E/G/nu inline; a disc by mass or by geometry; increasing table
speeds).  What needs the rest of the file -- nodes against the shaft, material names, defaults from the shaft or
from gravity, one truth factor per identified bearing -- is checked where the machine is built (:mod:`.build`).
SI units; speeds in rpm where the key says so.  A table may be ``{csv: FILE}`` (relative to the validation
context's ``base_dir``, the params file's folder).
"""
from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

from pydantic import Field, field_validator, model_validator, StrictBool, ValidationError, ValidationInfo

from .errors import got, message, problem, short
from .fields import Direction, Load, Num, Numbers, Pair, Section, Shear

Node = Annotated[int, Num('', 1, None, whole=True)]
Name = str | None         # text; a number is taken as text
Length = Annotated[float, Num('m', 1e-4, 10)]
Bore = Annotated[float, Num('m', 0, 10)]
Density = Annotated[float, Num('kg/m^3', 100, 30000)]
Modulus = Annotated[float, Num('Pa', 0.0, 1e13, positive=True)]
Mass = Annotated[float, Num('kg', 0, 1e6)]
Inertia = Annotated[float, Num('kg m^2', 0, 1e6)]
ShearCoefficient = Annotated[Any, Shear()]
Factors = Annotated[tuple, Numbers('-', 0.05, 20)]
Hz = Annotated[tuple, Numbers('Hz', 0, 1e7)]
KColumn = Annotated[tuple, Numbers('N/m', -1e13, 1e13)]
CColumn = Annotated[tuple, Numbers('N s/m', -1e13, 1e13)]
KINDS = ('short', 'finite', 'table')
Kind = Literal['short', 'finite', 'table']
TABLE_COEFFS = ('kxx', 'kxy', 'kyx', 'kyy', 'cxx', 'cxy', 'cyx', 'cyy')
TABLE_CSV_MAX_BYTES = 1 << 20
MAX_ELEMENTS = 2000            # shaft elements of a v2 shaft (plant models have 30-150)


class Elastic(Section):
    """Two of E [Pa], G [Pa], nu [-] and the density [kg/m^3]; :meth:`resolve` fills in E and G."""

    E: Modulus = None
    G: Modulus = None
    nu: Annotated[float, Num('-', -0.99, 0.5)] = None
    density: Density = None

    def resolve(self) -> None:
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
    """A named material (``materials: {NAME: {E, G or nu, density}}``)."""

    @model_validator(mode='after')
    def _check(self):
        self.resolve()
        return self


class LayerFile(Elastic):
    """
    A concentric full element on its host's nodes (a sleeve, a hub), and the base of a shaft element.

    Diameters [m] (a layer's bore defaults to its host's diameter), a named ``material`` (an element's defaults to
    the shaft's) or E/G/nu/density inline, and its own shear coefficient (None: the shaft's).
    """

    material: Name = None
    outer_diameter: Length
    inner_diameter: Bore = None
    shear_coefficient: ShearCoefficient = None    # None: the shaft's

    @model_validator(mode='after')
    def _check(self):
        if self.inner_diameter is not None and self.inner_diameter >= self.outer_diameter:
            raise problem(f' = {self.inner_diameter!r} m must be smaller than outer_diameter = '
                          f'{self.outer_diameter!r} m', '.inner_diameter')
        if self.given('E', 'G', 'nu', 'density'):
            if self.material is not None:
                raise problem(': give material or E/G/nu/density inline, not both')
            self.resolve()
        return self


class AddedMassFile(Section):
    """A mass-only layer: diameters [m] (bore: the host's diameter), a density [kg/m^3] or a material's."""

    outer_diameter: Length
    inner_diameter: Bore = None
    density: Annotated[float, Num('kg/m^3', 1e-3, 30000)] = None
    material: Name = None

    @model_validator(mode='after')
    def _check(self):
        if self.inner_diameter is not None and self.inner_diameter > self.outer_diameter:
            raise problem(f' = {self.inner_diameter!r} m is larger than outer_diameter', '.inner_diameter')
        if self.given('density', 'material') == ['density', 'material']:
            raise problem(': give density or material, not both')
        if self.material is None and self.density is None:
            raise self.missing('density', 'or a material')
        return self


class ElementFile(LayerFile):
    """A shaft element of a v2 shaft: length [m], diameters [m] (solid by default), layers, added masses."""

    name: Name = None
    length: Annotated[float, Num('m', 1e-5, 100)]
    inner_diameter: Bore = 0.0
    added_mass: list[AddedMassFile] | None = None
    layers: list[LayerFile] | None = None


class SectionFile(ElementFile):
    """A section of a v2 shaft: ``n_elements`` equal elements."""

    n_elements: Annotated[int, Num('', 1, 500, whole=True)] = 1


class ShaftFile(Section):
    """A uniform v1 shaft or a v2 shaft of ``sections`` or ``elements``; rotor damping alpha M + beta K, shear."""

    damping_alpha: Annotated[float, Num('1/s', 0, 1e4)] = 0.0
    damping_beta: Annotated[float, Num('s', 0, 1)] = 0.0
    shear_coefficient: ShearCoefficient = 'hutchinson'
    length: Annotated[float, Num('m', 1e-3, 100)] = None
    diameter: Length = None
    inner_diameter: Bore = 0.0
    n_elements: Annotated[int, Num('', 1, 500, whole=True)] = None
    element_lengths: Annotated[tuple, Numbers('m', 1e-5, 100)] | None = None
    density: Density = None
    youngs_modulus: Annotated[float, Num('Pa', 1e6, 1e13)] = None
    poisson_ratio: Annotated[float, Num('-', 0, 0.5)] = None
    sections: list[SectionFile] | None = None
    elements: list[ElementFile] | None = None
    material: Name = None

    V1: ClassVar[tuple] = ('length', 'n_elements', 'diameter', 'density', 'youngs_modulus', 'poisson_ratio')

    @classmethod
    def allowed(cls, d):
        v2 = 'sections' in d or 'elements' in d
        return ('damping_alpha', 'damping_beta', 'shear_coefficient') + (
            ('sections', 'elements', 'material') if v2 else cls.V1 + ('inner_diameter', 'element_lengths'))

    @classmethod
    def required(cls, d):
        return () if 'sections' in d or 'elements' in d else cls.V1

    @model_validator(mode='after')
    def _check(self):
        v2 = self.given('sections', 'elements')
        if len(v2) == 2:
            raise problem(': give sections or elements, not both')
        if v2 and getattr(self, v2[0]) is None:
            raise self.missing(v2[0])
        if v2 and not getattr(self, v2[0]):
            raise problem(' is empty', f'.{v2[0]}')
        if v2 and sum(getattr(p, 'n_elements', 1) for p in getattr(self, v2[0])) > MAX_ELEMENTS:
            raise problem(f': more than {MAX_ELEMENTS} elements', f'.{v2[0]}')
        el, n = self.element_lengths, self.n_elements
        if el is not None and len(el) != n:
            raise problem(f' must be a list of {n} lengths [m] or null, got {short(list(el))}', '.element_lengths')
        if el is not None and abs(sum(el) - self.length) > 1e-9 * max(1.0, self.length):
            raise problem(f' sum to {sum(el)!r} m, not shaft.length = {self.length!r} m', '.element_lengths')
        return self


class DiscFile(Section):
    """A disc by geometry (diameters, thickness [m]; bore and density default to the shaft's) or by mass/Ip/Id."""

    name: Name = None
    node: Node
    outer_diameter: Length = None
    inner_diameter: Bore = None
    thickness: Annotated[float, Num('m', 1e-5, 10)] = None
    density: Density = None
    mass_factor: Annotated[float, Num('-', 0.01, 100)] = 1.0
    mass: Mass = None
    Ip: Inertia = 0.0
    Id: Inertia = 0.0

    @model_validator(mode='after')
    def _check(self):
        geo = self.given('outer_diameter', 'inner_diameter', 'thickness', 'density')
        if 'mass' in self.model_fields_set and geo:
            raise problem(f': give the disc by mass/Ip/Id or by geometry, not both (has {geo})')
        if 'mass' in self.model_fields_set:
            return self
        for k in self.given('Ip', 'Id'):
            raise problem(f': a disc given by geometry has no {k} (give mass, Ip and Id instead)', f'.{k}')
        for k in ('outer_diameter', 'thickness'):
            if getattr(self, k) is None:
                raise self.missing(k, 'or give mass, Ip and Id')
        if self.inner_diameter is not None and self.inner_diameter > self.outer_diameter:
            raise problem(f' = {self.inner_diameter!r} m is larger than outer_diameter', '.inner_diameter')
        return self


class PointMassFile(Section):
    """A point mass [kg] with inertias Ip, Id [kg m^2]."""

    name: Name = None
    node: Node
    mass: Mass
    Ip: Inertia = 0.0
    Id: Inertia = 0.0


class SupportFile(Section):
    """A pedestal in series with the film: mass [kg], stiffness [N/m], damping [N s/m], each a value or [x, y]."""

    mass: Annotated[tuple, Pair('kg', 1e-6, 1e7)]
    stiffness: Annotated[tuple, Pair('N/m', 1.0, 1e13)]
    damping: Annotated[tuple, Pair('N s/m', 0.0, 1e10)] = (0.0, 0.0)


class TableFile(Section):
    """
    K [N/m] and C [N s/m] per speed (``speed_rpm`` [rpm] or ``speed`` [rad/s], increasing); cross terms 0.

    ``interpolation`` between the speeds: 'linear' (default) or 'cubic' (a not-a-knot cubic spline through the rows).
    """

    speed_rpm: Annotated[tuple, Numbers('rpm', 0, 1e7)] = None
    speed: Annotated[tuple, Numbers('rad/s', 0, 1e6)] = None
    kxx: KColumn = None
    kxy: KColumn = None
    kyx: KColumn = None
    kyy: KColumn = None
    cxx: CColumn = None
    cxy: CColumn = None
    cyx: CColumn = None
    cyy: CColumn = None
    interpolation: Literal['linear', 'cubic'] = 'linear'

    @classmethod
    def prepare(cls, d, info):
        if 'csv' not in d:
            return d
        other = [k for k in d if k not in ('csv', 'interpolation')]
        if other:
            raise problem(': a table from csv has no other key but interpolation', '.' + str(other[0]))
        try:
            cols = read_csv(d['csv'], (info.context or {}).get('base_dir'))
            cls.model_validate(cols)         # its problems named below .csv
            return {**cols, **({'interpolation': d['interpolation']} if 'interpolation' in d else {})}
        except ValidationError as exc:
            tail = ': ' + message(exc.errors(include_url=False)[0], root='')
        except ValueError as exc:
            tail = str(exc)
        raise problem(tail, '.csv')

    @model_validator(mode='after')
    def _check(self):
        if (self.speed_rpm is None) == (self.speed is None):
            raise problem(': give speed_rpm [rpm] or speed [rad/s] (one of them)')
        sp = self.speeds()
        if not sp:
            raise problem(': the table has no speeds')
        if any(b <= a for a, b in zip(sp, sp[1:])):
            raise problem(': speeds must increase strictly')
        for k in TABLE_COEFFS:
            unit, v = 'N/m' if k[0] == 'k' else 'N s/m', getattr(self, k)
            if v is None and k[1] == k[2]:
                raise problem(f' is missing ({unit}, one per speed)', f'.{k}')
            if v is not None and len(v) != len(sp):
                raise problem(f' must be a list of {len(sp)} values [{unit}] (one per speed), got {short(list(v))}',
                              f'.{k}')
        return self

    def speeds(self) -> tuple:
        """Return the speeds [rad/s]."""
        return self.speed if self.speed is not None else tuple(s * 2.0 * math.pi / 60.0 for s in self.speed_rpm)


def read_csv(name, base_dir) -> dict:
    """Read a table CSV (a header row naming the columns, '#' comment lines) into {column: [text]}; ValueError."""
    if not isinstance(name, str):
        raise ValueError(f' must be a file name, got {got(name)}')
    p = Path(base_dir or '.') / name
    try:
        size, text = p.stat().st_size, ''
        text = p.read_text(encoding='utf-8') if size <= TABLE_CSV_MAX_BYTES else ''
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f': cannot read {p}: {exc}') from None
    if size > TABLE_CSV_MAX_BYTES:
        raise ValueError(f': {p} is larger than {TABLE_CSV_MAX_BYTES} bytes')
    rows = list(csv.reader(line for line in text.splitlines() if line.strip() and not line.startswith('#')))
    if len(rows) < 2:
        raise ValueError(f': {p} needs a header row and at least one row of values')
    for i, r in enumerate(rows[1:]):
        if len(r) != len(rows[0]):
            raise ValueError(f': {p} row {i + 2} has {len(r)} values, the header {len(rows[0])}')
    return {h.strip(): [r[j].strip() for r in rows[1:]] for j, h in enumerate(rows[0])}


class BearingFile(Section):
    """
    A bearing: ``kind`` (v1: ``model``) 'short' or 'finite' film of geometry [m] and viscosity [Pa s], or 'table'.

    ``identify: false``: a known element of the rotor model.  ``load`` [N]: a number, null (from statics) or the film
    force [Fx, Fy].  ``support``: a pedestal in series with the film.
    """

    name: Name = None
    node: Node
    kind: Kind = None
    model: Kind = None
    identify: StrictBool = None
    diameter: Length = None
    length: Annotated[float, Num('m', 1e-5, 10)] = None
    clearance: Annotated[float, Num('m', 1e-7, 1e-2)] = None
    viscosity: Annotated[float, Num('Pa s', 1e-5, 10)] = None
    cavitation: Literal['swift_stieber', 'gumbel'] = 'swift_stieber'
    load: Annotated[Any, Load()] = None
    support: SupportFile | None = None
    table: TableFile | None = None

    SEAL: ClassVar[bool] = False

    @model_validator(mode='after')
    def _check(self):
        if self.given('kind', 'model') == ['kind', 'model'] and self.kind != self.model:
            raise problem(f': kind and model (its v1 name) disagree: {short(self.kind)} vs {short(self.model)}')
        kinds, key = ('table',) if self.SEAL else KINDS, 'kind' if self.kind is not None else 'model'
        self.kind = self.kind or self.model or kinds[0]
        if self.kind not in kinds:
            raise problem(f' must be one of {kinds}, got {short(self.kind)}', f'.{key}')
        if self.SEAL and self.identify:
            raise problem(': seals are known elements (never identified)', '.identify')
        self.identify = not self.SEAL if self.identify is None else self.identify
        for k in ('diameter', 'length', 'clearance', 'viscosity') if self.kind != 'table' else ():
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


class ProbeFile(Section):
    """A displacement probe: ``direction`` ('x', 'y', '45deg') or ``angle_deg`` [deg] from +x to +y; a gain [-]."""

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
    """An unbalance [kg m] (forward) or a force [N] along x or y; phase [rad] or phase_deg [deg]; frequency ratio."""

    kind: Literal['unbalance', 'force']
    node: Node
    magnitude: float
    phase: Annotated[float, Num('rad', -1e3, 1e3)] = None
    phase_deg: Annotated[float, Num('deg', -1e5, 1e5)] = None
    direction: Literal['forward', 'x', 'y'] = None
    frequency_ratio: Annotated[float, Num('-', 1e-3, 20)] = 1.0

    EXPECT: ClassVar[dict] = {'kind': "'unbalance' or 'force'", 'magnitude': 'kg m for an unbalance, N for a force'}

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
        if self.given('phase', 'phase_deg') == ['phase', 'phase_deg']:
            raise problem(': give phase [rad] or phase_deg [deg], not both')
        self.direction = self.direction or 'forward'
        return self


class RunFile(Section):
    """An excitation run: its ``id`` and what excites the rotor."""

    run_id: Name = Field(None, alias='id')
    excitation: list[ExcitationFile]


class TruthFile(Section):
    """The simulated machine's bearings: film model, true / nominal factors per identified bearing."""

    bearing_model: Literal['short', 'finite'] = 'short'
    viscosity_factor: Factors = None
    clearance_factor: Factors = None
    k_factor: Factors = None
    c_factor: Factors = None


class SimulationFile(Section):
    """The simulated rig: sample rate [Hz], block [samples], speeds [rpm], dwell and ramp [s], noise, seed, runs."""

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

    measured_hz: Hz | None = None
    paper_initial_hz: Hz | None = None
    paper_updated_hz: Hz | None = None


class RigFile(Section):
    """The whole parameter file; gravity [m/s^2] as (gx, gy)."""

    name: Name = None
    materials: dict[str, MaterialFile] | None = None
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
