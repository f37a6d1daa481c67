"""``python -m validation report``: bad input is refused in one line with status 2 before anything
is written; a selection with nothing to run is refused, not reported as success; ``--quick``
skips the slow cases (their criteria hold at full size only) and says so; the summary names only
files that were written.

Run in-process through ``validation.__main__.main``. The runs that reach the execution use a small
registry of stand-in entries (``validation.report.load_all`` replaced), or the cheapest real case
(fig10_steady_structure, ~0.3 s).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from validation import report as report_mod
from validation.__main__ import build_parser, main
from validation.framework import TIERS, Entry, Verdict


def _run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err.splitlines()


def _refused(argv, capsys, *words):
    """Status 2, exactly one stderr line that contains every word; returns the line."""
    code, out, err = _run(argv, capsys)
    assert code == 2, (code, out, err)
    assert len(err) == 1, err
    assert "Traceback" not in err[0]
    for w in words:
        assert w in err[0], (w, err[0])
    return err[0]


@pytest.fixture
def in_tmp(tmp_path, monkeypatch):
    """Work in an empty folder; the tests check it is still empty after a refusal."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _nothing_written(folder: Path, *keep):
    assert sorted(p.name for p in folder.iterdir()) == sorted(keep)


# ---------------------------------------------------------------- --out (faults 3, 4)
@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs /proc")
def test_out_unwritable_refused(in_tmp, capsys):
    _refused(["report", "--only", "fig10_steady_structure", "--out", "/proc/x"], capsys,
             "--out", "'/proc/x'", "cannot write")
    assert not os.path.exists("/proc/x")
    _nothing_written(in_tmp)


def test_out_existing_file_refused(in_tmp, capsys):
    f = in_tmp / "somefile"
    f.write_text("keep me\n")
    _refused(["report", "--only", "fig10_steady_structure", "--out", str(f)], capsys,
             "--out", str(f), "not a folder")
    assert f.read_text() == "keep me\n"
    _nothing_written(in_tmp, "somefile")


def test_out_below_a_file_refused(in_tmp, capsys):
    (in_tmp / "somefile").write_text("")
    _refused(["report", "--only", "fig10_steady_structure", "--out", "somefile/rep"], capsys,
             "--out", "somefile/rep", "is a file")
    _nothing_written(in_tmp, "somefile")


def test_out_empty_refused(in_tmp, capsys):
    _refused(["report", "--only", "fig10_steady_structure", "--out", ""], capsys, "--out", "''")
    _nothing_written(in_tmp)


# ---------------------------------------------------------------- --tier (fault 5)
@pytest.mark.parametrize("extra", [["--out", "tq"], ["--only", "fig10_steady_structure"]])
def test_unknown_tier_refused_with_the_valid_tiers(in_tmp, capsys, extra):
    _refused(["report", "--tier", "nosuch", *extra], capsys, "--tier", "nosuch",
             ", ".join(TIERS))
    _nothing_written(in_tmp)


def test_tier_without_names_refused(in_tmp, capsys):
    _refused(["report", "--tier", "--out", "tq"], capsys, "--tier", ", ".join(TIERS))
    _nothing_written(in_tmp)


def test_selection_matching_nothing_refused(in_tmp, capsys):
    """A name outside the chosen tier, or a benchmark with --no-bench: nothing would run."""
    _refused(["report", "--tier", "mpm2d", "--only", "fig10_steady_structure", "--out", "r"],
             capsys, "--only", "fig10_steady_structure", "--tier mpm2d")
    _refused(["report", "--only", "bench_fit_speed", "--no-bench", "--out", "r"], capsys,
             "--only", "bench_fit_speed", "--no-bench")
    _nothing_written(in_tmp)


# ---------------------------------------------------------------- --only (fault 6)
def test_only_without_names_refused(in_tmp, capsys):
    _refused(["report", "--only", "--out", "rep", "--quick", "--no-bench"], capsys, "--only",
             "no names")
    _nothing_written(in_tmp)


def test_only_unknown_name_refused_with_the_valid_names(in_tmp, capsys):
    line = _refused(["report", "--only", "fig10_steady_structure", "nosuch", "--out", "rep"],
                    capsys, "--only", "'nosuch'", "valid:")
    valid = line.split("valid:", 1)[1]
    assert "fig10_steady_structure" in valid and "mpm2d_speed" in valid
    _nothing_written(in_tmp)


# ---------------------------------------------------------------- --quick (fault 7)
def test_quick_with_a_named_slow_case_refused(in_tmp, capsys):
    from validation.framework import load_all

    slow = sorted(e.name for e in load_all().values() if e.kind == "case" and e.slow)
    assert "impact_fig4_paper" in slow
    _refused(["report", "--only", "fig10_steady_structure", "impact_fig4_paper", "--quick",
              "--out", "rep"], capsys, "--only", "impact_fig4_paper", "--quick")
    _nothing_written(in_tmp)


def test_quick_help_states_the_rule():
    sub = next(a for a in build_parser()._actions if a.dest == "cmd").choices["report"]
    text = " ".join(sub.format_help().split())
    assert "skipped" in text and "refused" in text and "slow" in text


@pytest.fixture
def fake_registry(monkeypatch):
    """Three stand-in entries: a fast case, a slow case, a benchmark; records what ran."""
    ran = []

    def make(name, passed=True, interrupt=False):
        def func(out, quick):
            ran.append((name, quick))
            if interrupt:
                raise KeyboardInterrupt
            return Verdict(criterion=f"{name} criterion", measured=f"{name} measured",
                           passed=passed)
        return func

    reg = {"fast_one": Entry("case", "rheology", "fast_one", "fast", make("fast_one")),
           "slow_one": Entry("case", "rheology", "slow_one", "slow", make("slow_one"), True),
           "failing_one": Entry("case", "rheometer", "failing_one", "fails",
                                make("failing_one", passed=False)),
           "stop_one": Entry("case", "shear1d", "stop_one", "Ctrl-C",
                             make("stop_one", interrupt=True))}
    monkeypatch.setattr(report_mod, "load_all", lambda: reg)
    return ran


def test_quick_skips_slow_cases_and_says_so(in_tmp, capsys, fake_registry):
    code, out, err = _run(["report", "--tier", "rheology", "--quick", "--out", "rep"], capsys)
    assert code == 0, (out, err)
    assert fake_registry == [("fast_one", True)]            # the slow case never ran
    assert "slow_one: skipped: slow case, run without --quick" in out
    last = out.strip().splitlines()[-1]
    assert "1/1 pass" in last and "skipped 1" in last and "slow_one" in last
    page = (in_tmp / "rep" / "report.html").read_text()
    assert "SKIPPED" in page and "slow_one" in page and "run without --quick" in page
    rows = {r["name"]: r
            for r in json.loads((in_tmp / "rep" / "results.json").read_text())["entries"]}
    assert rows["fast_one"]["passed"] is True and rows["fast_one"]["skipped"] is None
    assert rows["slow_one"]["passed"] is None
    assert rows["slow_one"]["skipped"] == "slow case, run without --quick"
    assert not (in_tmp / "rep" / "slow_one").exists()


def test_without_quick_slow_cases_run(in_tmp, capsys, fake_registry):
    code, out, _ = _run(["report", "--tier", "rheology", "--out", "rep"], capsys)
    assert code == 0
    assert sorted(fake_registry) == [("fast_one", False), ("slow_one", False)]
    assert "skipped" not in out


def test_quick_with_only_slow_cases_selected_refused(in_tmp, capsys, fake_registry, monkeypatch):
    reg = report_mod.load_all()
    monkeypatch.setattr(report_mod, "load_all", lambda: {"slow_one": reg["slow_one"]})
    _refused(["report", "--quick", "--out", "rep"], capsys, "--quick", "slow")
    assert fake_registry == []
    _nothing_written(in_tmp)


def test_failure_is_status_1_and_named(in_tmp, capsys, fake_registry):
    code, out, _ = _run(["report", "--tier", "rheometer", "--out", "rep"], capsys)
    assert code == 1
    assert "FAIL failing_one: criterion failing_one criterion; measured failing_one measured" in out
    assert (in_tmp / "rep" / "report.html").exists()


def test_interrupt_says_what_was_written(in_tmp, capsys, fake_registry):
    code, out, err = _run(["report", "--tier", "rheology", "shear1d", "--out", "rep"], capsys)
    assert code == 130
    assert len(err) == 1 and "interrupted" in err[0]
    assert "2 of 3 selected entries finished, marked incomplete" in err[0] and "--resume" in err[0]
    doc = json.loads((in_tmp / "rep" / "results.json").read_text())
    assert (doc["complete"], doc["status"], doc["pending"]) == (False, "interrupted", ["stop_one"])
    assert [r["name"] for r in doc["entries"]] == ["fast_one", "slow_one"]
    assert "INCOMPLETE" in (in_tmp / "rep" / "report.html").read_text()


# ---------------------------------------------------------------- a real (cheap) run
def test_real_case_writes_what_it_claims(in_tmp, capsys):
    code, out, err = _run(["report", "--only", "fig10_steady_structure", "--quick", "--out",
                           "rep"], capsys)
    assert code == 0, (out, err)
    last = out.strip().splitlines()[-1]
    assert last.startswith(f"wrote {Path('rep') / 'report.html'} and results.json: 1/1 pass")
    doc = json.loads((in_tmp / "rep" / "results.json").read_text())
    assert doc["complete"] is True and doc["status"] == "complete"
    assert [(r["name"], r["passed"]) for r in doc["entries"]] == [("fig10_steady_structure", True)]
    assert "fig10_steady_structure" in (in_tmp / "rep" / "report.html").read_text()


def test_real_mpm2d_case_leaves_no_checkpoint_of_its_completed_runs(in_tmp, capsys):
    """mpm2d_piston's runs complete: their folders keep no checkpoint (they used to keep
    checkpoint.npz); every one of them says complete."""
    code, out, err = _run(["report", "--only", "mpm2d_piston", "--quick", "--out", "rep"],
                          capsys)
    assert code == 0, (out, err)
    manifests = list((in_tmp / "rep").rglob("manifest.json"))
    assert manifests and all(json.loads(m.read_text())["status"] == "complete"
                             for m in manifests)
    assert not list((in_tmp / "rep").rglob("checkpoint*.npz"))


def test_list_marks_slow_cases(capsys):
    assert main(["list"]) == 0
    lines = {ln.split()[2]: ln for ln in capsys.readouterr().out.splitlines()}
    assert lines["impact_fig4_paper"].split()[3] == "slow"
    assert lines["fig10_steady_structure"].split()[3] != "slow"


def test_list_out_writes_the_list_atomically_in_each_format(in_tmp, capsys):
    assert main(["list"]) == 0
    printed = capsys.readouterr().out
    for fmt in ("txt", "csv", "json"):
        code, out, err = _run(["list", "--out", f"sub/cases.{fmt}"], capsys)
        assert code == 0 and err == [] and out.startswith(f"wrote {Path('sub') / f'cases.{fmt}'}")
    assert (in_tmp / "sub" / "cases.txt").read_text() == printed
    rows = json.loads((in_tmp / "sub" / "cases.json").read_text())
    assert [r["name"] for r in rows] == [ln.split()[2] for ln in printed.splitlines()]
    assert {r["name"]: r["slow"] for r in rows}["impact_fig4_paper"] is True
    csv = (in_tmp / "sub" / "cases.csv").read_text().splitlines()
    assert csv[0] == "tier,kind,name,slow,title" and len(csv) == len(rows) + 1
    assert sorted(p.name for p in (in_tmp / "sub").iterdir()) == [
        "cases.csv", "cases.json", "cases.txt"]                  # no temporary left


@pytest.mark.parametrize("path, words", [
    ("cases.xyz", ("--out = 'cases.xyz'", "format 'xyz' is not one of txt, csv, json")),
    ("", ("--out = ''", "not one of txt, csv, json")),
    ("folder/", ("--out = 'folder/'", "names a folder")),
    ("afile/cases.txt", ("--out = 'afile/cases.txt'", "is a file, not a folder"))])
def test_list_out_bad_paths_refused_before_anything_is_written(in_tmp, capsys, path, words):
    (in_tmp / "afile").write_text("x")
    _refused(["list", "--out", path], capsys, *words)
    _nothing_written(in_tmp, "afile")
