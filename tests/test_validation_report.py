"""The validation report keeps what ran: strict ``results.json`` with nulls and their reasons, an
unexpected non-finite value failing only its own entry, rewrites after every entry (marked
incomplete until the end), an entry that raises or a write that fails losing nothing else, SIGTERM
writing what finished, and ``--resume`` running only what is missing or whose code changed.

Run in-process through ``validation.__main__.main`` on temporary entries (the registry the report
reads is replaced), so no physics runs here: the cases' own checks are in the tier tests.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from validation import report as report_mod
from validation.__main__ import main
from validation.framework import UNEXPECTED, BenchResult, Entry, Verdict

NAN, INF = float("nan"), float("inf")


def _strict(path):
    """Parse with a parser that refuses NaN/Infinity tokens."""
    def refuse(token):
        raise AssertionError(f"{path} holds {token}")
    return json.loads(path.read_text(), parse_constant=refuse)


def _planted_case(out, quick):
    return Verdict(criterion="order > 1.9", measured="orders 2.0", passed=True, rows=[
        {"h": 1.0, "order": None, "order_note": "coarsest grid: no coarser one to compare"},
        {"h": 0.5, "order": NAN},                  # NaN without a reason: unexpected
        {"h": 0.25, "order": INF}])                # inf: never a result


def _planted_bench(out, quick):
    return BenchResult(summary="s", rows=[
        {"method": "ida", "dt": None, "error": 1e-4},          # undefined: notes["dt"]
        {"method": "explicit", "dt": 1e-3, "error": NAN},      # unexpected NaN
        {"method": "explicit", "dt": 2e-3, "error": INF}],     # unexpected inf
        targets=[("error < 1e-3", "1e-4", True)], notes={"dt": "IDA steps adaptively"})


def _undefined_bench(out, quick):
    """Only values undefined by construction, each with its reason: the entry passes."""
    return BenchResult(summary="s", rows=[
        {"method": "explicit", "dt": 3.0, "error": None,
         "error_note": "diverged: no velocity to compare"},
        {"method": "explicit", "dt": 1.0, "error": NAN}],      # NaN in a column with a note
        targets=[("diverges above the limit", "at 3x", True)],
        notes={"error": "diverged"})


def _clean_case(out, quick):
    return Verdict(criterion="c", measured="m", passed=True, rows=[{"x": 1.5}])


def _raising_case(out, quick):
    raise ZeroDivisionError("planted")


@pytest.fixture
def registry(monkeypatch, tmp_path):
    """Temporary entries, one tier each kind; returns (the registry, the list of names run)."""
    ran = []

    def entry(kind, tier, name, func):
        def run(out, quick):
            ran.append(name)
            return func(out, quick)
        return Entry(kind, tier, name, name.replace("_", " "), run)

    reg = {e.name: e for e in (
        entry("case", "rheology", "clean_case", _clean_case),
        entry("case", "rheology", "planted_case", _planted_case),
        entry("case", "rheometer", "raising_case", _raising_case),
        entry("benchmark", "rheology", "planted_bench", _planted_bench),
        entry("benchmark", "shear1d", "undefined_bench", _undefined_bench))}
    monkeypatch.setattr(report_mod, "load_all", lambda: reg)
    monkeypatch.chdir(tmp_path)
    return reg, ran


def _report(capsys, *args):
    code = main(["report", "--out", "rep", *args])
    out, err = capsys.readouterr()
    return code, out, err.strip().splitlines()


def test_planted_values_null_with_reason_or_fail_their_entry(registry, capsys, tmp_path):
    code, out, err = _report(capsys)
    assert code == 1 and err == []
    doc = _strict(tmp_path / "rep" / "results.json")
    assert doc["complete"] is True and doc["status"] == "complete" and doc["pending"] == []
    by = {r["name"]: r for r in doc["entries"]}
    assert sorted(by) == sorted(registry[0])
    # the case: the None with its reason kept; the NaN and the inf fail the entry, named
    case = by["planted_case"]
    assert case["passed"] is False and case["error"] is None
    assert case["rows"] == [
        {"h": 1.0, "order": None, "order_note": "coarsest grid: no coarser one to compare"},
        {"h": 0.5, "order": None, "order_note": UNEXPECTED},
        {"h": 0.25, "order": None, "order_note": UNEXPECTED}]
    assert case["problems"] == ["rows[1].order = nan (row 1, h=0.5)",
                                "rows[2].order = inf (row 2, h=0.25)"]
    assert "rows[1].order = nan" in case["reason"]
    # the benchmark: likewise, its row named by the first columns
    bench = by["planted_bench"]
    assert bench["passed"] is False
    assert bench["rows"][0] == {"method": "ida", "dt": None, "error": 1e-4}
    assert bench["notes"] == {"dt": "IDA steps adaptively"}
    assert bench["rows"][1]["error"] is None and bench["rows"][1]["error_note"] == UNEXPECTED
    assert bench["problems"] == ["rows[1].error = nan (row 1, method=explicit, dt=0.001)",
                                 "rows[2].error = inf (row 2, method=explicit, dt=0.002)"]
    # values undefined by construction pass; the other entries are intact
    undefined = by["undefined_bench"]
    assert undefined["passed"] is True and undefined["problems"] == []
    assert [r["error"] for r in undefined["rows"]] == [None, None]
    assert undefined["rows"][0]["error_note"] == "diverged: no velocity to compare"
    assert by["clean_case"]["passed"] is True and by["clean_case"]["rows"] == [{"x": 1.5}]
    assert by["raising_case"]["passed"] is False
    assert "ZeroDivisionError: planted" in by["raising_case"]["error"]
    assert by["raising_case"]["reason"] == "error: ZeroDivisionError: planted"
    # the console names each failing entry with the row and column
    assert "FAIL planted_case: values that are not results: rows[1].order = nan" in out
    assert "FAIL planted_bench: values that are not results: rows[1].error = nan" in out
    assert "2/5 pass" in out.strip().splitlines()[-1]
    # HTML: a null is "-" with its reason as the cell's title
    page = (tmp_path / "rep" / "report.html").read_text()
    assert "<td title='coarsest grid: no coarser one to compare'>-<sup>1</sup></td>" in page
    assert "<td title='IDA steps adaptively'>-<sup>1</sup></td>" in page
    assert f"title='{UNEXPECTED}'" in page
    assert "<td>nan</td>" not in page and "<td>inf</td>" not in page


def test_a_null_without_a_reason_fails_its_entry(registry, capsys, tmp_path, monkeypatch):
    reg, _ = registry
    reg["clean_case"].func = lambda out, quick: Verdict(
        criterion="c", measured=None, passed=True, rows=[{"x": None}])
    code, out, _ = _report(capsys, "--only", "clean_case")
    assert code == 1
    (r,) = _strict(tmp_path / "rep" / "results.json")["entries"]
    assert r["problems"] == ["measured is null with no reason",
                             "rows[0].x is null with no reason (row 0)"]


def test_report_rewritten_after_every_entry_marked_incomplete(registry, capsys, tmp_path,
                                                              monkeypatch):
    seen = []
    real = report_mod.atomic_write_json

    def spy(path, doc):
        seen.append((doc["status"], [r["name"] for r in doc["entries"]], list(doc["pending"])))
        return real(path, doc)

    monkeypatch.setattr(report_mod, "atomic_write_json", spy)
    _report(capsys, "--tier", "rheology", "--no-bench")
    assert seen == [("running", ["clean_case"], ["planted_case"]),
                    ("running", ["clean_case", "planted_case"], []),
                    ("complete", ["clean_case", "planted_case"], [])]


def test_a_failed_write_loses_no_entry(registry, capsys, tmp_path, monkeypatch):
    """The second write fails (disk full): the first file stays whole, the next has everything."""
    real, calls = report_mod.atomic_write_json, []

    def flaky(path, doc):
        calls.append(len(doc["entries"]))
        if len(calls) == 2:
            assert [r["name"] for r in _strict(path)["entries"]] == ["clean_case"]
            raise OSError(28, "No space left on device")
        return real(path, doc)

    monkeypatch.setattr(report_mod, "atomic_write_json", flaky)
    code, out, err = _report(capsys, "--tier", "rheology")
    assert "could not write the report ([Errno 28] No space left on device); " in out
    assert ("keeps the report written before (1 finished entries); trying again after the "
            "next entry") in out
    doc = _strict(tmp_path / "rep" / "results.json")
    assert doc["complete"] and [r["name"] for r in doc["entries"]] == [
        "clean_case", "planted_case", "planted_bench"]


def test_a_failed_last_write_is_status_1_naming_what_is_kept(registry, capsys, tmp_path,
                                                             monkeypatch):
    real = report_mod.atomic_write_json

    def full_at_end(path, doc):
        if doc["status"] == "complete":
            raise OSError(28, "No space left on device")
        return real(path, doc)

    monkeypatch.setattr(report_mod, "atomic_write_json", full_at_end)
    code, out, err = _report(capsys, "--tier", "rheology", "--no-bench")
    assert code == 1 and len(err) == 1
    assert "failed: could not write the report" in err[0] and "holds 2 finished entries" in err[0]
    assert _strict(tmp_path / "rep" / "results.json")["status"] == "running"


def _sigterm_in(reg, name):
    def func(out, quick):
        os.kill(os.getpid(), signal.SIGTERM)
        raise AssertionError("SIGTERM did not stop the run")
    reg[name].func = func


def test_sigterm_writes_what_finished_and_resume_finishes_it(registry, capsys, tmp_path):
    reg, ran = registry
    good = reg["planted_bench"].func
    _sigterm_in(reg, "planted_bench")
    code, out, err = _report(capsys, "--tier", "rheology")
    assert code == 130 and len(err) == 1
    assert "2 of 3 selected entries finished, marked incomplete" in err[0]
    doc = _strict(tmp_path / "rep" / "results.json")
    assert (doc["complete"], doc["status"], doc["pending"]) == (False, "interrupted",
                                                                ["planted_bench"])
    assert "INCOMPLETE (interrupted)" in (tmp_path / "rep" / "report.html").read_text()
    reg["planted_bench"].func = good
    ran.clear()
    code, out, err = _report(capsys, "--tier", "rheology", "--resume")
    assert ran == ["planted_bench"]                  # the two finished entries are kept
    assert "clean_case: kept from the run of" in out and "(same code and sizes; PASS)" in out
    assert "2 kept from the earlier run" in out.strip().splitlines()[-1]
    doc = _strict(tmp_path / "rep" / "results.json")
    assert doc["complete"] is True and doc["pending"] == []
    assert [r["name"] for r in doc["entries"]] == ["clean_case", "planted_case", "planted_bench"]


def _runs(out, statuses):
    """Run folders ``out/<status>`` with a manifest of that status and a checkpoint."""
    for status in statuses:
        (out / status).mkdir(parents=True)
        (out / status / "manifest.json").write_text(json.dumps({"status": status}))
        (out / status / "checkpoint.npz").write_bytes(b"npz")


def test_completed_runs_lose_their_checkpoints_interrupted_ones_keep_them(registry, capsys,
                                                                         tmp_path):
    reg, _ = registry

    def case(out, quick):
        _runs(out, ("complete", "stopped", "running"))
        return Verdict("c", "m", True)

    def interrupted(out, quick):
        _runs(out, ("complete",))
        raise KeyboardInterrupt

    reg["clean_case"].func, reg["planted_case"].func = case, interrupted
    code, _, _ = _report(capsys, "--tier", "rheology", "--no-bench")
    assert code == 130
    rep = tmp_path / "rep"
    assert sorted(str(p.relative_to(rep)) for p in rep.rglob("checkpoint.npz")) == [
        "clean_case/running/checkpoint.npz", "clean_case/stopped/checkpoint.npz",
        "planted_case/complete/checkpoint.npz"]        # an interrupted entry's runs keep theirs


#: a report of three stand-in entries, run in a subprocess: python work (a), a run whose own
#: window records a signal and finishes (b), and a run that sleeps before its drive window and
#: then steps with a checkpoint (c); argv: the folder and the route (cli or library)
_SIGNALLED = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    from runkit.run import Checkpoint, Interrupts, drive
    from validation import report
    from validation.__main__ import main
    from validation.framework import Entry, Verdict

    class Clock:
        t, t_end, steps = 0.0, 1.2, 0
        def advance(self):
            time.sleep(0.01)
            self.t, self.steps = self.t + 0.01, self.steps + 1
        def state(self):
            return {"t": self.t}

    def python_work(out, quick):
        time.sleep(0.3)
        return Verdict("c", "m", True)

    def finishes_after_a_signal(out, quick):
        with Interrupts(defer=True):
            time.sleep(0.4)
        return Verdict("c", "m", True)

    def driven(out, quick):
        time.sleep(0.3)                       # before the run's drive window
        drive(Clock(), checkpoint=Checkpoint(Path(out) / "checkpoint.npz", {}), every=1e9)
        return Verdict("c", "m", True)

    reg = {n: Entry("case", "rheology", n, n, f) for n, f in (
        ("a_python", python_work), ("b_window", finishes_after_a_signal), ("c_drive", driven))}
    report.load_all = lambda: reg
    if sys.argv[2] == "cli":
        sys.exit(main(["report", "--out", sys.argv[1]]))
    try:
        report.write_report(sys.argv[1])
    except KeyboardInterrupt as exc:
        print(exc, file=sys.stderr)
        sys.exit(130)
""")


def test_sigterm_at_any_moment_leaves_a_strict_incomplete_report(tmp_path):
    """SIGTERM at several moments (in python work, in an entry's own window that lets its run
    finish, before and inside a run's drive window), through the CLI and the library: the
    report stops with status 130 and results.json is strict JSON naming every unfinished entry
    in ``pending``; a run stopped in its drive window keeps its checkpoint (a report killed
    before the first entry finished wrote nothing, and one called from the library died at
    a signal outside a drive window)."""
    script = tmp_path / "signalled.py"
    script.write_text(_SIGNALLED)
    names = ["a_python", "b_window", "c_drive"]
    seen = []
    for i, delay in enumerate((0.0, 0.45, 0.85, 1.5)):
        out = tmp_path / f"rep{i}"
        proc = subprocess.Popen([sys.executable, str(script), str(out),
                                 ("cli", "library")[i % 2]], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True,
                                cwd=os.path.dirname(os.path.dirname(__file__)))
        assert "a_python" in proc.stdout.readline()          # the first entry started
        time.sleep(delay)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 130, (delay, proc.returncode, err)
        assert "marked incomplete" in err and "Traceback" not in err, err
        doc = _strict(out / "results.json")
        done = [r["name"] for r in doc["entries"]]
        assert (doc["complete"], doc["status"]) == (False, "interrupted")
        assert doc["pending"] == [n for n in names if n not in done] != []
        if "c_drive" in doc["pending"] and (out / "c_drive" / "checkpoint.npz").exists():
            seen.append("in the drive window")
        seen.append(len(done))
    assert 0 in seen and "in the drive window" in seen, seen


def test_resume_reruns_changed_code_and_raised_entries_and_merges(registry, capsys, tmp_path,
                                                                  monkeypatch):
    reg, ran = registry
    _report(capsys, "--tier", "rheology", "rheometer", "--no-bench")
    assert ran == ["clean_case", "planted_case", "raising_case"]
    ran.clear()
    real = report_mod.fingerprint
    monkeypatch.setattr(report_mod, "fingerprint", lambda e, q: real(e, q) + (
        "-edited" if e.name == "planted_case" else ""))
    code, out, _ = _report(capsys, "--tier", "rheology", "rheometer", "shear1d", "--resume")
    # changed code and an entry that raised run again; entries new to the report are added
    assert ran == ["planted_case", "planted_bench", "raising_case", "undefined_bench"]
    assert "planted_case ... (again: its code changed)" in out
    assert "raising_case ... (again: it raised)" in out
    assert "planted_bench ...\n" in out and "undefined_bench ...\n" in out    # new: no note
    ran.clear()
    code, out, _ = _report(capsys, "--only", "undefined_bench", "--resume")
    assert ran == []                                 # done: kept; the rest of the report too
    doc = _strict(tmp_path / "rep" / "results.json")
    names = ["clean_case", "planted_case", "planted_bench", "raising_case", "undefined_bench"]
    assert [r["name"] for r in doc["entries"]] == names
    assert doc["kept_from_earlier_runs"] == sorted(names) and doc["complete"] is True
    assert doc["code_changed_since"] == []
    # an entry outside the selection whose code has changed since is kept and named
    monkeypatch.setattr(report_mod, "fingerprint", lambda e, q: real(e, q) + (
        "-edited" if e.name in ("planted_case", "clean_case") else ""))
    _report(capsys, "--only", "undefined_bench", "--resume")
    doc = _strict(tmp_path / "rep" / "results.json")
    assert ran == [] and doc["code_changed_since"] == ["clean_case"]
    assert "Their code has changed since for: clean_case" in (
        tmp_path / "rep" / "report.html").read_text()


@pytest.mark.parametrize("setup, words", [
    (None, ["--resume", "no report in --out 'rep'", "without --resume"]),
    ("{\"entries\": [], \"quick\": NaN}", ["--resume", "not a report", "NaN"]),
    ("[]", ["--resume", "not a report this version can resume"]),
    ("{\"entries\": [], \"quick\": true}", ["--resume", "written with --quick"]),
    ("{\"entries\": [{\"name\": \"x\"}], \"quick\": false}", ["--resume", "entry 'x' has no tier"]),
])
def test_resume_refusals_are_one_line_status_2(registry, capsys, tmp_path, setup, words):
    reg, ran = registry
    if setup is not None:
        (tmp_path / "rep").mkdir()
        (tmp_path / "rep" / "results.json").write_text(setup)
    code, out, err = _report(capsys, "--resume")
    assert code == 2 and len(err) == 1 and ran == []
    for w in words:
        assert w in err[0], (w, err[0])
    after = sorted(p.name for p in (tmp_path / "rep").iterdir()) if setup else None
    assert after == (["results.json"] if setup else None)


def test_no_slow_skips_slow_cases_at_full_size(registry, capsys, tmp_path):
    reg, ran = registry
    reg["planted_case"].slow = True
    code, out, err = _report(capsys, "--tier", "rheology", "--no-bench", "--no-slow")
    assert code == 0 and ran == ["clean_case"]
    doc = _strict(tmp_path / "rep" / "results.json")
    skipped = {r["name"]: r["skipped"] for r in doc["entries"]}
    assert skipped == {"clean_case": None, "planted_case": "slow case, run without --no-slow"}
    assert doc["quick"] is False
    code, out, err = _report(capsys, "--only", "planted_case", "--no-slow")
    assert code == 2 and "run without --no-slow" in err[0]


def test_io_json_writer_stays_strict(tmp_path):
    """runkit.io writes strict JSON: a NaN is refused unless its key is nullable."""
    from runkit.io import atomic_write_json

    with pytest.raises(RuntimeError, match=r"x\[1\] = nan is not finite"):
        atomic_write_json(tmp_path / "a.json", {"x": [1.0, NAN]})
    assert not (tmp_path / "a.json").exists()
    atomic_write_json(tmp_path / "b.json", {"x": NAN, "y": 1.0}, nullable=("x",))
    assert _strict(tmp_path / "b.json") == {"x": None, "y": 1.0}
    assert math.isfinite(_strict(tmp_path / "b.json")["y"])
