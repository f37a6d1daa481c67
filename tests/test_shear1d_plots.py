"""Every shear1d figure shows its data where the CSV has data, with honest axes: the Couette
wall history on two labelled axes from 0 with one legend; the annular front only where a jammed
band exists (the non-empty front_m cells of <tag>_front.csv)."""

import matplotlib.pyplot as plt
import numpy as np
import pytest

from shear1d import plots
from shear1d.integrate import solve
from shear1d.scenes import (SceneRun, annular_shear_jamming, couette_frames,
                            couette_profile_outputs, front_frame, plane_couette, summarize)


@pytest.fixture(scope="module")
def fast_run():
    pb, t_end = annular_shear_jamming(0.084, n_cells=24)
    res = solve(pb, t_end, n_out=62, method="explicit")
    return SceneRun("fast", res, summarize(res))


@pytest.fixture(scope="module")
def slow_run():
    pb, t_end = annular_shear_jamming(0.00084, n_cells=12)
    res = solve(pb, t_end, n_out=31, method="explicit")
    return SceneRun("slow", res, summarize(res))


def test_couette_figure_has_the_csv_data_on_two_axes_from_zero_with_a_legend():
    res = solve(plane_couette(0.01, n_cells=10), 0.2, n_out=10)
    prof, wall = couette_frames(res)
    fig = plots.couette_figure(res, couette_profile_outputs(res))
    try:
        left, right = fig.axes[1], fig.axes[2]
        (tau_line,), (rate_line,) = left.get_lines(), right.get_lines()
        assert np.array_equal(tau_line.get_xdata(), wall["time_s"])
        assert np.array_equal(tau_line.get_ydata(), wall["wall_shear_stress_Pa"])
        assert np.array_equal(rate_line.get_ydata(), wall["mean_shear_rate_per_s"])
        rate = wall["mean_shear_rate_per_s"].to_numpy()
        assert np.ptp(rate) < 1e-9 * rate.max()          # speed-driven: a constant rate ...
        lo, hi = right.get_ylim()
        assert lo == 0.0 and rate.max() < hi < 1.2 * rate.max()   # ... shown as one, from 0
        lo, hi = left.get_ylim()
        assert lo == 0.0 and wall["wall_shear_stress_Pa"].max() < hi
        legend = left.get_legend()
        assert legend is not None and len(legend.get_texts()) == 2
        assert "[Pa]" in left.get_ylabel() and "[1/s]" in right.get_ylabel()
        profiles = fig.axes[0].get_lines()
        assert len(profiles) == prof["time_s"].nunique()
        for line, (_, grp) in zip(profiles, prof.groupby("time_s", sort=True)):
            assert np.array_equal(line.get_ydata(), grp["v_m_per_s"])
    finally:
        plt.close(fig)


def test_front_figure_draws_the_front_exactly_where_the_csv_has_one(fast_run, slow_run):
    fr = front_frame(fast_run.result)
    has = fr["front_m"].notna().to_numpy()
    assert 0 < has.sum() < len(fr)                      # no front before the band, after the stop
    wall = fast_run.summary["front_at_wall_rotation_rad"]
    assert wall is not None and fr["rotation_rad"][has].max() <= wall + 1e-12
    fig = plots.front_positions_figure([fast_run, slow_run])
    try:
        ax = fig.axes[0]
        front_line = ax.get_lines()[0]
        assert np.array_equal(front_line.get_xdata(), fr["rotation_rad"][has])
        g = fast_run.result.problem.grid
        assert np.allclose(front_line.get_ydata(), (fr["front_m"][has] - g.inner) / g.gap)
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert not any("0.84 mm/s" in x for x in labels)          # the slow case has no band
        assert "jammed band" in ax.get_title()
    finally:
        plt.close(fig)


def test_fields_figure_draws_the_band_front_only(fast_run, slow_run):
    fr = front_frame(fast_run.result)
    has = fr["front_m"].notna().to_numpy()
    fig = plots.run_fields_figure(fast_run)
    try:
        for ax in fig.axes[:4]:                       # the maps (then their colour bars)
            (line,) = ax.get_lines()
            assert np.allclose(line.get_xdata(), fr["front_m"][has] * 1e3)
            assert np.allclose(line.get_ydata(), fr["rotation_rad"][has])
    finally:
        plt.close(fig)
    assert front_frame(slow_run.result)["front_m"].isna().all()
    fig = plots.run_fields_figure(slow_run)
    try:
        assert all(len(ax.get_lines()) == 0 for ax in fig.axes)
        assert "no front" in fig._suptitle.get_text()
    finally:
        plt.close(fig)


def test_titles_say_what_the_runs_show_as_their_summaries_do(fast_run, slow_run):
    """Issue 27: the fast case stops and flows again; its panel says where (the summary's
    rotations) and how close its last profile is to the Newtonian one; the slow panel says it
    did not jam and its profiles coincide with the Newtonian one. No legend over data."""
    from figure_checks import assert_legends_clear_of_data

    fig = plots.velocity_profiles_figure([fast_run, slow_run])
    try:
        titles = {ax.get_title().split("\n")[0]: ax.get_title() for ax in fig.axes
                  if ax.get_visible()}
        fast = titles["u_i = 84 mm/s, locked"]
        s = fast_run.summary
        assert "jammed" in fast and "not jammed" not in fast
        if s["flow_stopped_rotation_rad"] is not None:
            assert f"flow stopped at {s['flow_stopped_rotation_rad']:.3f} rad" in fast
            again = s["flow_restarted_rotation_rad"]
            assert (f"flowing again from {again:.3f} rad" if again is not None
                    else "still stopped") in fast
        dev = s["newtonian_deviation_max_over_u"]["0.31"]
        assert f"within {100 * dev:.2g}% of u_i of the Newtonian profile" in fast
        slow = titles["u_i = 0.84 mm/s, locked"]
        assert "not jammed" in slow and "coincide with the Newtonian" in slow
        assert_legends_clear_of_data(fig)
    finally:
        plt.close(fig)


def test_flow_restart_is_where_the_bulk_speed_is_back_above_the_stop_level(fast_run):
    from shear1d import analysis
    from shear1d.integrate import FLOW_STOP_LEVEL
    from shear1d.summary import flow_restart_time, flow_stop_time, rotation_of

    res, s = fast_run.result, fast_run.summary
    stop, again = flow_stop_time(res), flow_restart_time(res)
    if stop is None:
        assert again is None
        return
    g, u, v = res.problem.grid, res.problem.drive_amplitude, res.field("v")
    bulk = np.array([analysis.bulk_speed(g, vk, u) for vk in v])
    between = (res.t > stop) & (res.t < (again if again is not None else np.inf))
    assert np.all(bulk[between] < FLOW_STOP_LEVEL)
    if again is not None:
        k = int(np.argmin(np.abs(res.t - again)))
        assert bulk[k] >= FLOW_STOP_LEVEL
        assert s["flow_restarted_rotation_rad"] == pytest.approx(float(rotation_of(res, again)))


def test_coinciding_fronts_are_named_together_and_colour_scales_cover_the_fields(fast_run,
                                                                                 slow_run):
    from figure_checks import assert_colour_range_covers, assert_legends_clear_of_data

    from shear1d.scenes import SceneRun

    twin = SceneRun("twin", fast_run.result, fast_run.summary)      # the same curves twice
    fig = plots.front_positions_figure([fast_run, twin, slow_run])
    try:
        labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
        assert sum("coincides with" in x for x in labels) == 2       # front and structure
        assert sum("linear fit" in x for x in labels) == 2           # the twin's in its entry
        assert "no jammed band, no front: u_i = 0.84 mm/s" in fig.axes[0].get_title()
        assert_legends_clear_of_data(fig)
    finally:
        plt.close(fig)
    fig = plots.run_fields_figure(fast_run)
    try:
        for ax in fig.axes[:4]:
            (im,) = ax.images
            assert_colour_range_covers(im, im.get_array())
    finally:
        plt.close(fig)
