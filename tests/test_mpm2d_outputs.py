"""What a ParaView user and a log reader get from an mpm2d run: VTU fields named with their
units in one convention, integers as integers, the points of every frame in id order (the
engine re-sorts them in memory), and progress as plain lines when stderr is not a terminal."""

import io
import json
import re

import meshio
import numpy as np

from mpm2d.output import vtu_name
from mpm2d.run import run_scene
from mpm2d.scenes import disks, shear
from runkit.run import Progress

#: a unit suffix of the project's column convention, or a dimensionless field
_UNIT = re.compile(r"_(m|m_per_s|Pa|per_s|m3_per_(m|rad)|kg_per_(m|rad)|kg_per_m3)$")
_DIMENSIONLESS = {"id", "phi", "f", "case"}


def _fields_named(names):
    for n in names:
        last = n.rsplit(".", 1)[-1]
        assert last in _DIMENSIONLESS or _UNIT.search(last), n


def test_frames_keep_points_in_id_order_with_unit_names(tmp_path):
    out = tmp_path / "d"
    res = run_scene(disks.setup, out, dict(cells=16), progress=False,
                    frames=4, log=lambda m: None)
    sim = res["scene"].sim
    assert not np.array_equal(sim.sets[0].id, np.sort(sim.sets[0].id))   # re-sorted in memory
    man = json.loads((out / "manifest.json").read_text())
    x_by_id = {}
    for fr in man["frames"]:
        with np.load(out / fr["npz"]) as snap:
            for s in sim.sets:
                mesh = meshio.read(out / fr["vtu"][s.name])
                ids = mesh.point_data["id"]
                assert ids.dtype.kind == "i" and np.array_equal(ids, np.arange(len(ids)))
                assert np.array_equal(snap[f"{s.name}.id"], ids)
                assert np.array_equal(mesh.points[:, :2], snap[f"{s.name}.x"])
                _fields_named(mesh.point_data)
                x_by_id.setdefault(s.name, []).append(mesh.points[:, :2])
        grid = meshio.read(out / fr["vtu"]["grid"])
        _fields_named(grid.point_data)
    for name, xs in x_by_id.items():     # point k moves continuously: the same material point
        steps = [np.max(np.linalg.norm(b - a, axis=1)) for a, b in zip(xs, xs[1:])]
        assert max(steps) < 2 * 0.1 * 3.0 / 4, (name, steps)    # ~ speed x frame interval


def test_integer_fields_of_the_suspension_law_are_integers(tmp_path):
    out = tmp_path / "s"
    run_scene(shear.setup, out, {}, progress=False, frames=1, log=lambda m: None)
    man = json.loads((out / "manifest.json").read_text())
    mesh = meshio.read(out / man["frames"][-1]["vtu"]["suspension"])
    case = mesh.point_data["case"]
    assert case.dtype.kind == "i" and set(np.unique(case)) <= {0, 1, 2, 3}
    assert "plastic_shear_rate_per_s" in mesh.point_data and "taubar_Pa" in mesh.point_data
    _fields_named(mesh.point_data)


def test_vtu_names_carry_units_per_thickness_or_radian():
    assert vtu_name("V", False) == "volume_m3_per_m" and vtu_name("V", True) == "volume_m3_per_rad"
    assert vtu_name("solid.mass", True) == "solid.mass_kg_per_rad"
    assert vtu_name("bed.granular_pressure_Pa", False) == "bed.granular_pressure_Pa"


def test_progress_is_plain_periodic_lines_when_not_a_terminal(monkeypatch):
    clock = [0.0]
    monkeypatch.setattr("runkit.run.time.perf_counter", lambda: clock[0])
    buf = io.StringIO()
    bar = Progress(0.0, 2.0, 0, stream=buf, label="demo", every=30.0)
    for k in range(1, 201):                  # 200 steps, 1 s of wall time each
        clock[0] = float(k)
        bar.update(0.01 * k, k)
    bar.close(2.0, 200)
    text = buf.getvalue()
    lines = text.splitlines()
    assert "\r" not in text and "|" not in text
    assert len(lines) == 200 // 30 + 1           # one every 30 s, and the last
    assert lines[0] == ("demo:  15.0% t = 0.3/2 s, step 30, 1e+03 ms/step, 0:30 elapsed, "
                        "~2:50 left")            # 170 s left at the rate so far
    assert lines[-1].startswith("demo: 100.0% t = 2/2 s, step 200") and "left" not in lines[-1]
