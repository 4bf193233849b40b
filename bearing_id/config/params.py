"""
Load and validate the rig/model YAML (``params/rig.yaml``) into small frozen dataclasses.

Every error names the offending field (``bearings[1].clearance``) and the expected unit and range, so that a
malformed file fails at load time with a message a person can act on.  SI units throughout.

Reading YAML is bounded (:func:`load_yaml_bounded`, also used for bag metadata): files larger than
``YAML_MAX_BYTES`` are refused before reading, nesting deeper than ``YAML_MAX_DEPTH`` and documents whose anchors and
aliases would expand to more than ``YAML_MAX_NODES`` nodes (a "billion laughs") are refused from the parser's event
stream before anything is built, so a hostile file costs milliseconds, not memory.  A wrong type anywhere (a number
where a mapping is expected, ``bearings: [1, 2]``, a string where a number is expected) is a :class:`ParamError`
naming the field, never an AttributeError/TypeError/KeyError.
"""
from __future__ import annotations

import csv
import dataclasses
from dataclasses import dataclass, field
import difflib
import math
from pathlib import Path
import re
import reprlib
from typing import Any

import pint
import yaml

from ..conventions import GRAVITY, parse_probe_direction, probe_direction

PACKAGE_PARAMS = Path(__file__).resolve().parents[2] / 'params'


class ParamError(ValueError):
    """A parameter file or value is invalid; the message names the field."""


# ---------------------------------------------------------------------------------------------- dataclasses
@dataclass(frozen=True)
class Material:
    name: str
    youngs_modulus: float         # Pa
    shear_modulus: float          # Pa
    density: float                # kg/m^3

    @property
    def poisson_ratio(self) -> float:
        return self.youngs_modulus / (2.0 * self.shear_modulus) - 1.0


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
    """K and C (2x2, our frame) vs speed; interpolated linearly in speed, held flat outside (bearings.table)."""

    speeds: tuple                 # rad/s, increasing
    K: tuple                      # per speed ((kxx, kxy), (kyx, kyy)) N/m
    C: tuple                      # per speed ((cxx, cxy), (cyx, cyy)) N s/m


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

    @property
    def kind(self) -> str:
        return self.model


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


# ---------------------------------------------------------------------------------------------- bounded YAML
YAML_MAX_BYTES = 4 * 1024 * 1024    # a rig file is ~4 kB; an augmented one ~10 kB
YAML_MAX_DEPTH = 64                 # nesting of mappings/sequences (rig files use 4)
YAML_MAX_NODES = 200_000            # nodes after expanding every alias (rig files have ~300)


def _yaml_loader():
    return getattr(yaml, 'CSafeLoader', yaml.SafeLoader)


def check_yaml_events(text: str, what: str, *, max_depth: int = YAML_MAX_DEPTH,
                      max_nodes: int = YAML_MAX_NODES) -> None:
    """
    Walk the parser's event stream (no objects are built) and refuse too deep or too large a document.

    Refuses nesting deeper than ``max_depth`` or a document whose aliases would expand to more than ``max_nodes`` nodes;
    raises ParamError (or yaml.YAMLError for a syntax error).  Linear in the size of the text; a billion-laughs file is
    refused after a few hundred events.
    """
    depth = 0
    total = 0                           # nodes so far, every alias counted as the size of what it refers to
    open_anchors: list = []             # (anchor or None, total at its start), one per open collection
    sizes: dict = {}                    # anchor -> expanded size of its node
    for ev in yaml.parse(text, Loader=_yaml_loader()):
        if isinstance(ev, yaml.AliasEvent):
            n = sizes.get(ev.anchor)
            if n is None:               # an alias to an anchor still open (recursive) or undefined
                raise ParamError(f'{what}: alias *{ev.anchor} refers to an undefined or enclosing anchor')
            total += n
        elif isinstance(ev, yaml.ScalarEvent):
            total += 1
            if ev.anchor is not None:
                sizes[ev.anchor] = 1
        elif isinstance(ev, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            depth += 1
            total += 1
            if depth > max_depth:
                raise ParamError(f'{what}: nested deeper than {max_depth} levels (refused; a parameter file needs '
                                 f'a handful)')
            open_anchors.append((ev.anchor, total - 1))
        elif isinstance(ev, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            depth -= 1
            anchor, start = open_anchors.pop()
            if anchor is not None:
                sizes[anchor] = total - start
        if total > max_nodes:
            raise ParamError(f'{what}: more than {max_nodes} values once its anchors/aliases are expanded (refused: '
                             f"an alias bomb such as 'billion laughs')")


def load_yaml_bounded(path: str | Path, what: str | None = None, *, max_bytes: int = YAML_MAX_BYTES,
                      max_depth: int = YAML_MAX_DEPTH, max_nodes: int = YAML_MAX_NODES):
    """
    Run ``yaml.safe_load`` on a file with bounds on its size, nesting and nodes.

    Size <= ``max_bytes`` (checked before reading), nesting <= ``max_depth``, nodes after alias expansion <=
    ``max_nodes`` (checked on the event stream before anything is constructed).  Every failure -- unreadable, too big,
    not UTF-8, not YAML, over a bound -- is a ParamError naming the file.
    """
    path = Path(path)
    what = what or str(path)
    try:
        size = path.stat().st_size
        if size > max_bytes:
            raise ParamError(f'{what}: {size} bytes, more than the {max_bytes} a parameter file may have (refused '
                             f'unread)')
        with open(path, 'rb') as fh:
            raw = fh.read(max_bytes + 1)
    except OSError as exc:
        raise ParamError(f'cannot read {what}: {exc}') from exc
    if len(raw) > max_bytes:            # grew since stat, or a device
        raise ParamError(f'{what}: more than {max_bytes} bytes (refused)')
    try:
        text = raw.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise ParamError(f'{what} is not UTF-8 text ({exc.reason} at byte {exc.start})') from None
    try:
        check_yaml_events(text, what, max_depth=max_depth, max_nodes=max_nodes)
        return yaml.load(text, Loader=_yaml_loader())   # noqa: S506 - a SafeLoader (C or Python)
    except yaml.YAMLError as exc:
        text = ' '.join(str(exc).replace('"<unicode string>"', path.name).split())
        raise ParamError(f'{what} is not valid YAML: {text}') from None
    except RecursionError:              # unreachable with the depth bound; kept as a last line
        raise ParamError(f'{what}: nested too deeply') from None


# ---------------------------------------------------------------------------------------------- validation
def _kind(v) -> str:
    return {dict: 'a mapping', list: 'a list', str: 'a string', bool: 'a boolean', type(None): 'null'}.get(
        type(v), 'a number' if isinstance(v, (int, float)) else type(v).__name__)


def _short(v, n: int = 60) -> str:
    """Return the repr of a value for a message, cut to ``n`` characters (a hostile value may be huge)."""
    r = reprlib.Repr()
    r.maxstring, r.maxother, r.maxlist, r.maxdict, r.maxlevel = n, n, 6, 6, 2
    return r.repr(v)


def _map(v, where: str) -> dict:
    """``v`` itself must be a mapping (a section or one list item)."""
    if not isinstance(v, dict):
        raise ParamError(f'{where} must be a mapping (key: value), got {_kind(v)} {_short(v)}')
    return v


def _list(v, where: str) -> list:
    if not isinstance(v, list):
        raise ParamError(f'{where} must be a list, got {_kind(v)} {_short(v)}')
    return v


#: unit text used in messages -> the pint unit it converts to (SI)
_PINT_UNIT = {'m': 'm', 'Pa': 'Pa', 'kg/m^3': 'kg/m**3', 'Pa s': 'Pa*s', 'N': 'N', 'rpm': 'rpm', 'Hz': 'Hz', 's': 's',
              '1/s': '1/s', 'N/m': 'N/m', 'N s/m': 'N*s/m', 'kg m': 'kg*m', 'kg m^2': 'kg*m**2', 'kg': 'kg',
              'deg': 'deg', 'rad': 'rad', 'rad/s': 'rad/s', 'm/s^2': 'm/s**2', '-': 'dimensionless'}
_UREG = None
#: what a number with a unit may look like: a decimal number, then unit names joined by spaces, '*', '/' or '.', each
#: with at most a one-digit power ('m^2', 'm**-1'); nothing else reaches pint's expression evaluator
_UNIT_NAME = r'[A-Za-z\u00b5\u03bc\u00b0\u2126_]+(?:(?:\*\*|\^)-?\d)?'
_UNIT_TEXT = re.compile(r'\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d{1,3})?)\s*('
                        + rf'(?:1\s*/\s*)?{_UNIT_NAME}(?:\s*[*/.\u00b7]?\s*{_UNIT_NAME})*' + r')\s*$')


def _unit_registry():
    """Return the shared pint registry (imported on first use: plain numbers never load pint)."""
    global _UREG
    if _UREG is None:
        _UREG = pint.UnitRegistry()
    return _UREG


def _with_unit(text: str, unit: str, where: str) -> float:
    """Convert ``text`` such as '12.65 mm' or '3000 rpm' to the SI ``unit`` of the field; ParamError otherwise."""
    target = _PINT_UNIT.get(unit)
    if target is None:
        raise ParamError(f'{where} must be a number [{unit}], got {_short(text)} (units are not accepted here)')
    m = _UNIT_TEXT.match(text) if len(text) <= 200 else None
    if m is None:     # pint evaluates expressions ('9**9**9 m' would never return): only NUMBER UNIT reaches it
        raise ParamError(f'{where} must be a number [{unit}] or a number with a unit such as "12.65 mm", got '
                         f'{_short(text)}')
    ureg = _unit_registry()
    try:
        q = ureg.Quantity(float(m.group(1)), m.group(2))
    except Exception:  # pint raises its own errors (UndefinedUnitError, DefinitionSyntaxError, ...) and others
        raise ParamError(f'{where} must be a number [{unit}] or a number with a unit such as "12.65 mm", got '
                         f'{_short(text)} (unknown unit)') from None
    try:
        return float(q.to(target).magnitude) if hasattr(q, 'to') else float(q)
    except Exception:
        raise ParamError(f'{where} = {_short(text)} has the wrong unit: expected {unit} (or a unit of the same '
                         f'dimension)') from None


def _num(d: dict, key: str, where: str, lo=None, hi=None, unit='', default: Any = ..., allow_none=False):
    _map(d, where)
    if key not in d:
        if default is ...:
            raise ParamError(f'{where}.{key} is missing ({unit})'.replace(' ()', ''))
        return default
    v = d[key]
    if v is None and allow_none:
        return None
    if isinstance(v, str):  # YAML 1.1 reads 2.06e11 (no dot, no sign) as a string; else a number with a unit
        try:
            v = float(v.strip())
        except ValueError:
            v = _with_unit(v.strip(), unit, f'{where}.{key}')
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ParamError(f'{where}.{key} must be a number [{unit}], got {_kind(v)} {_short(v)}')
    try:
        v = float(v)
    except OverflowError:   # an integer beyond the float range
        raise ParamError(f'{where}.{key} = {_short(v)} [{unit}] is out of range') from None
    if not math.isfinite(v):
        raise ParamError(f'{where}.{key} must be finite [{unit}], got {v!r}')
    if lo is not None and v < lo or hi is not None and v > hi:
        raise ParamError(f'{where}.{key} = {v!r} [{unit}] is outside the allowed range [{lo}, {hi}]')
    return v


def _keys(d: dict, allowed, where: str) -> None:
    """Refuse a key of ``d`` that is not in ``allowed`` (a typo or an unsupported entry), suggesting the nearest."""
    for k in d:
        if not isinstance(k, str) or k not in allowed:
            near = difflib.get_close_matches(str(k), [str(a) for a in allowed], n=1, cutoff=0.6)
            hint = f' (did you mean {near[0]}?)' if near else f" (known: {', '.join(sorted(allowed))})"
            name = k if isinstance(k, str) and len(k) <= 40 else _short(k, 40)
            raise ParamError(f'{where}.{name}: unknown key{hint}')


def _int(d, key, where, lo=None, hi=None, default: Any = ...):
    v = _num(d, key, where, lo, hi, default=default)
    if v is None or v is ...:
        return v
    if float(v) != int(v):
        raise ParamError(f'{where}.{key} must be a whole number, got {v!r}')
    return int(v)


def _choice(d, key, where, choices, default: Any = ...):
    _map(d, where)
    if key not in d:
        if default is ...:
            raise ParamError(f'{where}.{key} is missing (one of {choices})')
        return default
    v = d[key]
    if not isinstance(v, str) or v not in choices:
        raise ParamError(f'{where}.{key} must be one of {choices}, got {_short(v)}')
    return v


def _text(d, key, where, default: str) -> str:
    """Read a name: a string (a number is accepted and written as text)."""
    v = _map(d, where).get(key, default)
    if v is None:
        return default
    if isinstance(v, bool) or not isinstance(v, (str, int, float)):
        raise ParamError(f'{where}.{key} must be a name (text), got {_kind(v)} {_short(v)}')
    return str(v)


def _section(d, key, where, kind=dict, optional=False):
    _map(d, where)
    if key not in d or d[key] is None:
        if optional:
            return None
        raise ParamError(f'{where}.{key} is missing')
    v = d[key]
    if not isinstance(v, kind):
        raise ParamError(f"{where}.{key} must be {'a mapping' if kind is dict else 'a list'}, got {_kind(v)} "
                         f'{_short(v)}')
    return v


def _numbers(v, where: str, lo=None, hi=None, unit='-') -> tuple:
    """Read a list of numbers (each checked like :func:`_num`)."""
    return tuple(_num({'v': x}, 'v', f'{where}[{i}]', lo, hi, unit) for i, x in enumerate(_list(v, where)))


def _node(d, key, where, n_nodes):
    v = _int(d, key, where, 1, n_nodes)
    return v


def _bool(d, key, where, default: bool) -> bool:
    v = _map(d, where).get(key, default)
    if not isinstance(v, bool):
        raise ParamError(f'{where}.{key} must be true or false, got {_kind(v)} {_short(v)}')
    return v


def _pair(d, key, where, lo, hi, unit, default: Any = ...) -> tuple:
    """Read a number (same in x and y) or a list [x, y]."""
    v = _map(d, where).get(key, ...)
    if v is ...:
        if default is ...:
            raise ParamError(f'{where}.{key} is missing ({unit})')
        return default
    if isinstance(v, list):
        if len(v) != 2:
            raise ParamError(f'{where}.{key} must be a number or a list [x, y] of two [{unit}], got {_short(v)}')
        return _numbers(v, f'{where}.{key}', lo, hi, unit)
    x = _num(d, key, where, lo, hi, unit)
    return (x, x)


SHAFT_V1_KEYS = ('length', 'diameter', 'inner_diameter', 'n_elements', 'element_lengths', 'density',
                 'youngs_modulus', 'poisson_ratio')
SHAFT_COMMON_KEYS = ('damping_alpha', 'damping_beta', 'shear_coefficient')
MAX_ELEMENTS = 2000            # shaft elements of a v2 shaft (plant models have 30-150)
SECTION_KEYS = ('length', 'outer_diameter', 'inner_diameter', 'material', 'E', 'G', 'nu', 'density', 'n_elements',
                'added_mass', 'layers', 'shear_coefficient', 'name')
LAYER_KEYS = ('outer_diameter', 'inner_diameter', 'material', 'E', 'G', 'nu', 'density', 'shear_coefficient')
ELASTIC_KEYS = ('E', 'G', 'nu', 'density')
SHEAR_METHODS = ('hutchinson', 'cowper')


def _shear(d: dict, where: str, default: Any = None):
    """Read ``shear_coefficient``: 'hutchinson', 'cowper' or kappa in [0.1, 2] (a number, or a number text)."""
    if 'shear_coefficient' not in d:
        return default
    v = d['shear_coefficient']
    if isinstance(v, str) and v in SHEAR_METHODS:
        return v
    try:
        return _num(d, 'shear_coefficient', where, 0.1, 2.0, '-')
    except ParamError as exc:
        raise ParamError(f'{exc} (or one of {SHEAR_METHODS})') from None


def _modulus(d: dict, key: str, where: str):
    """Read a modulus [Pa] (optional): finite, > 0 and <= 1e13 (tiny values are allowed: ROSS's hub layers)."""
    v = _num(d, key, where, 0.0, 1e13, 'Pa', default=None)
    if v is not None and not v > 0.0:
        raise ParamError(f'{where}.{key} = {v!r} [Pa] must be > 0')
    return v


def _elastic(d: dict, where: str) -> tuple:
    """(E, G, density) from density and two of E [Pa], G [Pa], nu [-] (or E and G)."""
    have = [k for k in ('E', 'G', 'nu') if k in d]
    if len(have) != 2:
        raise ParamError(f'{where} needs density and exactly two of E [Pa], G [Pa], nu [-], got {have or "none"}')
    E = _modulus(d, 'E', where)
    G = _modulus(d, 'G', where)
    nu = _num(d, 'nu', where, -0.99, 0.5, '-', default=None)
    if E is None:
        E = 2.0 * G * (1.0 + nu)
    elif G is None:
        G = E / (2.0 * (1.0 + nu))
    nu_eff = E / (2.0 * G) - 1.0
    if not -0.99 <= nu_eff <= 0.5:
        raise ParamError(f'{where}: E = {E!r} Pa and G = {G!r} Pa give Poisson ratio {nu_eff:.3g}, outside '
                         f'[-0.99, 0.5]')
    return E, G, _num(d, 'density', where, 100, 30000, 'kg/m^3')


def parse_materials(d) -> dict:
    """Named materials {name: Material}."""
    out = {}
    if d is None:
        return out
    _map(d, 'materials')
    for name, md in d.items():
        w = f'materials.{name if isinstance(name, str) and len(name) <= 40 else _short(name, 40)}'
        _map(md, w)
        _keys(md, ELASTIC_KEYS, w)
        E, G, rho = _elastic(md, w)
        out[str(name)] = Material(str(name), E, G, rho)
    return out


def _section_elements(sd: dict, where: str, materials: dict, default_material, element: bool) -> list:
    _map(sd, where)
    _keys(sd, tuple(k for k in SECTION_KEYS if not (element and k == 'n_elements')), where)
    length = _num(sd, 'length', where, 1e-5, 100, 'm')
    od = _num(sd, 'outer_diameter', where, 1e-4, 10, 'm')
    idd = _num(sd, 'inner_diameter', where, 0, od, 'm', default=0.0)
    if idd >= od:
        raise ParamError(f'{where}.inner_diameter = {idd!r} m must be smaller than outer_diameter = {od!r} m')
    inline = [k for k in ELASTIC_KEYS if k in sd]
    if 'material' in sd and inline:
        raise ParamError(f'{where}: give material or {"/".join(ELASTIC_KEYS)} inline, not both')
    if inline:
        E, G, rho = _elastic(sd, where)
        mname = ''
    else:
        mname = sd.get('material', default_material)
        if mname is None:
            raise ParamError(f'{where}.material is missing (a name from materials:, or E/G/nu/density inline)')
        if not isinstance(mname, str) or mname not in materials:
            raise ParamError(f'{where}.material = {_short(mname)} is not one of the materials {sorted(materials)}')
        m = materials[mname]
        E, G, rho = m.youngs_modulus, m.shear_modulus, m.density
    added = []
    for k, ad in enumerate(_section(sd, 'added_mass', where, list, optional=True) or []):
        wa = f'{where}.added_mass[{k}]'
        _map(ad, wa)
        _keys(ad, ('outer_diameter', 'inner_diameter', 'density', 'material'), wa)
        aod = _num(ad, 'outer_diameter', wa, 1e-4, 10, 'm')
        aid = _num(ad, 'inner_diameter', wa, 0, aod, 'm', default=od)
        if 'density' in ad and 'material' in ad:
            raise ParamError(f'{wa}: give density or material, not both')
        if 'material' in ad:
            if ad['material'] not in materials:
                raise ParamError(f"{wa}.material = {_short(ad['material'])} is not one of {sorted(materials)}")
            arho = materials[ad['material']].density
        else:
            arho = _num(ad, 'density', wa, 1e-3, 30000, 'kg/m^3')
        added.append(AddedMass(aod, aid, arho))
    layers = []
    for k, ld in enumerate(_section(sd, 'layers', where, list, optional=True) or []):
        wl = f'{where}.layers[{k}]'
        _map(ld, wl)
        _keys(ld, LAYER_KEYS, wl)
        lod = _num(ld, 'outer_diameter', wl, 1e-4, 10, 'm')
        lid = _num(ld, 'inner_diameter', wl, 0, lod, 'm', default=od)
        if lid >= lod:
            raise ParamError(f'{wl}.inner_diameter = {lid!r} m must be smaller than outer_diameter = {lod!r} m')
        linline = [key for key in ELASTIC_KEYS if key in ld]
        if 'material' in ld and linline:
            raise ParamError(f'{wl}: give material or {"/".join(ELASTIC_KEYS)} inline, not both')
        if linline:
            lE, lG, lrho = _elastic(ld, wl)
            lname = ''
        else:
            lname = ld.get('material')
            if lname is None:
                raise ParamError(f'{wl}.material is missing (a name from materials:, or E/G/nu/density inline)')
            if not isinstance(lname, str) or lname not in materials:
                raise ParamError(f'{wl}.material = {_short(lname)} is not one of the materials {sorted(materials)}')
            lm = materials[lname]
            lE, lG, lrho = lm.youngs_modulus, lm.shear_modulus, lm.density
        layers.append(Layer(lod, lid, lE, lG, lrho, lname, _shear(ld, wl)))
    shear = _shear(sd, where)
    n = 1 if element else _int(sd, 'n_elements', where, 1, 500, default=1)
    return [ElementSpec(length / n, od, idd, E, G, rho, tuple(added), mname, tuple(layers), shear)] * n


def parse_shaft(d: dict, materials: dict | None = None) -> Shaft:
    w = 'shaft'
    _map(d, w)
    materials = materials or {}
    v2 = [k for k in ('sections', 'elements') if k in d]
    shear = _shear(d, w, 'hutchinson')
    damping = {'damping_alpha': _num(d, 'damping_alpha', w, 0, 1e4, '1/s', default=0.0),
               'damping_beta': _num(d, 'damping_beta', w, 0, 1, 's', default=0.0), 'shear_coefficient': shear}
    if v2:
        if len(v2) == 2:
            raise ParamError('shaft: give sections or elements, not both')
        _keys(d, SHAFT_COMMON_KEYS + ('sections', 'elements', 'material'), w)
        els = []
        for i, sd in enumerate(_section(d, v2[0], w, list)):
            els += _section_elements(sd, f'{w}.{v2[0]}[{i}]', materials, d.get('material'), v2[0] == 'elements')
            if len(els) > MAX_ELEMENTS:
                raise ParamError(f'shaft.{v2[0]}: more than {MAX_ELEMENTS} elements')
        if not els:
            raise ParamError(f'shaft.{v2[0]} is empty')
        e0 = els[0]
        return Shaft(length=sum(e.length for e in els), diameter=max(e.outer_diameter for e in els),
                     inner_diameter=min(e.inner_diameter for e in els), n_elements=len(els),
                     element_lengths=tuple(e.length for e in els), density=e0.density,
                     youngs_modulus=e0.youngs_modulus, poisson_ratio=e0.youngs_modulus / (2 * e0.shear_modulus) - 1,
                     elements=tuple(els), reference_density=e0.density, reference_modulus=e0.youngs_modulus,
                     **damping)
    _keys(d, SHAFT_V1_KEYS + SHAFT_COMMON_KEYS, w)
    length = _num(d, 'length', w, 1e-3, 100, 'm')
    n_el = _int(d, 'n_elements', w, 1, 500)
    el = d.get('element_lengths')
    if el is None:
        el = (length / n_el,) * n_el
    else:
        if not isinstance(el, list) or len(el) != n_el:
            raise ParamError(f'{w}.element_lengths must be a list of {n_el} lengths [m] or null, got {_kind(el)} '
                             f'{_short(el)}')
        el = _numbers(el, f'{w}.element_lengths', 1e-5, 100, 'm')
        if abs(sum(el) - length) > 1e-9 * max(1.0, length):
            raise ParamError(f'{w}.element_lengths sum to {sum(el)!r} m, not shaft.length = {length!r} m')
    return Shaft(
        length=length,
        diameter=_num(d, 'diameter', w, 1e-4, 10, 'm'),
        inner_diameter=_num(d, 'inner_diameter', w, 0, 10, 'm', default=0.0),
        n_elements=n_el,
        element_lengths=tuple(el),
        density=_num(d, 'density', w, 100, 30000, 'kg/m^3'),
        youngs_modulus=_num(d, 'youngs_modulus', w, 1e6, 1e13, 'Pa'),
        poisson_ratio=_num(d, 'poisson_ratio', w, 0, 0.5, '-'),
        **damping,
    )


def parse_excitation(d: dict, where: str, n_nodes: int) -> ExcitationEntry:
    _map(d, where)
    _keys(d, ('kind', 'node', 'magnitude', 'phase', 'phase_deg', 'direction', 'frequency_ratio'), where)
    kind = _choice(d, 'kind', where, ('unbalance', 'force'))
    direction = _choice(d, 'direction', where, ('forward', 'x', 'y') if kind == 'force' else ('forward',),
                        default='forward' if kind == 'unbalance' else ...)
    if 'phase' in d and 'phase_deg' in d:
        raise ParamError(f'{where}: give phase [rad] or phase_deg [deg], not both')
    phase = _num(d, 'phase', where, -1e3, 1e3, 'rad', default=None)
    if phase is None:
        phase = math.radians(_num(d, 'phase_deg', where, -1e5, 1e5, 'deg', default=0.0))
    return ExcitationEntry(
        kind=kind,
        node=_node(d, 'node', where, n_nodes),
        magnitude=_num(d, 'magnitude', where, 0, 1e6, 'kg m' if kind == 'unbalance' else 'N'),
        phase=phase,
        direction=direction,
        frequency_ratio=_num(d, 'frequency_ratio', where, 1e-3, 20, '-', default=1.0),
    )


TABLE_COEFFS = ('kxx', 'kxy', 'kyx', 'kyy', 'cxx', 'cxy', 'cyx', 'cyy')
TABLE_CSV_MAX_BYTES = 1 << 20


def _read_table_csv(path_text, where: str, base_dir) -> dict:
    """Read a coefficient table CSV (header row naming the columns) into {column: [values]}."""
    if not isinstance(path_text, str):
        raise ParamError(f'{where}.csv must be a file name, got {_kind(path_text)} {_short(path_text)}')
    p = Path(path_text)
    if not p.is_absolute():
        p = Path(base_dir or '.') / p
    try:
        if p.stat().st_size > TABLE_CSV_MAX_BYTES:
            raise ParamError(f'{where}.csv: {p} is larger than {TABLE_CSV_MAX_BYTES} bytes')
        text = p.read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as exc:
        raise ParamError(f'{where}.csv: cannot read {p}: {exc}') from None
    rows = list(csv.reader(line for line in text.splitlines() if line.strip() and not line.startswith('#')))
    if len(rows) < 2:
        raise ParamError(f'{where}.csv: {p} needs a header row and at least one row of values')
    head = [h.strip() for h in rows[0]]
    out: dict = {h: [] for h in head}
    for i, r in enumerate(rows[1:]):
        if len(r) != len(head):
            raise ParamError(f'{where}.csv: {p} row {i + 2} has {len(r)} values, the header {len(head)}')
        for h, v in zip(head, r):
            out[h].append(v.strip())
    return out


def parse_table(td, where: str, base_dir=None) -> BearingTable:
    """Read a coefficient table: inline lists or {csv: file}; speeds in rpm (speed_rpm) or rad/s (speed)."""
    _map(td, where)
    if 'csv' in td:
        _keys(td, ('csv',), where)
        td = _read_table_csv(td['csv'], where, base_dir)
        where = f'{where}.csv'
    _keys(td, ('speed_rpm', 'speed') + TABLE_COEFFS, where)
    if ('speed_rpm' in td) == ('speed' in td):
        raise ParamError(f'{where}: give speed_rpm [rpm] or speed [rad/s] (one of them)')
    if 'speed_rpm' in td:
        sp = _numbers(td['speed_rpm'], f'{where}.speed_rpm', 0, 1e7, 'rpm')
        sp = tuple(s * 2.0 * math.pi / 60.0 for s in sp)
    else:
        sp = _numbers(td['speed'], f'{where}.speed', 0, 1e6, 'rad/s')
    n = len(sp)
    if n < 1:
        raise ParamError(f'{where}: the table has no speeds')
    if any(b <= a for a, b in zip(sp, sp[1:])):
        raise ParamError(f'{where}: speeds must increase strictly')
    cols = {}
    for k in TABLE_COEFFS:
        unit = 'N/m' if k[0] == 'k' else 'N s/m'
        if k not in td:
            if k[1] == k[2]:
                raise ParamError(f'{where}.{k} is missing ({unit}, one per speed)')
            cols[k] = (0.0,) * n
            continue
        v = td[k]
        if not isinstance(v, list) or len(v) != n:
            raise ParamError(f'{where}.{k} must be a list of {n} values [{unit}] (one per speed), got {_kind(v)} '
                             f'{_short(v)}')
        cols[k] = _numbers(v, f'{where}.{k}', -1e13, 1e13, unit)
    K = tuple(((cols['kxx'][i], cols['kxy'][i]), (cols['kyx'][i], cols['kyy'][i])) for i in range(n))
    C = tuple(((cols['cxx'][i], cols['cxy'][i]), (cols['cyx'][i], cols['cyy'][i])) for i in range(n))
    return BearingTable(speeds=tuple(sp), K=K, C=C)


#: a table bearing's absent geometry (diameter, length, clearance, viscosity): one shared NaN object, so that two
#: RigParams read from equal files compare equal (tuples compare identical objects as equal)
NOT_GIVEN = float('nan')

BEARING_KEYS = ('name', 'node', 'kind', 'model', 'identify', 'diameter', 'length', 'clearance', 'viscosity',
                'cavitation', 'load', 'support', 'table')
KINDS = ('short', 'finite', 'table')


def parse_bearing(bd: dict, w: str, nn: int, default_name: str, gravity: tuple, base_dir=None,
                  seal: bool = False) -> Bearing:
    _map(bd, w)
    _keys(bd, BEARING_KEYS, w)
    if 'kind' in bd and 'model' in bd and bd['kind'] != bd['model']:
        raise ParamError(f'{w}: kind and model (its v1 name) disagree: {_short(bd["kind"])} vs {_short(bd["model"])}')
    key = 'kind' if 'kind' in bd else 'model'
    kind = _choice(bd, key, w, ('table',) if seal else KINDS, default='table' if seal else 'short')
    geo = kind != 'table'
    dflt: Any = ... if geo else NOT_GIVEN
    identify = _bool(bd, 'identify', w, not seal)
    if seal and identify:
        raise ParamError(f'{w}.identify: seals are known elements (never identified)')
    load, direction = None, None
    lv = bd.get('load')
    if isinstance(lv, list):
        vec = _numbers(lv, f'{w}.load', -1e7, 1e7, 'N')
        if len(vec) != 2 or math.hypot(*vec) == 0:
            raise ParamError(f'{w}.load must be a number [N], null, or a non-zero vector [Fx, Fy] [N], got '
                             f'{_short(lv)}')
        load = math.hypot(*vec)
        direction = (vec[0] / load, vec[1] / load)
    else:
        load = _num(bd, 'load', w, 0, 1e7, 'N', default=None, allow_none=True)
    if direction is None and tuple(gravity) != (0.0, -GRAVITY):
        g = math.hypot(*gravity)
        direction = (-gravity[0] / g, -gravity[1] / g)
    support = None
    sd = _section(bd, 'support', w, optional=True)
    if sd is not None:
        ws = f'{w}.support'
        _keys(sd, ('mass', 'stiffness', 'damping'), ws)
        support = Support(mass=_pair(sd, 'mass', ws, 1e-6, 1e7, 'kg'),
                          stiffness=_pair(sd, 'stiffness', ws, 1.0, 1e13, 'N/m'),
                          damping=_pair(sd, 'damping', ws, 0.0, 1e10, 'N s/m', default=(0.0, 0.0)))
    table = None
    if kind == 'table':
        table = parse_table(_section(bd, 'table', w), f'{w}.table', base_dir)
    elif 'table' in bd:
        raise ParamError(f"{w}.table: only a bearing of kind 'table' has a table (this one is {kind!r})")
    cav = _choice(bd, 'cavitation', w, ('swift_stieber', 'gumbel'), default='swift_stieber')
    if 'cavitation' in bd and kind != 'finite':
        raise ParamError(f"{w}.cavitation: only a 'finite' bearing has a cavitation condition (this one is {kind!r}; "
                         f"'short' is the half-Sommerfeld film already)")
    return Bearing(
        name=_text(bd, 'name', w, default_name), node=_node(bd, 'node', w, nn),
        diameter=_num(bd, 'diameter', w, 1e-4, 10, 'm', default=dflt),
        length=_num(bd, 'length', w, 1e-5, 10, 'm', default=dflt),
        clearance=_num(bd, 'clearance', w, 1e-7, 1e-2, 'm', default=dflt),
        viscosity=_num(bd, 'viscosity', w, 1e-5, 10, 'Pa s', default=dflt),
        load=load, model=kind, identify=identify, cavitation=cav, load_direction=direction, support=support,
        table=table)


def parse_probe(pd: dict, w: str, nn: int, default_name: str) -> Probe:
    _map(pd, w)
    _keys(pd, ('name', 'node', 'direction', 'angle_deg', 'gain'), w)
    if 'direction' in pd and 'angle_deg' in pd:
        raise ParamError(f'{w}: give direction (x, y) or angle_deg, not both')
    gain = _num(pd, 'gain', w, 1e-3, 1e3, '-', default=1.0)
    if 'angle_deg' in pd:
        angle = _num(pd, 'angle_deg', w, -360, 360, 'deg')
    else:
        d = pd.get('direction')
        if d is None:
            raise ParamError(f'{w}.direction is missing (x or y; or give angle_deg)')
        try:
            angle, g0 = parse_probe_direction(d) if isinstance(d, str) else (None, None)
        except ValueError:
            angle = None
        if angle is None:
            raise ParamError(f"{w}.direction must be one of ('x', 'y') or an angle text like '45deg' (or give "
                             f'angle_deg), got {_short(d)}')
        gain *= g0
    return Probe(name=_text(pd, 'name', w, default_name), node=_node(pd, 'node', w, nn),
                 direction=probe_direction(angle, gain))


def parse_rig(d: dict, base_dir=None) -> RigParams:
    """
    Validate a rig mapping (as loaded from YAML) into :class:`RigParams`.

    Every problem is a ParamError naming the field.  ``base_dir``: where relative CSV table paths start (the params
    file's folder; default the working directory).
    """
    if not isinstance(d, dict):
        raise ParamError(f'the rig file must be a YAML mapping (name:, shaft:, bearings:, ...), got {_kind(d)}')
    try:
        return _parse_rig(d, base_dir)
    except ParamError:
        raise
    except (TypeError, AttributeError, KeyError, IndexError, ValueError, ArithmeticError) as exc:
        # every field is checked above; this is the last line for a shape nobody foresaw
        raise ParamError(f'malformed rig file ({type(exc).__name__}: {_short(str(exc), 200)})') from None


RIG_KEYS = ('name', 'materials', 'shaft', 'discs', 'point_masses', 'gravity', 'bearings', 'seals', 'probes',
            'simulation', 'modal_test', 'extra')
DISC_KEYS = ('name', 'node', 'outer_diameter', 'inner_diameter', 'thickness', 'density', 'mass_factor', 'mass', 'Ip',
             'Id')


def _parse_rig(d: dict, base_dir=None) -> RigParams:
    materials = parse_materials(_section(d, 'materials', 'rig', optional=True))
    shaft = parse_shaft(_section(d, 'shaft', 'rig'), materials)
    nn = shaft.n_nodes
    gravity = (0.0, -GRAVITY)
    if d.get('gravity') is not None:
        gravity = _numbers(_list(d['gravity'], 'rig.gravity'), 'rig.gravity', -1e3, 1e3, 'm/s^2')
        if len(gravity) != 2 or math.hypot(*gravity) == 0:
            raise ParamError(f'rig.gravity must be a non-zero vector [gx, gy] [m/s^2], got {_short(d["gravity"])}')

    def outer_at(node):
        if not shaft.elements:
            return shaft.diameter
        i = node - 1
        return max(e.outer_diameter for e in shaft.elements[max(0, i - 1):i + 1])

    discs = []
    for i, dd in enumerate(_section(d, 'discs', 'rig', list, optional=True) or []):
        w = f'discs[{i}]'
        _map(dd, w)
        _keys(dd, DISC_KEYS, w)
        node = _node(dd, 'node', w, nn)
        mf = _num(dd, 'mass_factor', w, 0.01, 100, '-', default=1.0)
        if 'mass' in dd:
            geo = [k for k in ('outer_diameter', 'inner_diameter', 'thickness', 'density') if k in dd]
            if geo:
                raise ParamError(f'{w}: give the disc by mass/Ip/Id or by geometry, not both (has {geo})')
            discs.append(Disc(node=node, outer_diameter=0.0, inner_diameter=0.0, thickness=0.0, density=0.0,
                              mass_factor=mf, given_mass=_num(dd, 'mass', w, 0, 1e6, 'kg'),
                              given_Ip=_num(dd, 'Ip', w, 0, 1e6, 'kg m^2', default=0.0),
                              given_Id=_num(dd, 'Id', w, 0, 1e6, 'kg m^2', default=0.0)))
            continue
        for k in ('Ip', 'Id'):
            if k in dd:
                raise ParamError(f'{w}.{k}: a disc given by geometry has no {k} (give mass, Ip and Id instead)')
        od = _num(dd, 'outer_diameter', w, 1e-4, 10, 'm')
        idd = _num(dd, 'inner_diameter', w, 0, od, 'm', default=outer_at(node))
        discs.append(Disc(node=node, outer_diameter=od, inner_diameter=idd,
                          thickness=_num(dd, 'thickness', w, 1e-5, 10, 'm'),
                          density=_num(dd, 'density', w, 100, 30000, 'kg/m^3', default=shaft.density),
                          mass_factor=mf))
    pms = []
    for i, pd in enumerate(_section(d, 'point_masses', 'rig', list, optional=True) or []):
        w = f'point_masses[{i}]'
        _map(pd, w)
        _keys(pd, ('name', 'node', 'mass', 'Ip', 'Id'), w)
        pms.append(PointMass(node=_node(pd, 'node', w, nn), mass=_num(pd, 'mass', w, 0, 1e6, 'kg'),
                             Ip=_num(pd, 'Ip', w, 0, 1e6, 'kg m^2', default=0.0),
                             Id=_num(pd, 'Id', w, 0, 1e6, 'kg m^2', default=0.0)))
    bearings, known = [], []
    for i, bd in enumerate(_section(d, 'bearings', 'rig', list)):
        b = parse_bearing(bd, f'bearings[{i}]', nn, f'bearing{i + 1}', gravity, base_dir)
        (bearings if b.identify else known).append(b)
    if not bearings and not known:
        raise ParamError('rig.bearings is empty (a rotor needs its bearings)')
    if not bearings:
        raise ParamError('rig.bearings: no bearing to identify (every one has identify: false)')
    if len({b.node for b in bearings}) != len(bearings):
        raise ParamError('bearings: two identified bearings on one node')
    seals = [parse_bearing(sd, f'seals[{i}]', nn, f'seal{i + 1}', gravity, base_dir, seal=True)
             for i, sd in enumerate(_section(d, 'seals', 'rig', list, optional=True) or [])]
    probes = [parse_probe(pd, f'probes[{i}]', nn, f'probe{i}')
              for i, pd in enumerate(_section(d, 'probes', 'rig', list, optional=True) or [])]
    sim = None
    sd = _section(d, 'simulation', 'rig', optional=True)
    if sd is not None:
        w = 'simulation'
        td = _section(sd, 'truth', w)
        _keys(td, ('bearing_model', 'viscosity_factor', 'clearance_factor', 'k_factor', 'c_factor'), f'{w}.truth')
        nb = len(bearings)

        def per_bearing(key):
            v = td.get(key, [1.0] * nb)
            if not isinstance(v, list) or len(v) != nb:
                raise ParamError(f'simulation.truth.{key} must be a list with one factor per identified bearing '
                                 f'({nb}), got {_kind(v)} {_short(v)}')
            return _numbers(v, f'simulation.truth.{key}', 0.05, 20)

        truth = Truth(bearing_model=_choice(td, 'bearing_model', f'{w}.truth', ('short', 'finite'), default='short'),
                      viscosity_factor=per_bearing('viscosity_factor'),
                      clearance_factor=per_bearing('clearance_factor'),
                      k_factor=per_bearing('k_factor') if 'k_factor' in td else (),
                      c_factor=per_bearing('c_factor') if 'c_factor' in td else ())
        _keys(sd, ('sample_rate', 'block_size', 'speeds_rpm', 'dwell', 'ramp', 'noise', 'seed', 'truth', 'runs'), w)
        runs = []
        for j, rd in enumerate(_section(sd, 'runs', w, list)):
            wr = f'{w}.runs[{j}]'
            _map(rd, wr)
            _keys(rd, ('id', 'excitation'), wr)
            ex = tuple(parse_excitation(e, f'{wr}.excitation[{k}]', nn)
                       for k, e in enumerate(_section(rd, 'excitation', wr, list)))
            runs.append(Run(id=_text(rd, 'id', wr, chr(ord('A') + j % 26)), excitation=ex))
        speeds = _numbers(_section(sd, 'speeds_rpm', w, list), f'{w}.speeds_rpm', 0, 1e6, 'rpm')
        sim = Simulation(
            sample_rate=_num(sd, 'sample_rate', w, 10, 1e7, 'Hz'),
            block_size=_int(sd, 'block_size', w, 16, 1 << 20, default=1024),
            speeds_rpm=speeds,
            dwell=_num(sd, 'dwell', w, 1e-3, 1e5, 's'),
            ramp=_num(sd, 'ramp', w, 0, 1e4, 's', default=0.0),
            noise=_num(sd, 'noise', w, 0, 1, '-', default=0.0),
            seed=_int(sd, 'seed', w, 0, 2**31, default=0),
            truth=truth, runs=tuple(runs))
    mt = None
    md = _section(d, 'modal_test', 'rig', optional=True)
    if md is not None:
        w = 'modal_test'

        def hz(key):
            v = md.get(key)
            return () if v is None else _numbers(v, f'{w}.{key}', 0, 1e7, 'Hz')

        mt = ModalTest(measured_hz=hz('measured_hz'), paper_initial_hz=hz('paper_initial_hz'),
                       paper_updated_hz=hz('paper_updated_hz'))
        _keys(md, ('measured_hz', 'paper_initial_hz', 'paper_updated_hz'), w)
    extra = d.get('extra')
    if extra is not None and not isinstance(extra, dict):
        raise ParamError(f'rig.extra must be a mapping, got {_kind(extra)} {_short(extra)}')
    _keys(d, RIG_KEYS, 'rig')
    return RigParams(name=_text(d, 'name', 'rig', 'rig'), shaft=shaft, discs=tuple(discs), bearings=tuple(bearings),
                     probes=tuple(probes), simulation=sim, modal_test=mt, extra=dict(extra or {}),
                     point_masses=tuple(pms), known_bearings=tuple(known), seals=tuple(seals),
                     gravity=tuple(gravity), materials=tuple(materials.values()))


def load_rig(path: str | Path | None = None) -> RigParams:
    """
    Load a rig YAML file; ``None`` loads the packaged default ``params/rig.yaml``.

    Bounded reading (:func:`load_yaml_bounded`); every problem is a ParamError naming the file and the field.
    Relative CSV table paths start at the file's folder.
    """
    path = Path(path) if path is not None else default_rig_path()
    if path.is_dir():
        raise ParamError(f'cannot read parameter file {path}: it is a directory')
    data = load_yaml_bounded(path, f'parameter file {path}')
    try:
        return parse_rig(data, base_dir=path.parent)
    except ParamError as exc:
        raise ParamError(f'{path}: {exc}') from exc


def parse_probes(text: str) -> tuple[Probe, ...]:
    """
    Parse '6x,6y,3x' -> probes p6x, p6y, p3x (node numbers 1-based, direction x or y).

    'NODE@ANGLE' is a probe at ANGLE degrees from +x towards +y: '17@45,17@135' is an API 670 pair at +-45 deg from
    vertical at node 17 (probes p17a45, p17a135).
    """
    out = []
    for tok in filter(None, (s.strip() for s in text.split(','))):
        if '@' in tok:
            node, _, angle = tok.partition('@')
            try:
                a = float(angle)
                ok = node.isdigit() and -360.0 <= a <= 360.0
            except ValueError:
                ok = False
            if not ok:
                raise ParamError(f"--probes: '{tok}' is not NODE@ANGLE (e.g. 17@45: node 17, 45 deg from +x to +y)")
            out.append(Probe(f'p{node}a{angle}', int(node), probe_direction(a)))
            continue
        node, direction = tok[:-1], tok[-1]
        if direction not in ('x', 'y') or not node.isdigit():
            raise ParamError(f"--probes: '{tok}' is not NODE followed by x or y (e.g. 6x) or NODE@ANGLE (17@45)")
        out.append(Probe(f'p{node}{direction}', int(node), direction))
    if not out:
        raise ParamError('--probes: no probe given')
    return tuple(out)


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
                out['added_mass'] = [{'outer_diameter': a.outer_diameter, 'inner_diameter': a.inner_diameter,
                                      'density': a.density} for a in e.added_mass]
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
        d['point_masses'] = [{'node': p.node, 'mass': p.mass, 'Ip': p.Ip, 'Id': p.Id} for p in rig.point_masses]
    if tuple(rig.gravity) != (0.0, -GRAVITY):
        d['gravity'] = list(rig.gravity)

    def table(t):
        K = [[[float(v) for v in row] for row in k] for k in t.K]
        C = [[[float(v) for v in row] for row in c] for c in t.C]
        out = {'speed': list(t.speeds)}
        for i, a in enumerate('xy'):
            for j, b in enumerate('xy'):
                out[f'k{a}{b}'] = [k[i][j] for k in K]
                out[f'c{a}{b}'] = [c[i][j] for c in C]
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
            o['support'] = {'mass': list(b.support.mass), 'stiffness': list(b.support.stiffness),
                            'damping': list(b.support.damping)}
        if b.table is not None:
            o['table'] = table(b.table)
        return o

    d['bearings'] = [bearing(b) for b in rig.bearings] + [bearing(b) for b in rig.known_bearings]
    if rig.seals:
        d['seals'] = [bearing(b, seal=True) for b in rig.seals]
    d['probes'] = [{'name': p.name, 'node': p.node, 'direction': p.direction} for p in rig.probes]
    if rig.modal_test is not None:
        d['modal_test'] = {'measured_hz': list(rig.modal_test.measured_hz),
                           'paper_initial_hz': list(rig.modal_test.paper_initial_hz),
                           'paper_updated_hz': list(rig.modal_test.paper_updated_hz)}
    s = rig.simulation
    if s is not None:
        t = s.truth
        truth = {'bearing_model': t.bearing_model, 'viscosity_factor': list(t.viscosity_factor),
                 'clearance_factor': list(t.clearance_factor)}
        if t.k_factor:
            truth['k_factor'] = list(t.k_factor)
        if t.c_factor:
            truth['c_factor'] = list(t.c_factor)
        d['simulation'] = {'sample_rate': s.sample_rate, 'block_size': s.block_size, 'speeds_rpm': list(s.speeds_rpm),
                           'dwell': s.dwell, 'ramp': s.ramp, 'noise': s.noise, 'seed': s.seed, 'truth': truth,
                           'runs': [{'id': r.id, 'excitation': [
                               {'kind': e.kind, 'node': e.node, 'magnitude': e.magnitude, 'phase': e.phase,
                                'direction': e.direction, 'frequency_ratio': e.frequency_ratio}
                               for e in r.excitation]} for r in s.runs]}
    if rig.extra:
        d['extra'] = dict(rig.extra)
    return d


def default_rig_path() -> Path:
    """
    Return the packaged rig file: the source tree's params/, else the installed share/bearing_id/params/.

    Installed by colcon the module sits at <prefix>/lib/pythonX.Y/site-packages/bearing_id/ and the data at
    <prefix>/share/bearing_id/params/ (ament_index is asked first when it is importable).
    """
    cand = [PACKAGE_PARAMS / 'rig.yaml']
    try:
        from ament_index_python.packages import get_package_share_directory
        cand.append(Path(get_package_share_directory('bearing_id')) / 'params' / 'rig.yaml')
    except Exception:  # no ament index (plain pip / source tree) or package not registered
        pass
    here = Path(__file__).resolve()
    cand += [p / 'share' / 'bearing_id' / 'params' / 'rig.yaml' for p in here.parents[2:7]]
    for c in cand:
        if c.exists():
            return c
    raise ParamError('no default params/rig.yaml found; pass --params')


__all__ = ['ParamError', 'Material', 'AddedMass', 'Layer', 'ElementSpec', 'PointMass', 'Support', 'BearingTable',
           'Shaft', 'Disc', 'Bearing', 'Probe', 'ExcitationEntry', 'Run', 'Truth', 'Simulation',
           'ModalTest', 'RigParams', 'parse_rig', 'load_rig', 'rig_to_dict', 'default_rig_path', 'load_yaml_bounded',
           'check_yaml_events', 'GRAVITY']
