"""``rheometer``: the 0-D virtual rheometer from the shell (CSV, units in the column names; PNG).

Every subcommand runs on a default material (hermes2016, the cornstarch fit of Hermes et al. 2016)
with no options and writes a CSV and a PNG named after it (flow_curve.csv, flow_curve.png, ...)
in the current folder. A transient also writes its run record (startup.json, ...): a run that
reaches the elastic-strain limit 0.1 or whose solver fails ends there, its rows up to the end
written, the record's status and ends saying where and why; exit status 3 (0 complete, 1 failed,
2 bad input, 130 interrupted).

Examples::

    rheometer flow-curve
    rheometer flow-curve --material hermes2016 --phi 0.48 0.50 0.52 --stress-range 1e-3 1e4 \\
        --points 200 --out fc.csv
    rheometer flow-curve --control rate --rate-range 1e-3 1e2      # every branch, stable or not
    rheometer relax --material hermes2016 --phi 0.52 --stress 10 --G 1e4 --K0 1 --t-end 50 \\
        --out relax.csv
    rheometer startup --rate 0.5 --t-end 60
    rheometer creep --stress 10 --t-end 60
    rheometer program steps.txt         # e.g. lines 'shear at 0.5 1/s for 60 s', 'rest for 100 s'
    rheometer material-point --rate 1 --dt 1e-3 --control pressure --pressure 2
    rheometer materials
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
from pathlib import Path

import numpy as np
import pandas as pd

import rheology
from rheology.elastic import ELASTIC_STRAIN_LIMIT, elastic_strain_limit_stress
from rheology.materials import set_argument, set_overrides
from rheology.run_end import EndedEarly
from runkit.command import OneLineParser
from runkit.command import run as run_command
from runkit import limits as physical
from runkit.io import atomic_write_csv, check_input_file, check_output_path
from runkit.limits import ge, le
from runkit.params import Param

from . import instrument_cli, limits, plots
from .checkpoint import ProgramCheckpoint
from .fit_cli import add_subcommands
from .instrument_cli import extra_outputs, finish_table, materials_note, write_record
from .limits import RATE_MAX, Quantity
from .material_point import POINTS, simple_shear_point
from .options import (common_options, material_with, number_options, plot_path,
                      sample_material, transient_label, transient_options)
from .plots import mark_ends, normalise_units
from .program import hysteresis_program, parse_program
from .protocols import at_phi, combined, creep, flow_curve, relax, startup
from .transient import skeleton

_EPILOG = ("Stress words: 'granular shear stress' (taubar) is the stress carried by the particle "
           "skeleton; 'mixture shear stress' = granular + eta0 (1 + 5/2 phi) gdot is what a "
           "rheometer measures. G [Pa] and K0 default to the material's values, else G = 1e4 Pa "
           "and K0 = 1 (Tables 5, 7; Fig. 15: from 1 kPa at phi = 0.52, t(1/e) = 0.7 s, and "
           "t(1/e) G = 7.3e3 Pa s).")


class _Parser(OneLineParser):
    """The top-level parser: a word no option of the command takes is refused by the command's
    parser (:func:`_refuse_unknown`)."""

    def parse_known_args(self, args=None, namespace=None):
        parsed, extra = super().parse_known_args(args, namespace)
        if extra and getattr(parsed, "cmd", None):
            _refuse_unknown(parsed, extra)
        return parsed, extra


def build_parser() -> argparse.ArgumentParser:
    ap = _Parser(prog="rheometer", description=__doc__.replace("``", "").replace("::", ":"),
                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=_EPILOG)
    sub = ap.add_subparsers(dest="cmd", metavar="COMMAND", parser_class=OneLineParser)
    sub.required = True

    p = sub.add_parser("materials", help="list the parameter sets and their sources")
    p.add_argument("--material", default=None, metavar="NAME", help="show every parameter of one")
    p.add_argument("--set", action="append", type=set_argument, metavar="NAME=VALUE",
                   help="override numeric parameters of --material (not name, citation, units, "
                        "notes)")
    p.add_argument("--out", default=None, metavar="FILE.csv", help="also write the table as CSV")

    p = sub.add_parser(
        "flow-curve", help="steady flow curves (stress, mixture-stress or rate control)",
        description="Steady flow curves. --control stress (default) imposes the GRANULAR shear "
                    "stress: one steady state each, the whole S-shaped DST curve. "
                    "--control mixture-stress imposes the MIXTURE shear stress and --control rate "
                    "the shear rate: every steady state, with columns branch and stable.",
        epilog=_EPILOG)
    common_options(p, 3, "flow_curve")
    p.add_argument("--control", choices=("stress", "mixture-stress", "rate"), default="stress")
    p.add_argument("--stress-range", type=Quantity("--stress-range", limits.POSITIVE_STRESS),
                   nargs=2, default=None, metavar=("LO", "HI"),
                   help="stress range [Pa] (granular or mixture per --control; 1e-3 1e4)")
    p.add_argument("--rate-range", type=Quantity("--rate-range", limits.POSITIVE_RATE),
                   nargs=2, default=None, metavar=("LO", "HI"),
                   help="shear-rate range [1/s] for --control rate (1e-4 1e3)")
    p.add_argument("--points", type=Quantity("--points", limits.rows(2, "a curve joins two or "
                                                                "more values")), default=200,
                   help="values, log-spaced (200)")

    for name, (text, t_end, (flag, value, flag_help, quantity), _, _) in _TRANSIENTS.items():
        p = sub.add_parser(name, help=text, epilog=_EPILOG)
        common_options(p, 1, name)
        p.add_argument(flag, type=Quantity(flag, quantity, later=True), default=value,
                       help=flag_help)
        transient_options(p, t_end)

    p = sub.add_parser("program", help="a test program from a text file (steps and ramps)",
                       epilog="Lines: 'shear at 0.5 1/s for 60 s', 'shear at 1 1/s until strain 5', "
                              "'stress 5 Pa for 60 s', 'stress 5 Pa until strain 10', "
                              "'rest for 100 s', 'ramp rate from 0.1 to 100 1/s over 60 s [log|"
                              "linear]', 'ramp stress from 1 to 100 Pa over 60 s', 'start from "
                              "steady stress 10 Pa', 'oscillate at 1 Hz with strain 0.01 for 10 "
                              "cycles', 'oscillate at 1 Hz with stress 5 Pa for 10 cycles'; '#' "
                              "comments. Without FILE: stress and rate sweeps up and down across "
                              "DST, built for the material and the first phi (hysteresis).")
    p.add_argument("file", nargs="?", default=None, help="program file ('-' for stdin)")
    common_options(p, 1, "program")
    transient_options(p)
    p.add_argument("--checkpoint-every", type=Quantity("--checkpoint-every", Param(
                       ge(1e-9, "a nanosecond of computing, shorter than any step: a "
                                 "checkpoint after every step"), physical.TIME_MAX, unit="s")),
                   default=60.0, metavar="SECONDS",
                   help="write a checkpoint (the --out name with .checkpoint.npz) every SECONDS "
                        "of computing (60), and always on Ctrl-C / SIGTERM")
    p.add_argument("--resume", action="store_true",
                   help="continue an interrupted run from its checkpoint (same file, options)")

    p = sub.add_parser("material-point",
                       help="the Table 8 tensor law at one point in simple shear (time-stepped)",
                       epilog="Volume control keeps phi; pressure control imposes the granular "
                              "pressure and lets phi evolve. Start from the steady state at "
                              "--stress0 or from rest under --pressure0.")
    common_options(p, 1, "material_point")
    # --rate, --t-end, --dt, --f0, --points: read here, checked once by rheometer.material_point
    # (named by their options: _POINT_LABELS)
    number_options(p, ("--rate", limits.RATE, 0.5, "shear rate [1/s] (0.5)"),
                   ("--t-end", limits.DURATION, 10.0, "duration [s] (10)"),
                   ("--dt", limits.DURATION, 1e-3, "largest time step [s] (1e-3; sub-stepped "
                                                   "where the rate needs it)"), later=True)
    p.add_argument("--control", choices=("volume", "pressure"), default="volume")
    number_options(p, ("--pressure", limits.POSITIVE_STRESS, None,
                       "imposed granular pressure [Pa] (pressure control)"),
                   ("--stress0", limits.POSITIVE_STRESS, None,
                    "start from the steady state at this granular shear stress [Pa]"),
                   ("--pressure0", limits.STRESS, None,
                    "contact pressure at rest [Pa] (default 1e-3 tau*; 0: stress free)"))
    number_options(p, ("--f0", limits.STRUCTURE, None, "initial structure f"), later=True)
    number_options(p, ("--G", limits.MODULUS, None, "shear modulus [Pa] (default 1e4)"),
                   ("--K", limits.MODULUS, None, "bulk modulus [Pa] (default 2.18 G)"),
                   ("--K0", limits.K0, None, "structure-rate scale (default 1)"))
    p.add_argument("--points", type=Quantity("--points", POINTS, later=True), default=400,
                   help="output rows (400)")
    _COMMANDS.update(add_subcommands(sub))
    _COMMANDS.update(instrument_cli.add_subcommands(sub))
    ap.set_defaults(commands=sub.choices)
    return ap


def _refuse_unknown(args, extra: list) -> None:
    """Refuse the words no option of the command takes, by the command's own parser; a word
    naming a material parameter (``--phi_j=0.3``) is told to use ``--set``."""
    command = args.commands[args.cmd]
    fields = {k.lower(): k for k in rheology.materials.FIELD_UNITS}
    for i, word in enumerate(extra):
        key, eq, value = word.lstrip("-").partition("=")
        field = fields.get(key.replace("-", "_").lower())
        if word.startswith("--") and field is not None and hasattr(args, "set"):
            value = value if eq else (extra[i + 1] if i + 1 < len(extra) else "VALUE")
            command.error(f"unrecognized argument {word}: {field} is a parameter of the "
                          f"material; give --set {field}={value}")
    command.error(f"unrecognized arguments: {' '.join(extra)}")


# ------------------------------------------------------------------ commands
#: Columns left empty where undefined by construction (listed in the README): the viscosity
#: tau/gdot where the shear rate is zero (at rest, at the start of a creep, a jammed steady state).
EMPTY_OK = ("viscosity_Pa_s", "relative_viscosity")


def _write(args, sample, df: pd.DataFrame, fig_maker, *, record: bool = False, marked=None):
    """Write the CSV and the figure; with ``record`` (the transients) also the run record
    ``<out>.json`` (rheology.run_end: status and the ends in ``df.attrs["ends"]``, those in
    ``marked``, default all, marked on the figure). Returns (message, the
    :class:`~rheology.run_end.EndedEarly` :func:`main` raises after it (exit 3) or None)."""
    plot = plot_path(args)
    ends = list(df.attrs.get("ends") or []) if record else []
    table, empty_ok = finish_table(sample, df, EMPTY_OK, args.cmd)   # instrument, mass, units
    atomic_write_csv(args.out, table, empty_ok=empty_ok)
    written = [args.out]
    msg = f"wrote {args.out} ({len(df)} rows)"
    if plot is not None:
        fig = fig_maker()
        mark_ends(fig, ends if marked is None else marked)
        if sample.material.units == "normalised":
            normalise_units(fig)
        written.append(plots.save(fig, plot))
        msg += f" and {plot}"
    if record:
        written.append(write_record(args, ends, len(df)))
        msg += f" and {written[-1]}"
    ended = EndedEarly(ends, partial=df, written=written) if ends else None
    events = df.attrs.get("events") or []
    if events:
        shown = "; ".join(f"t = {t:.6g} s (step {k}): {what}" for t, k, what in events[:5])
        msg += f"\nevents: {shown}" + (f"; ... ({len(events)} in all)" if len(events) > 5 else "")
    if df.attrs.get("substeps_note"):
        msg += f"\n{df.attrs['substeps_note']}"
    for note in df.attrs.get("notes") or []:
        msg += f"\nnote: {note}"
    return msg + extra_outputs(args, sample, df, plot), ended


def _per_phi(sample, run) -> pd.DataFrame:
    """``run(phi)`` at every --phi (column phi, or phi0 where phi evolves), concatenated
    (:func:`rheometer.protocols.combined`: the ends in ``attrs["ends"]``)."""
    frames, ends = [], []
    for ph in sample.phi:
        df = at_phi(run, ph, ends)
        if df is not None:
            df.insert(0, "phi0" if "phi" in df.columns else "phi", ph)
        frames.append(df)
    return combined(frames, ends)


def _cmd_materials(args) -> str:
    if args.out:
        check_output_path("--out", args.out, ["csv"])
    if args.material is not None:
        print(material_with(args.material, set_overrides(args.set)).summary())
        return ""
    if args.set:
        raise ValueError("--set needs --material NAME (the parameter set to change)")
    rows = rheology.list_materials()
    width = max(len(n) for n, _ in rows)
    for name, cite in rows:
        print(f"{name:{width}s}  {cite}")
    print(materials_note())
    if args.out:
        table = pd.DataFrame([{"name": n, "citation": c, **{
            k: getattr(rheology.get_material(n), k) for k in rheology.materials.FIELD_UNITS}}
            for n, c in rows])
        atomic_write_csv(args.out, table, empty_ok=tuple(rheology.materials.FIELD_UNITS))
        return f"wrote {args.out} ({len(table)} rows; empty: parameter not given by the paper)"
    return ""


def _cmd_flow_curve(args) -> str:
    plot_path(args)
    sample = sample_material(args)
    m, phis = sample.material, sample.phi
    n = int(args.points)
    # a range of the other control would be ignored: refused (defaults: 1e-3 1e4 Pa, 1e-4 1e3 1/s)
    if args.control == "rate" and args.stress_range is not None:
        raise ValueError("--stress-range is for --control stress or mixture-stress; --control "
                         "rate takes --rate-range")
    if args.control != "rate" and args.rate_range is not None:
        raise ValueError(f"--rate-range is for --control rate; --control {args.control} takes "
                         "--stress-range")
    lo, hi = ((args.rate_range or [1e-4, 1e3]) if args.control == "rate" else
              (args.stress_range or [1e-3, 1e4]))
    if not lo < hi:
        which = "--rate-range" if args.control == "rate" else "--stress-range"
        raise ValueError(f"{which} {lo:g} {hi:g} must satisfy 0 < LO < HI")
    values = np.logspace(np.log10(lo), np.log10(hi), n)
    df = (flow_curve(m, phis, rate=values, control="rate") if args.control == "rate" else
          flow_curve(m, phis, stress=values, control=args.control))
    if args.control == "rate":      # rates without a steady state leave no row: say which
        notes = []
        for ph in phis:
            hit = set(df.loc[np.isclose(df["phi"], ph), "index"].astype(int))
            missing = [values[k] for k in range(n) if k not in hit]
            if missing:
                why = (f"shear-jammed: phi > phi_c = {m.phi_c:g}, the structure takes "
                       "phi_m(f) down to phi" if ph > m.phi_c else "no flowing state")
                notes.append(f"phi = {ph:g}: no steady state at {len(missing)} of {n} rates "
                             f"({min(missing):.4g}-{max(missing):.4g} 1/s; {why}); --control "
                             "stress shows the whole S-shaped curve")
        df.attrs["notes"] = notes
    df = _below_rate_max(df, n)
    return _write(args, sample, df, lambda: plots.flow_curve_figure(df, m))


def _below_rate_max(df: pd.DataFrame, n: int) -> pd.DataFrame:
    """The steady states within the largest shear rate (runkit.limits.RATE_MAX), those past it
    counted in a note; ValueError when none is."""
    fast = df["shear_rate_per_s"].to_numpy() > RATE_MAX
    if not fast.any():
        return df
    why = f"the largest shear rate {RATE_MAX:g} 1/s, {physical.RATE_MAX.why}"
    if fast.all():
        phis = ", ".join(f"{p:g}" for p in df["phi"].unique())
        raise ValueError(f"every steady state of --phi {phis} at these stresses flows faster "
                         f"than {why}; give a lower --stress-range or a higher --phi")
    out = df[~fast].reset_index(drop=True)
    out.attrs.update(df.attrs)
    out.attrs["notes"] = [*df.attrs.get("notes", []), *(
        f"phi = {ph:g}: {int(k)} of {n} steady states flow faster than {why}: not written"
        for ph, k in pd.Series(fast).groupby(df["phi"].to_numpy()).sum().items() if k)]
    return out


def _check_relax_stress(args, m) -> None:
    """``relax --stress`` starts from a steady state at that granular stress: its elastic strain
    stress/G is known before the run; past the small-strain limit (rheology.elastic) the run is
    refused here (exit 2) rather than failed by the solver's check (exit 1)."""
    G, _ = skeleton(m, args.G)
    top = elastic_strain_limit_stress(G)
    src = "--G" if args.G is not None else (f"G of {m.name}" if m.G else "the default G")
    Param(physical.STRESS_MIN, le(top * (1.0 + 1e-12), (
        f"the steady state before cessation would strain the skeleton by stress/G = "
        f"{args.stress / G:.3g}, past the small-elastic-strain limit {ELASTIC_STRAIN_LIMIT:g} of "
        f"the hypoelastic law (G = {G:g} Pa, {src}); lower --stress or raise --G")),
        unit="Pa").check("--stress", args.stress)


#: the transients: help, default --t-end, the imposed value's option (flag, default, help,
#: quantity: read by the parser, checked once by the run's Step and Rheometer.run, the liquid's
#: rate limit, or by _check_relax_stress), the protocol and the figure's words
_TRANSIENTS = {
    "startup": ("start-up of shear at an imposed rate, from rest", 60.0,
                ("--rate", 0.5, "imposed shear rate [1/s] (0.5)", limits.RATE), startup,
                "start-up at {:g} 1/s"),
    "creep": ("creep at an imposed mixture shear stress, from rest", 60.0,
              ("--stress", 10.0, "imposed MIXTURE shear stress [Pa], > 0 (10)", limits.STRESS),
              creep, "creep at mixture stress {:g} Pa"),
    "relax": ("stress relaxation after cessation of steady shear (Fig. 15)", 50.0,
              ("--stress", 1000.0, "GRANULAR shear stress of the steady state before cessation "
                                   "[Pa] (1000)", limits.STRESS), relax,
              "relaxation from steady granular stress {:g} Pa")}


def _transient(args) -> str:
    plot_path(args)
    sample = sample_material(args)
    m = sample.material
    _, _, (flag, *_), run, what = _TRANSIENTS[args.cmd]
    opts = dict(G=args.G, K0=args.K0, rtol=args.rtol, points=args.points, elastic_limit=True,
                label=transient_label)
    value = getattr(args, flag[2:])
    if args.cmd == "relax":
        _check_relax_stress(args, m)
    else:
        opts["name"] = flag
    df = _per_phi(sample, lambda ph: run(m, ph, value, args.t_end, **opts))
    title = (f"{m.name}: {what.format(value)} (G = {df.attrs['G_Pa']:g} Pa, K0 = "
             f"{df.attrs['K0']:g})")
    frames = {f"phi = {ph:g}": d for ph, d in df.groupby("phi", sort=False)}
    return _write(args, sample, df, lambda: plots.transient_figure(frames, title, log_time=True),
                  record=True)


def read_program_file(name: str) -> tuple[str, str]:
    """(text, display name) of a program file, '-' for stdin; ValueError naming the file if it
    is missing, a folder, or not UTF-8 text."""
    if name == "-":
        return sys.stdin.read(), "stdin"
    path = check_input_file("program file", name)
    data = path.read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"program file {name!r} is not a text program (byte "
                         f"0x{data[exc.start]:02x} at offset {exc.start} is not UTF-8); lines "
                         f"read like 'shear at 10 1/s for 60 s'") from None
    if "\x00" in text:
        raise ValueError(f"program file {name!r} is not a text program (it holds NUL bytes); "
                         f"lines read like 'shear at 10 1/s for 60 s'")
    return text, path.name


def _cmd_program(args) -> str:
    plot_path(args)
    sample = sample_material(args)
    m = sample.material
    if args.file is None:
        text = hysteresis_program(m, sample.phi[0])
        name = f"built-in stress and rate sweeps up and down at phi = {sample.phi[0]:g}"
    else:
        text, name = read_program_file(args.file)
    program = parse_program(text)
    ck = ProgramCheckpoint(Path(args.out).with_suffix(".checkpoint.npz"), m, list(sample.phi),
                           text, dict(G=args.G, K0=args.K0, rtol=args.rtol, points=args.points,
                                      elastic_limit=True, label=transient_label),
                           every=args.checkpoint_every)
    used = ck.path
    if args.resume:
        used = ck.load(log=lambda msg: print(msg, file=sys.stderr))
    df = ck.run(program)
    title = (f"{m.name}: program '{name}', phi = {', '.join(f'{p:g}' for p in sample.phi)} "
             f"(G = {df.attrs['G_Pa']:g} Pa, K0 = {df.attrs['K0']:g})")
    drawn = float(df["phi"].iloc[0])           # the first phi with rows
    first = df[df["phi"] == drawn]
    first.attrs.update(df.attrs)
    msg, ended = _write(args, sample, df, lambda: plots.program_figure(first, title), record=True,
                 marked=[e for e in df.attrs["ends"] if e.run == f"phi = {drawn:g}"])
    for osc in df.attrs.get("oscillations") or []:
        msg += "\noscillation " + ", ".join(f"{k} = {v:.4g}" if isinstance(v, float) else
                                            f"{k} = {v}" for k, v in osc.items())
    ck.remove()
    if args.resume:
        msg += f"\nresumed from {used}"
    return msg, ended


def _cmd_material_point(args) -> str:
    plot_path(args)
    # options another choice makes irrelevant are refused, not ignored
    if args.control == "volume" and args.pressure is not None:
        raise ValueError("--pressure is the imposed pressure of --control pressure; --control "
                         "volume keeps phi: remove --pressure or give --control pressure")
    if args.stress0 is not None and args.pressure0 is not None:
        raise ValueError("give --stress0 (start from the steady state at that stress) or "
                         "--pressure0 (start from rest under that pressure), not both")
    sample = sample_material(args)
    m = sample.material
    df = _per_phi(sample, lambda ph: simple_shear_point(
        m, ph, args.rate, args.t_end, args.dt, control=args.control, pressure=args.pressure,
        f0=args.f0, stress0=args.stress0, pressure0=args.pressure0, G=args.G, K=args.K,
        K0=args.K0, points=args.points, elastic_limit=True,
        label=lambda k: _POINT_LABELS.get(k, k)))
    title = (f"{m.name}: material point, {args.control} control, rate {args.rate:g} 1/s, "
             f"dt = {args.dt:g} s, phi0 = {', '.join(f'{p:g}' for p in sample.phi)}")
    # every run, by its initial phi (phi itself evolves under pressure control)
    return _write(args, sample, df, lambda: plots.material_point_figure(df, title), record=True)


#: the options of rheometer.material_point's parameters
_POINT_LABELS = {"rate": "--rate", "t_end": "--t-end", "dt": "--dt", "points": "--points",
                 "f0": "--f0"}


_COMMANDS = {"materials": _cmd_materials, "flow-curve": _cmd_flow_curve,
             **dict.fromkeys(_TRANSIENTS, _transient),
             "program": _cmd_program, "material-point": _cmd_material_point}


def main(argv=None) -> int:
    """Entry point of the ``rheometer`` console script; returns the exit status."""
    args = build_parser().parse_args(argv)

    def body():
        # what a command prints is held until it ends: a refusal (bad input, exit 2) prints
        # only its one line; any other outcome prints it before its own line
        held = io.StringIO()
        try:
            with contextlib.redirect_stdout(held):
                out = _COMMANDS[args.cmd](args)
        except ValueError:
            raise
        except BaseException:
            sys.stdout.write(held.getvalue())
            raise
        sys.stdout.write(held.getvalue())
        msg, ended = out if isinstance(out, tuple) else (out, None)
        if msg:
            print(msg)
        if ended is not None:            # written up to its end: status 3
            raise ended

    return run_command(f"rheometer {args.cmd}", body)


if __name__ == "__main__":
    sys.exit(main())
