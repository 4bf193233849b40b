"""
Node parameters without ROS: their specs, validation, ``--help`` text and the ``params/<node>.yaml`` files.

:func:`bearing_id.nodes.declare.declare_parameters` declares them on an rclpy node; each node's ``SPECS`` list is in
its core module (``*_core.py``).  ``python -m bearing_id.nodes.specs [PARAMS_DIR]`` regenerates the three params
files after a node's SPECS changed.
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass
import importlib
import math
from pathlib import Path
import textwrap
from typing import Any

import yaml

from ..config.params import ParamError


@dataclass(frozen=True)
class ParamSpec:
    """
    One node parameter: its default, what it means (with unit) and the allowed values.

    ``lo``/``hi`` bound numbers (and every element of a number list); ``choices`` restricts strings.
    """

    name: str
    default: Any
    description: str
    unit: str = ''
    lo: float | None = None
    hi: float | None = None
    choices: tuple | None = None
    type_: str | None = None       # needed when default is None ("unset": the node falls back, e.g. to the rig file)

    @property
    def kind(self) -> str:
        if self.type_ is not None:
            return self.type_
        d = self.default
        if isinstance(d, bool):
            return 'bool'
        if isinstance(d, int):
            return 'int'
        if isinstance(d, float):
            return 'float'
        if isinstance(d, str):
            return 'str'
        if isinstance(d, (list, tuple)):
            if d and all(isinstance(x, str) for x in d):
                return 'str[]'
            if d and all(isinstance(x, int) and not isinstance(x, bool) for x in d):
                return 'int[]'
            return 'float[]'
        raise TypeError(f'parameter {self.name}: unsupported default {d!r}')

    def doc(self) -> str:
        """One line for --help and the yaml comments: description [unit]; range; default."""
        parts = [self.description + (f' [{self.unit}]' if self.unit else '')]
        if self.choices:
            parts.append('one of ' + ' | '.join(map(str, self.choices)))
        elif self.lo is not None or self.hi is not None:
            parts.append(f"range [{'' if self.lo is None else self.lo}, {'' if self.hi is None else self.hi}]")
        parts.append('default: unset' if self.default is None else f'default {self.default!r}')
        return '; '.join(parts)


def _check_number(spec: ParamSpec, v, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ParamError(f"parameter '{where}' must be a number [{spec.unit}], got {v!r}")
    if not math.isfinite(float(v)):
        raise ParamError(f"parameter '{where}' must be finite [{spec.unit}], got {v!r}")
    if (spec.lo is not None and v < spec.lo) or (spec.hi is not None and v > spec.hi):
        raise ParamError(f"parameter '{where}' = {v!r} [{spec.unit}] is outside the allowed range "
                         f'[{spec.lo}, {spec.hi}]: {spec.description}')
    return v


def validate_value(spec: ParamSpec, v):
    """Check one value against its spec; returns it (ints kept int) or raises ParamError naming the parameter."""
    kind = spec.kind
    if spec.default is None and is_unset(v):
        return None
    if kind == 'bool':
        if not isinstance(v, bool):
            raise ParamError(f"parameter '{spec.name}' must be true or false, got {v!r}")
    elif kind == 'int':
        if isinstance(v, float) and v == int(v):
            v = int(v)
        if not isinstance(v, int) or isinstance(v, bool):
            raise ParamError(f"parameter '{spec.name}' must be a whole number [{spec.unit}], got {v!r}")
        _check_number(spec, v, spec.name)
    elif kind == 'float':
        v = float(_check_number(spec, v, spec.name))
    elif kind == 'str':
        if not isinstance(v, str):
            raise ParamError(f"parameter '{spec.name}' must be a string, got {v!r}")
        if spec.choices and v not in spec.choices:
            raise ParamError(f"parameter '{spec.name}' must be one of {list(spec.choices)}, got {v!r}")
    else:
        if not isinstance(v, (list, tuple)):
            raise ParamError(f"parameter '{spec.name}' must be a list, got {v!r}")
        v = list(v)
        for i, x in enumerate(v):
            if kind == 'str[]':
                if not isinstance(x, str):
                    raise ParamError(f"parameter '{spec.name}[{i}]' must be a string, got {x!r}")
            else:
                _check_number(spec, x, f'{spec.name}[{i}]')
        if kind == 'float[]':
            v = [float(x) for x in v]
    return v


def unset_value(kind: str):
    """
    Return the typed value a parameter without a default is declared with.

    An empty list, NaN for a float, '' for a string, so that every declared parameter has a value (rclpy's
    get_parameters service -- ``ros2 param dump`` -- answers nothing at all for a request that names a declared
    parameter without one).
    """
    if kind.endswith('[]'):
        return []
    if kind == 'float':
        return float('nan')
    if kind == 'str':
        return ''
    raise TypeError(f"a parameter of kind {kind} needs a default (no 'unset' value for it)")


def is_unset(v) -> bool:
    """
    Return True for the values that mean "unset" for a parameter without a default.

    None (``[]`` in a params file reads as not set), an empty list, NaN, ''.
    """
    if v is None or (isinstance(v, (list, tuple)) and len(v) == 0) or (isinstance(v, str) and v == ''):
        return True
    return isinstance(v, float) and math.isnan(v)


INPUT_RELIABILITY = ('reliable', 'best_effort')

# Parameters every node declares (appended to its own specs by with_common()).
EXECUTORS = ('events', 'single_threaded')

COMMON_SPECS = [
    ParamSpec('input_reliability', 'reliable',
              "reliability this node's stream subscriptions request (displacement, speed, bearing displacement; "
              'sensor_driver has none): reliable = nothing lost, a slow node back-pressures the publisher; '
              'best_effort = also accepts a best-effort publisher (e.g. a DAQ driver with SensorDataQoS), but a '
              'block lost on the way is not re-sent (it is detected by its sequence number and ends the steady '
              'window). Publishers stay reliable', choices=INPUT_RELIABILITY),
    ParamSpec('machine_id', '', 'the machine this node serves: prefixes its /diagnostics status names and is their '
              "hardware_id, the coefficients' frame_id and the machine named in the identifier's record (empty: the "
              'node namespace without its leading slash; in the root namespace none, and the rig name identifies it)'),
    ParamSpec('executor', 'events',
              "how the node's callbacks are dispatched: events = rclpy's events executor (each message or timer "
              'dispatched from C++ as it arrives; a machine of three nodes took 17 % less CPU than with the stock '
              'executor, which rebuilds its wait set at every wake-up); single_threaded = '
              'rclpy.executors.SingleThreadedExecutor (the stock executor, should the events executor misbehave on '
              'a middleware)', choices=EXECUTORS),
]


def with_common(specs: list[ParamSpec]) -> list[ParamSpec]:
    """``specs`` + the :data:`COMMON_SPECS` it does not already hold: the parameters a node really declares."""
    names = {s.name for s in specs}
    return list(specs) + [c for c in COMMON_SPECS if c.name not in names]


def validate_values(specs: list[ParamSpec], values: dict) -> dict:
    """Validate ``values`` (name -> value, missing names take the default); unknown names are an error."""
    names = {s.name for s in specs}
    unknown = sorted(set(values) - names)
    if unknown:
        raise ParamError(f'unknown parameter(s) {unknown}; known: {sorted(names)}')
    return {s.name: validate_value(s, values.get(s.name, s.default)) for s in specs}


def help_epilog(specs: list[ParamSpec]) -> str:
    lines = ['ROS parameters (set with --ros-args -p name:=value or --params-file FILE):']
    for s in specs:
        lines.append(f'  {s.name}: {s.doc()}')
    return '\n'.join(lines)


PARAMS_KEY = '/**'


def yaml_block(node_name: str, specs: list[ParamSpec]) -> str:
    """
    Return the body of ``params/<node>.yaml`` for ``specs``.

    Every default written and commented; unset ones commented out.  Keyed ``/**:`` (any node name, any namespace): a
    file keyed by the node name is silently ignored when the node runs under a namespace (``/rig1/kf_estimator`` does
    not match ``kf_estimator:``).  ``node_name`` only names the node in a comment.
    """
    out = [f'{PARAMS_KEY}:  # the {node_name} node, under any namespace', '  ros__parameters:']
    for s in specs:
        out.append('')
        for ln in textwrap.wrap(s.doc(), 110) or ['']:
            out.append(f'    # {ln}')
        if s.default is None:
            out.append(f'    # {s.name}: (unset)')
            continue
        val = yaml.safe_dump({s.name: list(s.default) if isinstance(s.default, tuple) else s.default},
                             default_flow_style=True, width=1000).strip()[1:-1]
        out.append(f'    {val}')
    return '\n'.join(out) + '\n'


def write_params_file(path, node_name: str, specs: list[ParamSpec]) -> str:
    """
    (Re)write ``params/<node>.yaml``; returns the text.

    Its leading comment block (the hand-written header) is kept, the body is :func:`yaml_block` of
    ``with_common(specs)``.  Regenerate all three after changing a node's SPECS: ``python -m bearing_id.nodes.specs``.
    """
    path = Path(path)
    header = []
    if path.exists():
        for ln in path.read_text().splitlines():
            if ln.strip() and not ln.startswith('#'):
                break
            header.append(ln)
        while header and not header[-1].strip():
            header.pop()
    text = ('\n'.join(header) + '\n\n' if header else '') + yaml_block(node_name, with_common(specs))
    path.write_text(text)
    return text


PARAMS_DIR = Path(__file__).resolve().parents[2] / 'params'
NODES = ('sensor_driver', 'kf_estimator', 'identifier')


if __name__ == '__main__':  # python -m bearing_id.nodes.specs [PARAMS_DIR]: regenerate params/<node>.yaml
    from bearing_id.nodes import specs as _specs  # the module the nodes' specs refer to, not this __main__ copy
    _ap = argparse.ArgumentParser(prog='python -m bearing_id.nodes.specs',
                                  description="regenerate params/<node>.yaml from the nodes' parameter specs "
                                              '(each file keeps its comment header)')
    _ap.add_argument('params_dir', nargs='?', type=Path, default=_specs.PARAMS_DIR,
                     help='the directory holding <node>.yaml (default: %(default)s)')
    _dir = _ap.parse_args().params_dir
    if not _dir.is_dir():
        _ap.error(f'{_dir} is not a directory')
    for _node in NODES:
        _node_specs = importlib.import_module(f'bearing_id.nodes.{_node}_core').SPECS
        _specs.write_params_file(_dir / f'{_node}.yaml', _node, _node_specs)
        print(f"wrote {_dir / (_node + '.yaml')}")
