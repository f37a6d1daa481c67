"""A scene file of the user's runs by path like a built-in scene: ``mpm2d show FILE`` and
``mpm2d run FILE`` with the shipped example (an elastic column settling under gravity, whose
mean and largest sink are exact), and the refusals of a file that is not a scene."""

import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

import mpm2d
from mpm2d.cli import main

EXAMPLE = Path(mpm2d.__file__).parent / "examples" / "elastic_column.py"


def test_show_prints_the_files_docstring_and_parameters(capsys):
    assert main(["show", str(EXAMPLE)]) == 0
    out = capsys.readouterr().out
    assert "elastic column settling under its own weight" in out
    assert "cells = 16" in out and "valid: integer in [4, 4096]" in out


def test_run_by_path_gives_the_exact_mean_and_largest_sink(tmp_path):
    """Over whole periods of the first mode every mode of the fixed-free column completes
    whole cycles: the mean sink of the centre of mass is the static rho g H^2/(3M); at T/2
    every mode is at its extreme: twice that. 2 x 2 points per cell, 32 cells: within 1%."""
    out = tmp_path / "col"
    r = subprocess.run([sys.executable, "-m", "mpm2d.cli", "run", str(EXAMPLE), "--set",
                        "cells=32", "--out", str(out), "--no-vtk"], capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr
    assert "run size: 256 points" in r.stdout
    res = pd.read_csv(out / "column_result.csv").iloc[0]
    assert res["mean_over_static"] == pytest.approx(1.0, abs=0.01)
    assert res["max_over_static"] == pytest.approx(2.0, abs=0.02)
    assert (out / "column.png").stat().st_size > 10_000
    assert "elastic_column.py" in (out / "manifest.json").read_text()


def test_a_relative_path_defaults_the_output_folder_to_its_stem(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "my_scene.py").write_text(EXAMPLE.read_text())
    assert main(["run", "my_scene.py", "--set", "cells=8", "--set", "periods=1", "--quiet",
                 "--no-vtk"]) == 0
    assert (tmp_path / "my_scene" / "column_result.csv").exists()


@pytest.mark.parametrize("text, words", [
    (None, "does not exist"),
    ("x = (", "could not be imported: SyntaxError"),
    ("def setup(a=1):\n    return None\n", "has no setup(**params) declared"),
])
def test_a_file_that_is_not_a_scene_is_refused_in_one_line(tmp_path, capsys, text, words):
    path = tmp_path / "not_a_scene.py"
    if text is not None:
        path.write_text(text)
    out = tmp_path / "never"
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not out.exists()


def test_bad_set_on_a_scene_file_names_the_parameter(tmp_path, capsys):
    assert main(["run", str(EXAMPLE), "--set", "cells=2", "--out", str(tmp_path / "n"),
                 "--quiet"]) == 2
    assert "cells = 2" in capsys.readouterr().err
