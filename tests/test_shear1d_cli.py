"""The shear1d command line end to end on tiny grids, and its handling of bad input."""

import json
import subprocess
import sys

import pandas as pd
import pytest

from shear1d.cli import main


def test_annular_command_writes_csv_json_png(tmp_path):
    out = tmp_path / "run"
    assert main(["annular", "--u-inner", "0.084", "--cells", "20", "--outputs", "62",
                 "--mode", "locked", "--out", str(out)]) == 0
    tag = "u84mm_s_locked"
    for name in (f"{tag}_velocity_profiles.csv", f"{tag}_cell_profiles.csv", f"{tag}_front.csv",
                 f"{tag}_fields.csv", f"{tag}_summary.json", f"{tag}_fields.png",
                 "velocity_profiles.png", "front_position.png"):
        assert (out / name).stat().st_size > 0, name
    prof = pd.read_csv(out / f"{tag}_velocity_profiles.csv")
    assert {"rotation_rad", "r_m", "v_over_u_inner", "v_over_omega_r"} <= set(prof.columns)
    assert sorted(prof["rotation_rad"].round(3).unique()) == [0.0, 0.1, 0.2, 0.31]
    s = json.loads((out / f"{tag}_summary.json").read_text())
    assert s["front_speed_m_per_s"] > 0 and s["front_fit_r2"] > 0.9
    assert not list(out.glob("*.checkpoint.npz"))


def test_couette_command(tmp_path):
    assert main(["couette", "--speed", "0.01", "--cells", "10", "--time", "0.2", "--outputs", "10",
                 "--out", str(tmp_path)]) == 0
    wall = pd.read_csv(tmp_path / "couette_wall.csv")
    assert wall["wall_shear_stress_Pa"].iloc[-1] > 0
    assert (tmp_path / "couette.png").stat().st_size > 0


@pytest.mark.parametrize("args, word", [
    (["annular", "--u-inner", "-1"], "u_inner"),
    (["annular", "--u-inner", "abc"], "invalid float"),
    (["annular", "--mode", "drained"], "--mode"),
    (["annular", "--cells", "2"], "n_cells"),
    (["annular", "--u-inner", "0.084", "--method", "explicit", "--dt", "1"], "stability"),
    (["couette", "--speed", "0.01", "--stress", "2"], "not allowed"),
    (["bogus"], "invalid choice"),
])
def test_bad_input_exits_nonzero_with_one_line(tmp_path, args, word):
    proc = subprocess.run([sys.executable, "-m", "shear1d", *args, "--out", str(tmp_path)]
                          if args[0] != "bogus" else [sys.executable, "-m", "shear1d", *args],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode != 0
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr and word in lines[0], lines[0]
