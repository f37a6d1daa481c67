"""Command line: ``python -m validation report --out DIR`` (also ``suspension-report``).

Subcommands:
  report   run cases and benchmarks, write DIR/report.html and DIR/results.json
  list     list every case and benchmark with its tier (slow cases marked); --out FILE
           writes the list to FILE (.txt as printed, .csv or .json: tier, kind, name, slow,
           title) atomically instead

DIR/results.json and DIR/report.html are rewritten after every entry, marked incomplete until
the run ends; an entry that raises, or reports a value that is not a result (NaN, inf, a null
without its reason), fails alone and the report goes on. Ctrl-C or SIGTERM writes what finished
(marked incomplete); --resume then runs only what is missing or whose code changed.

Bad input (an unknown tier or name, --only or --tier with nothing after it, a selection with
nothing to run, an --out that is a file or cannot be written (for list: a folder, another
format, a folder that cannot be written), --resume without a report there)
is refused with one line and status 2 before anything is written. Status 1: a case or
benchmark failed (each is named with its criterion and measured value), or the report could not
be written; 130: interrupted (Ctrl-C or SIGTERM).
"""

from __future__ import annotations

import argparse
import sys

import pandas as pd

from runkit.command import OneLineParser
from runkit.command import run as run_command
from runkit.io import atomic_write_csv, atomic_write_json, atomic_write_text, check_output_path
from .report import select, write_report

LIST_FORMATS = ("txt", "csv", "json")

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
    rep.add_argument("--no-slow", action="store_true",
                     help="skip the slow cases (listed as skipped) and run the rest at full size")
    rep.add_argument("--resume", action="store_true",
                     help="continue the report in --out: keep its entries run with the same "
                          "sizes and the same source code (a hash of rheology, the entry's tier "
                          "package and its validation module) that did not raise; run the rest "
                          "of the selection and merge (entries outside it are kept)")
    lst = sub.add_parser("list", help="list the cases and benchmarks")
    lst.add_argument("--out", metavar="FILE",
                     help=f"write the list to FILE ({', '.join(LIST_FORMATS)}) instead of "
                          "printing it")
    return ap


def _list(out=None) -> int:
    path = None if out is None else check_output_path("--out", out, LIST_FORMATS)
    rows = [{"tier": e.tier, "kind": e.kind, "name": e.name,
             "slow": bool(e.slow and e.kind == "case"), "title": e.title} for e in select()]
    lines = "".join(f"{r['tier']:10s} {r['kind']:9s} {r['name']:40s} "
                    f"{'slow' if r['slow'] else '':4s} {r['title']}\n" for r in rows)
    if path is None:
        print(lines, end="")
        return 0
    kind = path.suffix.lower().lstrip(".")
    if kind == "json":
        atomic_write_json(path, rows)
    elif kind == "csv":
        atomic_write_csv(path, pd.DataFrame(rows))
    else:
        atomic_write_text(path, lines)
    print(f"wrote {path}: {len(rows)} cases and benchmarks")
    return 0


def _report(args) -> int:
    rep = write_report(args.out, args.tier, args.only, args.quick, not args.no_bench,
                       not args.no_slow, args.resume)
    ran = [r for r in rep.entries if r["skipped"] is None]
    failed = [r for r in ran if not r["passed"]]
    skipped = [r for r in rep.entries if r["skipped"] is not None]
    for r in failed:
        print(f"FAIL {r['name']}: {r['reason']}")
    print(f"wrote {rep.html} and {rep.json.name}: {len(ran) - len(failed)}/{len(ran)} pass"
          + (f"; failing: {', '.join(r['name'] for r in failed)}" if failed else "")
          + (f"; skipped {len(skipped)} ({skipped[0]['skipped']}): "
             f"{', '.join(r['name'] for r in skipped)}" if skipped else "")
          + (f"; {len(rep.kept)} kept from the earlier run" if rep.kept else ""))
    return 1 if failed else 0


def main(argv=None) -> int:
    """Entry point of ``python -m validation`` and ``suspension-report``; returns the status."""
    args = build_parser().parse_args(argv)
    body = (lambda: _list(args.out)) if args.cmd == "list" else lambda: _report(args)
    return run_command(f"python -m validation {args.cmd}", body)


if __name__ == "__main__":
    sys.exit(main())
