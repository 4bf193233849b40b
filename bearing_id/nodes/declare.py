"""Declaring a node's parameters on an rclpy node: descriptors (description, unit, range, read-only) and validation."""
from __future__ import annotations

import difflib
import sys

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException, ParameterException
from rclpy.parameter import Parameter

from .specs import ParamSpec, unset_value, validate_values, with_common
from ..config.params import ParamError


def declare_parameters(node, specs: list[ParamSpec]) -> dict:
    """
    Declare ``specs`` + :data:`COMMON_SPECS` on an rclpy node with descriptors and return the validated values.

    Descriptors: description + unit, numeric ranges, read-only.  Raises ParamError naming the parameter on any bad
    value.

    Every parameter is declared with a value, so ``ros2 param dump`` / ``get_parameters`` answer for all of them: one
    without a default gets its :func:`unset_value` ([] / NaN / '') and dynamic typing (an empty list has no element
    type in rclpy, and a params file sets the typed value); its validated python value stays None.
    """
    values = {}
    specs = with_common(specs)
    for s in specs:
        desc = ParameterDescriptor(description=s.doc(), read_only=True)
        kind = s.kind
        if s.default is None:
            desc.dynamic_typing = True      # type checked by validate_value; no range (NaN is not in one)
        elif kind in ('float', 'float[]') and (s.lo is not None or s.hi is not None):
            desc.floating_point_range = [FloatingPointRange(
                from_value=float(-sys.float_info.max if s.lo is None else s.lo),
                to_value=float(sys.float_info.max if s.hi is None else s.hi), step=0.0)]
        if s.default is not None and kind in ('int', 'int[]') and (s.lo is not None or s.hi is not None):
            desc.integer_range = [IntegerRange(from_value=int(-2**62 if s.lo is None else s.lo),
                                               to_value=int(2**62 if s.hi is None else s.hi), step=1)]
        if s.choices:
            desc.additional_constraints = 'one of: ' + ', '.join(map(str, s.choices))
        default = list(s.default) if isinstance(s.default, tuple) else s.default
        # `[]` in a params file (what `ros2 param dump` writes for an unset list) reads as NOT_SET: declare the
        # sentinel instead, so that a dump of this node shows [] again (a NOT_SET value dumps as null, which a params
        # file reads as the string 'null')
        ignore = False
        if default is None:
            default = unset_value(kind)
            override = getattr(node, '_parameter_overrides', {}).get(s.name)
            ignore = override is not None and override.type_ == Parameter.Type.NOT_SET
        try:
            p = node.declare_parameter(s.name, default, desc, ignore_override=ignore)
        except (InvalidParameterValueException, InvalidParameterTypeException, ParameterException, TypeError) as exc:
            text = str(exc).split('\n')[0]
            raise ParamError(f"parameter '{s.name}': {text} (expected {s.doc()})") from None
        values[s.name] = p.value
    check_overrides(getattr(node, '_parameter_overrides', {}), specs)
    return validate_values(specs, values)


# parameters rclpy declares on every node, or reads from overrides itself
ROS_PARAMETERS = ('use_sim_time', 'start_type_description_service')


def check_overrides(overrides, specs: list[ParamSpec]) -> None:
    """
    Raise ParamError for a parameter given to the node (params file or ``-p``) that it does not have.

    rclpy ignores such a value and the node would run on its default: a misspelled ``proces_noise`` must not pass as
    a tuned filter.  The message names the key and the nearest known one.  rclpy's own parameters and QoS overrides
    (``qos_overrides.*``) are known.
    """
    known = {s.name for s in specs} | set(ROS_PARAMETERS)
    unknown = sorted(k for k in overrides if k not in known and not k.startswith('qos_overrides.'))
    if not unknown:
        return
    hints = []
    for k in unknown:
        near = difflib.get_close_matches(k, sorted(known), n=1, cutoff=0.6)
        hints.append(f"'{k}'" + (f" (did you mean '{near[0]}'?)" if near else ''))
    raise ParamError(f"unknown parameter(s) {', '.join(hints)}: this node has {', '.join(s.name for s in specs)}")
