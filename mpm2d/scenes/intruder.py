"""A rigid rod driven at constant speed v0 into a suspension bed: jamming fronts (Figs. 6-7).

The controlled-intrusion experiment of Han, Peters & Jaeger (Nat. Commun. 7, 12243, 2016) as
simulated by Baumgarten & Kamrin (section "Impact activated solidification", Table 6, Figs. 6-7):
a flat-ended rod moves down at a prescribed speed v0 into a density-matched cornstarch
suspension; a solid plug grows ahead of it, its front (u_z = v0/2) moving at v_fl along the axis
and v_ft across it, with k_l = v_fl/v0 - 1 about twice k_t = v_ft/v0 for every phi and v0.

Equations: axisymmetric (r, z) MPM of the Table 8 law (rheology.local_update) with the Table 6
parameter set ``intruder`` (Hermes 2016 steady fit, eta0 = 4.6 mPa s, rho_s = rho_f = 1620
kg/m^3, G = 3.8e7 Pa, K = 8.3e7 Pa, K0 = 0.2; d = 5.85 um, K3 = 4.715, K4 = 0; kappa = K, our
choice, the paper gives no fluid modulus). Default mode: the locked mixture (one velocity field,
undrained pore pressure); ``mode=two-phase`` runs grains and fluid on two fields with implicit
Beetstra drag. The rod is a rigid body with every component prescribed (velocity (0, -v0) from
t = 0) meeting the bed through multi-velocity-field contact (mpm2d.contact: gap criterion,
Coulomb mu_w, free separation); its reaction force is recorded.

Drained or undrained (DESIGN.md section 5, whose "c_v of order 1 m^2/s" is 1000x too large),
numbers for phi0 = 0.47: Beetstra F = 17.3, Darcy permeability k = (1 - phi) d^2/(18 phi F) =
1.24e-13 m^2 (k/eta0 = 2.7e-11 m^2/(Pa s)); with the skeleton's constrained modulus M = K + 4G/3
= 1.34e8 Pa and the fluid's storage (1 - phi)/kappa, c_v = k/(eta0 (1/M + (1 - phi)/kappa)) =
1.9e-3 m^2/s (3.6e-3 without the storage). Over the plug's 1 cm the pore pressure needs L^2/c_v
= 51 ms to drain, longer than the 20 ms run: the intrusion is undrained, grains and fluid move
together, and an unjammed skeleton (phi < phi_m), which has no stiffness, drains even less (the
Darcy velocity k/eta0 grad p ~ 2.7e-5 m/s for 1e4 Pa over 1 cm is 1e-4 of v0 = 0.175 m/s and
changes phi by ~5e-5 in 20 ms), as Han et al. measured (no detectable change of packing fraction
at the front). So the locked mixture is the default; the two-phase mode is kept to show the
difference: measured at phi0 = 0.47, v0 = 0.5 m/s over 8 ms, two-phase gives k_l 8.5% and k_t
8.4% lower (the same k_l/k_t, 0.64) at 2.3x the wall time (validation case
``mpm2d_intruder_modes``).

Geometry and choices where the paper is silent (Baumgarten & Kamrin give only "axisymmetric MPM
on a 50x35 element Cartesian grid with 1mm x 1mm resolution"; the author's code,
aaronbaumgarten/mpm_3d, holds no intruder scene in any commit of its history: no script, config
or driver names or mentions an intruder, Han et al., or 0.175 m/s):
- bed: radius 50 mm, depth 35 mm (the paper's grid is the bed); the grid adds, above the bed,
  room for the rod (v0 t_end + 5 mm) and for the free surface to heave: 50 x (35 + that) cells.
  The author's impact generator (mpm_pygen/GenerateImpactMixture2D_v2.py) writes its grid as
  Nx x Ny = radius x height with the room above the bed inside the height (0.30 m of bed in a
  0.60 m grid) and 3 x 3 points per cell; read that way, the paper's 50 x 35 would be 50 mm of
  radius by 35 mm of height including the rod's room, a shallower bed. Unverified either way; a
  deeper bed (35 mm radius x 50 mm) moved k_l/k_t by less than 0.1 (below);
- rod radius 3.175 mm (a 1/4-inch rod, the diameter we take for Han et al.'s intruder: we
  could not check it against their methods section from here, so it is a parameter; 6.35 and
  12.7 mm moved k_l/k_t by less than 0.15, below);
  on the point lattice (spacing h/2) the rod is ``n h/2`` wide, n = floor(2 rod_radius/h):
  3.0 mm at h = 1 mm; the transverse front is searched beyond that represented radius;
- rod contact no-slip (mu_w = inf: a viscous suspension wets the rod; ``rod_contact=
  frictionless`` for mu_w = 0), free to separate; the tip starts at the free surface;
- container: no-slip floor and outer wall (a rigid container wetted by the suspension), axis
  r = 0, free top surface;
- the bed starts at rest (mpm2d.geostatic): loose (phi0 < phi_j), so the pore pressure carries
  the weight and f = 0.

Fronts (Han et al. 2016, mpm2d.fronts): the vertical velocity of the bed's points binned to the
grid's cells (mass-weighted); the longitudinal front is the depth below the initial surface
where u_z/(-v0) falls below 1/2 on the axis column below the rod's tip (linear interpolation
between cell centres), the transverse front the radius where it does on the row of cells just
below the tip, searched outward from the rod's radius. Fit: straight lines over the stretch
from the first record after the contact transient (four acoustic crossings of the bed, 0.3 ms
on the default bed) and after the bed first jams (a point's f reaches f_jam, phi_m(f_jam) =
phi0; ``jammed`` in summary.json says whether it did) where both fronts exist and the
longitudinal front is at least 2 cells ahead of the tip until either front comes within
``fit_margin`` of the floor or the outer wall, or either (its running median over 9 records)
falls back by more than a cell (h) from its farthest position (the plug stopped growing: it
unjams once the stress waves come back from the floor); records where a front is momentarily
undefined (the cell under the tip lagging the rod by more than v0/2 for a step) are left out of
the fits, not ended at.
k_l = v_fl/v0 - 1, k_t = v_ft/v0: the paper's "(v_fl - v0)/v_ft ~ 2 ... transverse and
longitudinal front propagation factors k_t = v_ft/v0 and k_l = v_fl/v0 - 1", front "defined by
u_z = 0.5 v0"; v_fl is the lab-frame speed of the front along the axis (v_fl - v0 its speed
ahead of the tip, the same number whether the front is read from the surface or from the tip).

Status against Fig. 7 (measured, locked mixture, 1 mm): NOT reproduced. The plug grows about
as fast across as along the axis in the lab frame (v_fl ~ v_ft), where Han et al.'s ratio needs
v_fl = (2 + 1/k_t) v_ft, so k_l/k_t = 0.6-1.0 instead of ~2. At phi0 = 0.47, v0 = 0.5 m/s
(fit 0.5-5 ms): the default measure 0.86; the transverse front read at the tip's row, 3 or 6 mm
below the tip, at 5 or 10 mm depth, or as the plug's widest radius: 0.67-0.86 (the reading moves
k_t by < 30%, never towards 2); a frictionless rod 0.98; rod radius 6.35 mm 0.97, 12.7 mm 0.93;
slip floor and wall 1.02; a 35 mm radius x 50 mm deep bed 0.79; the rod started 12 mm deep (no
free surface at the tip) 0.86; h = 0.5 mm 0.89 (over 5 ms). The fields show why: the plug's
side is a thin shear band (high gdot_p, so H = (taubar/tau*)^(3/2) and the structure rate K0 H
gdot_p are high and f reaches f_jam within a cell or two), while ahead of the plug u_z falls
off over ~10 mm (a low rate), so jamming spreads at about the same lab speed both ways. That is
the model as the engine integrates it (rheology.local_update, mpm2d), not the front reading.
At v0 = 0.175-0.2 m/s and phi0 <= 0.47 the bed does not jam within 20 ms (max f ~ 0.3 <
f_jam = 0.66-0.76): ``jammed`` is false and the 'front' is the rod's near field, whereas the
paper's Fig. 6 shows a plug at phi = 0.47, v0 = 0.175 m/s. Measured at that default: not jammed
in two-phase mode either (k_l/k_t 1.86 against 1.80 locked, transverse R^2 0.87), nor with rod
radii 6.35 or 12.7 mm (2.2, 1.4). The 0-D law at phi = 0.47 (``rheometer startup --material
intruder --phi 0.47 --rate R --t-end 0.02``) shear-jams within 20 ms only above ~30 1/s (at
11 ms for 40 1/s; 20 1/s reaches f = 0.11), while the rates the 1 mm grid resolves around the
rod are 7-10 1/s (|D_rz|, |D_zz| at 20 ms; v0/R_rod = 55 1/s is spread over ~10 mm; max f/f_m
0.28). At h = 0.5 mm the same default run grows a plug: max f/f_m 0.996, strain rate at its
boundary, k_l = 2.02, k_t = 1.29, k_l/k_t = 1.56, R^2 0.99/0.98 (f only tends to f_m = f_jam
with Delta = 0, so ``jammed`` stays false); phi0 = 0.50, v0 = 0.5 at 0.5 mm: 1.56 (R^2
0.97/0.93, fit 0.5-2.7 ms). At h = 0.25 mm (``cells_per_mm=4``, 39 min on one thread) the
default jams at 2.6 ms: k_l = 1.98, k_t = 1.84, k_l/k_t = 1.07 (R^2 0.98/0.95). So k_l converges
(1.08, 2.02, 1.98 at 1, 0.5, 0.25 mm) while k_t grows as the plug's side shear band is resolved
(0.60, 1.29, 1.84): refinement takes the ratio away from 2 (1.80, 1.56, 1.07); at v0 = 0.5
and 0.25 mm (5 ms runs) phi0 = 0.47, 0.48, 0.50 give 1.03, 1.67, 1.82 (k_l 4.17, 7.59, 6.44; k_t
4.06, 4.55, 3.55), against 0.81, 0.86, 1.61 at 1 mm and 1.31, 1.10, 1.56 at 0.5 mm: the grid
dependence differs from case to case. The ten Fig. 7
cases at 1 mm (``mpm2d sweep intruder --set phi0=0.46,...,0.50 --set v0=0.2,0.5``; at 0.5 mm, with
``--set cells_per_mm=2``: mean 1.24, one of ten in range): k_l/k_t = 1.74 and 1.69 (phi0 0.46,
0.47 at 0.2 m/s, not jammed), 0.99, 0.81, 0.53, 0.86, 1.38, 1.27, 0.84, 1.61 (phi0 0.46 and 0.47
at 0.5 m/s; 0.48 at 0.2, 0.5; 0.49 at 0.2, 0.5; 0.50 at 0.2, 0.5): mean 1.17, sd 0.40, three
of ten in [1.5, 2.5]. The ratio also depends on the fit window, because the longitudinal front
slows down long before the floor: over 0.5-4 ms it is 0.8-1.6 for the 0.5 m/s cases (jammed
within 0.4 ms), 1.3 at phi0 = 0.50, 0.2 m/s (jammed at 0.3 ms), and 2.3-3.3 for phi0 <= 0.49 at
0.2 m/s, whose bed has not jammed by then (not at all, or after 2 ms): the unjammed near field
of the rod is elongated along the axis, the jammed plug is not.

Parameters: phi0, v0 [m/s], t_end [s], radius, depth [m], cells_per_mm (1/h in 1/mm),
rod_radius [m], rod_contact, mode, fit_margin [m], gravity [m/s^2], cfl.

Outputs (besides history.csv, frames, manifest): ``front.csv`` (time_s, longitudinal_m,
transverse_m), ``front.png``, ``summary.json`` (k_l, k_t, R^2 of each fit, window, speeds),
``fields.png`` (Fig. 6(a)-(e): u_z at 6.2, 13.2 and 20 ms, |D_rz| and |D_zz| at t_end with the
u_z = 0.5 v0 contour bold). A sweep (``mpm2d sweep intruder --set phi0=... --set v0=...``)
writes ``fronts.csv`` and ``fronts.png`` (the k_l-k_t scatter with k_l = 2 k_t, Fig. 7).

Run: ``mpm2d run intruder --out intruder`` (mode: locked mixture)
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from rheology import get_material
from rheology.io import atomic_write_csv, atomic_write_json

from .. import plots
from ..bodies import RigidBody, fill
from ..fronts import cell_field, fit_speed, longitudinal_front, transverse_front
from ..geostatic import geostatic
from ..grid import Grid
from ..output import load_frames
from . import spec
from .beds import suspension_bed
from ..run import Scene
from ..simulation import Simulation

#: Fig. 6(a)-(c) snapshot times [s]
FIELD_TIMES = (6.2e-3, 13.2e-3, 20e-3)
#: the front threshold u_z / v (Han et al. 2016)
FRONT_FRACTION = 0.5
#: rod length above its travel [m]
ROD_EXTRA = 5e-3
#: summary.json keys that may be undefined (no front formed, too few points)
_NULLABLE = ("k_l", "k_t", "k_l_over_k_t", "r2_longitudinal", "r2_transverse",
             "v_fl_m_per_s", "v_ft_m_per_s", "fit_t_start_s", "fit_t_end_s", "t_jam_s")


def _rod_length(p) -> float:
    return p["v0"] * p["t_end"] + ROD_EXTRA


def _headroom_cells(p) -> int:
    h = 1e-3 / p["cells_per_mm"]
    return int(math.ceil(_rod_length(p) / h)) + 3


def _points(p) -> float:
    n = ((p["radius"] * p["depth"] + p["rod_radius"] * _rod_length(p))
         * (p["cells_per_mm"] * 1e3) ** 2 * 4)
    return n * (2 if p["mode"] == "two-phase" else 1)


@spec.parameters_of(
    phi0=spec.phi_below_jamming(fixed="intruder", doc="solid volume fraction of the bed"),
    v0=spec.Param(0.0, 10.0, lo_closed=False, unit="m/s", doc="rod speed (downwards)"),
    t_end=spec.Param(0.0, lambda p: 0.8 * p["depth"] / p["v0"], lo_closed=False, unit="s",
                     doc="end time", note="the rod travels at most 80% of the bed depth"),
    radius=spec.Param(lambda p: p["rod_radius"] + 4e-3 / p["cells_per_mm"], 1.0, unit="m",
                      doc="bed (container) radius", note="at least the rod radius + 4 cells"),
    depth=spec.Param(lambda p: 4e-3 / p["cells_per_mm"], 1.0, unit="m", doc="bed depth",
                     note="at least 4 cells"),
    cells_per_mm=spec.Param(0.1, 20.0, unit="1/mm", doc="1/h in 1/mm (1: the paper's 1 mm)"),
    rod_radius=spec.Param(lambda p: 1e-3 / p["cells_per_mm"], 0.5, unit="m", doc="rod radius",
                          note="at least one cell"),
    rod_contact=spec.Param(choices=("noslip", "frictionless"),
                           doc="rod-suspension contact: no slip (mu_w = inf) or mu_w = 0"),
    mode=spec.Param(choices=("locked mixture", "two-phase"),
                    doc="locked mixture (undrained, default) or two-phase (grains + fluid)"),
    fit_margin=spec.Param(0.0, lambda p: 0.5 * min(p["depth"], p["radius"]), unit="m",
                          doc="fronts fitted until within this distance of the floor or wall",
                          note="at most half the bed depth and radius"),
    gravity=spec.gravity(), rules=spec.rules(), cfl=spec.cfl(),
    size=lambda p: (_points(p), (p["radius"] * p["cells_per_mm"] * 1e3 + 5)
                    * (p["depth"] * p["cells_per_mm"] * 1e3 + _headroom_cells(p) + 5)))
def setup(phi0=0.47, v0=0.175, t_end=0.02, radius=0.05, depth=0.035, cells_per_mm=1.0,
          rod_radius=3.175e-3, rod_contact="noslip", mode="locked mixture", fit_margin=5e-3,
          gravity=9.81, rules="table8", cfl=0.5):
    params = dict(phi0=phi0, v0=v0, t_end=t_end, radius=radius, depth=depth,
                  cells_per_mm=cells_per_mm, rod_radius=rod_radius, rod_contact=rod_contact,
                  mode=mode, fit_margin=fit_margin, gravity=gravity, rules=rules, cfl=cfl)
    h = 1e-3 / cells_per_mm
    m = get_material("intruder", rules=rules)
    nx = int(round(radius / h))
    nz = int(round(depth / h)) + _headroom_cells(params)
    grid = Grid(nx, nz, h, axisymmetric=True,
                boundaries=dict(xmin="axis", xmax="noslip", ymin="noslip", ymax="free"))
    spacing = h / 2
    x, area = fill(lambda r, z: np.ones_like(r, dtype=bool), (0.0, 0.0), (nx * h, depth), spacing)
    sets, extra = suspension_bed(m, x, area, phi0, mode, axisymmetric=True)
    length = _rod_length(params)
    nrod = int(math.floor(rod_radius / spacing + 1e-9))
    rod_r = nrod * spacing                                 # the represented rod radius
    xr, ar = fill(lambda r, z: r < rod_r, (0.0, depth), (rod_r, depth + length), spacing)
    rod = RigidBody("rod", xr, ar, density=m.rho_s, velocity=(0.0, -v0), prescribed="all",
                    axisymmetric=True, mu_w=math.inf if rod_contact == "noslip" else 0.0)
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
        zl = longitudinal_front(uz, rc, zc, tip, v, FRONT_FRACTION)
        rt = transverse_front(uz, rc, zc, tip, rod_r, v, FRONT_FRACTION)
        return tip, zl, rt

    def record(sim):
        tip, zl, rt = fronts_now(sim)
        return {"tip_depth_m": depth - tip, "longitudinal_m": depth - zl, "transverse_m": rt,
                "max_f": float(np.max(sim.sets[0].f)),
                "max_phi": float(np.max(sim.sets[0].svol / sim.sets[0].V))}

    events = tuple(t for t in FIELD_TIMES if t <= t_end * (1 + 1e-9))
    notes = (f"mode {mode}; rod radius {rod_r:g} m as represented ({rod_radius:g} m given), "
             f"length {length:g} m, prescribed v0 = {v0:g} m/s, contact {rod_contact}")
    return Scene(sim, t_end, params, frames=10, history_rows=400, record=record,
                 frame_times=events,
                 report=lambda sim, hist, out: report(sim, hist, out, params, rod_r),
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
    """The stretch [t0, t1] over which the fronts are fitted (see the module docstring).

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
    if not formed.any():
        return float("nan"), float("nan")
    k0 = int(np.argmax(formed))
    with np.errstate(invalid="ignore"):
        near = (zl >= depth - margin) | (rt >= radius - margin)
        # a front that falls back by more than a cell from its farthest position: the plug
        # stopped growing (it unjams once the stress waves return from the floor)
        for pos in (zl, rt):
            # a running median over 9 records: the binning and contact noise left out
            med = pd.Series(pos).rolling(9, center=True, min_periods=1).median().to_numpy()
            best = np.fmax.accumulate(np.where(np.arange(len(med)) >= k0, med, np.nan))
            near |= med < best - h
    near[:k0] = False
    k1 = int(np.argmax(near)) - 1 if near.any() else len(t) - 1
    if k1 < k0:
        return float("nan"), float("nan")
    return float(t[k0]), float(t[k1])


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
            "front_fraction": FRONT_FRACTION, "mode": params["mode"], "jammed": jammed,
            "t_jam_s": t_jam, "f_jam": f_jam, "set_up_time_s": set_up_time(params),
            "cells_per_mm": params["cells_per_mm"], "fit_note": note}


def _clean(d: dict) -> dict:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
            for k, v in d.items()}


def report(sim, history, out, params, rod_r):
    out = Path(out)
    h = sim.grid.h
    front = history[["time_s", "longitudinal_m", "transverse_m"]].copy()
    atomic_write_csv(out / "front.csv", front, empty_ok=("longitudinal_m", "transverse_m"))
    res = analyse(front, history["tip_depth_m"].to_numpy(), params, h,
                  history["max_f"].to_numpy())
    res["rod_radius_m"] = rod_r
    atomic_write_json(out / "summary.json", res, nullable=_NULLABLE)
    return [front_figure(history, res, params, out / "front.png"),
            fields_figure(sim, out, params, rod_r, out / "fields.png")]


def front_figure(history, res, params, path):
    fig, ax = plots.plt.subplots(figsize=(6.5, 4.5))
    t = history["time_s"].to_numpy() * 1e3
    ax.plot(t, history["longitudinal_m"] * 1e3, "b.", ms=3, label="longitudinal (depth)")
    ax.plot(t, history["transverse_m"] * 1e3, "r.", ms=3, label="transverse (radius)")
    ax.plot(t, history["tip_depth_m"] * 1e3, "k-", lw=1, label="rod tip depth")
    t0, t1 = res["fit_t_start_s"], res["fit_t_end_s"]
    if math.isfinite(t0):
        tt = np.array([t0, t1])
        for col, speed, c in (("longitudinal_m", res["v_fl_m_per_s"], "b"),
                              ("transverse_m", res["v_ft_m_per_s"], "r")):
            sel = (history["time_s"] >= t0) & (history["time_s"] <= t1)
            y = history.loc[sel, col].to_numpy()
            ts = history.loc[sel, "time_s"].to_numpy()
            b = float(np.mean(y) - speed * np.mean(ts))
            ax.plot(tt * 1e3, (b + speed * tt) * 1e3, c + "-", lw=2)
        ax.axvspan(t0 * 1e3, t1 * 1e3, color="0.9", zorder=0, label="fit window")
    ax.set_xlabel("t [ms]")
    ax.set_ylabel("front position [mm]")
    kl, kt = res["k_l"], res["k_t"]
    ax.set_title(f"phi0 = {params['phi0']}, v0 = {params['v0']} m/s: k_l = {kl:.3g}, "
                 f"k_t = {kt:.3g}, k_l/k_t = {res['k_l_over_k_t']:.3g}", fontsize=9)
    ax.legend(fontsize=8)
    return plots.save(fig, path)


def _grid_uz(x, v, m, h, shape):
    return cell_field(x, v, m, (0.0, 0.0), h, shape)


def fields_figure(sim, out, params, rod_r, path):
    """Fig. 6(a)-(e): u_z at the event times, |D_rz| and |D_zz| at the end."""
    h = sim.grid.h
    nx, ny = sim.grid.nx, sim.grid.ny
    v0 = params["v0"]
    ext = (0.0, nx * h * 1e3, 0.0, ny * h * 1e3)
    frames = [f for f in load_frames(out, tag="event")]
    bed = sim.sets[0]
    L = bed.L
    drz = np.abs(0.5 * (L[:, 1] + L[:, 2]))
    dzz = np.abs(L[:, 3])
    uz_end = _grid_uz(bed.x, bed.v[:, 1], bed.m, h, (nx, ny))
    panels = [(float(f["time_s"]), _grid_uz(f["bed.x"], f["bed.v"][:, 1], f["bed.m"], h, (nx, ny)),
               f["body.rod.x"]) for f in frames]
    n = len(panels) + 2
    fig, axs = plots.plt.subplots(1, n, figsize=(3.6 * n, 3.4))
    rc = (np.arange(nx) + 0.5) * h * 1e3
    zc = (np.arange(ny) + 0.5) * h * 1e3

    def draw_rod(ax, xr):
        ax.fill_between([0, rod_r * 1e3], xr[:, 1].min() * 1e3, xr[:, 1].max() * 1e3,
                        color="0.4")

    for ax, (t, uz, xr) in zip(axs, panels):
        im = ax.imshow(uz.T, origin="lower", extent=ext, cmap="viridis", vmin=-v0, vmax=0.0)
        ax.contour(rc, zc, uz.T, levels=[-0.5 * v0], colors="w", linewidths=2)
        draw_rod(ax, xr)
        ax.set_title(f"u_z at t = {t * 1e3:.1f} ms", fontsize=9)
        fig.colorbar(im, ax=ax, label="u_z [m/s]", shrink=0.8)
    for ax, d, name in ((axs[-2], drz, "|D_rz|"), (axs[-1], dzz, "|D_zz|")):
        field = cell_field(bed.x, d, bed.m, (0.0, 0.0), h, (nx, ny))
        vmax = np.nanpercentile(field, 99) if np.isfinite(field).any() else 1.0
        im = ax.imshow(field.T, origin="lower", extent=ext, cmap="magma", vmin=0.0,
                       vmax=vmax if vmax > 0 else 1.0)
        levels = [-0.9 * v0, -0.7 * v0, -0.3 * v0, -0.1 * v0]
        ax.contour(rc, zc, uz_end.T, levels=levels, colors="c", linewidths=0.6)
        ax.contour(rc, zc, uz_end.T, levels=[-0.5 * v0], colors="c", linewidths=2.5)
        draw_rod(ax, sim.bodies[0].x)
        ax.set_title(f"{name} at t = {sim.t * 1e3:.1f} ms\n(contours of u_z, 0.5 v0 bold)",
                     fontsize=9)
        fig.colorbar(im, ax=ax, label=f"{name} [1/s]", shrink=0.8)
    for ax in axs:
        ax.set_xlabel("r [mm]")
        ax.set_ylabel("z [mm]")
        ax.set_aspect("equal")
    fig.tight_layout()
    return plots.save(fig, path)


# ---------------------------------------------------------------- sweeps (Fig. 7)
SWEEP_COLUMNS = ("phi0", "v0_m_per_s", "k_l", "k_t", "k_l_over_k_t", "r2_longitudinal",
                 "r2_transverse")


def sweep_report(table, out) -> list:
    """``out/fronts.csv`` (one row per complete case: phi0, v0_m_per_s, k_l, k_t, k_l_over_k_t,
    r2_longitudinal, r2_transverse, jammed (whether the bed jammed during the run, from
    summary.json), case) and ``out/fronts.png`` (k_l against k_t with the line k_l = 2 k_t,
    Fig. 7; a case that never jammed drawn faint), from each case's ``summary.json``."""
    out = Path(out)
    rows = []
    for _, r in table.iterrows():
        p = out / str(r["case"]) / "summary.json"
        if not p.exists():
            continue
        s = json.loads(p.read_text())
        rows.append({**{k: (np.nan if s.get(k) is None else s[k]) for k in SWEEP_COLUMNS},
                     "jammed": bool(s.get("jammed", True)), "case": str(r["case"])})
    if not rows:
        return []
    df = pd.DataFrame(rows, columns=[*SWEEP_COLUMNS, "jammed", "case"])
    undefined = ("k_l", "k_t", "k_l_over_k_t", "r2_longitudinal", "r2_transverse")
    paths = [atomic_write_csv(out / "fronts.csv", df, empty_ok=undefined)]
    fig, ax = plots.plt.subplots(figsize=(5.5, 4.5))
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
        kt = np.linspace(0, 1.1 * ok["k_t"].max(), 2)
        ax.plot(kt, 2 * kt, "k--", label="k_l = 2 k_t (Han et al. 2016)")
        ratio = ok["k_l_over_k_t"]
        ax.set_title(f"k_l/k_t = {ratio.mean():.2f} +- {ratio.std(ddof=0):.2f} "
                     f"(min {ratio.min():.2f}, max {ratio.max():.2f})", fontsize=9)
    ax.set_xlabel("k_t = v_ft/v0")
    ax.set_ylabel("k_l = v_fl/v0 - 1")
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8)
    paths.append(plots.save(fig, out / "fronts.png"))
    return [Path(p) for p in paths]
