"""
The value types of the parameter-file schema, and :class:`Section`, the base of its pydantic models.

A value type is pydantic metadata (``Annotated[float, Num('m', 1e-4, 10)]``) whose ``check`` is the whole validation
of one YAML value, raising :func:`.errors.problem` with what was expected.  A number is finite, within its range and
in SI units, or text NUMBER UNIT converted by :func:`.units.to_si` ("12.65 mm"); YAML 1.1's '1e9' (a string) is a
number too, a boolean never is.  A :class:`Section` must be a mapping; an unknown key is refused with the nearest
known one, a missing key is named with its unit.
"""
from __future__ import annotations

import difflib
import math
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, model_validator, ValidationInfo
from pydantic_core import core_schema, PydanticCustomError

from .errors import got, problem, short
from .units import to_si
from ..conventions import parse_probe_direction


class Check:
    """Pydantic metadata: :meth:`check` validates and converts the value; ``expect`` says what it must be."""

    expect = ''

    def check(self, v):
        return v

    def __get_pydantic_core_schema__(self, source, handler):
        return core_schema.no_info_plain_validator_function(self.check)


class Num(Check):
    """A number [``unit``] in [``lo``, ``hi``]; ``whole``: an int; ``positive``: > 0 too; ``null``: None passes."""

    def __init__(self, unit: str = '-', lo: float | None = None, hi: float | None = None, *, whole: bool = False,
                 positive: bool = False, null: bool = False):
        self.unit, self.lo, self.hi, self.whole, self.positive, self.null = unit, lo, hi, whole, positive, null
        self.expect = unit

    def check(self, v):
        unit = f' [{self.unit}]' if self.unit else ''
        if v is None and self.null:
            return None
        if isinstance(v, str):
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
        if self.whole and v != int(v):
            raise problem(f' must be a whole number, got {v!r}')
        return int(v) if self.whole else v


def at(sub: str, fn, *args):
    """Return ``fn(*args)``; its :func:`problem` names the sub-field ``sub`` ('[1]')."""
    try:
        return fn(*args)
    except PydanticCustomError as exc:
        raise problem(exc.context['tail'], sub + exc.context['sub']) from None


class Numbers(Check):
    """A list of numbers [``unit``] in [``lo``, ``hi``], read as a tuple."""

    def __init__(self, unit: str = '-', lo: float | None = None, hi: float | None = None):
        self.num = Num(unit, lo, hi)
        self.expect = f'a list of numbers [{unit}]'

    def check(self, v):
        if not isinstance(v, list):
            raise problem(f' must be {self.expect}, got {got(v)}')
        return tuple(at(f'[{i}]', self.num.check, x) for i, x in enumerate(v))


class Pair(Numbers):
    """A number [``unit``] (the same in x and y) or a list [x, y], read as the tuple (x, y)."""

    def check(self, v):
        if not isinstance(v, list):
            return (self.num.check(v),) * 2
        if len(v) != 2:
            raise problem(f' must be a number or a list [x, y] of two [{self.num.unit}], got {short(v)}')
        return super().check(v)


class Shear(Check):
    """A shear coefficient: 'hutchinson', 'cowper' or a number kappa in [0.1, 2]."""

    METHODS = ('hutchinson', 'cowper')

    def check(self, v):
        if isinstance(v, str) and v in self.METHODS:
            return v
        try:
            return Num('-', 0.1, 2.0).check(v)
        except PydanticCustomError as exc:
            raise problem(f"{exc.context['tail']} (or one of {self.METHODS})") from None


class Load(Check):
    """A static load: a number [N] >= 0, null (from statics) or the film force on the journal [Fx, Fy] [N] != 0."""

    def check(self, v):
        if not isinstance(v, list):
            return Num('N', 0, 1e7, null=True).check(v)
        vec = Numbers('N', -1e7, 1e7).check(v)
        if len(vec) != 2 or math.hypot(*vec) == 0:
            raise problem(f' must be a number [N], null, or a non-zero vector [Fx, Fy] [N], got {short(v)}')
        return vec


class Direction(Check):
    """A probe axis: 'x', 'y' or an angle text ('45deg', '45deg*1.02': :mod:`bearing_id.conventions`)."""

    def check(self, v):
        try:
            if isinstance(v, str) and parse_probe_direction(v):
                return v
        except ValueError:
            pass
        raise problem(f" must be one of ('x', 'y') or an angle text like '45deg' (or give angle_deg), got {short(v)}")


class Section(BaseModel):
    """
    A mapping of the file (a pydantic model): a mapping, no unknown key, no missing required key.

    ``allowed(data)`` and ``required(data)`` may depend on the keys present (a v1 or a v2 shaft); ``prepare(data,
    info)`` may replace the data first (a table from a CSV file).  ``EXPECT`` words a key's expectation by hand.
    """

    model_config = ConfigDict(extra='forbid', coerce_numbers_to_str=True)
    EXPECT: ClassVar[dict] = {}

    @classmethod
    def allowed(cls, d: dict) -> tuple:
        return tuple(f.alias or k for k, f in cls.model_fields.items())

    @classmethod
    def required(cls, d: dict) -> tuple:
        return tuple(f.alias or k for k, f in cls.model_fields.items() if f.is_required())

    @classmethod
    def prepare(cls, d: dict, info: ValidationInfo):
        return d

    @classmethod
    def missing(cls, key: str, why: str = '') -> PydanticCustomError:
        """Return the error for ``key`` not given: its unit or choices, and ``why``."""
        f = cls.model_fields.get(key)
        expect = cls.EXPECT.get(key) or next((m.expect for m in (f.metadata if f else ()) if
                                              getattr(m, 'expect', '')), '')
        note = '; '.join(x for x in (expect, why) if x)
        return problem(f' is missing ({note})' if note else ' is missing', f'.{key}')

    @model_validator(mode='before')
    @classmethod
    def _mapping(cls, d: Any, info: ValidationInfo) -> Any:
        if not isinstance(d, dict):
            raise problem(f' must be a mapping (key: value), got {got(d)}')
        d = cls.prepare(d, info)
        allowed = cls.allowed(d)
        for k in d:
            if not isinstance(k, str) or k not in allowed:
                near = difflib.get_close_matches(str(k), allowed, n=1, cutoff=0.6)
                hint = f'did you mean {near[0]}?' if near else f"known: {', '.join(sorted(allowed))}"
                name = k if isinstance(k, str) and len(k) <= 40 else short(k, 40)
                raise problem(f': unknown key ({hint})', f'.{name}')
        for k in cls.required(d):
            if k not in d:
                raise cls.missing(k)
        return d

    def given(self, *keys: str) -> list:
        """Return those of ``keys`` the file gives (even as null)."""
        return [k for k in keys if k in self.model_fields_set]
