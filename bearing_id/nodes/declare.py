"""Declaring a node's parameters on an rclpy node: descriptors (description, unit, range, read-only) and validation."""
from __future__ import annotations

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
    return validate_values(specs, values)
