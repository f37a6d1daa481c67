"""Measures of a shear-jamming front on velocity profiles: where it is, how fast, how rigid.

Definitions (stated once, used by the events, the outputs and the validation):

- rigid ratio ``v/(omega r)`` (annular) or ``v/U`` (plane): 1 where the mixture moves rigidly with
  the moving wall, 0 at rest;
- front position (kinematic, what PIV sees): the first place, walking out from the moving wall,
  where the rigid ratio falls below ``FRONT_THRESHOLD`` = 0.5 (linear interpolation between
  faces): the edge of the region carried along with the bob. No-slip keeps a layer at the fixed
  wall at rest, so this front stalls short of it;
- structure front: the first cell centre from the moving wall where f < f_jam(phi0)/2, half way to
  jamming; the band "reaches the outer wall" when this front passes ``WALL_FRACTION`` of the gap;
- band rigidity: the mean rigid ratio of the faces between the moving wall and the front;
- bulk speed: the mean of v/u_i over the faces beyond 20 % of the gap (away from the bob layer);
- front speed: slope of a least-squares line through the front positions while the front crosses
  10-90 % of the gap, with its coefficient of determination R^2.
"""

from __future__ import annotations

import numpy as np

from .geometry import Grid

FRONT_THRESHOLD = 0.5
#: The front has "reached the outer wall" when it is beyond this fraction of the gap (no-slip
#: keeps the last boundary layer at rest, so the threshold crossing never reaches the wall itself).
WALL_FRACTION = 0.9
BULK_FROM = 0.2


def rigid_ratio(grid: Grid, v: np.ndarray, u_wall: float) -> np.ndarray:
    """v over the speed of rigid motion with the moving wall, on the faces [-]."""
    v = np.asarray(v, dtype=float)
    if u_wall == 0:
        return np.zeros_like(v)
    return v / grid.rigid_speed(u_wall, grid.faces)


def front_position(grid: Grid, v: np.ndarray, u_wall: float,
                   threshold: float = FRONT_THRESHOLD) -> float:
    """Front position [m]: first threshold crossing of the rigid ratio from the moving wall."""
    return _first_below(grid, grid.faces, rigid_ratio(grid, v, u_wall), threshold)


def structure_front(grid: Grid, f: np.ndarray, f_ref: float, fraction: float = 0.5) -> float:
    """First cell centre from the moving wall where f < fraction * f_ref (interpolated) [m]."""
    return _first_below(grid, grid.centres, np.asarray(f, dtype=float), fraction * f_ref)


def _first_below(grid: Grid, x, q, level: float) -> float:
    """Where q(x) first falls below ``level`` from the moving wall, interpolated [m] (the
    moving wall if q starts below, the outer wall if it never falls)."""
    below = np.flatnonzero(q < level)
    if below.size == 0:
        return float(grid.outer)
    k = int(below[0])
    if k == 0:
        return float(grid.inner)
    return float(x[k - 1] + (q[k - 1] - level) / (q[k - 1] - q[k]) * (x[k] - x[k - 1]))


def band_rigidity(grid: Grid, v: np.ndarray, u_wall: float, front: float) -> float:
    """Mean rigid ratio of the faces between the moving wall and the front (nan if none)."""
    inside = (grid.faces > grid.inner) & (grid.faces < front)
    if not np.any(inside):
        return float("nan")
    return float(np.mean(rigid_ratio(grid, v, u_wall)[inside]))


def bulk_speed(grid: Grid, v: np.ndarray, u_wall: float) -> float:
    """Mean of |v|/u_wall over the faces beyond BULK_FROM of the gap [-]."""
    sel = grid.faces >= grid.inner + BULK_FROM * grid.gap
    return float(np.mean(np.abs(v[sel]))) / abs(u_wall) if u_wall else 0.0


def front_fit(t: np.ndarray, front: np.ndarray, grid: Grid, lo: float = 0.1,
              hi: float = WALL_FRACTION) -> dict:
    """Linear fit of the front position while it advances across [lo, hi] of the gap.

    The window runs from the first time the front passes ``lo`` of the gap to the first time it
    passes ``hi`` or reaches its largest position, whichever comes first (a kinematic front stalls
    short of the no-slip outer wall and falls back once the flow stops; NaN positions - no front
    - end it too). Returns speed [m/s], intercept [m], r2, t_start, t_end [s], the number of
    points and ``gap_reached``, the largest gap fraction of the fitted stretch (below ``hi``: the
    speed is over part of the gap).
    """
    t, front = np.asarray(t, dtype=float), np.asarray(front, dtype=float)
    x = (front - grid.inner) / grid.gap
    start = np.flatnonzero(np.isfinite(x) & (x >= lo))
    out = dict(speed=float("nan"), intercept=float("nan"), r2=float("nan"),
               t_start=float("nan"), t_end=float("nan"), points=0, gap_reached=float("nan"))
    if start.size == 0:
        return out
    i0 = int(start[0])
    gone = np.flatnonzero(~np.isfinite(x[i0:]))        # NaN: no front (no band) from there on
    i_end = i0 + int(gone[0]) - 1 if gone.size else len(t) - 1
    stop = np.flatnonzero(x[i0:i_end + 1] >= hi)
    i1 = i0 + int(stop[0]) if stop.size else i_end
    i1 = min(i1, i0 + int(np.argmax(x[i0:i_end + 1])))
    sel = slice(i0, i1 + 1)
    tt, ff = t[sel], front[sel]
    if tt.size < 3:
        return out
    slope, icpt = np.polyfit(tt, ff, 1)
    resid = ff - (slope * tt + icpt)
    ss = np.sum((ff - ff.mean()) ** 2)
    r2 = 1.0 - np.sum(resid ** 2) / ss if ss > 0 else float("nan")
    return dict(speed=float(slope), intercept=float(icpt), r2=float(r2), t_start=float(tt[0]),
                t_end=float(tt[-1]), points=int(tt.size), gap_reached=float(np.max(x[sel])))
