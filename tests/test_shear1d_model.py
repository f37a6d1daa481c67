"""shear1d model and integrators: Jacobian band, bad input, stability, conservation, bounds,
checkpoints."""

import numpy as np
import pytest

import rheology
from runkit.io import load_checkpoint
from shear1d import analysis
from shear1d.geometry import Grid
from shear1d.integrate import check_state, output_times, solve, stable_time_step
from shear1d.model import Couette
from shear1d.scenes import annular_shear_jamming, plane_couette, summarize

FAST = 0.084


@pytest.mark.parametrize("mode", ["locked", "two-phase"])
@pytest.mark.parametrize("stress", [False, True])
def test_banded_jacobian_holds_every_coupling(mode, stress):
    m = rheology.get_material("annular_shear")
    grid = Grid("annular", 12.5e-3, 36e-3, 7)
    kw = dict(wall_stress=200.0) if stress else dict(wall_speed=FAST)
    pb = Couette(m, grid, mode=mode, **kw)
    res = solve(pb, 2e-3, n_out=2)                       # a sheared, non-uniform state
    y, t, delta = res.y[-1], float(res.t[-1]), 1e-5
    f0 = np.empty(pb.size)
    pb.rhs(t, y, f0, delta)
    J = np.zeros((pb.size, pb.size))
    for j in range(pb.size):
        h = 1e-7 * max(abs(y[j]), 1e-3)
        yp = y.copy()
        yp[j] += h
        f1 = np.empty(pb.size)
        pb.rhs(t, yp, f1, delta)
        J[:, j] = (f1 - f0) / h
    i, j = np.nonzero(np.abs(J) > 0)
    assert np.max(np.abs(i - j)) <= pb.bandwidth()
    assert np.max(np.abs(i - j)) >= pb.bandwidth() - 2          # the band is not oversized


@pytest.mark.parametrize("call, word", [
    (lambda: Grid("cone", 0.01, 0.02, 10), "kind"),
    (lambda: Grid("annular", 0.01, 0.02, 2), "n_cells"),
    (lambda: Grid("annular", 0.02, 0.01, 10), "r_outer = 0.01 is outside the valid range "
                                              r"\(0.02, 10\] m \(the cup must lie beyond"),
    (lambda: Grid("annular", 0.0, 0.01, 10), r"r_inner = 0 is outside the valid range \[1e-06"),
    (lambda: Grid("plane", 0.0, 20.0, 10), r"gap = 20 is outside the valid range \[1e-06, 10\] m"),
    (lambda: annular_shear_jamming(-0.1),
     r"wall_speed = -0.1 is outside the valid range \[1e-18, "),
    (lambda: annular_shear_jamming(float("nan")), "wall_speed = nan: must be finite"),
    (lambda: annular_shear_jamming(0.08, rotation=200.0), r"rotation = 200 .* \[1e-09, 100\] rad"),
    (lambda: annular_shear_jamming(0.08, ramp_time=-1.0),
     r"ramp_time = -1 .*\[1e-12, 1e\+09\] s, or 0"),
    (lambda: solve(plane_couette(0.01, n_cells=5), 1.0, rtol=1.0),
     r"rtol = 1 is outside the valid range \[1e-12, 0.01\] \(a looser tolerance"),
    (lambda: solve(plane_couette(0.01, n_cells=5), 1.0, n_out=0), r"n_out = 0 .*\[1, 100000\]"),
    (lambda: annular_shear_jamming(0.08, mode="drained"), "mode"),
    (lambda: annular_shear_jamming(0.08, phi0=0.6), "phi0"),
    (lambda: annular_shear_jamming(0.08, G=-1.0), "G"),
    (lambda: annular_shear_jamming(0.08, material="nonsense"), "nonsense"),
    (lambda: plane_couette(0.01, material="hermes2016"), "not set"),
    (lambda: plane_couette(0.01, stress=1.0), "exactly one"),
    (lambda: plane_couette(stress=-1.0), "wall_stress"),
    (lambda: solve(plane_couette(0.01, n_cells=5), 1.0, method="rk4"), "method"),
    (lambda: solve(plane_couette(0.01, n_cells=5), -1.0), "t_end"),
    (lambda: output_times(1.0, t_out=[0.0, 0.5, 0.4]), "t_out"),
])
def test_bad_input_raises_a_clear_value_error(call, word):
    with pytest.raises(ValueError, match=word):
        call()


def test_explicit_step_beyond_stability_is_refused():
    pb, t_end = annular_shear_jamming(FAST, n_cells=20)
    lim = stable_time_step(pb)
    assert lim["dt"] <= lim["dt_wave"] * (1 + 1e-12)
    dx_over_c = pb.grid.dx / np.sqrt(pb.material.G / pb.material.rho_s)
    assert 0.9 * dx_over_c < lim["dt_wave"] <= 1.0 * dx_over_c * (1 + 1e-12)
    with pytest.raises(ValueError, match="stability"):
        solve(pb, t_end, method="explicit", dt=1.5 * lim["dt"])
    res = solve(pb, 1e-3, method="explicit", dt=0.9 * lim["dt"], n_out=2)
    assert np.all(np.isfinite(res.y))


def test_two_phase_conserves_solids_and_keeps_bounds():
    pb, t_end = annular_shear_jamming(FAST, n_cells=30, mode="two-phase")
    res = solve(pb, t_end, n_out=31)
    phi, f = res.field("phi"), res.field("f")
    vol = pb.grid.cell_volumes()
    solids = phi @ vol
    assert np.max(np.abs(solids - solids[0])) / solids[0] < 1e-12
    assert np.ptp(phi[-1]) > 1e-6                  # it did migrate
    fm = rheology.f_max(phi, pb.material)
    assert np.all(f >= -1e-6) and np.all(f <= fm + 1e-6)
    assert np.all(res.field("pressure") > 0)


def test_results_do_not_depend_on_the_contact_pressure_floor():
    fronts = []
    for p_floor in (1e-3, 1e-5):
        pb, t_end = annular_shear_jamming(FAST, n_cells=30, rotation=0.15)
        pb = Couette(pb.material, pb.grid, wall_speed=FAST, contact_pressure=p_floor)
        fronts.append(solve(pb, t_end, n_out=15).front())
    assert np.max(np.abs(fronts[0] - fronts[1])) < 5e-3 * pb.grid.gap


@pytest.mark.parametrize("method", ["explicit", "ida"])
def test_checkpoint_resume_continues_the_run(tmp_path, method):
    pb, t_end = annular_shear_jamming(FAST, n_cells=16, rotation=0.05)
    times = output_times(t_end, 10)
    full = solve(pb, t_out=times, method=method)
    ck = tmp_path / "run.npz"

    def stop(t):
        if t >= times[4]:
            raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt, match="run.npz"):
        solve(pb, t_out=times, method=method, checkpoint=ck, stop_hook=stop)
    assert load_checkpoint(ck)["t_out"].size == 5
    resumed = solve(pb, t_out=times, method=method, checkpoint=ck, resume=True)
    assert np.allclose(resumed.t, full.t)
    tol = 0.0 if method == "explicit" else 2e-3
    scale = np.maximum(np.abs(full.y), 1.0)
    assert np.max(np.abs(resumed.y - full.y) / scale) <= tol
    other, _ = annular_shear_jamming(2 * FAST, n_cells=16, rotation=0.05)
    with pytest.raises(ValueError, match=r"--resume: drive = \[0\.168, .* differs from the "
                                         r"checkpoint's drive = \[0\.084, .*run\.npz"):
        solve(other, t_out=times, method=method, checkpoint=ck, resume=True)
    with pytest.raises(ValueError, match="no checkpoint"):
        solve(pb, t_out=times, method=method, checkpoint=tmp_path / "none.npz", resume=True)
    assert "run.fingerprint" in load_checkpoint(ck)


def test_unphysical_state_is_reported_with_diagnostics():
    pb = plane_couette(0.01, n_cells=5)
    y = pb.initial_state()
    y[pb.layout()["i_f"][2]] = 1.5
    diag = pb.diagnostics(0.0, pb.initial_state(), 1e-6)
    with pytest.raises(RuntimeError, match=r"f = 1\.5 outside \[0, 1\] in cell 2"):
        check_state(pb, 0.0, y, diag)


def test_front_measures_on_synthetic_profiles():
    g = Grid("annular", 0.01, 0.03, 20)
    rigid = g.rigid_speed(0.1, g.faces)
    v = np.where(g.faces < 0.02, rigid, 0.0)
    v[-1] = 0.0
    assert 0.019 <= analysis.front_position(g, v, 0.1) <= 0.021
    assert analysis.band_rigidity(g, v, 0.1, 0.02) == pytest.approx(1.0)
    t = np.linspace(0, 1, 50)
    fit = analysis.front_fit(t, g.inner + 0.5 * g.gap * t + 0.1 * g.gap, g)
    assert fit["speed"] == pytest.approx(0.5 * g.gap) and fit["r2"] == pytest.approx(1.0)
    assert fit["gap_reached"] == pytest.approx(0.6) and fit["gap_reached"] < analysis.WALL_FRACTION
    full = analysis.front_fit(t, g.inner + 0.95 * g.gap * t, g)      # crosses 10-90 %
    assert full["gap_reached"] >= analysis.WALL_FRACTION


def test_summary_reports_newtonian_slow_case():
    pb, t_end = annular_shear_jamming(0.84e-3, n_cells=30)
    s = summarize(solve(pb, t_end, n_out=31))
    assert max(s["newtonian_deviation_max_over_u"].values()) < 0.01
    assert s["f_max"] < 0.01 * s["f_jam"]


@pytest.mark.parametrize("kw", [dict(u_inner=1e-15),
                                dict(u_inner=1.0, rotation=1e-9, r_inner=1e-4, r_outer=1e-3)])
def test_annular_duration_outside_the_tiers_durations_is_refused(kw):
    """u_inner = 1e-300 asked for a 3.9e297 s run (it failed in the law); rotation = 1e-300 ran
    1.5e-301 s. Both are now below their physical ranges (SPEED_MIN, STRAIN_MIN); within them,
    t_end must still lie in runkit.limits' [TIME_MIN, TIME_MAX], and the message gives both
    parameters' ranges, within their physical ranges, which hold (a value at the edge is
    accepted)."""
    from runkit import limits

    TIME_MIN, TIME_MAX = limits.TIME_MIN.value, limits.TIME_MAX.value

    with pytest.raises(ValueError, match=r"outside the valid durations \[1e-12, 1e\+09\] s"):
        annular_shear_jamming(n_cells=8, **kw)
    with pytest.raises(ValueError, match=r"wall_speed = 1e-300 is outside the valid range "
                                         r"\[1e-18, "):
        annular_shear_jamming(1e-300, n_cells=8)
    with pytest.raises(ValueError, match=r"rotation = 1e-300 is outside the valid range \[1e-09, "):
        annular_shear_jamming(0.084, rotation=1e-300, n_cells=8)
    ri = 12.5e-3                                          # shear1d's default bob radius [m]
    slowest = 0.31 * ri / TIME_MAX * 1.001                # the lower edge of u_inner's range
    assert annular_shear_jamming(slowest, n_cells=8)[1] <= TIME_MAX
    ri, u = 1e-4, 1.0                                     # a small fast bob: t_end near TIME_MIN
    least = TIME_MIN * u / ri * 1.001                     # the lower edge of rotation's range
    assert annular_shear_jamming(u, rotation=least, n_cells=8, r_inner=ri,
                                 r_outer=1e-3)[1] >= TIME_MIN
