"""The validation report: runs cases and benchmarks and writes ``report.html`` and ``results.json``."""

from __future__ import annotations

import html
import json
import os
import platform
import time
from pathlib import Path

from rheology.io import atomic_write_json, atomic_write_text

from .framework import BenchResult, Outcome, Verdict, load_all, run_entry


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
    """Registry entries filtered by tier, name and kind, in tier order."""
    from .framework import TIERS

    reg = load_all()
    out = [e for e in reg.values() if e.kind in kinds
           and (not tiers or e.tier in tiers) and (not names or e.name in names)]
    unknown = set(names or ()) - set(reg)
    if unknown:
        raise ValueError(f"unknown case or benchmark {sorted(unknown)}; valid: {sorted(reg)}")
    return sorted(out, key=lambda e: (TIERS.index(e.tier), e.kind != "case", e.name))


def _rel(path, root: Path) -> str:
    return html.escape(os.path.relpath(Path(path), root))


def _render(outcomes: list[Outcome], root: Path, seconds: float) -> str:
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
    style = ("body{font-family:sans-serif;max-width:1400px;margin:auto}table{border-collapse:"
             "collapse;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 6px;font-size:90%;"
             "vertical-align:top}pre{background:#f6f8fa;padding:6px;overflow:auto}")
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>Validation report</title>"
            f"<style>{style}</style></head><body><h1>Dense-suspension toolkit: validation report</h1>"
            f"<p>Baumgarten &amp; Kamrin model. {npass}/{len(cases)} cases pass; "
            f"{len(benches)} benchmarks. Run {time.strftime('%Y-%m-%d %H:%M')} in {seconds:.0f} s on "
            f"{html.escape(machine_description())}.</p>"
            f"<table><tr><th>tier</th><th>kind</th><th>name</th><th>criterion / target</th>"
            f"<th>measured</th><th>verdict</th><th>s</th></tr>{''.join(rows)}</table>"
            + "\n<hr>\n".join(sections) + "</body></html>")


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return "" if v is None else str(v)


def write_report(out, tiers=None, names=None, quick: bool = False, benchmarks: bool = True,
                 log=print) -> list[Outcome]:
    """Run the selected cases (and benchmarks) and write ``out/report.html`` and ``results.json``."""
    root = Path(out)
    root.mkdir(parents=True, exist_ok=True)
    kinds = ("case", "benchmark") if benchmarks else ("case",)
    outcomes, t0 = [], time.perf_counter()
    for e in select(tiers, names, kinds):
        log(f"[{e.tier}] {e.kind} {e.name} ...", flush=True)
        o = run_entry(e, root, quick)
        log(f"    {'PASS' if o.passed else 'FAIL (' + o.reason + ')'} in {o.seconds:.1f} s"
            + (f"\n{o.error}" if o.error else ""), flush=True)
        outcomes.append(o)
        # rewrite after every entry so a long run shows progress and survives interruption
        atomic_write_text(root / "report.html", _render(outcomes, root, time.perf_counter() - t0))
    results = [{"tier": o.entry.tier, "kind": o.entry.kind, "name": o.entry.name,
                "passed": o.passed, "seconds": o.seconds, "error": o.error,
                "criterion": getattr(o.result, "criterion", None),
                "measured": getattr(o.result, "measured", None),
                "targets": getattr(o.result, "targets", None),
                "rows": getattr(o.result, "rows", None)} for o in outcomes]
    atomic_write_json(root / "results.json", results, nullable=("measured",))
    return outcomes
