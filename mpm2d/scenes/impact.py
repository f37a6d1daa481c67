"""A free aluminium rod strikes a cornstarch suspension: impact-activated solidification (Figs. 4-5).

The rod-impact experiments of Waitukaitis & Jaeger (Nature 487, 205, 2012) as simulated by
Baumgarten & Kamrin (section "Impact Activated Solidification", Table 5, Figs. 4 and 5): a
flat-ended aluminium rod hits the free surface of a cornstarch-water(-glycerol) suspension at v0;
a solid plug forms under it and grows ahead of it (a jamming front), the rod decelerates hard,
then sinks slowly as in a liquid.

Equations: axisymmetric (r, z) MPM of the Table 8 law (rheology.local_update) with the Table 5
set: ``rod_impact`` (eta0 = 7 mPa s, Fig. 4) or ``rod_impact_1cp`` (eta0 = 1 mPa s, Fig. 5), both
on the Hermes 2016 steady fit (Tables 2-3), rho_s = 1620, rho_f = 1000 kg/m^3, G = 3.8e7 Pa,
K = 8.3e7 Pa, K0 = 1; d = 5.85 um, K3 = 4.715, K4 = 0; kappa = K (the paper gives no fluid
modulus). The rod is a free rigid body (mass, gravity, axial translation) meeting the bed through
multi-velocity-field contact (mpm2d.contact), solved implicitly with the rod's velocity:
``M dV/dt = -M g + F_contact``. Default mode: the locked mixture (one velocity field, undrained
pore pressure: the drainage time L^2/c_v of the plug exceeds the run, docs/measurements.md);
``mode=two-phase`` runs grains and fluid on two fields with implicit Beetstra drag.

Choices where the paper is silent:

- ``size=fig4``: container radius 10 cm, depth 10 cm on the paper's 100 x 120 grid at 1 mm,
  ``rod_impact``, v0 = 1.0 m/s, 60 ms; ``size=fig5``: radius 15 cm, depth 20.5 cm on the
  paper's 150 x 225 grid, ``rod_impact_1cp``, 60 ms (speeds by ``mpm2d sweep impact --set
  size=fig5 --set v0=0.5,1,2``); ``size=default``: Fig. 4 at 2 mm cells (50 x 60), 60 ms;
- rod: radius 9.5 mm (the paper), aluminium 2700 kg/m^3, length 20 cm (mass 153 g). Only its
  lowest 15 mm are body points, their density raised to rod_density rod_length/15 mm so that
  the body has the whole rod's mass; the lattice is fitted to the radius;
- launch: the face on the free surface moving down at v0 at t = 0 (times are "after impact");
  the free-drop height H = v0^2/(2 g) is reported, air drag neglected;
- phi0 = 0.47 (default, fig4) and 0.50 (fig5), between Hermes 2016's phi_c = 0.436 and
  phi_j = 0.535 (DST and shear jamming, a liquid at rest); fig5's eta0 = 1 mPa s needs the
  denser bed for a plug to form (docs/measurements.md);
- contact no-slip (mu_w = inf; ``rod_contact=frictionless`` for mu_w = 0), free to separate;
  container: no-slip floor and outer wall, axis r = 0, free top; the bed starts at rest
  (mpm2d.geostatic: the pore pressure carries the weight, f = 0).

Measures: rod z(t) of its face above the initial free surface; v(t), a(t) by the paper's
first-order difference over ``stencil`` (default the longest shear-wave round trip to a wall,
2 max(depth, radius)/c_s, c_s = sqrt(G/rho_mix)), centred; the raw a = F/M - g beside it. The
jamming front: where u_z = v_rod/2 on the axis below the face (mpm2d.fronts.longitudinal_front,
Han et al. 2016's criterion), while the rod moves faster than 0.1 v0; its speed by a straight-line
fit from the first record 2 cells ahead of the face until the rod has lost half its speed or the
front is within 2 cells of the floor; k = front speed/mean rod speed (Waitukaitis & Jaeger),
``k_penetration`` = d(front depth)/d(rod depth), with ``front_r2`` and ``front_r2_penetration``.
|Delta z| below the rod per initial depth (Fig. 4c): the plug reaches down to where it drops
below 5% of the rod's displacement; co-moving points (Fig. 4a): |Delta z| >= 90% of it.

Parameters: size (default|fig4|fig5), v0 [m/s], phi0, radius, depth [m], cells_per_mm (1/h in
1/mm), t_end [s] (after impact), material, rod_radius, rod_length [m], rod_density [kg/m^3],
rod_contact, mode, stencil [s], gravity [m/s^2], cfl. ``none`` (``auto`` for the material, the
defaults) takes the size's value.

Outputs (besides history.csv, frames, manifest): ``rod.csv`` (v0_m_per_s, time_s, z_m,
v_m_per_s, a_m_per_s2), ``rod_raw.csv`` (time_s, z_m, force_N, a_raw_m_per_s2), ``front.csv``
(v0_m_per_s, time_s, front_depth_m), ``displacement_vs_depth.csv`` (depth_m, displacement_m),
``summary.json``, ``displacement.png`` (Fig. 4a), ``displacement_vs_depth.png`` (Fig. 4c),
``rod.png`` (Fig. 5) and ``front.png``; a sweep over v0 writes them for all speeds together
(``sweep_report``) with ``speeds.csv``.

Run: ``mpm2d run impact --out impact`` (locked mixture)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from rheology import get_material
from runkit.io import atomic_write_csv, atomic_write_json
from runkit.limits import ge, le

from .. import plots
from ..bodies import RigidBody, fill
from ..fronts import cell_field, fit_speed, longitudinal_front
from ..geostatic import geostatic
from ..grid import Grid
from ..output import case_summaries
from . import spec
from .beds import bed_phases, suspension_bed
from ..run import Scene
from ..simulation import Simulation

#: presets: (radius [m], depth [m], cells per mm, material, v0 [m/s], t_end [s], phi0)
SIZES = {
    "default": dict(radius=0.10, depth=0.10, cells_per_mm=0.5, material="rod_impact", v0=1.0,
                    t_end=0.06, phi0=0.47),
    "fig4": dict(radius=0.10, depth=0.10, cells_per_mm=1.0, material="rod_impact", v0=1.0,
                 t_end=0.06, phi0=0.47),
    "fig5": dict(radius=0.15, depth=0.205, cells_per_mm=1.0, material="rod_impact_1cp", v0=1.0,
                 t_end=0.06, phi0=0.50),
}
#: room above the bed [m] (the paper's grids: 120 - 100 and 225 - 205 cells of 1 mm)
HEADROOM = 0.02
#: represented length of the rod [m] (its lowest part; mass of the whole rod)
ROD_REPRESENTED = 0.015
#: coarsest grid [cells/mm]: HEADROOM holds the rod's represented part and 2.25 cells above it
CELLS_PER_MM_MIN = 0.45
#: the front criterion u_z / v_rod (Han et al. 2016)
FRONT_FRACTION = 0.5
#: the front is recorded while |v_rod| > this fraction of v0
FRONT_MIN_SPEED = 0.1
#: the front fit ends once the rod has lost this fraction of its speed
FIT_SPEED_FRACTION = 0.5
#: plug: |Delta z| >= this fraction of the rod's displacement
PLUG_FRACTION = 0.05
#: co-moving: |Delta z| >= this fraction of the rod's displacement
COMOVING_FRACTION = 0.9
#: records of the rod per run
HISTORY_ROWS = 2400
_NULLABLE = ("front_speed_m_per_s", "front_r2", "k", "k_penetration", "front_r2_penetration",
             "fit_t_start_s",
             "fit_t_end_s", "plug_depth_m", "plug_r2", "plug_slope", "late_velocity_m_per_s",
             "mean_rod_speed_fit_m_per_s", "front_speed_after_fit_m_per_s", "k_after_fit")


def resolved(p: dict) -> dict:
    """The parameters with every ``None`` replaced by its size's value."""
    base = SIZES[p["size"]]
    return {k: (base[k] if (k in base and (v is None or (k == "material" and v == "auto")))
                else v) for k, v in p.items()}


def _h(p) -> float:
    return 1e-3 / resolved(p)["cells_per_mm"]


def _points(p) -> float:
    q = resolved(p)
    n = 4 * q["radius"] * q["depth"] * (q["cells_per_mm"] * 1e3) ** 2
    return n * (2 if q["mode"] == "two-phase" else 1)


def _nodes(p) -> float:
    q = resolved(p)
    c = q["cells_per_mm"] * 1e3
    return (q["radius"] * c + 5) * ((q["depth"] + HEADROOM) * c + 5)


def _steps(p) -> tuple:
    """(first step [s], end time [s], fewest steps) from the parameters (none: the size's):
    the wave limit of the bed in its mode, its viscous limit or the advection of the rod at
    v0, whichever is smallest."""
    q = resolved(p)
    phases = bed_phases(get_material(q["material"], rules=q["rules"]), q["phi0"], q["mode"])
    return spec.first_step(q["cfl"], _h(q), phases, q["v0"]), q["t_end"], 1


def _geo(make, doc, **kw):
    """A parameter of the size (none: its value), ``make`` one of the physical kinds of
    :mod:`mpm2d.scenes.spec` (``spec.length``, ...)."""
    return make(doc + " (none: the size's value)", optional=True, **kw)


@spec.parameters_of(
    lambda p: (_points(p), _nodes(p)),
    size=spec.Param(choices=tuple(SIZES), doc="scene: default (Fig. 4 at 2 mm), fig4 (100 x 120 "
                    "at 1 mm, 7 mPa s), fig5 (150 x 225 at 1 mm, 1 mPa s)"),
    v0=_geo(spec.speed, "impact speed (downwards)",
            hi=le(5.0, "five times the paper's 1 m/s (Figs. 4-5)")),
    phi0=spec.phi_below_jamming(fixed=lambda p: resolved(p)["material"], optional=True,
                                fill=lambda p: resolved(p)["phi0"],
                                doc="solid volume fraction of the bed (none: the size's value, "
                                    "0.47; fig5 0.50)"),
    radius=_geo(spec.length, "container (mixture) radius", above=ge(
        lambda p: p["rod_radius"] + 4e-3 / resolved(p)["cells_per_mm"],
        "at least the rod radius + 4 cells")),
    depth=_geo(spec.length, "mixture depth", above=ge(
        lambda p: 8e-3 / resolved(p)["cells_per_mm"], "at least 8 cells")),
    cells_per_mm=_geo(spec.resolution, "1/h in 1/mm (1: the paper's 1 mm)",
                      lo=ge(CELLS_PER_MM_MIN,
                            f"the {HEADROOM * 1e3:g} mm of grid above the bed must hold the "
                            f"rod's represented {ROD_REPRESENTED * 1e3:g} mm and 2 cells above "
                            "it, h <= 2.2 mm"),
                      hi=le(4.0, "a cell of 0.25 mm, four times finer than the paper's 1 mm")),
    t_end=_geo(spec.duration, "end time after impact", fill=lambda p: resolved(p)["t_end"]),
    material=spec.Param(choices=("auto", "rod_impact", "rod_impact_1cp"),
                        doc="Table 5 set: rod_impact (7 mPa s) or rod_impact_1cp (1 mPa s); "
                            "auto: the size's (fig5: 1 mPa s, else 7 mPa s)"),
    rod_radius=spec.length("rod radius", hi=le(0.1, "a rod as wide as the paper's containers "
                                                    "(0.2-0.3 m)"), above=ge(
        lambda p: 2e-3 / resolved(p)["cells_per_mm"], "at least 2 cells, at most the container "
        "radius - 4 cells"), below=le(
        lambda p: resolved(p)["radius"] - 4e-3 / resolved(p)["cells_per_mm"],
        "at least 2 cells, at most the container radius - 4 cells")),
    rod_length=spec.length("rod length (sets its mass)",
                           lo=ge(ROD_REPRESENTED, "at least the represented 15 mm")),
    rod_density=spec.density("rod density (aluminium 2700)"),
    rod_contact=spec.Param(choices=("noslip", "frictionless"),
                           doc="rod-suspension contact: no slip (mu_w = inf) or mu_w = 0"),
    mode=spec.Param(choices=("locked mixture", "two-phase"),
                    doc="locked mixture (undrained, default) or two-phase (grains + fluid)"),
    stencil=spec.duration("finite-difference stencil of v and a (none: the shear-wave round "
                          "trip 2 max(depth, radius)/c_s)", optional=True,
                          below=le(lambda p: 0.25 * resolved(p)["t_end"],
                                   "at most a quarter of t_end")),
    gravity=spec.gravity(), rules=spec.rules(), cfl=spec.cfl(), steps=lambda p: _steps(p))
def setup(size="default", v0=None, phi0=None, radius=None, depth=None, cells_per_mm=None,
          t_end=None, material="auto", rod_radius=0.0095, rod_length=0.20, rod_density=2700.0,
          rod_contact="noslip", mode="locked mixture", stencil=None, gravity=9.81, rules="table8",
          cfl=0.5):
    params = dict(locals())                   # every parameter, as checked
    q = resolved(params)
    phi0 = q["phi0"]
    h = 1e-3 / q["cells_per_mm"]
    m = get_material(q["material"], rules=rules)
    R, D, v0 = q["radius"], q["depth"], q["v0"]
    nx = int(round(R / h))
    nd = int(round(D / h))
    nz = nd + int(round(HEADROOM / h))
    D = nd * h
    grid = Grid(nx, nz, h, axisymmetric=True,
                boundaries=dict(xmin="axis", xmax="noslip", ymin="noslip", ymax="free"))
    x, area = fill(lambda r, z: np.ones_like(r, dtype=bool), (0.0, 0.0), (nx * h, D), h / 2)
    sets, extra = suspension_bed(m, x, area, phi0, mode, axisymmetric=True)
    x_init = x.copy()                                       # by point id (ids = arange)
    # the rod: lattice fitted to its radius, its lowest ROD_REPRESENTED represented
    nr = int(math.ceil(rod_radius / (h / 2) - 1e-9))
    sr, sz = rod_radius / nr, h / 2
    nzr = int(round(ROD_REPRESENTED / sz))
    side = math.sqrt(sr * sz)
    z_face = D + 0.5 * sz - 0.5 * side                      # contact face on the free surface
    rr, zz = np.meshgrid((np.arange(nr) + 0.5) * sr, z_face + (np.arange(nzr) + 0.5) * sz,
                         indexing="ij")
    xr = np.stack([rr.ravel(), zz.ravel()], axis=1)
    rep_len = nzr * sz
    rho_eff = rod_density * rod_length / rep_len
    rod = RigidBody("rod", xr, sr * sz, density=rho_eff, velocity=(0.0, -v0), prescribed="none",
                    axisymmetric=True, mu_w=math.inf if rod_contact == "noslip" else 0.0)
    sim = Simulation(grid, sets, [rod], mode=mode, gravity=(0.0, -gravity), cfl=cfl,
                     name="impact", **extra)
    geostatic(sim, sets=[s.name for s in sets])            # the bed at rest under gravity
    rho_mix = phi0 * m.rho_s + (1 - phi0) * m.rho_f
    c_s = math.sqrt(m.G / rho_mix)
    c_p = math.sqrt((m.K + 4 * m.G / 3 + m.kappa / (1 - phi0)) / rho_mix)
    st = stencil if stencil is not None else 2 * max(D, R) / c_s
    offset = float(rod.center[1]) - D                       # face = centre - offset + ... at t=0
    face0 = float(rod.center[1])
    mass = rod.mass
    info = dict(h=h, nx=nx, nz=nz, depth=D, radius=R, v0=v0, t_end=q["t_end"], stencil=st,
                c_s=c_s, c_p=c_p, rho_mix=rho_mix, material=q["material"], rod_radius=rod_radius,
                rod_mass_kg=mass * 2 * math.pi, rod_represented_m=rep_len, rho_eff=rho_eff,
                launch_height_m=v0 ** 2 / (2 * gravity), gravity=gravity, mode=mode,
                size=size, phi0=phi0)

    def face(sim) -> float:
        """Height of the rod's face above the initial free surface [m]."""
        return float(sim.bodies[0].center[1]) - face0

    def front_now(sim, z_face_abs, v) -> float:
        if not abs(v) > FRONT_MIN_SPEED * v0:
            return float("nan")
        bed = sim.sets[0]
        uz = cell_field(bed.x, bed.v[:, 1], bed.m, (0.0, 0.0), h, (nx, nz))
        rc = (np.arange(nx) + 0.5) * h
        zc = (np.arange(nz) + 0.5) * h
        zf = longitudinal_front(uz, rc, zc, z_face_abs, v, FRONT_FRACTION)
        return D - zf if math.isfinite(zf) else float("nan")

    def record(sim):
        r = sim.bodies[0]
        z = face(sim)
        v = float(r.velocity[1])
        return {"rod_z_m": z, "rod_velocity_m_per_s": v,
                "rod_force_N": float(r.force[1]) * 2 * math.pi,
                "rod_acceleration_raw_m_per_s2": float(r.force[1] / r.mass - gravity),
                "front_depth_m": front_now(sim, D + z, v),
                "max_f": float(np.max(sim.sets[0].f))}

    top_limit = (nz - 1.5) * h

    def before_step(sim):
        r = sim.bodies[0]
        top = float(np.max(r.x[:, 1])) + 0.5 * sz
        bottom = float(np.min(r.x[:, 1])) - 0.5 * sz
        if top > top_limit:
            raise RuntimeError(f"impact: the rod bounced out of the grid (its represented top at "
                               f"{top:.4g} m > {top_limit:.4g} m) at t = {sim.t:.4g} s")
        if bottom < 3 * h:
            raise RuntimeError(f"impact: the rod reached the floor (face at {bottom:.4g} m) at "
                               f"t = {sim.t:.4g} s; use a deeper bed or a shorter t_end")

    notes = (f"mode {mode}; size {size}; rod radius {rod_radius:g} m, mass "
             f"{info['rod_mass_kg']:.4g} kg ({rod_length:g} m of {rod_density:g} kg/m^3, lowest "
             f"{rep_len:g} m represented), v0 = {v0:g} m/s (free-drop height "
             f"{info['launch_height_m']:.4g} m), contact {rod_contact}; material "
             f"{q['material']}, phi0 = {phi0}; FD stencil {st:.4g} s")
    return Scene(sim, q["t_end"], params, frames=10, history_rows=HISTORY_ROWS, record=record,
                 before_step=before_step,
                 report=lambda sim, hist, out: report(sim, hist, out, info, x_init),
                 notes=notes, undefined=("front_depth_m",))


# ---------------------------------------------------------------- analysis (pure functions)
def finite_difference(t, y, stencil):
    """First-order difference of ``y`` over ``stencil`` [s], placed at the stencil's centre.

    ``t`` must be (nearly) uniform; the stencil is rounded to an even number n >= 2 of samples:
    d_i = (y_{i+n/2} - y_{i-n/2})/(t_{i+n/2} - t_{i-n/2}); NaN where the stencil does not fit.
    Returns (derivative array, n).
    """
    t, y = np.asarray(t, float), np.asarray(y, float)
    out = np.full(t.shape, np.nan)
    if t.size < 3:
        return out, 2
    dt = float(np.median(np.diff(t)))
    n = max(2, 2 * int(round(0.5 * stencil / dt)))
    k = n // 2
    if t.size > n:
        out[k:-k] = (y[n:] - y[:-n]) / (t[n:] - t[:-n])
    return out, n


def rod_kinematics(t, z, stencil):
    """v = dz/dt and a = -dv/dt... as the paper: both by :func:`finite_difference` over
    ``stencil``; a is the acceleration (dv/dt, positive when a falling rod decelerates)."""
    v, n = finite_difference(t, z, stencil)
    a, _ = finite_difference(t, v, stencil)
    return v, a, n


def linear_fit(x, y) -> dict:
    """Least-squares line y = a x + b: slope, intercept, R^2, points (NaN with < 3 points)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 3:
        nan = float("nan")
        return {"slope": nan, "intercept": nan, "r2": nan, "points": int(ok.sum())}
    res = fit_speed(x[ok], y[ok])
    return {"slope": res["speed"], "intercept": res["intercept"], "r2": res["r2"],
            "points": res["points"]}


def displacement_profile(x, x0, rod_radius, depth, row):
    """|Delta z| against initial depth below the rod (Fig. 4c).

    Parameters
    ----------
    x, x0 : (n, 2) arrays [m]: current and initial point positions (same order)
    rod_radius, depth : [m]; row : the initial row spacing [m]

    Returns
    -------
    DataFrame (depth_m, displacement_m): mean |z - z0| of the points with r0 < rod_radius per
    row of initial depth, ordered from the surface down.
    """
    sel = x0[:, 0] < rod_radius
    d0 = depth - x0[sel, 1]
    dz = np.abs(x[sel, 1] - x0[sel, 1])
    k = np.floor(d0 / row).astype(int)
    n = int(k.max()) + 1 if k.size else 0
    cnt = np.bincount(k, minlength=n)
    tot = np.bincount(k, dz, minlength=n)
    keep = cnt > 0
    return pd.DataFrame({"depth_m": ((np.arange(n) + 0.5) * row)[keep],
                         "displacement_m": tot[keep] / cnt[keep]})


def plug_fit(profile: pd.DataFrame, rod_disp: float) -> dict:
    """Linearity of |Delta z| over the plug: from the surface to where |Delta z| first drops
    below PLUG_FRACTION of the rod's displacement (R^2, slope, plug depth)."""
    d = profile["depth_m"].to_numpy()
    u = profile["displacement_m"].to_numpy()
    below = np.flatnonzero(u < PLUG_FRACTION * rod_disp)
    end = int(below[0]) if below.size else len(u)
    fit = linear_fit(d[:end], u[:end])
    return {"plug_depth_m": float(d[end - 1]) if end > 0 else float("nan"),
            "plug_r2": fit["r2"], "plug_slope": fit["slope"], "plug_points": fit["points"]}


def front_fit(t, front, z, v, v0, h, depth) -> dict:
    """Front speed, R^2 and k over the window of the module docstring."""
    t, front, z, v = (np.asarray(a, float) for a in (t, front, z, v))
    nan = float("nan")
    formed = np.isfinite(front) & (front - (-z) >= 2 * h)
    res = {"fit_t_start_s": nan, "fit_t_end_s": nan, "front_speed_m_per_s": nan,
           "front_r2": nan, "k": nan, "k_penetration": nan, "front_r2_penetration": nan,
           "mean_rod_speed_fit_m_per_s": nan, "fit_points": 0,
           "front_speed_after_fit_m_per_s": nan, "k_after_fit": nan}
    if not formed.any():
        return res
    k0 = int(np.argmax(formed))
    with np.errstate(invalid="ignore"):
        stop = (np.abs(v) < FIT_SPEED_FRACTION * v0) | (front >= depth - 2 * h)
    stop[:k0 + 1] = False
    k1 = int(np.argmax(stop)) - 1 if stop.any() else len(t) - 1
    sel = np.zeros(len(t), bool)
    sel[k0:k1 + 1] = True
    sel &= np.isfinite(front)
    if sel.sum() < 3:
        return res
    f = linear_fit(t[sel], front[sel])
    pen = linear_fit(-z[sel], front[sel])
    mean_v = float(np.mean(np.abs(v[sel])))
    res.update(fit_t_start_s=float(t[k0]), fit_t_end_s=float(t[k1]),
               front_speed_m_per_s=f["slope"], front_r2=f["r2"], k=f["slope"] / mean_v,
               k_penetration=pen["slope"], front_r2_penetration=pen["r2"],
               mean_rod_speed_fit_m_per_s=mean_v,
               fit_points=int(sel.sum()))
    after = (t > t[k1]) & np.isfinite(front)            # the front after the window
    if after.sum() >= 3:
        g = linear_fit(t[after], front[after])
        res.update(front_speed_after_fit_m_per_s=g["slope"],
                   k_after_fit=g["slope"] / float(np.mean(np.abs(v[after]))))
    return res


# ---------------------------------------------------------------- report
def report(sim, history, out, info, x_init):
    out = Path(out)
    v0, h = info["v0"], info["h"]
    t = history["time_s"].to_numpy()
    z = history["rod_z_m"].to_numpy()
    v_fd, a_fd, n = rod_kinematics(t, z, info["stencil"])
    rod = pd.DataFrame({"v0_m_per_s": v0, "time_s": t, "z_m": z, "v_m_per_s": v_fd,
                        "a_m_per_s2": a_fd})
    atomic_write_csv(out / "rod.csv", rod, empty_ok=("v_m_per_s", "a_m_per_s2"))
    raw = pd.DataFrame({"time_s": t, "z_m": z,
                        "force_N": history["rod_force_N"].to_numpy(),
                        "a_raw_m_per_s2": history["rod_acceleration_raw_m_per_s2"].to_numpy()})
    atomic_write_csv(out / "rod_raw.csv", raw)
    front = pd.DataFrame({"v0_m_per_s": v0, "time_s": t,
                          "front_depth_m": history["front_depth_m"].to_numpy()})
    atomic_write_csv(out / "front.csv", front, empty_ok=("front_depth_m",))
    bed = sim.sets[0]
    x0 = x_init[bed.id]
    prof = displacement_profile(bed.x, x0, info["rod_radius"], info["depth"], h / 2)
    atomic_write_csv(out / "displacement_vs_depth.csv", prof)
    rod_disp = float(-z[-1])
    plug = plug_fit(prof, rod_disp)
    ff = front_fit(t, front["front_depth_m"], z, history["rod_velocity_m_per_s"], v0, h,
                   info["depth"])
    late = t >= 0.8 * t[-1]
    late_v = float(np.nanmean(v_fd[late])) if np.isfinite(v_fd[late]).any() else float("nan")
    raw_a = raw["a_raw_m_per_s2"].to_numpy()
    dz = bed.x[:, 1] - x0[:, 1]
    res = {"v0_m_per_s": v0, "size": info["size"], "mode": info["mode"],
           "material": info["material"], "phi0": info["phi0"], "h_m": h,
           "grid": [info["nx"], info["nz"]], "depth_m": info["depth"],
           "radius_m": info["radius"], "t_end_s": info["t_end"],
           "rod_mass_kg": info["rod_mass_kg"], "rod_radius_m": info["rod_radius"],
           "launch_height_m": info["launch_height_m"],
           "stencil_s": info["stencil"], "stencil_samples": n,
           "shear_wave_speed_m_per_s": info["c_s"], "p_wave_speed_m_per_s": info["c_p"],
           "peak_deceleration_m_per_s2": float(np.nanmax(a_fd)) if np.isfinite(a_fd).any()
           else float("nan"),
           "time_of_peak_s": float(t[int(np.nanargmax(a_fd))]) if np.isfinite(a_fd).any()
           else float("nan"),
           "peak_raw_acceleration_m_per_s2": float(np.max(raw_a)),
           "final_rod_depth_m": rod_disp, "final_rod_velocity_m_per_s": float(
               sim.bodies[0].velocity[1]),
           "late_velocity_m_per_s": late_v, "late_window_s": [float(0.8 * t[-1]), float(t[-1])],
           "max_f": float(history["max_f"].max()),
           "max_heave_m": float(max(dz.max(), 0.0)),
           "heave_fraction_over_1mm": float(np.mean(dz > 1e-3)),
           "comoving_fraction": COMOVING_FRACTION, "plug_fraction": PLUG_FRACTION,
           "front_fraction": FRONT_FRACTION, **plug, **ff}
    atomic_write_json(out / "summary.json", res, nullable=_NULLABLE + ("peak_deceleration_m_per_s2",
                                                                       "time_of_peak_s"))
    return figures(out)


def figures(out) -> list:
    """The run's four figures, drawn from its files alone (summary.json, the tables, the first
    and last snapshots): ``displacement.png``, ``displacement_vs_depth.png``, ``rod.png``,
    ``front.png``."""
    out = Path(out)
    s = json.loads((out / "summary.json").read_text())
    rod, raw = pd.read_csv(out / "rod.csv"), pd.read_csv(out / "rod_raw.csv")
    return [plots.save(displacement_figure(out, s), out / "displacement.png"),
            plots.save(profile_figure(pd.read_csv(out / "displacement_vs_depth.csv"), s),
                       out / "displacement_vs_depth.png"),
            plots.save(rod_figure([(s["v0_m_per_s"], rod, raw)], summary=s), out / "rod.png"),
            plots.save(front_figure(pd.read_csv(out / "front.csv"), rod["z_m"].to_numpy(), s),
                       out / "front.png")]


def _first_last(out):
    """The bed's points (x, m) of the first and the last snapshot, ordered by id, and the last
    snapshot's time."""
    man = json.loads((Path(out) / "manifest.json").read_text())
    with np.load(Path(out) / man["frames"][0]["npz"]) as a, \
            np.load(Path(out) / man["frames"][-1]["npz"]) as b:
        return a["bed.x"], b["bed.x"], b["bed.m"], float(b["time_s"])


def displacement_field(out, s):
    """The cell-averaged z-displacement [m] of the bed in its deformed configuration, (nx, nz)
    (NaN in empty cells), with the points' dz and the last snapshot (x, time)."""
    x0, x, m, t = _first_last(out)
    dz = x[:, 1] - x0[:, 1]
    nx, nz = s["grid"]
    return cell_field(x, dz, m, (0.0, 0.0), s["h_m"], (nx, nz)), dz, x, t


def displacement_figure(out, s):
    """Fig. 4a: the z-displacement field in the deformed configuration (the points' current
    positions, as an X-ray image shows it) on a diverging map centred at 0 and spanning the
    field (down: blue, heave: red), contours at fractions of the rod's displacement and of the
    heave; co-moving points marked."""
    field, dz, x, t = displacement_field(out, s)
    h, (nx, nz) = s["h_m"], s["grid"]
    rod_disp, heave = s["final_rod_depth_m"], s["max_heave_m"]
    fig, ax = plots.plt.subplots(figsize=(7.5, 7.4))
    ext = (0.0, nx * h * 1e2, 0.0, nz * h * 1e2)
    lim = float(np.nanmax(np.abs(field))) * 1e2 if np.isfinite(field).any() else 1e-9
    im = ax.imshow(field.T * 1e2, origin="lower", extent=ext, cmap="RdBu_r", vmin=-lim,
                   vmax=lim, interpolation="nearest")
    rc = (np.arange(nx) + 0.5) * h * 1e2
    zc = (np.arange(nz) + 0.5) * h * 1e2
    levels = sorted([-f * rod_disp * 1e2 for f in (0.05, 0.1, 0.25, 0.5, 0.75, 0.9)]
                    + [f * heave * 1e2 for f in (0.25, 0.5) if heave > 0])
    if np.isfinite(field).any():
        cs = ax.contour(rc, zc, np.ma.masked_invalid(field.T * 1e2), levels=levels, colors="k",
                        linewidths=0.7)
        ax.clabel(cs, fmt="%.2f", fontsize=6)
    co = np.abs(dz) >= COMOVING_FRACTION * rod_disp
    ax.scatter(x[co, 0] * 1e2, x[co, 1] * 1e2, s=4, c="w", edgecolors="k", linewidths=0.3,
               label=f"co-moving points (|dz| >= {COMOVING_FRACTION:.0%} of the rod's)")
    ax.fill_between([0, s["rod_radius_m"] * 1e2], (s["depth_m"] - rod_disp) * 1e2,
                    nz * h * 1e2, color="0.55", label="rod")
    fig.colorbar(im, ax=ax, label="z-displacement [cm] (< 0 down, > 0 up)", shrink=0.8)
    ax.set_xlabel("r [cm]")
    ax.set_ylabel("z [cm]")
    ax.set_title(f"z-displacement {t * 1e3:.0f} ms after impact at v0 = {s['v0_m_per_s']:g} "
                 f"m/s: the rod {rod_disp * 1e3:.1f} mm deep, heave up to "
                 f"{heave * 1e3:.1f} mm\n({s['heave_fraction_over_1mm']:.0%} of the bed's points "
                 f"rose more than 1 mm); {nx} x {nz} cells of {h * 1e3:g} mm; phi0 = "
                 f"{s['phi0']:g} (our choice: the paper gives none)", fontsize=9)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=2, fontsize=7,
              frameon=False)
    ax.set_aspect("equal")
    return fig


def profile_figure(prof, s):
    """Fig. 4c: |Delta z| against depth below the rod, the plug's straight line."""
    fig, ax = plots.plt.subplots(figsize=(6.4, 5.0))
    d, u = prof["depth_m"].to_numpy(), prof["displacement_m"].to_numpy()
    ax.plot(d * 1e2, u * 1e2, "k.-", ms=3,
            label=f"simulation (mean over r < the rod's {s['rod_radius_m'] * 1e3:g} mm)")
    plug = s.get("plug_depth_m")
    if plug is not None and s.get("plug_slope") is not None:
        sel = (d <= plug) & np.isfinite(u)
        b = float(np.mean(u[sel]) - s["plug_slope"] * np.mean(d[sel]))
        ax.plot(d[sel] * 1e2, (b + s["plug_slope"] * d[sel]) * 1e2, "r-",
                label=f"straight line over the plug, R^2 = {s['plug_r2']:.3f}")
        what = (f"plug (|dz| > {PLUG_FRACTION:.0%} of the rod's {s['final_rod_depth_m'] * 1e3:.1f}"
                f" mm) from the surface to {plug * 1e2:.3g} cm")
    else:
        what = "no plug"
    ax.set_xlabel("initial depth below the surface z [cm]")
    ax.set_ylabel("|Delta z| [cm]")
    ax.set_title(f"displacement below the rod, {s['t_end_s'] * 1e3:.0f} ms after impact:\n{what}",
                 fontsize=9)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=1, fontsize=8,
              frameon=False)
    return fig


def rod_figure(runs, path=None, summary=None):
    """Fig. 5: z, v, a against t for each v0 (a from z, stencil), the raw a(t) lighter; one
    legend below the panels. With one run's ``summary`` the title gives its peak deceleration
    and late sinking speed. ``path``: save there and return the path, else return the figure."""
    fig, axs = plots.plt.subplots(1, 3, figsize=(15, 5.0))
    colors = plots.plt.cm.viridis(np.linspace(0, 0.85, max(len(runs), 1)))
    for (v0, rod, raw), c in zip(runs, colors):
        t = rod["time_s"].to_numpy() * 1e3
        axs[0].plot(t, rod["z_m"] * 1e2, color=c, label=f"v0 = {v0:g} m/s")
        axs[1].plot(t, rod["v_m_per_s"], color=c)
        if raw is not None:
            axs[2].plot(raw["time_s"] * 1e3, raw["a_raw_m_per_s2"], color=c, lw=0.5, alpha=0.35)
        axs[2].plot(t, rod["a_m_per_s2"], color=c, lw=2)
    axs[0].set_ylabel("rod face z [cm]")
    axs[1].set_ylabel("rod velocity v [m/s]")
    axs[2].set_ylabel("rod acceleration a [m/s^2] (thin: raw F/M - g)")
    for ax in axs:
        ax.set_xlabel("t after impact [ms]")
    if summary is not None:
        s = summary
        peak = s.get("peak_deceleration_m_per_s2")
        fig.suptitle(
            (f"peak deceleration {peak:.3g} m/s^2 at {s['time_of_peak_s'] * 1e3:.2g} ms"
             if peak is not None else "no deceleration") +
            f" (v and a from z over the {s['stencil_s'] * 1e3:.3g} ms stencil); late sinking "
            + (f"{abs(late):.3g} m/s" if (late := s.get("late_velocity_m_per_s")) is not None
               else "undefined (run too short)")
            + f"; rod {s['final_rod_depth_m'] * 1e3:.1f} mm deep at {s['t_end_s'] * 1e3:.0f} ms",
            fontsize=10)
    fig.tight_layout(rect=(0, 0.07, 1, 0.95))
    fig.legend(*axs[0].get_legend_handles_labels(), loc="lower center", ncol=min(len(runs), 6),
               fontsize=8, frameon=False)
    return plots.save(fig, path) if path is not None else fig


def front_figure(front, z, s):
    """The jamming front's depth against time, the rod's depth, the straight-line fit over its
    window (shaded) and what the front does after it."""
    fig, ax = plots.plt.subplots(figsize=(6.8, 5.4))
    t = front["time_s"].to_numpy()
    y = front["front_depth_m"].to_numpy()
    ax.plot(t * 1e3, y * 1e2, "b.", ms=2, label="front (u_z = v_rod/2 on the axis)")
    ax.plot(t * 1e3, -np.asarray(z) * 1e2, "k-", lw=1, label="rod face depth")
    t_end = s["t_end_s"]
    if s.get("fit_t_start_s") is not None and s.get("front_speed_m_per_s") is not None:
        t0, t1 = s["fit_t_start_s"], s["fit_t_end_s"]
        sel = (t >= t0) & (t <= t1) & np.isfinite(y)
        b = float(np.mean(y[sel]) - s["front_speed_m_per_s"] * np.mean(t[sel]))
        tt = np.array([t0, t1])
        ax.axvspan(t0 * 1e3, t1 * 1e3, color="orange", alpha=0.25, lw=0,
                   label=f"fit window {t0 * 1e3:.2g}-{t1 * 1e3:.3g} ms (until the rod has lost "
                         f"{FIT_SPEED_FRACTION:.0%} of its speed)")
        ax.plot(tt * 1e3, (b + s["front_speed_m_per_s"] * tt) * 1e2, "r-", lw=2,
                label=f"fit: {s['front_speed_m_per_s']:.3g} m/s, R^2 = {s['front_r2']:.3f}, "
                      f"k = {s['k']:.3g}")
        after = s.get("front_speed_after_fit_m_per_s")
        later = (f"after it the front advances at {after:.2g} m/s (k = "
                 f"{s['k_after_fit']:.2g})" if after is not None else "after it: no front")
        title = (f"jamming front, v0 = {s['v0_m_per_s']:g} m/s: k = {s['k']:.3g} over the first "
                 f"{t1 * 1e3:.3g} ms of {t_end * 1e3:.0f} ms;\n{later}")
    else:
        title = f"jamming front, v0 = {s['v0_m_per_s']:g} m/s: no front formed ahead of the rod"
    ax.set_xlabel("t after impact [ms]")
    ax.set_ylabel("depth below the initial surface [cm]")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=1, fontsize=8,
              frameon=False)
    return fig


# ---------------------------------------------------------------- sweeps (Fig. 5)
def sweep_report(table, out) -> list:
    """All speeds together: ``out/rod.csv``, ``out/front.csv`` (the same columns, every
    case), ``out/rod.png`` (Fig. 5), ``out/speeds.csv`` (per v0: peak deceleration, late
    velocity, k, R^2) and ``out/summary.json`` (with the log-log slope of the peak deceleration
    against v0 and whether it grows monotonically)."""
    out = Path(out)
    runs, rods, fronts, rows = [], [], [], []
    for case, folder, s in case_summaries(table, out):
        rod = pd.read_csv(folder / "rod.csv")
        raw = pd.read_csv(folder / "rod_raw.csv") if (folder / "rod_raw.csv").exists() else None
        rods.append(rod)
        fronts.append(pd.read_csv(folder / "front.csv"))
        runs.append((s["v0_m_per_s"], rod, raw))
        rows.append({k: (np.nan if s.get(k) is None else s[k]) for k in SPEED_COLUMNS}
                    | {"case": case})
    if not rows:
        return []
    order = np.argsort([r[0] for r in runs])
    runs = [runs[i] for i in order]
    speeds = pd.DataFrame(rows).sort_values("v0_m_per_s")
    paths = [atomic_write_csv(out / "rod.csv", pd.concat([rods[i] for i in order]),
                              empty_ok=("v_m_per_s", "a_m_per_s2")),
             atomic_write_csv(out / "front.csv", pd.concat([fronts[i] for i in order]),
                              empty_ok=("front_depth_m",)),
             atomic_write_csv(out / "speeds.csv", speeds, empty_ok=SPEED_COLUMNS[2:])]
    summ = peak_scaling(speeds["v0_m_per_s"].to_numpy(),
                        speeds["peak_deceleration_m_per_s2"].to_numpy())
    summ["cases"] = speeds.replace({np.nan: None}).to_dict(orient="records")
    paths.append(atomic_write_json(out / "summary.json", summ,
                                   nullable=("loglog_slope", "loglog_r2")))
    paths.append(rod_figure(runs, out / "rod.png"))
    return [Path(p) for p in paths]


SPEED_COLUMNS = ("v0_m_per_s", "peak_deceleration_m_per_s2", "late_velocity_m_per_s", "k",
                 "front_r2", "front_r2_penetration", "plug_r2", "final_rod_depth_m")


def late_change(time_s, v, fraction=0.2) -> tuple[float, float]:
    """The rod's late sinking: its mean velocity and its velocity change over the last
    ``fraction`` of the run (a straight line fitted to v(t) there, times the window length).

    time_s, v : (N,) time [s] and rod velocity [m/s] (NaN where the stencil has no value).
    Returns (mean v [m/s], change of v over the window [m/s]); NaN if fewer than 3 finite
    samples. A steady sinking has |change| << |mean v| (the paper: "the steady sinking that is
    observed once the rods have slowed").
    """
    t, v = np.asarray(time_s, float), np.asarray(v, float)
    late = (t >= (1.0 - fraction) * t[-1]) & np.isfinite(v)
    if late.sum() < 3:
        return float("nan"), float("nan")
    slope = np.polyfit(t[late], v[late], 1)[0]
    return float(np.mean(v[late])), float(slope * (t[late][-1] - t[late][0]))


def peak_scaling(v0, peak) -> dict:
    """Monotonicity (every finite peak, sorted by v0) and log-log slope (over the positive
    peaks: a rod that never decelerates has none) of the peak deceleration against v0."""
    v0, peak = np.asarray(v0, float), np.asarray(peak, float)
    o = np.argsort(v0)
    v0, peak = v0[o], peak[o]
    mono = bool(np.isfinite(peak).all() and np.all(np.diff(peak) > 0))
    ok = np.isfinite(peak) & (peak > 0)             # the slope: decelerating runs only
    fit = linear_fit(np.log(v0[ok]), np.log(peak[ok])) if ok.sum() >= 2 else None
    if fit is not None and ok.sum() == 2:        # the line through both: R^2 undefined
        lv, lp = np.log(v0[ok]), np.log(peak[ok])
        fit = {"slope": float((lp[1] - lp[0]) / (lv[1] - lv[0])), "r2": float("nan")}
    out = {"v0_m_per_s": v0.tolist(), "peak_deceleration_m_per_s2": peak.tolist(),
           "monotone": mono, "loglog_slope": fit["slope"] if fit else float("nan"),
           "loglog_r2": fit["r2"] if fit else float("nan")}
    if not np.isfinite(out["loglog_r2"]):
        out["loglog_r2_null_reason"] = (f"{int(ok.sum())} decelerating speed(s): R^2 needs at "
                                        "least 3 (a line through 2 points fits them exactly)")
    return out
