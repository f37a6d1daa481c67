"""The rheometer's figures show their data: every panel has finite data inside its axis limits,
covering what the CSV holds (issue 15: an empty material-point figure under pressure control, a
relaxation f axis that magnified 0.1%, a program's stress and rate on one axis down to 1e-12,
isolated unlabelled states of the rate-controlled flow curve)."""

import numpy as np
import pytest

import rheology
from rheometer import (HYSTERESIS_PROGRAM, flow_curve, plots, relax, run_program,
                       simple_shear_point)
from rheometer import geometry as geo
from rheometer import oscillation as osc
from rheometer.plots import normalise_units
from runkit.plotting import plt

HERMES = rheology.get_material("hermes2016")


def _data(ax):
    """Finite plotted points (x, y) of every line of ``ax`` that the axis scales can show."""
    xs, ys = [], []
    for line in ax.get_lines():
        x = np.asarray(line.get_xdata(), dtype=float)
        y = np.asarray(line.get_ydata(), dtype=float)
        if x.size != y.size or x.size == 0 or line.get_transform() != ax.transData:
            continue                      # axvline/axhline: axes-fraction coordinates
        ok = np.isfinite(x) & np.isfinite(y)
        if ax.get_xscale() == "log":
            ok &= x > 0
        if ax.get_yscale() == "log":
            ok &= y > 0
        xs.append(x[ok])
        ys.append(y[ok])
    return (np.concatenate(xs), np.concatenate(ys)) if xs else (np.zeros(0), np.zeros(0))


def _shows(ax, x_expected=None, min_points=2):
    """The panel has >= min_points finite points, all inside its limits, and (if given) its x
    data spans ``x_expected`` (the CSV's range)."""
    x, y = _data(ax)
    assert x.size >= min_points, f"panel {ax.get_ylabel()!r} is empty"
    x0, x1 = sorted(ax.get_xlim())
    y0, y1 = sorted(ax.get_ylim())
    tol = 1e-9
    inside = ((x >= x0 * (1 - tol) - tol) & (x <= x1 * (1 + tol) + tol)
              & (y >= y0 * (1 - tol) - tol) & (y <= y1 * (1 + tol) + tol))
    assert inside.mean() > 0.99, f"panel {ax.get_ylabel()!r}: data outside its axis limits"
    if x_expected is not None:
        lo, hi = np.nanmin(x_expected), np.nanmax(x_expected)
        assert x.min() <= lo + 1e-9 * abs(hi) and x.max() >= hi * (1 - 1e-9) - 1e-12


def test_material_point_pressure_control_figure_has_data():
    df = simple_shear_point(HERMES, 0.50, 0.5, 1.0, 1e-3, control="pressure", pressure=2.0,
                            points=100)
    assert df["phi"].iloc[-1] != df["phi"].iloc[0]          # phi moves under pressure control
    df.insert(0, "phi0", 0.50)                               # what the CLI writes
    fig = plots.material_point_figure(df, "pressure control")
    for ax in fig.axes:
        _shows(ax, df["time_s"])
    plt.close(fig)


def test_relax_f_axis_starts_at_zero():
    df = relax(HERMES, 0.52, 10.0, 50.0, K0=1e-3, points=100)   # f barely moves
    fig = plots.transient_figure({"phi = 0.52": df}, "relax", log_time=True)
    ax_f = fig.axes[2]
    lo, hi = ax_f.get_ylim()
    assert lo == 0.0 and hi >= df["f"].max()
    change = (df["f"].max() - df["f"].min()) / df["f"].max()
    assert 0 < change < 0.01                                 # a ~0.1% change, as in the issue
    assert (hi - lo) > 50 * (df["f"].max() - df["f"].min())   # ... drawn as small as it is
    assert "%" in ax_f.get_ylabel()
    t = df["time_s"][df["time_s"] > 0]
    for ax in fig.axes:
        _shows(ax, t)
    plt.close(fig)


def test_program_stress_and_rate_on_separate_axes_with_step_marks():
    df = run_program(HERMES, 0.46, HYSTERESIS_PROGRAM, points=80)
    fig = plots.program_figure(df, "program")
    ax_loop, ax_s, ax_r, ax_f = fig.axes
    assert "[Pa]" in ax_s.get_ylabel() and "[1/s]" in ax_r.get_ylabel()
    assert ax_s is not ax_r and ax_s.get_shared_y_axes().get_siblings(ax_s) == [ax_s]
    n_steps = df["step"].nunique()
    for ax in (ax_s, ax_r, ax_f):
        marks = [ln for ln in ax.get_lines() if ln.get_linestyle() == ":"]
        assert len(marks) == n_steps - 1
        assert len(ax.texts) == n_steps
    _shows(ax_loop)
    _shows(ax_s, df["time_s"])
    _shows(ax_r)
    _shows(ax_f, df["time_s"])
    plt.close(fig)


def test_rate_controlled_flow_curve_branches_as_lines():
    df = flow_curve(HERMES, [0.50, 0.52], rate=np.logspace(-3, 2, 60), control="rate")
    assert (~df["stable"]).any()
    fig = plots.flow_curve_figure(df, HERMES)
    ax1 = fig.axes[0]
    labels = [t.get_text() for t in ax1.get_legend().get_texts()]
    assert any("unstable" in s for s in labels) and any(s.endswith(" stable") for s in labels)
    dashed = [ln for ln in ax1.get_lines() if ln.get_linestyle() == "--"]
    assert dashed and all(len(ln.get_xdata()) >= 2 for ln in dashed)
    _shows(ax1, df["shear_rate_per_s"])
    _shows(fig.axes[1])
    plt.close(fig)


def test_oscillation_and_lissajous_figures_have_data():
    pts, waves = osc.oscillation_sweep(HERMES, 0.50, frequency=1.0,
                                       amplitude=[0.001, 0.05, 0.3])
    fig = plots.oscillation_figure(pts, "sweep", dst_stress=osc.dst_onset_stress(HERMES, 0.50))
    for ax in fig.axes:
        _shows(ax, pts["strain_amplitude"])
    plt.close(fig)
    fig = plots.lissajous_figure(waves, "LB")
    for ax in fig.axes:
        x, y = _data(ax)
        assert x.size >= len(waves) and np.abs(y).max() == pytest.approx(1.0)
        _shows(ax)
    plt.close(fig)


def test_parallel_plate_figure_has_true_apparent_and_corrected():
    pp = geo.parallel_plate_flow_curve(HERMES, 0.50)
    tc = flow_curve(HERMES, [0.50], stress=np.logspace(-3, 3, 100))
    fig = plots.parallel_plate_figure(pp, tc, "plate")
    ax1, ax2 = fig.axes
    labels = [t.get_text() for t in ax1.get_legend().get_texts()]
    assert any("apparent" in s for s in labels) and any("Rabinowitsch" in s for s in labels)
    _shows(ax1, pp["rim_shear_rate_per_s"])
    _shows(ax2, pp["rim_shear_rate_per_s"])
    plt.close(fig)


def test_normalised_material_figures_carry_normalised_units():
    """A Table 1 (normalised) set's figure labels say eta0 gdot0 and gdot0, not Pa and 1/s."""
    fig, ax = plt.subplots()
    ax.set_xlabel("shear rate [1/s]")
    ax.set_ylabel("viscosity [Pa s]")
    ax.set_title("stress [Pa] over time [s]")
    normalise_units(fig)
    assert ax.get_xlabel() == "shear rate [gdot0]" and ax.get_ylabel() == "viscosity [eta0]"
    assert ax.get_title() == "stress [eta0 gdot0] over time [1/gdot0]"
    plt.close(fig)


def test_relax_log_stress_axis_stops_below_the_tolerance():
    """A relaxation from 10 Pa decays to ~1e-30 Pa over 50 s: the log stress axis went down
    there, drawing the integrator's noise (a staircase, an upturn); it now ends LOG_FLOOR
    (1e-9) below the largest stress."""
    df = relax(HERMES, 0.52, 10.0, 50.0, points=200)
    stress = df["shear_stress_Pa"][df["time_s"] > 0]
    assert stress.min() < plots.LOG_FLOOR * stress.max()      # the decay reaches the noise
    fig = plots.transient_figure({"phi = 0.52": df}, "relax", log_time=True)
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    lo, hi = ax.get_ylim()
    assert lo == pytest.approx(plots.LOG_FLOOR * stress.max()) and hi >= stress.max()
    plt.close(fig)


def test_program_log_stress_axis_stops_below_the_tolerance():
    """The program figure's log stress axis has the same floor as the transients' (a rest after
    shear relaxes the stress to ~1e-50 Pa, the integrator's noise)."""
    df = run_program(HERMES, 0.5, "shear at 0.5 1/s for 10 s\nrest for 50 s", points=100)
    stress = df["shear_stress_Pa"].to_numpy()
    assert stress.min() > 0 and stress.min() < plots.LOG_FLOOR * stress.max()
    fig = plots.program_figure(df, "program")
    ax = fig.axes[1]
    assert ax.get_yscale() == "log"
    assert ax.get_ylim()[0] == pytest.approx(plots.LOG_FLOOR * stress.max())
    plt.close(fig)
