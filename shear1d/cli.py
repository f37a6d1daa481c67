"""Command line of the shear1d tier.

  shear1d annular [--u-inner U ...] [--out DIR] [--mode locked|two-phase|both] ...
      the dynamic shear-jamming cell of the paper's Fig. 3 (default: both bob speeds, 0.84 and
      84 mm/s, both modes, 200 cells, IDA) -> CSV, JSON and PNG in DIR
  shear1d couette (--speed U | --stress TAU) [--gap H] [--time T] [--out DIR] ...
      plane Couette start-up, driven by the moving plate's speed or shear stress

Bad input ends with one line on stderr and a non-zero exit status.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from rheology.cli_common import OneLineParser, run_command


def _parser() -> argparse.ArgumentParser:
    from .scenes import R_INNER, R_OUTER, ROTATION_END, SPEEDS

    ap = OneLineParser(prog="shear1d", description=__doc__,
                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True, parser_class=OneLineParser)

    def numerics(p, cells, outputs):
        p.add_argument("--cells", type=int, default=cells, help=f"cells across the gap "
                       f"(default {cells})")
        p.add_argument("--mode", default=None, help="locked (phases move together, phi fixed), "
                       "two-phase (Darcy migration), or both")
        p.add_argument("--method", default="ida", help="ida (default) or explicit")
        p.add_argument("--rtol", type=float, default=1e-4, help="IDA tolerance (default 1e-4)")
        p.add_argument("--dt", type=float, default=None, help="explicit step [s] (default: half "
                       "the stability limit; larger than the limit is refused)")
        p.add_argument("--outputs", type=int, default=outputs, help=f"output intervals "
                       f"(default {outputs})")

    a = sub.add_parser("annular", help="Fig. 3: annular shear, dynamic shear-jamming fronts")
    a.add_argument("--u-inner", type=float, nargs="+", default=list(SPEEDS),
                   help="bob surface speed(s) [m/s] (default 0.00084 0.084)")
    a.add_argument("--out", default="annular_shear_jamming", help="output folder")
    a.add_argument("--r-inner", type=float, default=R_INNER, help=f"bob radius [m] (default "
                   f"{R_INNER})")
    a.add_argument("--r-outer", type=float, default=R_OUTER, help=f"cup radius [m] (default "
                   f"{R_OUTER})")
    a.add_argument("--rotation", type=float, default=ROTATION_END,
                   help=f"bob rotation to simulate [rad] (default {ROTATION_END})")
    a.add_argument("--ramp-time", type=float, default=0.0, help="start-up ramp of the bob [s] "
                   "(default 0: impulsive)")
    a.add_argument("--resume", action="store_true", help="continue from checkpoints in --out")
    numerics(a, 200, 310)

    c = sub.add_parser("couette", help="plane Couette start-up (speed- or stress-driven)")
    drive = c.add_mutually_exclusive_group(required=True)
    drive.add_argument("--speed", type=float, help="speed of the moving plate [m/s]")
    drive.add_argument("--stress", type=float, help="shear stress on the moving plate [Pa]")
    c.add_argument("--gap", type=float, default=1e-2, help="gap [m] (default 0.01)")
    c.add_argument("--time", type=float, default=1.0, help="duration [s] (default 1)")
    c.add_argument("--phi", type=float, default=None, help="volume fraction (default: the "
                   "material's phi0)")
    c.add_argument("--material", default="annular_shear", help="rheology material name "
                   "(needs G, K, K0, densities; default annular_shear)")
    c.add_argument("--out", default="plane_couette", help="output folder")
    numerics(c, 100, 200)
    return ap


def _modes(mode: str | None, default: tuple[str, ...]) -> tuple[str, ...]:
    from .model import MODES

    if mode is None:
        return default
    if mode == "both":
        return MODES
    if mode not in MODES:
        raise ValueError(f"--mode {mode!r} must be one of {MODES + ('both',)}")
    return (mode,)


def _annular(args) -> None:
    from .scenes import run_annular

    run_annular(args.out, tuple(args.u_inner), _modes(args.mode, ("locked", "two-phase")),
                n_cells=args.cells, method=args.method, rtol=args.rtol, dt=args.dt,
                n_out=args.outputs, r_inner=args.r_inner, r_outer=args.r_outer,
                rotation=args.rotation, ramp_time=args.ramp_time, resume=args.resume)


def _couette(args) -> None:
    import pandas as pd

    from rheology.io import atomic_write_csv

    from . import plots
    from .integrate import solve
    from .scenes import plane_couette

    modes = _modes(args.mode, ("locked",))
    if len(modes) != 1:
        raise ValueError("--mode both is for the annular scene; give locked or two-phase")
    pb = plane_couette(args.speed, stress=args.stress, gap=args.gap, n_cells=args.cells,
                       mode=modes[0], phi0=args.phi, material=args.material)
    res = solve(pb, args.time, method=args.method, n_out=args.outputs, rtol=args.rtol, dt=args.dt)
    out = Path(args.out)
    g = pb.grid
    v, tau = res.field("v"), np.abs(res.field("shear_stress"))
    idx = np.unique(np.linspace(0, len(res.t) - 1, 6).astype(int))
    prof = pd.concat([pd.DataFrame({"time_s": res.t[k], "y_m": g.faces, "v_m_per_s": v[k]})
                      for k in idx], ignore_index=True)
    wall = pd.DataFrame({"time_s": res.t, "wall_speed_m_per_s": v[:, 0],
                         "wall_shear_stress_Pa": tau[:, 0],
                         "mean_shear_rate_per_s": (v[:, 0] - v[:, -1]) / g.gap,
                         "f_mean": res.field("f").mean(axis=1)})
    atomic_write_csv(out / "couette_profiles.csv", prof)
    atomic_write_csv(out / "couette_wall.csv", wall)
    png = plots.couette(out / "couette.png", res, idx)
    print(f"shear1d: plane Couette, {g.n} cells, {res.method}, {res.wall_time:.2f} s; wrote "
          f"{out}/couette_profiles.csv, couette_wall.csv, {png.name}")


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    return run_command(f"shear1d {args.cmd}", lambda: (_annular if args.cmd == "annular"
                                                      else _couette)(args),
                       on_interrupt="rerun with --resume to continue from the checkpoint")


if __name__ == "__main__":
    sys.exit(main())
