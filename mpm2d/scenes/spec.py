"""The parameters of the scenes: one declaration per ``setup`` parameter, one check.

Every scene declares each ``setup`` parameter with :func:`parameters_of` and a :class:`Param`::

    @parameters_of(
        cells=Param(2, 4096, integer=True, doc="cells along L"),
        phi0=phi_below_jamming(),                # (0, phi_j of the material)
        material=Param(choices=suspension_materials),
        size=lambda p: (points, nodes),          # memory estimate before anything is built
    )
    def setup(cells=32, phi0=0.3, material="rod_impact"): ...

The decorated ``setup`` validates its keyword arguments on every call (:meth:`SceneSpec.coerce`):
each value alone through :meth:`runkit.params.Param.check` (type, finiteness, static range with
its physical reason from :mod:`runkit.limits`), then every bound that is a function of the other
parameters (a material's phi_j, a geometric limit), then the memory estimate. A refusal is one
``ValueError`` line naming the parameter the user set, its value and its valid range at the
other values (found by bisection, :func:`runkit.params.valid_interval`).
"""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from runkit import limits
from runkit.limits import MAX_STEPS, Bound, check_memory
from runkit.params import Number, OutOfRange, integer_range, shown
from runkit.params import Param as SchemaParam
from rheology import get_material, material_names
from rheology.materials import RULES, scene_material

#: memory estimate: bytes per material point (kinematic arrays ~40 float64, material state,
#: the output copies of a snapshot and the permutation copies of a sort) and per grid node (per
#: phase: the node fields, one private copy per thread, velocities; two phases at most)
BYTES_PER_POINT = 1200
BYTES_PER_NODE = 2 * 8 * (9 * 3 + 12)
#: what any run takes besides its arrays (interpreter, numba and its compiled kernels)
BASE_BYTES = 2e8
#: the reason of the step-count limit (runkit.limits.MAX_STEPS)
STEPS_WHY = "about a day on one core at the smallest scene"


@dataclass(frozen=True)
class Param:
    """The valid values of one scene parameter, declared as the scenes read it; the check is
    :meth:`runkit.params.Param.check` of :attr:`schema`.

    Parameters
    ----------
    lo, hi : float, None or callable(params) -> float
        Bounds (None: unbounded); a callable receives the dict of every (already individually
        checked) parameter, e.g. ``lambda p: get_material(p["material"]).phi_j``.
    integer, lo_closed, hi_closed, unit, optional, doc
        As :class:`runkit.params.Param` (``optional``: ``none`` is valid too).
    choices : tuple of str, or callable() -> tuple
        A text parameter: one of these (case-insensitive).
    boolean : bool
        A switch (``true/false/1/0/yes/no``).
    note : str or callable(params) -> str
        Where a derived bound comes from (the reason printed with its refusal).
    material_of : str, optional
        A material parameter: any SI set or a material file, on this scene set
        (:func:`scene_material_param`).
    fraction_of : callable(params) -> str, optional
        A volume fraction of the named material (:func:`phi_below_jamming`): ``mpm2d run
        --mass-fraction`` sets it through Eq. (20).
    fill : callable(params) -> value, optional
        The value an optional parameter left at ``None`` takes (the scene's choice from the
        others); its derived bounds are checked on that value.
    lo_why, hi_why : str
        The physical reason of a static bound (:mod:`runkit.limits`), printed with a refusal.
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
    fill: Callable | None = None
    lo_why: str = ""
    hi_why: str = ""

    @property
    def kind(self) -> str:
        if self.material_of is not None:
            return "material"
        return "choice" if self.choices is not None else "bool" if self.boolean else "number"

    @property
    def derived(self) -> bool:
        """Whether a bound depends on the other parameters."""
        return callable(self.lo) or callable(self.hi)

    @functools.cached_property
    def schema(self) -> SchemaParam:
        """The :class:`runkit.params.Param` that checks this parameter."""
        if self.kind == "material":
            return SchemaParam(kind="text", convert=self._material, optional=self.optional)
        if self.kind in ("choice", "bool"):
            return SchemaParam(kind=self.kind, choices=self.choices or (),
                               optional=self.optional)

        def bound(x, closed, why):
            return None if x is None else Bound(x, closed, self.note if callable(x) else why)

        return SchemaParam(bound(self.lo, self.lo_closed, self.lo_why),
                           bound(self.hi, self.hi_closed, self.hi_why), unit=self.unit,
                           kind="integer" if self.integer else "number", optional=self.optional)

    def _material(self, value) -> str:
        name = "material"
        if not isinstance(value, str) or not value.strip():
            raise ValueError(f"{name} = {value!r} is not a parameter set name or a material file")
        try:
            scene_material(self.material_of, value.strip())
        except ValueError as exc:
            raise ValueError(f"{name} = {value!r} is not one of the SI parameter sets or a "
                             f"valid material file: {exc}") from None
        return value.strip()

    def number(self, name: str, params: dict | None = None) -> Number:
        """The :class:`~runkit.params.Number` of this parameter (bounds resolved against
        ``params`` where they are derived; unresolved derived bounds are left open)."""
        lo, lc, _, hi, hc, _ = self.schema.bounds(params, static=params is None)
        return Number(name, lo, hi, integer=self.integer, lo_closed=lc, hi_closed=hc,
                      unit=self.unit)

    def options(self) -> tuple:
        return self.schema.options()

    def range_text(self, params: dict | None = None) -> str:
        """The valid values as text, with derived bounds evaluated at ``params``."""
        if self.kind == "material":
            text = ("an SI parameter set (rheometer materials) or a material file *.json; the "
                    f"moduli, densities, d and K0 it leaves unset come from {self.material_of}")
            text += ", or none" if self.optional else ""
        else:
            text = self.schema.range_text(params, static=params is None, typed=True)
        note = self.note_text(params)
        return text + (f" ({note})" if note else "")

    def note_text(self, params) -> str:
        if callable(self.note):
            return self.note(params) if params is not None else ""
        return self.note

    def convert(self, name: str, value):
        """Type check and conversion of one value, static range included (derived bounds are
        checked by :meth:`check_derived`)."""
        return self.schema.check(name, value, static=True)

    def check_derived(self, name: str, value, params: dict):
        """Check ``value`` (``None``: its ``fill``) against the bounds resolved at ``params``
        (ValueError naming both)."""
        shown = self.fill(params) if value is None and self.fill is not None else value
        if shown is None or self.kind != "number" or not self.derived:
            return value
        checked = self.schema.check(name, shown, params)
        return value if value is None else checked


def _is_real(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def _empty(number: Number) -> bool:
    """Whether a range admits no value (inverted, or a single point open on a side)."""
    lo, hi = number.lo, number.hi
    if lo is None or hi is None:
        return False
    return lo > hi or (lo == hi and not (number.lo_closed and number.hi_closed))


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
            if _empty(p.number(key, others)):  # never print an empty or inverted range
                return exc
        except Exception:                    # a bound that cannot be evaluated: keep the first
            return exc
        first = (f"{exc.name} = {exc.value_text}" if isinstance(exc, OutOfRange)
                 else str(exc).split("; valid range")[0])
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
                with np.errstate(all="ignore"):
                    full[k] = self.params[k].check_derived(k, full[k], full)
            except ValueError as exc:
                raise self._explain(k, exc, full, out) from None
            if k in out:
                out[k] = full[k]
        self._check_steps(full, out)
        self.check_memory(full)
        return out

    def _derived_ok(self, full: dict) -> bool:
        """Whether every derived bound holds at ``full``, the step count included (arithmetic
        failures count as no)."""
        try:
            with np.errstate(all="ignore"):
                for k, p in self.params.items():
                    p.check_derived(k, full[k], full)
        except (ValueError, ArithmeticError, TypeError):
            return False
        return self.steps_fit(full)

    def steps_fit(self, full: dict) -> bool:
        """Whether the run takes at most MAX_STEPS steps at the largest step its parameters
        allow (:meth:`step_bound`; True where they give none)."""
        try:
            bound = self.step_bound(full)
        except (ValueError, ArithmeticError, TypeError):
            return False
        if bound is None:
            return True
        dt, t_end, _ = bound
        with np.errstate(all="ignore"):
            return bool(dt > 0 and t_end / dt <= MAX_STEPS)

    def _check_steps(self, full: dict, given: dict) -> None:
        """Refuse a run needing more than MAX_STEPS steps even at the largest step its
        parameters allow: said about a given number out of its valid range at the others."""
        if self.steps_fit(full):
            return
        dt, t_end, knobs = self.step_bound(full)
        why = (f"a run takes at most {MAX_STEPS:.0e} steps, {STEPS_WHY}; {knobs} give a step "
               f"of at most {dt:.3g} s, at least {t_end / dt:.3g} steps")
        for g in given:
            rng = self.valid_range(g, full)
            if rng is None or full[g] is None or rng.contains(float(full[g])) or _empty(rng):
                continue
            raise ValueError(f"{g} = {shown(float(full[g]))} is outside the valid range "
                             f"{rng.range_text} at the other parameters' values ({why})")
        what = ", ".join(f"{g} = {v}" for g, v in given.items()) or "the defaults"
        raise ValueError(f"scene {self.name}: with {what}, {why}; change "
                         f"{', '.join(given) or 'them'} ('mpm2d show {self.name}' lists the "
                         "ranges)")

    def valid_range(self, key: str, full: dict) -> Number | None:
        """The valid values of the number ``key`` with every other parameter as in ``full``:
        its static range intersected with every derived bound it takes part in (its own, and
        the others' that depend on it), as the :class:`Number` of the interval around the
        declared default; None when the default itself is not valid there (no interval to
        report) or ``key`` is not a number."""
        p = self.params[key]
        if p.kind != "number":
            return None
        lo, lc, _, hi, hc, _ = p.schema.bounds(static=True)
        static = Number(key, lo, hi, lo_closed=lc, hi_closed=hc)

        def ok(x):
            return static.contains(x) and self._derived_ok({**full, key: x})

        rng = integer_range(ok, [self.defaults.get(key)], integer=p.integer)
        if rng is None:
            return None
        lo, lc, hi, hc = rng
        return Number(key, lo, hi, integer=p.integer, lo_closed=lc, hi_closed=hc, unit=p.unit)

    def _explain(self, key: str, exc: ValueError, full: dict, given: dict) -> ValueError:
        """The refusal of a derived bound of ``key``, said about the parameter the user set.

        A given number whose value lies outside its valid range at the other parameters
        (:meth:`valid_range`) is named with that range (``--set radius=1e-300`` is refused as
        radius, not as the default hub_radius that no longer fits); else, when the bound of
        ``key`` is empty or inverted there, the message says so without printing it and names
        the parameters to change; else the bound's own message (with the given values)."""
        p = self.params[key]
        for g in given:
            if self.params[g].kind != "number" or full[g] is None:
                continue
            rng = self.valid_range(g, full)
            if rng is None or rng.contains(float(full[g])) or _empty(rng):
                continue
            value = shown(float(full[g]))
            note = p.note_text(full)
            if g != key:
                val = full[key] if full[key] is not None or p.fill is None else p.fill(full)
                why = (f" at the other parameters' values ({key} = {shown(val)}"
                       + (f" must be within {note}" if note else " must stay valid") + ")")
            else:
                try:
                    own = p.number(key, full).range_text == rng.range_text
                except Exception:
                    own = False
                others = "" if own else "the bounds of the others at their values"
                why = "; ".join(filter(None, [note, others]))
                why = f" ({why})" if why else ""
            return ValueError(f"{g} = {value} is outside the valid range {rng.range_text}{why}")
        try:
            rng = p.number(key, full)
            empty = _empty(rng)
        except Exception:
            empty = True
        if empty:
            note = p.note_text(full)
            what = ", ".join(f"{g} = {v}" for g, v in given.items()) or "the defaults"
            change = ", ".join(given) or "the parameters it depends on"
            return ValueError(f"with {what}, no value of {key} is valid"
                              + (f" ({key}: {note})" if note else "")
                              + f"; change {change} ('mpm2d show {self.name}' lists the ranges)")
        if key in given or not given:
            return exc
        return ValueError(f"{exc}; with " + ", ".join(f"{g} = {v}" for g, v in given.items()))

    def step_bound(self, params: dict) -> tuple | None:
        """An upper bound of the run's first step from the parameters alone, before the set-up.

        The explicit step is at most ``cfl h / c`` (the elastic wave limit; the advection and
        viscous limits are smaller still), and the wave speed of the scene's suspension is at
        least ``c = sqrt(G min(1, moduli_factor) / max(rho_s, rho_f))`` of its material (the P
        wave, the pore fluid and the locked mixture's kappa only add to the modulus; a point's
        V/m is at least 1/max(rho_s, rho_f)); a fixed ``dt`` is the step itself. Scenes whose
        parameters do not give ``cfl``, ``t_end`` and the cell size (``h`` or ``cells_per_mm``)
        and a suspension material with G and densities get None (the runner's check after the
        set-up still applies).

        Returns
        -------
        (dt_max [s], t_end [s], text naming the parameters and their values) or None.
        """
        t_end = params.get("t_end")
        if not _is_real(t_end) or t_end <= 0:
            return None
        if _is_real(params.get("dt")) and params["dt"] > 0:
            return float(params["dt"]), float(t_end), f"dt = {params['dt']:g} s, t_end = " \
                                                      f"{t_end:g} s"
        cfl = params.get("cfl")
        if "h" in params and _is_real(params["h"]):
            h, h_text = float(params["h"]), f"h = {params['h']:g} m"
        elif "cells_per_mm" in params and _is_real(params["cells_per_mm"]):
            h = 1e-3 / float(params["cells_per_mm"])
            h_text = f"h = {h:g} m (cells_per_mm = {params['cells_per_mm']:g})"
        else:
            return None
        key = volume_fraction_key(self)
        if not _is_real(cfl) or key is None:
            return None
        try:
            name = self.params[key].fraction_of(params)
            m = get_material(name)
            factor = min(1.0, float(params.get("moduli_factor", 1.0)))
            rho = max(x for x in (m.rho_s, m.rho_f) if x is not None)
            with np.errstate(all="ignore"):
                c = math.sqrt(m.G * factor / rho)
        except (ValueError, TypeError, ArithmeticError):   # no G or densities: no estimate
            return None
        if not (c > 0 and math.isfinite(c)):
            return None
        return (float(cfl) * h / c, float(t_end),
                f"cfl = {cfl:g}, t_end = {t_end:g} s, {h_text} (the wave speed of material "
                f"{name!r} is at least {c:.3g} m/s)")

    def validate(self, given: dict) -> dict:
        """Every parameter (defaults completed by ``given``), checked (see :meth:`coerce`)."""
        return {**self.defaults, **self.coerce(given)}

    def estimate_bytes(self, params: dict) -> float:
        """Memory estimate of a run with ``params`` [bytes] (0 if the scene has no size): 2-3x
        the peak RSS growth of the scenes' runs (docs/measurements.md)."""
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


def parameters_of(size: Callable | None = None, /, **params: Param):
    """Decorator declaring the valid range of every parameter of a scene's ``setup``.

    ``size(params) -> (points, grid nodes)`` estimates the run's size for the memory check
    (positional, or the keyword ``size`` when it is not a :class:`Param`: a scene may have a
    parameter named ``size``). The wrapped ``setup`` validates its keyword arguments on every
    call (see :meth:`SceneSpec.coerce`) and has ``setup.spec``; ``setup.raw`` is the function
    itself, for a caller whose values are checked already (``mpm2d run``).

    Raises
    ------
    TypeError
        At import: the declaration and the signature do not name the same parameters, or a
        parameter has no default (a programming error, not bad input).
    """
    if size is None and callable(params.get("size")) and not isinstance(params["size"], Param):
        size = params.pop("size")

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

        checked.spec, checked.raw = spec, setup
        return checked

    return wrap


# ---------------------------------------------------------------- common declarations
def positive(hi, unit="", doc="", lo=0.0):
    """A number in (lo, hi] (default lo = 0)."""
    return Param(lo, hi, lo_closed=False, unit=unit, doc=doc)


def count(lo, hi, doc=""):
    """An integer in [lo, hi]."""
    return Param(lo, hi, integer=True, doc=doc)


def physical(lo: Bound, hi: Bound, unit: str, doc: str = "") -> Param:
    """A number between two physical limits of :mod:`runkit.limits`, with their reasons."""
    return Param(lo.value, hi.value, lo_closed=lo.closed, hi_closed=hi.closed, unit=unit,
                 doc=doc, lo_why=lo.why, hi_why=hi.why)


def modulus(doc=""):
    return physical(limits.MODULUS_MIN, limits.MODULUS_MAX, "Pa", doc)


def density(doc=""):
    return physical(limits.DENSITY_MIN, limits.DENSITY_MAX, "kg/m^3", doc)


def grain_size(doc="grain diameter (sets the drag)"):
    return physical(limits.GRAIN_MIN, limits.GRAIN_MAX, "m", doc)


#: the stable step's safety factor: its physical range and the reasons
CFL_MIN = limits.ge(0.01, "a step below 1% of the stable one gains no accuracy (the error is "
                          "the grid's) for 50 times the steps of the default 0.5")
CFL_MAX = limits.le(1.0, "the Courant-Friedrichs-Lewy limit of the explicit step: a wave "
                         "crosses at most one cell per step")


def cfl(doc="safety factor of the stable step"):
    return physical(CFL_MIN, CFL_MAX, "", doc)


def transfer():
    return Param(choices=("apic", "flip", "pic"), doc="particle-grid transfer")


def flip_alpha():
    return Param(0.0, 1.0, doc="FLIP fraction of the FLIP/PIC blend (transfer=flip)")


def gravity(doc="gravitational acceleration (downwards; the bed rests under it)"):
    """Gravity of a scene whose bed starts at rest under it (mpm2d.geostatic)."""
    return physical(limits.GRAVITY_MIN, limits.GRAVITY_MAX, "m/s^2", doc)


def rules() -> Param:
    """The ``rules`` of the scene's suspension material (:data:`rheology.materials.RULES`)."""
    return Param(choices=RULES, doc="yield rules of the Table 8 law: table8 (the paper's) or "
                                    "mpm_3d (the author's code; rheology.local_update)")


def scene_material_param(scene_set: str, doc: str = "steady-flow parameters") -> Param:
    """A ``material`` parameter: any SI parameter set or a material file (``fit/material.json``
    from ``rheometer fit``), put on the scene's own set ``scene_set`` by
    :func:`rheology.materials.scene_material` (which the scene calls to build it)."""
    return Param(material_of=scene_set, doc=doc)


def materials_where(predicate: Callable, what: str) -> Callable[[], tuple]:
    """Choices: the rheology parameter sets ``m`` with ``predicate(m)`` true (``what`` says
    which, for ``mpm2d show``)."""

    def names():
        return tuple(n for n in material_names() if predicate(get_material(n)))

    names.what = what
    return names


def phi_below_jamming(material_key="material", fixed=None, doc="initial solid volume fraction",
                      optional=False, fill=None):
    """A volume fraction in (0, phi_j) of the scene's material (``params[material_key]``, or the
    ``fixed`` material: a name or a function of the parameters); ``optional``: ``none`` allowed
    (the scene picks its value, ``fill(params)``, checked the same)."""

    def name(p):
        return fixed(p) if callable(fixed) else fixed if fixed else p[material_key]

    def phi_j(p):
        return get_material(name(p)).phi_j

    return Param(0.0, phi_j, lo_closed=False, hi_closed=False, doc=doc, optional=optional,
                 note=lambda p: f"phi_j of material {name(p)!r}", fraction_of=name, fill=fill)


def volume_fraction_key(spec) -> str | None:
    """The scene's volume-fraction parameter (declared with :func:`phi_below_jamming`), if any."""
    return next((k for k, p in spec.params.items() if p.fraction_of is not None), None)


