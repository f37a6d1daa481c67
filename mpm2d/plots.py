"""Figures of runs (matplotlib, Agg backend), written atomically."""

from __future__ import annotations

import numpy as np
from pandas.api.types import is_bool_dtype, is_numeric_dtype

from runkit.io import atomic_savefig
from runkit.plotting import plt


def particles(ax, sim, field: str = "speed", cmap="viridis", vmin=None, vmax=None, sets=None,
              size=None):
    """Scatter the points of ``sets`` (default all) coloured by ``field`` (``speed`` or any
    material output field); rigid bodies in grey. Returns the mappable."""
    sc = None
    chosen = [s for s in sim.sets if sets is None or s.name in sets]
    vals = []
    for s in chosen:
        vals.append(np.hypot(s.v[:, 0], s.v[:, 1]) if field == "speed"
                    else np.asarray(s.material.output_fields(s)[field]))
    if vals:
        allv = np.concatenate(vals)
        vmin = np.nanmin(allv) if vmin is None else vmin
        vmax = np.nanmax(allv) if vmax is None else vmax
    area = (sim.grid.h * 72 * 4.0 / max(sim.grid.nx, sim.grid.ny) / sim.grid.h) ** 2 / 4.0
    for s, v in zip(chosen, vals):
        sc = ax.scatter(s.x[:, 0], s.x[:, 1], c=v, s=size or area, cmap=cmap, vmin=vmin,
                        vmax=vmax, linewidths=0)
    for b in sim.bodies:
        ax.scatter(b.x[:, 0], b.x[:, 1], c="0.5", s=size or area, linewidths=0)
    lo, hi = sim.grid.lower, sim.grid.upper
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("r [m]" if sim.grid.axisymmetric else "x [m]")
    ax.set_ylabel("z [m]" if sim.grid.axisymmetric else "y [m]")
    return sc


def save(fig, path):
    """Save atomically and close."""
    atomic_savefig(fig, path)
    plt.close(fig)
    return path


def ended_history(history, end, path, scene: str = ""):
    """The recorded history of a run that ended before its end time, up to its last row, with
    the end marked: one panel per numeric column of ``history`` against ``time_s`` (at most 12,
    in the order recorded), a vertical line at ``end.time_s`` (the last row kept) and, where
    known, at ``end.past_s`` (the step that failed), the reason in the title.

    Parameters
    ----------
    history : pandas.DataFrame with a ``time_s`` column [s] (the rows kept).
    end : rheology.run_end.RunEnd
    path : output PNG (written atomically).
    """
    cols = [c for c in history.columns if c != "time_s"
            and is_numeric_dtype(history[c]) and not is_bool_dtype(history[c])][:12]
    n = max(len(cols), 1)
    ncol = min(3, n)
    nrow = -(-n // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 2.6 * nrow + 0.8), squeeze=False)
    t = history["time_s"].to_numpy()
    for ax, c in zip(axes.flat, cols):
        ax.plot(t, history[c].to_numpy(), lw=1)
        ax.set_ylabel(c, fontsize=8)
        ax.set_xlabel("time_s", fontsize=8)
        ax.tick_params(labelsize=7)
        if end.time_s is not None:
            ax.axvline(end.time_s, color="C3", lw=1, label="last row kept")
        if end.past_s is not None and end.past_s != end.time_s:
            ax.axvline(end.past_s, color="C3", lw=1, ls=":", label="run ended")
    for ax in list(axes.flat)[len(cols):]:
        ax.set_axis_off()
    handles, labels = axes.flat[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="lower center", ncol=2, fontsize=8, frameon=False)
    reason = end.reason if len(end.reason) <= 160 else end.reason[:157] + "..."
    fig.suptitle(f"{scene + ': ' if scene else ''}ended early ({end.kind}) at t = "
                 f"{end.past_s if end.past_s is not None else end.time_s:.4g} s; nothing past "
                 f"the red line is a result\n{reason}", fontsize=8)
    fig.tight_layout(rect=(0, 0.06 if handles else 0, 1, 0.92))
    return save(fig, path)
