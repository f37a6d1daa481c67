"""Command line of the shear1d tier.

  shear1d annular [--u-inner U ...] [--out DIR] [--mode locked|two-phase|both] ...
      the dynamic shear-jamming cell of the paper's Fig. 3 (default: both bob speeds, 0.84 and
      84 mm/s, both modes, 200 cells, IDA) -> CSV, JSON and PNG in DIR
  shear1d couette (--speed U | --stress TAU) [--gap H] [--time T] [--out DIR] ...
      plane Couette start-up, driven by the moving plate's speed or shear stress

Long runs show a progress bar of the simulated time (--quiet: none), keep a checkpoint in DIR
(every --checkpoint-every seconds, and on Ctrl-C or SIGTERM) and continue with --resume.
Bad input ends with one line on stderr and exit status 2, before anything is written (an empty
--out too: it would write into the current folder). A run that ends early (a cell's elastic
strain taubar/G or p/K past 0.1, a solver or local-update failure, an unphysical state) keeps its
outputs up to the end: its files and figures are written from them, its summary JSON (annular)
or couette.json says where and why (status, ends), one line per run on stderr, exit status 3
(SUNDIALS' own error text, which sksundae prints on stdout, is kept off stdout and put on that
line). A run failing before its second output: one line, status 1. An interrupt: status 130 and
where the checkpoint is.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import rheology
from rheology.materials import scene_material, set_argument, set_overrides
from rheology.sample import add_mass_fraction_options, mass_fraction_phi
from runkit import limits as physical
from runkit.command import OneLineParser
from runkit.command import run as run_command
from runkit.limits import gt, le
from runkit.params import Number, OutOfRange, Param

from .dae import check_material
from .geometry import CELL_MIN_GRAINS, R_INNER_MIN_GRAINS, min_gap
from .integrate import METHODS
from .model import ELASTIC_STRAIN_LIMIT, MODES, drive_limit, max_wall_speed
from .scenes import (R_INNER, R_OUTER, ROTATION_END, SPEEDS, plane_couette, run_annular,
                     run_couette)

TIME_MIN, TIME_MAX = physical.TIME_MIN.value, physical.TIME_MAX.value

#: Size bounds of --cells (the explicit method's cost grows as cells^2: hours at 20000; a cell
#: holds at least one grain, checked with the gap: _check_lengths) and --outputs; the memory a
#: run needs is checked as well, before it starts.
MAX_CELLS = 20000
MAX_OUTPUTS = 100000


def _parser() -> argparse.ArgumentParser:
    m = rheology.get_material("annular_shear")
    u_max = max_wall_speed(m, m.phi0)
    ap = OneLineParser(prog="shear1d", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True, parser_class=OneLineParser)

    def numerics(p, cells, outputs, modes):
        p.add_argument("--cells", type=Number("--cells", 4, MAX_CELLS, integer=True),
                       default=cells, help=f"cells across the gap, 4-{MAX_CELLS} and at most "
                       f"gap/d (a grain per cell; default {cells}; the memory the run needs "
                       "is checked first)")
        p.add_argument("--mode", default=None, choices=modes,
                       help="locked (phases move together, phi fixed), two-phase (Darcy "
                            "migration)" + (", or both" if "both" in modes else ""))
        p.add_argument("--method", default="ida", choices=METHODS, help="ida (default, full "
                       "Table 8 law as a rate), explicit (full law), or dae (locked mode only: the "
                       "full law as a smooth DAE, fastest for many cells, see shear1d.dae)")
        p.add_argument("--rtol", type=Number("--rtol", 1e-12, 1e-2), default=1e-4,
                       help="IDA tolerance, 1e-12-1e-2 (default 1e-4)")
        p.add_argument("--dt", type=Number("--dt", 0, None, lo_closed=False, unit="s"),
                       default=None, help="explicit step [s] (default: half the stability "
                       "limit; larger than the limit is refused)")
        p.add_argument("--outputs", type=Number("--outputs", 1, MAX_OUTPUTS, integer=True),
                       default=outputs, help=f"output intervals, 1-{MAX_OUTPUTS} (default "
                       f"{outputs})")
        p.add_argument("--resume", action="store_true", help="continue from the checkpoints in "
                       "--out (refused if there are none)")
        p.add_argument("--checkpoint-every", type=Number("--checkpoint-every", 0, None,
                                                         lo_closed=False, unit="s"),
                       default=60.0, help="wall-time seconds between checkpoints (default 60; "
                       "one is also written at the end and on Ctrl-C/SIGTERM)")
        p.add_argument("--quiet", action="store_true", help="no progress bar")
        p.add_argument("--material", default="annular_shear", metavar="NAME|FILE.json",
                       help="steady-flow parameters: a set name or a material file (e.g. "
                            "fit/material.json from 'rheometer fit'); the moduli, densities, d "
                            "and K0 it leaves unset come from Table 4 (annular_shear, default)")
        p.add_argument("--set", action="append", type=set_argument, metavar="NAME=VALUE",
                       help="a parameter of the material (repeatable), e.g. rules=mpm_3d (the "
                            "yield rules of the author's code) or K0=0.1")
        p.add_argument("--phi", type=Number("--phi", 0, 1, lo_closed=False, hi_closed=False),
                       default=None, help="volume fraction, below the material's phi_j (default: "
                                          "Table 4's phi0 = 0.505)")
        add_mass_fraction_options(p, nargs=None)

    a = sub.add_parser("annular", help="Fig. 3: annular shear, dynamic shear-jamming fronts")
    # --u-inner, --speed, --stress: bounded by the run's material and phi (model.drive_limit),
    # checked once by _check_drive; the parser only reads numbers.
    a.add_argument("--u-inner", type=Number("--u-inner", shown_range=(
                       "(0, 0.1 sqrt(G/rho)] m/s for the run's material and phi")),
                   nargs="+", default=list(SPEEDS),
                   help=f"bob surface speed(s) [m/s], in (0, 0.1 sqrt(G/rho)]: (0, {u_max:.6g}] "
                        f"for annular_shear at phi {m.phi0:g} (the model is a small-elastic-strain "
                        "law; default 0.00084 0.084)")
    a.add_argument("--out", default="annular_shear_jamming",
                   help="output folder (a non-empty path; created if absent)")
    a.add_argument("--r-inner", type=Number("--r-inner", 0, 1.0, lo_closed=False, unit="m"),
                   default=R_INNER, help=f"bob radius [m] (default {R_INNER})")
    a.add_argument("--r-outer", type=Number("--r-outer", 0, 2.0, lo_closed=False, unit="m"),
                   default=None, help=f"cup radius [m], > the bob radius (default {R_OUTER})")
    a.add_argument("--rotation", type=Number("--rotation", 0, 100.0, lo_closed=False,
                                             unit="rad"), default=ROTATION_END,
                   help=f"bob rotation to simulate [rad] (default {ROTATION_END})")
    a.add_argument("--ramp-time", type=Number("--ramp-time", 0, TIME_MAX, unit="s"),
                   default=0.0,
                   help="start-up ramp of the bob [s] (default 0: impulsive), at most the "
                        "rotation time --rotation x --r-inner / --u-inner at full speed (the "
                        "fastest speed's; then the bob reaches full speed by half the rotation: "
                        "a longer ramp would end the run before or just after the bob is up to "
                        "speed, not the start-up of a shear at --u-inner)")
    numerics(a, 200, 310, MODES + ("both",))

    c = sub.add_parser("couette", help="plane Couette start-up (speed- or stress-driven)")
    drive = c.add_mutually_exclusive_group(required=True)
    drive.add_argument("--speed", type=Number("--speed", shown_range=(
                           "(0, 0.1 sqrt(G/rho)] m/s for the run's material and phi")),
                       help=f"speed of the moving plate [m/s], in (0, 0.1 sqrt(G/rho)]: (0, "
                            f"{u_max:.6g}] for annular_shear at phi {m.phi0:g}")
    drive.add_argument("--stress", type=Number("--stress", shown_range=(
                           "(0, 0.1 G] Pa for the run's material")),
                       help=f"shear stress on the moving plate [Pa], in (0, 0.1 G]: (0, "
                            f"{ELASTIC_STRAIN_LIMIT * m.G:g}] for annular_shear")
    c.add_argument("--gap", type=Number("--gap", 0, 1.0, lo_closed=False, unit="m"), default=1e-2,
                   help="gap [m] (default 0.01)")
    c.add_argument("--time", type=Number("--time", TIME_MIN, TIME_MAX, unit="s"),
                   default=1.0, help=f"duration [s], in [{TIME_MIN:g}, {TIME_MAX:g}] (1 ps to 30 "
                   "years, the durations of every tier; default 1); the computing time grows "
                   "with it")
    c.add_argument("--out", default="plane_couette",
                   help="output folder (a non-empty path; created if absent)")
    numerics(c, 100, 200, MODES)
    return ap


def _modes(mode: str | None, default: tuple[str, ...]) -> tuple[str, ...]:
    if mode is None:
        return default
    return MODES if mode == "both" else (mode,)


def _sample(args):
    """The material (the user's steady fit on Table 4's moduli) and phi0 (from --phi or
    --mass-fraction, else the material's), with the conversion printed."""
    m = scene_material("annular_shear", args.material, **set_overrides(args.set))
    if args.phi is not None and args.mass_fraction is not None:
        raise ValueError("give --phi or --mass-fraction, not both")
    phis, note = mass_fraction_phi(args, m)
    if phis is not None:
        print(f"shear1d: {note}")
        return m, phis[0]
    if args.phi is not None and args.phi >= m.phi_j:
        raise OutOfRange("--phi", f"{args.phi:g}", f"(0, {m.phi_j:g})", f"below phi_j of {m.name}")
    return m, args.phi


def _check_drive(option: str, values, material, phi0, *, stress: bool = False) -> None:
    """--u-inner / --speed in (0, 0.1 c_s] or --stress in (0, 0.1 G] for this material and phi
    (:func:`shear1d.model.drive_limit`); ValueError naming the option, in its units."""
    phi = material.phi0 if phi0 is None else phi0
    if phi is None:                   # no phi at all: the Couette problem refuses it by name
        return
    material.require("G", "rho_s", "rho_f")
    top, unit, why = drive_limit(material, phi, stress)
    for v in values:
        Param(gt(0.0), le(top, why), unit=unit).check(option, v, static=True)


def _check_annulus(r_inner: float, r_outer: float, default_outer: bool = False) -> None:
    """--r-outer beyond --r-inner; ``default_outer``: the message says it is the default."""
    if not r_outer > r_inner:
        raise OutOfRange("--r-outer", f"{r_outer:g}" + (" (the default)" if default_outer else ""),
                         f"({r_inner:g}, 2] m",
                         f"the cup must lie beyond the bob, --r-inner = {r_inner:g} m")


def _check_dae(method: str, modes: tuple[str, ...], material, phi0) -> None:
    """Refuse --method dae for a two-phase run or outside :func:`shear1d.dae.check_material`."""
    if method != "dae":
        return
    if "two-phase" in modes:
        raise ValueError("--method dae is for --mode locked only "
                         f"(got modes {', '.join(modes)}); add --mode locked or use --method "
                         "ida|explicit")

    phi = material.phi0 if phi0 is None else phi0
    if phi is not None:                 # no phi at all is refused by the Couette problem
        check_material(material, phi)


def _check_out(out: str) -> None:
    """An empty --out would write into the current folder: refused by name (the scene checks
    the rest: runkit.io.check_output_dir)."""
    if not str(out).strip():
        raise ValueError(f"--out = {out!r} is empty: give the output folder's name (use "
                         "--out . for the current folder)")


def _check_ramp(ramp_time: float, rotation: float, r_inner: float, speeds) -> None:
    """--ramp-time at most the rotation time at full speed, rotation r_inner / u, of the fastest
    --u-inner (see the option's help); ValueError naming it with the range."""
    u = max(speeds)
    top = rotation * r_inner / u
    if ramp_time > top:
        raise OutOfRange("--ramp-time", f"{ramp_time:g} s", f"[0, {top:.4g}] s",
                         f"at most the rotation time --rotation x --r-inner / --u-inner = "
                         f"{rotation:g} x {r_inner:g} m / {u:g} m/s at full speed: a longer ramp "
                         "leaves the bob below full speed past half of --rotation, a slow "
                         "start-up, not a shear at --u-inner; lower it, or raise --rotation")


def _check_lengths(material, option: str, value: float, hi: float, cells: int,
                   base: float = 0.0, r_inner: float | None = None) -> None:
    """The gap ``value - base`` holds ``cells`` cells of CELL_MIN_GRAINS grains, the bob
    R_INNER_MIN_GRAINS grains (:mod:`shear1d.geometry`); OutOfRange at the other options."""
    d = getattr(material, "d", None)
    if not d or d <= 0:
        return
    grains = f"d = {d:g} m of {material.name}"
    if r_inner is not None and r_inner < R_INNER_MIN_GRAINS * d:
        raise OutOfRange("--r-inner", f"{r_inner:g} m", f"[{R_INNER_MIN_GRAINS * d:.4g}, 1] m",
                         f"the bob must be a continuum wall, a radius of at least "
                         f"{R_INNER_MIN_GRAINS:g} grain diameters: {grains}")
    gap, lo = value - base, min_gap(cells, d)
    if gap < lo * (1.0 - 1e-12):
        most = int(gap / (CELL_MIN_GRAINS * d))
        at = f" at --r-inner = {base:g} m and" if base else " at"
        alt = f"; or at most {most} --cells at this gap" if most >= 4 else ""
        raise OutOfRange(option, f"{value:g} m", f"[{base + lo:.4g}, {hi:g}] m{at} --cells = "
                         f"{cells}", f"each cell of the gap must hold at least "
                         f"{CELL_MIN_GRAINS:g} grain, {grains}, the continuum the model "
                         f"describes{alt}")


def _in_out(out: str, run) -> None:
    """Run ``run()``; a failed run removes the --out folder it created if that is empty."""
    path = Path(out)
    existed = path.exists()
    try:
        run()
    except BaseException:
        if not existed and path.is_dir() and not any(path.iterdir()):
            path.rmdir()
        raise


def _annular(args) -> None:
    _check_out(args.out)
    m, phi0 = _sample(args)
    default_outer = args.r_outer is None
    if default_outer:
        args.r_outer = R_OUTER
    _check_annulus(args.r_inner, args.r_outer, default_outer)
    _check_drive("--u-inner", args.u_inner, m, phi0)
    _check_ramp(args.ramp_time, args.rotation, args.r_inner, args.u_inner)
    modes = _modes(args.mode, ("locked",) if args.method == "dae" else ("locked", "two-phase"))
    if args.method == "dae" and args.mode is None:
        print("shear1d: --method dae runs the locked mode only (no --mode given: locked)")
    _check_dae(args.method, modes, m, phi0)
    _check_lengths(m, "--r-outer" + (" (the default)" if default_outer else ""), args.r_outer,
                   2.0, args.cells, base=args.r_inner, r_inner=args.r_inner)
    _in_out(args.out, lambda: run_annular(args.out, tuple(args.u_inner), modes,
                n_cells=args.cells, method=args.method, rtol=args.rtol, dt=args.dt,
                n_out=args.outputs, r_inner=args.r_inner, r_outer=args.r_outer,
                rotation=args.rotation, ramp_time=args.ramp_time, resume=args.resume,
                checkpoint_every=args.checkpoint_every, progress=not args.quiet,
                material=m, phi0=phi0))


def _couette(args) -> None:
    _check_out(args.out)
    m, phi0 = _sample(args)
    if args.speed is not None:
        _check_drive("--speed", [args.speed], m, phi0)
    else:
        _check_drive("--stress", [args.stress], m, phi0, stress=True)
    _check_dae(args.method, _modes(args.mode, ("locked",)), m, phi0)
    _check_lengths(m, "--gap", args.gap, 1.0, args.cells)
    pb = plane_couette(args.speed, stress=args.stress, gap=args.gap, n_cells=args.cells,
                       mode=_modes(args.mode, ("locked",))[0], phi0=phi0, material=m)
    _in_out(args.out, lambda: run_couette(
        args.out, pb, args.time, method=args.method, n_out=args.outputs, rtol=args.rtol,
        dt=args.dt, resume=args.resume, checkpoint_every=args.checkpoint_every,
        progress=not args.quiet))


def main(argv=None) -> int:
    args = _parser().parse_args(argv)

    def body():
        (_annular if args.cmd == "annular" else _couette)(args)

    return run_command(f"shear1d {args.cmd}", body, on_interrupt="nothing was saved")


if __name__ == "__main__":
    sys.exit(main())
