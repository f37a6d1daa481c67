"""mpm2d wheel scene (running on oobleck, Figs. 8, 9, 14): the default run runs both omegas,
hub.csv/summary.json keep the interface columns and strict JSON, the driven wheel obeys its
kinematics (spin = omega, no faster than free fall), bad --set values are refused, and the
analysis helpers (grid phi, pressure noise, transition omega) give known answers."""

from __future__ import annotations

import contextlib
import io
import json
import math

import numpy as np
import pandas as pd
import pytest

from mpm2d.cli import main
from mpm2d.run import run_scene
from mpm2d.scenes import wheel

#: a tiny wheel: R = 0.1 m on h = 25 mm (R/4), 0.8 m x 0.1 m bed, 0.03 s
TINY = dict(radius=0.1, hub_radius=0.035, spoke_width=0.04, width=0.8, bed_depth=0.1,
            height=0.45, h=0.025, t_end=0.03, frames=3)


def _strict(text):
    def bad(c):
        raise ValueError(f"non-strict JSON constant {c}")
    return json.loads(text, parse_constant=bad)


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    out = tmp_path_factory.mktemp("wheel") / "both"
    res = run_scene(wheel.setup, out, TINY, progress=False, vtk=False, log=lambda m: None)
    return out, res


def test_default_runs_both_omegas_with_interface_files(both):
    out, res = both
    hub = pd.read_csv(out / "hub.csv")
    assert list(hub.columns) == ["omega_per_s", "time_s", "x_m", "y_m"]
    assert sorted(hub["omega_per_s"].unique()) == [1.0, 10.0]
    assert np.isfinite(hub.to_numpy()).all()
    for _, g in hub.groupby("omega_per_s"):
        assert np.all(np.diff(g["time_s"].to_numpy()) > 0)
        assert g["time_s"].iloc[-1] == pytest.approx(TINY["t_end"], rel=0.02)
    s = _strict((out / "summary.json").read_text())
    assert set(s["sink_depth_m"]) == {"10", "1"}
    assert all(isinstance(v, float) for v in s["sink_depth_m"].values())
    assert (out / "omega_1" / "summary.json").exists()
    for name in ("hub.png", "fig8.png", "fig9.png", "wheel.gif"):
        assert (out / name).stat().st_size > 1000, name
    assert res["manifest"]["status"] == "complete"


def test_wheel_kinematics(both):
    """Each run: the spokes turn with the hub at the prescribed omega (within 10 %), the hub
    falls no faster than free fall (the bed only pushes up), and the fast wheel advances more."""
    out, _ = both
    s = _strict((out / "summary.json").read_text())
    g, t = 9.81, TINY["t_end"]
    for key, r in s["runs"].items():
        assert abs(r["wheel_spin_per_s"] - float(key)) <= 0.1 * float(key), r
        assert r["max_sink_m"] <= 0.5 * g * t ** 2 * 1.01 + 1e-9, r
    assert s["runs"]["10"]["advance_m"] > s["runs"]["1"]["advance_m"]


def test_wheel_spins_at_the_prescribed_rate_single_omega(tmp_path):
    out = tmp_path / "w10"
    run_scene(wheel.setup, out, {**TINY, "omega": 10}, progress=False, vtk=False,
              log=lambda m: None)
    hub = pd.read_csv(out / "hub.csv")
    assert set(hub["omega_per_s"]) == {10.0}
    s = _strict((out / "summary.json").read_text())
    assert list(s["sink_depth_m"]) == ["10"]
    assert not (out / "omega_1").exists()


def _call(argv):
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            rc = main(argv)
        except SystemExit as exc:
            rc = exc.code
    return rc, err.getvalue().strip().splitlines()


@pytest.mark.parametrize("setting, words", [
    ("omega=0", "omega = 0 is outside the valid range [1e-09, 100] 1/s"),
    ("omega=-1", "omega = -1 is outside"),
    ("omega=nan", "omega = nan: must be finite"),
    ("omega=fast", "omega = 'fast' is not a number"),
    ("t_end=5", "t_end = 5 is outside the valid range [1e-12, 1.04] s"),
    ("transfer=pic", "transfer = 'pic' is not one of apic, flip"),
    ("moduli_factor=0", "moduli_factor = 0 is outside"),
    ("phi0=0.6", "phi_j of material 'wheel'"),
    ("hub_radius=0.2", "hub_radius = 0.2 is outside"),
    ("frames=0", "frames = 0 is outside"),
    ("start_angle=60", "start_angle = 60 is outside"),
    ("mu_w=-1", "mu_w = -1 is outside"),
    ("kappa_factor=0", "kappa_factor = 0 is outside"),
])
def test_bad_set_values_are_refused(setting, words, tmp_path):
    out = tmp_path / "o"
    rc, err = _call(["run", "wheel", "--set", setting, "--out", str(out), "--quiet"])
    assert rc == 2 and len(err) == 1 and words in err[0], err
    assert not out.exists()


def test_grid_phi_is_phi_inside_and_zero_outside():
    """Partition of unity: a uniform block at phi = 0.5 gives 0.5 at every node 1.5 cells inside,
    0 two cells outside (quadratic B-splines reach 1.5 cells)."""
    h, nx, ny = 0.1, 10, 10
    s = h / 2
    xs = np.arange(s / 2, nx * h, s)
    ys = np.arange(s / 2, 0.5, s)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    x = np.column_stack([X.ravel(), Y.ravel()])
    gp = wheel.grid_phi(x, 0.5 * s * s * np.ones(len(x)), h, nx, ny)
    assert gp.shape == (nx, ny + 1)
    assert np.allclose(gp[:, 2:4], 0.5, rtol=1e-12)
    assert np.all(gp[:, 7:] == 0.0)


def _frame(p_of_cell, h=0.1, nx=20, ny=10):
    s = h / 2
    xs = np.arange(s / 2, nx * h, s)
    ys = np.arange(s / 2, ny * h, s)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    x = np.column_stack([X.ravel(), Y.ravel()])
    i, j = np.floor(x[:, 0] / h).astype(int), np.floor(x[:, 1] / h).astype(int)
    n = len(x)
    return {"bed.x": x, "bed.phi": np.full(n, 0.5), "bed.V": np.full(n, s * s),
            "bed.m": np.ones(n), "bed.granular_pressure_Pa": p_of_cell(i, j),
            "body.hub.center": np.array([1.0, 1.0])}


def test_pressure_noise_smooth_versus_checkerboard():
    params = dict(h=0.1, width=2.0, height=1.0, phi0=0.5, radius=0.25)
    smooth = wheel.pressure_noise(_frame(lambda i, j: 1000.0 + 10.0 * (10 - j)), params)
    checker = wheel.pressure_noise(_frame(lambda i, j: 1000.0 * (1 + 0.5 * (-1.0) ** (i + j))),
                                   params)
    # smooth: every jump 10 Pa in y, 0 in x -> RMS sqrt(1/2 * 100)-ish over a mean ~1050
    assert smooth < 0.01
    # checkerboard of amplitude 0.5: every jump is 1000 Pa, the mean 1000 Pa
    assert checker == pytest.approx(1.0, rel=0.05)


def test_transition_omega_interpolates_in_log_omega():
    w = [1, 2, 4, 6, 10]
    s = [0.3, 0.28, 0.2, 0.05, 0.02]
    # mid = 0.16, crossed between 4 (0.2) and 6 (0.05): a = 0.04/0.15
    expect = math.exp(math.log(4) + (0.04 / 0.15) * (math.log(6) - math.log(4)))
    assert wheel.transition_omega(w, s) == pytest.approx(expect, rel=1e-12)
    assert math.isnan(wheel.transition_omega([1, 2], [0.1, 0.1]))


@pytest.mark.parametrize("angle, lowest", [(45.0, 2), (0.0, 1)])
def test_start_rests_on_the_surface(angle, lowest):
    """The wheel starts resting on the undisturbed surface: its lowest point faces on the bed's
    top faces, on two spoke tips at 45 deg and on one at 0 deg; the hub centre's start height
    above the surface is R cos(angle) + (w/2) sin(angle) to within a point spacing, and the
    fast-wheel band FAST_BAND is at most that height at the default start (so a fast wheel within
    the band keeps its hub centre above the surface it started on)."""
    p = dict(TINY, start_angle=angle, omega=10.0)
    sc = wheel.setup(**p)
    bed, hub = sc.sim.sets[0], sc.sim.bodies[0]
    spacing = p["h"] / 2
    top = bed.x[:, 1].max() + 0.5 * spacing
    low = hub.x[:, 1].min() - 0.5 * spacing
    assert low == pytest.approx(top, abs=1e-9)
    # the points of the lowest two rows form one group per resting tip (gaps > 2 spacings)
    xs = np.sort(hub.x[hub.x[:, 1] < low + 2.01 * spacing][:, 0])
    assert 1 + int(np.sum(np.diff(xs) > 2 * spacing)) == lowest, xs
    a = math.radians(angle)
    w = p["spoke_width"]
    expect = p["radius"] * math.cos(a) + 0.5 * w * math.sin(a)
    assert hub.center[1] - top == pytest.approx(expect, abs=spacing)
    R, r_hub, w0 = 0.15, 0.05, 0.0556
    default_height = R * math.cos(math.pi / 4) + 0.5 * w0 * math.sin(math.pi / 4)
    assert wheel.FAST_BAND * R <= default_height


def test_checks_band_advance_and_ratio():
    """checks(): the fast wheel passes only within the band AND advancing at least R; the slow
    wheel passes only sinking at least SINK_RATIO times the fast wheel's sink."""
    R = 0.15

    def run(exc, adv, sink, dip=None):
        return {"max_excursion_over_R": exc, "advance_m": adv, "sink_depth_m": sink,
                "sink_over_R": sink / R, "max_sink_m": sink if dip is None else dip}
    ok = wheel.checks({"10": run(0.79, 0.9, 0.08, 0.105), "1": run(1.9, 0.05, 0.25, 0.254)}, R)
    assert ok["fast_stays_up"] and ok["slow_sinks_3x"] and ok["sink_ratio"] == pytest.approx(3.125)
    assert ok["sink_ratio_largest_dip"] == pytest.approx(0.254 / 0.105)     # the other reading
    deep = wheel.checks({"10": run(0.81, 0.9, 0.08), "1": run(1.9, 0.05, 0.25)}, R)
    assert not deep["fast_stays_up"]
    stuck = wheel.checks({"10": run(0.5, 0.1, 0.08), "1": run(1.9, 0.05, 0.25)}, R)
    assert not stuck["fast_stays_up"]
    weak = wheel.checks({"10": run(0.79, 0.9, 0.09), "1": run(1.9, 0.05, 0.25)}, R)
    assert not weak["slow_sinks_3x"] and weak["sink_ratio"] == pytest.approx(0.25 / 0.09)


@pytest.mark.parametrize("offset", [1e-7, 1e-4, 0.05])
def test_surface_point_barely_reaching_a_node_gives_bounded_acceleration(offset):
    """Regression (mpm2d.transfer.p2g, met in this scene: 'a point left the grid'): a free-surface
    point whose stencil barely reaches the node above it (weight 0.5 offset^2 there, node mass ->
    0) must not give that node an unbounded acceleration through the well-balanced hydrostatic
    term (N'' = 1/h^2 does not vanish with the weight). One stress-free point at rest under
    gravity: after one step every nodal velocity is within a few g dt."""
    from mpm2d.grid import Grid
    from mpm2d.materials import LinearElastic
    from mpm2d.particles import ParticleSet
    from mpm2d.simulation import Simulation

    h, g, dt = 0.02, 9.81, 1e-4
    grid = Grid(6, 6, h, boundaries=dict(xmin="periodic", xmax="periodic", ymin="noslip",
                                         ymax="free"))
    # base node j = floor(y/h - 0.5); the upper node's weight is 0.5 (fy - 0.5)^2, fy = y/h - j
    y = (2 + 0.5 + offset) * h
    ps = ParticleSet("p", LinearElastic(1000.0, E=1e6, nu=0.3), np.array([[0.06, y]]),
                     np.array([(h / 2) ** 2]))
    sim = Simulation(grid, [ps], gravity=(0.0, -g), cfl=0.5)
    sim.step(dt)
    vmax = max(float(np.abs(v).max()) for v in sim.vg.values())
    assert vmax <= 4.0 * g * dt, vmax
    assert np.all(np.isfinite(ps.L)) and float(np.abs(ps.L).max()) <= 4.0 * g * dt / h


def test_default_run_interrupted_in_its_omega_1_sub_run_resumes(both, tmp_path, monkeypatch):
    """The default run's second omega runs inside the first's report; an interrupt there used to
    leave no DIR/checkpoint.npz, so the same command with --resume was refused. Interrupted in
    the sub-run (its checkpoint written), resumed from DIR: every table equals the
    uninterrupted run's byte for byte."""
    import mpm2d.run as runmod

    real, calls = runmod.run_scene, []

    def interrupted_sub_run(setup, out, params, **kw):
        calls.append(out)
        real(setup, out, params, **{**kw, "stop_after_steps": 20})
        raise KeyboardInterrupt(f"checkpoint written to {out}/checkpoint.npz")

    monkeypatch.setattr(runmod, "run_scene", interrupted_sub_run)
    out = tmp_path / "both"
    with pytest.raises(KeyboardInterrupt):
        real(wheel.setup, out, TINY, progress=False, vtk=False, log=lambda m: None)
    assert calls and (out / "checkpoint.npz").exists() and (out / "omega_1" / "checkpoint.npz").exists()
    monkeypatch.setattr(runmod, "run_scene", real)
    res = real(wheel.setup, out, TINY, resume=True, progress=False, vtk=False, log=lambda m: None)
    assert res["manifest"]["status"] == "complete"
    ref = both[0]
    for name in ("hub.csv", "summary.json", "history.csv", "omega_1/history.csv",
                 "omega_1/hub.csv", "omega_1/summary.json"):
        assert (out / name).read_bytes() == (ref / name).read_bytes(), name


def test_figures_cover_their_data_and_say_what_summary_says(both):
    """Issue 27: Figs. 8-9 colour every cell of bed by its f on a scale that spans every
    panel's f (no pale points), a few hundred arrows a panel, titles with the summary's sink;
    hub.png draws the fast-wheel band only where the fast wheel is drawn."""
    import matplotlib.pyplot as plt
    from figure_checks import (assert_colour_range_covers, assert_legends_clear_of_data,
                               assert_uniform_cmap)

    out, _ = both
    s = _strict((out / "summary.json").read_text())
    params = json.loads((out / "manifest.json").read_text())["params"]
    for w, folder in ((10.0, out), (1.0, out / "omega_1")):
        res = s["runs"][f"{w:g}"]
        fig = wheel.snapshots_figure(folder, params, w, None, summary=res)
        panels = [ax for ax in fig.axes if ax.get_xlabel() == "x [m]"]
        assert len(panels) == 4
        for ax in panels:
            (mesh,) = [c for c in ax.collections if hasattr(c, "get_array")
                       and c.get_array() is not None and c.get_array().ndim >= 1
                       and c.__class__.__name__ == "QuadMesh"]
            assert_colour_range_covers(mesh, mesh.get_array().compressed())
            assert_uniform_cmap(mesh)
            arrows = [c for c in ax.collections if c.__class__.__name__ == "Quiver"]
            assert len(arrows) == 1 and 0 < arrows[0].N <= 500
        title = fig._suptitle.get_text()
        assert f"sank {res['sink_depth_m'] * 1e3:.0f} mm ({res['sink_over_R']:.2f} R)" in title
        assert f"at most {res['max_sink_m'] * 1e3:.0f} mm" in title
        plt.close(fig)
    hub = pd.read_csv(out / "hub.csv")
    fig = wheel.hub_figure(hub, params["radius"], summary=s)
    assert any("fast-wheel check" in t.get_text() for t in fig.legends[0].get_texts())
    title = fig._suptitle.get_text()
    for res in s["runs"].values():
        assert f"{res['sink_depth_m'] * 1e3:.0f} mm (largest {res['max_sink_m'] * 1e3:.0f} mm)" \
            in title
    ratio, dip = s["checks"]["sink_ratio"], s["checks"]["sink_ratio_largest_dip"]
    assert (f"slow/fast sink {ratio:.2f}" if ratio is not None else "undefined") in title
    if dip is not None:
        assert f"{dip:.2f} by the largest dips" in title
    assert_legends_clear_of_data(fig)
    plt.close(fig)
    fig = wheel.hub_figure(hub[hub["omega_per_s"] == 1.0], params["radius"])
    assert not any("fast-wheel" in t.get_text() for t in fig.legends[0].get_texts())
    plt.close(fig)
