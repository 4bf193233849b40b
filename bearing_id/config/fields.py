"""
The value types of the parameter-file schema and its base model, for pydantic v2.

Each value type (:class:`Num`, :class:`Numbers`, :class:`Choice`, :class:`Text`, :class:`Flag`, :class:`Pair`,
:class:`Shear`, :class:`Load`, :class:`Direction`) is pydantic metadata that validates one YAML value the way an
engineer writes it and raises :func:`.errors.problem` with what was expected: a number is finite, within its range
and in SI units -- or text NUMBER UNIT converted by :func:`.units.to_si` ("12.65 mm"); YAML 1.1's '1e9' (a string) is
a number too; a boolean is never a number.  :class:`Section` is the base of every mapping of the file: it must be a
mapping, its unknown keys are refused with a did-you-mean, a missing required key is named with its unit.
"""
from __future__ import annotations

import difflib
import math
from typing import Any

from pydantic import BaseModel, ConfigDict, model_validator, ValidationInfo
from pydantic_core import core_schema, PydanticCustomError

from .errors import got, problem, short
from .units import to_si
from ..conventions import parse_probe_direction


class _Plain:
    """Pydantic metadata whose :meth:`check` is the whole validation of the value (a plain validator)."""

    expect = ''

    def check(self, v):
        raise NotImplementedError

    def __get_pydantic_core_schema__(self, source, handler):
        return core_schema.no_info_plain_validator_function(self.check)


class Num(_Plain):
    """
    A number [``unit``] within [``lo``, ``hi``] (None: no bound).

    ``whole``: an integer (returned as int); ``positive``: also > 0 (a modulus); ``null``: None passes (null).
    """

    def __init__(self, unit: str = '-', lo: float | None = None, hi: float | None = None, *, whole: bool = False,
                 positive: bool = False, null: bool = False):
        self.unit, self.lo, self.hi, self.whole, self.positive, self.null = unit, lo, hi, whole, positive, null
        self.expect = unit

    def check(self, v):
        unit = f' [{self.unit}]' if self.unit else ''
        if v is None and self.null:
            return None
        if isinstance(v, str):   # YAML 1.1 reads 2e11 (no dot) as a string; else a number with a unit
            try:
                v = float(v.strip())
            except ValueError:
                try:
                    v = to_si(v.strip(), self.unit)
                except ValueError as exc:
                    raise problem(str(exc)) from None
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise problem(f' must be a number{unit}, got {got(v)}')
        try:
            v = float(v)
        except OverflowError:    # an integer beyond the float range
            raise problem(f' = {short(v)}{unit} is out of range') from None
        if not math.isfinite(v):
            raise problem(f' must be finite{unit}, got {v!r}')
        if self.hi is None and v < self.lo:
            raise problem(f' = {v!r}{unit} must be >= {self.lo}')
        if self.lo is not None and v < self.lo or self.hi is not None and v > self.hi:
            raise problem(f' = {v!r}{unit} is outside the allowed range [{self.lo}, {self.hi}]')
        if self.positive and not v > 0.0:
            raise problem(f' = {v!r}{unit} must be > 0')
        if self.whole:
            if v != int(v):
                raise problem(f' must be a whole number, got {v!r}')
            return int(v)
        return v


class Numbers(_Plain):
    """A list of numbers [``unit``] within [``lo``, ``hi``], read as a tuple (an item's error names its index)."""

    def __init__(self, unit: str = '-', lo: float | None = None, hi: float | None = None):
        self.num = Num(unit, lo, hi)
        self.expect = f'a list of numbers [{unit}]'

    def check(self, v):
        if not isinstance(v, list):
            raise problem(f' must be {self.expect}, got {got(v)}')
        return tuple(at(f'[{i}]', self.num.check, x) for i, x in enumerate(v))


class Choice(_Plain):
    """One of the given words."""

    def __init__(self, *options: str):
        self.options = options
        self.expect = f'one of {options}'

    def check(self, v):
        if not isinstance(v, str) or v not in self.options:
            raise problem(f' must be one of {self.options}, got {short(v)}')
        return v


class Text(_Plain):
    """A name: text (a number is accepted and kept as text; null means 'not given' and stays None)."""

    def check(self, v):
        if v is None or isinstance(v, str):
            return v
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise problem(f' must be a name (text), got {got(v)}')
        return str(v)


class Flag(_Plain):
    """True or false."""

    def check(self, v):
        if not isinstance(v, bool):
            raise problem(f' must be true or false, got {got(v)}')
        return v


class Pair(_Plain):
    """A number [``unit``] (the same in x and y) or a list [x, y] of two; read as the tuple (x, y)."""

    def __init__(self, unit: str, lo: float, hi: float):
        self.num = Num(unit, lo, hi)
        self.expect = unit

    def check(self, v):
        if not isinstance(v, list):
            x = self.num.check(v)
            return (x, x)
        if len(v) != 2:
            raise problem(f' must be a number or a list [x, y] of two [{self.num.unit}], got {short(v)}')
        return tuple(at(f'[{i}]', self.num.check, x) for i, x in enumerate(v))


class Shear(_Plain):
    """The shear coefficient: 'hutchinson', 'cowper' or a number kappa in [0.1, 2]."""

    METHODS = ('hutchinson', 'cowper')

    def check(self, v):
        if isinstance(v, str) and v in self.METHODS:
            return v
        try:
            return Num('-', 0.1, 2.0).check(v)
        except PydanticCustomError as exc:
            raise problem(f"{exc.context['tail']} (or one of {self.METHODS})") from None


class Load(_Plain):
    """A bearing's static load: a number [N] >= 0, null (from statics), or the film force [Fx, Fy] [N], non-zero."""

    def check(self, v):
        if not isinstance(v, list):
            return Num('N', 0, 1e7, null=True).check(v)
        vec = tuple(at(f'[{i}]', Num('N', -1e7, 1e7).check, x) for i, x in enumerate(v))
        if len(vec) != 2 or math.hypot(*vec) == 0:
            raise problem(f' must be a number [N], null, or a non-zero vector [Fx, Fy] [N], got {short(v)}')
        return vec


class Direction(_Plain):
    """A probe axis: 'x', 'y' or an angle text such as '45deg' or '45deg*1.02' (:mod:`bearing_id.conventions`)."""

    def check(self, v):
        try:
            ok = isinstance(v, str) and parse_probe_direction(v) is not None
        except ValueError:
            ok = False
        if not ok:
            raise problem(f" must be one of ('x', 'y') or an angle text like '45deg' (or give angle_deg), got "
                          f'{short(v)}')
        return v


def at(sub: str, fn, *args):
    """Run ``fn(*args)``, naming the sub-field ``sub`` ('[1]', '.magnitude') in the :func:`problem` it raises."""
    try:
        return fn(*args)
    except PydanticCustomError as exc:
        raise problem(exc.context['tail'], sub + exc.context['sub']) from None


class Section(BaseModel):
    """
    A mapping of the file: refuses anything but a mapping, unknown keys (with the nearest known one) and a missing key.

    ``_keys(data)`` and ``_required(data)`` give the allowed and the required keys for the data at hand (a subclass
    may make them depend on which keys are there: a v1 or a v2 shaft); ``_prepare(data, info)`` may replace the data
    first (a table read from a CSV file).
    """

    model_config = ConfigDict(extra='forbid', arbitrary_types_allowed=True)

    @classmethod
    def _keys(cls, d: dict) -> tuple:
        return tuple(f.alias or name for name, f in cls.model_fields.items())

    @classmethod
    def _required(cls, d: dict) -> tuple:
        return tuple(f.alias or name for name, f in cls.model_fields.items() if f.is_required())

    @classmethod
    def _prepare(cls, d: dict, info: ValidationInfo) -> dict:
        return d

    @classmethod
    def missing(cls, key: str, why: str = ''):
        """Return the error for ``key`` of this mapping not given, with its unit or choices and ``why``."""
        f = cls.model_fields.get(key)
        expect = getattr(cls, 'EXPECT', {}).get(key) or next(
            (m.expect for m in (f.metadata if f else ()) if getattr(m, 'expect', '')), '')
        note = '; '.join(x for x in (expect, why) if x)
        return problem(f' is missing ({note})' if note else ' is missing', f'.{key}')

    @model_validator(mode='before')
    @classmethod
    def _mapping(cls, d: Any, info: ValidationInfo) -> Any:
        if isinstance(d, cls):
            return d
        if not isinstance(d, dict):
            raise problem(f' must be a mapping (key: value), got {got(d)}')
        d = cls._prepare(d, info)
        if isinstance(d, cls):
            return d
        allowed = cls._keys(d)
        for k in d:
            if not isinstance(k, str) or k not in allowed:
                near = difflib.get_close_matches(str(k), allowed, n=1, cutoff=0.6)
                hint = f' (did you mean {near[0]}?)' if near else f" (known: {', '.join(sorted(allowed))})"
                name = k if isinstance(k, str) and len(k) <= 40 else short(k, 40)
                raise problem(f': unknown key{hint}', f'.{name}')
        for k in cls._required(d):
            if k not in d:
                raise cls.missing(k)
        return d

    def given(self, *keys: str) -> list:
        """Return those of ``keys`` the file gives (even as null)."""
        return [k for k in keys if k in self.model_fields_set]
