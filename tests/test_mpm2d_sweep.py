"""``mpm2d sweep`` on Dask: a 4-case sweep of a tiny scene on a 2-worker LocalCluster, resume after
a case's folder is removed, one case made to fail while the others finish."""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

from mpm2d.sweep import case_name, expand, parse_grid, run_sweep

TINY = ["cells=8,12", "periods=0.05,0.1", "ppc=1"]


def test_grid_is_the_cartesian_product():
    grid = parse_grid(["phi0=0.46,0.47,0.48,0.49,0.50", "v0=0.2,0.5"])
    cases = expand(grid)
    assert len(cases) == 10 and len({case_name(c) for c in cases}) == 10
    assert cases[0] == {"phi0": "0.46", "v0": "0.2"} and cases[-1] == {"phi0": "0.50", "v0": "0.5"}
    for bad in (["phi0"], ["phi0="], ["phi0=0.4,"], ["a=1", "a=2"]):
        with pytest.raises(ValueError):
            parse_grid(bad)


def test_sweep_resume_and_failure(tmp_path):
    import os

    out = tmp_path / "sw"
    env = dict(os.environ)
    table = run_sweep("bar", parse_grid(TINY), out, workers=2, progress=False, log=lambda m: None)
    assert dict(os.environ) == env      # the cluster leaves our environment (and numba's) alone
    assert list(table["status"]) == ["done"] * 4
    for name in table["case"]:
        hist = pd.read_csv(out / name / "history.csv")
        assert hist["time_s"].iloc[-1] > 0 and np.isfinite(hist["total_J"]).all()
        assert not (out / f"{name}.partial").exists()
    assert (out / "sweep.csv").exists()

    # resume: the complete cases are skipped, the removed one runs again
    removed = table["case"].iloc[1]
    first_history = (out / table["case"].iloc[0] / "history.csv").read_bytes()
    shutil.rmtree(out / removed)
    again = run_sweep("bar", parse_grid(TINY), out, workers=2, progress=False, log=lambda m: None)
    status = dict(zip(again["case"], again["status"]))
    assert status.pop(removed) == "done" and set(status.values()) == {"skipped"}
    assert (out / table["case"].iloc[0] / "history.csv").read_bytes() == first_history

    # a case that fails (a fixed step beyond the stability limit, refused inside the run) is
    # reported with its error while the other finishes
    bad = run_sweep("bar", parse_grid(["cells=8", "ppc=1", "periods=0.05", "dt=1e-6,1.0"]),
                    tmp_path / "fail", workers=2, progress=False, log=lambda m: None)
    st = dict(zip(bad["dt"], bad["status"]))
    assert st == {"1e-6": "done", "1.0": "failed"}
    err = bad.loc[bad["status"] == "failed", "error"].iloc[0]
    assert "stability" in err


def test_bad_input_refused_before_anything_is_written(tmp_path):
    with pytest.raises(ValueError, match="nope"):
        run_sweep("bar", parse_grid(["nope=1,2"]), tmp_path / "x", workers=1, progress=False,
                  log=lambda m: None)
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("items, words", [
    (["cells=8,8"], "--set cells: value '8' is given twice"),
    (["cells=8,12", "v0=1e-3,0.001"], "--set v0: values '1e-3' and '0.001' are the same value"),
    (["transfer=apic,APIC"], "--set transfer: values 'apic' and 'APIC' are the same value"),
])
def test_colliding_cases_name_the_key(items, words, tmp_path):
    """Two cases that are one run (or share a folder) were refused without naming the key
    (or, for apic/APIC, ran twice): the refusal names the --set key and its values, before the
    cluster starts or anything is written."""
    from mpm2d.cli import main

    out = tmp_path / "sw"
    with pytest.raises(ValueError, match=words.replace("(", r"\(")):
        run_sweep("bar", parse_grid(items), out, workers=1, progress=False, log=lambda m: None)
    assert not out.exists()
    assert main(["sweep", "bar", *sum((["--set", i] for i in items), []), "--out", str(out)]) == 2
    assert not out.exists()


def test_folder_collision_names_the_key():
    """Values that differ only in characters a folder name cannot hold share a case folder."""
    from mpm2d.sweep import check_distinct_cases

    with pytest.raises(ValueError, match="--set material: values 'a b' and 'a-b' give the same "
                                         "case folder 'material=a-b'"):
        check_distinct_cases({"material": ["a b", "a-b"]})


def test_empty_scheduler_is_refused(tmp_path):
    """--scheduler '' ran on a local cluster as if no scheduler had been given."""
    out = tmp_path / "sw"
    with pytest.raises(ValueError, match="--scheduler = '' is empty"):
        run_sweep("bar", parse_grid(["cells=8"]), out, scheduler="", progress=False,
                  log=lambda m: None)
    assert not out.exists()
