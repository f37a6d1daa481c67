"""Command line: ``python -m validation report --out DIR`` (also ``suspension-report``).

Subcommands:
  report   run cases and benchmarks, write DIR/report.html and DIR/results.json
  list     list every case and benchmark with its tier
"""

from __future__ import annotations

import argparse
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m validation", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    rep = sub.add_parser("report", help="run the validation cases and benchmarks, write HTML")
    rep.add_argument("--out", default="report", help="output folder (default: report)")
    rep.add_argument("--tier", nargs="*", help="only these tiers (rheology rheometer shear1d mpm2d)")
    rep.add_argument("--only", nargs="*", help="only these cases/benchmarks, by name")
    rep.add_argument("--quick", action="store_true", help="small sizes (as in the test suite)")
    rep.add_argument("--no-bench", action="store_true", help="skip the benchmarks")
    sub.add_parser("list", help="list the cases and benchmarks")
    args = ap.parse_args(argv)
    from .report import select, write_report

    try:
        if args.cmd == "list":
            for e in select():
                print(f"{e.tier:10s} {e.kind:9s} {e.name:32s} {e.title}")
            return 0
        outcomes = write_report(args.out, args.tier, args.only, args.quick, not args.no_bench)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    failed = [o for o in outcomes if not o.passed]
    for o in failed:
        print(f"FAIL {o.entry.name}: {o.reason}")
    print(f"wrote {args.out}/report.html: {len(outcomes) - len(failed)}/{len(outcomes)} pass"
          + (f"; failing: {', '.join(o.entry.name for o in failed)}" if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
