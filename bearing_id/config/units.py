"""
Numbers with a unit in parameter files ("12.65 mm", "3000 rpm", "50 um") converted to SI through pint.

Only text of the form NUMBER UNIT reaches pint: pint evaluates expressions ('9**9**9 m' would never return), so the
text is matched first against :data:`UNIT_TEXT` (a decimal number, then unit names joined by spaces, '*', '/' or '.',
each with at most a one-digit power).  pint is imported, and its registry built, on the first such string: importing
pint alone costs about 0.1 s of every process's start, and files of plain numbers never need it.
"""
from __future__ import annotations

import re

from .errors import short

#: unit as written in messages (the field's SI unit) -> the pint unit it converts to
PINT_UNIT = {'m': 'm', 'Pa': 'Pa', 'kg/m^3': 'kg/m**3', 'Pa s': 'Pa*s', 'N': 'N', 'rpm': 'rpm', 'Hz': 'Hz', 's': 's',
             '1/s': '1/s', 'N/m': 'N/m', 'N s/m': 'N*s/m', 'kg m': 'kg*m', 'kg m^2': 'kg*m**2', 'kg': 'kg',
             'deg': 'deg', 'rad': 'rad', 'rad/s': 'rad/s', 'm/s^2': 'm/s**2', '-': 'dimensionless'}
_UNIT_NAME = r'[A-Za-z\u00b5\u03bc\u00b0\u2126_]+(?:(?:\*\*|\^)-?\d)?'
UNIT_TEXT = re.compile(r'\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d{1,3})?)\s*('
                       + rf'(?:1\s*/\s*)?{_UNIT_NAME}(?:\s*[*/.\u00b7]?\s*{_UNIT_NAME})*' + r')\s*$')
_UREG = None


def _registry():
    """Return pint's unit registry, imported and built on first use (module docstring)."""
    global _UREG
    if _UREG is None:
        import pint
        _UREG = pint.UnitRegistry()
    return _UREG


def to_si(text: str, unit: str) -> float:
    """
    Return ``text`` ('12.65 mm') as a number in the SI ``unit`` of the field (a key of :data:`PINT_UNIT`).

    Raises ValueError whose message follows the field's name: ' must be a number [m] or a number with a unit ...'
    (not NUMBER UNIT, or a unit pint does not know), ' = '12.65 kg' has the wrong unit ...' (another dimension), or
    ' must be a number [...] ... (units are not accepted here)' for a field without a unit.
    """
    target = PINT_UNIT.get(unit)
    if target is None:
        raise ValueError(f' must be a number [{unit}], got {short(text)} (units are not accepted here)')
    m = UNIT_TEXT.match(text) if len(text) <= 200 else None
    expect = f' must be a number [{unit}] or a number with a unit such as "12.65 mm", got {short(text)}'
    if m is None:
        raise ValueError(expect)
    try:
        q = _registry().Quantity(float(m.group(1)), m.group(2))
    except Exception:  # pint raises its own errors (UndefinedUnitError, DefinitionSyntaxError, ...) and others
        raise ValueError(expect + ' (unknown unit)') from None
    try:
        return float(q.to(target).magnitude) if hasattr(q, 'to') else float(q)
    except Exception:
        raise ValueError(f' = {short(text)} has the wrong unit: expected {unit} (or a unit of the same '
                         f'dimension)') from None
