"""The parameters of the scenes, declared on :class:`runkit.params.Schema`: one check.

Every scene declares each ``setup`` parameter with :func:`parameters_of`::

    @parameters_of(
        cells=cells("cells along L", 2, 4096),   # each bound with its reason
        height=length("bed height"),             # [LENGTH_MIN, LENGTH_MAX] m
        phi0=phi_below_jamming(),                # [PHI_MIN, phi_j of the material)
        material=Param(choices=suspension_materials),
        size=lambda p: (points, nodes),          # memory estimate before anything is built
    )
    def setup(cells=32, height=0.1, phi0=0.3, material="rod_impact"): ...

:func:`Param` and the helpers below build :class:`runkit.params.Param`: a parameter with a unit
between the physical limits of :mod:`runkit.limits` with their reasons (:func:`physical` and its
kinds :func:`length`, :func:`speed`, :func:`duration`, :func:`rate`, :func:`stress`, ...), or
tighter where a bound of the scene's own (with its reason) or a function of the other
parameters is; a dimensionless one with the reason of each end. The
decorated ``setup`` checks its keyword arguments by its ``setup.spec``, a
:class:`runkit.params.Schema` (type, finiteness, static range; the derived bounds; the step
count; the memory estimate). A refusal is one ``ValueError`` line naming the parameter the user
set, its value and its valid range at the other values.

The step count: a scene states its run with ``steps`` (its first stable step from its
parameters, :func:`first_step`: the limits of
:meth:`mpm2d.simulation.Simulation.stable_dt` at t = 0; its end time; its fewest steps), and a
run outside [fewest, :data:`runkit.limits.MAX_STEPS`] steps is refused before the set-up, said
about the parameter the user set with its bound in its units (:func:`run_refusal`). A scene
without ``steps`` has the schema's constraint: the explicit step is at most ``cfl h / c`` with
``c >= sqrt(G min(1, moduli_factor) / max(rho_s, rho_f))`` of the scene's suspension (or the
fixed ``dt``), so ``t_end / dt_max`` steps at least (:func:`step_bound`), at most MAX_STEPS.
"""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable

import numpy as np

from runkit import limits
from runkit.limits import MAX_STEPS, Bound
from runkit.params import Param as SchemaParam
from runkit.params import Schema, shown
from rheology import get_material, material_names
from rheology.materials import RULES, scene_material

from ..simulation import Simulation

#: memory estimate: bytes per material point (kinematic arrays ~40 float64, material state,
#: the output copies of a snapshot and the permutation copies of a sort) and per grid node (per
#: phase: the node fields, one private copy per thread, velocities; two phases at most)
BYTES_PER_POINT = 1200
BYTES_PER_NODE = 2 * 8 * (9 * 3 + 12)
#: what any run takes besides its arrays (interpreter, numba and its compiled kernels)
BASE_BYTES = 2e8
#: the reason of the step-count limit (runkit.limits.MAX_STEPS)
STEPS_WHY = "about a day on one core at the smallest scene"


def Param(lo=None, hi=None, *, integer=False, lo_closed=True, hi_closed=True, unit="",
          choices=None, boolean=False, optional=False, doc="", note: str | Callable = "",
          fill=None, lo_why="", hi_why="", role="", of=None) -> SchemaParam:
    """A scene parameter as :class:`runkit.params.Param`: ``lo``, ``hi`` a number, None or a
    function of the other parameters (then ``note``, text or a function of them, is its
    reason; a static bound's is ``lo_why``/``hi_why``, else a text ``note``); ``choices``
    (a tuple or a function returning one), ``boolean``; ``fill``, ``role``, ``of`` as
    :class:`runkit.params.Param`."""
    def bound(x, closed, why):
        if x is None:
            return None
        return Bound(x, closed, note if callable(x) else why or
                     (note if isinstance(note, str) else ""))

    kind = ("choice" if choices is not None else "bool" if boolean else
            "integer" if integer else "number")
    return SchemaParam(bound(lo, lo_closed, lo_why), bound(hi, hi_closed, hi_why), unit=unit,
                       kind=kind, doc=doc, choices=choices or (), optional=optional,
                       fill=fill, role=role, of=of)


#: the safety factor of the viscous limit of the scenes' steps (Simulation's default)
CFL_VISC = inspect.signature(Simulation).parameters["cfl_visc"].default


def first_step(cfl: float, h: float, phases, speed: float = 0.0,
               cfl_visc: float = CFL_VISC) -> float:
    """The set-up's first stable step from the parameters alone [s]: the limits of
    :meth:`mpm2d.simulation.Simulation.stable_dt` at t = 0, the smallest of the elastic wave
    ``cfl h / sqrt(max S V/m)``, the advection ``cfl h / |v|max`` and the viscous diffusion
    ``cfl_visc h^2 / max(eta V/m)`` limits.

    Parameters
    ----------
    cfl : float
        Safety factor of the wave and advection limits.
    h : float
        Cell size [m].
    phases : iterable of (material, density)
        Each point set's material (:mod:`mpm2d.materials`: its ``wave_modulus()`` S [Pa] and
        ``viscosity_bound()`` eta [Pa s]) and the smallest m/V of its points [kg/m^3] (V/m
        at its largest: a fluid compressed by the weight only raises m/V).
    speed : float
        The largest initial speed of a point or a rigid body's point [m/s].
    cfl_visc : float
        Safety factor of the viscous limit.
    """
    phases = list(phases)
    c2 = max(mat.wave_modulus() / rho for mat, rho in phases)
    nu = max(mat.viscosity_bound() / rho for mat, rho in phases)
    return min(cfl * h / math.sqrt(c2) if c2 > 0 else math.inf,
               cfl * h / speed if speed > 0 else math.inf,
               cfl_visc * h * h / nu if nu > 0 else math.inf)


def _is_real(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def volume_fraction_key(schema) -> str | None:
    """The scene's volume-fraction parameter (declared with :func:`phi_below_jamming`), if any."""
    return next((k for k, p in schema.params.items() if p.role == "volume_fraction"), None)


def step_bound(schema, params: dict) -> tuple | None:
    """An upper bound of the run's first step from the parameters alone, before the set-up.

    The explicit step is at most ``cfl h / c`` (the elastic wave limit; the advection and
    viscous limits are smaller still), and the wave speed of the scene's suspension is at least
    ``c = sqrt(G min(1, moduli_factor) / max(rho_s, rho_f))`` of its material (the P wave, the
    pore fluid and the locked mixture's kappa only add to the modulus; a point's V/m is at
    least 1/max(rho_s, rho_f)); a fixed ``dt`` is the step itself. Scenes whose parameters do
    not give ``cfl``, ``t_end`` and the cell size (``h`` or ``cells_per_mm``) and a suspension
    material with G and densities get None (the runner's check after the set-up still applies).

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
    if _is_real(params.get("h")):
        h, h_text = float(params["h"]), f"h = {params['h']:g} m"
    elif _is_real(params.get("cells_per_mm")):
        h = 1e-3 / float(params["cells_per_mm"])
        h_text = f"h = {h:g} m (cells_per_mm = {params['cells_per_mm']:g})"
    else:
        return None
    key = volume_fraction_key(schema)
    if not _is_real(cfl) or key is None:
        return None
    try:
        name = schema.params[key].of(params)
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


def run_steps(schema, params: dict) -> tuple | None:
    """(first step [s], t_end [s], fewest steps) before the set-up: the scene's ``steps``
    (its first stable step) where it declares them, else :func:`step_bound` (an upper bound of
    the step, so the steps are a lower bound; its third entry is the text naming the
    parameters); None where neither can be evaluated."""
    if schema.steps is None:
        return step_bound(schema, params)
    try:
        with np.errstate(all="ignore"):
            return schema.steps(params)
    except (ValueError, ArithmeticError, TypeError):
        return None


def steps_unmet(schema, params: dict) -> str | None:
    """The step-count constraint: None where the run takes at most MAX_STEPS steps at the
    largest step its parameters allow (or they give none, or the scene states its run with
    ``steps``: :func:`run_refusal` says it, at its first stable step), else the reason."""
    bound = None if schema.steps is not None else step_bound(schema, params)
    if bound is None:
        return None
    dt, t_end, knobs = bound
    if dt > 0 and t_end / dt <= MAX_STEPS:
        return None
    return (f"a run takes at most {MAX_STEPS:.0e} steps, {STEPS_WHY}; {knobs} give a step of at "
            f"most {dt:.3g} s, at least {t_end / dt:.3g} steps")


def estimate_bytes(schema, params: dict) -> float:
    """Memory estimate of a run with ``params`` [bytes] (0 if the scene has no size): 2-3x the
    peak RSS growth of the scenes' runs (docs/measurements.md)."""
    if schema.extent is None:
        return 0.0
    points, nodes = schema.extent(params)
    nbytes = BASE_BYTES + float(points) * BYTES_PER_POINT + float(nodes) * BYTES_PER_NODE
    return nbytes if math.isfinite(nbytes) else math.inf


def _round_toward(x: float, up: bool) -> float:
    """``x`` to 3 significant digits, rounded toward ``up`` (away from the invalid side)."""
    if x == 0 or not math.isfinite(x):
        return x
    e = math.floor(math.log10(abs(x))) - 2
    m = x / 10.0 ** e
    return float(f"{(math.ceil(m) if up else math.floor(m)) * 10.0 ** e:.3g}")


def _run_why(schema, params: dict) -> str | None:
    """Why the run the parameters give cannot be analysed (None: it can): its step count from
    the scene's ``steps`` (first step, end time, fewest steps) outside [fewest, MAX_STEPS]."""
    try:
        with np.errstate(all="ignore"):
            if schema.steps is not None:
                dt, t_end, need = schema.steps(params)
                n = t_end / dt if dt > 0 else math.inf
                if n > MAX_STEPS:
                    return (f"makes the run too long (a step of {dt:.3g} s to t_end = "
                            f"{t_end:.3g} s is {n:.3g} steps, more than {MAX_STEPS:.0e})")
                if not n >= need:
                    return (f"makes the run too short (t_end = {t_end:.3g} s is {n:.3g} of its "
                            f"first stable steps ({dt:.3g} s); the run needs at least {need})")
    except (ValueError, ArithmeticError, TypeError):
        return "makes the run undefined (its step cannot be evaluated)"
    return None


def run_refusal(schema, params: dict, given: dict) -> ValueError | None:
    """The refusal of a run whose step count (:func:`_run_why`) its
    parameters put out of range, before the set-up, said about each given parameter out of its
    valid range at the other values (:meth:`runkit.params.Schema.valid_range` with the run's
    condition: the bound the scene's formulas give, rounded toward the valid side); None when
    the run can be analysed."""
    why = _run_why(schema, params)
    if why is None:
        return None
    changed = [k for k, v in given.items() if v != schema.defaults.get(k)]
    if not changed:
        return ValueError(f"scene {schema.name}: its defaults {why}")
    parts = []
    for k in changed:
        p, v = schema.params[k], params[k]
        if not p.numeric or v is None:
            continue
        stable = []                          # a fixed step: start at the stable one
        if k == "dt" and schema.steps is not None:
            stable = [schema.steps({**params, k: None})[0]]
        if p.fill is not None:               # an optional one: also at the value none takes
            stable.append(p.fill({**params, k: None}))
        rng = schema.valid_range(k, params, lambda at: _run_why(schema, at) is None, stable)
        if rng is None:
            continue
        lo, lc, hi, hc = rng
        up = lo is not None and (v < lo or (v == lo and not lc))
        if not up and not (hi is not None and (v > hi or (v == hi and not hc))):
            continue
        edge = _round_toward(lo if up else hi, up)
        if _run_why(schema, {**params, k: edge}) is not None:
            edge = lo if up else hi
        unit = f" {p.unit}" if p.unit else ""
        parts.append(f"{k} = {shown(v)} {why}; valid: {k} {'>=' if up else '<='} {edge:.6g}"
                     f"{unit} at the other values" + (f", or {k} = none" if p.optional else ""))
    if parts:
        return ValueError(f"scene {schema.name}: " + "; ".join(parts))
    what = ", ".join(f"{k} = {shown(params[k])}" for k in changed)
    return ValueError(f"scene {schema.name}: {what} {why}; valid: move them toward their "
                      f"defaults ('mpm2d show {schema.name}' lists the ranges)")


def parameters_of(size: Callable | None = None, /, *, steps: Callable | None = None,
                  **params: SchemaParam):
    """Decorator declaring the valid range of every parameter of a scene's ``setup``.

    ``size(params) -> (points, grid nodes)`` estimates the run's size for the memory check
    (positional, or the keyword ``size`` when it is not a parameter: a scene may have a
    parameter named ``size``). The wrapped ``setup`` checks its keyword arguments on every call
    by ``setup.spec``, the scene's :class:`runkit.params.Schema` (with ``name`` and
    ``extent``, the size function); ``setup.raw`` is the function itself, for a caller whose
    values are checked already (``mpm2d run``).

    ``steps(params) -> (first stable step [s], end time [s], fewest steps)`` states, where the
    scene can, its run from its parameters alone: a run outside it is refused before the set-up
    (:func:`run_refusal`).

    Raises
    ------
    TypeError
        At import: the declaration and the signature do not name the same parameters, or a
        parameter has no default (a programming error, not bad input).
    """
    if size is None and callable(params.get("size")) and \
            not isinstance(params["size"], SchemaParam):
        size = params.pop("size")

    def wrap(setup):
        sig = inspect.signature(setup).parameters
        missing = [k for k in sig if k not in params]
        extra = [k for k in params if k not in sig]
        if missing or extra:
            raise TypeError(f"{setup.__module__}.setup: parameters without a declared range "
                            f"{missing}, declared but not in the signature {extra}")
        nodefault = [k for k, p in sig.items() if p.default is inspect.Parameter.empty]
        if nodefault:
            raise TypeError(f"{setup.__module__}.setup: parameters without a default {nodefault}")
        name = setup.__module__.rsplit(".", 1)[-1]
        schema = Schema(params, {k: p.default for k, p in sig.items()},
                        size=None if size is None else lambda p: estimate_bytes(schema, p),
                        where=f"scene {name}", at_others=True,
                        hint=f" ('mpm2d show {name}' lists the ranges)",
                        constraints=[lambda p: steps_unmet(schema, p)])
        schema.name, schema.extent, schema.steps = name, size, steps

        @functools.wraps(setup)
        def checked(**kwargs):
            return setup(**schema.check(kwargs))

        checked.spec, checked.raw = schema, setup
        return checked

    return wrap


# ---------------------------------------------------------------- common declarations
def positive(hi, unit="", doc="", lo=0.0):
    """A number in (lo, hi] (default lo = 0)."""
    return Param(lo, hi, lo_closed=False, unit=unit, doc=doc)


def count(lo, hi, doc="", lo_why="", hi_why=""):
    """An integer in [lo, hi], each end with its reason."""
    return Param(lo, hi, integer=True, doc=doc, lo_why=lo_why, hi_why=hi_why)


#: the reasons of the resolution counts
CELLS_WHY = "two cells: the smallest grid with a node between its ends"
CELLS_MAX_WHY = ("at 1e5 cells the grid's error (~h^2) is below 1e-10, the rounding of the "
                 "positions: no finer grid changes the result")
PPC_WHY = ("one point per cell and direction at least", "8 per direction (64 per cell): past "
           "where more points change the quadrature of a cell")


def ppc():
    return count(1, 8, "points per cell and direction", *PPC_WHY)


def cells(doc, lo=2, hi=100000, lo_why=CELLS_WHY, hi_why=CELLS_MAX_WHY):
    return count(lo, hi, doc, lo_why, hi_why)


def runs_for(doc, hi, hi_why):
    """A dimensionless run length (periods, a time in units of the scene's): positive, the
    step count bounding it below."""
    return Param(0.0, hi, lo_closed=False, doc=doc, lo_why="a run of positive length (its step "
                 "count bounds it further)", hi_why=hi_why)


def _tighter(limit: Bound, derived: Bound | None, upper: bool) -> Bound:
    """The physical ``limit``, or the ``derived`` bound (a function of the other parameters,
    with its reason) where that is tighter."""
    if derived is None:
        return limit

    def value(p):
        return (min if upper else max)(limit.value, derived.at(p)[0])

    def why(p):
        return derived.at(p)[2] if value(p) != limit.value else limit.why

    return Bound(value, derived.closed if derived.derived else limit.closed, why)


def physical(lo: Bound, hi: Bound, unit: str, doc: str = "", *, above: Bound | None = None,
             below: Bound | None = None, **kw) -> SchemaParam:
    """A number between two physical limits of :mod:`runkit.limits`, with their reasons (or
    tighter, a scene's own :class:`~runkit.limits.Bound` with its reason); ``above``,
    ``below``: bounds that are functions of the other parameters, where tighter (its valid
    range at the others). ``kw``: ``optional``, ``fill``, ``also``, ``role``, ``of`` of
    :class:`runkit.params.Param`."""
    return SchemaParam(_tighter(lo, above, False), _tighter(hi, below, True), unit=unit, doc=doc,
                       **kw)


def length(doc="", lo=limits.LENGTH_MIN, hi=limits.LENGTH_MAX, **kw):
    return physical(lo, hi, "m", doc, **kw)


def speed(doc="", lo=limits.SPEED_MIN, hi=limits.SPEED_MAX, **kw):
    return physical(lo, hi, "m/s", doc, **kw)


def duration(doc="", lo=limits.TIME_MIN, hi=limits.TIME_MAX, **kw):
    return physical(lo, hi, "s", doc, **kw)


def rate(doc="", lo=limits.RATE_MIN, hi=limits.RATE_MAX, **kw):
    return physical(lo, hi, "1/s", doc, **kw)


def stress(doc="", lo=limits.STRESS_MIN, hi=limits.STRESS_MAX, zero=False, **kw):
    """A stress; ``zero``: 0 (none) valid too."""
    return physical(lo, hi, "Pa", doc, also=(0.0,) if zero else (), **kw)


#: the grid resolution 1/h [1/mm]: a cell within the physical lengths
RESOLUTION_MIN = limits.ge(1e-3 / limits.LENGTH_MAX.value, "a cell of at most "
                           f"{limits.LENGTH_MAX.value:g} m: {limits.LENGTH_MAX.why}")
RESOLUTION_MAX = limits.le(1e-3 / limits.LENGTH_MIN.value, "a cell of at least "
                           f"{limits.LENGTH_MIN.value:g} m: {limits.LENGTH_MIN.why}")


def resolution(doc="1/h in 1/mm", lo=RESOLUTION_MIN, hi=RESOLUTION_MAX, **kw):
    return physical(lo, hi, "1/mm", doc, **kw)


def viscosity(doc="fluid viscosity"):
    return physical(limits.VISCOSITY_MIN, limits.VISCOSITY_MAX, "Pa s", doc)


def poisson(doc="Poisson ratio"):
    """A Poisson ratio in (-1, 1/2): the moduli of an isotropic elastic solid positive."""
    return SchemaParam(limits.gt(-1.0, "the shear modulus E/(2(1 + nu)) must be positive"),
                       limits.lt(0.5, "the bulk modulus E/(3(1 - 2 nu)) must be finite (0.5: "
                                      "incompressible)"), doc=doc)


def fraction(doc, lo_why, hi_why, hi_closed=True):
    """A dimensionless fraction in [0, 1]."""
    return Param(0.0, 1.0, doc=doc, lo_why=lo_why, hi_why=hi_why, hi_closed=hi_closed)


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
    return fraction("FLIP fraction of the FLIP/PIC blend (transfer=flip)", "0: PIC",
                    "1: FLIP (a blend of the two)")


def gravity(doc="gravitational acceleration (downwards; the bed rests under it)"):
    """Gravity of a scene whose bed starts at rest under it (mpm2d.geostatic)."""
    return physical(limits.GRAVITY_MIN, limits.GRAVITY_MAX, "m/s^2", doc)


def rules() -> SchemaParam:
    """The ``rules`` of the scene's suspension material (:data:`rheology.materials.RULES`)."""
    return Param(choices=RULES, doc="yield rules of the Table 8 law: table8 (the paper's) or "
                                    "mpm_3d (the author's code; rheology.local_update)")


def scene_material_param(scene_set: str, doc: str = "steady-flow parameters") -> SchemaParam:
    """A ``material`` parameter: any SI parameter set or a material file (``fit/material.json``
    from ``rheometer fit``), put on the scene's own set ``scene_set`` by
    :func:`rheology.materials.scene_material` (which the scene calls to build it)."""
    def convert(value) -> str:
        if not isinstance(value, str) or not value.strip():
            raise ValueError(f"material = {value!r} is not a parameter set name or a material "
                             "file")
        try:
            scene_material(scene_set, value.strip())
        except ValueError as exc:
            raise ValueError(f"material = {value!r} is not one of the SI parameter sets or a "
                             f"valid material file: {exc}") from None
        return value.strip()

    convert.what = ("an SI parameter set (rheometer materials) or a material file *.json; the "
                    f"moduli, densities, d and K0 it leaves unset come from {scene_set}")
    return SchemaParam(kind="text", convert=convert, doc=doc, role="material")


def materials_where(predicate: Callable, what: str) -> Callable[[], tuple]:
    """Choices: the rheology parameter sets ``m`` with ``predicate(m)`` true (``what`` says
    which, for ``mpm2d show``)."""

    def names():
        return tuple(n for n in material_names() if predicate(get_material(n)))

    names.what = what
    return names


def phi_below_jamming(material_key="material", fixed=None, doc="initial solid volume fraction",
                      optional=False, fill=None):
    """A volume fraction in [PHI_MIN, phi_j) of the scene's material (``params[material_key]``, or the
    ``fixed`` material: a name or a function of the parameters); ``optional``: ``none`` allowed
    (the scene picks its value, ``fill(params)``, checked the same). ``mpm2d run
    --mass-fraction`` sets it through Eq. (20) (its ``role``)."""

    def name(p):
        return fixed(p) if callable(fixed) else fixed if fixed else p[material_key]

    return SchemaParam(limits.PHI_MIN, Bound(lambda p: get_material(name(p)).phi_j, False,
                                             lambda p: f"phi_j of material {name(p)!r}"),
                       doc=doc, optional=optional, fill=fill, role="volume_fraction", of=name)


def spec_of(setup: Callable) -> Schema:
    """The declared parameters (:class:`runkit.params.Schema`) of a scene's ``setup``."""
    spec = getattr(setup, "spec", None)
    if spec is None:
        raise TypeError(f"{getattr(setup, '__module__', setup)}.setup declares no parameters "
                        "(decorate it with mpm2d.scenes.spec.parameters_of)")
    return spec
