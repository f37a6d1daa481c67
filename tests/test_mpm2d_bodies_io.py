"""mpm2d rigid bodies, the driven wheel, outputs (npz, VTK), checkpoint/restart and the CLI."""

from __future__ import annotations

import json
import subprocess
import sys

import meshio
import numpy as np
import pandas as pd
import pytest

from mpm2d import Grid, LinearElastic, ParticleSet, RigidBody, Simulation, box
from mpm2d.cli import main
from mpm2d.run import run_scene
from mpm2d.scenes import bar, piston, terzaghi, wheel


def _run(setup, path, **kw):
    params = kw.pop("params", {})
    return run_scene(setup, path, params, progress=False, log=lambda m: None, **kw)


def test_prescribed_piston_gives_impact_stress_rho_c_v(tmp_path):
    _run(piston.setup, tmp_path / "p", params=dict(cells=32), vtk=False)
    r = pd.read_csv(tmp_path / "p" / "piston_result.csv").iloc[0]
    assert r["force_error"] < 0.01 and r["stress_error"] < 0.05, r


def test_free_body_falls_with_gravity_away_from_material():
    """A free rigid body far from the material follows symplectic Euler under g exactly."""
    h = 0.1
    grid = Grid(20, 40, h, boundaries=dict(xmin="free", xmax="free", ymin="free", ymax="free"))
    x, a = box((0.2, 0.2), (0.6, 0.6), h / 2)
    block = ParticleSet("block", LinearElastic(1000.0, 1e4, 1e4), x, a)
    xb, ab = box((1.2, 3.0), (1.6, 3.4), h / 2)
    body = RigidBody("rod", xb, ab, density=2700.0, velocity=(0.0, -1.0), prescribed="none")
    sim = Simulation(grid, [block], [body], gravity=(0.0, -9.81), dt=1e-3)
    y0 = body.center[1]
    n = 100
    for _ in range(n):
        sim.step()
    # v_k = -1 - k g dt, y_n = y0 + dt sum_{k=1..n} v_k
    expect = y0 + 1e-3 * sum(-1.0 - k * 9.81e-3 for k in range(1, n + 1))
    assert body.center[1] == pytest.approx(expect, rel=0, abs=1e-12)
    assert body.velocity[0] == 0.0 and body.omega == 0.0


def test_free_body_collision_conserves_momentum():
    """A free rigid body hits a free elastic block (no gravity, no walls): the total momentum of
    body and material is conserved exactly by the implicit projection, and the body slows."""
    h = 0.05
    grid = Grid(40, 10, h, boundaries=dict(xmin="free", xmax="free", ymin="periodic",
                                          ymax="periodic"))
    x, a = box((1.0, 0.0), (1.6, 0.5), h / 2)
    block = ParticleSet("block", LinearElastic(1000.0, 1e5, 1e5), x, a)
    xb, ab = box((0.6, 0.0), (0.95, 0.5), h / 2)
    body = RigidBody("ram", xb, ab, density=500.0, velocity=(2.0, 0.0), prescribed="none")
    sim = Simulation(grid, [block], [body])
    p0 = sim.momentum()
    for _ in range(150):
        sim.step()
    assert np.abs(sim.momentum() - p0).max() < 1e-12 * abs(p0[0])
    assert body.velocity[0] < 1.5 and block.v[:, 0].mean() > 0.1


def test_wheel_spins_at_the_prescribed_rate(tmp_path):
    """Elastic spokes bonded to the driven hub turn with it: their mean angular velocity about
    the hub (second half of the run) is the prescribed omega to 15 %."""
    res = _run(wheel.setup, tmp_path / "w", params=dict(
        spokes="elastic", omega=10, radius=0.1, hub_radius=0.035, spoke_width=0.04, width=0.8,
        bed_depth=0.1, height=0.45, h=0.025, t_end=0.06, frames=2), vtk=False)
    r = json.loads((tmp_path / "w" / "summary.json").read_text())["runs"]["10"]
    assert abs(r["wheel_spin_per_s"] - 10.0) < 1.5, r
    assert res["manifest"]["mode"] == "locked mixture"


def test_restart_is_bit_for_bit(tmp_path):
    """N steps == k steps + checkpoint + restart + (N - k) steps, array-equal (two-phase)."""
    params = dict(cells=8, t_end_T=0.02)
    full = _run(terzaghi.setup, tmp_path / "full", params=params, vtk=False)
    n = full["scene"].sim.step_count
    _run(terzaghi.setup, tmp_path / "part", params=params, vtk=False, stop_after_steps=n // 3)
    resumed = _run(terzaghi.setup, tmp_path / "part", resume=True, vtk=False)
    a, b = full["scene"].sim.state(), resumed["scene"].sim.state()
    assert resumed["scene"].sim.step_count == n
    assert a.keys() == b.keys()
    for k in a:
        assert np.array_equal(a[k], b[k]), k


def test_snapshots_manifest_and_vtu(tmp_path):
    res = _run(bar.setup, tmp_path / "b", params=dict(cells=8, periods=0.5), frames=3)
    man = json.loads((tmp_path / "b" / "manifest.json").read_text())
    assert man["status"] == "complete" and man["mode"] == "single phase"
    assert len(man["frames"]) >= 4 and man["frames"][-1]["step"] == res["scene"].sim.step_count
    last = man["frames"][-1]
    snap = np.load(tmp_path / "b" / last["npz"])
    vtu = meshio.read(tmp_path / "b" / last["vtu"]["bar"])
    assert np.array_equal(vtu.points[:, :2], snap["bar.x"])
    assert np.array_equal(vtu.point_data["stress_Pa"].reshape(-1, 3, 3), snap["bar.stress"])
    assert np.array_equal(vtu.point_data["velocity_m_per_s"][:, :2], snap["bar.v"])
    assert (tmp_path / "b" / "vtk" / "bar.pvd").exists()
    hist = pd.read_csv(tmp_path / "b" / "history.csv")
    assert {"time_s", "kinetic_J", "strain_J", "total_J"} <= set(hist.columns)


@pytest.mark.parametrize("argv, message", [
    (["run", "nosuchscene"], "unknown scene"),
    (["run", "bar", "--set", "cellz=4"], "unknown parameter 'cellz'"),
    (["run", "bar", "--set", "cells=four"], "cells = 'four' is not an integer"),
    (["run", "bar", "--set", "E=-1"], "E = -1 is outside the valid range"),
    (["run", "bar", "--set", "dt=1"], "dt = 1 s exceeds the stability limit"),
    (["run", "bar", "--resume", "--out", "/nonexistent/x"], "no checkpoint"),
])
def test_cli_bad_input_is_one_line(argv, message, capsys, tmp_path):
    if "--out" not in argv:
        argv = argv + ["--out", str(tmp_path / "o")]
    assert main(argv + ["--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mpm2d run: error: ") and message in err[0], err


def test_cli_list_and_run(tmp_path):
    out = subprocess.run([sys.executable, "-m", "mpm2d.cli", "list"], capture_output=True,
                         text=True, check=True).stdout
    for name in ("bar", "disks", "terzaghi", "column", "cylinder", "couette", "shear"):
        assert name in out
    assert main(["run", "bar", "--set", "cells=8", "--set", "periods=0.25", "--out",
                 str(tmp_path / "bar"), "--quiet", "--no-vtk"]) == 0
    assert (tmp_path / "bar" / "bar.png").exists()
