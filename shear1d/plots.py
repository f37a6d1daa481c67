"""Figures of the shear1d scenes (matplotlib, Agg backend, written atomically)."""

from __future__ import annotations

import numpy as np

import rheology
from rheology.run_end import mark_end
from runkit.io import atomic_savefig
from runkit.plotting import plt

from .analytic import annular_steady
from .summary import band_front, couette_frames, front_frame, jammed, rotation_of


def _finish(fig, path, layout: bool = True):
    """Lay out (unless the figure did), save atomically, close; return the path."""
    if layout:
        fig.tight_layout()
    atomic_savefig(fig, path)
    plt.close(fig)
    return path


def _label(run) -> str:
    s = run.summary
    return f"u_i = {s['u_inner_m_per_s'] * 1e3:g} mm/s, {s['mode']}"


def _end_rotation(run):
    """(bob rotation [rad] at the last output, label) of a run that ended early, else None."""
    end = run.result.end
    if end is None:
        return None
    return float(rotation_of(run.result, end.time_s)), f"ended: {end.label}"


def _mark_end(ax, run, named: bool = True, **kwargs) -> None:
    """Mark where a run that ended early ended (its label before the end's if ``named``)."""
    ended = _end_rotation(run)
    if ended:
        mark_end(ax, ended[0], f"{_label(run)}: {ended[1]}" if named else ended[1], **kwargs)


def _what_happened(run) -> str:
    """What the run shows, in lines: jammed or not, where the band reached the outer wall, when
    the flow stopped and started again, and how Newtonian the last profile is."""
    s = run.summary
    dev = {float(k): v for k, v in s["newtonian_deviation_max_over_u"].items()}
    last = max(dev) if dev else None
    if not jammed(s):
        lines = [f"not jammed (f_max = {s['f_max'] / s['f_jam']:.2g} f_jam)"]
        if dev and max(dev.values()) < COINCIDE:
            lines.append(f"the profiles from {min(dev):g} rad on coincide with the Newtonian "
                         f"one (within {100 * max(dev.values()):.2g}% of u_i)")
        elif last is not None:
            lines.append(f"at {last:g} rad within {100 * dev[last]:.2g}% of u_i of the "
                         "Newtonian profile")
        return "\n".join(lines)
    lines = ["jammed" + (f": structure f >= f_jam at the outer wall at "
                         f"{s['front_at_wall_rotation_rad']:.3f} rad"
                         if s["front_at_wall_rotation_rad"] is not None else "")]
    if s["front_at_wall_rotation_rad"] is not None and not s["front_crossed_gap"]:
        reached = (s["max_front_position_m"] - s["r_inner_m"]) / (s["r_outer_m"] - s["r_inner_m"])
        lines.append(f"the rigid band (velocity front) reached only {100 * reached:.0f}% of the gap"
                     if np.isfinite(reached) else "no rigid band (velocity front) formed")
    if s["flow_stopped_rotation_rad"] is not None:
        again = s.get("flow_restarted_rotation_rad")
        lines.append(f"flow stopped at {s['flow_stopped_rotation_rad']:.3f} rad, " +
                     (f"flowing again from {again:.3f} rad" if again is not None
                      else "still stopped at the end"))
    if last is not None:
        lines.append(f"at {last:g} rad within {100 * dev[last]:.2g}% of u_i of the Newtonian "
                     "profile")
    return "\n".join(lines)


def velocity_profiles_figure(runs, rotations=(0.0, 0.1, 0.2, 0.31)):
    """Fig. 3a: v/u_i against r at the given bob rotations; a row per speed, a column per mode.
    Each panel's title says what its run shows (:func:`_what_happened`: jammed or not, the band
    at the outer wall, the flow stopping and starting again, the last profile against the
    Newtonian one); one legend below the panels."""

    speeds = sorted({r.summary["u_inner_m_per_s"] for r in runs})
    modes = sorted({r.summary["mode"] for r in runs}, key=lambda m: m != "locked")
    fig, axes = plt.subplots(len(speeds), len(modes), figsize=(6.2 * len(modes),
                                                              4.6 * len(speeds)), squeeze=False)
    for ax in axes.ravel():
        ax.set_visible(False)
    for run in runs:
        ax = axes[speeds.index(run.summary["u_inner_m_per_s"]), modes.index(run.summary["mode"])]
        ax.set_visible(True)
        res, g = run.result, run.result.problem.grid
        u = res.problem.drive_amplitude
        rot = rotation_of(res, res.t)
        v = res.field("v")
        ended = _end_rotation(run)
        # a run that ended early: the rotations it reached, then its last profile
        shown = rotations if not ended else [x for x in rotations if x < rot[-1]] + [rot[-1]]
        for target, c in zip(shown, plt.cm.viridis(np.linspace(0, 0.9, len(rotations)))):
            k = int(np.argmin(np.abs(rot - target)))
            ax.plot(g.faces * 1e3, v[k] / u, color=c, lw=1.8, label=f"{target:.2f} rad")
        ax.plot(g.faces * 1e3, annular_steady(g.faces, g.inner, g.outer, u) / u, "k--", lw=1,
                label="Newtonian steady")
        ax.plot(g.faces * 1e3, g.faces / g.inner, "k:", lw=1, label="rigid rotation")
        ax.set_ylim(min(-0.05, float(np.nanmin(v / u)) - 0.05),
                    max(1.6, float(np.nanmax(v / u)) + 0.05))
        ax.set_xlabel("r [mm]")
        ax.set_ylabel("v / u_i")
        ax.set_title(_label(run) + f"\n{_what_happened(run)}" +
                     (f"\n{ended[1]} at {ended[0]:.3g} rad (the last profile)" if ended else ""),
                     fontsize=9, color="crimson" if ended else "k")
        ax.grid(alpha=0.3)
    handles, labels = next(ax for ax in axes.ravel() if ax.get_visible()) \
        .get_legend_handles_labels()
    fig.suptitle("Annular shear: velocity profiles after 0, 0.1, 0.2, 0.31 rad of bob rotation")
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
    return fig


def _coincide(x, y, x_ref, y_ref, tol) -> bool:
    """Whether the curve (x, y) lies within ``tol`` of (x_ref, y_ref) where both are defined."""
    ok, ok_ref = np.isfinite(y), np.isfinite(y_ref)
    if ok.sum() < 2 or ok_ref.sum() < 2:
        return False
    xr, yr = np.asarray(x_ref)[ok_ref], np.asarray(y_ref)[ok_ref]
    x, y = np.asarray(x)[ok], np.asarray(y)[ok]
    inside = (x >= xr.min()) & (x <= xr.max())
    return bool(inside.sum() >= 2 and np.max(np.abs(np.interp(x[inside], xr, yr)
                                                    - y[inside])) < tol)


def _coinciding(drawn: list, run, x, y, tol):
    """(the label of the earlier curve of ``drawn`` that (x, y) coincides with, or None; the
    line style: thin and dashed on top of it, else full); (x, y) is added to ``drawn``."""
    same = next((lab for x0, y0, lab in drawn if _coincide(x, y, x0, y0, tol)), None)
    drawn.append((x, y, _label(run)))
    return same, dict(lw=1.0, dashes=(4, 3)) if same else dict(lw=2.2)


#: two curves closer than this (in the plotted units) are said to coincide in their legend entry
COINCIDE = 0.005


def front_positions_figure(runs):
    """Kinematic and structure fronts against bob rotation for the runs that jammed, where a
    jammed band exists (:func:`shear1d.summary.band_present`: the non-empty front_m cells of
    <tag>_front.csv), with the linear fit and the events. Fronts that coincide with an earlier
    run's (within :data:`COINCIDE` of the gap) are drawn thin and dashed on top, the legend
    (below the axes) saying so; the runs without a band are named in the title."""
    fig, ax = plt.subplots(figsize=(8, 6.6))
    none = [_label(r) for r in runs if not jammed(r.summary)]
    runs = [r for r in runs if jammed(r.summary)]
    drawn = []
    events = {}
    for k, (run, c) in enumerate(zip(runs, plt.cm.tab10(np.arange(len(runs))))):
        res, g, s = run.result, run.result.problem.grid, run.summary
        fr = front_frame(res)
        band = np.isfinite(fr["front_m"].to_numpy())
        rot = fr["rotation_rad"].to_numpy()[band]
        y = (fr["front_m"].to_numpy()[band] - g.inner) / g.gap
        ys = (fr["structure_front_m"].to_numpy()[band] - g.inner) / g.gap
        same, thin = _coinciding(drawn, run, rot, y, COINCIDE)
        note = f" (coincides with {same} within {COINCIDE:.1%} of the gap)" if same else ""
        ax.plot(rot, y, color=c, label=f"{_label(run)}: front v/(omega r) = 1/2{note}", **thin)
        ax.plot(rot, ys, ":" if same else "--", color=c, lw=1.0 if same else 1.4,
                label=f"{_label(run)}: structure front f = f_jam/2{note}")
        fit = s["front_speed_m_per_s"]
        if fit is not None and np.isfinite(fit):
            lo, hi = s["front_fit_rotation_rad"]
            what = f"linear fit {fit:.3g} m/s over {lo:.3f}-{hi:.3f} rad"
            if same:           # on the line already drawn: named in the front's entry
                ax.lines[-2].set_label(ax.lines[-2].get_label() + f"; {what}")
            else:
                rr = np.linspace(lo, hi, 20)
                x = fit * rr * g.inner / s["u_inner_m_per_s"] + s["front_fit_intercept_m"]
                ax.plot(rr, (x - g.inner) / g.gap, "-", color="k", lw=0.8,
                        label=f"{_label(run)}: {what}")
        for key, what in (("front_at_wall_rotation_rad", "structure at the outer wall"),
                          ("flow_stopped_rotation_rad", "flow stopped")):
            if s[key] is not None:
                events.setdefault(what, []).append((s[key], run))
        _mark_end(ax, run)
    for (what, marks), ls in zip(events.items(), (":", "-.")):
        for x, run in marks:
            ax.axvline(x, color="0.3", ls=ls, lw=0.9)
        ax.plot([], [], color="0.3", ls=ls, lw=0.9, label=f"{what}: " + ", ".join(
            f"{x:.3f} rad ({run.summary['mode']})" for x, run in marks))
    if not runs:
        ax.text(0.5, 0.5, "no run jammed (f < f_jam/2 everywhere): no front", ha="center",
                transform=ax.transAxes)
    ax.set_xlabel("bob rotation [rad]")
    ax.set_ylabel("(front - R_i) / (R_o - R_i)")
    ax.set_ylim(0, 1.02)
    ax.set_title("Shear-jamming front, drawn only while a jammed band (f >= f_jam/2 at the bob) "
                 "grows,\nuntil it reaches the outer wall (it then fills the gap) or the flow "
                 "stops" + (f"\nno jammed band, no front: {'; '.join(none)}" if none else ""),
                 fontsize=9)
    if runs:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=1, fontsize=7,
                  frameon=False)
    ax.grid(alpha=0.3)
    return fig


def _span(data, lo=None, hi=None) -> dict:
    """vmin/vmax covering the finite ``data``, widened to include ``lo``/``hi`` if given."""
    d = np.asarray(data, float)
    d = d[np.isfinite(d)]
    return dict(vmin=min(float(d.min()), np.inf if lo is None else lo),
                vmax=max(float(d.max()), -np.inf if hi is None else hi)) if d.size else {}


def run_fields_figure(run):
    """Space-time maps of one run: v/(omega r), f, plastic shear rate and granular pressure,
    each colour scale spanning its data (v/(omega r) at least 0-1.1, f/f_jam at least 0-1); the
    front is drawn only where a jammed band exists (as in <tag>_front.csv)."""
    res, g = run.result, run.result.problem.grid
    u = res.problem.drive_amplitude
    rot = rotation_of(res, res.t)
    v = res.field("v")
    vc = 0.5 * (v[:, 1:] + v[:, :-1]) / g.rigid_speed(u, g.centres)
    fjam = float(rheology.f_jam(res.problem.phi0, res.problem.material))
    f = res.field("f") / fjam
    rate = np.log10(np.abs(res.field("plastic_shear_rate")) + 1e-6)
    pres = np.log10(res.field("pressure") + 1e-3)
    maps = [(vc, "v / (omega r)", dict(_span(vc, 0.0, 1.1), cmap="viridis")),
            (f, "f / f_jam(phi0)", dict(_span(f, 0.0, 1.0), cmap="magma")),
            (rate, "log10(plastic shear rate [1/s] + 1e-6)", dict(_span(rate), cmap="cividis")),
            (pres, "log10(granular pressure [Pa] + 1e-3)", dict(_span(pres), cmap="plasma"))]
    fig, axes = plt.subplots(1, 4, figsize=(18, 4.6))
    ext = [g.inner * 1e3, g.outer * 1e3, rot[0], rot[-1]]
    front = band_front(res)
    band = np.isfinite(front)
    for ax, (data, title, kw) in zip(axes, maps):
        im = ax.imshow(data, origin="lower", aspect="auto", extent=ext, interpolation="nearest",
                       **kw)
        if band.any():
            ax.plot(front[band] * 1e3, rot[band], "w-", lw=1.0)
        fig.colorbar(im, ax=ax)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("r [mm]")
        _mark_end(ax, run, named=False, vertical=False)
    axes[0].set_ylabel("bob rotation [rad]")
    what = ("white: front v/(omega r) = 1/2, drawn while a jammed band grows" if band.any()
            else "no jammed band formed: no front drawn")
    fig.suptitle(f"{_label(run)}, {g.n} cells ({res.method}); {what}\n"
                 + _what_happened(run).replace("\n", "; "), fontsize=10)
    return fig


def mode_comparison(path, runs):
    """Locked mixture against two-phase: the fronts (runs with a jammed band) and the volume
    fraction at the end (two-phase runs; locked keeps phi = phi0, one line for all). Coinciding
    curves are drawn as in :func:`front_positions_figure`; legends below the panels."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 6.0))
    drawn = []
    no_band = []
    for run, c in zip(runs, plt.cm.tab10(np.arange(len(runs)))):
        res, g = run.result, run.result.problem.grid
        fr = front_frame(res)
        rot = fr["rotation_rad"].to_numpy()
        y = (fr["front_m"].to_numpy() - g.inner) * 1e3
        if not np.isfinite(y).any():
            no_band.append(_label(run))
        else:
            same, style = _coinciding(drawn, run, rot, y, COINCIDE * g.gap * 1e3)
            axes[0].plot(rot, y, color=c, label=_label(run) + (f" (coincides with {same})"
                                                               if same else ""), **style)
        if run.summary["mode"] != "locked":
            axes[1].plot(g.centres * 1e3, res.field("phi")[-1] - res.problem.phi0, color=c,
                         lw=1.5, label=_label(run))
        _mark_end(axes[0], run)
    if any(r.summary["mode"] == "locked" for r in runs):
        g = runs[0].result.problem.grid
        axes[1].plot([g.inner * 1e3, g.outer * 1e3], [0.0, 0.0], ":", color="0.4", lw=1.0,
                     zorder=1, label="locked mixture (every speed): phi = phi0 by construction")
    axes[0].set_xlabel("bob rotation [rad]")
    axes[0].set_ylabel("front - R_i [mm]")
    axes[0].set_title("fronts of the jammed bands" + (
        f"\nno jammed band, no front: {'; '.join(no_band)}" if no_band else ""), fontsize=9)
    axes[1].set_xlabel("r [mm]")
    axes[1].set_ylabel("phi - phi0")
    axes[1].set_title("volume fraction at the end (of a run that ended early: its last output)",
                      fontsize=9)
    for ax in axes:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=1, fontsize=8,
                  frameon=False)
        ax.grid(alpha=0.3)
    fig.suptitle("Locked mixture against two-phase Darcy migration")
    return _finish(fig, path)


def couette_figure(res, idx=None):
    """Plane Couette: velocity profiles at the outputs ``idx`` (left) and, against time, the wall
    shear stress and the mean shear rate on two axes that both start at 0, with one legend for
    both (right). The data are those of couette_profiles.csv and couette_wall.csv."""
    g = res.problem.grid
    prof, wall = couette_frames(res)
    fig, axes = plt.subplots(1, 2, figsize=(11.5, 4.4))
    groups = list(prof.groupby("time_s", sort=True))
    for (t, grp), c in zip(groups, plt.cm.viridis(np.linspace(0, 0.9, len(groups)))):
        axes[0].plot(grp["y_m"] * 1e3, grp["v_m_per_s"], color=c, label=f"t = {t:.3g} s")
    axes[0].set_xlabel("y [mm] (moving plate at 0)")
    axes[0].set_ylabel("v [m/s]")
    axes[0].legend(fontsize=8)
    t = wall["time_s"].to_numpy()
    tau, rate = wall["wall_shear_stress_Pa"].to_numpy(), wall["mean_shear_rate_per_s"].to_numpy()
    l1 = axes[1].plot(t, tau, "C0", label="wall shear stress [Pa] (left axis)")
    axes[1].set_xlabel("t [s]")
    axes[1].set_ylabel("wall shear stress [Pa]", color="C0")
    ax2 = axes[1].twinx()
    l2 = ax2.plot(t, rate, "C1--", label="mean shear rate (v_wall - v_fixed)/gap [1/s] "
                                         "(right axis)")
    ax2.set_ylabel("mean shear rate [1/s]", color="C1")
    for ax, data in ((axes[1], tau), (ax2, rate)):       # both from 0: a constant is a flat line
        top = float(np.max(data)) if data.size else 0.0
        bottom = min(0.0, float(np.min(data))) if data.size else 0.0
        ax.set_ylim(1.08 * bottom, 1.08 * top if top > 0 else 1.0)
    axes[1].legend(l1 + l2, [ln.get_label() for ln in l1 + l2], fontsize=8, loc="lower right")
    if res.end is not None:
        mark_end(axes[1], res.end.time_s, f"ended: {res.end.label}")
    for ax in axes:
        ax.grid(alpha=0.3)
    drive = (f"plate speed {res.problem.drive_amplitude:g} m/s" if not res.problem.stress_driven
             else f"plate stress {res.problem.drive_amplitude:g} Pa")
    fig.suptitle(f"Plane Couette, gap {g.gap * 1e3:g} mm, phi = {res.problem.phi0:g}, "
                 f"{res.problem.mode}, {drive}")
    return fig


def _writer(make, layout: bool = True):
    def write(path, *args):
        return _finish(make(*args), path, layout)
    write.__doc__ = f"Write :func:`{make.__name__}` (same arguments) to ``path``."
    return write


velocity_profiles = _writer(velocity_profiles_figure, layout=False)
front_positions = _writer(front_positions_figure)
run_fields = _writer(run_fields_figure)
couette = _writer(couette_figure)
