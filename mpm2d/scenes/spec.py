"""Parameter validation of the scenes: one mechanism for every scene.

Every scene declares the valid range of every ``setup`` parameter with the :func:`parameters_of`
decorator and :class:`Param` entries::

    @parameters_of(
        cells=Param(2, 4096, integer=True, doc="cells along L"),
        phi0=Param(0.0, lambda p: material_of(p).phi_j, lo_closed=False, hi_closed=False,
                   note=lambda p: f"phi_j of material {p['material']!r}"),
        material=Param(choices=suspension_materials),
        size=lambda p: (points, cells),          # memory estimate before anything is built
    )
    def setup(cells=32, phi0=0.3, material="rod_impact"): ...

The decorator checks that the declaration and the signature name the same parameters, attaches
the :class:`SceneSpec` as ``setup.spec`` and makes ``setup`` validate its arguments on every call
(CLI strings are converted; Python values are type-checked). :meth:`SceneSpec.validate` checks,
for every key: the type (number, integer, bool, one of the choices, or None where optional), the
finiteness and the range; a bound may be a function of the other parameters (a material's
phi_j, a geometric limit), evaluated once every parameter has passed its own static check, so
derived bounds go through the same path and the same message. Then the memory estimate of the
run (points x bytes per point + nodes x bytes per node) is checked against the available memory
(:func:`rheology.checks.check_memory`). Every refusal is one ``ValueError`` line naming the
parameter, its value and the valid range, raised before anything is built or written.
"""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rheology.checks import check_memory
from rheology.cli_common import Number

#: memory estimate: bytes per material point (kinematic arrays ~40 float64, material state,
#: the output copies of a snapshot and the permutation copies of a sort) and per grid node (per
#: phase: the node fields, one private copy per thread, velocities; two phases at most)
BYTES_PER_POINT = 1200
BYTES_PER_NODE = 2 * 8 * (9 * 3 + 12)
#: what any run takes besides its arrays (interpreter, numba and its compiled kernels)
BASE_BYTES = 2e8

_TRUE, _FALSE = ("true", "1", "yes", "on"), ("false", "0", "no", "off")


def _resolve(x, params):
    return x(params) if callable(x) else x


@dataclass(frozen=True)
class Param:
    """The valid values of one scene parameter.

    Parameters
    ----------
    lo, hi : float, None or callable(params) -> float
        Bounds (None: unbounded); a callable receives the dict of every (already individually
        checked) parameter, e.g. ``lambda p: get_material(p["material"]).phi_j``.
    integer : bool
        An integer (``"3"`` or 3; ``3.5`` and ``True`` are refused).
    lo_closed, hi_closed : bool
        Whether the bounds are valid values.
    unit : str
        Printed after the range.
    choices : tuple of str, or callable() -> tuple
        A text parameter: one of these (case-insensitive).
    boolean : bool
        A switch (``true/false/1/0/yes/no``).
    optional : bool
        ``None`` (``--set dt=none``) is valid too.
    doc : str
        What the parameter is (printed by ``mpm2d show``).
    note : str or callable(params) -> str
        Where a derived bound comes from (appended to the message), e.g. ``phi_j of material``.
    material_of : str, optional
        A material parameter: any SI set or a material file, on this scene set
        (:func:`scene_material_param`).
    fraction_of : callable(params) -> str, optional
        A volume fraction of the named material (:func:`phi_below_jamming`): ``mpm2d run
        --mass-fraction`` sets it through Eq. (20).
    """

    lo: float | Callable | None = None
    hi: float | Callable | None = None
    integer: bool = False
    lo_closed: bool = True
    hi_closed: bool = True
    unit: str = ""
    choices: tuple | Callable | None = None
    boolean: bool = False
    optional: bool = False
    doc: str = ""
    note: str | Callable = ""
    material_of: str | None = None
    fraction_of: Callable | None = None

    @property
    def kind(self) -> str:
        if self.material_of is not None:
            return "material"
        return "choice" if self.choices is not None else "bool" if self.boolean else "number"

    @property
    def derived(self) -> bool:
        """Whether a bound depends on the other parameters."""
        return callable(self.lo) or callable(self.hi)

    def number(self, name: str, params: dict | None = None) -> Number:
        """The :class:`~rheology.cli_common.Number` of this parameter (bounds resolved against
        ``params`` where they are derived; unresolved derived bounds are left open)."""
        lo = _resolve(self.lo, params) if (params is not None or not callable(self.lo)) else None
        hi = _resolve(self.hi, params) if (params is not None or not callable(self.hi)) else None
        return Number(name, lo, hi, integer=self.integer, lo_closed=self.lo_closed,
                      hi_closed=self.hi_closed, unit=self.unit)

    def options(self) -> tuple:
        return tuple(self.choices() if callable(self.choices) else self.choices)

    def range_text(self, params: dict | None = None) -> str:
        """The valid values as text, with derived bounds evaluated at ``params``."""
        if self.kind == "material":
            text = ("an SI parameter set (rheometer materials) or a material file *.json; the "
                    f"moduli, densities, d and K0 it leaves unset come from {self.material_of}")
        elif self.kind == "choice":
            text = "one of " + ", ".join(map(str, self.options()))
        elif self.kind == "bool":
            text = "true or false"
        else:
            text = ("integer in " if self.integer else "") + self.number("x", params).range_text
        if self.optional:
            text += ", or none"
        note = self.note_text(params)
        return text + (f" ({note})" if note else "")

    def note_text(self, params) -> str:
        if callable(self.note):
            return self.note(params) if params is not None else ""
        return self.note

    def convert(self, name: str, value):
        """Type check and conversion of one value (static range included; derived bounds are
        checked by :meth:`check_derived`)."""
        if self.optional and (value is None or (isinstance(value, str)
                                                and value.strip().lower() in ("none", ""))):
            return None
        if self.kind == "material":
            from rheology.materials import scene_material

            if not isinstance(value, str) or not value.strip():
                raise ValueError(f"{name} = {value!r} is not a parameter set name or a material "
                                 "file")
            try:
                scene_material(self.material_of, value.strip())
            except ValueError as exc:
                raise ValueError(f"{name} = {value!r} is not one of the SI parameter sets or a "
                                 f"valid material file: {exc}") from None
            return value.strip()
        if self.kind == "choice":
            opts = self.options()
            if not isinstance(value, str) or value.strip().lower() not in [str(o).lower()
                                                                           for o in opts]:
                raise ValueError(f"{name} = {value!r} is not one of {', '.join(map(str, opts))}")
            return next(o for o in opts if str(o).lower() == value.strip().lower())
        if self.kind == "bool":
            if isinstance(value, bool):
                return value
            if isinstance(value, str) and value.strip().lower() in _TRUE + _FALSE:
                return value.strip().lower() in _TRUE
            raise ValueError(f"{name} = {value!r} is not true or false")
        static = Param(None if callable(self.lo) else self.lo,
                       None if callable(self.hi) else self.hi, self.integer, self.lo_closed,
                       self.hi_closed, self.unit).number(name)
        if isinstance(value, bool) or not (isinstance(value, str) or _is_real(value)):
            kind = "an integer" if self.integer else "a number"
            raise ValueError(f"{name} = {value!r} is not {kind}; valid range {static.range_text}")
        return static.check(value.strip() if isinstance(value, str) else value)

    def check_derived(self, name: str, value, params: dict):
        """Check ``value`` against the bounds resolved at ``params`` (ValueError naming both)."""
        if value is None or self.kind != "number" or not self.derived:
            return value
        try:
            return self.number(name, params).check(value)
        except ValueError as exc:
            note = self.note_text(params)
            raise ValueError(f"{exc}{f' ({note})' if note else ''}") from None


def _is_real(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating))


class SceneSpec:
    """The declared parameters of one scene: ``params`` (name -> :class:`Param`), ``defaults``
    (from the ``setup`` signature) and ``size`` (params -> (points, grid nodes), for the memory
    estimate)."""

    def __init__(self, name: str, params: dict[str, Param], defaults: dict,
                 size: Callable | None):
        self.name, self.params, self.defaults, self.size = name, params, defaults, size

    def _with_derived_range(self, key, value, given: dict, exc: ValueError) -> ValueError:
        """A refusal of a value with a derived bound (NaN, text, ...) states the bound as it is
        for the other parameters (e.g. phi_j of the material), not the static (0, inf)."""
        p = self.params[key]
        if not p.derived:
            return exc
        others = {**self.defaults}
        for k, v in given.items():
            if k != key and k in self.params:
                try:
                    others[k] = self.params[k].convert(k, v)
                except ValueError:
                    return exc
        try:
            text = p.range_text(others)
        except Exception:                    # a bound that cannot be evaluated: keep the first
            return exc
        first = str(exc).split("; valid range")[0].split(" is outside")[0]
        return ValueError(f"{first}; valid range {text}")

    def coerce(self, given: dict) -> dict:
        """Convert and check the ``given`` overrides (strings or values) and return them (with
        the canonical types), after checking them together with the defaults of the others.

        Raises
        ------
        ValueError
            An unknown key, a wrong type, a value outside its (static or derived) range, or a
            memory estimate beyond the available memory; one line naming the parameter.
        """
        out = {}
        for k, v in given.items():
            if k not in self.params:
                raise ValueError(f"unknown parameter {k!r} of scene {self.name}; valid: "
                                 f"{', '.join(self.params)}")
            try:
                out[k] = self.params[k].convert(k, v)
            except ValueError as exc:
                raise self._with_derived_range(k, v, given, exc) from None
        full = {**self.defaults, **out}
        for k, p in self.params.items():
            if k not in out:
                full[k] = p.convert(k, full[k])
        # derived bounds: the same path, once every key passed its own static check; the given
        # keys first, so a bad value is named itself
        for k in [*out, *(k for k in self.params if k not in out)]:
            try:
                full[k] = self.params[k].check_derived(k, full[k], full)
            except ValueError as exc:
                if k in out or not out:
                    raise
                given = ", ".join(f"{g} = {v}" for g, v in out.items())
                raise ValueError(f"{exc}; with {given}") from None
            if k in out:
                out[k] = full[k]
        self.check_memory(full)
        return out

    def validate(self, given: dict) -> dict:
        """Every parameter (defaults completed by ``given``), checked (see :meth:`coerce`)."""
        return {**self.defaults, **self.coerce(given)}

    def estimate_bytes(self, params: dict) -> float:
        """Memory estimate of a run with ``params`` [bytes] (0 if the scene has no size).

        Measured (peak RSS growth of a run, 3 steps and a VTK frame, against this estimate):
        bar 320k points 234 MB vs 759 MB, terzaghi 256k points 187-231 MB vs 540 MB, disks 264k
        points 269 MB vs 683 MB, column 640k points 426 MB vs 1024 MB, wheel 44k points 98-139 MB
        vs 279 MB: conservative by 2-3x."""
        if self.size is None:
            return 0.0
        points, nodes = self.size(params)
        return BASE_BYTES + float(points) * BYTES_PER_POINT + float(nodes) * BYTES_PER_NODE

    def check_memory(self, params: dict) -> None:
        nbytes = self.estimate_bytes(params)
        if not math.isfinite(nbytes):
            nbytes = math.inf
        keys = [k for k, p in self.params.items() if p.kind == "number" and
                (p.integer or k in ("h", "cells_per_mm"))] or list(self.params)[:1]
        check_memory(", ".join(keys), ", ".join(str(params[k]) for k in keys), nbytes)

    def describe(self) -> list[str]:
        """One line per parameter: name = default, valid range, doc."""
        lines = []
        for k, p in self.params.items():
            doc = f"{p.doc}; " if p.doc else ""
            lines.append(f"  {k} = {self.defaults[k]!r}  ({doc}valid: "
                         f"{p.range_text(self.defaults)})")
        return lines


def parameters_of(size: Callable | None = None, **params: Param):
    """Decorator declaring the valid range of every parameter of a scene's ``setup``.

    ``size(params) -> (points, grid nodes)`` estimates the run's size for the memory check.
    The wrapped ``setup`` validates its keyword arguments on every call (see
    :meth:`SceneSpec.coerce`) and has ``setup.spec``.

    Raises
    ------
    TypeError
        At import: the declaration and the signature do not name the same parameters, or a
        parameter has no default (a programming error, not bad input).
    """

    def wrap(setup):
        sig = inspect.signature(setup)
        names = [k for k in sig.parameters]
        missing = [k for k in names if k not in params]
        extra = [k for k in params if k not in names]
        if missing or extra:
            raise TypeError(f"{setup.__module__}.setup: parameters without a declared range "
                            f"{missing}, declared but not in the signature {extra}")
        nodefault = [k for k, p in sig.parameters.items() if p.default is inspect.Parameter.empty]
        if nodefault:
            raise TypeError(f"{setup.__module__}.setup: parameters without a default {nodefault}")
        defaults = {k: p.default for k, p in sig.parameters.items()}
        spec = SceneSpec(setup.__module__.rsplit(".", 1)[-1], dict(params), defaults, size)

        @functools.wraps(setup)
        def checked(**kwargs):
            return setup(**spec.validate(kwargs))

        checked.spec = spec
        return checked

    return wrap


# ---------------------------------------------------------------- common declarations
def positive(hi, unit="", doc="", lo=0.0):
    """A number in (lo, hi] (default lo = 0)."""
    return Param(lo, hi, lo_closed=False, unit=unit, doc=doc)


def count(lo, hi, doc=""):
    """An integer in [lo, hi]."""
    return Param(lo, hi, integer=True, doc=doc)


def modulus(doc="", hi=1e12):
    return positive(hi, "Pa", doc)


def density(doc="", hi=1e5):
    return positive(hi, "kg/m^3", doc)


def cfl(doc="safety factor of the stable step"):
    return Param(0.0, 1.0, lo_closed=False, doc=doc)


def transfer():
    return Param(choices=("apic", "flip", "pic"), doc="particle-grid transfer")


def flip_alpha():
    return Param(0.0, 1.0, doc="FLIP fraction of the FLIP/PIC blend (transfer=flip)")


def gravity(hi=1000.0):
    """Gravity of a scene whose bed starts at rest under it (mpm2d.geostatic): > 0."""
    return Param(0.0, hi, lo_closed=False, unit="m/s^2",
                 doc="gravitational acceleration (downwards; the bed rests under it)")


def scene_material_param(scene_set: str, doc: str = "steady-flow parameters") -> Param:
    """A ``material`` parameter: any SI parameter set or a material file (``fit/material.json``
    from ``rheometer fit``), put on the scene's own set ``scene_set`` by
    :func:`rheology.materials.scene_material` (which the scene calls to build it)."""
    return Param(material_of=scene_set, doc=doc)


def materials_where(predicate: Callable, what: str) -> Callable[[], tuple]:
    """Choices: the rheology parameter sets ``m`` with ``predicate(m)`` true (``what`` says
    which, for ``mpm2d show``)."""

    def names():
        from rheology import get_material, material_names

        return tuple(n for n in material_names() if predicate(get_material(n)))

    names.what = what
    return names


def phi_below_jamming(material_key="material", fixed=None, doc="initial solid volume fraction",
                      optional=False):
    """A volume fraction in (0, phi_j) of the scene's material (``params[material_key]``, or the
    named ``fixed`` material); ``optional``: ``none`` allowed (the scene picks its value)."""

    def name(p):
        return fixed if fixed else p[material_key]

    def phi_j(p):
        from rheology import get_material

        return get_material(name(p)).phi_j

    return Param(0.0, phi_j, lo_closed=False, hi_closed=False, doc=doc, optional=optional,
                 note=lambda p: f"phi_j of material {name(p)!r}", fraction_of=name)


def volume_fraction_key(spec) -> str | None:
    """The scene's volume-fraction parameter (declared with :func:`phi_below_jamming`), if any."""
    return next((k for k, p in spec.params.items() if p.fraction_of is not None), None)


