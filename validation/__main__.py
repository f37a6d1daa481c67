"""Command line: ``python -m validation report --out DIR`` (also ``suspension-report``).

Subcommands:
  report   run cases and benchmarks, write DIR/report.html and DIR/results.json
  list     list every case and benchmark with its tier (slow cases marked)

Bad input (an unknown tier or name, --only or --tier with nothing after it, a selection with
nothing to run, an --out that is a file or cannot be written) is refused with one line and
status 2 before anything is written. Status 1: a case or benchmark failed (each is named with
its criterion and measured value); 130: interrupted (Ctrl-C or SIGTERM).
"""

from __future__ import annotations

import argparse
import sys

from rheology.cli_common import OneLineParser, run_command

_QUICK_HELP = ("small sizes (as in the test suite). Cases marked slow (their criteria hold at "
               "full size only; 'list' marks them) are skipped and listed as skipped in the "
               "console and the report; naming a slow case in --only together with --quick is "
               "refused. Benchmarks run at small sizes (leave them out with --no-bench)")


def build_parser() -> OneLineParser:
    """The ``python -m validation`` parser (subcommands ``report`` and ``list``)."""
    ap = OneLineParser(prog="python -m validation", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True, metavar="COMMAND",
                            parser_class=OneLineParser)
    rep = sub.add_parser("report", help="run the validation cases and benchmarks, write HTML")
    rep.add_argument("--out", default="report",
                     help="output folder, created if absent (default: report)")
    rep.add_argument("--tier", nargs="*", metavar="TIER",
                     help="only these tiers: rheology rheometer shear1d mpm2d")
    rep.add_argument("--only", nargs="*", metavar="NAME",
                     help="only these cases/benchmarks, by name (see 'list')")
    rep.add_argument("--quick", action="store_true", help=_QUICK_HELP)
    rep.add_argument("--no-bench", action="store_true", help="skip the benchmarks")
    sub.add_parser("list", help="list the cases and benchmarks")
    return ap


def _list() -> int:
    from .report import select

    for e in select():
        slow = "slow" if e.slow and e.kind == "case" else ""
        print(f"{e.tier:10s} {e.kind:9s} {e.name:40s} {slow:4s} {e.title}")
    return 0


def _report(args) -> int:
    from .report import write_report

    rep = write_report(args.out, args.tier, args.only, args.quick, not args.no_bench)
    failed = [o for o in rep.outcomes if not o.passed]
    for o in failed:
        print(f"FAIL {o.entry.name}: {o.reason}")
    skipped = (f"; skipped {len(rep.skipped)} ({rep.skipped[0][1]}): "
               f"{', '.join(e.name for e, _ in rep.skipped)}" if rep.skipped else "")
    print(f"wrote {rep.html} and {rep.json.name}: {len(rep.outcomes) - len(failed)}/"
          f"{len(rep.outcomes)} pass"
          + (f"; failing: {', '.join(o.entry.name for o in failed)}" if failed else "")
          + skipped)
    return 1 if failed else 0


def main(argv=None) -> int:
    """Entry point of ``python -m validation`` and ``suspension-report``; returns the status."""
    args = build_parser().parse_args(argv)
    prog = f"python -m validation {args.cmd}"
    if args.cmd == "list":
        return run_command(prog, _list)
    return run_command(prog, lambda: _report(args))


if __name__ == "__main__":
    sys.exit(main())
