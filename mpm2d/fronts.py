"""Jamming fronts ahead of an intruder: where the material moves with it, and how fast that grows.

Han, Peters & Jaeger (2016) measure a front as the contour where the vertical velocity is half the
intruder's, ``u_z = 0.5 v``: the longitudinal front along the axis below the intruder's tip, the
transverse front across it at the tip's depth. The front speeds, from straight-line fits of the
positions over the stretch where they move steadily, give ``k_l = v_fl/v0 - 1`` (the longitudinal
front's lab-frame speed relative to the intruder's) and ``k_t = v_ft/v0``; the paper's Fig. 7 finds
``k_l ~ 2 k_t``. The impact scene uses the same longitudinal measure with the rod's current speed.

The functions here are pure and work on fields binned to cell centres (:func:`cell_field`), so they
do not depend on the engine's internals. Conventions: plane (r, z) with r >= 0 the radius
(``x[:, 0]``) and z the height (``x[:, 1]``, up); velocities ``u_z`` positive up, an intruder moving
down has ``v < 0``, and fronts are detected on ``u_z / v >= frac``.
"""

from __future__ import annotations

import numpy as np


def cell_field(x, values, weights, origin, h: float, shape) -> np.ndarray:
    """Weighted mean of a point quantity in each grid cell (NaN where a cell has no point).

    Parameters
    ----------
    x : (n, 2) array [m]
        Point positions.
    values, weights : (n,) arrays
        The quantity and its weights (e.g. u_z and point masses).
    origin : (2,) [m]
        Lower-left corner of cell (0, 0).
    h : float [m]
        Cell size.
    shape : (nx, ny)
        Number of cells.

    Returns
    -------
    (nx, ny) array, the weighted mean per cell.
    """
    x = np.asarray(x, dtype=float)
    nx, ny = int(shape[0]), int(shape[1])
    i = np.floor((x[:, 0] - origin[0]) / h).astype(int)
    j = np.floor((x[:, 1] - origin[1]) / h).astype(int)
    ok = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
    idx = i[ok] * ny + j[ok]
    w = np.asarray(weights, dtype=float)[ok]
    num = np.bincount(idx, w * np.asarray(values, dtype=float)[ok], nx * ny)
    den = np.bincount(idx, w, nx * ny)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)
    return out.reshape(nx, ny)


def _crossing(coords, ratio, frac: float) -> float:
    """First position along ``coords`` (ordered away from the intruder) where ``ratio`` falls
    below ``frac``, linearly interpolated between cells; NaN if the first cell is already below,
    the last cell if it never falls. Empty cells (NaN) end the search."""
    ratio = np.asarray(ratio, dtype=float)
    if ratio.size == 0 or not ratio[0] >= frac:
        return float("nan")
    for k in range(1, ratio.size):
        if not np.isfinite(ratio[k]):
            return float(coords[k - 1])
        if ratio[k] < frac:
            s = (ratio[k - 1] - frac) / (ratio[k - 1] - ratio[k])
            return float(coords[k - 1] + s * (coords[k] - coords[k - 1]))
    return float(coords[-1])


def longitudinal_front(uz, r_centres, z_centres, tip_z: float, v: float,
                       frac: float = 0.5) -> float:
    """Height [m] of the front below the tip, along the axis (the first column of cells).

    Parameters
    ----------
    uz : (nr, nz) array [m/s]
        Vertical velocity per cell (:func:`cell_field`).
    r_centres, z_centres : (nr,), (nz,) arrays [m]
        Cell-centre coordinates.
    tip_z : float [m]
        Height of the intruder's tip.
    v : float [m/s]
        The intruder's vertical velocity (nonzero).
    frac : float
        Threshold ``u_z / v`` (0.5 in Han et al. 2016).

    Returns
    -------
    float: the front's height (<= tip_z), NaN where the cell under the tip does not move with it.
    """
    below = np.flatnonzero(np.asarray(z_centres) < tip_z)[::-1]          # going down
    col = np.asarray(uz)[0, below] / v
    return _crossing(np.asarray(z_centres)[below], col, frac)


def transverse_front(uz, r_centres, z_centres, tip_z: float, rod_radius: float, v: float,
                     frac: float = 0.5) -> float:
    """Radius [m] of the front at the tip's depth (the row of cells just below the tip).

    Searches outward from the first cell beyond the rod's radius; returns NaN where that cell does
    not move with the intruder (no front yet) and the outermost cell if the whole row does.
    """
    z_centres = np.asarray(z_centres)
    rows = np.flatnonzero(z_centres < tip_z)
    if rows.size == 0:
        return float("nan")
    j = rows[-1]
    out = np.flatnonzero(np.asarray(r_centres) > rod_radius)
    return _crossing(np.asarray(r_centres)[out], np.asarray(uz)[out, j] / v, frac)


def fit_speed(t, position, t_min: float = -np.inf, t_max: float = np.inf) -> dict:
    """Straight-line fit of a front's position against time over ``[t_min, t_max]``.

    Returns
    -------
    dict with ``speed`` [m/s] (the slope), ``intercept`` [m], ``r2`` (coefficient of
    determination; NaN for a front that does not move, where it is 0/0) and ``points`` (number
    used); NaN values where fewer than 3 finite points.
    """
    t, p = np.asarray(t, dtype=float), np.asarray(position, dtype=float)
    sel = np.isfinite(t) & np.isfinite(p) & (t >= t_min) & (t <= t_max)
    if sel.sum() < 3:
        return {"speed": float("nan"), "intercept": float("nan"), "r2": float("nan"),
                "points": int(sel.sum())}
    slope, icpt = np.polyfit(t[sel], p[sel], 1)
    res = p[sel] - (slope * t[sel] + icpt)
    tot = p[sel] - p[sel].mean()
    r2 = 1.0 - float(res @ res) / float(tot @ tot) if float(tot @ tot) > 0 else float("nan")
    return {"speed": float(slope), "intercept": float(icpt), "r2": r2, "points": int(sel.sum())}


def front_coefficients(t, longitudinal, transverse, v0: float, t_min: float = -np.inf,
                       t_max: float = np.inf) -> dict:
    """``k_l = v_fl/v0 - 1`` and ``k_t = v_ft/v0`` from the front positions (Han et al. 2016).

    ``longitudinal`` is a height (falling for an intruder moving down), ``transverse`` a radius;
    ``v0 > 0`` is the intruder's speed.
    """
    fl = fit_speed(t, longitudinal, t_min, t_max)
    ft = fit_speed(t, transverse, t_min, t_max)
    k_l = -fl["speed"] / v0 - 1.0
    k_t = ft["speed"] / v0
    return {"k_l": k_l, "k_t": k_t, "k_l_over_k_t": k_l / k_t if k_t else float("nan"),
            "r2_longitudinal": fl["r2"], "r2_transverse": ft["r2"],
            "v_fl_m_per_s": -fl["speed"], "v_ft_m_per_s": ft["speed"],
            "fit_points": min(fl["points"], ft["points"])}
