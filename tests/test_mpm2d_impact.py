"""The impact scene (Figs. 4-5): a tiny run writes the interface files, the rod decelerates on
contact and pushes a plug ahead of it; the analysis functions recover known answers; bad --set
values are refused before anything is written."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from mpm2d.cli import main
from mpm2d.run import run_scene, spec_of
from mpm2d.scenes import get_setup
from mpm2d.scenes.impact import (SPEED_COLUMNS, displacement_profile, finite_difference,
                                 front_fit, peak_scaling, plug_fit, rod_kinematics,
                                 setup, sweep_report)

#: a tiny case: 2 mm cells, a 2 cm x 1.6 cm bed, 1 ms after impact at 1 m/s (~500 steps)
TINY = dict(radius=0.02, depth=0.016, cells_per_mm=0.5, t_end=0.001, stencil=1e-4)


def _strict(text):
    def bad(c):
        raise ValueError(f"non-strict JSON constant {c}")
    return json.loads(text, parse_constant=bad)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("impact")
    res = run_scene(get_setup("impact"), out, dict(TINY), progress=False, vtk=False,
                    log=lambda m: None)
    return out, res


def test_run_writes_the_interface_files(tiny_run):
    out, res = tiny_run
    assert res["complete"]
    cols = {"rod.csv": ["v0_m_per_s", "time_s", "z_m", "v_m_per_s", "a_m_per_s2"],
            "front.csv": ["v0_m_per_s", "time_s", "front_depth_m"],
            "displacement_vs_depth.csv": ["depth_m", "displacement_m"]}
    for name, c in cols.items():
        df = pd.read_csv(out / name)
        assert list(df.columns) == c, name
        assert len(df) > 10
    rod = pd.read_csv(out / "rod.csv")
    assert np.all(rod["v0_m_per_s"] == 1.0)
    assert rod["v_m_per_s"].notna().sum() > 0.5 * len(rod)     # empty only at the stencil's ends
    summary = _strict((out / "summary.json").read_text())
    for k in ("peak_deceleration_m_per_s2", "late_velocity_m_per_s", "plug_r2", "front_r2", "k",
              "rod_mass_kg", "stencil_s"):
        assert k in summary
    for png in ("displacement.png", "displacement_vs_depth.png", "rod.png", "front.png"):
        assert (out / png).stat().st_size > 1000


def test_rod_decelerates_on_contact_and_pushes_a_plug(tiny_run):
    out, res = tiny_run
    raw = pd.read_csv(out / "rod_raw.csv")
    hist = res["history"]
    v = hist["rod_velocity_m_per_s"].to_numpy()
    # the rod starts at -v0 and loses speed at once (contact from the first steps)
    assert v[0] == pytest.approx(-1.0)
    assert v[-1] > -0.9                                   # (in so shallow a bed it may bounce)
    assert raw["force_N"].iloc[1:].max() > 0.0             # the bed pushes up
    assert raw["a_raw_m_per_s2"].max() > 100.0             # far above g: a stiff response
    # the rod's momentum went into the bed: total momentum change = gravity + walls' impulse,
    # but the bed just below the rod moves down with it (the plug)
    prof = pd.read_csv(out / "displacement_vs_depth.csv")
    rod_disp = -float(hist["rod_z_m"].iloc[-1])
    top = prof["displacement_m"].iloc[0]
    assert top == pytest.approx(rod_disp, rel=0.25)
    assert prof["displacement_m"].iloc[-1] < 0.5 * top      # decays with depth


def test_finite_difference_exact_for_a_parabola():
    t = np.linspace(0.0, 0.01, 501)
    z = -1.0 * t + 0.5 * 300.0 * t ** 2
    v, a, n = rod_kinematics(t, z, 1e-3)
    assert n == 50
    ok = np.isfinite(a)
    assert ok.sum() == len(t) - 2 * n
    np.testing.assert_allclose(v[np.isfinite(v)], (-1.0 + 300.0 * t)[np.isfinite(v)], atol=1e-10)
    np.testing.assert_allclose(a[ok], 300.0, rtol=1e-8)
    d, m = finite_difference(t[:2], z[:2], 1e-3)
    assert np.all(np.isnan(d))


def test_plug_fit_and_profile():
    # points of a lattice displaced linearly with initial depth under the rod, zero outside
    r0, z0 = np.meshgrid((np.arange(20) + 0.5) * 5e-4, (np.arange(40) + 0.5) * 5e-4,
                         indexing="ij")
    x0 = np.stack([r0.ravel(), z0.ravel()], axis=1)
    depth = 0.02
    d0 = depth - x0[:, 1]
    disp = np.clip(4e-3 - 0.4 * d0, 0.0, None)
    x = x0.copy()
    x[:, 1] -= disp
    prof = displacement_profile(x, x0, 5e-3, depth, 5e-4)
    assert len(prof) == 40
    np.testing.assert_allclose(prof["displacement_m"], np.clip(4e-3 - 0.4 * prof["depth_m"], 0,
                                                               None), atol=1e-12)
    res = plug_fit(prof, 4e-3)
    assert res["plug_r2"] > 0.999
    assert res["plug_slope"] == pytest.approx(-0.4, rel=1e-6)
    assert 9e-3 < res["plug_depth_m"] < 1e-2


def test_front_fit_recovers_k():
    t = np.linspace(0, 0.01, 201)
    v = -np.full_like(t, 0.8)
    z = v * t
    front = 8.0 * t + 2.5e-3                 # 10 x the rod speed, ahead of the rod
    res = front_fit(t, front, z, v, 1.0, 1e-3, 0.5)
    assert res["front_speed_m_per_s"] == pytest.approx(8.0)
    assert res["k"] == pytest.approx(10.0)
    assert res["k_penetration"] == pytest.approx(10.0)
    assert res["front_r2"] == pytest.approx(1.0)
    none = front_fit(t, np.full_like(t, np.nan), z, v, 1.0, 1e-3, 0.5)
    assert math.isnan(none["k"])


def test_peak_scaling_slope():
    v0 = np.array([2.0, 0.5, 1.0])
    res = peak_scaling(v0, 1000.0 * v0 ** 1.5)
    assert res["monotone"] and res["loglog_slope"] == pytest.approx(1.5)
    assert not peak_scaling(v0, np.array([1.0, 3.0, 2.0]))["monotone"]
    neg = peak_scaling(v0, np.array([200.0, -2.0, 25.0]))   # v0 = 0.5 never decelerates
    assert neg["monotone"] and neg["loglog_slope"] == pytest.approx(math.log(8) / math.log(2))
    # two decelerating speeds: the line through them, and no R^2 (null with its reason), not 1
    assert math.isnan(neg["loglog_r2"]) and "at least 3" in neg["loglog_r2_null_reason"]
    assert "loglog_r2_null_reason" not in res and res["loglog_r2"] == pytest.approx(1.0)


def test_sweep_report_gathers_speeds(tmp_path):
    rows = []
    for v0 in (1.0, 0.5):
        case = f"v0={v0}"
        d = tmp_path / case
        d.mkdir()
        t = np.linspace(0, 0.01, 11)
        pd.DataFrame({"v0_m_per_s": v0, "time_s": t, "z_m": -v0 * t, "v_m_per_s": -v0,
                      "a_m_per_s2": 0.0}).to_csv(d / "rod.csv", index=False)
        pd.DataFrame({"v0_m_per_s": v0, "time_s": t, "front_depth_m": 10 * v0 * t}).to_csv(
            d / "front.csv", index=False)
        (d / "summary.json").write_text(json.dumps(
            {"v0_m_per_s": v0, "peak_deceleration_m_per_s2": 1e3 * v0 ** 2,
             "late_velocity_m_per_s": -0.01, "k": 10.0, "front_r2": 0.99, "plug_r2": 0.98,
             "final_rod_depth_m": 0.01}))
        rows.append({"v0": str(v0), "case": case})
    paths = sweep_report(pd.DataFrame(rows), tmp_path)
    rod = pd.read_csv(tmp_path / "rod.csv")
    assert list(rod.columns) == ["v0_m_per_s", "time_s", "z_m", "v_m_per_s", "a_m_per_s2"]
    assert sorted(rod["v0_m_per_s"].unique()) == [0.5, 1.0]
    s = _strict((tmp_path / "summary.json").read_text())
    assert s["monotone"] and s["loglog_slope"] == pytest.approx(2.0)
    speeds = pd.read_csv(tmp_path / "speeds.csv")
    assert list(speeds.columns)[:len(SPEED_COLUMNS)] == list(SPEED_COLUMNS)
    assert (tmp_path / "rod.png").exists() and len(paths) == 5


@pytest.mark.parametrize("item", ["size=fig6", "v0=-1", "v0=nan", "cells_per_mm=inf",
                                  "phi0=0.6", "stencil=0.02", "rod_radius=0.2", "mode=dry",
                                  "t_end=0", "radius=0.01"])
def test_bad_values_are_refused(tmp_path, capsys, item):
    out = tmp_path / "never"
    assert main(["run", "impact", "--set", item, "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and item.split("=")[0] in err[0]
    assert not out.exists()


def test_a_grid_too_coarse_for_the_rod_is_refused(tmp_path, capsys):
    """cells_per_mm = 0.25 ran and ended at t = 0 ('the rod bounced out of the grid': the 20 mm
    above the bed could not hold the represented rod and the cells above it). Refused: one line
    naming cells_per_mm, its value, the valid range and the reason, exit 2, nothing written; the
    bound itself sets up a rod inside the grid."""
    from mpm2d.scenes.impact import CELLS_PER_MM_MIN

    out = tmp_path / "never"
    assert main(["run", "impact", "--set", "cells_per_mm=0.25", "--out", str(out)]) == 2
    cap = capsys.readouterr()
    err = cap.err.strip().splitlines()
    assert cap.out == "" and len(err) == 1, err
    assert (f"cells_per_mm = 0.25 is outside the valid range [{CELLS_PER_MM_MIN:g}, 4] 1/mm, or none (the "
            "20 mm of grid above the bed must hold the rod's represented 15 mm") in err[0]
    assert not out.exists()
    scene = get_setup("impact")(**{**TINY, "radius": 0.03, "depth": 0.02,
                                   "cells_per_mm": CELLS_PER_MM_MIN})
    scene.before_step(scene.sim)                 # raises when the rod is out of the grid


def test_interrupted_run_resumes_to_the_same_files(tmp_path, tiny_run):
    out0, _ = tiny_run
    out = tmp_path / "resumed"
    part = run_scene(get_setup("impact"), out, dict(TINY), progress=False, vtk=False,
                     log=lambda m: None, stop_after_steps=150)
    assert not part["complete"]
    res = run_scene(get_setup("impact"), out, dict(TINY), resume=True, progress=False,
                    vtk=False, log=lambda m: None)
    assert res["complete"]
    for name in ("rod.csv", "front.csv", "displacement_vs_depth.csv", "summary.json"):
        assert (out / name).read_bytes() == (out0 / name).read_bytes(), name


def test_late_change_is_the_velocity_change_over_the_late_window():
    """A rod decelerating uniformly: the late window (last 20%) sees its velocity change by
    a (0.2 t_end); NaN samples (the stencil's ends) are left out; too few samples give NaN."""
    from mpm2d.scenes.impact import late_change
    t = np.linspace(0.0, 0.05, 501)
    v = -0.3 + 2.0 * t                       # a = 2 m/s^2
    v[-3:] = np.nan
    mean, change = late_change(t, v)
    late = (t >= 0.8 * t[-1]) & np.isfinite(v)
    assert change == pytest.approx(2.0 * (t[late][-1] - t[late][0]), rel=1e-9)
    assert mean == pytest.approx(np.mean(v[late]), rel=1e-12)
    assert np.isnan(late_change(t[:3], np.array([np.nan, 1.0, np.nan]))[0])


def test_figures_cover_their_data_and_say_what_summary_says(tiny_run):
    """Issue 27: the displacement map spans the field on a diverging scale centred at 0 (the
    heave shows), no jet; each title states the summary's numbers (rod depth, heave, k and its
    window); every legend is off the data."""
    import matplotlib.pyplot as plt
    from figure_checks import (assert_colour_range_covers, assert_legends_clear_of_data,
                               assert_uniform_cmap)

    from mpm2d.scenes import impact

    out, _ = tiny_run
    s = _strict((out / "summary.json").read_text())
    field, dz, _, _ = impact.displacement_field(out, s)
    assert dz.max() > 0 > dz.min()                       # the bed rises beside the rod
    assert s["max_heave_m"] == pytest.approx(dz.max())
    fig = impact.displacement_figure(out, s)
    im = fig.axes[0].images[0]
    assert_colour_range_covers(im, field.T, centred=True)
    assert_uniform_cmap(im)
    title = fig.axes[0].get_title()
    assert f"rod {s['final_rod_depth_m'] * 1e3:.1f} mm deep" in title
    assert f"heave up to {s['max_heave_m'] * 1e3:.1f} mm" in title
    assert_legends_clear_of_data(fig)
    plt.close(fig)
    rod = pd.read_csv(out / "rod.csv")
    fig = impact.front_figure(pd.read_csv(out / "front.csv"), rod["z_m"].to_numpy(), s)
    title = fig.axes[0].get_title()
    if s["k"] is not None:
        assert f"k = {s['k']:.3g} over the first {s['fit_t_end_s'] * 1e3:.3g} ms" in title
        fit = [ln for ln in fig.axes[0].get_lines() if ln.get_color() == "r"]
        assert fit and np.all(np.isfinite(fit[0].get_ydata()))
    else:
        assert "no front" in title
    assert_legends_clear_of_data(fig)
    plt.close(fig)
    fig = impact.profile_figure(pd.read_csv(out / "displacement_vs_depth.csv"), s)
    assert_legends_clear_of_data(fig)
    plt.close(fig)


def test_a_rod_as_wide_as_the_container_is_refused_at_the_size_default_radius():
    """rod_radius is bounded by the container radius - 4 cells also when radius is left at its
    size's value (0.10 m at 2 mm: at most 0.092 m); it was accepted up to 0.1 m."""
    spec = spec_of(setup)
    with pytest.raises(ValueError, match=r"rod_radius = 0.1 is outside the valid range "
                                         r"\[0.004, 0.092\] m \(at least 2 cells, at most the "
                                         r"container radius - 4 cells\)"):
        spec.coerce({"rod_radius": 0.1})
    assert spec.coerce({"rod_radius": 0.09})["rod_radius"] == 0.09
