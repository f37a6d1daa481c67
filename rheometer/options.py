"""The options every measuring command of ``rheometer`` shares (the sample: material, ``--set``,
``--phi``, mass fraction, measuring geometry; ``--G``, ``--K0`` and the transient options; the
figure path) and the :class:`Sample` they describe, resolved once (:func:`sample_material`) and
passed to :mod:`rheometer.cli`'s and :mod:`rheometer.instrument_cli`'s commands.

Every option is checked once: its static range by its :class:`runkit.params.Option` while
parsing (or, where a library function checks it, by that function, named as the option), a
bound that depends on the material (``--phi`` below phi_j, ``--set`` against the
material's other fields, a geometry's dimensions against each other) when the sample is
resolved, with the valid range at the other values."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

import rheology
from rheology.materials import (FIELD_UNITS, Material, default_fraction, default_fractions,
                                set_argument, set_overrides)
from rheology.sample import add_mass_fraction_options, mass_fraction_phi
from runkit.io import check_output_path
from runkit.params import Number, OutOfRange, valid_interval

from . import geometry as geo
from . import limits
from .limits import Quantity
from .transient import check_phi

DEFAULT_MATERIAL = "hermes2016"
#: ``--phi`` of the fit commands: its static range [1e-6, 1) (a measured fraction, checked by
#: rheology.data); a measuring command's --phi is read as a number and checked once, in
#: [1e-6, phi_j) of the material, by :class:`Sample` (:func:`check_phi`)
PHI = Quantity("--phi", limits.PHI)
#: where phi_j comes from in a --phi refusal when the user set it (not the named material's)
SET_PHI_J = "(--set phi_j)"


# ------------------------------------------------------------------ the measuring geometry
def _flag(key: str) -> str:
    return "--" + key.replace("_", "-")


_d = geo.DEFAULTS
_NAMES = {"cone_angle": "cone_angle_deg"}          # option dest -> Geometry.make's name


def add_instrument_options(p) -> None:
    """Geometry and mass-fraction options of every measuring command."""
    g = p.add_argument_group("measuring geometry (torque, rotation speed, apparent stress and "
                             "rate by the standard conversions)")
    g.add_argument("--geometry", choices=geo.GEOMETRIES, default=None,
                   help="cone-plate | parallel-plate | couette (default: none, sample values only)")
    # a bound set by another dimension (cone angle, cup radius) is checked with it, in
    # Geometry.make: here the range in words
    g.add_argument("--cone-angle", type=Quantity(
                       "--cone-angle", geo.CONE_ANGLE, f"[atan({geo.LENGTH_MIN:g} m / radius), "
                       f"{geo.CONE_ANGLE_MAX:g}] deg"), default=None,
                   help=f"cone angle [deg] (cone-plate; {_d['cone_angle_deg']:g})")
    g.add_argument("--radius", type=Quantity("--radius", geo.LENGTH), default=None,
                   help=f"cone or plate radius [m] ({_d['cone_radius']:g} cone, "
                        f"{_d['plate_radius']:g} plate)")
    for key, what, kind in (("gap", "plate gap", "parallel-plate"),
                            ("bob_radius", "bob radius", "couette"),
                            ("cup_radius", "cup radius", "couette"),
                            ("bob_length", "immersed bob length", "couette")):
        g.add_argument(_flag(key), type=Quantity(_flag(key), *(
                           (geo.CUP_RADIUS, f"[bob radius + {geo.LENGTH_MIN:g}, "
                                            f"{geo.LENGTH_MAX:g}] m")
                           if key == "cup_radius" else (geo.LENGTH,))), default=None,
                       help=f"{what} [m] ({kind}; {_d[key]:g})")
    add_mass_fraction_options(p)


def geometry_of(args) -> geo.Geometry | None:
    """The geometry of ``--geometry`` and its dimensions, checked once (by
    :meth:`~rheometer.geometry.Geometry.make`; None without it); ValueError when a dimension of another geometry is given."""
    kind = getattr(args, "geometry", None)
    given = {k: getattr(args, k) for k in ("cone_angle", "radius", "gap", "bob_radius",
                                           "cup_radius", "bob_length")
             if getattr(args, k, None) is not None}
    if kind is None:
        if given:
            raise ValueError(f"{_flag(next(iter(given)))} needs --geometry "
                             f"(cone-plate, parallel-plate or couette)")
        return None
    params = geo.DIMENSIONS[kind][0]
    wrong = [k for k in given if _NAMES.get(k, k) not in params]
    if wrong:
        raise ValueError(f"{_flag(wrong[0])} is not a dimension of --geometry {kind} "
                         f"(its dimensions: {', '.join(map(_option, params))})")
    return geo.Geometry.make(kind, label=_option, **{_NAMES.get(k, k): v for k, v in given.items()})


def _option(name: str) -> str:
    """The option of a dimension of :meth:`rheometer.geometry.Geometry.make`."""
    return _flag({v: k for k, v in _NAMES.items()}.get(name, name))


def _range_without(label: str, v: float, x0: float, ok, unit: str = "") -> str | None:
    """The valid range of a value at the others' (bisection around the valid ``x0`` with the
    check ``ok``, :func:`runkit.params.valid_interval`) as text, when ``v`` lies outside it;
    else None (``v`` is valid, or ``x0`` is not)."""
    if not ok(float(x0)):
        return None
    lo, lo_closed, hi, hi_closed = valid_interval(ok, float(x0))
    rng = Number(label, lo, hi, lo_closed=lo_closed, hi_closed=hi_closed, unit=unit)
    return None if rng.contains(float(v)) else rng.range_text


# ------------------------------------------------------------------ the sample
@dataclass(frozen=True)
class Sample:
    """What a measuring command runs on: the material, the volume fractions (``--phi``, from
    ``--mass-fraction`` or the material's defaults; each in (0, phi_j)), the measuring geometry
    (None: sample values only) and, from ``--mass-fraction``, phi -> mass fraction and the note
    of the Eq. 20 conversion."""

    material: Material
    phi: list
    geometry: geo.Geometry | None = None
    mass: dict | None = None
    mass_note: str = ""


def once(option: str, values, note: str = "give each once") -> None:
    """Refuse a value given twice to a list option (one line naming the option and value)."""
    seen = []
    for v in values or []:
        if v in seen:
            raise ValueError(f"{option} {v} is given twice; {note}")
        seen.append(v)


def _fractions(args, m) -> tuple[list, dict | None, str]:
    """(phi, phi -> mass fraction or None, note) of the options. ValueError (one line, exit 2)
    for --phi with --mass-fraction, a fraction given twice, or a fraction >= phi_j: the one
    check of --phi (rheometer.transient.check_phi: in [PHI_MIN, phi_j) of the material)."""
    repeat = "its curves would repeat; give distinct "
    if getattr(args, "mass_fraction", None) is not None:
        if args.phi is not None:
            raise ValueError("give --phi or --mass-fraction, not both")
        once("--mass-fraction", [float(w) for w in args.mass_fraction],
             repeat + "mass fractions")
        phi, note = mass_fraction_phi(args, m)
        return phi, dict(zip(phi, map(float, args.mass_fraction))), note
    if args.phi is None:
        count = getattr(args, "_phi_count", 1)
        return (default_fractions(m) if count > 1 else [default_fraction(m)]), None, ""
    once("--phi", args.phi, repeat + "fractions")
    source = SET_PHI_J if "phi_j" in set_overrides(args.set) else ""
    return [check_phi("--phi", p, m, source=source) for p in args.phi], None, ""


def material_with(name, overrides: dict, option: str = "--set"):
    """``rheology.get_material(name, **overrides)`` whose refusal names the parameter set.

    The Material checks its fields together (phi_c < phi_j, a_inf >= a0, mu_2 >= mu_c, phi0 <
    phi_j), so its refusal may name a parameter the user did not set (``--set phi_j=0.3``
    breaks phi_c < phi_j); such a refusal is restated about the set parameter with its valid
    range at the material's other values (bisection on the Material's checks,
    :func:`valid_interval`).

    Raises
    ------
    ValueError
        ``--set NAME = VALUE is outside the valid range R (with material M's other parameters:
        <the check it breaks>)``, or the Material's own message when that already names a set
        parameter with a range that holds.
    """
    try:
        return rheology.get_material(name, **overrides)
    except ValueError as exc:
        try:
            base = rheology.get_material(name)
        except ValueError:
            raise exc from None
        raise about_set(base, overrides, exc, option, FIELD_UNITS) from None


def about_set(base, overrides: dict, exc: ValueError, option: str, units: dict) -> ValueError:
    for key, v in overrides.items():
        x0 = getattr(base, key, None)
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not isinstance(
                x0, (int, float)):
            continue

        def ok(x, key=key):
            try:
                with np.errstate(all="ignore"):
                    base.replace(**{**overrides, key: x})
            except (ValueError, ArithmeticError):
                return False
            return True

        unit = units.get(key, "-")
        rng = _range_without(f"{option} {key}", v, x0, ok, "" if unit == "-" else unit)
        if rng is None:
            continue
        # the Material's refusal names the field it failed on, its value and the reason
        # ("material M; NOTE"): keep the field, its value and the note, not its range
        if isinstance(exc, OutOfRange):
            note = exc.why.partition("; ")[2] if exc.why.startswith("material ") else exc.why
            if exc.name == key:
                why = f" ({note})" if note else ""
            else:
                why = (f" (with material {base.name}'s other parameters: {exc.name} = "
                       f"{exc.value_text}" + (f"; {note}" if note else "") + ")")
        else:
            why = f" (with material {base.name}'s other parameters: {exc})"
        return ValueError(f"{option} {key} = {v:g} is outside the valid range {rng}"
                          f"{why}")
    return exc


def sample_material(args) -> Sample:
    """The :class:`Sample` of a measuring command's options (material with ``--set``)."""
    m = material_with(args.material, set_overrides(args.set))
    phi, mass, note = _fractions(args, m)
    return Sample(m, phi, geometry_of(args), mass, note)


def default_phis(count: int) -> list[float]:
    """The fractions a command with ``count`` default fractions runs at on DEFAULT_MATERIAL
    (rheology.materials, the rule :class:`Sample` applies): three, or the middle one."""
    return (default_fractions(DEFAULT_MATERIAL) if count > 1
            else [default_fraction(DEFAULT_MATERIAL)])


#: --phi's range as a refusal before the material is known states it (nan, text): its upper
#: bound is phi_j of the material the later check (check_phi) knows
PHI_SHOWN = f"[{limits.PHI.lo.value:g}, phi_j of the material)"


def common_options(p, phi_count, out_default):
    """Options of every measuring command; ``phi_count`` (1 or 3) default fractions."""
    phi_default = default_phis(phi_count)
    p.add_argument("--material", default=DEFAULT_MATERIAL, metavar="NAME",
                   help=f"parameter set (default {DEFAULT_MATERIAL}; see 'rheometer materials')")
    p.add_argument("--phi", type=Quantity("--phi", limits.PHI, PHI_SHOWN, later=True), nargs="+",
                   default=None,
                   metavar="PHI",
                   help=("volume fraction(s) (default: "
                         + ("the material's reference fraction" if len(phi_default) == 1 else
                            f"{len(phi_default)} fractions around the material's reference")
                         + f", see 'rheometer materials'; for {DEFAULT_MATERIAL}: "
                         f"{' '.join(f'{x:g}' for x in phi_default)})"))
    p.set_defaults(_phi_count=len(phi_default))
    p.add_argument("--set", action="append", type=set_argument, metavar="NAME=VALUE",
                   help="override a numeric material parameter, e.g. --set eta0=0.01, or unset "
                        "an optional one (G=none); repeatable; the text fields name, citation, "
                        "units, notes are not settable")
    p.add_argument("--out", default=f"{out_default}.csv", metavar="FILE.csv",
                   help=f"CSV output (default {out_default}.csv)")
    p.add_argument("--plot", default=None, metavar="FILE.png",
                   help=f"figure (default: the --out name with .png, {out_default}.png; 'none' "
                        f"for no figure)")
    add_instrument_options(p)      # --geometry and dimensions, --mass-fraction


def number_options(p, *options, later: bool = False) -> None:
    """Options of numbers, ``(flag, quantity, default, help)`` each: ``type=`` the
    :class:`~rheometer.limits.Quantity` of the flag (``later``: read here, checked once by the
    library function, named as the option)."""
    for flag, quantity, default, text in options:
        p.add_argument(flag, type=Quantity(flag, quantity, later=later), default=default,
                       help=text)


def skeleton_options(p) -> None:
    """``--G`` and ``--K0`` (default: the material's, else 1e4 Pa and 1)."""
    number_options(p, ("--G", limits.MODULUS, None, "granular shear modulus [Pa]"),
                   ("--K0", limits.K0, None, "structure-rate scale K0 [-]"))


#: what a transient's refusal (rheometer.protocols, Rheometer, Step) calls the parameters of
#: :func:`transient_options`: their options
TRANSIENT_LABELS = {"t_end": "--t-end", "rtol": "--rtol", "points": "--points"}


def transient_label(name: str) -> str:
    """The option of a transient's parameter (:data:`TRANSIENT_LABELS`), else the name."""
    return TRANSIENT_LABELS.get(name, name)


def transient_options(p, t_end=None):
    """--G, --K0, (with ``t_end``, its default) --t-end, --rtol, --points: the last three read
    here, checked once by the run (:class:`~rheometer.transient.Rheometer`, its
    :class:`~rheometer.transient.Step`), named by :func:`transient_label`."""
    skeleton_options(p)
    if t_end is not None:
        number_options(p, ("--t-end", limits.DURATION, t_end, f"duration [s] (default {t_end:g})"),
                       later=True)
    number_options(p, ("--rtol", limits.RTOL, 1e-7, "IDA relative tolerance (1e-7)"),
                   ("--points", limits.STEP_ROWS, 300, "output rows per step (300)"), later=True)


def plot_path(args):
    """The figure path (None for no figure), checked with --out BEFORE any work is done."""
    check_output_path("--out", args.out, ["csv"])
    plot = args.plot if args.plot is not None else str(Path(args.out).with_suffix(".png"))
    if plot.lower() == "none":
        return None
    check_output_path("--plot", plot, ["figure"])
    return plot
