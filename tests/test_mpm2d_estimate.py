"""Before a run: its size (points, steps, point-steps, memory, a probed wall time) is printed,
and a run past mpm2d.estimate.CONFIRM_POINT_STEPS needs --yes, else it is refused with the
estimate before anything is written (before the set-up where the parameters bound the size)."""

import re

import pytest

from mpm2d import estimate
from mpm2d.run import run_scene
from mpm2d.scenes import bar, get_setup

TINY_IMPACT = dict(radius=0.02, depth=0.016, cells_per_mm=0.5, t_end=0.001, stencil=1e-4)


def test_a_run_past_the_limit_is_refused_before_its_set_up(tmp_path, monkeypatch):
    """320 points x at least ~490 steps (t_end over the scene's first stable step, from its
    parameters) = 1.6e5 point-steps: past a limit of 1e4 the run is refused, naming the size
    and --yes (the numbers printed to 3 digits)."""
    monkeypatch.setattr(estimate, "CONFIRM_POINT_STEPS", 1e4)
    built = []
    setup = get_setup("impact")
    monkeypatch.setattr(estimate, "_coarse_probe",
                        lambda *a: (built.append(a) or (2e-6, "cells_per_mm = 0.5")))
    out = tmp_path / "never"
    with pytest.raises(ValueError, match="need --yes") as err:
        run_scene(setup, out, dict(TINY_IMPACT), progress=False, log=lambda m: None,
                  yes=False)
    text = str(err.value)
    points, steps, work = (float(x) for x in re.search(
        r"a run of (\S+) points x at least (\S+) steps = at least (\S+) point-steps",
        text).groups())
    assert points == 320 and work == pytest.approx(points * steps, rel=5e-3)
    assert "memory ~" in text and f"at least {estimate._clock(work * 2e-6)}" in text
    assert not out.exists() and len(built) == 1


def test_with_yes_it_runs_and_says_its_size(tmp_path, monkeypatch):
    monkeypatch.setattr(estimate, "CONFIRM_POINT_STEPS", 10.0)
    lines = []
    res = run_scene(bar.setup, tmp_path / "b", dict(cells=8, periods=0.1), progress=False,
                    vtk=False, log=lines.append, yes=True)
    assert res["complete"]
    (size,) = [x for x in lines if x.startswith("run size: ")]
    sim = res["scene"].sim
    assert size.startswith(f"run size: {len(sim.sets[0].x)} points x ~")
    assert re.search(r"wall time (~|< )\S+ .*median of a timed probe of \d+ steps, load "
                     r"average", size)
    with pytest.raises(ValueError, match=r"run size|a run of .* need --yes"):
        run_scene(bar.setup, tmp_path / "n", dict(cells=8, periods=0.1), progress=False,
                  vtk=False, log=lambda m: None, yes=False)
    assert not (tmp_path / "n").exists()


def test_the_coarse_probe_times_the_same_scene_at_fewer_points():
    """The probe before the set-up builds the scene itself at a coarser cell size, never finer
    than the run; a size the scene refuses (0.1 cells per mm: below its 0.45, the grid above the
    bed too coarse for the rod) is moved halfway back, geometrically, until it is valid (0.224,
    0.334, 0.409, then 0.452 cells per mm: 45 x 45 cells, 8100 points)."""
    setup = get_setup("impact")
    params = setup.spec.validate({"cells_per_mm": 0.5})
    per, what = estimate._coarse_probe(setup, params, 1e5)
    assert 0 < per < 1e-3 and what.startswith("cells_per_mm = 0.452 (8100 points")


def test_a_sweep_refuses_a_case_past_the_limit_before_any_case_runs(tmp_path, monkeypatch):
    """mpm2d sweep applies run's size refusal to every case before the cluster starts: the
    finer impact case (past a limit of 5e5 point-steps; the coarser has 1.6e5) is named and
    nothing is written."""
    from mpm2d.sweep import run_sweep

    monkeypatch.setattr(estimate, "CONFIRM_POINT_STEPS", 5e5)
    monkeypatch.setattr(estimate, "_coarse_probe", lambda *a: (2e-6, "cells_per_mm = 0.5"))
    grid = {k: [str(v)] for k, v in TINY_IMPACT.items() if k != "cells_per_mm"}
    grid["cells_per_mm"] = ["0.5", "1"]              # 320 and 1280 points
    out = tmp_path / "never"
    with pytest.raises(ValueError, match=r"\(case \S*cells-per-mm=1\): .*need --yes"):
        run_sweep("impact", grid, out, progress=False, log=lambda m: None)
    assert not out.exists()
