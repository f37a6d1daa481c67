"""mpm2d runner: resume is byte-exact (every file, runs stopped twice, a real SIGTERM), resume of
another scene or other parameters refused by name, corrupt checkpoints, typed history, no
temporary files left, VTK read back with meshio (points and the grid's nodal fields), .pvd
collections without repeated timesteps."""

from __future__ import annotations

import inspect
import json
import re
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import meshio
import numpy as np
import pandas as pd
import pytest

from mpm2d.cli import main
from mpm2d.output import grid_fields
from mpm2d.run import run_scene
from mpm2d.scenes import bar, terzaghi

TERZ = dict(cells=8, t_end_T=0.05)         # two-phase, ~250 steps, 5 event frames


def _run(setup, path, **kw):
    kw.setdefault("progress", False)
    return run_scene(setup, path, kw.pop("params", {}), log=lambda m: None, **kw)


def _files(folder: Path) -> dict[str, Path]:
    return {str(p.relative_to(folder)): p for p in sorted(folder.rglob("*")) if p.is_file()}


def _checkpoint_arrays(path):
    with np.load(path, allow_pickle=False) as d:
        return {k: d[k] for k in d.files}


def assert_same_run(full: Path, resumed: Path) -> int:
    """Every file of ``resumed`` equals ``full``'s byte for byte (the checkpoints array for
    array, with dtypes); no file is missing or extra except ``checkpoint.prev.npz`` (the kept
    predecessor) and no temporary file exists. Returns the number of byte-identical files."""
    a, b = _files(full), _files(resumed)
    extra = set(b) - set(a) - {"checkpoint.prev.npz"}
    missing = set(a) - set(b) - {"checkpoint.prev.npz"}
    assert not extra and not missing, (extra, missing)
    assert not [f for f in b if Path(f).name.startswith(".")], "temporary files left"
    same = 0
    for name, path in a.items():
        if name.startswith("checkpoint"):
            ca, cb = _checkpoint_arrays(path), _checkpoint_arrays(b[name])
            assert ca.keys() == cb.keys()
            for k in ca:
                assert ca[k].dtype == cb[k].dtype and np.array_equal(ca[k], cb[k]), (name, k)
            continue
        assert path.read_bytes() == b[name].read_bytes(), name
        same += 1
    return same


def test_resume_twice_is_byte_identical(tmp_path):
    """Stopped after 1/3 and after 2/3 of the steps, resumed twice: every file identical."""
    full = _run(terzaghi.setup, tmp_path / "full", params=TERZ, frames=4)
    n = full["scene"].sim.step_count
    part = tmp_path / "part"
    _run(terzaghi.setup, part, params=TERZ, frames=4, stop_after_steps=n // 3)
    _run(terzaghi.setup, part, resume=True, stop_after_steps=n // 3)
    res = _run(terzaghi.setup, part, resume=True)
    assert res["complete"] and res["scene"].sim.step_count == n
    count = assert_same_run(tmp_path / "full", part)
    # 5 frames x (npz + vtu of 2 sets + grid) + 3 pvds + history, manifest, result csv, png
    assert count == 27, count
    hist = pd.read_csv(part / "history.csv")
    assert hist["step"].dtype.kind == "i"
    assert json.loads((part / "manifest.json").read_text())["status"] == "complete"


def test_signal_inside_a_step_is_deferred(tmp_path):
    """SIGTERM at a random moment of the run (in-process, from a timer thread): the run stops
    after the current step with a checkpoint, and the resumed run equals the uninterrupted one
    (a signal raised inside a step used to leave the state half-updated: 1e-5 relative drift)."""
    params = dict(cells=8, t_end_T=0.1)
    full = _run(terzaghi.setup, tmp_path / "full", params=params, vtk=False)
    wall = full["scene"].sim.timings
    total = sum(wall.values())
    part = tmp_path / "part"
    for frac in (0.3, 0.3):
        timer = threading.Timer(frac * total, os.kill, (os.getpid(), signal.SIGTERM))
        timer.start()
        try:
            with pytest.raises(KeyboardInterrupt):
                _run(terzaghi.setup, part, params=params, vtk=False,
                     resume=(part / "checkpoint.npz").exists())
        finally:
            timer.cancel()
    _run(terzaghi.setup, part, resume=True, vtk=False)
    assert assert_same_run(tmp_path / "full", part) > 10


@pytest.mark.slow
def test_real_sigterm_twice_terzaghi_cli(tmp_path):
    """``mpm2d run terzaghi --out t``, SIGTERM twice (real signals to a subprocess, each 1-2 s
    into the stepping), then ``--resume``: every file equals the uninterrupted run's."""
    cmd = [sys.executable, "-m", "mpm2d.cli", "run", "terzaghi", "--quiet", "--out"]
    subprocess.run(cmd + [str(tmp_path / "full")], check=True, capture_output=True)
    out = tmp_path / "t"
    for k, delay in enumerate((1.0, 2.0)):
        proc = subprocess.Popen(cmd + [str(out)] + (["--resume"] if k else []),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for line in proc.stdout:                 # the run loop starts after the "mode:" line
            if line.startswith("mode:"):
                break
        time.sleep(delay)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=300)
        assert proc.returncode == 130, err
        assert "checkpoint written" in err and "--resume" in err
    proc = subprocess.run(cmd + [str(out), "--resume"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "resumed from" in proc.stdout
    assert assert_same_run(tmp_path / "full", out) > 40


def test_resume_of_another_scene_or_parameters_is_refused(tmp_path, capsys):
    out = str(tmp_path / "o")
    assert main(["run", "bar", "--set", "periods=0.05", "--set", "cells=8", "--out", out,
                 "--quiet", "--no-vtk"]) == 0
    before = {k: p.read_bytes() for k, p in _files(Path(out)).items()}
    capsys.readouterr()
    for argv, words in ((["run", "disks", "--resume"], "of scene 'bar', not 'disks'"),
                        (["run", "bar", "--resume", "--set", "cells=16"],
                         "cells = 16 differs from the checkpoint's cells = 8"),
                        (["run", "bar", "--resume", "--frames", "3"], "--frames 3 differs")):
        assert main(argv + ["--out", out, "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err
    assert {k: p.read_bytes() for k, p in _files(Path(out)).items()} == before


def test_corrupt_checkpoint_is_named_and_the_previous_one_used(tmp_path, capsys):
    out = tmp_path / "o"
    params = dict(cells=8, periods=0.2)
    full = _run(bar.setup, tmp_path / "full", params=params, vtk=False)
    n = full["scene"].sim.step_count
    _run(bar.setup, out, params=params, vtk=False, stop_after_steps=n // 4)
    _run(bar.setup, out, resume=True, vtk=False, stop_after_steps=n // 4)
    (out / "checkpoint.npz").write_bytes(b"garbage, not a zip file")
    logs = []
    res = run_scene(bar.setup, out, {}, resume=True, vtk=False, progress=False, log=logs.append)
    assert any("checkpoint.npz is corrupt" in m and "previous checkpoint" in m for m in logs)
    assert res["complete"] and res["scene"].sim.step_count == n
    assert assert_same_run(tmp_path / "full", out) > 5
    # both corrupt: refused with one line naming the file
    (out / "checkpoint.npz").write_bytes(b"x")
    (out / "checkpoint.prev.npz").write_bytes(b"y")
    assert main(["run", "bar", "--resume", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "corrupt" in err[0] and "checkpoint.npz" in err[0], err


def test_stale_temporary_files_are_removed(tmp_path):
    """A killed write (SIGKILL) can leave ``.NAME.XXXXXXXX.npz``; the next run removes it."""
    out = tmp_path / "o"
    _run(bar.setup, out, params=dict(cells=8, periods=0.1), vtk=False, stop_after_steps=5)
    (out / ".checkpoint.npz.ab12cd_9.npz").write_bytes(b"partial")
    (out / "frames" / ".frame_00001.npz.zz99yy00.npz").write_bytes(b"partial")
    _run(bar.setup, out, resume=True, vtk=False)
    assert not [p for p in out.rglob(".*") if p.is_file()]


def test_vtk_read_back_with_meshio_and_pvd_unique(tmp_path):
    """Points and fields of the .vtu equal the npz snapshot; the grid file carries the nodal
    fields (two-phase: both velocity fields, nodal phi, projected pore pressure) on (nx+1)(ny+1)
    nodes; each .pvd lists every timestep once, although event and regular frames coincide."""
    res = _run(terzaghi.setup, tmp_path / "t", params=dict(cells=8, t_end_T=0.2))
    sim = res["scene"].sim
    out = tmp_path / "t"
    man = json.loads((out / "manifest.json").read_text())
    last = man["frames"][-1]
    with np.load(out / last["npz"]) as snap:
        mesh = meshio.read(out / last["vtu"]["grains"])
        assert np.array_equal(mesh.points[:, :2], snap["grains.x"])
        assert np.array_equal(mesh.point_data["stress_Pa"].reshape(-1, 3, 3),
                              snap["grains.stress"])
        assert np.array_equal(mesh.point_data["velocity_m_per_s"][:, :2], snap["grains.v"])
        assert np.all(mesh.point_data["velocity_m_per_s"][:, 2] == 0.0)
    grid = meshio.read(out / last["vtu"]["grid"])
    g = sim.grid
    assert grid.points.shape == ((g.nx + 1) * (g.ny + 1), 3)
    assert grid.cells_dict["quad"].shape == (g.nx * g.ny, 4)
    for key in ("solid.velocity_m_per_s", "fluid.velocity_m_per_s", "solid.mass_kg_per_m",
                "phi", "fluid.pore_pressure_Pa"):
        assert key in grid.point_data, sorted(grid.point_data)
    nodal = grid_fields(sim)
    assert np.array_equal(grid.point_data["phi"], nodal["phi"].ravel())
    # the projected pore pressure is a mass-weighted average of the points' values: within
    # their range wherever a point reaches the node
    pf = sim.sets[1].pf
    proj = nodal["fluid.pore_pressure_Pa"]
    ok = np.isfinite(proj)
    assert ok.sum() > 0.5 * proj.size
    assert proj[ok].min() >= pf.min() - 1e-9 * abs(pf).max()
    assert proj[ok].max() <= pf.max() + 1e-9 * abs(pf).max()
    for pvd in (out / "vtk").glob("*.pvd"):
        text = pvd.read_text()
        steps = [s.split('"')[1] for s in text.split("timestep=")[1:]]
        assert len(steps) == len(set(steps)) >= 2, pvd.name
    events = [f for f in man["frames"] if f["tag"] == "event"]
    assert len(events) == 2                      # T = 0.1, 0.2 (each also a regular frame time)
    assert len({f["step"] for f in man["frames"]}) == len(man["frames"])


def test_history_step_column_is_integer_after_resume(tmp_path):
    out = tmp_path / "o"
    _run(bar.setup, out, params=dict(cells=8, periods=0.1), vtk=False, stop_after_steps=7)
    _run(bar.setup, out, resume=True, vtk=False)
    lines = (out / "history.csv").read_text().splitlines()
    col = lines[0].split(",").index("step")
    steps = [r.split(",")[col] for r in lines[1:]]
    assert all(s.isdigit() for s in steps), steps[:5]
    assert [int(s) for s in steps] == sorted(int(s) for s in steps)


def test_signal_during_set_up_stops_at_once_and_writes_nothing(tmp_path, monkeypatch):
    """The set-up (a bed's geostatic relaxation) is not deferred: a Ctrl-C/SIGTERM there stops
    the run at once with the reason, and no output folder is created; a resume's set-up
    interrupted the same way leaves the checkpoint as it was."""
    from mpm2d.scenes import rod_drop

    calls = []

    def interrupted(*a, **k):
        calls.append(1)
        raise KeyboardInterrupt

    small = dict(radius=0.02, depth=0.02, cells_per_mm=0.5, t_end=0.001)
    monkeypatch.setattr(rod_drop, "geostatic", interrupted)
    out = tmp_path / "o"
    with pytest.raises(KeyboardInterrupt, match="set-up, nothing written"):
        _run(rod_drop.setup, out, params=small)
    assert calls and not out.exists()
    monkeypatch.undo()
    _run(rod_drop.setup, out, params=small, stop_after_steps=3)
    before = {k: p.read_bytes() for k, p in _files(out).items()}
    monkeypatch.setattr(rod_drop, "geostatic", interrupted)
    with pytest.raises(KeyboardInterrupt, match="checkpoint.npz is as it was"):
        _run(rod_drop.setup, out, params=small, resume=True)
    assert {k: p.read_bytes() for k, p in _files(out).items()} == before


def test_set_without_a_value_and_resume_of_a_default_are_refused_by_name(tmp_path, capsys):
    """``--set v0=`` is refused (not taken as the default) by run as by sweep; a resume that sets
    an optional parameter whose checkpoint value is the default says 'none (the scene's
    default)', not 'None'."""
    out = tmp_path / "o"
    for cmd in ("run", "sweep"):
        assert main([cmd, "bar", "--set", "rho=", "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "'rho='" in err[0] and "empty" in err[0], err
        assert not out.exists()
    assert main(["run", "bar", "--set", "periods=0.05", "--set", "cells=8", "--out", str(out),
                 "--quiet", "--no-vtk"]) == 0
    capsys.readouterr()
    assert main(["run", "bar", "--resume", "--set", "dt=1e-5", "--out", str(out),
                 "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "checkpoint's dt = none (the scene's default)" in err[0], err


def test_fresh_run_into_an_old_run_folder_leaves_none_of_its_snapshots(tmp_path):
    """A new run (no --resume) into the folder of an earlier one with more frames: the earlier
    snapshots, VTK files and checkpoints are removed, so the folder holds one run (the manifest's
    frames are exactly the files present)."""
    out = tmp_path / "o"
    _run(bar.setup, out, params=dict(cells=8, periods=0.1), frames=8)
    assert len(list((out / "frames").glob("frame_*.npz"))) >= 8
    res = _run(bar.setup, out, params=dict(cells=8, periods=0.05), frames=2)
    listed = {Path(f["npz"]).name for f in res["manifest"]["frames"]}
    assert {p.name for p in (out / "frames").glob("frame_*.npz")} == listed
    vtus = {p.name for p in (out / "vtk").glob("*.vtu")}
    assert all(any(f"_{int(Path(n).stem.split('_')[1]):05d}" in v for n in listed) for v in vtus)


def test_signal_while_the_last_files_are_written_completes_the_run(tmp_path, monkeypatch):
    """A SIGTERM that arrives after the last step, while the report, manifest and final
    checkpoint are written (it used to reach the command as 'interrupted', exit 130, though every
    file was complete): the run finishes, says so, and its files equal an undisturbed run's."""
    from mpm2d.output import RunFolder

    params = dict(cells=8, t_end_T=0.05)
    _run(terzaghi.setup, tmp_path / "full", params=params, vtk=False)
    real, sent = RunFolder.write_manifest, []

    def manifest_then_signal(folder, *args, **kwargs):
        path = real(folder, *args, **kwargs)
        if folder.manifest.get("status") == "complete" and not sent:
            sent.append(1)
            os.kill(os.getpid(), signal.SIGTERM)
        return path

    monkeypatch.setattr(RunFolder, "write_manifest", manifest_then_signal)
    lines = []
    res = run_scene(terzaghi.setup, tmp_path / "late", params, progress=False, vtk=False,
                    log=lines.append)
    assert sent and res["complete"]
    assert "SIGTERM received after the last step: every output is complete" in lines[-1]
    assert assert_same_run(tmp_path / "full", tmp_path / "late") > 5


def test_a_run_that_would_never_end_is_refused_up_front(tmp_path, capsys):
    """cfl = 1e-300 passed the range check (0, 1] and ran for ever (found by a fresh-user test);
    its refusal then stated a bound that moved with the other values. cfl's range is the stated
    limit [0.01, 1] (the explicit step's stability limit; below 1% of the stable step no
    accuracy is gained): one line naming cfl, its value, the range and the reason, exit 2,
    nothing written; the bound itself runs."""
    out = tmp_path / "o"
    assert main(["run", "column", "--set", "cfl=1e-300", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cfl = 1e-300 is outside the valid range [0.01, 1] (a step below " \
        "1% of the stable one gains no accuracy" in err[0], err
    assert not out.exists()
    from mpm2d.run import MAX_STEPS, _first_step
    from mpm2d.scenes import column
    assert _first_step(column.setup(cfl=0.01))[1] <= MAX_STEPS


def test_a_grain_size_below_its_physical_limit_is_refused_with_the_reason(tmp_path, capsys):
    """d = 1e-300 divided by zero in terzaghi's set-up: the grain size's physical range (a grain
    many liquid molecules across) refuses it first, one line naming the parameter, its value,
    the range and the reason, exit 2, nothing written."""
    out = tmp_path / "o"
    assert main(["run", "terzaghi", "--set", "d=1e-300", "--out", str(out), "--quiet"]) == 2
    err = [l for l in capsys.readouterr().err.strip().splitlines() if l]
    assert len(err) == 1 and "d = 1e-300 is outside the valid range [1e-08, 0.01] m" in err[0]
    assert "liquid molecules" in err[0]
    assert not out.exists()


@pytest.mark.parametrize("ramp", ["1e-300", "0.01"])
def test_a_load_ramp_shorter_than_the_undrained_transits_is_refused(tmp_path, capsys, ramp):
    """terzaghi's ramp = 1e-300 ran (a load applied at once launches the undrained Biot wave the
    quasi-static theory omits): the ramp is at least 10 transit times H/c_u, in its own units
    (cv t_r/H^2), the bound computed from the other parameters."""
    out = tmp_path / "o"
    assert main(["run", "terzaghi", "--set", f"ramp={ramp}", "--out", str(out), "--quiet"]) == 2
    err = [l for l in capsys.readouterr().err.strip().splitlines() if l]
    defaults = {k: v.default for k, v in inspect.signature(terzaghi.setup.raw).parameters.items()}
    k = terzaghi.constants(defaults)
    lo = 10 * k["transit_s"] / k["t_c_s"]                     # 0.0485 at the defaults
    assert len(err) == 1 and f"ramp = {ramp} is outside the valid range [{lo:.6g}, 10]" in err[0]
    assert "10 undrained transit times H/c_u" in err[0]
    assert not out.exists()


# ---------------------------------------------------------------- fresh-user faults (round 2)
def _cli(argv, capsys):
    rc = main(argv)
    cap = capsys.readouterr()
    return rc, cap.out.strip().splitlines(), [l for l in cap.err.strip().splitlines() if l]


def test_end_time_below_the_steps_the_analysis_needs_is_refused(tmp_path, capsys):
    """bar periods=1e-300 (an end time of 1e-301 s, far below one stable step) ran one step and
    fitted omega from two samples, exit 0. Refused: one line naming periods, its value and the
    smallest valid value (the run must span bar.MIN_SAMPLES first stable steps: periods >=
    MIN_SAMPLES dt / T, T = 2 pi / omega the period), nothing on stdout, nothing written."""
    out = tmp_path / "x1"
    rc, so, err = _cli(["run", "bar", "--set", "periods=1e-300", "--out", str(out)], capsys)
    assert rc == 2 and so == [] and len(err) == 1, (so, err)
    assert "periods = 1e-300 makes the run too short" in err[0]
    lo = float(re.search(r"valid: periods >= (\S+) at the other values", err[0]).group(1))
    sc = bar.setup()
    period = sc.t_end / 2.0                              # default: 2 periods
    assert lo == pytest.approx(bar.MIN_SAMPLES * sc.sim.stable_dt() / period, rel=0.03)
    assert not out.exists()
    # the bound it states runs (and analyses) without a refusal
    res = _run(bar.setup, out, params=dict(periods=lo), vtk=False)
    assert res["complete"] and len(res["history"]) >= bar.MIN_SAMPLES + 1


@pytest.mark.parametrize("argv, key, bound", [
    (["bar", "--set", "dt=1e-11"], "dt", r"dt >= (\S+) s"),
    (["annular", "--set", "u_inner=1e-18"], "u_inner", r"u_inner >= (\S+) m/s"),
])
def test_step_count_refusal_names_the_parameter_set(tmp_path, capsys, argv, key, bound):
    """The too-many-steps refusal named cfl, t_end and h whatever the user set (dt=1e-300 was
    told to raise cfl; annular has no t_end) and printed 'setting up scene X...' first. Now the
    only output is one line naming the parameter set, its value and its bound, and the bound
    is the transition (the value at the bound runs within MAX_STEPS, 10x beyond it does not).
    The values are inside their physical ranges (TIME_MIN, SPEED_MIN: 1e-300 is refused by
    those, column phi0 = 1e-300 by PHI_MIN, tests/test_mpm2d_cli.py)."""
    from mpm2d.run import MAX_STEPS, _first_step
    from mpm2d.scenes import get_setup

    out = tmp_path / "o"
    rc, so, err = _cli(["run", *argv, "--out", str(out)], capsys)
    assert rc == 2 and so == [] and len(err) == 1, (so, err)
    value = argv[-1].split("=")[1]
    assert f"{key} = {value} makes the run too long" in err[0] and "raise cfl" not in err[0]
    assert "setting up" not in err[0] and not out.exists()
    lim = float(re.search(bound, err[0]).group(1))
    setup = get_setup(argv[0])
    assert _first_step(setup(**{key: lim}))[1] <= MAX_STEPS
    assert _first_step(setup(**{key: lim / 10}))[1] > MAX_STEPS


def test_resume_with_another_thread_count_names_threads(tmp_path, monkeypatch):
    """A resume with another --threads said 'set the same chunks' (not an option): it names
    --threads with the checkpoint's count, before the set-up, nothing written."""
    import numba

    out = tmp_path / "o"
    written = numba.get_num_threads()                 # 1 or 2 here, whatever the machine gives
    _run(bar.setup, out, params=dict(cells=8), stop_after_steps=3, vtk=False)
    before = {k: p.read_bytes() for k, p in _files(out).items()}
    monkeypatch.setattr(numba, "get_num_threads", lambda: written + 1)
    with pytest.raises(ValueError) as exc:
        _run(bar.setup, out, params=dict(cells=8), resume=True)
    assert f"resume with --threads {written}" in str(exc.value)
    assert "chunks" not in str(exc.value)
    assert {k: p.read_bytes() for k, p in _files(out).items()} == before


def test_a_run_failing_mid_way_marks_its_manifest_and_prints_no_numpy_warnings(tmp_path):
    """A run failing after its set-up (here its analysis, after a numpy warning; disks
    speed=1e-300 printed three RuntimeWarnings, then failed with a manifest still 'running'):
    a RuntimeError citing numpy's first warning, none emitted, the files kept for the diagnosis
    and the manifest says failed with the message."""
    import warnings

    def setup(**p):
        sc = bar.setup(**p)

        def report(sim, hist, out):
            np.float64(1.0) / np.float64(0.0)
            raise RuntimeError("the analysis broke down")

        sc.report = report
        return sc

    setup.spec = bar.setup.spec
    out = tmp_path / "o"
    with warnings.catch_warnings(record=True) as seen, pytest.raises(RuntimeError) as exc:
        warnings.simplefilter("always")
        _run(setup, out, params=dict(cells=8, periods=0.05), vtk=False)
    assert "the analysis broke down" in str(exc.value) and "divide by zero" in str(exc.value)
    assert not [w for w in seen if issubclass(w.category, RuntimeWarning)]
    man = json.loads((out / "manifest.json").read_text())
    assert man["status"] == "failed" and "the analysis broke down" in man["error"]
    assert (out / "history.csv").is_file() and (out / "checkpoint.npz").is_file()


def test_a_report_with_a_fault_of_its_own_marks_the_manifest_failed(tmp_path):
    """impact t_end=0.002 died in its rod figure (abs(None): no late sinking speed) with a
    traceback and a manifest still 'running': any exception from a report is the run's
    failure (RuntimeError naming it, manifest failed, files kept), not a traceback."""
    def setup(**p):
        sc = bar.setup(**p)
        sc.report = lambda sim, hist, out: abs(None)
        return sc

    setup.spec = bar.setup.spec
    out = tmp_path / "o"
    with pytest.raises(RuntimeError, match="the report failed: TypeError: bad operand"):
        _run(setup, out, params=dict(cells=8, periods=0.05), vtk=False)
    man = json.loads((out / "manifest.json").read_text())
    assert man["status"] == "failed" and "TypeError" in man["error"]
    assert (out / "history.csv").is_file()


def test_the_rod_figure_of_a_run_too_short_for_a_late_speed(tmp_path):
    """A run ending before the late-sinking window has late_velocity null: the figure says so."""
    from mpm2d.scenes.impact import rod_figure

    t = np.linspace(0.0, 2e-3, 40)
    rod = pd.DataFrame({"time_s": t, "z_m": 0.01 - 0.5 * t, "v_m_per_s": -0.5 + 0 * t,
                        "a_m_per_s2": 0 * t})
    summary = {"peak_deceleration_m_per_s2": None, "stencil_s": 1e-4,
               "late_velocity_m_per_s": None, "final_rod_depth_m": 1e-3, "t_end_s": 2e-3}
    fig = rod_figure([(1.0, rod, None)], summary=summary)
    assert "late sinking undefined" in fig.texts[0].get_text()


def test_values_leaving_the_analysis_undefined_are_refused_up_front(tmp_path, capsys):
    """disks speed=1e-300: the initial energy underflowed to 0 and the energy loss (relative to
    it) was NaN after the whole run. Refused before anything is written by the speed's physical
    range (runkit.limits.SPEED_MIN, with its reason); at that bound the initial energy is
    positive at the scene's finest resolution and lightest density."""
    from mpm2d.scenes import disks
    from runkit.limits import SPEED_MIN, DENSITY_MIN

    out = tmp_path / "d"
    rc, so, err = _cli(["run", "disks", "--set", "speed=1e-300", "--out", str(out)], capsys)
    assert rc == 2 and so == [] and len(err) == 1, err
    assert "speed = 1e-300" in err[0] and SPEED_MIN.why in err[0]
    lo = float(re.search(r"valid range \[(\S+), ", err[0]).group(1))
    assert lo == SPEED_MIN.value
    sc = disks.setup.raw(speed=lo, cells=8, rho=DENSITY_MIN.value, E=DENSITY_MIN.value)
    assert sc.sim.energies()["total_J"] > 0
    assert not out.exists()


def test_values_breaking_the_first_step_are_refused_up_front(tmp_path, capsys):
    """column d=1e-300 failed with 'a point left the grid at t = 0' and left empty frames/ and
    vtk/: refused up front by the grain size's physical range, naming it, nothing written."""
    out = tmp_path / "c"
    rc, so, err = _cli(["run", "column", "--set", "d=1e-300", "--set", "t_end=0.05", "--set",
                        "cells=8", "--out", str(out)], capsys)
    assert rc == 2 and so == [] and len(err) == 1, err
    assert "d = 1e-300 is outside the valid range [1e-08, 0.01] m (a grain must be" in err[0]
    assert not out.exists()


def _user_folder(path: Path) -> dict:
    (path / "vtk").mkdir(parents=True)
    (path / "frames").mkdir()
    files = {"vtk/paper.vtu": b"<VTKFile/>", "history.csv": b"a,b\n1,2\n",
             "frames/mine.npz": b"npz", "notes.txt": b"my notes"}
    for k, v in files.items():
        (path / k).write_bytes(v)
    return files


def test_a_folder_of_the_users_is_refused_not_overwritten(tmp_path, capsys):
    """--out into an existing folder that is not a run of ours deleted vtk/paper.vtu and
    overwrote history.csv silently: refused in one line (exit 2), every file as it was."""
    out = tmp_path / "userdir"
    files = _user_folder(out)
    rc, so, err = _cli(["run", "bar", "--set", "cells=8", "--out", str(out)], capsys)
    assert rc == 2 and so == [] and len(err) == 1 and "no manifest.json of ours" in err[0]
    assert {k: p.read_bytes() for k, p in _files(out).items()} == files
    # an empty folder (even with empty frames/ and vtk/) is fine
    empty = tmp_path / "empty"
    (empty / "frames").mkdir(parents=True)
    assert _run(bar.setup, empty, params=dict(cells=8, periods=0.05), vtk=False)["complete"]


def test_a_fresh_run_removes_only_what_the_previous_run_wrote(tmp_path):
    """In a folder of an earlier run, the user's own files (notes, a paper.vtu) survive a fresh
    run; the earlier run's snapshots are gone."""
    out = tmp_path / "o"
    _run(bar.setup, out, params=dict(cells=8, periods=0.1), frames=6)
    (out / "notes.txt").write_text("mine")
    (out / "vtk" / "paper.vtu").write_text("<VTKFile/>")
    res = _run(bar.setup, out, params=dict(cells=8, periods=0.05), frames=2)
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "vtk" / "paper.vtu").read_text() == "<VTKFile/>"
    listed = {Path(f["npz"]).name for f in res["manifest"]["frames"]}
    assert {p.name for p in (out / "frames").glob("*.npz")} == listed


def test_resume_messages_name_what_was_used(tmp_path, capsys):
    """--resume --frames 5 said '(frames = None)'; a corrupt checkpoint.npz fell back to
    checkpoint.prev.npz but said 'resumed from .../checkpoint.npz'."""
    out = tmp_path / "o"
    params = dict(cells=8, periods=0.5)
    _run(bar.setup, out, params=params, stop_after_steps=3, vtk=False, checkpoint_every=1e-9)
    with pytest.raises(ValueError) as exc:
        _run(bar.setup, out, params=params, resume=True, frames=5)
    assert "--frames 5 differs" in str(exc.value) and "None" not in str(exc.value)
    assert (out / "checkpoint.prev.npz").is_file()
    (out / "checkpoint.npz").write_bytes(b"corrupt")
    lines = []
    run_scene(bar.setup, out, params, resume=True, progress=False, log=lines.append,
              stop_after_steps=1)
    resumed = [l for l in lines if l.startswith("resumed from")]
    assert len(resumed) == 1 and "checkpoint.prev.npz" in resumed[0], lines


@pytest.mark.parametrize("argv, words", [
    (["bar", "--set", "v0=1e-300"], "v0 = 1e-300 is outside the valid range [3.16228e-08"),
    (["terzaghi", "--set", "load=1e-300"], "load = 1e-300 is outside the valid range [0.001"),
    (["column", "--set", "eta0=1e-300"], "eta0 = 1e-300 is outside the valid range [1e-05"),
])
def test_values_lost_in_rounding_are_refused_with_their_range(tmp_path, capsys, argv, words):
    """bar v0=1e-300 fitted omega at the edge of its window (frequency error 0.2), terzaghi
    load=1e-300 reported a settlement error of 1, column eta0=1e-300 failed mid-run with an
    infinite Reynolds number, all accepted: their declared ranges now exclude them."""
    out = tmp_path / "o"
    rc, so, err = _cli(["run", *argv, "--out", str(out)], capsys)
    assert rc == 2 and so == [] and len(err) == 1 and words in err[0], err
    assert not out.exists()


def test_bar_at_its_smallest_amplitude_is_as_accurate_as_the_default(tmp_path):
    """At the lower bound of v0 (strain amplitude 1e-9) the bar's fitted frequency and
    amplitude errors are those of the default amplitude (linear elasticity: the errors do not
    depend on v0 while the motion is resolved)."""
    spec = bar.setup.spec
    lo = spec.params["v0"].bounds(spec.defaults)[0]
    small = bar.analyse(_run(bar.setup, tmp_path / "s", params=dict(v0=lo, cells=16),
                             vtk=False)["history"], {**spec.defaults, "v0": lo, "cells": 16})
    ref = bar.analyse(_run(bar.setup, tmp_path / "r", params=dict(cells=16), vtk=False)["history"],
                      {**spec.defaults, "cells": 16})
    assert small["frequency_error"] == pytest.approx(ref["frequency_error"], rel=0.01)
    assert small["amplitude_error"] == pytest.approx(ref["amplitude_error"], rel=0.01, abs=1e-6)
    assert small["frequency_error"] < 0.01


def test_a_run_killed_before_its_first_checkpoint_leaves_a_folder_that_can_be_replaced(
        tmp_path, monkeypatch):
    """The manifest marks the folder as ours before the first snapshot: a run killed (here: an
    error while writing snapshot 0) leaves a folder a fresh run may replace, not one it refuses
    as the user's."""
    import mpm2d.run as runmod

    out = tmp_path / "o"
    real = runmod.write_frame

    def killed(*a, **k):
        real(*a, **k)
        raise KeyboardInterrupt("killed")

    monkeypatch.setattr(runmod, "write_frame", killed)
    with pytest.raises(KeyboardInterrupt):
        _run(bar.setup, out, params=dict(cells=8, periods=0.05), vtk=False)
    assert (out / "frames" / "frame_00000.npz").is_file()
    monkeypatch.setattr(runmod, "write_frame", real)
    res = _run(bar.setup, out, params=dict(cells=8, periods=0.05), vtk=False)
    assert res["complete"] and res["manifest"]["status"] == "complete"


@pytest.mark.parametrize("key, words", [
    ("d", "d = 1e-300 is outside the valid range [1e-08, 0.01] m (a grain must be many liquid"),
    ("gravity", "gravity = 1e-300 is outside the valid range [0.001, 1000] m/s^2 (below the "
                "surface gravity of the smallest bodies"),
    ("K", "K = 1e-300 is outside the valid range [1, 1e+12] Pa (the weakest colloidal gels"),
    ("G", "G = 1e-300 is outside the valid range [1, 1e+12] Pa (the weakest colloidal gels"),
    ("kappa", "kappa = 1e-300 is outside the valid range [1, 1e+12] Pa"),
])
def test_column_refuses_values_below_physical_limits_with_the_reason(tmp_path, capsys, key,
                                                                     words):
    """mpm2d run column with a grain size, gravity or modulus of 1e-300 ran to meaningless
    numbers with exit 0 (or failed on arithmetic): each is refused by its physical limit
    (runkit.limits) with the reason, exit 2, nothing written."""
    out = tmp_path / "c"
    rc, so, err = _cli(["run", "column", "--set", f"{key}=1e-300", "--out", str(out)], capsys)
    assert rc == 2 and so == [] and len(err) == 1 and words in err[0], err
    assert not out.exists()


def test_sigterm_during_the_set_up_of_a_library_run_stops_it_not_the_process(tmp_path,
                                                                              monkeypatch):
    """run_scene from Python (no command line's window): a SIGTERM in the set-up raises
    KeyboardInterrupt, nothing written, as documented; its default action ended the process (a
    timer's SIGTERM landing in a resume's set-up killed the test run under load)."""
    import mpm2d.run as runmod

    real = runmod._set_up

    def set_up_then_signal(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)
        return real(*args, **kwargs)

    monkeypatch.setattr(runmod, "_set_up", set_up_then_signal)
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(KeyboardInterrupt):
        run_scene(terzaghi.setup, tmp_path / "t", dict(cells=8, t_end_T=0.05), progress=False,
                  vtk=False, log=lambda msg: None)
    assert not (tmp_path / "t").exists()
    assert signal.getsignal(signal.SIGTERM) is before       # the window restored it


class _Terminal:
    """A stderr that says it is a terminal and keeps what was written to it."""

    def __init__(self):
        self.text = ""

    def isatty(self):
        return True

    def write(self, s):
        self.text += s

    def flush(self):
        pass


@pytest.mark.parametrize("via_cli", [False, True])
def test_a_refusal_after_a_slow_set_up_is_the_only_output(tmp_path, capsys, monkeypatch,
                                                          via_cli):
    """intruder's step-count refusal came after 'setting up scene intruder...' on stdout (its
    set-up is slower than SETUP_NOTICE_S): a refusal is one line on stderr, exit status 2,
    nothing written. The notice is a status line on a terminal's stderr, erased when the set-up
    ends, so whatever the scene, nothing of it is left before the refusal."""
    import mpm2d.cli
    import mpm2d.run

    def setup(**p):
        sc = bar.setup(**p)
        time.sleep(0.3)                               # slower than the notice's delay below
        sc.t_end = 1e6                                # too many steps: refused after set-up
        return sc

    setup.spec = bar.setup.spec
    monkeypatch.setattr(mpm2d.run, "SETUP_NOTICE_S", 0.05)
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    out = tmp_path / "o"
    if via_cli:
        monkeypatch.setattr(mpm2d.cli, "get_setup", lambda name: setup)
        rc = main(["run", "bar", "--set", "cells=8", "--out", str(out)])
        assert rc == 2
    else:
        with pytest.raises(ValueError, match="too many|first stable steps"):
            run_scene(setup, out, params=dict(cells=8), vtk=False)
    so = capsys.readouterr().out
    assert so == "" and "setting up" not in so
    notice, _, rest = term.text.partition("\r\x1b[K")
    assert notice == "setting up scene bar..."       # shown while it ran, then erased
    assert "setting up" not in rest
    assert rest.count("\n") == (1 if via_cli else 0)
    assert not out.exists()
