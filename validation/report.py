"""The validation report: runs cases and benchmarks and writes ``report.html`` and ``results.json``.

``results.json`` is strict JSON (no NaN or Infinity tokens): an object with ``complete`` (false
until every selected entry has run), ``status`` (``running``, ``interrupted`` or ``complete``),
``started``, ``updated``, ``seconds``, ``quick``, ``machine``, ``pending`` (selected entries not
yet finished), ``kept_from_earlier_runs`` and ``code_changed_since`` (``--resume``) and
``entries``: one object per case or benchmark with ``tier``, ``kind``, ``name``, ``title``,
``passed`` (null for a skipped entry), ``skipped`` (the reason, else null), ``reason`` (why it
failed, else null), ``seconds``, ``error`` (the traceback of an entry that raised), ``problems``
(values that are not results), ``criterion``, ``measured``, ``details``, ``summary``,
``targets`` (``[target, measured, met]``), ``rows`` (a null's reason in ``<column>_note`` or in
``notes``), ``notes``, ``figures`` (paths relative to the folder), ``quick``, ``fingerprint``
(:func:`framework.fingerprint`) and ``run`` (when the run that computed it started).
"""

from __future__ import annotations

import html
import json
import os
import platform
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from runkit.command import one_line
from runkit.io import atomic_write_json, atomic_write_text, check_output_dir
from runkit.run import Interrupts

from .framework import NOTE, TIERS, Entry, Outcome, fingerprint, load_all, run_entry


def machine_description() -> str:
    """CPU model, core count and Python/numpy versions, for timings."""
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
    reg = load_all()
    unknown = sorted(set(names or ()) - set(reg))
    if unknown:
        raise ValueError(f"--only = {' '.join(unknown)!r}: unknown case or benchmark "
                         f"name{'s' if len(unknown) > 1 else ''}; valid: {', '.join(sorted(reg))}")
    out = [e for e in reg.values() if e.kind in kinds
           and (not tiers or e.tier in tiers) and (not names or e.name in names)]
    return sorted(out, key=lambda e: _order(vars(e)))


def _order(r: dict):
    """The report's order of an entry (its fields as a dict): by tier, cases first, by name."""
    tier = TIERS.index(r["tier"]) if r["tier"] in TIERS else len(TIERS)
    return tier, r["kind"] != "case", r["name"]


#: Why ``--quick`` leaves a slow case out (the console and the report say it).
SKIP_SLOW = "slow case, run without --quick"
SKIP_NO_SLOW = "slow case, run without --no-slow"


@dataclass
class Plan:
    """What a report will do: the entries to run and the (entry, reason) pairs it skips."""

    run: list[Entry]
    skipped: list[tuple[Entry, str]] = field(default_factory=list)


def plan(tiers=None, names=None, quick: bool = False, benchmarks: bool = True,
         slow: bool = True) -> Plan:
    """Check a selection (``--tier``, ``--only``: None for all) and decide what runs, before
    anything is written. ``quick`` (``--quick``) and ``slow`` False (``--no-slow``) skip the
    cases registered ``slow=True``, whose criteria hold at full size only (reasons
    :data:`SKIP_SLOW`, :data:`SKIP_NO_SLOW`); benchmarks shrink under ``--quick`` and are left
    out by ``benchmarks`` False (``--no-bench``).

    Raises
    ------
    ValueError
        One line naming the option and value: an empty or unknown ``--tier`` or ``--only``, a
        named entry the other options leave out (its tier not in ``--tier``, a benchmark with
        ``--no-bench``, a slow case with ``--quick`` or ``--no-slow``: a quick run of it would
        report a failure that is no finding), or a selection with nothing to run.
    """
    skip_opt = "--quick" if quick else ("--no-slow" if not slow else None)
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
    reg, named = load_all(), list(dict.fromkeys(names or ()))
    refusals = (   # (left out, why) of a named entry the other options leave out
        (lambda e: tiers and e.tier not in tiers,
         lambda off: f"not in --tier {' '.join(tiers)} (tier "
                     f"{', '.join(reg[n].tier for n in off)})"),
        (lambda e: not benchmarks and e.kind == "benchmark",
         lambda off: f"benchmark{'s' if len(off) > 1 else ''}, which --no-bench leaves out"),
        (lambda e: skip_opt and e.kind == "case" and e.slow,
         lambda off: f"slow case{'s' if len(off) > 1 else ''}"
                     + (" whose criteria hold at full size only" if quick else "")
                     + f"; run without {skip_opt}"))
    for left_out, why in refusals:
        off = [n for n in named if left_out(reg[n])]
        if off:
            raise ValueError(f"--only = {' '.join(off)!r}: {why(off)}")
    is_skipped = [bool(skip_opt) and e.kind == "case" and e.slow for e in chosen]
    run = [e for e, s in zip(chosen, is_skipped) if not s]
    why = SKIP_SLOW if quick else SKIP_NO_SLOW
    skipped = [(e, why) for e, s in zip(chosen, is_skipped) if s]
    if not run:
        what = " ".join(filter(None, [f"--tier {' '.join(tiers)}" if tiers else "",
                                      f"--only {' '.join(names)}" if names else "",
                                      "--no-bench" if not benchmarks else "",
                                      skip_opt or ""]))
        why = (f"all {len(skipped)} selected cases are slow, which {skip_opt} skips; run "
               f"without {skip_opt}" if skipped else "nothing to run")
        raise ValueError(f"{what or 'the selection'}: {why}")
    return Plan(run, skipped)


def _esc(x) -> str:
    return html.escape("" if x is None else str(x))


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return "" if v is None else str(v)


def _verdict(r: dict) -> str:
    if r["skipped"] is not None:
        return "SKIPPED"
    return "PASS" if r["passed"] else ("ERROR" if r["error"] else "FAIL")


def _table(rows: list[dict], notes: dict) -> str:
    """A result's rows as an HTML table: a null is "-" with its reason as the cell's title and as
    a numbered footnote below the table."""
    keys = list(dict.fromkeys(k for r in rows for k in r if not k.endswith(NOTE)))
    foot: dict[str, int] = {}

    def cell(row, k):
        if k not in row:
            return "<td></td>"
        if row[k] is not None:
            return f"<td>{_esc(_fmt(row[k]))}</td>"
        why = row.get(k + NOTE) or notes.get(k) or "no reason given"
        n = foot.setdefault(why, len(foot) + 1)
        return f"<td title='{_esc(why)}'>-<sup>{n}</sup></td>"

    body = "".join("<tr>" + "".join(cell(r, k) for k in keys) + "</tr>" for r in rows)
    return ("<table><tr>" + "".join(f"<th>{_esc(k)}</th>" for k in keys) + f"</tr>{body}</table>"
            + "".join(f"<p style='font-size:85%'><sup>{n}</sup> {_esc(w)}</p>"
                      for w, n in foot.items()))


def _section(r: dict) -> str:
    run = (f"; {'small sizes' if r['quick'] else 'full size'}, run {r['run']}" if r.get("run")
           else "")
    parts = [
        f"<h3 id='{_esc(r['name'])}'>{_esc(r['title'])} <small>({r['tier']} {r['kind']} "
        f"<code>{_esc(r['name'])}</code>, {_verdict(r)}, {r['seconds']:.1f} s{run})</small></h3>",
        r["error"] and f"<pre>{_esc(r['error'])}</pre>",
        r["problems"] and ("<p><b>Values that are not results (the entry fails):</b></p><ul>"
                           + "".join(f"<li>{_esc(p)}</li>" for p in r["problems"]) + "</ul>"),
        r["kind"] == "case" and not r["error"] and (
            f"<p><b>Criterion:</b> {_esc(r['criterion'])}<br>"
            f"<b>Measured:</b> {_esc(r['measured'])}</p>"),
        r.get("summary") and f"<p>{_esc(r['summary'])}</p>",
        r.get("targets") and (
            "<table><tr><th>target</th><th>measured</th><th>met</th></tr>" + "".join(
                f"<tr><td>{_esc(t)}</td><td>{_esc(m)}</td><td>{'yes' if ok is True else 'NO'}"
                "</td></tr>" for t, m, ok in r["targets"]) + "</table>"),
        r.get("details") and f"<pre>{_esc(r['details'])}</pre>",
        r.get("rows") and _table(r["rows"], r.get("notes") or {}),
        *(f"<img src='{_esc(p)}' style='max-width:48%;margin:4px'>"
          for p in r.get("figures") or [])]
    return "\n".join(p for p in parts if p)


def _render(doc: dict) -> str:
    """``report.html`` from the ``results.json`` document (so a resumed report renders the entries
    of earlier runs exactly as the new ones)."""
    entries = doc["entries"]
    ran = [r for r in entries if r["skipped"] is None]
    cases = [r for r in ran if r["kind"] == "case"]
    benches = [r for r in ran if r["kind"] == "benchmark"]
    colour = {"PASS": "#1a7f37", "FAIL": "#cf222e", "ERROR": "#9a6700", "SKIPPED": "#57606a"}
    rows = []
    for r in entries:
        v = _verdict(r)
        if r["skipped"] is not None:
            crit, meas = "-", r["skipped"]
        elif r["kind"] == "case":
            crit, meas = r["criterion"] or "-", r["measured"] or "-"
        else:
            crit = "; ".join(t for t, _, _ in r["targets"] or []) or "-"
            meas = "; ".join(m for _, m, _ in r["targets"] or []) or r["summary"] or "-"
        name = (f"<a href='#{_esc(r['name'])}'>{_esc(r['name'])}</a>" if v != "SKIPPED"
                else _esc(r["name"]))
        secs = "-" if r["seconds"] is None else f"{r['seconds']:.1f}"
        rows.append(f"<tr><td>{r['tier']}</td><td>{r['kind']}</td><td>{name}</td>"
                    f"<td>{_esc(crit)}</td><td>{_esc(meas)}</td><td style='color:{colour[v]};"
                    f"font-weight:bold'>{v}</td><td>{secs}</td></tr>")
    state = ""
    if not doc["complete"]:
        state = (f"<p style='color:#9a6700;font-weight:bold'>INCOMPLETE ({doc['status']}): "
                 f"{len(doc['pending'])} selected entries not finished ("
                 f"{_esc(', '.join(doc['pending']))}); the same command with --resume runs "
                 "them and keeps the rest.</p>")
    kept = doc.get("kept_from_earlier_runs") or []
    changed = doc.get("code_changed_since") or []
    kept_note = (f" {len(kept)} entries kept from earlier runs (--resume): "
                 f"{_esc(', '.join(kept))}." if kept else "")
    kept_note += (f" Their code has changed since for: {_esc(', '.join(changed))} (rerun those "
                  "with --only)." if changed else "")
    skipped = [r for r in entries if r["skipped"] is not None]
    note = f" {len(skipped)} cases skipped (slow)." if skipped else ""
    sizes = " Small sizes (<code>--quick</code>)." if doc["quick"] else ""
    style = ("body{font-family:sans-serif;max-width:1400px;margin:auto}table{border-collapse:"
             "collapse;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 6px;font-size:90%;"
             "vertical-align:top}pre{background:#f6f8fa;padding:6px;overflow:auto}")
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>Validation report</title>"
            f"<style>{style}</style></head><body><h1>Dense-suspension toolkit: validation report"
            f"</h1>{state}<p>Baumgarten &amp; Kamrin model. {sum(r['passed'] for r in cases)}/"
            f"{len(cases)} cases pass" + (f"; {sum(r['passed'] for r in benches)}/"
                                          f"{len(benches)} benchmarks meet their targets"
                                          if benches else "")
            + f".{note}{sizes}{kept_note} Run started "
            f"{doc['started']}, {doc['seconds']:.0f} s{'' if doc['complete'] else ' so far'}, on "
            f"{_esc(doc['machine'])}.</p>"
            f"<table><tr><th>tier</th><th>kind</th><th>name</th><th>criterion / target</th>"
            f"<th>measured</th><th>verdict</th><th>s</th></tr>{''.join(rows)}</table>"
            + "\n<hr>\n".join(_section(r) for r in ran) + "</body></html>")


@dataclass
class Report:
    """What :func:`write_report` wrote: the entries of ``results.json`` (in report order), the
    two files, and the names kept from an earlier run (``--resume``)."""

    entries: list[dict]
    html: Path
    json: Path
    kept: list[str] = field(default_factory=list)


_FIELDS = ("criterion", "measured", "details", "summary", "targets", "rows", "notes")


def _record(e: Entry, run: str, quick: bool, fp: str | None, o: Outcome | None = None,
            skipped: str | None = None, root: Path = Path(".")) -> dict:
    """One entry of ``results.json``: a run's outcome, or (``o`` None) a skipped entry."""
    d = o.data if o is not None else {}
    return {"tier": e.tier, "kind": e.kind, "name": e.name, "title": e.title,
            "passed": getattr(o, "passed", None), "skipped": skipped,
            **{k: getattr(o, k, None) for k in ("reason", "seconds", "error")},
            "problems": getattr(o, "problems", []), **{k: d.get(k) for k in _FIELDS},
            "figures": [os.path.relpath(p, root) for p in d.get("figures") or []],
            "quick": quick, "fingerprint": fp, "run": run}


_KEYS = tuple(_record(Entry("case", TIERS[0], "", "", print), "", False, None))


def _reject_constant(name):
    raise ValueError(f"{name} is not strict JSON")


def _earlier(root: Path, out, quick: bool) -> dict[str, dict]:
    """``--resume``: the entries of the report in ``root``, by name.

    Raises
    ------
    ValueError
        No report there, one that is not strict JSON or not a report, or one of other sizes
        (``--quick`` on one run only).
    """
    path = root / "results.json"
    if not path.is_file():
        raise ValueError(f"--resume: no report in --out {str(out)!r} (no results.json); run "
                         "without --resume to start one")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"), parse_constant=_reject_constant)
        entries = {r["name"]: r for r in doc["entries"]}
        was_quick = bool(doc["quick"])
        for r in entries.values():
            missing = [k for k in _KEYS if k not in r]
            if missing:
                raise KeyError(f"entry {r['name']!r} has no {', '.join(missing)}")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"--resume: {path} is not a report this version can resume "
                         f"({type(exc).__name__}: {' '.join(str(exc).split())[:120]}); run "
                         "without --resume") from None
    if was_quick != quick:
        raise ValueError(f"--resume: {path} was written {'with' if was_quick else 'without'} "
                         f"--quick; resume {'with' if was_quick else 'without'} it, or give "
                         "another --out")
    return entries


def write_report(out, tiers=None, names=None, quick: bool = False, benchmarks: bool = True,
                 slow: bool = True, resume: bool = False, log=print) -> Report:
    """Run the selection (:func:`plan`) and write ``out/results.json`` and ``report.html``.

    The selection, the folder (``runkit.io.check_output_dir``) and, with ``resume``, the earlier
    report are checked before anything is written or run. Both files are rewritten atomically
    after every entry (``results.json`` first; ``"status": "running"`` until the last is done),
    so a crash or a kill loses at most the entry running; an entry that raises is recorded with
    its traceback, values that are not results fail their entry only (:func:`framework.clean`),
    and a failed write is tried again after the next entry. ``resume`` (``--resume``) keeps the
    entries of the report in ``out`` whose :func:`framework.fingerprint` is this run's and which
    did not raise, runs the others and keeps the entries outside this selection.

    Raises
    ------
    ValueError
        Bad selection, ``--out`` or ``--resume`` (one line; nothing written).
    RuntimeError
        The report could not be written at the end (the message says what the folder holds).
    KeyboardInterrupt
        Ctrl-C or SIGTERM at any moment once the selection is checked (SIGTERM is a
        ``KeyboardInterrupt`` here, called from the library too; a signal an entry's own window
        recorded and let its run finish stops the report after that entry): what finished is
        written first, marked ``"status": "interrupted"`` with every unfinished entry in
        ``pending``, and the message says so.
    """
    with Interrupts(defer=False) as stop:
        return _write_report(stop, out, tiers, names, quick, benchmarks, slow, resume, log)


def _write_report(stop, out, tiers, names, quick, benchmarks, slow, resume, log) -> Report:
    todo = plan(tiers, names, quick, benchmarks, slow)
    root = check_output_dir("--out", out)
    for fname in ("report.html", "results.json"):
        if (root / fname).is_dir():
            raise ValueError(f"--out = {str(out)!r}: {root / fname} is a folder; the report "
                             "writes a file there")
    for e in todo.run:
        if (root / e.name).exists() and not (root / e.name).is_dir():
            raise ValueError(f"--out = {str(out)!r}: {root / e.name} is a file; case "
                             f"{e.name} writes its figures in a folder there")
    records = _earlier(root, out, quick) if resume else {}
    run, t0 = time.strftime("%Y-%m-%d %H:%M:%S"), time.perf_counter()
    html_path, json_path = root / "report.html", root / "results.json"
    reg = load_all()
    earlier = [n for n, r in records.items() if r["skipped"] is None
               and n not in {e.name for e in todo.run}]
    changed = [n for n in earlier
               if n in reg and records[n]["fingerprint"] != fingerprint(reg[n], quick)]
    for e, why in todo.skipped:
        log(f"[{e.tier}] {e.kind} {e.name}: skipped: {why}", flush=True)
        if records.get(e.name, {}).get("skipped", "") is not None:     # keep an earlier result
            records[e.name] = _record(e, run, quick, None, skipped=why)
    pending, kept, written = [e.name for e in todo.run], [], 0

    def write(status: str) -> None:
        nonlocal written
        doc = {"complete": status == "complete", "status": status, "started": run,
               "updated": time.strftime("%Y-%m-%d %H:%M:%S"),
               "seconds": time.perf_counter() - t0, "quick": quick,
               "machine": machine_description(), "pending": pending,
               "kept_from_earlier_runs": sorted(set(kept) | set(earlier)),
               "code_changed_since": changed,
               "entries": sorted(records.values(), key=_order)}
        atomic_write_json(json_path, doc)               # strict JSON: no NaN/Infinity tokens
        atomic_write_text(html_path, _render(doc))
        written = sum(r["skipped"] is None for r in doc["entries"])

    root.mkdir(parents=True, exist_ok=True)     # the first thing written: from here a signal
    try:                                        # leaves a results.json naming what is pending
        for e in todo.run:
            fp = fingerprint(e, quick)
            old = records.get(e.name)
            if old is not None and old.get("fingerprint") == fp and old["error"] is None:
                log(f"[{e.tier}] {e.kind} {e.name}: kept from the run of {old['run']} (same "
                    f"code and sizes; {_verdict(old)})", flush=True)
                kept.append(e.name)
                pending.remove(e.name)
                continue
            again = ("" if old is None or old["skipped"] is not None else " (again: it raised)"
                     if old["error"] else " (again: its code changed)")
            log(f"[{e.tier}] {e.kind} {e.name} ...{again}", flush=True)
            o = run_entry(e, root, quick)
            log(f"    {'PASS' if o.passed else 'FAIL (' + o.reason + ')'} in {o.seconds:.1f} s"
                + (f"\n{o.error}" if o.error else ""), flush=True)
            records[e.name] = _record(e, run, quick, fp, o, root=root)
            pending.remove(e.name)
            try:
                write("running")
            except OSError as exc:
                log(f"    could not write the report ({one_line(exc)}); "
                    + (f"{json_path} keeps the report written before ({written} finished "
                       "entries)" if written else "nothing written yet")
                    + "; trying again after the next entry",
                    flush=True)
            if pending:               # a signal the entry's run recorded and finished after
                stop.check()
    except KeyboardInterrupt:
        done = len(todo.run) - len(pending)
        try:
            with Interrupts(defer=True):             # a second Ctrl-C waits for the write
                write("interrupted")
            what = (f"{json_path} and {html_path.name} have the {done} of {len(todo.run)} "
                    "selected entries finished, marked incomplete; the same command with "
                    "--resume runs the rest")
        except OSError as exc:
            what = (f"could not write the report ({one_line(exc)}); "
                    + (f"{json_path} holds {written} finished entries" if written
                       else "none written"))
        raise KeyboardInterrupt(what) from None
    try:
        write("complete")
    except OSError as exc:
        raise RuntimeError(f"could not write the report in {root} ({one_line(exc)}); "
                           + (f"{json_path} holds {written} finished entries, marked incomplete"
                              if written else "nothing was written")) from None
    return Report(sorted(records.values(), key=_order), html_path, json_path, kept)
