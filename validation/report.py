"""The validation report: runs cases and benchmarks and writes ``report.html`` and ``results.json``."""

from __future__ import annotations

import html
import os
import platform
import time
from dataclasses import dataclass, field
from pathlib import Path

from rheology.io import atomic_write_json, atomic_write_text, check_output_dir

from .framework import BenchResult, Entry, Outcome, Verdict, load_all, run_entry


def machine_description() -> str:
    """CPU model, core count and Python/numpy versions, for timings."""
    import numpy as np

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, "
            f"numpy {np.__version__}")


def select(tiers=None, names=None, kinds=("case", "benchmark")):
    """Registry entries filtered by tier, name and kind, in tier order.

    Raises
    ------
    ValueError
        A name that is not registered (the message lists the valid names).
    """
    from .framework import TIERS

    reg = load_all()
    unknown = sorted(set(names or ()) - set(reg))
    if unknown:
        raise ValueError(f"--only = {' '.join(unknown)!r}: unknown case or benchmark "
                         f"name{'s' if len(unknown) > 1 else ''}; valid: {', '.join(sorted(reg))}")
    out = [e for e in reg.values() if e.kind in kinds
           and (not tiers or e.tier in tiers) and (not names or e.name in names)]
    return sorted(out, key=lambda e: (TIERS.index(e.tier), e.kind != "case", e.name))


#: Why ``--quick`` leaves a slow case out (the console and the report say it).
SKIP_SLOW = "slow case, run without --quick"


@dataclass
class Plan:
    """What a report will do: the entries to run and the (entry, reason) pairs it skips."""

    run: list[Entry]
    skipped: list[tuple[Entry, str]] = field(default_factory=list)


def plan(tiers=None, names=None, quick: bool = False, benchmarks: bool = True) -> Plan:
    """Check a selection and decide what runs, before anything is written.

    Parameters
    ----------
    tiers : list of str or None
        ``--tier``: None for every tier; each must be one of ``framework.TIERS``.
    names : list of str or None
        ``--only``: None for every entry; otherwise registered case or benchmark names.
    quick : bool
        ``--quick``: small sizes. A case registered ``slow=True`` states criteria that hold at
        full size only, so ``--quick`` skips it (reason :data:`SKIP_SLOW`) unless it is named in
        ``--only``, which is refused: a quick run of it would report a failure that is no
        finding. Benchmarks are not skipped (their sizes shrink; ``--no-bench`` leaves them out).
    benchmarks : bool
        False for ``--no-bench``.

    Raises
    ------
    ValueError
        One line naming the option and value: an empty or unknown ``--tier`` or ``--only``, a
        named entry the other options leave out (its tier not in ``--tier``, a benchmark with
        ``--no-bench``, a slow case with ``--quick``), or a selection with nothing to run.
    """
    from .framework import TIERS

    if tiers is not None:
        if not tiers:
            raise ValueError(f"--tier given no tier; valid: {', '.join(TIERS)}")
        bad = [t for t in tiers if t not in TIERS]
        if bad:
            raise ValueError(f"--tier = {' '.join(bad)!r}: unknown tier; valid: "
                             f"{', '.join(TIERS)}")
    if names is not None and not names:
        raise ValueError("--only given no names; name one or more cases or benchmarks "
                         "('python -m validation list' shows them)")
    kinds = ("case", "benchmark") if benchmarks else ("case",)
    chosen = select(tiers, names, kinds)             # refuses unknown names
    if names:
        reg = load_all()
        named = list(dict.fromkeys(names))
        if tiers:
            off = [n for n in named if reg[n].tier not in tiers]
            if off:
                raise ValueError(f"--only = {' '.join(off)!r}: not in --tier "
                                 f"{' '.join(tiers)} (tier {', '.join(reg[n].tier for n in off)})")
        if not benchmarks:
            off = [n for n in named if reg[n].kind == "benchmark"]
            if off:
                raise ValueError(f"--only = {' '.join(off)!r}: benchmark"
                                 f"{'s' if len(off) > 1 else ''}, which --no-bench leaves out")
        if quick:
            off = [n for n in named if reg[n].kind == "case" and reg[n].slow]
            if off:
                raise ValueError(f"--only = {' '.join(off)!r}: slow case"
                                 f"{'s' if len(off) > 1 else ''} whose criteria hold at full "
                                 "size only; run without --quick")
    run = [e for e in chosen if not (quick and e.kind == "case" and e.slow)]
    skipped = [(e, SKIP_SLOW) for e in chosen if quick and e.kind == "case" and e.slow]
    if not run:
        what = " ".join(filter(None, [f"--tier {' '.join(tiers)}" if tiers else "",
                                      f"--only {' '.join(names)}" if names else "",
                                      "--no-bench" if not benchmarks else "",
                                      "--quick" if quick else ""]))
        why = (f"all {len(skipped)} selected cases are slow, which --quick skips; run without "
               "--quick" if skipped else "nothing to run")
        raise ValueError(f"{what or 'the selection'}: {why}")
    return Plan(run, skipped)


def _rel(path, root: Path) -> str:
    return html.escape(os.path.relpath(Path(path), root))


def _render(outcomes: list[Outcome], root: Path, seconds: float,
            skipped: list[tuple[Entry, str]] = (), quick: bool = False) -> str:
    cases = [o for o in outcomes if o.entry.kind == "case"]
    benches = [o for o in outcomes if o.entry.kind == "benchmark"]
    npass = sum(o.passed for o in cases)
    rows, sections = [], []
    for o in outcomes:
        e = o.entry
        verdict = "PASS" if o.passed else ("ERROR" if o.error else "FAIL")
        colour = {"PASS": "#1a7f37", "FAIL": "#cf222e", "ERROR": "#9a6700"}[verdict]
        if isinstance(o.result, Verdict):
            crit, meas = o.result.criterion, o.result.measured
        elif isinstance(o.result, BenchResult):
            crit = "; ".join(t for t, _, _ in o.result.targets) or "-"
            meas = "; ".join(m for _, m, _ in o.result.targets) or o.result.summary
        else:
            crit, meas = "-", "-"
        rows.append(f"<tr><td>{e.tier}</td><td>{e.kind}</td><td><a href='#{e.name}'>{e.name}</a>"
                    f"</td><td>{html.escape(crit)}</td><td>{html.escape(meas)}</td>"
                    f"<td style='color:{colour};font-weight:bold'>{verdict}</td>"
                    f"<td>{o.seconds:.1f}</td></tr>")
        body = [f"<h3 id='{e.name}'>{html.escape(e.title)} <small>({e.tier} {e.kind} "
                f"<code>{e.name}</code>, {verdict})</small></h3>"]
        if o.error:
            body.append(f"<pre>{html.escape(o.error)}</pre>")
        elif isinstance(o.result, Verdict):
            body.append(f"<p><b>Criterion:</b> {html.escape(o.result.criterion)}<br>"
                        f"<b>Measured:</b> {html.escape(o.result.measured)}</p>")
            if o.result.details:
                body.append(f"<pre>{html.escape(o.result.details)}</pre>")
        else:
            r = o.result
            body.append(f"<p>{html.escape(r.summary)}</p>")
            if r.targets:
                body.append("<table><tr><th>target</th><th>measured</th><th>met</th></tr>" + "".join(
                    f"<tr><td>{html.escape(t)}</td><td>{html.escape(m)}</td><td>{'yes' if ok else 'NO'}"
                    f"</td></tr>" for t, m, ok in r.targets) + "</table>")
            if r.rows:
                keys = list(r.rows[0])
                body.append("<table><tr>" + "".join(f"<th>{html.escape(k)}</th>" for k in keys)
                            + "</tr>" + "".join("<tr>" + "".join(
                                f"<td>{html.escape(_fmt(row.get(k)))}</td>" for k in keys) + "</tr>"
                                for row in r.rows) + "</table>")
        figs = getattr(o.result, "figures", []) if o.result is not None else []
        body += [f"<img src='{_rel(p, root)}' style='max-width:48%;margin:4px'>" for p in figs]
        sections.append("\n".join(body))
    for e, why in skipped:
        rows.append(f"<tr><td>{e.tier}</td><td>{e.kind}</td><td>{e.name}</td><td>-</td>"
                    f"<td>{html.escape(why)}</td><td style='color:#57606a;font-weight:bold'>"
                    f"SKIPPED</td><td>-</td></tr>")
    note = (f" {len(skipped)} slow cases skipped ({html.escape(SKIP_SLOW)})." if skipped else "")
    sizes = " Small sizes (<code>--quick</code>)." if quick else ""
    style = ("body{font-family:sans-serif;max-width:1400px;margin:auto}table{border-collapse:"
             "collapse;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 6px;font-size:90%;"
             "vertical-align:top}pre{background:#f6f8fa;padding:6px;overflow:auto}")
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>Validation report</title>"
            f"<style>{style}</style></head><body><h1>Dense-suspension toolkit: validation report</h1>"
            f"<p>Baumgarten &amp; Kamrin model. {npass}/{len(cases)} cases pass; "
            f"{len(benches)} benchmarks.{note}{sizes} Run {time.strftime('%Y-%m-%d %H:%M')} in {seconds:.0f} s on "
            f"{html.escape(machine_description())}.</p>"
            f"<table><tr><th>tier</th><th>kind</th><th>name</th><th>criterion / target</th>"
            f"<th>measured</th><th>verdict</th><th>s</th></tr>{''.join(rows)}</table>"
            + "\n<hr>\n".join(sections) + "</body></html>")


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return "" if v is None else str(v)


@dataclass
class Report:
    """What :func:`write_report` did: the outcomes, the skipped entries and the files written."""

    outcomes: list[Outcome]
    skipped: list[tuple[Entry, str]]
    html: Path
    json: Path


def _results(outcomes, skipped) -> list[dict]:
    rows = [{"tier": o.entry.tier, "kind": o.entry.kind, "name": o.entry.name,
             "passed": o.passed, "skipped": None, "seconds": o.seconds, "error": o.error,
             "criterion": getattr(o.result, "criterion", None),
             "measured": getattr(o.result, "measured", None),
             "targets": getattr(o.result, "targets", None),
             "rows": getattr(o.result, "rows", None)} for o in outcomes]
    rows += [{"tier": e.tier, "kind": e.kind, "name": e.name, "passed": None, "skipped": why,
              "seconds": None, "error": None, "criterion": None, "measured": None,
              "targets": None, "rows": None} for e, why in skipped]
    return rows


def write_report(out, tiers=None, names=None, quick: bool = False, benchmarks: bool = True,
                 log=print) -> Report:
    """Run the selected cases (and benchmarks) and write ``out/report.html`` and ``results.json``.

    The selection (:func:`plan`) and the folder (``rheology.io.check_output_dir``) are checked
    before anything is written or run. ``report.html`` is rewritten after every entry (a long
    run shows progress); ``results.json`` (one object per entry, ``passed`` null and ``skipped``
    the reason for a skipped one) once all have run.

    Raises
    ------
    ValueError
        Bad selection or ``--out`` (one line; nothing written).
    KeyboardInterrupt
        Ctrl-C or SIGTERM, with a message saying what was written so far.
    """
    if not str(out).strip():
        raise ValueError(f"--out = {str(out)!r}: give a folder name")
    todo = plan(tiers, names, quick, benchmarks)
    root = check_output_dir("--out", out)
    for fname in ("report.html", "results.json"):
        if (root / fname).is_dir():
            raise ValueError(f"--out = {str(out)!r}: {root / fname} is a folder; the report "
                             "writes a file there")
    for e in todo.run:
        if (root / e.name).exists() and not (root / e.name).is_dir():
            raise ValueError(f"--out = {str(out)!r}: {root / e.name} is a file; case "
                             f"{e.name} writes its figures in a folder there")
    root.mkdir(parents=True, exist_ok=True)
    for e, why in todo.skipped:
        log(f"[{e.tier}] {e.kind} {e.name}: skipped: {why}", flush=True)
    outcomes, t0 = [], time.perf_counter()
    html_path, json_path = root / "report.html", root / "results.json"
    try:
        for e in todo.run:
            log(f"[{e.tier}] {e.kind} {e.name} ...", flush=True)
            o = run_entry(e, root, quick)
            log(f"    {'PASS' if o.passed else 'FAIL (' + o.reason + ')'} in {o.seconds:.1f} s"
                + (f"\n{o.error}" if o.error else ""), flush=True)
            outcomes.append(o)
            # rewrite after every entry so a long run shows progress and survives interruption
            atomic_write_text(html_path, _render(outcomes, root, time.perf_counter() - t0,
                                                 todo.skipped, quick))
    except KeyboardInterrupt:
        done = (f"{html_path} has the {len(outcomes)} of {len(todo.run)} entries finished; "
                f"{json_path.name} not written" if outcomes else "no entry finished; no report "
                "written")
        raise KeyboardInterrupt(done) from None
    atomic_write_json(json_path, _results(outcomes, todo.skipped), nullable=("measured",))
    return Report(outcomes, todo.skipped, html_path, json_path)
