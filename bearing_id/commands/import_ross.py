"""
``bearing-id import-ross ROTOR.toml --out machine.yaml``: a rotor saved by ROSS 2.x into the params schema v2.

Reads the TOML written by ROSS's ``Rotor.save`` (ROSS itself is not needed) and writes a params file with the
shaft elements, materials, discs, bearings and seals as tables vs speed, pedestals as supports (see
:mod:`bearing_id.io.ross_import` for every mapping).  Prints what was imported and the mappings it made, then loads
the file it wrote (exit 1 with a warning if this params version cannot load it).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ..config.params import load_rig, ParamError
from ..io.ross_import import import_ross, LAYERS, TABLE_VALUES, to_yaml


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser('import-ross', help='convert a rotor saved by ROSS (Rotor.save, TOML) into a params YAML',
                       description='Read a rotor saved by ROSS 2.x (Rotor.save, .toml) and write it as a bearing_id '
                                   'params file (schema v2): shaft elements and materials, discs by m/Ip/Id, '
                                   'bearings and seals as K, C tables vs speed, pedestals as supports.')
    p.add_argument('rotor', help='ROSS rotor file (.toml written by Rotor.save)')
    p.add_argument('--out', required=True, help='params YAML to write')
    p.add_argument('--name', help='machine name (default: the file name without extension)')
    p.add_argument('--table-values', choices=TABLE_VALUES, default='ross',
                   help="'ross' (default): ROSS's smoothing spline at the table's speeds, so the model equals "
                        "ROSS's there; 'rows': the file's rows as they are")
    p.add_argument('--layers', choices=LAYERS, default='layers',
                   help="several ROSS elements on one station: 'layers' (default, full concentric elements, exact) "
                        "or 'added_mass' (mass only, about 1e-3 off ROSS's eigenvalues)")
    return p


def run(args) -> int:
    out = Path(args.out)
    params = import_ross(args.rotor, None, name=args.name, table_values=args.table_values, layers=args.layers)
    text = to_yaml(params, Path(args.rotor).name)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    sh = params['shaft']['elements']
    n_layers = sum(len(e.get('layers', ())) + len(e.get('added_mass', ())) for e in sh)
    print(f'{out}: {len(sh)} shaft elements ({n_layers} layers), {len(params.get("discs", []))} discs, '
          f'{len(params.get("point_masses", []))} point masses, {len(params["bearings"])} bearings, '
          f'{len(params.get("seals", []))} seals')
    for note in params['_notes']:
        print(f'  {note}')
    try:                                # the file must load: say so now, not at the first use
        load_rig(out)
    except ParamError as exc:
        print(f'warning: {out} does not load with this version of the params schema: {exc}'
              + (' (--layers added_mass writes a loadable approximation)' if n_layers else ''))
        return 1
    return 0
