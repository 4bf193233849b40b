"""
The parameter-file API: :func:`load_rig` / :func:`parse_rig` read a rig file into :class:`RigParams`.

Reading is bounded (:mod:`.yaml_bounded`), the file is validated by its pydantic schema (:mod:`.schema`: keys, types,
units, ranges) and the machine built from it (:mod:`.build`: cross references, defaults); every problem is one
:class:`ParamError` naming the field (``bearings[1].clearance``), the value and what was expected -- never an
AttributeError/TypeError/KeyError.  :func:`rig_to_dict` writes a machine back (:mod:`.dump`);
:func:`parse_probes` reads a ``--probes`` option.  Every name other modules use is importable from here.
"""
from __future__ import annotations

from pathlib import Path

from pydantic import ValidationError

from . import build
from .dump import rig_to_dict
from .errors import from_validation, kind, ParamError
from .rig import (AddedMass, Bearing, BearingTable, Disc, ElementSpec, ExcitationEntry, Layer, Material, ModalTest,
                  PointMass, Probe, RigParams, Run, Shaft, Simulation, Support, Truth)
from .schema import RigFile
from .yaml_bounded import check_yaml_events, load_yaml_bounded
from ..conventions import GRAVITY, probe_direction

PACKAGE_PARAMS = Path(__file__).resolve().parents[2] / 'params'


def parse_rig(d: dict, base_dir=None) -> RigParams:
    """
    Validate a rig mapping (as loaded from YAML) into :class:`RigParams`.

    Every problem is a ParamError naming the field.  ``base_dir``: where relative CSV table paths start (the params
    file's folder; default the working directory).
    """
    if not isinstance(d, dict):
        raise ParamError(f'the rig file must be a YAML mapping (name:, shaft:, bearings:, ...), got {kind(d)}')
    try:
        f = RigFile.model_validate(d, context={'base_dir': base_dir})
    except ValidationError as exc:
        raise from_validation(exc) from None
    return build.rig(f)


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
           'Shaft', 'Disc', 'Bearing', 'Probe', 'ExcitationEntry', 'Run', 'Truth', 'Simulation', 'ModalTest',
           'RigParams', 'parse_rig', 'load_rig', 'rig_to_dict', 'parse_probes', 'default_rig_path', 'PACKAGE_PARAMS',
           'load_yaml_bounded', 'check_yaml_events', 'GRAVITY']
