"""Checks shared by the figure tests: a legend never covers data, a colour scale covers the
data it colours (centred at 0 for a signed field), a title says what the summary says."""

from __future__ import annotations

import numpy as np


def data_display_points(ax) -> np.ndarray:
    """(n, 2) display coordinates of the finite data points of ``ax``: line vertices in data
    coordinates and scatter offsets (axvline/axhline and annotations excluded)."""
    pts = []
    for line in ax.get_lines():
        if line.get_transform() != ax.transData or not line.get_visible():
            continue
        xy = np.column_stack([np.asarray(line.get_xdata(), float),
                              np.asarray(line.get_ydata(), float)])
        pts.append(xy[np.all(np.isfinite(xy), axis=1)])
    for coll in ax.collections:
        off = np.asarray(coll.get_offsets(), float)
        if off.ndim == 2 and off.shape[1] == 2 and coll.get_offset_transform() == ax.transData:
            pts.append(off[np.all(np.isfinite(off), axis=1)])
    if not pts:
        return np.zeros((0, 2))
    xy = np.concatenate(pts)
    for k, scale in ((0, ax.get_xscale()), (1, ax.get_yscale())):
        if scale == "log":
            xy = xy[xy[:, k] > 0]
    return ax.transData.transform(xy) if len(xy) else np.zeros((0, 2))


def legends(fig) -> list:
    out = list(fig.legends)
    out += [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    return out


def assert_legends_clear_of_data(fig) -> None:
    """No data point of any panel lies inside any legend's box."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for leg in legends(fig):
        box = leg.get_window_extent(renderer)
        for ax in fig.axes:
            clip = ax.get_window_extent(renderer)
            p = data_display_points(ax)
            inside_ax = ((p[:, 0] >= clip.x0) & (p[:, 0] <= clip.x1) & (p[:, 1] >= clip.y0)
                         & (p[:, 1] <= clip.y1))
            p = p[inside_ax]
            hit = ((p[:, 0] > box.x0) & (p[:, 0] < box.x1) & (p[:, 1] > box.y0)
                   & (p[:, 1] < box.y1))
            assert not hit.any(), (f"legend {[t.get_text() for t in leg.get_texts()][:2]} covers "
                                   f"{int(hit.sum())} data points of panel "
                                   f"{ax.get_title() or ax.get_ylabel()!r}")


def assert_colour_range_covers(mappable, data, *, centred: bool = False) -> None:
    """The colour scale of ``mappable`` spans the finite ``data`` (signed fields: centred at
    0, so that 0 is the neutral colour of a diverging map)."""
    d = np.asarray(data, float)
    d = d[np.isfinite(d)]
    lo, hi = mappable.norm.vmin, mappable.norm.vmax
    assert d.size, "no finite data"
    assert lo <= d.min() and hi >= d.max(), (f"colour range [{lo:g}, {hi:g}] misses the data "
                                             f"[{d.min():g}, {d.max():g}]")
    if centred:
        assert np.isclose(lo, -hi), f"signed field on [{lo:g}, {hi:g}]: not centred at 0"


def assert_uniform_cmap(mappable) -> None:
    """A perceptually uniform (or diverging) colour map, never jet/rainbow/hsv."""
    name = mappable.get_cmap().name.removesuffix("_r")
    assert name not in ("jet", "rainbow", "hsv", "gist_rainbow", "nipy_spectral", "gist_ncar"), \
        name
