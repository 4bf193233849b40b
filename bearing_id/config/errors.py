"""
ParamError and the one way a parameter problem becomes its message: ``FIELD PATH`` + what is wrong.

A message names the field as a path into the file (``bearings[1].clearance``, ``materials.hub.E``; ``rig`` for the
top level), the offending value (cut short: a hostile value may be huge) and what was expected.  The schema
(:mod:`.fields`, :mod:`.schema`) raises :func:`problem` inside pydantic, which adds the location;
:func:`from_validation` turns pydantic's ValidationError into one ParamError of one line.
"""
from __future__ import annotations

import reprlib

from pydantic import ValidationError
from pydantic_core import PydanticCustomError


class ParamError(ValueError):
    """A parameter file or value is invalid; the message names the field."""


def short(v, n: int = 60) -> str:
    """Return the repr of a value for a message, cut to ``n`` characters."""
    r = reprlib.Repr()
    r.maxstring, r.maxother, r.maxlist, r.maxdict, r.maxlevel = n, n, 6, 6, 2
    return r.repr(v)


def kind(v) -> str:
    """Return what a YAML value is, in words ('a mapping', 'a list', 'a number', ...)."""
    return {dict: 'a mapping', list: 'a list', str: 'a string', bool: 'a boolean', type(None): 'null'}.get(
        type(v), 'a number' if isinstance(v, (int, float)) else type(v).__name__)


def got(v) -> str:
    """Return 'a string 'oil'' -- the kind and the value, for the end of a message."""
    return 'null' if v is None else f'{kind(v)} {short(v)}'


def problem(tail: str, sub: str = '') -> PydanticCustomError:
    """
    Return the error a schema validator raises: ``tail`` follows the field's path (and ``sub`` below it).

    ``tail`` starts with what separates it from the path (' must be ...', ': unknown key ...', ' = 3.0 ...');
    ``sub`` names a field below the one being validated ('.inner_diameter', '.csv.kxx[2]').
    """
    return PydanticCustomError('param', '{tail}', {'tail': tail, 'sub': sub})


def path(loc) -> str:
    """Return pydantic's location ('bearings', 1, 'clearance') as 'bearings[1].clearance'."""
    out = ''
    for part in loc:
        if isinstance(part, int):
            out += f'[{part}]'
        elif part == '[key]':              # a mapping's key is what is wrong
            out += ' (a key)'
        else:
            name = part if len(part) <= 40 else short(part, 40)
            out += f'.{name}' if out else name
    return out


#: pydantic's own checks (those the schema leaves to it): error type -> what the field must be
_EXPECTED = {'list_type': 'a list', 'tuple_type': 'a list', 'dict_type': 'a mapping', 'string_type': 'text',
             'bool_type': 'true or false', 'model_type': 'a mapping (key: value)'}


def split(err: dict) -> tuple[str, str]:
    """Return (field path, what is wrong) of one pydantic error (a :func:`problem`, or one of pydantic's own)."""
    where, ctx, typ = path(err['loc']), err.get('ctx') or {}, err['type']
    if typ == 'param':
        return where + ctx['sub'], ctx['tail']
    if typ == 'missing':
        return where, ' is missing'
    if typ == 'extra_forbidden':
        return where, ': unknown key'
    if typ in _EXPECTED:
        return where, f" must be {_EXPECTED[typ]}, got {got(err['input'])}"
    return where, f": {err['msg']} (got {got(err['input'])})"


def message(err: dict) -> str:
    """Return the one-line message of one pydantic error; 'rig' names the file's top level."""
    where, tail = split(err)
    return (f'rig{where}' if where[:1] in ('', '.') else where) + tail


def from_validation(exc: ValidationError, limit: int = 3) -> ParamError:
    """Return one ParamError of one line listing the first ``limit`` problems of a ValidationError."""
    errs = exc.errors(include_url=False)
    text = '; '.join(message(e) for e in errs[:limit])
    if len(errs) > limit:
        text += f' (and {len(errs) - limit} more)'
    return ParamError(text)
