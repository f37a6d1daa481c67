"""Figures of runs (matplotlib, Agg backend), written atomically."""

from __future__ import annotations

import numpy as np

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
