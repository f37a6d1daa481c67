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
from runkit.command import OneLineParser
from runkit.command import run as run_command
from runkit.limits import PHI_MIN, SPEED_MIN, STRESS_MIN
from runkit.params import Number, OutOfRange, Param

from .geometry import CELLS, LENGTH
from .geometry import R_OUTER as CUP
from .integrate import CHECKPOINT_EVERY, DT, DURATION, METHODS, OUTPUTS, RTOL
from .model import (ELASTIC_STRAIN_LIMIT, MODES, PHI0, RAMP_TIME, WALL_SPEED, WALL_STRESS,
                    max_wall_speed)
from .scenes import (R_INNER, R_OUTER, ROTATION, ROTATION_END, SPEEDS, plane_couette,
                     run_annular, run_couette)

#: The option that sets each quantity a refusal of the library names (its one check: the
#: parser only reads the numbers).
OPTIONS = {"n_cells": "--cells", "n_out": "--outputs", "rtol": "--rtol", "dt": "--dt",
           "method": "--method", "mode": "--mode", "checkpoint_every": "--checkpoint-every",
           "phi0": "--phi", "r_inner": "--r-inner", "r_outer": "--r-outer", "gap": "--gap",
           "rotation": "--rotation", "ramp_time": "--ramp-time", "t_end": "--time",
           "wall_stress": "--stress"}


def _number(flag: str, param: Param, upper: str = "", shown: str = "") -> Number:
    """A number read from the command line; its range, ``param``'s (its one declaration, with
    the reasons), is stated here and checked by the library. ``upper``: the text of a derived
    upper bound (the static lower bound shown before it); ``shown``: the whole range."""
    if upper:
        lo, lc, _, _, _, _ = param.bounds(static=True)
        shown = f"{'[' if lc else '('}{lo:g}, {upper}"
    also = "".join(f", or {a:g}" for a in param.also)
    return Number(flag, integer=param.kind == "integer",
                  shown_range=(shown or param.range_text(static=True)) + also)


def _parser() -> argparse.ArgumentParser:
    m = rheology.get_material("annular_shear")
    u_max = max_wall_speed(m, m.phi0)
    ap = OneLineParser(prog="shear1d", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True, parser_class=OneLineParser)

    def numerics(p, cells, outputs, modes):
        p.add_argument("--cells", type=_number("--cells", CELLS), default=cells,
                       help=f"cells across the gap, {CELLS.range_text()} and at most gap/d (a "
                       f"grain per cell; default {cells}; the memory the run needs is checked "
                       "first)")
        p.add_argument("--mode", default=None, metavar="{" + ",".join(modes) + "}",
                       help="locked (phases move together, phi fixed), two-phase (Darcy "
                            "migration)" + (", or both" if "both" in modes else ""))
        p.add_argument("--method", default="ida", metavar="{" + ",".join(METHODS) + "}",
                       help="ida (default, full Table 8 law as a rate), explicit (full law), or "
                       "dae (locked mode only: the full law as a smooth DAE, fastest for many "
                       "cells, see shear1d.dae)")
        p.add_argument("--rtol", type=_number("--rtol", RTOL), default=1e-4,
                       help=f"IDA tolerance, {RTOL.range_text()} (default 1e-4)")
        p.add_argument("--dt", type=_number("--dt", DT), default=None,
                       help=f"explicit step [s], {DT.range_text()} and at most the stability "
                            "limit of the grid (default: half that limit)")
        p.add_argument("--outputs", type=_number("--outputs", OUTPUTS), default=outputs,
                       help=f"output intervals, {OUTPUTS.range_text()} (default {outputs})")
        p.add_argument("--resume", action="store_true", help="continue from the checkpoints in "
                       "--out (refused if there are none)")
        p.add_argument("--checkpoint-every", type=_number("--checkpoint-every",
                                                          CHECKPOINT_EVERY),
                       default=60.0, help="wall-time seconds between checkpoints, "
                       f"{CHECKPOINT_EVERY.range_text()} (default 60; one is also written at "
                       "the end and on Ctrl-C/SIGTERM)")
        p.add_argument("--quiet", action="store_true", help="no progress bar")
        p.add_argument("--material", default="annular_shear", metavar="NAME|FILE.json",
                       help="steady-flow parameters: a set name or a material file (e.g. "
                            "fit/material.json from 'rheometer fit'); the moduli, densities, d "
                            "and K0 it leaves unset come from Table 4 (annular_shear, default)")
        p.add_argument("--set", action="append", type=set_argument, metavar="NAME=VALUE",
                       help="a parameter of the material (repeatable), e.g. rules=mpm_3d (the "
                            "yield rules of the author's code) or K0=0.1")
        p.add_argument("--phi", type=_number("--phi", PHI0, "phi_j of the material)"),
                       default=None, help=f"volume fraction, at least {PHI_MIN.value:g} (the "
                                          "dilute limit), below the material's phi_j (default: "
                                          "Table 4's phi0 = 0.505)")
        add_mass_fraction_options(p, nargs=None)

    speed = "0.1 sqrt(G/rho)] m/s for the run's material and phi"
    u_range = f"[{SPEED_MIN.value:g}, 0.1 sqrt(G/rho)]: [{SPEED_MIN.value:g}, {u_max:.6g}]"
    a = sub.add_parser("annular", help="Fig. 3: annular shear, dynamic shear-jamming fronts")
    a.add_argument("--u-inner", type=_number("--u-inner", WALL_SPEED, speed), nargs="+",
                   default=list(SPEEDS),
                   help=f"bob surface speed(s) [m/s], in {u_range} for annular_shear at phi "
                        f"{m.phi0:g} (the model is a small-elastic-strain law; default 0.00084 "
                        "0.084)")
    a.add_argument("--out", default="annular_shear_jamming",
                   help="output folder (a non-empty path; created if absent)")
    a.add_argument("--r-inner", type=_number("--r-inner", LENGTH), default=R_INNER,
                   help=f"bob radius [m], {LENGTH.range_text()} (default {R_INNER})")
    a.add_argument("--r-outer", type=_number("--r-outer", CUP, shown="(--r-inner, 10] m"),
                   default=None, help=f"cup radius [m], beyond the bob radius, at most 10 "
                                      f"(default {R_OUTER})")
    a.add_argument("--rotation", type=_number("--rotation", ROTATION), default=ROTATION_END,
                   help=f"bob rotation to simulate [rad], {ROTATION.range_text()} (default "
                        f"{ROTATION_END})")
    a.add_argument("--ramp-time", type=_number("--ramp-time", RAMP_TIME), default=0.0,
                   help=f"start-up ramp of the bob [s], 0 (default: impulsive) or in "
                        f"{RAMP_TIME.range_text()} and at most the "
                        "rotation time --rotation x --r-inner / --u-inner at full speed (the "
                        "fastest speed's; then the bob reaches full speed by half the rotation: "
                        "a longer ramp would end the run before or just after the bob is up to "
                        "speed, not the start-up of a shear at --u-inner)")
    numerics(a, 200, 310, MODES + ("both",))

    c = sub.add_parser("couette", help="plane Couette start-up (speed- or stress-driven)")
    drive = c.add_mutually_exclusive_group(required=True)
    drive.add_argument("--speed", type=_number("--speed", WALL_SPEED, speed),
                       help=f"speed of the moving plate [m/s], in {u_range} for annular_shear "
                            f"at phi {m.phi0:g}")
    drive.add_argument("--stress", type=_number("--stress", WALL_STRESS,
                                                "0.1 G] Pa for the run's material"),
                       help=f"shear stress on the moving plate [Pa], in [{STRESS_MIN.value:g}, "
                            f"0.1 G]: [{STRESS_MIN.value:g}, {ELASTIC_STRAIN_LIMIT * m.G:g}] for "
                            "annular_shear")
    c.add_argument("--gap", type=_number("--gap", LENGTH), default=1e-2,
                   help=f"gap [m], {LENGTH.range_text()} (default 0.01)")
    c.add_argument("--time", type=_number("--time", DURATION), default=1.0,
                   help=f"duration [s], in {DURATION.range_text()} (1 ps to 30 years, the "
                   "durations of every tier; default 1); the computing time grows with it")
    c.add_argument("--out", default="plane_couette",
                   help="output folder (a non-empty path; created if absent)")
    numerics(c, 100, 200, MODES)
    return ap


def _sample(args):
    """The material (the user's steady fit on Table 4's moduli) and phi0 (from --phi or
    --mass-fraction, else the material's), with the conversion printed."""
    m = scene_material("annular_shear", args.material, **set_overrides(args.set))
    if args.phi is not None and args.mass_fraction is not None:
        raise ValueError("give --phi or --mass-fraction, not both")
    phis, note = mass_fraction_phi(args, m)
    if phis is not None:
        try:
            PHI0.check("phi", phis[0], {"material": m})
        except OutOfRange as exc:
            raise ValueError(f"--mass-fraction = {args.mass_fraction:g} gives phi = {phis[0]:.3g} "
                             f"(Eq. 20), outside its valid range {exc.range_text} ({exc.why})"
                             ) from None
        print(f"shear1d: {note}")
        return m, phis[0]
    return m, args.phi


def _as_option(exc: ValueError, options: dict, defaults=()) -> ValueError:
    """A refusal of the library (``NAME = VALUE ...``) naming the option that sets NAME; ``(the
    default)`` after the value of one of ``defaults`` (an option the user did not give)."""
    name = next((k for k in options if str(exc).startswith(f"{k} = ")), None)
    if name is None:
        return exc
    if isinstance(exc, OutOfRange):
        return OutOfRange(options[name], exc.value_text + (" (the default)" if name in defaults
                                                           else ""), exc.range_text, exc.why)
    return ValueError(options[name] + str(exc)[len(name):])


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
    m, phi0 = _sample(args)
    if args.mode is not None:            # "both" is the command's, the modes the library's
        args.mode = Param(kind="choice", choices=MODES + ("both",)).check("--mode", args.mode)
    modes = MODES if args.mode in ("both", None) else (args.mode,)
    if args.method == "dae" and args.mode is None:   # the default: both modes, locked with dae
        modes = ("locked",)
        print("shear1d: --method dae runs the locked mode only (no --mode given: locked)")
    _in_out(args.out, lambda: run_annular(
        args.out, tuple(args.u_inner), modes, n_cells=args.cells, method=args.method,
        rtol=args.rtol, dt=args.dt, n_out=args.outputs, r_inner=args.r_inner,
        r_outer=R_OUTER if args.r_outer is None else args.r_outer, rotation=args.rotation,
        ramp_time=args.ramp_time, resume=args.resume, checkpoint_every=args.checkpoint_every,
        progress=not args.quiet, material=m, phi0=phi0))


def _couette(args) -> None:
    m, phi0 = _sample(args)
    pb = plane_couette(args.speed, stress=args.stress, gap=args.gap, n_cells=args.cells,
                       mode=args.mode or "locked", phi0=phi0, material=m)
    _in_out(args.out, lambda: run_couette(
        args.out, pb, args.time, method=args.method, n_out=args.outputs, rtol=args.rtol,
        dt=args.dt, resume=args.resume, checkpoint_every=args.checkpoint_every,
        progress=not args.quiet))


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    options = {**OPTIONS, "wall_speed": "--u-inner" if args.cmd == "annular" else "--speed"}
    defaults = ("r_outer",) if getattr(args, "r_outer", 0) is None else ()

    def body():
        try:
            (_annular if args.cmd == "annular" else _couette)(args)
        except ValueError as exc:
            raise _as_option(exc, options, defaults) from None

    return run_command(f"shear1d {args.cmd}", body, on_interrupt="nothing was saved")


if __name__ == "__main__":
    sys.exit(main())
