"""One schema for every parameter: its type, unit, bounds with their physical reasons, the check
and the one-line refusal, the command-line option.

A :class:`Param` declares a parameter: ``kind`` (number, integer, bool, choice or text with a
converter), ``unit``, ``doc``, and two :class:`Bound` (``lo``, ``hi``), each a value or a
function of the other parameters, closed or open, with the reason for it (``why``). A
:class:`Schema` holds the parameters of one command, scene or parameter set with their
defaults and validates a set of values once:

1. each given value alone: its type, finiteness and static bounds (``NAME = VALUE is outside
   the valid range [LO, HI] UNIT (WHY)``);
2. every bound that depends on the others, at the completed values. A refusal there is said
   about a parameter the user gave: its valid range at the other values, found by one bisection
   over the ordered floats (64 checks per side at most) and stated with the reason of the bound
   that closes it; when no single given value can be moved into range, the refusal names them
   all;
3. the ``constraints`` between parameters that are no one parameter's bound (a run's step
   count), explained the same way;
4. the memory the run needs (``size``), against what the machine has (:mod:`runkit.limits`).

A parameter may be ``optional`` with a ``fill`` (the value None stands for, from the others:
its derived bounds are checked on it) and carry a ``role`` for its tier (a volume fraction
``of`` a material). :meth:`Schema.valid_range` is the range of one parameter at the others'
values, also under a further condition of the caller's.

Every refusal is one ``ValueError`` line. :meth:`Schema.add_options` builds the ``argparse``
options (``type=`` an :class:`Option`, which does step 1 while parsing); :func:`check_range` is
the same check for the arrays a physics function receives.
"""

from __future__ import annotations

import argparse
import functools
import inspect
import math
import struct
import sys
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .limits import Bound, check_memory

_TRUE, _FALSE = ("true", "1", "yes", "on"), ("false", "0", "no", "off")


def as_bool(name: str, value) -> bool:
    """A bool, or a command line's true/1/yes/on and false/0/no/off (any case); ValueError
    naming ``name`` for anything else."""
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.strip().lower() in _TRUE + _FALSE:
        return value.strip().lower() in _TRUE
    raise ValueError(f"{name} = {value!r} is not true or false")


def _as_bound(b) -> Bound | None:
    return b if b is None or isinstance(b, Bound) else Bound(b)


def interval_text(lo, lo_closed, hi, hi_closed, unit="") -> str:
    """``"[lo, hi) unit"`` (None: unbounded). A closed end whose printed value (6 digits) lies
    past it is shown open: the number printed is itself refused (0.1 sqrt(10) as 0.316228)."""
    left = "(-inf" if lo is None else (
        "[" if lo_closed and float(f"{lo:g}") >= lo else "(") + f"{lo:g}"
    right = "inf)" if hi is None else f"{hi:g}" + (
        "]" if hi_closed and float(f"{hi:g}") <= hi else ")")
    return f"{left}, {right}" + (f" {unit}" if unit else "")


def shown(value) -> str:
    """A value as a refusal shows it: as typed; a float at 6 digits when that is exact."""
    if isinstance(value, (float, np.floating)):
        x = float(value)
        return f"{x:.6g}" if float(f"{x:.6g}") == x else repr(x)
    return value if isinstance(value, str) else str(value)


class OutOfRange(ValueError):
    """A value outside its valid range: the one-line refusal, with its parts as attributes
    (``name``; ``value_text``, the value as shown; ``why``, the failing bound's reason) so a
    caller re-explaining it never parses the text."""

    def __init__(self, name: str, value_text: str, range_text: str, why: str = ""):
        self.name, self.value_text, self.range_text, self.why = name, value_text, range_text, why
        super().__init__(f"{name} = {value_text} is outside the valid range {range_text}"
                         + (f" ({why})" if why else ""))

    def __reduce__(self):                # pickled whole (a Dask worker's refusal)
        return type(self), (self.name, self.value_text, self.range_text, self.why)


@dataclass(frozen=True)
class Param:
    """The valid values of one parameter (see the module docstring).

    ``lo``, ``hi``: :class:`Bound` or a number (a closed bound without reason) or None;
    ``kind``: ``"number"``, ``"integer"``, ``"bool"``, ``"choice"`` (``choices``, a tuple or a
    function returning one; case-insensitive) or ``"text"`` (``convert(text)`` returns the
    value or raises ValueError); ``optional``: None (``none``) is valid too; ``also``: values
    valid besides the range (a grain size 0: the viscous limit); ``fill(values)``: the value an
    optional parameter left at None takes (its derived bounds are checked on it); ``role``,
    ``of``: what the parameter is to its tier (``"volume_fraction"`` of the material named by
    ``of(values)``).
    """

    lo: Bound | float | None = None
    hi: Bound | float | None = None
    unit: str = ""
    kind: str = "number"
    doc: str = ""
    choices: tuple | Callable = ()
    convert: Callable | None = None
    optional: bool = False
    also: tuple = ()
    fill: Callable | None = None
    role: str = ""
    of: Callable | None = None

    def __post_init__(self):
        object.__setattr__(self, "lo", _as_bound(self.lo))
        object.__setattr__(self, "hi", _as_bound(self.hi))

    @property
    def numeric(self) -> bool:
        return self.kind in ("number", "integer")

    @property
    def derived(self) -> bool:
        return any(b is not None and b.derived for b in (self.lo, self.hi))

    def reasons(self, params) -> str:
        """The reasons of the derived bounds at ``params`` ("" without, or where they cannot be
        evaluated)."""
        try:
            whys = [b.at(params)[2] for b in (self.lo, self.hi) if b is not None and b.derived]
        except (ValueError, ArithmeticError, TypeError, KeyError):
            return ""
        return "; ".join(dict.fromkeys(w for w in whys if w))

    def bounds(self, params=None, static=False):
        """(lo, lo_closed, lo_why, hi, hi_closed, hi_why); a derived bound is None when
        ``static`` or without ``params``."""
        out = []
        for b in (self.lo, self.hi):
            if b is None or (b.derived and (static or params is None)):
                out += [None, True, ""]
            else:
                out += list(b.at(params))
        return tuple(out)

    def range_text(self, params=None, static=False, typed=False) -> str:
        if self.kind == "bool":
            text = "true or false"
        elif self.kind == "choice":
            text = "one of " + ", ".join(map(str, self.options()))
        elif self.kind == "text":
            text = getattr(self.convert, "what", "") or self.doc or "text"
        else:
            lo, lc, _, hi, hc, _ = self.bounds(params, static)
            text = ("integer in " if typed and self.kind == "integer" else "") + interval_text(
                lo, lc, hi, hc, self.unit)
        return text + (", or none" if self.optional else "")

    def options(self) -> tuple:
        return tuple(self.choices() if callable(self.choices) else self.choices)

    def _outside(self, x, params, static) -> str | None:
        """The reason ``x`` is outside the bounds (the bound's why, "" without one), or None."""
        lo, lc, lw, hi, hc, hw = self.bounds(params, static)
        if lo is not None and (x < lo or (x == lo and not lc)):
            return lw
        if hi is not None and (x > hi or (x == hi and not hc)):
            return hw
        return None

    def check(self, name: str, value, params=None, *, static=False):
        """``value`` converted (str from a command line, or a Python value) and checked against
        the static bounds and, with ``params``, the derived ones; ValueError naming ``name``."""
        if self.optional and (value is None or (isinstance(value, str)
                                                and value.strip().lower() in ("none", ""))):
            return None
        rng = self.range_text(params, static) + "".join(f", or {a:g}" for a in self.also)
        if self.kind == "bool":
            return as_bool(name, value)
        if self.kind == "choice":
            opts = {str(o).lower(): o for o in self.options()}
            if not isinstance(value, str) or value.strip().lower() not in opts:
                raise ValueError(f"{name} = {value!r} is not {rng}")
            return opts[value.strip().lower()]
        if self.kind == "text":
            return self.convert(value) if self.convert else value
        what = "an integer" if self.kind == "integer" else "a number"
        whys = [b.why for b in (self.lo, self.hi)    # a value no finite number: the reasons too
                if b is not None and b.why and not callable(b.why) and not b.derived]
        told = rng + (f" ({'; '.join(dict.fromkeys(whys))})" if whys else "")
        if isinstance(value, bool):
            raise ValueError(f"{name} = {value!r} is not {what}; valid range {told}")
        try:
            x = float(value.strip() if isinstance(value, str) else value)
        except (TypeError, ValueError):
            raise ValueError(f"{name} = {value!r} is not {what}; valid range {told}") from None
        text = shown(value)
        if not math.isfinite(x):
            raise ValueError(f"{name} = {text}: must be finite; valid range {told}")
        if x != 0.0 and abs(x) < sys.float_info.min:
            raise ValueError(f"{name} = {text} is subnormal (nonzero but below "
                             f"{sys.float_info.min:.3g}, held with lost precision); valid range "
                             f"{told}")
        if self.kind == "integer" and x != int(x):
            raise ValueError(f"{name} = {text} is not an integer; valid range {told}")
        why = None if x in self.also else self._outside(x, params, static)
        if why is not None:
            raise OutOfRange(name, text, rng, why)
        return int(x) if self.kind == "integer" else x


class Option:
    """The argparse ``type=`` of a parameter's option: the static check while parsing (a
    refusal is argparse's one line, status 2); derived bounds are the :class:`Schema`'s."""

    def __init__(self, name: str, param: Param):
        self.name, self.param = name, param
        self.__name__ = "integer" if param.kind == "integer" else "number"

    @property
    def range_text(self) -> str:
        return self.param.range_text(static=True)

    def check(self, value):
        """``value`` converted and checked against the static bounds, or ValueError naming the
        option."""
        return self.param.check(self.name, value, static=True)

    def __call__(self, text):
        try:
            return self.check(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    def __repr__(self):
        return f"{type(self).__name__}({self.name!r}, {self.range_text})"


class Number(Option):
    """The :class:`Option` of a number in a static range, declared in place: ``Number("--t-end",
    0, None, lo_closed=False)``; a bound may be a :class:`~runkit.limits.Bound` (its reason is
    printed with a refusal). ``shown_range``: for an option whose bounds depend on the run
    (checked once it is known), the range the parse-time message states (``lo = hi = None``)."""

    def __init__(self, name: str, lo=None, hi=None, *, integer: bool = False,
                 lo_closed: bool = True, hi_closed: bool = True, unit: str = "",
                 shown_range: str = ""):
        if shown_range and (lo is not None or hi is not None):
            raise ValueError(f"{name}: shown_range is for bounds checked later (lo = hi = None)")
        lo, hi = (b if b is None or isinstance(b, Bound) else Bound(b, c)
                  for b, c in ((lo, lo_closed), (hi, hi_closed)))
        super().__init__(name, Param(lo, hi, unit=unit, kind="integer" if integer else "number"))
        self.lo, self.hi = (None if b is None else b.value for b in (lo, hi))
        self.lo_closed, self.hi_closed = (b is None or b.closed for b in (lo, hi))
        self.integer, self.unit, self.shown_range = integer, unit, shown_range

    @property
    def range_text(self) -> str:
        if self.shown_range:
            return self.shown_range + (f" {self.unit}" if self.unit else "")
        return self.param.range_text(static=True)

    def contains(self, x: float) -> bool:
        """Whether ``x`` (a float) is a valid value."""
        return (math.isfinite(x) and not (self.integer and x != int(x))
                and self.param._outside(x, None, True) is None)

    def check(self, value):
        """``value`` as int or float, or ValueError naming the option."""
        try:
            return self.param.check(self.name, value, static=True)
        except ValueError as exc:
            if not self.shown_range:
                raise
            raise ValueError(str(exc).replace(self.param.range_text(static=True),
                                              self.range_text)) from None


def check_range(name: str, value, lo=None, hi=None, *, lo_closed=True, hi_closed=True,
                note: str = "") -> np.ndarray:
    """``value`` (a number or an array) as a float array, every element finite and in range;
    else ValueError naming ``name``, the first bad element and the range (``note``: its reason).
    """
    p = Param(None if lo is None else Bound(lo, lo_closed, note),
              None if hi is None else Bound(hi, hi_closed, note))
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r} is not a number") from None
    bad = ~np.isfinite(arr)
    if lo is not None:
        bad |= (arr < lo) if lo_closed else (arr <= lo)
    if hi is not None:
        bad |= (arr > hi) if hi_closed else (arr >= hi)
    if np.any(bad):
        p.check(name, float(np.ravel(arr[bad] if arr.ndim else arr)[0]))   # raises
    return arr


def check_positive(name: str, value, note: str = "") -> np.ndarray:
    """:func:`check_range` for ``value > 0``."""
    return check_range(name, value, 0.0, None, lo_closed=False, note=note)


def check_nonnegative(name: str, value, note: str = "") -> np.ndarray:
    """:func:`check_range` for ``value >= 0``."""
    return check_range(name, value, 0.0, None, note=note)


# ---------------------------------------------------------------- the valid range at the others
_SIGN = 1 << 63


def _ordered(x: float) -> int:
    """An integer ordering the floats as they are ordered (adjacent floats differ by 1)."""
    i = struct.unpack("<q", struct.pack("<d", x))[0]
    return i if i >= 0 else -(i & (_SIGN - 1))


def _float(k: int) -> float:
    if k < 0:
        k = ((-k) | _SIGN) - (1 << 64)
    return struct.unpack("<d", struct.pack("<q", k))[0]


def valid_interval(ok: Callable[[float], bool], x0: float, lo=None, hi=None) -> tuple:
    """The interval of valid values around a valid ``x0`` of a monotone check ``ok``, inside
    [lo, hi] (None: the largest floats): each side by bisection over the ordered floats, the
    edge at 6 significant digits, closed when that value is valid.

    Returns (lo, lo_closed, hi, hi_closed), None for a side valid up to the largest float."""
    out = []
    for far in (-sys.float_info.max if lo is None else lo, sys.float_info.max if hi is None
                else hi):
        if ok(far):
            out += [None if abs(far) == sys.float_info.max else far, True]
            continue
        good, bad = _ordered(x0), _ordered(far)
        while abs(bad - good) > 1:
            mid = (good + bad) // 2
            good, bad = (mid, bad) if ok(_float(mid)) else (good, mid)
        g, b = _float(good), _float(bad)
        edge = float(f"{b:.6g}")
        if not min(g, b) <= edge <= max(g, b):
            edge = float(f"{g:.6g}")
        if abs(edge) <= sys.float_info.min:            # a bound on the subnormals: at 0
            edge = 0.0
        out += [edge, ok(edge)]
    return tuple(out)


def integer_range(ok: Callable[[float], bool], starts, lo=None, hi=None, integer=False):
    """(lo, lo_closed, hi, hi_closed) of :func:`valid_interval` around the first of ``starts``
    that is valid (None when none is); ``integer``: the integers inside, closed."""
    x0 = next((float(s) for s in starts if isinstance(s, (int, float)) and not
               isinstance(s, bool) and math.isfinite(s) and ok(float(s))), None)
    if x0 is None:
        return None
    lo, lc, hi, hc = valid_interval(ok, x0, lo, hi)
    if integer:
        lo = None if lo is None else float(math.ceil(lo) if lc else math.floor(lo) + 1)
        hi = None if hi is None else float(math.floor(hi) if hc else math.ceil(hi) - 1)
        lc = hc = True
    return lo, lc, hi, hc


class Schema:
    """The parameters of one command, scene or parameter set (see the module docstring).

    Parameters
    ----------
    params : dict name -> Param
    defaults : dict name -> value (a name without default must be given)
    size : callable(values) -> bytes, optional
        The memory estimate of a run, checked last (:func:`runkit.limits.check_memory`).
    label : callable(name) -> str
        How a refusal names a parameter (``"--t-end"``, ``"--set eta0"``); default the name.
    where : str
        Said in a refusal that names several parameters (``"scene column"``).
    constraints : sequence of callable(values) -> str or None
        Conditions between parameters that are no one parameter's bound (a run's step count):
        None where they hold, else the reason; checked after the bounds, and part of every valid
        range (:meth:`valid_range`).
    at_others : bool
        A refusal by another's bound says ``at the other parameters' values (k = v must be
        within WHY)`` (the scenes' wording) rather than ``(k: WHY)``.
    hint : str
        Appended to a refusal that names several parameters (``" ('mpm2d show column' lists
        the ranges)"``).
    """

    def __init__(self, params: dict[str, Param], defaults: dict | None = None, *, size=None,
                 label: Callable[[str], str] = str, where: str = "", constraints=(),
                 at_others: bool = False, hint: str = ""):
        self.params, self.defaults = dict(params), dict(defaults or {})
        self.size, self.label, self.where = size, label, where
        self.constraints, self.at_others, self.hint = tuple(constraints), at_others, hint

    def check(self, given: dict) -> dict:
        """Every parameter (defaults completed by ``given``), each checked once; ValueError."""
        unknown = [k for k in given if k not in self.params]
        if unknown:
            raise ValueError(f"unknown parameter {unknown[0]!r}"
                             + (f" of {self.where}" if self.where else "")
                             + f"; valid: {', '.join(self.params)}")
        missing = [k for k in self.params if k not in given and k not in self.defaults]
        if missing:
            raise ValueError(f"{self.label(missing[0])} is required")
        full = {**self.defaults, **given}
        order = [*given, *(k for k in self.params if k not in given)]
        for k in order:
            try:
                full[k] = self.params[k].check(self.label(k), full[k], static=True)
            except ValueError as exc:
                raise self._derived_range(k, exc, full) from None
        for k in order:
            if self.params[k].derived and self._value(k, full) is not None:
                try:
                    with np.errstate(all="ignore"):
                        self.params[k].check(self.label(k), self._value(k, full), full)
                except (ValueError, ArithmeticError) as exc:
                    raise self._explain(k, exc, full, given) from None
        for c in self.constraints:
            why = self._unmet(c, full)
            if why is not None:
                raise self._explain(None, ValueError(why), full, given) from None
        if self.size is not None:
            keys = [k for k, p in self.params.items() if p.kind == "integer"] or order[:1]
            check_memory(", ".join(map(self.label, keys)),
                         ", ".join(str(full[k]) for k in keys), float(self.size(full)))
        return full

    validate = check

    def coerce(self, given: dict) -> dict:
        """The ``given`` values checked (:meth:`check`, with the defaults of the others), with
        their canonical types."""
        full = self.check(given)
        return {k: full[k] for k in given}

    def _value(self, key, values):
        """The value of ``key``; an optional one left at None: its ``fill``."""
        v, p = values[key], self.params[key]
        return p.fill(values) if v is None and p.fill is not None else v

    @staticmethod
    def _unmet(constraint, values) -> str | None:
        try:
            with np.errstate(all="ignore"):
                return constraint(values)
        except (ValueError, ArithmeticError, TypeError):
            return "its bound cannot be evaluated there"

    def _derived_range(self, key, exc, values) -> ValueError:
        """A value refused alone (NaN, text, ...) whose bounds are derived: its valid range as
        the other values make it (phi_j of the material), not the static (0, inf). The bounds
        are evaluated with the others converted and ``key`` at its default (a bound of ``key``
        is a function of the others; a formula that also reads ``key``, as a scene's time
        scales do, never sees the refused text)."""
        p = self.params[key]
        if not p.derived:
            return exc
        try:
            others = {k: self.params[k].check(k, self.defaults.get(k) if k == key else v,
                                              static=True)
                      for k, v in values.items()}
            lo, lc, _, hi, hc, _ = p.bounds(others)
            if lo is not None and hi is not None and (lo > hi or (lo == hi and not lc & hc)):
                return exc
            text = p.range_text(others) + "".join(f", or {a:g}" for a in p.also)
        except Exception:                    # a bound that cannot be evaluated: the first
            return exc
        if isinstance(exc, OutOfRange):      # a static bound failed: its reason, the range
            return OutOfRange(exc.name, exc.value_text, text, exc.why or p.reasons(others))
        why = p.reasons(others)
        return ValueError(f"{str(exc).split('; valid range')[0]}; valid range {text}"
                          + (f" ({why})" if why else ""))

    def _failing(self, values: dict) -> dict:
        """The derived bounds and constraints that fail at ``values``: name (a constraint:
        itself) -> reason (an arithmetic failure: "its bound cannot be evaluated there")."""
        out = {}
        for k, p in self.params.items():
            if p.derived and p.numeric:
                try:
                    x = self._value(k, values)
                    with np.errstate(all="ignore"):
                        why = (None if x is None or x in p.also
                               else p._outside(float(x), values, False))
                except (ValueError, ArithmeticError, TypeError):
                    why = "its bound cannot be evaluated there"
                if why is not None:
                    out[k] = why
        for c in self.constraints:
            why = self._unmet(c, values)
            if why is not None:
                out[c] = why
        return out

    def holds(self, values: dict) -> bool:
        """Whether every derived bound holds at ``values`` (an arithmetic failure: no)."""
        return not self._failing(values)

    def valid_range(self, key: str, values: dict, also: Callable | None = None, starts=()):
        """(lo, lo_closed, hi, hi_closed) of ``key`` at the other values: its static range
        intersected with every derived bound (its own and the others'), constraint and
        ``also(values)`` (a further condition of the caller's), around the default (or
        ``starts``, or the given value's nearest static bound), or None when no valid start is
        found."""
        p = self.params[key]
        lo, _, _, hi, _, _ = p.bounds(static=True)

        def ok(x):                       # the bounds only: an integer's are found on the floats
            at = {**values, key: x}
            return (p._outside(x, None, True) is None and self.holds(at)
                    and (also is None or also(at)))

        return integer_range(ok, [self.defaults.get(key), *starts, values[key], lo, hi], lo, hi,
                             p.kind == "integer")

    def _why_at(self, key, values, x) -> tuple[str, bool]:
        """The reasons of the derived bounds and constraints that fail at ``values`` with
        ``key`` = x, and whether any is not ``key``'s own (``at_others``: the first, own first).
        """
        at = {**values, key: x}
        own, other = [], []
        for k, why in self._failing(at).items():
            if k == key or not why or not isinstance(k, str):
                (own if k == key else other).append(why)
            elif self.at_others:
                other.append(f"{self.label(k)} = {shown(self._value(k, at))} must be within {why}")
            else:
                other.append(f"{self.label(k)}: {why}")
        whys = [w for w in dict.fromkeys(own + other) if w]
        return "; ".join(whys[:1] if self.at_others else whys), bool(other)

    def _explain(self, key, exc, values, given) -> ValueError:
        """A derived bound of ``key`` (None: a constraint) fails: said about a given parameter
        out of its valid range at the other values (with the reasons of the bounds it passes),
        else about them all."""
        for g in given:
            p = self.params[g]
            if not p.numeric or values[g] is None:
                continue
            rng = self.valid_range(g, values)
            v = float(values[g])
            if rng is None:
                continue
            lo, lc, hi, hc = rng
            inside = ((lo is None or v > lo or (v == lo and lc))
                      and (hi is None or v < hi or (v == hi and hc)))
            if inside or (lo is not None and hi is not None and lo > hi):
                continue
            why, others = self._why_at(g, values, v)
            at = " at the other parameters' values" if self.at_others and others else ""
            return ValueError(f"{self.label(g)} = {shown(values[g] if self.at_others else given[g])}"
                              f" is outside the valid range {interval_text(lo, lc, hi, hc, p.unit)}"
                              + at + (f" ({why})" if why else ""))
        what = ", ".join(f"{self.label(g)} = {shown(v)}" for g, v in given.items())
        change = ", ".join(map(self.label, given)) or "them"
        if key is None:
            return ValueError(f"{self.where}: with {what or 'the defaults'}, {exc}; change "
                              f"{change}{self.hint}")
        try:
            lo, lc, why, hi, hc, _ = self.params[key].bounds(values)
            empty = lo is not None and hi is not None and (lo > hi or (lo == hi and not lc & hc))
        except (ValueError, ArithmeticError, TypeError):
            empty, why = True, ""
        if empty:                            # never print an empty or inverted range
            return ValueError(f"with {what or 'the defaults'}, no value of {self.label(key)} "
                              f"is valid" + (f" ({why})" if why else "")
                              + f"; change {change}{self.hint}")
        if not given or key in given:
            return exc if isinstance(exc, ValueError) else ValueError(str(exc))
        return ValueError(f"{exc}; with {what}: change {', '.join(map(self.label, given))}")

    # ------------------------------------------------------------ command line
    def add_options(self, parser, keys=None, *, option: Callable[[str], str] | None = None,
                    **per_key) -> None:
        """Add ``--key`` options (``option(key)`` their flag) to ``parser``: ``type=`` an
        :class:`Option` for numbers, ``choices`` for a choice, a switch for a bool; ``per_key``
        maps a key to extra ``add_argument`` keywords (``nargs``, ``metavar``, ...)."""
        option = option or (lambda k: "--" + k.replace("_", "-"))
        for k in keys or self.params:
            p, flag = self.params[k], option(k)
            kw = dict(default=self.defaults.get(k), dest=k,
                      help=(p.doc + "; " if p.doc else "") + p.range_text(static=True, typed=True))
            if p.kind == "bool":
                kw.update(action="store_true")
            elif p.kind == "choice":
                kw.update(choices=p.options())
            elif p.numeric:
                kw.update(type=Option(flag, p))
            kw.update(per_key.get(k, {}))
            parser.add_argument(flag, **kw)

    def describe(self) -> list[str]:
        """One line per parameter: ``name = default  (doc; valid: range)``."""
        def why(p):
            w = p.reasons(self.defaults)
            return f" ({w})" if w else ""

        return [f"  {k} = {self.defaults.get(k)!r}  ({p.doc + '; ' if p.doc else ''}valid: "
                f"{p.range_text(self.defaults, typed=True)}{why(p)})"
                for k, p in self.params.items()]


def checked(size=None, label: Callable[[str], str] = str, **params: Param):
    """Declare the parameters of an entry point (a scene's ``setup``, a protocol, a command's
    body): the decorated function checks its keyword arguments once (:meth:`Schema.check`,
    defaults from its signature) and calls the function; ``fn.schema`` builds the options and
    checks with other labels, ``fn.raw`` is the function itself, for callers whose values are
    checked already. TypeError at import when the declaration and the signature disagree."""

    def wrap(fn):
        sig = inspect.signature(fn).parameters
        if set(sig) != set(params):
            raise TypeError(f"{fn.__qualname__}: declared {sorted(params)}, signature "
                            f"{sorted(sig)}")
        defaults = {k: p.default for k, p in sig.items() if p.default is not p.empty}
        schema = Schema(params, defaults, size=size, label=label, where=fn.__qualname__)

        @functools.wraps(fn)
        def entry(**given):
            return fn(**schema.check(given))

        entry.schema, entry.raw = schema, fn
        return entry

    return wrap


__all__ = ["OutOfRange", "Param", "Schema", "Option", "checked", "check_range", "valid_interval",
           "integer_range", "interval_text", "shown"]
