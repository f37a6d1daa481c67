"""A rigid rod driven at constant speed v0 into a suspension bed: jamming fronts (Figs. 6-7).

The controlled intrusion of Han, Peters & Jaeger (Nat. Commun. 7, 12243, 2016) as simulated by
Baumgarten & Kamrin (section "Impact activated solidification", Table 6, Figs. 6-7): a flat rod
moves down at v0 into a density-matched cornstarch suspension; a plug grows ahead of it, its
front (u_z = v0/2) moving at v_fl along the axis and v_ft across it, with the factors
k_l = v_fl/v0 - 1 and k_t = v_ft/v0, k_l ~ 2 k_t for every phi0 and v0 (Han et al.).

Model: axisymmetric (r, z) MPM of the Table 8 law (rheology.local_update; ``rules`` table8 or
mpm_3d) with the Table 6 set ``intruder`` (eta0 = 4.6 mPa s, rho_s = rho_f = 1620 kg/m^3,
G = 3.8e7 Pa, K = 8.3e7 Pa, d = 5.85 um; fluid modulus kappa = K, our choice: the paper gives
none). Undrained: with Beetstra drag at phi0 = 0.47 the permeability is 1.24e-13 m^2 and the
consolidation coefficient c_v = k/(eta0 (1/M + (1 - phi)/kappa)) = 1.9e-3 m^2/s (M = K + 4G/3),
so draining the plug's 1 cm takes L^2/c_v = 51 ms, longer than the 20 ms run. The rod is a
rigid body with its velocity (0, -v0) prescribed from t = 0; it meets the bed through
multi-velocity-field contact (mpm2d.contact), compressive only, on approach, with Coulomb
friction (``rod_contact``: no slip, the default, or frictionless); the bed starts at rest under
gravity (mpm2d.geostatic); axis r = 0 a symmetry line, floor and outer wall no slip, top free.

Layouts (``layout``; geometry parameters left at none/auto take the layout's values):
- ``default``, our reading of the paper's "50x35 element Cartesian grid with 1mm x 1mm
  resolution": bed 50 mm x 35 mm plus room above for the rod, rod radius 3.175 mm (a 1/4-inch
  rod) represented on the h/2 point lattice (3.0 mm at h = 1 mm), tip starting at the surface,
  locked mixture (undrained), contact ``touch`` (only where the points' squares touch).
- ``mpm_3d``, the author's scene (aaronbaumgarten/mpm_3d, mpm_pygen/GenerateMixture2D_v2.py and
  GenerateBlock2D_v2.py, with src/objects/boundaries/assigned_velocity.cpp and
  src/objects/contacts/contact_rigid_reflected_boundary.cpp): grid 50 x 35 cells of 1 mm, bed
  0-50 mm x 0-30 mm (5 mm headroom) at 2 x 2 points per cell, grains and fluid as two bodies
  (two-phase), rod the block r 0-3 mm, z 32-35 mm (tip 2 mm above the surface), density 1e5
  kg/m^3, contact ``mass`` (every node where the rod and a field both have mass, normal from the
  rod's area gradient). With quadratic B-splines (reach 1.5 h) it acts on the bed from t = 0.
  Not in the files, our choices: the friction, container, initial stress and shape functions.

Fronts (mpm2d.fronts): u_z of the bed's (granular) points binned to the cells; the longitudinal
front is the depth where u_z/(-v0) falls below 1/2 on the axis column under the rod's face, the
transverse front the radius where it does on the row below the face, searched outward from the
rod's radius. The face is the tip, or the top of the highest filled axis cell below it where
contact ``mass`` pushes the bed from a distance. The bed jams where a point's f reaches f_jam
(phi_m(f_jam) = phi0); ``jammed`` in summary.json says whether it did: if not, the fronts are
the rod's viscous near field, not a plug.

Fit: straight lines (least squares on the finite records) over a window after the contact
transient (four acoustic crossings of the bed) and after the first jamming, where both fronts
exist and the longitudinal one is 2 cells ahead of the tip, ended by a front within
``fit_margin`` of the floor or wall or falling back by more than h from its farthest position
(running median over 9 records); of such stretches, the one over which both fronts advance
most. A speed over less than two cells of travel is null with its reason.

Parameters: layout, phi0, v0 [m/s], t_end [s], radius, depth [m], cells_per_mm [1/mm],
rod_radius [m], rod_contact, contact, mode, fit_margin [m], gravity [m/s^2], rules, cfl.
Outputs: front.csv (time_s, longitudinal_m, transverse_m), front.png (fronts, fit lines, the
jam state and window in the title), summary.json (k_l, k_t, R^2, window, jammed, t_jam_s,
max_f_over_f_jam), fields.png (Fig. 6: u_z at 6.2, 13.2, 20 ms up to t_end and at t_end;
|D_rz|, |D_zz| and f/f_jam at t_end). ``mpm2d sweep intruder`` writes fronts.csv and fronts.png (Fig. 7's k_l-k_t scatter).
Run: ``mpm2d run intruder``; the author's scene: ``mpm2d run intruder --set layout=mpm_3d``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import matplotlib.colors as mcolors
import numpy as np
import pandas as pd

from rheology import get_material
from runkit.io import atomic_write_csv, atomic_write_json
from runkit.limits import ge, le

from .. import plots
from ..bodies import RigidBody, fill
from ..fronts import cell_field, fit_speed, longitudinal_front, transverse_front
from ..geostatic import geostatic
from ..grid import Grid
from ..output import case_summaries, load_frames
from . import spec
from .beds import bed_phases, suspension_bed
from ..run import Scene
from ..simulation import Simulation

#: Fig. 6(a)-(c) snapshot times [s]
FIELD_TIMES = (6.2e-3, 13.2e-3, 20e-3)
#: the front threshold u_z / v (Han et al. 2016)
FRONT_FRACTION = 0.5
#: rod length above its travel, default layout [m]
ROD_EXTRA = 5e-3
#: per layout: the geometry parameters' values, the rod's length and density, its tip's start
#: above the bed and the grid's room above the bed (None: the default layout's rule: rod
#: v0 t_end + ROD_EXTRA long, room for it plus 3 cells) [m, kg/m^3]
LAYOUTS = {
    "default": dict(radius=0.05, depth=0.035, rod_radius=3.175e-3, mode="locked mixture",
                    contact="touch", rod_length=None, rod_density=None, gap=0.0,
                    headroom=None),
    "mpm_3d": dict(radius=0.05, depth=0.030, rod_radius=3e-3, mode="two-phase",
                   contact="mass", rod_length=3e-3, rod_density=1e5, gap=2e-3, headroom=5e-3),
}
#: summary.json keys that may be undefined (no front formed, too few points)
_NULLABLE = ("k_l", "k_t", "k_l_over_k_t", "r2_longitudinal", "r2_transverse",
             "v_fl_m_per_s", "v_ft_m_per_s", "fit_t_start_s", "fit_t_end_s", "t_jam_s",
             "max_f_over_f_jam")


def resolved(p: dict) -> dict:
    """The parameters with every ``None`` or ``auto`` replaced by its layout's value, plus the
    layout's rod and headroom entries."""
    base = LAYOUTS[p["layout"]]
    q = {k: (base[k] if k in base and (v is None or v == "auto") else v) for k, v in p.items()}
    for k in ("rod_length", "rod_density", "gap", "headroom"):
        q[k] = base[k]
    if q["rod_length"] is None:
        q["rod_length"] = q["v0"] * q["t_end"] + ROD_EXTRA
    return q


def _headroom_cells(q) -> int:
    h = 1e-3 / q["cells_per_mm"]
    if q["headroom"] is not None:
        return int(round(q["headroom"] / h))
    return int(math.ceil((q["gap"] + q["rod_length"]) / h)) + 3


def grid_shape(q) -> tuple:
    """(h [m], nx, nz) of the grid of the resolved parameters ``q`` (:func:`resolved`)."""
    h = 1e-3 / q["cells_per_mm"]
    return h, int(round(q["radius"] / h)), int(round(q["depth"] / h)) + _headroom_cells(q)


def _size(p) -> tuple:
    q = resolved(p)
    c = q["cells_per_mm"] * 1e3
    n = (q["radius"] * q["depth"] + q["rod_radius"] * q["rod_length"]) * c ** 2 * 4
    points = n * (2 if q["mode"] == "two-phase" else 1)
    return points, (q["radius"] * c + 5) * (q["depth"] * c + _headroom_cells(q) + 5)


def _steps(p) -> tuple:
    """(first step [s], end time [s], fewest steps) from the parameters: the wave limit of the
    bed in the layout's mode, its viscous limit or the advection of the rod at v0, whichever is
    smallest."""
    q = resolved(p)
    phases = bed_phases(get_material("intruder", rules=q["rules"]), q["phi0"], q["mode"])
    return spec.first_step(q["cfl"], 1e-3 / q["cells_per_mm"], phases, q["v0"]), q["t_end"], 1


def _geo(key, doc, above=None, below=None, note=""):
    """A length of the bed, none: the layout's; ``above``, ``below``: functions of the other
    parameters bounding it (reason ``note``) where tighter than the physical lengths."""
    return spec.length(doc + " (none: the layout's)", optional=True,
                       fill=lambda p: resolved(p)[key],
                       above=None if above is None else ge(above, note),
                       below=None if below is None else le(below, note))


@spec.parameters_of(
    layout=spec.Param(choices=tuple(LAYOUTS),
                      doc="default (our reading of the paper) or mpm_3d (the author's scene)"),
    phi0=spec.phi_below_jamming(fixed="intruder", doc="solid volume fraction of the bed"),
    v0=spec.speed("rod speed (downwards)", hi=le(10.0, "about 60 times the paper's 0.175 m/s")),
    t_end=spec.duration("end time", below=le(lambda p: 0.8 * resolved(p)["depth"] / p["v0"],
                                             "the rod travels at most 80% of the bed depth")),
    radius=_geo("radius", "bed (container) radius",
                lambda p: resolved(p)["rod_radius"] + 4e-3 / p["cells_per_mm"],
                note="at least the rod radius + 4 cells"),
    depth=_geo("depth", "bed depth", lambda p: 4e-3 / p["cells_per_mm"],
               note="at least 4 cells"),
    cells_per_mm=spec.resolution(
        "1/h in 1/mm (1: the paper's 1 mm)",
        lo=ge(0.1, "a cell of at most 10 mm: the rod (a few mm) spans at least part of one"),
        hi=le(20.0, "a cell of 50 um: 20 times finer than the paper's 1 mm grid, past any "
                    "convergence study of the fronts")),
    rod_radius=_geo("rod_radius", "rod radius", lambda p: 1e-3 / p["cells_per_mm"],
                    lambda p: resolved(p)["radius"] - 4e-3 / p["cells_per_mm"],
                    note="at least one cell, at most the bed radius - 4 cells"),
    rod_contact=spec.Param(choices=("noslip", "frictionless"),
                           doc="rod-suspension friction: no slip (mu_w = inf) or mu_w = 0"),
    contact=spec.Param(choices=("auto", "touch", "mass"),
                       doc="where the rod meets the bed: touch (surfaces touching), mass (any "
                           "node where both have mass, the author's); auto: the layout's"),
    mode=spec.Param(choices=("auto", "locked mixture", "two-phase"),
                    doc="locked mixture (undrained) or two-phase (grains + fluid); auto: the "
                        "layout's"),
    fit_margin=spec.length("fronts fitted until within this distance of the floor or wall (0: "
                           "to the floor)", lo=ge(0.0, "0: fitted to the floor and wall"),
                           below=le(
                               lambda p: 0.5 * min(resolved(p)["depth"], resolved(p)["radius"]),
                               "at most half the bed depth and radius")),
    gravity=spec.gravity(), rules=spec.rules(), cfl=spec.cfl(),
    size=_size, steps=lambda p: _steps(p))
def setup(layout="default", phi0=0.47, v0=0.175, t_end=0.02, radius=None, depth=None,
          cells_per_mm=1.0, rod_radius=None, rod_contact="noslip", contact="auto", mode="auto",
          fit_margin=5e-3, gravity=9.81, rules="table8", cfl=0.5):
    q = resolved(dict(locals()))              # every parameter, the layout's where none
    h, nx, nz = grid_shape(q)
    m = get_material("intruder", rules=rules)
    depth, mode = q["depth"], q["mode"]
    grid = Grid(nx, nz, h, axisymmetric=True,
                boundaries=dict(xmin="axis", xmax="noslip", ymin="noslip", ymax="free"))
    spacing = h / 2
    x, area = fill(lambda r, z: np.ones_like(r, dtype=bool), (0.0, 0.0), (nx * h, depth), spacing)
    sets, extra = suspension_bed(m, x, area, phi0, mode, axisymmetric=True)
    length, bottom = q["rod_length"], depth + q["gap"]
    nrod = int(math.floor(q["rod_radius"] / spacing + 1e-9))
    rod_r = nrod * spacing                                 # the represented rod radius
    xr, ar = fill(lambda r, z: r < rod_r, (0.0, bottom), (rod_r, bottom + length), spacing)
    rod = RigidBody("rod", xr, ar, density=q["rod_density"] or m.rho_s, velocity=(0.0, -v0),
                    prescribed="all", axisymmetric=True, contact=q["contact"],
                    mu_w=math.inf if rod_contact == "noslip" else 0.0)
    sim = Simulation(grid, sets, [rod], mode=mode, gravity=(0.0, -gravity), cfl=cfl,
                     name="intruder", **extra)
    geostatic(sim, sets=[s.name for s in sets])           # the bed at rest under gravity
    half = 0.5 * length

    def fronts_now(sim):
        bed = sim.sets[0]
        rod = sim.bodies[0]
        tip = float(rod.center[1] - half)
        v = float(rod.velocity[1])
        uz = cell_field(bed.x, bed.v[:, 1], bed.m, (0.0, 0.0), h, (nx, nz))
        rc = (np.arange(nx) + 0.5) * h
        zc = (np.arange(nz) + 0.5) * h
        # the fronts are read from the bed's face under the rod: the tip, or the top of the
        # highest filled axis cell below it where the bed is pushed from a distance (mass)
        filled = np.flatnonzero(np.isfinite(uz[0]) & (zc < tip))
        face = min(tip, zc[filled[-1]] + 0.5 * h) if filled.size else tip
        zl = longitudinal_front(uz, rc, zc, face, v, FRONT_FRACTION)
        rt = transverse_front(uz, rc, zc, face, rod_r, v, FRONT_FRACTION)
        return tip, face, zl, rt

    def record(sim):
        tip, face, zl, rt = fronts_now(sim)
        return {"tip_depth_m": depth - tip, "face_depth_m": depth - face,
                "longitudinal_m": depth - zl, "transverse_m": rt,
                "max_f": float(np.max(sim.sets[0].f)),
                "max_phi": float(np.max(sim.sets[0].svol / sim.sets[0].V))}

    events = tuple(t for t in FIELD_TIMES if t <= t_end * (1 + 1e-9))
    notes = (f"layout {layout}; mode {mode}; rod radius {rod_r:g} m as represented "
             f"({q['rod_radius']:g} m given), length {length:g} m, tip {q['gap']:g} m above the "
             f"bed, prescribed v0 = {v0:g} m/s, contact {q['contact']}, {rod_contact}")
    return Scene(sim, t_end, q, frames=10, history_rows=400, record=record,
                 frame_times=events,
                 report=lambda sim, hist, out: report(sim, hist, out, q, rod_r),
                 notes=notes, undefined=("longitudinal_m", "transverse_m"))


# ---------------------------------------------------------------- analysis
def set_up_time(params) -> float:
    """The contact transient [s]: four crossings of the bed's larger dimension by the locked
    mixture's fastest (acoustic) wave, c^2 = (K + 4G/3 + kappa/(1 - phi_j))/rho (the near field
    around the rod is set up by reverberating pressure waves)."""
    m = get_material("intruder")
    rho = params["phi0"] * m.rho_s + (1.0 - params["phi0"]) * m.rho_f
    c = math.sqrt((m.K + 4.0 * m.G / 3.0 + m.kappa / (1.0 - m.phi_j)) / rho)
    return 4.0 * max(params["depth"], params["radius"]) / c


def jamming_structure(phi0) -> float:
    """The structure f at which phi_m(f) = phi_j + (phi_c - phi_j) f falls to phi0 (above it the
    bed is jammed; Table 6 set ``intruder``), clipped to [0, 1]."""
    m = get_material("intruder")
    return float(min(max((m.phi_j - phi0) / (m.phi_j - m.phi_c), 0.0), 1.0))


def fit_window(time, tip_depth, longitudinal, transverse, *, depth, radius, h, margin,
               t_min=0.0):
    """The stretch [t0, t1] over which the fronts are fitted (see the module docstring): of the
    stretches where both fronts exist ahead of the tip and grow, each ended by either front
    coming within ``margin`` of the floor or wall (no stretch after that) or falling back by
    more than h from its farthest position in the stretch (the next one starts at the next
    record where both exist), the one over which the fronts advance most (the lesser of the
    two advances).

    Parameters
    ----------
    time, tip_depth, longitudinal, transverse : (n,) arrays [s, m, m, m]
        Rod tip depth, longitudinal front depth (below the initial surface) and transverse front
        radius; NaN where no front.
    depth, radius, h, margin : float [m]
    t_min : float [s]
        No earlier start (the contact transient, the plug's jamming).

    Returns
    -------
    (t0, t1): NaN if the fronts never form.
    """
    t = np.asarray(time, float)
    zl, rt = np.asarray(longitudinal, float), np.asarray(transverse, float)
    formed = np.isfinite(zl) & np.isfinite(rt) & (zl - np.asarray(tip_depth, float) >= 2 * h) \
        & (t >= t_min)
    idx = np.arange(len(t))
    with np.errstate(invalid="ignore"):
        wall = (zl >= depth - margin) | (rt >= radius - margin)
        # running medians over 9 records: the binning and contact noise left out
        meds = [pd.Series(pos).rolling(9, center=True, min_periods=1).median().to_numpy()
                for pos in (zl, rt)]
    best, most = (float("nan"), float("nan")), -1.0
    start = np.flatnonzero(formed)
    while start.size:
        k0 = int(start[0])
        stop = wall & (idx >= k0)
        with np.errstate(invalid="ignore"):
            for med in meds:
                # a front falling back by more than a cell: the plug stopped growing (it
                # unjams once the stress waves return from the floor), or a transient ended
                far = np.fmax.accumulate(np.where(idx >= k0, med, np.nan))
                stop |= (med < far - h) & (idx >= k0)
        k1 = int(np.argmax(stop)) - 1 if stop.any() else len(t) - 1
        if k1 >= k0:
            # how far the fronts advance over the stretch: the lesser of the two
            adv = min(float(np.nanmax(p[k0:k1 + 1]) - np.nanmin(p[k0:k1 + 1])) for p in (zl, rt))
            if adv > most:
                best, most = (float(t[k0]), float(t[k1])), adv
        if not stop.any() or wall[k1 + 1]:
            break
        start = start[start > k1 + 1]
    return best


def analyse(front: pd.DataFrame, tip_depth, params, h, max_f=None) -> dict:
    """k_l, k_t and the fits' R^2 from the front table (``front.csv``'s columns).

    The fit starts after the contact transient (:func:`set_up_time`) and, if the bed jams
    (``max_f``, the largest structure per record, reaches :func:`jamming_structure`), not before
    it does; ``jammed`` in the result says whether it did (if not, the 'front' is the rod's
    viscous near field, not a jammed plug)."""
    t_min = set_up_time(params)
    f_jam = jamming_structure(params["phi0"])
    jammed, t_jam = False, float("nan")
    if max_f is not None:
        hit = np.flatnonzero(np.asarray(max_f, float) >= f_jam)
        if hit.size:
            jammed, t_jam = True, float(np.asarray(front["time_s"])[hit[0]])
            t_min = max(t_min, t_jam)
    t0, t1 = fit_window(front["time_s"], tip_depth, front["longitudinal_m"],
                        front["transverse_m"], depth=params["depth"], radius=params["radius"],
                        h=h, margin=params["fit_margin"], t_min=t_min)
    v0 = params["v0"]
    nan = float("nan")
    near = "" if jammed else ("the bed did not jam: the fronts are the rod's near field, "
                              "not a jammed plug")
    fits, short = {}, []
    for key, name in (("longitudinal_m", "longitudinal"), ("transverse_m", "transverse")):
        fits[key] = {"speed": nan, "r2": nan, "points": 0, "intercept": nan}
        if not math.isfinite(t0):
            continue
        # a speed needs the front to cross cells: at least 2 h over the fit window, else it is
        # not resolved by the grid (a window of a few us gave k_l ~ -1e302 at v0 = 1e-300)
        ts, c = np.asarray(front["time_s"], float), np.asarray(front[key], float)
        sel = (ts >= t0) & (ts <= t1) & np.isfinite(c)
        travel = float(c[sel].max() - c[sel].min()) if sel.any() else 0.0
        if travel < 2.0 * h:
            short.append(f"the {name} front advances only {travel:.3g} m")
        else:
            fits[key] = fit_speed(front["time_s"], front[key], t0, t1)
    fl, ft = fits["longitudinal_m"], fits["transverse_m"]
    if not math.isfinite(t0):
        why = ("not measured: no stretch after the contact transient "
               f"({set_up_time(params):.3g} s) where both fronts exist and grow")
    elif short:
        why = (f"not measured: {' and '.join(short)} over the fit window [{t0:.4g}, {t1:.4g}] s, "
               f"less than two cells (h = {h:g} m); run longer (t_end), faster (v0) or on a "
               "finer grid")
    else:
        why = ""
    note = "; ".join(x for x in (why, near) if x)
    k_l = fl["speed"] / v0 - 1.0
    k_t = ft["speed"] / v0
    ratio = k_l / k_t if (math.isfinite(k_t) and k_t != 0) else nan
    return {"phi0": params["phi0"], "v0_m_per_s": v0, "k_l": k_l, "k_t": k_t,
            "k_l_over_k_t": ratio, "r2_longitudinal": fl["r2"], "r2_transverse": ft["r2"],
            "v_fl_m_per_s": fl["speed"], "v_ft_m_per_s": ft["speed"],
            "fit_t_start_s": t0, "fit_t_end_s": t1, "fit_points": int(min(fl["points"],
                                                                          ft["points"])),
            "front_fraction": FRONT_FRACTION, "layout": params.get("layout", "default"),
            "mode": params["mode"], "contact": params.get("contact", "touch"),
            "jammed": jammed, "t_jam_s": t_jam, "f_jam": f_jam,
            "max_f_over_f_jam": (float(np.max(max_f)) / f_jam if max_f is not None and
                                 len(max_f) else nan),
            "set_up_time_s": set_up_time(params),
            "cells_per_mm": params["cells_per_mm"], "fit_note": note}


def report(sim, history, out, params, rod_r):
    out = Path(out)
    front = history[["time_s", "longitudinal_m", "transverse_m"]].copy()
    atomic_write_csv(out / "front.csv", front, empty_ok=("longitudinal_m", "transverse_m"))
    res = analyse(front, history["tip_depth_m"].to_numpy(), params, sim.grid.h,
                  history["max_f"].to_numpy())
    res["rod_radius_m"] = rod_r
    atomic_write_json(out / "summary.json", res, nullable=_NULLABLE)
    return [plots.save(front_figure(history, res, params), out / "front.png"),
            plots.save(fields_figure(out, res), out / "fields.png")]


def jam_text(res) -> str:
    """What the run shows about jamming, from its summary: 'jammed at T ms (max f/f_jam X)' or
    'did not jam (max f/f_jam X < 1)'."""
    mx = _value(res.get("max_f_over_f_jam"))
    tail = "" if mx is None else f"max f/f_jam {mx:.3g}"
    if res["jammed"]:
        return f"jammed at {1e3 * res['t_jam_s']:.3g} ms" + (f" ({tail})" if tail else "")
    return "did not jam" + (f" ({tail} < 1)" if tail else "")


def front_title(res, params) -> str:
    """front.png's title: the case, the jam state, the fit window and what was fitted (the
    factors of a plug, or the near field's speeds when the bed did not jam)."""
    head = f"phi0 {params['phi0']:g}, v0 {params['v0']:g} m/s, layout {params['layout']}, " \
           f"rules {params['rules']}: bed {jam_text(res)}"
    t0, t1 = _value(res["fit_t_start_s"]), res["fit_t_end_s"]
    if t0 is None:
        return head + "\nno fit window: " + res["fit_note"]
    kl, kt = (_value(res[k]) for k in ("k_l", "k_t"))
    window = f"fit {1e3 * t0:.3g}-{1e3 * t1:.3g} ms"
    why = res["fit_note"].split(" over the fit window")[0] if None in (kl, kt) else ""
    if not res["jammed"]:
        text = (f"{window}: near-field speeds, not a plug's fronts: v_fl/v0 - 1 = {_fmt(kl)}, "
                f"v_ft/v0 = {_fmt(kt)}")
    else:
        ratio = None if None in (kl, kt) or kt == 0 else kl / kt
        text = f"{window}: k_l = {_fmt(kl)}, k_t = {_fmt(kt)}, k_l/k_t = {_fmt(ratio)}"
    return head + "\n" + text + (f"\n({why})" if why else "")


def _value(x):
    """None for an undefined summary value (null or NaN), else the float."""
    return None if x is None or not math.isfinite(x) else float(x)


def _fmt(x) -> str:
    return "null" if x is None else f"{x:.3g}"


def front_figure(history, res, params):
    """front.png: both fronts and the rod tip against time, the fit window and its straight
    lines for each speed the analysis measured (least squares on the window's finite records,
    as in :func:`analyse`); ``res`` is the run's summary (null or NaN where undefined)."""
    fig, ax = plots.plt.subplots(figsize=(8.5, 4.8), layout="constrained")
    t = history["time_s"].to_numpy()
    ax.plot(t * 1e3, history["longitudinal_m"] * 1e3, "b.", ms=3, label="longitudinal (depth)")
    ax.plot(t * 1e3, history["transverse_m"] * 1e3, "r.", ms=3, label="transverse (radius)")
    ax.plot(t * 1e3, history["tip_depth_m"] * 1e3, "k-", lw=1, label="rod tip depth")
    t0, t1 = _value(res["fit_t_start_s"]), res["fit_t_end_s"]
    if t0 is not None:
        ax.axvspan(t0 * 1e3, t1 * 1e3, color="0.9", zorder=0, label="fit window")
        for col, speed, c in (("longitudinal_m", "v_fl_m_per_s", "b"),
                              ("transverse_m", "v_ft_m_per_s", "r")):
            fit = fit_speed(t, history[col].to_numpy(), t0, t1)
            if _value(res[speed]) is not None:          # a speed the analysis measured
                tt = np.array([t0, t1])
                ax.plot(tt * 1e3, (fit["intercept"] + fit["speed"] * tt) * 1e3, c + "-", lw=2)
    ax.set_xlabel("t [ms]")
    ax.set_ylabel("front position [mm]")
    ax.set_title(front_title(res, params), fontsize=8)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))      # off the data
    return fig


def event_fields(out) -> list:
    """u_z binned to the cells at each event snapshot (FIELD_TIMES) of the run in ``out``.

    Returns
    -------
    list of (t [s], u_z (nx, nz) [m/s] with NaN in empty cells, rod points (n, 2) [m]).
    """
    q = resolved(json.loads((Path(out) / "manifest.json").read_text())["params"])
    h, nx, nz = grid_shape(q)
    return [(float(f["time_s"]), cell_field(f["bed.x"], f["bed.v"][:, 1], f["bed.m"], (0.0, 0.0),
                                            h, (nx, nz)), f["body.rod.x"])
            for f in load_frames(out, tag="event")]


def uz_norm(v0, fields):
    """The colour scale of u_z panels: symmetric about 0 (a diverging map), spanning -v0 and
    every finite value of ``fields`` (the heave beside the rod is positive)."""
    top = max([v0] + [float(np.nanmax(np.abs(f))) for f in fields if np.isfinite(f).any()])
    return mcolors.Normalize(-top, top)


def draw_uz(ax, uz, h, v0, rod_x, rod_r, title, norm):
    """One Fig. 6(a)-(c) panel: u_z [m/s] on ``norm`` (:func:`uz_norm`, map RdBu_r: the bed
    moving down in blue) with the u_z = -v0/2 front contour (black) and the rod (grey).
    Returns the image."""
    nx, nz = uz.shape
    rc, zc = (np.arange(nx) + 0.5) * h * 1e3, (np.arange(nz) + 0.5) * h * 1e3
    im = ax.imshow(uz.T, origin="lower", extent=(0.0, nx * h * 1e3, 0.0, nz * h * 1e3),
                   cmap="RdBu_r", norm=norm)
    if np.nanmin(uz) < -0.5 * v0:
        ax.contour(rc, zc, uz.T, levels=[-0.5 * v0], colors="k", linewidths=1.5)
    _rod(ax, rod_x, rod_r)
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("r [mm]")
    ax.set_ylabel("z [mm]")
    return im


def _rod(ax, rod_x, rod_r):
    ax.fill_between([0, rod_r * 1e3], rod_x[:, 1].min() * 1e3, rod_x[:, 1].max() * 1e3,
                    color="0.45")


def end_fields(out) -> dict:
    """The last snapshot of the run in ``out`` on its cells: t [s], u_z, |D_rz|, |D_zz| [1/s]
    (central differences of the cell velocities; one-sided at the edges) and f/f_jam (the
    largest f of each cell), NaN in empty cells, and the rod's points."""
    q = resolved(json.loads((Path(out) / "manifest.json").read_text())["params"])
    h, nx, nz = grid_shape(q)
    f = load_frames(out)[-1]
    x, v, m = f["bed.x"], f["bed.v"], f["bed.m"]
    ur, uz = (cell_field(x, v[:, k], m, (0.0, 0.0), h, (nx, nz)) for k in (0, 1))
    dur_dr, dur_dz = np.gradient(ur, h)
    duz_dr, duz_dz = np.gradient(uz, h)
    idx = np.clip((x / h).astype(int), 0, [nx - 1, nz - 1])
    fmax = np.full((nx, nz), np.nan)
    fmax[idx[:, 0], idx[:, 1]] = -np.inf
    np.maximum.at(fmax, (idx[:, 0], idx[:, 1]), f["bed.f"])
    return {"t": float(f["time_s"]), "uz": uz, "D_rz": np.abs(0.5 * (dur_dz + duz_dr)),
            "D_zz": np.abs(duz_dz), "f_over_f_jam": fmax / jamming_structure(q["phi0"]),
            "rod_x": f["body.rod.x"], "h": h, "params": q}


def fields_figure(out, res):
    """fields.png (Fig. 6): u_z at the event times and at the end (one diverging scale centred
    at 0), then |D_rz|, |D_zz| (square-root scale from 0 to their largest value) and f/f_jam
    at the end (f_jam: 1, contoured), three panels a row; the title says whether the bed
    jammed (``res``, the run's summary)."""
    end = end_fields(out)
    h, q, rod_r = end["h"], end["params"], res["rod_radius_m"]
    v0 = q["v0"]
    panels = [(t, uz, xr) for t, uz, xr in event_fields(out)]
    if not panels or abs(panels[-1][0] - end["t"]) > 1e-9:
        panels.append((end["t"], end["uz"], end["rod_x"]))
    rows = -(-len(panels) // 3) + 1
    fig, axs = plots.plt.subplots(rows, 3, figsize=(11.0, 3.0 * rows + 0.5), squeeze=False,
                                 layout="constrained")
    norm = uz_norm(v0, [p[1] for p in panels])
    for ax, (t, uz, xr) in zip(axs.flat, panels):
        im = draw_uz(ax, uz, h, v0, xr, rod_r, f"u_z at t = {t * 1e3:.1f} ms", norm)
    fig.colorbar(im, ax=axs[:-1, :], label="u_z [m/s] (front u_z = -v0/2)", shrink=0.9)
    for ax in axs[:-1].flat[len(panels):]:
        ax.axis("off")
    nx, nz = end["uz"].shape
    ext = (0.0, nx * h * 1e3, 0.0, nz * h * 1e3)
    rc, zc = (np.arange(nx) + 0.5) * h * 1e3, (np.arange(nz) + 0.5) * h * 1e3
    for ax, key, label in zip(axs[-1], ("D_rz", "D_zz", "f_over_f_jam"),
                              ("|D_rz| [1/s]", "|D_zz| [1/s]", "f/f_jam")):
        field = end[key]
        top = float(np.nanmax(field)) if np.isfinite(field).any() else 1.0
        if key == "f_over_f_jam":
            nrm, cmap = mcolors.Normalize(0.0, max(1.0, top)), "cividis"
        else:
            nrm, cmap = mcolors.PowerNorm(0.5, 0.0, top if top > 0 else 1.0), "magma"
        im = ax.imshow(field.T, origin="lower", extent=ext, cmap=cmap, norm=nrm)
        if key == "f_over_f_jam":
            if np.nanmax(field) >= 1.0:
                ax.contour(rc, zc, field.T, levels=[1.0], colors="r", linewidths=1.2)
        elif np.nanmin(end["uz"]) < -0.5 * v0:
            ax.contour(rc, zc, end["uz"].T, levels=[-0.5 * v0], colors="c", linewidths=1.5)
        _rod(ax, end["rod_x"], rod_r)
        ax.set_title(f"{label.split(' [')[0]} at t = {end['t'] * 1e3:.1f} ms", fontsize=9)
        ax.set_xlabel("r [mm]")
        ax.set_ylabel("z [mm]")
        fig.colorbar(im, ax=ax, label=label, shrink=0.9)
    fig.suptitle(f"phi0 {q['phi0']:g}, v0 {v0:g} m/s, layout {q['layout']}, rules "
                 f"{q['rules']}: bed {jam_text(res)}; contours: u_z = -v0/2 (black, cyan), "
                 "f = f_jam (red)", fontsize=9)
    return fig


# ---------------------------------------------------------------- sweeps (Fig. 7)
SWEEP_COLUMNS = ("phi0", "v0_m_per_s", "k_l", "k_t", "k_l_over_k_t", "r2_longitudinal",
                 "r2_transverse")
#: fronts.csv's columns after ``jammed`` (from summary.json): first jamming time [s], largest
#: f/f_jam
_JAM_COLUMNS = ("t_jam_s", "max_f_over_f_jam")
#: equivalent shear strain per unit axial strain of an isochoric axial compression
#: (gdot = sqrt(2 D':D')): planar 2, axisymmetric sqrt(3)
STRAIN_FACTOR = {"planar": 2.0, "axisymmetric": math.sqrt(3.0)}


def onset_strain_k_l(k_t, flow="axisymmetric"):
    """k_l of the longitudinal front that jams at the same equivalent shear strain as a
    transverse front of factor k_t (both steady; validation.cases_intruder derives it):
    c ln(1 + 1/k_l) = 1/k_t, i.e. k_l = 1/(exp(1/(c k_t)) - 1), with c = STRAIN_FACTOR[flow].

    Parameters
    ----------
    k_t : float or array, > 0
    flow : "planar" or "axisymmetric"

    Returns
    -------
    k_l, same shape (between c k_t - 1/2 and c k_t).
    """
    return 1.0 / np.expm1(1.0 / (STRAIN_FACTOR[flow] * np.asarray(k_t, dtype=float)))


def reference_lines(ax, kt_max):
    """Han et al.'s k_l = 2 k_t and the single-onset-strain curves, for k_t in (0, kt_max]."""
    kt = np.linspace(kt_max / 200.0, kt_max, 200)
    ax.plot(kt, 2 * kt, "k--", label="k_l = 2 k_t (Han et al. 2016)")
    for flow, style in (("axisymmetric", "g-"), ("planar", "g:")):
        ax.plot(kt, onset_strain_k_l(kt, flow), style, lw=1,
                label=f"one onset strain, {flow}")


def sweep_report(table, out) -> list:
    """``out/fronts.csv`` (one row per complete case: phi0, v0_m_per_s, k_l, k_t, k_l_over_k_t,
    r2_longitudinal, r2_transverse, jammed (whether the bed jammed during the run), t_jam_s,
    max_f_over_f_jam (from summary.json), case) and ``out/fronts.png`` (k_l against k_t with
    the line k_l = 2 k_t and the single-onset-strain curves (:func:`reference_lines`), Fig. 7;
    a case that never jammed drawn faint), from each case's ``summary.json``."""
    out = Path(out)
    rows = [{**{k: (np.nan if s.get(k) is None else s[k]) for k in (*SWEEP_COLUMNS, *_JAM_COLUMNS)},
             "jammed": bool(s.get("jammed", True)), "case": case}
            for case, _, s in case_summaries(table, out)]
    if not rows:
        return []
    df = pd.DataFrame(rows, columns=[*SWEEP_COLUMNS, "jammed", *_JAM_COLUMNS, "case"])
    undefined = ("k_l", "k_t", "k_l_over_k_t", "r2_longitudinal", "r2_transverse",
                 *_JAM_COLUMNS)
    paths = [atomic_write_csv(out / "fronts.csv", df, empty_ok=undefined)]
    fig, ax = plots.plt.subplots(figsize=(7.5, 4.5), layout="constrained")
    ok = df.dropna(subset=["k_l", "k_t"])
    # colour range of phi0: a single phi0 gets a +-0.005 band (a zero-width range drew a
    # degenerate colour bar with an offset label)
    lo, hi = float(df["phi0"].min()), float(df["phi0"].max())
    if hi - lo < 1e-6:
        lo, hi = lo - 0.005, hi + 0.005
    for v0, mk in zip(sorted(ok["v0_m_per_s"].unique()), "osD^v"):
        for jam in (True, False):
            sel = ok[(ok["v0_m_per_s"] == v0) & (ok["jammed"] == jam)]
            if not len(sel):
                continue
            # a case whose bed never jammed (the 'front' is the rod's viscous near field, not a
            # plug): open marker
            sc = ax.scatter(sel["k_t"], sel["k_l"], c=sel["phi0"], cmap="coolwarm", marker=mk,
                            vmin=lo, vmax=hi,
                            edgecolors="k", linewidths=1.0 if jam else 2.0,
                            alpha=1.0 if jam else 0.35,
                            label=f"v0 = {v0:g} m/s" + ("" if jam else ", not jammed"))
    if len(ok):
        fig.colorbar(sc, ax=ax, label="phi0")
        if ok["k_t"].max() > 0:
            reference_lines(ax, 1.1 * ok["k_t"].max())
        ratio = ok["k_l_over_k_t"].dropna()
        jam = ok.loc[ok["jammed"], "k_l_over_k_t"].dropna()
        ax.set_title(f"{len(ratio)} of {len(df)} cases with both fronts fitted, "
                     f"{len(jam)} of them jammed\nk_l/k_t of the jammed: " + (
                         f"{jam.mean():.2f} +- {jam.std(ddof=0):.2f} (min {jam.min():.2f}, "
                         f"max {jam.max():.2f})" if len(jam) else "none"), fontsize=9)
    ax.set_xlabel("k_t = v_ft/v0")
    ax.set_ylabel("k_l = v_fl/v0 - 1")
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.25, 1.0))      # beside the bar
    paths.append(plots.save(fig, out / "fronts.png"))
    return [Path(p) for p in paths]
