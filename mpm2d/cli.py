"""Command line: ``mpm2d list``, ``mpm2d show SCENE``, ``mpm2d run SCENE --set key=value --out
DIR``, ``mpm2d sweep SCENE --set key=v1,v2 --out DIR``.

Examples::

    mpm2d list
    mpm2d show bar                                   # parameters with their valid ranges
    mpm2d run bar --out bar                          # elastic bar vs the exact mode
    mpm2d run disks --set transfer=flip --out disks  # two disks, FLIP transfer
    mpm2d run column --set t_end=2 --out column      # two-phase settling column
    mpm2d run column --out column --resume           # continue from column/checkpoint.npz
    mpm2d sweep bar --set cells=16,32 --out bars     # a parameter sweep on Dask
    mpm2d run mpm2d/examples/elastic_column.py       # a scene file of your own, by path
    mpm2d run intruder --set cells_per_mm=8 --yes    # a run past 1e10 point-steps

Bad input (an unknown scene or parameter, a value out of its range, a run too large for the
memory, a step beyond stability, a resume of another scene or other parameters) exits with
status 2 and one line ``mpm2d run: error: ...`` on stderr, before anything is written; a run
whose step fails ends there with its files and history up to it, the manifest's status
ended_early and ends saying where and why, status 3; a run failing after its last step with
status 1. Ctrl-C or SIGTERM stops after the current step, writes a checkpoint and exits with
status 130; ``--resume`` continues bit-for-bit.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numba

from rheology import get_material
from rheology.sample import add_mass_fraction_options, mass_fraction_phi
from runkit.command import OneLineParser
from runkit.command import run as run_command
from runkit.limits import ge, le
from runkit.params import Number, interval_text

from .run import CHECKPOINT_EVERY, FRAMES, run_scene
from .scenes import SCENES, get_setup, get_spec, is_scene_file
from .scenes.spec import volume_fraction_key
from .sweep import parse_grid, run_sweep


def _parse_set(items) -> dict:
    """``--set key=value`` items of ``mpm2d run`` -> {key: value}: the sweep's parser
    (:func:`mpm2d.sweep.parse_grid`: no empty key or value, no key twice), one value each."""
    return {k: v[0] for k, v in parse_grid(items, lists=False).items()}


class _TopParser(OneLineParser):
    """``mpm2d``'s parser: arguments left over by a subcommand are refused by that subcommand's
    parser (``mpm2d run: error: unrecognized arguments: 0.6``), not as ``mpm2d: error``."""

    def parse_known_args(self, args=None, namespace=None):
        ns, extra = super().parse_known_args(args, namespace)
        self._cmd = getattr(ns, "cmd", None)
        return ns, extra

    def error(self, message):
        sub = getattr(self, "_subparsers_action", None)
        cmd = getattr(self, "_cmd", None)
        if sub is not None and cmd in sub.choices and message.startswith("unrecognized"):
            sub.choices[cmd].error(message)
        super().error(message)


def main(argv=None) -> int:
    ap = _TopParser(prog="mpm2d", description=__doc__,
                    formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True, parser_class=OneLineParser)
    ap._subparsers_action = sub
    sub.add_parser("list", help="list the scenes")
    show = sub.add_parser("show", help="a scene's equations, parameters (valid ranges), command")
    show.add_argument("scene", help="a built-in scene (mpm2d list) or a scene file's path")
    ncpu = os.cpu_count() or 1
    run = sub.add_parser("run", help="run a scene")
    run.add_argument("scene", help="a built-in scene (mpm2d list) or the path of a scene file "
                                   "of your own (path/to/my_scene.py: a setup(**params) "
                                   "declared with mpm2d.scenes.spec.parameters_of)")
    run.add_argument("--set", action="append", metavar="KEY=VALUE", default=[],
                     help="override a scene parameter (repeatable; see mpm2d show SCENE)")
    run.add_argument("--out", default=None, help="output folder (default: ./SCENE)")
    run.add_argument("--resume", action="store_true", help="continue from OUT/checkpoint.npz")
    run.add_argument("--frames", type=FRAMES, default=None,
                     help="number of snapshots (default: the scene's)")
    vtk = run.add_mutually_exclusive_group()
    vtk.add_argument("--no-vtk", action="store_true", help="skip the VTK snapshots")
    vtk.add_argument("--vtk", action="store_true",
                     help="write the VTK snapshots where the scene does not by default (wheel)")
    run.add_argument("--yes", action="store_true",
                     help="run even past 1e10 point-steps (points x steps; about an hour or "
                          "more): without it such a run is refused with its estimate")
    run.add_argument("--quiet", action="store_true",
                     help="no progress bar and no progress lines (errors still on stderr)")
    threads = Number("--threads", ge(1, "at least one thread"),
                     le(ncpu, "the cores of this machine"), integer=True)
    run.add_argument("--threads", type=threads, default=None,
                     help=f"numba threads (1..{ncpu}; a resume needs the same number)")
    every = CHECKPOINT_EVERY
    run.add_argument("--checkpoint-every", type=every, default=60.0,
                     help="wall seconds between checkpoints (default 60)")
    add_mass_fraction_options(run, nargs="+")
    for action in run._actions:              # one run, one fraction (a sweep takes several)
        if action.dest == "mass_fraction":
            action.help = ("grain mass fraction m_grain/(m_grain + m_liquid), converted to the "
                           "scene's volume fraction by Eq. 20; one value per run (several: "
                           "mpm2d sweep with --set on the volume fraction)")
    sw = sub.add_parser("sweep", help="run a scene over a grid of parameters (Dask)")
    sw.add_argument("scene")
    sw.add_argument("--set", action="append", metavar="KEY=V1[,V2...]", default=[],
                    help="values of a parameter (repeatable): the cases are the product")
    sw.add_argument("--out", default=None, help="sweep folder (default: ./sweep_SCENE)")
    sw.add_argument("--scheduler", default=None, help="address of a Dask scheduler")
    sw.add_argument("--workers", type=Number("--workers", ge(1, "at least one worker"), le(
        4 * ncpu, "four per core: more only wait for the cores"), integer=True),
                    default=None, help="workers of the local cluster (default: one per core)")
    sw.add_argument("--checkpoint-every", type=every, default=60.0,
                    help="wall seconds between a case's checkpoints")
    sw.add_argument("--vtk", action="store_true", help="write the VTK snapshots of every case")
    sw.add_argument("--yes", action="store_true",
                    help="run cases past 1e10 point-steps (about an hour or more each on two "
                    "cores); without it such a case is refused with its estimate")
    sw.add_argument("--quiet", action="store_true",
                    help="no progress bar and no progress lines (failed cases still on stderr)")
    args = ap.parse_args(argv)
    # a run stopped by a signal says where its checkpoint is (run_scene's KeyboardInterrupt)
    hint = ("rerun the same command to continue: completed cases are kept, the others resume "
            "from their checkpoints" if args.cmd == "sweep" else "")
    return run_command(f"mpm2d {args.cmd}", lambda: _command(args), on_interrupt=hint)


def _command(args) -> None:
    if args.cmd != "list" and is_scene_file(args.scene):   # a scene file of the user's
        default_out = Path(args.scene).stem
        args.scene = str(Path(args.scene).expanduser().resolve())
    elif args.cmd != "list":
        default_out = args.scene

    if args.cmd == "list":
        for name, text in SCENES.items():
            print(f"{name:10s} {text}")
        print("(or the path of a scene file of your own: mpm2d run path/to/my_scene.py; "
              "example: mpm2d/examples/elastic_column.py)")
        return
    if args.cmd == "show":
        setup = get_setup(args.scene)
        print(setup.__module__)
        print(sys.modules[setup.__module__].__doc__)
        print("parameters (default, valid values):")
        for line in _described(get_spec(args.scene)):
            print(line)
        return
    if args.cmd == "sweep":
        out = f"sweep_{default_out}" if args.out is None else args.out      # '' is refused
        table = run_sweep(args.scene, parse_grid(args.set), out,
                          scheduler=args.scheduler, workers=args.workers,
                          checkpoint_every=args.checkpoint_every, vtk=args.vtk,
                          progress=not args.quiet, quiet=args.quiet, yes=args.yes)
        return 0 if (table["status"] != "failed").all() else 1
    if args.threads:
        cap = numba.config.NUMBA_NUM_THREADS
        if args.threads > cap:
            print(f"mpm2d {args.cmd}: --threads {args.threads}: numba is limited to {cap} "
                  f"thread(s) here (NUMBA_NUM_THREADS); running with {cap}", flush=True,
                  file=sys.stderr if args.quiet else sys.stdout)
        numba.set_num_threads(min(args.threads, cap))

    params = _parse_set(args.set)
    if args.mass_fraction is not None:
        if len(args.mass_fraction) != 1:
            raise ValueError(f"--mass-fraction takes one value per run, got "
                             f"{len(args.mass_fraction)} ({' '.join(f'{w:g}' for w in args.mass_fraction)}); "
                             "run each separately or use mpm2d sweep")
        args.mass_fraction = args.mass_fraction[0]
        _mass_fraction(args, get_spec(args.scene), params)
    run_scene(get_setup(args.scene), default_out if args.out is None else args.out, params,
              resume=args.resume, progress=not args.quiet,
              vtk=False if args.no_vtk else True if args.vtk else None,
              frames=args.frames, checkpoint_every=args.checkpoint_every, scene_name=args.scene,
              quiet=args.quiet, yes=args.yes)


def _described(spec) -> list[str]:
    """``spec.describe()`` with each derived range as a refusal states it (the valid range at
    the defaults, its ends rounded toward the valid side: ``0.316228)`` where the exact bound
    0.3162277... is not a 6-digit number)."""
    lines = spec.describe()
    for i, (k, p) in enumerate(spec.params.items()):
        rng = spec.valid_range(k, dict(spec.defaults)) if p.numeric and p.derived else None
        if rng is not None:
            text = interval_text(*rng, p.unit) + (", or none" if p.optional else "")
            lines[i] = lines[i].replace(p.range_text(spec.defaults, typed=True), text, 1)
    return lines


def _mass_fraction(args, spec, params: dict) -> None:
    """Set the scene's volume fraction from ``--mass-fraction`` (Eq. 20 with the scene material's
    densities unless given) and print the conversion; ValueError where the scene has none."""
    key = volume_fraction_key(spec)
    if key is None:
        raise ValueError(f"--mass-fraction: scene {spec.name} has no suspension volume fraction")
    if key in params:
        raise ValueError(f"give --set {key}=... or --mass-fraction, not both")
    full = {**spec.defaults, **spec.coerce(params)}
    m = get_material(spec.params[key].of(full))
    (phi,), note = mass_fraction_phi(args, m)
    params[key] = phi
    print(f"mpm2d run: {note}: {key} = {phi:.6g}")      # what ran: kept under --quiet too


if __name__ == "__main__":
    sys.exit(main())
