"""Command line: ``mpm2d list``, ``mpm2d show SCENE``, ``mpm2d run SCENE --set key=value --out DIR``.

Examples::

    mpm2d list
    mpm2d show bar
    mpm2d run bar --out bar                          # elastic bar vs the exact mode
    mpm2d run disks --set transfer=flip --out disks  # two disks, FLIP transfer
    mpm2d run column --set t_end=2 --out column      # two-phase settling column
    mpm2d run column --out column --resume           # continue from column/checkpoint.npz

Bad input (an unknown scene or parameter, a value out of range, a step beyond stability) exits
with status 2 and one line ``mpm2d run: error: ...`` on stderr; a failed run with status 1. Ctrl-C
or SIGTERM writes a checkpoint and exits with status 130; ``--resume`` continues bit-for-bit.
"""

from __future__ import annotations

import argparse
import signal
import sys

from rheology.cli_common import OneLineParser, run_command


def _parse_set(items):
    out = {}
    for item in items or []:
        if "=" not in item:
            raise ValueError(f"--set {item!r} must be key=value")
        k, v = item.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main(argv=None) -> int:
    ap = OneLineParser(prog="mpm2d", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True, parser_class=OneLineParser)
    sub.add_parser("list", help="list the scenes")
    show = sub.add_parser("show", help="a scene's equations, parameters and command")
    show.add_argument("scene")
    run = sub.add_parser("run", help="run a scene")
    run.add_argument("scene")
    run.add_argument("--set", action="append", metavar="KEY=VALUE", default=[],
                     help="override a scene parameter (repeatable)")
    run.add_argument("--out", default=None, help="output folder (default: ./SCENE)")
    run.add_argument("--resume", action="store_true", help="continue from OUT/checkpoint.npz")
    run.add_argument("--frames", type=int, default=None, help="number of snapshots")
    run.add_argument("--no-vtk", action="store_true", help="skip the .vtu snapshots")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.add_argument("--threads", type=int, default=None, help="numba threads")
    run.add_argument("--checkpoint-every", type=float, default=60.0,
                     help="wall seconds between checkpoints (default 60)")
    args = ap.parse_args(argv)
    return run_command(f"mpm2d {args.cmd}", lambda: _command(args),
                       on_interrupt="a checkpoint was written: rerun with --resume")


def _command(args) -> None:
    from .scenes import SCENES, get_setup, parameters

    if args.cmd == "list":
        for name, text in SCENES.items():
            print(f"{name:10s} {text}")
        return
    if args.cmd == "show":
        setup = get_setup(args.scene)
        print(setup.__module__)
        print(sys.modules[setup.__module__].__doc__)
        print("parameters (defaults):")
        for k, v in parameters(args.scene).items():
            print(f"  {k} = {v!r}")
        return
    signal.signal(signal.SIGTERM, _interrupt)      # batch schedulers: checkpoint, stop
    if args.threads:
        import numba

        numba.set_num_threads(args.threads)
    from .run import run_scene

    run_scene(get_setup(args.scene), args.out or args.scene, _parse_set(args.set),
              resume=args.resume, progress=not args.quiet, vtk=not args.no_vtk,
              frames=args.frames, checkpoint_every=args.checkpoint_every, scene_name=args.scene)


if __name__ == "__main__":
    sys.exit(main())
