"""
ParamError, and how a parameter problem is worded: the field's path, the offending value, what was expected.

A path is ``bearings[1].clearance`` or ``materials.hub.E`` (``rig`` is the file's top level).  The schema's
validators raise :func:`problem` (the words after the path) inside pydantic, which supplies the path;
:func:`from_validation` turns pydantic's ValidationError into one ParamError of one line.
"""
from __future__ import annotations

import reprlib

from pydantic import ValidationError
from pydantic_core import PydanticCustomError


class ParamError(ValueError):
    """A parameter file or value is invalid; the message names the field."""


def short(v, n: int = 60) -> str:
    """Return the repr of a value cut to about ``n`` characters (a hostile value may be huge)."""
    r = reprlib.Repr()
    r.maxstring, r.maxother, r.maxlist, r.maxdict, r.maxlevel = n, n, 6, 6, 2
    return r.repr(v)


def kind(v) -> str:
    """Return what a YAML value is, in words: 'a mapping', 'a list', 'a string', 'a number', ..."""
    return {dict: 'a mapping', list: 'a list', str: 'a string', bool: 'a boolean', type(None): 'null'}.get(
        type(v), 'a number' if isinstance(v, (int, float)) else type(v).__name__)


def got(v) -> str:
    """Return the kind and the value for a message: "a string 'oil'", 'null'."""
    return 'null' if v is None else f'{kind(v)} {short(v)}'


def problem(tail: str, sub: str = '') -> PydanticCustomError:
    """
    Return the error a schema validator raises: ``tail`` follows the path of the field (and of ``sub`` below it).

    ``tail`` begins with its separator (' must be ...', ': unknown key ...', ' = 3.0 [m] ...'); ``sub`` names a
    field below the one validated ('.inner_diameter', '[1]').
    """
    return PydanticCustomError('param', '{tail}', {'tail': tail, 'sub': sub})


#: pydantic's own checks of a container's type: error type -> what the value must be
_EXPECTED = {'list_type': 'a list', 'dict_type': 'a mapping', 'model_type': 'a mapping (key: value)',
             'string_type': 'a name (text)', 'bool_type': 'true or false', 'literal_error': 'one of {expected}'}


def message(err: dict, root: str = 'rig') -> str:
    """Return one pydantic error as 'PATH WHAT' (a :func:`problem`, or one of pydantic's own); ``root`` names loc ()."""
    ctx = err.get('ctx') or {}
    where = ''.join(f'[{p}]' if isinstance(p, int) else f'.{p if len(p) <= 40 else short(p, 40)}' for p in err['loc'])
    if err['type'] == 'param':
        where, tail = where + ctx['sub'], ctx['tail']
    elif err['type'] in _EXPECTED:
        tail = f" must be {_EXPECTED[err['type']].format(**ctx)}, got {got(err['input'])}"
    else:
        tail = f": {err['msg']} (got {got(err['input'])})"
    return ((root if not err['loc'] else '') + where).lstrip('.') + tail


def from_validation(exc: ValidationError, limit: int = 3) -> ParamError:
    """Return one ParamError of one line listing the first ``limit`` problems of a ValidationError."""
    errs = exc.errors(include_url=False)
    more = f' (and {len(errs) - limit} more)' if len(errs) > limit else ''
    return ParamError('; '.join(message(e) for e in errs[:limit]) + more)
