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

import dataclasses
from dataclasses import dataclass, field
import math
from pathlib import Path
import reprlib
from typing import Any

import yaml

from .conventions import GRAVITY

PACKAGE_PARAMS = Path(__file__).resolve().parent.parent / 'params'


class ParamError(ValueError):
    """A parameter file or value is invalid; the message names the field."""


# ---------------------------------------------------------------------------------------------- dataclasses
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

    @property
    def mass(self) -> float:
        """Disc mass [kg]."""
        return self.mass_factor * self.density * math.pi / 4 * (self.outer_diameter**2 - self.inner_diameter**2) \
            * self.thickness

    @property
    def polar_inertia(self) -> float:
        """Polar moment of inertia Ip [kg m^2] (thick annulus)."""
        return self.mass * (self.outer_diameter**2 + self.inner_diameter**2) / 8.0

    @property
    def diametral_inertia(self) -> float:
        """Diametral moment of inertia Id [kg m^2] about a diameter through the centre (thick annulus)."""
        return self.mass * ((self.outer_diameter**2 + self.inner_diameter**2) / 16.0 + self.thickness**2 / 12.0)


@dataclass(frozen=True)
class Bearing:
    name: str
    node: int
    diameter: float               # m, journal diameter D
    length: float                 # m, bearing length L
    clearance: float              # m, radial clearance c
    viscosity: float              # Pa s
    load: float | None            # N static load (None = from the rotor's weight, see rotor.static_bearing_loads)
    model: str = 'short'          # 'short' | 'finite'


@dataclass(frozen=True)
class Probe:
    name: str
    node: int
    direction: str                # 'x' | 'y'


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
    bearing_model: str            # 'short' | 'finite'
    viscosity_factor: tuple       # per bearing, true / nominal
    clearance_factor: tuple       # per bearing, true / nominal


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

    def replace(self, **kw) -> 'RigParams':
        return dataclasses.replace(self, **kw)

    def bearing_nodes(self) -> tuple:
        return tuple(b.node for b in self.bearings)


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


def _num(d: dict, key: str, where: str, lo=None, hi=None, unit='', default: Any = ..., allow_none=False):
    _map(d, where)
    if key not in d:
        if default is ...:
            raise ParamError(f'{where}.{key} is missing ({unit})'.replace(' ()', ''))
        return default
    v = d[key]
    if v is None and allow_none:
        return None
    if isinstance(v, str):  # YAML 1.1 reads 2.06e11 (no dot, no sign) as a string
        try:
            v = float(v.strip())
        except ValueError:
            raise ParamError(f'{where}.{key} must be a number [{unit}], got {_short(v)}') from None
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


def parse_shaft(d: dict) -> Shaft:
    w = 'shaft'
    _map(d, w)
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
        damping_alpha=_num(d, 'damping_alpha', w, 0, 1e4, '1/s', default=0.0),
        damping_beta=_num(d, 'damping_beta', w, 0, 1, 's', default=0.0),
    )


def parse_excitation(d: dict, where: str, n_nodes: int) -> ExcitationEntry:
    _map(d, where)
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


def parse_rig(d: dict) -> RigParams:
    """
    Validate a rig mapping (as loaded from YAML) into :class:`RigParams`.

    Every problem is a ParamError naming the field.
    """
    if not isinstance(d, dict):
        raise ParamError(f'the rig file must be a YAML mapping (name:, shaft:, bearings:, ...), got {_kind(d)}')
    try:
        return _parse_rig(d)
    except ParamError:
        raise
    except (TypeError, AttributeError, KeyError, IndexError, ValueError, ArithmeticError) as exc:
        # every field is checked above; this is the last line for a shape nobody foresaw
        raise ParamError(f'malformed rig file ({type(exc).__name__}: {_short(str(exc), 200)})') from None


def _parse_rig(d: dict) -> RigParams:
    shaft = parse_shaft(_section(d, 'shaft', 'rig'))
    nn = shaft.n_nodes
    discs = []
    for i, dd in enumerate(_section(d, 'discs', 'rig', list, optional=True) or []):
        w = f'discs[{i}]'
        _map(dd, w)
        od = _num(dd, 'outer_diameter', w, 1e-4, 10, 'm')
        idd = _num(dd, 'inner_diameter', w, 0, od, 'm', default=shaft.diameter)
        discs.append(Disc(node=_node(dd, 'node', w, nn), outer_diameter=od, inner_diameter=idd,
                          thickness=_num(dd, 'thickness', w, 1e-5, 10, 'm'),
                          density=_num(dd, 'density', w, 100, 30000, 'kg/m^3', default=shaft.density),
                          mass_factor=_num(dd, 'mass_factor', w, 0.01, 100, '-', default=1.0)))
    bearings = []
    for i, bd in enumerate(_section(d, 'bearings', 'rig', list)):
        w = f'bearings[{i}]'
        _map(bd, w)
        bearings.append(Bearing(
            name=_text(bd, 'name', w, f'bearing{i + 1}'), node=_node(bd, 'node', w, nn),
            diameter=_num(bd, 'diameter', w, 1e-4, 10, 'm'), length=_num(bd, 'length', w, 1e-5, 10, 'm'),
            clearance=_num(bd, 'clearance', w, 1e-7, 1e-2, 'm'),
            viscosity=_num(bd, 'viscosity', w, 1e-5, 10, 'Pa s'),
            load=_num(bd, 'load', w, 0, 1e7, 'N', default=None, allow_none=True),
            model=_choice(bd, 'model', w, ('short', 'finite'), default='short')))
    if not bearings:
        raise ParamError('rig.bearings is empty (a rotor needs its bearings)')
    if len({b.node for b in bearings}) != len(bearings):
        raise ParamError('bearings: two bearings on one node')
    probes = []
    for i, pd in enumerate(_section(d, 'probes', 'rig', list, optional=True) or []):
        w = f'probes[{i}]'
        _map(pd, w)
        probes.append(Probe(name=_text(pd, 'name', w, f'probe{i}'), node=_node(pd, 'node', w, nn),
                            direction=_choice(pd, 'direction', w, ('x', 'y'))))
    sim = None
    sd = _section(d, 'simulation', 'rig', optional=True)
    if sd is not None:
        w = 'simulation'
        td = _section(sd, 'truth', w)
        nb = len(bearings)

        def per_bearing(key):
            v = td.get(key, [1.0] * nb)
            if not isinstance(v, list) or len(v) != nb:
                raise ParamError(f'simulation.truth.{key} must be a list with one factor per bearing ({nb}), got '
                                 f'{_kind(v)} {_short(v)}')
            return _numbers(v, f'simulation.truth.{key}', 0.05, 20)

        truth = Truth(bearing_model=_choice(td, 'bearing_model', f'{w}.truth', ('short', 'finite'), default='short'),
                      viscosity_factor=per_bearing('viscosity_factor'),
                      clearance_factor=per_bearing('clearance_factor'))
        runs = []
        for j, rd in enumerate(_section(sd, 'runs', w, list)):
            wr = f'{w}.runs[{j}]'
            _map(rd, wr)
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
    extra = d.get('extra')
    if extra is not None and not isinstance(extra, dict):
        raise ParamError(f'rig.extra must be a mapping, got {_kind(extra)} {_short(extra)}')
    return RigParams(name=_text(d, 'name', 'rig', 'rig'), shaft=shaft, discs=tuple(discs), bearings=tuple(bearings),
                     probes=tuple(probes), simulation=sim, modal_test=mt, extra=dict(extra or {}))


def load_rig(path: str | Path | None = None) -> RigParams:
    """
    Load a rig YAML file; ``None`` loads the packaged default ``params/rig.yaml``.

    Bounded reading (:func:`load_yaml_bounded`); every problem is a ParamError naming the file and the field.
    """
    path = Path(path) if path is not None else default_rig_path()
    if path.is_dir():
        raise ParamError(f'cannot read parameter file {path}: it is a directory')
    data = load_yaml_bounded(path, f'parameter file {path}')
    try:
        return parse_rig(data)
    except ParamError as exc:
        raise ParamError(f'{path}: {exc}') from exc


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
    cand += [p / 'share' / 'bearing_id' / 'params' / 'rig.yaml' for p in here.parents[1:6]]
    for c in cand:
        if c.exists():
            return c
    raise ParamError('no default params/rig.yaml found; pass --params')


__all__ = ['ParamError', 'Shaft', 'Disc', 'Bearing', 'Probe', 'ExcitationEntry', 'Run', 'Truth', 'Simulation',
           'ModalTest', 'RigParams', 'parse_rig', 'load_rig', 'default_rig_path', 'load_yaml_bounded',
           'check_yaml_events', 'GRAVITY']
