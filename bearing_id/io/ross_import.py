"""
Import a rotor saved by ROSS 2.x (``Rotor.save``, TOML) into the params schema v2 (the ``import-ross`` bridge).

ROSS (ross-rotordynamics) is not needed: the TOML is read with :mod:`tomllib`.  What the file holds, and how it maps:

* ``ShaftElement_*`` -> ``shaft.elements`` (one entry per ROSS station ``n``), ``materials`` (ROSS's E and G_s and
  rho, named as in ROSS), ``shaft.shear_coefficient`` and ``damping_alpha``/``damping_beta`` (ROSS's per-element
  proportional damping C = alpha M + beta K, which must be the same on every element).  Several ROSS elements on the
  same station (ROSS's way of adding sleeves and impeller hubs, e.g. its compressor example) are one element (the
  stiffest, by E I) plus ``layers`` -- concentric full Timoshenko elements on the same two nodes, each with its own
  shear parameter, mass, stiffness and gyroscopics, exactly as ROSS sums them (``layers='layers'``, default), or
  mass-only ``added_mass`` layers (``layers='added_mass'``: no stiffness, the host's shape functions -- an
  approximation, 1e-3 off ROSS's eigenvalues on its compressor example).  The schema reads ``layers`` (with a
  material each, and a ``shear_coefficient`` where it is not the shaft-wide one: a layer without the key takes the
  shaft's) and a per-element ``shear_coefficient`` (:mod:`bearing_id.config.params`); the compressor example then loads
  through ``load_rig`` and ``RotorModel.from_params`` to ROSS's damped eigenvalues within 4e-10.
* Shear coefficient: ROSS's 'cowper' is ours; ROSS's 'hutchinson' lacks the square on (1 + nu) of Hutchinson (2001)
  (see :mod:`bearing_id.rotor.elements`), so it is written as the number kappa ROSS computes -- one shaft-wide
  number when all elements share it, else per element (``shear_coefficient`` on the element).
* ``DiskElement_*`` -> ``discs`` by ``mass``, ``Ip``, ``Id``; ``PointMass_*`` on a shaft node -> ``point_masses``.
* ``BearingElement_*`` (and any bearing class saved with its coefficients) -> ``bearings`` of kind ``table``;
  ``SealElement_*`` (any class with "Seal" in its name) -> ``seals``.  The table's speeds are ROSS's ``frequency``
  [rad/s] (ROSS evaluates a bearing at frequency = speed in its modal analysis, which is what a table vs speed is);
  a bearing without ``frequency`` is one constant row.  ROSS interpolates a table with a smoothing
  ``scipy.interpolate.UnivariateSpline(frequency, values)`` (s = number of rows; quadratic/linear interp1d for 3/2
  rows), which does not pass through the rows: on its compressor example the spline is up to 5e-4 of the largest
  entry off the rows.  ``table_values='ross'`` (default) writes ROSS's interpolant at the rows, so the imported
  machine equals ROSS's model at those speeds (linear in between, held flat outside -- ROSS extrapolates its
  spline); ``table_values='rows'`` writes the file's rows as they are.
* A bearing with ``n_link`` (ROSS's pedestal: the bearing links the shaft node to an extra node carrying a
  ``PointMass`` and a support bearing to ground) -> the bearing's ``support`` (pedestal mass [mx, my], stiffness and
  damping [x, y] of the support; the support must be constant and uncoupled).
* Node numbers: ROSS's 0-based station ``n`` is our 1-based node ``n + 1``.  ROSS's DOFs per node are
  [x, y, z, alpha, beta, theta]; the lateral ones [x, y, alpha, beta] are our [x, y, tx, ty] (same axes and signs,
  test/test_rotor_ross.py); axial and torsional ones (and kzz, czz) are dropped.

Refused, with the element named: tapered elements, axial force or torque, elements without shear, rotary inertia
or gyroscopics, bearing mass coefficients, per-element damping that differs, couplings, gears, unknown classes.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
import tomllib
import warnings

from scipy import interpolate
import yaml

from ..config.params import ParamError

MAX_TOML_BYTES = 50_000_000
TABLE_VALUES = ('ross', 'rows')
TABLE_REL_TOL = 1e-8    # linear interpolation of the imported samples vs ROSS's spline, of the K / C block's size
LAYERS = ('layers', 'added_mass')
COEFFS = ('kxx', 'kxy', 'kyx', 'kyy', 'cxx', 'cxy', 'cyx', 'cyy')
MASS_COEFFS = ('mxx', 'mxy', 'myx', 'myy')
REL = 1e-12


class RossImportError(ParamError):
    """The ROSS file cannot be expressed in the params schema (the message names the element and why)."""


# ------------------------------------------------------------------------------------------------- ROSS formulas
def ross_kappa(outer_d: float, inner_d: float, nu: float, method: str) -> float:
    """
    Shear coefficient kappa [-] as ROSS 2.x computes it (``ShaftElement``, ``shear_method_calc``).

    'cowper' is Cowper (1966), as ours; 'hutchinson' is ROSS's formula, with (1 + nu) where Hutchinson (2001) has
    (1 + nu)^2.
    """
    r2 = (inner_d / outer_d) ** 2
    r12 = (1.0 + r2) ** 2
    if method == 'hutchinson':
        return 6 * r12 * ((1 + nu) / ((r12 * (7 + 12 * nu + 4 * nu**2) + 4 * r2 * (5 + 6 * nu + 2 * nu**2))))
    if method == 'cowper':
        return 6 * r12 * ((1 + nu) / (r12 * (7 + 6 * nu) + r2 * (20 + 12 * nu)))
    raise ValueError(f"ROSS shear_method_calc must be 'cowper' or 'hutchinson', got {method!r}")


def ross_interpolant(frequency, values):
    """
    Return ROSS 2.x's interpolant of one bearing coefficient, ``f(speed [rad/s]) -> float``.

    As ``BearingElement._process_coefficient``: one value is constant; otherwise a default
    ``UnivariateSpline(frequency, values)`` (cubic, smoothing s = number of rows); if that fails (2 or 3 rows),
    ``interp1d`` of order rows - 1 with extrapolation.
    """
    values = [float(v) for v in values]
    if frequency is None or len(values) == 1:
        v0 = values[0]
        return lambda w: v0
    try:
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            spl = interpolate.UnivariateSpline(frequency, values)
        return lambda w: float(spl(w))
    except Exception:   # ROSS: "dfitpack.error is not exposed by scipy", a bare except
        f = interpolate.interp1d(frequency, values, kind=len(frequency) - 1, fill_value='extrapolate')
        return lambda w: float(f(w))


# ------------------------------------------------------------------------------------------------- reading
def read_toml(path) -> dict:
    """
    Read the TOML (or .json) of a ROSS rotor into a dict.

    Size-bounded; a non-ROSS or broken file is a RossImportError.  ``Rotor.save`` writes the same structure to
    either format (chosen by the extension).
    """
    p = Path(path)
    size = p.stat().st_size
    if size > MAX_TOML_BYTES:
        raise RossImportError(f'{p}: {size} bytes is larger than {MAX_TOML_BYTES} (not a rotor file?)')
    try:
        text = p.read_bytes().decode('utf-8')
        data = json.loads(text) if p.suffix.lower() == '.json' else tomllib.loads(text)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise RossImportError(f'{p}: not a readable {p.suffix.lstrip(".").upper() or "TOML"} file: {exc}') from None
    if not isinstance(data, dict):
        raise RossImportError(f'{p}: not a ROSS rotor file (top level is not a table)')
    if not any(isinstance(v, dict) and k.startswith('ShaftElement') for k, v in data.items()):
        raise RossImportError(f'{p}: no ShaftElement entries -- not a rotor saved by ROSS Rotor.save')
    return data


def _class_of(key: str) -> str:
    return key.split('_', 1)[0]


def _num(d: dict, key: str, where: str, default=None) -> float:
    v = d.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise RossImportError(f'{where}.{key} must be a finite number, got {v!r}')
    return float(v)


def _list(d: dict, key: str, where: str, n=None, default=0.0) -> list:
    v = d.get(key, default)
    v = v if isinstance(v, list) else [v]
    out = [_num({key: x}, key, where) for x in v]
    if n is not None and len(out) not in (1, n):
        raise RossImportError(f'{where}.{key} has {len(out)} values, the frequency list {n}')
    return out * n if n is not None and len(out) == 1 else out


def _same(a: float, b: float) -> bool:
    return abs(a - b) <= REL * max(abs(a), abs(b), 1e-300)


# ------------------------------------------------------------------------------------------------- conversion
def _shaft(data: dict, layers: str, notes: list) -> tuple[dict, dict, int]:
    """Return (materials, shaft section, number of shaft nodes) of the schema from ROSS's shaft elements."""
    stations: dict[int, list] = {}
    for key, d in data.items():
        if not (isinstance(d, dict) and _class_of(key) == 'ShaftElement'):
            continue
        w = f'[{key}]'
        n = d.get('n')
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise RossImportError(f'{w}.n must be a station number >= 0, got {n!r}')
        L = _num(d, 'L', w)
        idl, odl = _num(d, 'idl', w), _num(d, 'odl', w)
        idr, odr = _num(d, 'idr', w, idl), _num(d, 'odr', w, odl)
        if not (_same(idl, idr) and _same(odl, odr)):
            raise RossImportError(f'{w}: tapered element (idl {idl}, idr {idr}, odl {odl}, odr {odr} m) -- the '
                                  'schema has uniform elements only; split it into uniform ones in ROSS')
        for k in ('axial_force', 'torque'):
            if _num(d, k, w, 0.0) != 0.0:
                raise RossImportError(f'{w}.{k} = {d[k]!r}: axial force and torque stiffening are not modelled')
        for k in ('shear_effects', 'rotary_inertia', 'gyroscopic'):
            if d.get(k, True) is not True:
                raise RossImportError(f'{w}.{k} = {d[k]!r}: the model has shear, rotary inertia and gyroscopics on '
                                      'every element')
        m = d.get('material')
        if not isinstance(m, dict):
            raise RossImportError(f'{w}.material is {m!r}, not a material table (E, G_s, rho) saved with the rotor')
        wm = f'{w}.material'
        E, G, rho = _num(m, 'E', wm), _num(m, 'G_s', wm), _num(m, 'rho', wm)
        method = d.get('shear_method_calc', 'cowper')
        nu = E / (2 * G) - 1
        try:
            kappa = ross_kappa(odl, idl, nu, method)
        except ValueError as exc:
            raise RossImportError(f'{w}: {exc}') from None
        stations.setdefault(n, []).append({
            'key': key, 'L': L, 'od': odl, 'id': idl, 'E': E, 'G': G, 'rho': rho,
            'mname': str(m.get('name') or 'material'), 'method': method, 'kappa': kappa,
            'alpha': _num(d, 'alpha', w, 0.0), 'beta': _num(d, 'beta', w, 0.0), 'EI': E * (odl**4 - idl**4)})
    if not stations:
        raise RossImportError('the rotor has no shaft elements')
    ns = sorted(stations)
    if ns != list(range(len(ns))):
        missing = sorted(set(range(ns[-1] + 1)) - set(ns))
        raise RossImportError(f'shaft stations must run 0..{ns[-1]} without gaps; missing {missing[:10]}')
    every = [e for n in ns for e in stations[n]]
    alphas, betas = {e['alpha'] for e in every}, {e['beta'] for e in every}
    if len(alphas) > 1 or len(betas) > 1:
        raise RossImportError(f'ROSS proportional damping differs between elements (alpha {sorted(alphas)[:4]}, beta '
                              f'{sorted(betas)[:4]}): the schema has one shaft-wide alpha and beta')
    # materials, named as in ROSS (a second material of the same name with other values gets a suffix)
    materials: dict[str, dict] = {}

    def material(e) -> str:
        props = {'E': e['E'], 'G': e['G'], 'density': e['rho']}
        name, k = e['mname'], 1
        while name in materials and materials[name] != props:
            k += 1
            name = f"{e['mname']}_{k}"
        materials[name] = props
        return name

    methods = {e['method'] for e in every}
    hosts = [max(stations[n], key=lambda e: e['EI']) for n in ns]
    if methods == {'cowper'}:
        shear, per_element = 'cowper', False
    else:
        kap = {h['kappa'] for h in hosts}
        shear = hosts[0]['kappa']
        per_element = not all(_same(k, shear) for k in kap)
        notes.append("ROSS's 'hutchinson' shear option (kappa without the square on 1 + nu) is written as the "
                     'number kappa ROSS computes' + (' per element' if per_element else f' ({shear!r})'))
        if per_element:
            shear = 'cowper'   # shaft-wide default; every element carries its own number
    elements = []
    n_layers = 0
    for h, n in zip(hosts, ns):
        el = {'length': h['L'], 'outer_diameter': h['od'], 'inner_diameter': h['id'], 'material': material(h)}
        if per_element:
            el['shear_coefficient'] = h['kappa']
        others = [e for e in stations[n] if e is not h]
        for e in others:
            if not _same(e['L'], h['L']):
                raise RossImportError(f"[{e['key']}]: length {e['L']} m differs from {h['L']} m of [{h['key']}] on "
                                      f'the same station {n}')
        if others and layers == 'layers':
            el['layers'] = []
            for e in others:
                lay = {'outer_diameter': e['od'], 'inner_diameter': e['id'], 'material': material(e)}
                if e['method'] != 'cowper':
                    lay['shear_coefficient'] = e['kappa']
                elif shear != 'cowper':     # a layer without the key takes the shaft-wide coefficient
                    lay['shear_coefficient'] = 'cowper'
                el['layers'].append(lay)
        elif others:
            el['added_mass'] = [{'outer_diameter': e['od'], 'inner_diameter': e['id'], 'density': e['rho']}
                                for e in others]
        n_layers += len(others)
        elements.append(el)
    if n_layers:
        notes.append(f'{n_layers} ROSS elements share a station with another (sleeves, hubs): written as '
                     + ('layers (full concentric elements, as ROSS sums them)' if layers == 'layers' else
                        'added_mass (mass only, no stiffness: an approximation, about 1e-3 off ROSS)'))
    shaft = {'shear_coefficient': shear, 'damping_alpha': alphas.pop(), 'damping_beta': betas.pop(),
             'elements': elements}
    return materials, shaft, len(ns) + 1


def _table(d: dict, w: str, table_values: str) -> dict:
    freq = d.get('frequency')
    if freq is not None:
        freq = _list(d, 'frequency', w)
        n = len(freq)
        if n == 0:
            raise RossImportError(f'{w}.frequency is empty')
    else:
        n = 1
    cols = {k: _list(d, k, w, n, 0.0) for k in COEFFS}
    for k in ('kyy', 'cyy'):           # ROSS: kyy/cyy default to kxx/cxx (the saved file always has them)
        if k not in d:
            cols[k] = cols['kxx' if k == 'kyy' else 'cxx']
    for k in MASS_COEFFS:
        if any(v != 0.0 for v in _list(d, k, w, n, 0.0)):
            raise RossImportError(f'{w}.{k} is not zero: bearing mass coefficients are not in the schema')
    if freq is None:
        return {'speed': [0.0], **{k: cols[k] for k in COEFFS}}
    order = sorted(range(n), key=lambda i: freq[i])
    fs = [freq[i] for i in order]
    if any(b <= a for a, b in zip(fs, fs[1:])):
        raise RossImportError(f'{w}.frequency has repeated values')
    if table_values == 'ross' and n > 1:
        fns = {k: ross_interpolant(freq, cols[k]) for k in COEFFS}
        fs = spline_samples(fns, fs)
        out = {k: [fns[k](f) for f in fs] for k in COEFFS}
        if len(fs) >= 3:
            return {'speed': fs, **out, 'interpolation': 'cubic'}
    else:
        out = {k: [cols[k][i] for i in order] for k in COEFFS}
    return {'speed': fs, **out}


def spline_samples(fns: dict, rows: list, rel: float = TABLE_REL_TOL, max_rounds: int = 12) -> list:
    """
    Return speeds [rad/s] (the rows and points between) where a cubic spline through samples of ``fns`` fits them.

    ``fns``: {coefficient: f(speed)} (ROSS's interpolants).  Starting from the rows, every interval where the
    not-a-knot cubic spline through the samples (:mod:`bearing_id.bearings.table`, 'cubic') misses a coefficient by
    more than ``rel`` of the largest |value| of its block (K or C) over the rows, at 1/4, 1/2 or 3/4 of the interval,
    is halved; until none is (or ``max_rounds``).  ROSS's spline is a smooth piecewise cubic, so a few points suffice
    (a single cubic -- few rows, no interior knot -- needs none).
    """
    scale = {g: max(abs(fns[k](w)) for k in COEFFS if k[0] == g for w in rows) or 1.0 for g in 'kc'}
    grid = [float(w) for w in rows]
    for _ in range(max_rounds):
        if len(grid) < 3:
            return grid
        spl = {k: interpolate.CubicSpline(grid, [f(w) for w in grid]) for k, f in fns.items()}
        split = []
        for a, b in zip(grid, grid[1:]):
            ts = [a + t * (b - a) for t in (0.25, 0.5, 0.75)]
            if any(abs(spl[k](w) - f(w)) > rel * scale[k[0]] for k, f in fns.items() for w in ts):
                split.append(0.5 * (a + b))
        if not split:
            return grid
        grid = sorted(grid + split)
    return grid


def _constant_diagonal(d: dict, w: str) -> tuple:
    """((kxx, kyy), (cxx, cyy)) of a support bearing that must be constant and uncoupled."""
    rows = {k: _list(d, k, w) for k in COEFFS + MASS_COEFFS}
    for k, v in rows.items():
        if any(not _same(x, v[0]) for x in v):
            raise RossImportError(f'{w}.{k}: a pedestal support must have constant coefficients (a table is not '
                                  'supported there)')
    for k in ('kxy', 'kyx', 'cxy', 'cyx') + MASS_COEFFS:
        if rows[k][0] != 0.0:
            raise RossImportError(f'{w}.{k} = {rows[k][0]!r}: a pedestal support must be uncoupled and massless')
    kyy = rows['kyy'][0] if 'kyy' in d else rows['kxx'][0]
    cyy = rows['cyy'][0] if 'cyy' in d else rows['cxx'][0]
    return (rows['kxx'][0], kyy), (rows['cxx'][0], cyy)


def _unique(name, used: set, default: str) -> str:
    base = str(name) if name not in (None, '') else default
    out, k = base, 1
    while out in used:
        k += 1
        out = f'{base}_{k}'
    used.add(out)
    return out


def convert(data: dict, *, name: str | None = None, table_values: str = 'ross', layers: str = 'layers') -> dict:
    """
    Return the params schema v2 dict of a ROSS rotor (``read_toml`` output); ``result['_notes']`` lists the mappings.

    ``table_values``: 'ross' (ROSS's interpolant sampled at and between the rows for a cubic table,
    :func:`spline_samples`; default) or 'rows' (the file's rows as they are, linear).
    ``layers``: 'layers' (full concentric elements, exact, default) or 'added_mass' (mass only, approximate).
    """
    if table_values not in TABLE_VALUES:
        raise ValueError(f'table_values must be one of {TABLE_VALUES}, got {table_values!r}')
    if layers not in LAYERS:
        raise ValueError(f'layers must be one of {LAYERS}, got {layers!r}')
    notes = [f"ROSS {data.get('ross_version', '(version not recorded)')} rotor; ROSS station n is node n + 1; "
             'lateral DOFs [x, y, alpha, beta] = our [x, y, tx, ty]; axial/torsional DOFs dropped']
    materials, shaft, n_nodes = _shaft(data, layers, notes)
    out = {'name': name or 'ross_rotor', 'materials': materials, 'shaft': shaft}
    used: set = set()
    discs, pms, bearings, seals = [], [], [], []
    extra_mass: dict[int, list] = {}
    brg_items = []
    for key, d in data.items():
        if not isinstance(d, dict) or key in ('parameters',) or key.startswith('_'):
            continue
        cls = _class_of(key)
        w = f'[{key}]'
        if cls == 'ShaftElement':
            continue
        if cls == 'DiskElement':
            n = d.get('n')
            if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n < n_nodes:
                raise RossImportError(f'{w}.n = {n!r} is not a shaft node (0..{n_nodes - 1})')
            discs.append({'name': _unique(d.get('tag'), used, f'disc_{n + 1}'), 'node': n + 1,
                          'mass': _num(d, 'm', w), 'Ip': _num(d, 'Ip', w), 'Id': _num(d, 'Id', w)})
        elif cls == 'PointMass':
            n = d.get('n')
            mx, my = d.get('mx', d.get('m')), d.get('my', d.get('m'))
            if mx is None or my is None:
                raise RossImportError(f'{w}: needs m, or mx and my [kg]')
            mx, my = _num({'mx': mx}, 'mx', w), _num({'my': my}, 'my', w)
            if isinstance(n, bool) or not isinstance(n, int) or n < 0:
                raise RossImportError(f'{w}.n must be a node number, got {n!r}')
            if n < n_nodes:
                if not _same(mx, my):
                    raise RossImportError(f'{w}: mx {mx} != my {my} on a shaft node (point masses are isotropic here)')
                pms.append({'name': _unique(d.get('tag'), used, f'mass_{n + 1}'), 'node': n + 1, 'mass': mx})
            else:
                extra_mass.setdefault(n, []).append((mx, my, key))
        elif 'kxx' in d:
            brg_items.append((key, cls, d))
        else:
            raise RossImportError(f'{w}: ROSS class {cls} is not supported by the importer (shaft, disc, point mass, '
                                  'bearing and seal elements with saved coefficients are)')
    # pedestals: bearing(n -> n_link = k), PointMass at k, support bearing at k to ground
    supports = {}
    for key, cls, d in brg_items:
        n = d.get('n')
        if isinstance(n, int) and n >= n_nodes and d.get('n_link') is None:
            if n in supports:
                raise RossImportError(f'[{key}]: a second support bearing on extra node {n}')
            supports[n] = (key, _constant_diagonal(d, f'[{key}]'))
    for key, cls, d in brg_items:
        w = f'[{key}]'
        n = d.get('n')
        if isinstance(n, int) and n >= n_nodes and d.get('n_link') is None:
            continue
        if not isinstance(n, int) or not 0 <= n < n_nodes:
            raise RossImportError(f'{w}.n = {n!r} is not a shaft node (0..{n_nodes - 1}); bearings between extra '
                                  'nodes are not supported')
        entry = {'name': _unique(d.get('tag'), used, f'{cls.lower()}_{n + 1}'), 'node': n + 1, 'kind': 'table',
                 'table': _table(d, w, table_values)}
        link = d.get('n_link')
        if link is not None:
            if link not in supports or len(extra_mass.get(link, ())) != 1:
                raise RossImportError(f'{w}.n_link = {link!r}: a pedestal needs exactly one PointMass and one support '
                                      'bearing to ground on that extra node')
            (mx, my, _), ((kx, ky), (cx, cy)) = extra_mass.pop(link)[0], supports.pop(link)[1]
            entry['support'] = {'mass': [mx, my], 'stiffness': [kx, ky], 'damping': [cx, cy]}
            notes.append(f"{entry['name']}: ROSS n_link pedestal (extra node {link}) written as its support")
        (seals if 'Seal' in cls else bearings).append(entry)
    if supports or extra_mass:
        left = sorted(set(supports) | set(extra_mass))
        raise RossImportError(f'extra nodes {left} carry a support or point mass that no bearing links to (n_link)')
    if not bearings:
        raise RossImportError('the rotor has no bearing elements (the schema needs at least one bearing)')
    if discs:
        out['discs'] = discs
    if pms:
        out['point_masses'] = pms
    out['bearings'] = bearings
    if seals:
        out['seals'] = seals
    if table_values == 'ross' and any(len(b['table']['speed']) > 1 for b in bearings + seals):
        notes.append(f"bearing and seal tables: ROSS's interpolant (its smoothing spline) sampled at the rows and "
                     f'between them so that a cubic spline through the samples (interpolation: cubic) is within '
                     f'{TABLE_REL_TOL:g} of it (of the K or C block); outside the rows the first or last value is '
                     f'held and flagged where used (ROSS extrapolates its spline)')
    out['_notes'] = notes
    return out


# ------------------------------------------------------------------------------------------------- YAML
def to_yaml(params: dict, source: str = '') -> str:
    """YAML text of ``convert``'s dict: a header with the notes, lists of numbers on one line, floats exact."""

    class Dumper(yaml.SafeDumper):
        pass

    def represent_list(dumper, v):
        flow = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
        return dumper.represent_sequence('tag:yaml.org,2002:seq', v, flow_style=flow)

    Dumper.add_representer(list, represent_list)
    body = {k: v for k, v in params.items() if not k.startswith('_')}
    head = [f'# Imported from {source} by bearing-id import-ross.' if source else '# Imported by bearing-id '
            'import-ross.']
    head += [f'# {n}' for n in params.get('_notes', ())]
    head += ['# Probes, simulation and modal_test sections are not in a ROSS file: add them to simulate/identify.']
    return '\n'.join(head) + '\n' + yaml.dump(body, Dumper=Dumper, sort_keys=False, width=120)


def import_ross(path, out=None, *, name: str | None = None, table_values: str = 'ross',
                layers: str = 'layers') -> dict:
    """Read ROSS's TOML ``path``, convert it (:func:`convert`), write the YAML to ``out`` if given; return the dict."""
    path = Path(path)
    params = convert(read_toml(path), name=name or path.stem, table_values=table_values, layers=layers)
    if out is not None:
        Path(out).write_text(to_yaml(params, path.name))
    return params


__all__ = ['import_ross', 'convert', 'read_toml', 'to_yaml', 'ross_kappa', 'ross_interpolant', 'spline_samples',
           'RossImportError', 'TABLE_VALUES', 'LAYERS']
