"""Figures of the shear1d scenes (matplotlib, Agg backend, written atomically)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import rheology  # noqa: E402
from rheology.io import atomic_savefig  # noqa: E402

from .analytic import annular_steady  # noqa: E402


def _finish(fig, path):
    """Lay out, save atomically, close; return the path."""
    fig.tight_layout()
    atomic_savefig(fig, path)
    plt.close(fig)
    return path


def _label(run) -> str:
    s = run.summary
    return f"u_i = {s['u_inner_m_per_s'] * 1e3:g} mm/s, {s['mode']}"


def velocity_profiles(path, runs, rotations=(0.0, 0.1, 0.2, 0.31)):
    """Fig. 3a: v/u_i against r at the given bob rotations; a row per speed, a column per mode."""
    from .scenes import rotation_of

    speeds = sorted({r.summary["u_inner_m_per_s"] for r in runs})
    modes = sorted({r.summary["mode"] for r in runs}, key=lambda m: m != "locked")
    fig, axes = plt.subplots(len(speeds), len(modes), figsize=(5.6 * len(modes),
                                                              4.0 * len(speeds)), squeeze=False)
    for ax in axes.ravel():
        ax.set_visible(False)
    for run in runs:
        ax = axes[speeds.index(run.summary["u_inner_m_per_s"]), modes.index(run.summary["mode"])]
        ax.set_visible(True)
        res, g = run.result, run.result.problem.grid
        u = res.problem.drive_amplitude
        rot = rotation_of(res, res.t)
        v = res.field("v")
        for target, c in zip(rotations, plt.cm.viridis(np.linspace(0, 0.9, len(rotations)))):
            k = int(np.argmin(np.abs(rot - target)))
            ax.plot(g.faces * 1e3, v[k] / u, color=c, lw=1.8, label=f"{rot[k]:.2f} rad")
        ax.plot(g.faces * 1e3, annular_steady(g.faces, g.inner, g.outer, u) / u, "k--", lw=1,
                label="Newtonian steady")
        ax.plot(g.faces * 1e3, g.faces / g.inner, "k:", lw=1, label="rigid rotation")
        ax.set_ylim(min(-0.05, float(np.nanmin(v / u)) - 0.05),
                    max(1.6, float(np.nanmax(v / u)) + 0.05))
        ax.set_xlabel("r [mm]")
        ax.set_ylabel("v / u_i")
        ax.set_title(_label(run), fontsize=10)
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    fig.suptitle("Annular shear: velocity profiles after 0, 0.1, 0.2, 0.31 rad of bob rotation")
    return _finish(fig, path)


def front_positions(path, runs):
    """Kinematic and structure fronts against bob rotation, with the linear fit and events, for
    the runs that jammed."""
    from .scenes import front_frame, jammed

    fig, ax = plt.subplots(figsize=(7, 4.5))
    runs = [r for r in runs if jammed(r.summary)]
    for run, c in zip(runs, plt.cm.tab10(np.arange(len(runs)))):
        res, g, s = run.result, run.result.problem.grid, run.summary
        fr = front_frame(res)
        ax.plot(fr["rotation_rad"], (fr["front_m"] - g.inner) / g.gap, color=c, lw=1.8,
                label=f"{_label(run)}: v/(omega r) = 1/2")
        ax.plot(fr["rotation_rad"], (fr["structure_front_m"] - g.inner) / g.gap, "--", color=c,
                lw=1.2, label="  f = f_jam/2")
        if np.isfinite(s["front_speed_m_per_s"]):
            rot = np.linspace(*s["front_fit_rotation_rad"], 20)
            x = s["front_speed_m_per_s"] * rot * g.inner / s["u_inner_m_per_s"] \
                + s["front_fit_intercept_m"]
            ax.plot(rot, (x - g.inner) / g.gap, ":", color="k", lw=1)
        for key, mk in (("front_at_wall_rotation_rad", "s"), ("flow_stopped_rotation_rad", "x")):
            if s[key] is not None:
                ax.axvline(s[key], color=c, ls=":" if mk == "s" else "-.", lw=0.8)
    if not runs:
        ax.text(0.5, 0.5, "no run jammed (f < f_jam/2 everywhere)", ha="center",
                transform=ax.transAxes)
    ax.set_xlabel("bob rotation [rad]")
    ax.set_ylabel("(front - R_i) / (R_o - R_i)")
    ax.set_ylim(0, 1.02)
    ax.set_title("Shear-jamming front (dotted: linear fit; vertical lines: band at wall, "
                 "flow stopped)", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    return _finish(fig, path)


def run_fields(path, run):
    """Space-time maps of one run: v/(omega r), f, plastic shear rate and granular pressure."""
    from .scenes import rotation_of

    res, g = run.result, run.result.problem.grid
    u = res.problem.drive_amplitude
    rot = rotation_of(res, res.t)
    v = res.field("v")
    vc = 0.5 * (v[:, 1:] + v[:, :-1]) / g.rigid_speed(u, g.centres)
    fjam = float(rheology.f_jam(res.problem.phi0, res.problem.material))
    maps = [(vc, "v / (omega r)", dict(vmin=0, vmax=1.1, cmap="viridis")),
            (res.field("f") / fjam, "f / f_jam(phi0)", dict(vmin=0, vmax=1.0, cmap="magma")),
            (np.log10(np.abs(res.field("plastic_shear_rate")) + 1e-6),
             "log10 plastic shear rate [1/s]", dict(cmap="cividis")),
            (np.log10(res.field("pressure") + 1e-3), "log10 granular pressure [Pa]",
             dict(cmap="plasma"))]
    fig, axes = plt.subplots(1, 4, figsize=(18, 4.2))
    ext = [g.inner * 1e3, g.outer * 1e3, rot[0], rot[-1]]
    front = res.front()
    for ax, (data, title, kw) in zip(axes, maps):
        im = ax.imshow(data, origin="lower", aspect="auto", extent=ext, interpolation="nearest",
                       **kw)
        ax.plot(front * 1e3, rot, "w-", lw=0.8)
        fig.colorbar(im, ax=ax)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("r [mm]")
    axes[0].set_ylabel("bob rotation [rad]")
    fig.suptitle(f"{_label(run)}, {g.n} cells ({res.method}); white: front v/(omega r) = 1/2")
    return _finish(fig, path)


def mode_comparison(path, runs):
    """Locked mixture against two-phase: fronts and the volume fraction at the end."""
    from .scenes import front_frame

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for run, c in zip(runs, plt.cm.tab10(np.arange(len(runs)))):
        res, g = run.result, run.result.problem.grid
        fr = front_frame(res)
        ls = "-" if run.summary["mode"] == "locked" else "--"
        axes[0].plot(fr["rotation_rad"], (fr["front_m"] - g.inner) * 1e3, ls, color=c,
                     label=_label(run))
        axes[1].plot(g.centres * 1e3, res.field("phi")[-1] - res.problem.phi0, ls, color=c,
                     label=_label(run))
    axes[0].set_xlabel("bob rotation [rad]")
    axes[0].set_ylabel("front - R_i [mm]")
    axes[1].set_xlabel("r [mm]")
    axes[1].set_ylabel("phi - phi0 at the end")
    for ax in axes:
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    fig.suptitle("Locked mixture (solid) against two-phase Darcy migration (dashed)")
    return _finish(fig, path)


def couette(path, res, idx):
    """Plane Couette: velocity profiles at the outputs ``idx`` and the wall stress and rate."""
    g = res.problem.grid
    v, tau = res.field("v"), np.abs(res.field("shear_stress"))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for k, c in zip(idx, plt.cm.viridis(np.linspace(0, 0.9, len(idx)))):
        axes[0].plot(g.faces * 1e3, v[k], color=c, label=f"t = {res.t[k]:.3g} s")
    axes[0].set_xlabel("y [mm]")
    axes[0].set_ylabel("v [m/s]")
    axes[0].legend(fontsize=8)
    axes[1].plot(res.t, tau[:, 0], "C0", label="wall shear stress [Pa]")
    axes[1].set_xlabel("t [s]")
    axes[1].set_ylabel("wall shear stress [Pa]")
    ax2 = axes[1].twinx()
    ax2.plot(res.t, (v[:, 0] - v[:, -1]) / g.gap, "C1", label="mean shear rate [1/s]")
    ax2.set_ylabel("mean shear rate [1/s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(f"Plane Couette, gap {g.gap * 1e3:g} mm, phi = {res.problem.phi0:g}, "
                 f"{res.problem.mode}")
    return _finish(fig, path)
