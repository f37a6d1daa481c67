"""The annular shear cell of the paper's Fig. 3 as a 2-D (r, z) MPM with swirl.

Equations: the locked mixture (one velocity field, Table 8 granular law through
rheology.local_update with the full 3 x 3 L, undrained pore pressure, fluid stress
eta0 (1 + 5/2 phi)(L + L^T - 2/3 tr L)), in axisymmetry with the azimuthal velocity v_theta
(``Simulation(..., swirl=True)``)::

    rho D(r v_theta)/Dt = (1/r) d(r^2 sigma_r_theta)/dr + r d(sigma_theta_z)/dz
    rho Dv_r/Dt = div_rz(sigma)_r - sigma_thth/r + rho v_theta^2/r

A bob of radius R_i turns impulsively (or over ``ramp_time``) with surface speed u_i inside a
cup of radius R_o at rest, from rest, until it has turned ``rotation`` rad
(t_end = rotation R_i/u_i + ramp_time/2); u_i = 84 mm/s is the paper's fast case (a jammed band
grows from the bob), 0.84 mm/s the slow one.

Grid (how the paper's 36 x 50 cells of 1 mm map here): the paper's grid spans r = 0..36 mm
with the bob inside it; the material only fills the 23.5 mm gap R_i = 12.5 mm .. R_o = 36 mm
(shear1d's radii, see shear1d.scenes). We grid the gap alone, an annular axisymmetric grid whose
xmin wall is the bob surface and xmax wall the cup, so both walls lie on node lines (the mirror
boundary conditions are then exact for the B-splines); ``cells`` = 24 across the gap gives
h = 23.5/24 = 0.979 mm, the nearest to the paper's 1 mm that fits the gap. ``rows`` = 50 cells
of the same h in z (the paper's 50), periodic in z: the cell is long and the flow z-invariant,
which is what shear1d solves, so the rows are copies (use fewer for speed).

Initial state as in shear1d: at rest, f = 0, phi = phi0, isotropic granular contact pressure
``p0`` (shear1d's 1e-3 Pa floor), zero pore pressure. No gravity.

Parameters: material, phi0, u_inner [m/s], r_inner, r_outer [m], cells (across the gap), rows
(in z), ppc, rotation [rad], ramp_time [s], p0 [Pa], kappa [Pa] (fluid bulk modulus; default the
material's), transfer, flip_alpha, swirl_flip, cfl.

Transfer (``swirl_flip`` = 0.99): plain APIC replaces each point's l = r v_theta by the grid
interpolant every step, damping the jammed band's shear waves once per step (a front that slows
as dt falls); the APIC-FLIP blend (mpm2d.transfer.g2p_swirl) keeps 99 % of what a point carries
beyond the interpolant (alpha = 1 keeps the points next to the bob at their initial lag). The
measurements behind the choice are in docs/user/mpm2d.md.

Outputs (report): ``annular_front.csv`` (time, bob rotation, kinematic front position: the
first radius from the bob where v_theta / (u_i r/R_i) < 1/2, shear1d's definition; f at the bob)
and ``annular_summary.json`` with the front speed fitted while the front crosses 10-90 % of the
gap (shear1d.analysis.front_fit's window); ``annular.png``.

Run: ``mpm2d run annular --set u_inner=0.084 --out annular`` (mode: locked mixture)
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rheology import f_jam
from rheology.elastic import ELASTIC_STRAIN_LIMIT
from runkit import limits
from runkit.io import atomic_write_csv, atomic_write_json
from runkit.limits import STRAIN_MIN, ge, gt, le
from rheology.materials import scene_material

from .. import plots
from ..bodies import box
from ..fronts import fit_speed
from ..grid import Grid
from ..materials import NewtonianFluid, Suspension
from ..particles import ParticleSet
from . import spec
from ..run import Scene
from ..simulation import Simulation
from .beds import bed_phases

R_INNER = 12.5e-3
R_OUTER = 36e-3
#: kinematic front: rigid ratio threshold; fit window as fractions of the gap (as shear1d)
FRONT_THRESHOLD = 0.5
FIT_LO, FIT_HI = 0.1, 0.9


def newtonian_steady(r, r_inner, r_outer, u_inner):
    """Steady Newtonian annular Couette flow v_theta = A r + B/r [m/s] (bob turning at u_inner,
    cup at rest), r [m] any shape."""
    d = r_outer ** 2 - r_inner ** 2
    A, B = -u_inner * r_inner / d, u_inner * r_inner * r_outer ** 2 / d
    return A * np.asarray(r, dtype=float) + B / np.asarray(r, dtype=float)


def newtonian_check(cells, *, r_inner=R_INNER, r_outer=R_OUTER, u_inner=1e-3, rows=4,
                    eta=1.0, rho=1000.0, kappa=2e4, T=1.0, transfer="apic") -> dict:
    """Steady Newtonian annular Couette flow on the swirl engine against v = A r + B/r.

    A weakly compressible Newtonian fluid (eta [Pa s], rho, kappa: Re = u_i gap rho/eta ~ 0.02,
    Mach ~ 2e-4) fills the gap on ``cells`` x ``rows`` cells (periodic z), starts at rest with
    the bob turning at u_inner and runs T viscous times gap^2 rho/eta (the slowest mode decays
    as exp(-pi^2 T): 5e-5 at T = 1). Returns max |v_theta - exact|/u_i over the points, the
    largest meridional speed |v|/u_i, h [m] and the number of steps.
    """
    h = (r_outer - r_inner) / cells
    grid = Grid(cells, rows, h, origin=(r_inner, 0.0), axisymmetric=True,
                boundaries=dict(xmin="noslip", xmax="noslip", ymin="periodic", ymax="periodic"),
                wall_swirl={"xmin": u_inner})
    x, area = box((r_inner, 0.0), (r_outer, rows * h), h / 2)
    f = ParticleSet("fluid", NewtonianFluid(eta, rho, kappa, einstein=False), x, area,
                    axisymmetric=True)
    sim = Simulation(grid, [f], swirl=True, transfer=transfer, cfl_visc=0.4, name="newtonian")
    sim.run(T * (r_outer - r_inner) ** 2 * rho / eta)
    ex = newtonian_steady(f.x[:, 0], r_inner, r_outer, u_inner)
    return {"cells": cells, "h_m": h, "steps": sim.step_count,
            "max_error": float(np.abs(f.vtheta - ex).max() / u_inner),
            "rms_error": float(np.sqrt(np.mean((f.vtheta - ex) ** 2)) / u_inner),
            "max_meridional_over_u": float(np.abs(f.v).max() / u_inner)}


def radial_profile(x, values, r_inner, h, ppc):
    """Column means of ``values`` over the point columns (ppc per cell) -> (r, mean)."""
    k = np.floor((x[:, 0] - r_inner) / (h / ppc)).astype(int)
    n = int(k.max()) + 1
    cnt = np.bincount(k, minlength=n)
    s = np.bincount(k, weights=values, minlength=n)
    ok = cnt > 0
    r = r_inner + (np.arange(n) + 0.5) * h / ppc
    return r[ok], s[ok] / cnt[ok]


def front_position(r, vtheta, r_inner, r_outer, u_inner):
    """First radius from the bob where v_theta/(u r/R_i) < 1/2 (linear interpolation between
    profile points; R_i if already the first, R_o if none) [m]."""
    if u_inner == 0.0:
        return float(r_inner)
    ratio = vtheta / (u_inner * r / r_inner)
    below = np.flatnonzero(ratio < FRONT_THRESHOLD)
    if below.size == 0:
        return float(r_outer)
    k = int(below[0])
    if k == 0:
        return float(r_inner)
    q0, q1 = ratio[k - 1], ratio[k]
    return float(r[k - 1] + (q0 - FRONT_THRESHOLD) / (q0 - q1) * (r[k] - r[k - 1]))


def front_fit(t, front, r_inner, r_outer, lo=FIT_LO, hi=FIT_HI) -> dict:
    """Least-squares speed [m/s] of the front while it crosses [lo, hi] of the gap (from the
    first time past lo to the first past hi or its largest position); NaN if < 3 points.
    ``gap_reached``: the largest gap fraction the fitted stretch reaches (below ``hi``: the
    front stalled or the run ended before it crossed, and the speed is over part of the gap)."""
    t, front = np.asarray(t, float), np.asarray(front, float)
    x = (front - r_inner) / (r_outer - r_inner)
    start = np.flatnonzero(np.isfinite(x) & (x >= lo))
    out = dict(speed=float("nan"), r2=float("nan"), t_start=float("nan"), t_end=float("nan"),
               points=0, gap_reached=float("nan"))
    if start.size == 0:
        return out
    i0 = int(start[0])
    gone = np.flatnonzero(~np.isfinite(x[i0:]))
    i_end = i0 + int(gone[0]) - 1 if gone.size else len(t) - 1
    stop = np.flatnonzero(x[i0:i_end + 1] >= hi)
    i1 = i0 + int(stop[0]) if stop.size else i_end
    i1 = min(i1, i0 + int(np.argmax(x[i0:i_end + 1])))
    tt, ff = t[i0:i1 + 1], front[i0:i1 + 1]
    if tt.size < 3:
        return out
    fit = fit_speed(tt, ff)
    out.update(speed=fit["speed"], r2=fit["r2"], t_start=float(tt[0]), t_end=float(tt[-1]),
               points=int(tt.size), gap_reached=float(np.max(x[i0:i1 + 1])))
    return out


def _u_inner_max(p) -> float:
    """0.1 sqrt(G/rho) [m/s] of the run's material at phi0: the small-elastic-strain limit of
    the hypoelastic law (rheology.elastic), the bound shear1d's --u-inner has on the same cell."""
    m = scene_material("annular_shear", p["material"])
    rho = p["phi0"] * m.rho_s + (1.0 - p["phi0"]) * m.rho_f
    return ELASTIC_STRAIN_LIMIT * float(np.sqrt(m.G / rho))


def _t_end(p) -> float:
    """The end time [s]: the bob's rotation at u_i after the ramp's half."""
    return p["rotation"] * p["r_inner"] / p["u_inner"] + 0.5 * p["ramp_time"]


def _first_step(p) -> float:
    """The first step [s]: the wave limit of the locked mixture, K + 4G/3 + kappa/(1 - phi_j)
    on the mixture's density, or its viscous limit (it starts at rest), whichever is smaller."""
    m = scene_material("annular_shear", p["material"], rules=p["rules"])
    if p["kappa"] is not None:
        m = dataclasses.replace(m, kappa=float(p["kappa"]))
    return spec.first_step(p["cfl"], (p["r_outer"] - p["r_inner"]) / p["cells"],
                           bed_phases(m, p["phi0"], "locked mixture"))


@spec.parameters_of(
    material=spec.scene_material_param("annular_shear"),
    phi0=spec.phi_below_jamming(doc="initial solid volume fraction"),
    u_inner=spec.speed("bob surface speed u_i", below=le(
        _u_inner_max, "0.1 sqrt(G/rho): the small-elastic-strain limit, as shear1d's")),
    r_inner=spec.length("bob radius R_i"),
    r_outer=spec.length("cup radius R_o", above=gt(lambda p: p["r_inner"], "the cup outside the bob, R_o > R_i")),
    cells=spec.cells("cells across the gap", 4, 4096, "4 cells: a gap resolved by a few",
                     "4096 cells: 1e3 times the paper's gap resolution"),
    rows=spec.cells("cells in z (periodic)", 2, 4096, hi_why="4096 cells: a periodic column "
                    "repeats; more rows only average"),
    ppc=spec.count(1, 4, "points per cell and direction", spec.PPC_WHY[0],
                   "4 per direction (16 per cell): past where more change the fronts"),
    rotation=spec.physical(
        gt(0.0, "a rotation"), le(100.0, "about 16 turns: the fronts settle within a few"),
        "rad", "bob rotation to simulate", above=ge(
            lambda p: STRAIN_MIN.value * (p["r_outer"] - p["r_inner"]) / p["r_inner"],
            f"a strain R_i rotation/(R_o - R_i) of at least {STRAIN_MIN.value:g}: "
            f"{STRAIN_MIN.why}")),
    ramp_time=spec.duration("linear start-up of the bob speed (0: none)", also=(0.0,),
                            below=le(lambda p: p["rotation"] * p["r_inner"] / p["u_inner"],
                                     "at most the rotation time R_i rotation/u_i, as "
                                     "shear1d's")),
    p0=spec.stress("initial isotropic granular pressure (0: none)", zero=True),
    transfer=spec.transfer(),
    flip_alpha=spec.flip_alpha(),
    kappa=spec.physical(limits.MODULUS_MIN, limits.MODULUS_MAX, "Pa",
                        "fluid bulk modulus (none: the material's)", optional=True),
    swirl_flip=spec.fraction("FLIP fraction of the APIC swirl transfer (APIC-FLIP blend)",
                             "0: APIC", "below 1: a pure FLIP swirl is not stable",
                             hi_closed=False),
    rules=spec.rules(),
    cfl=spec.cfl(),
    size=lambda p: (p["cells"] * p["rows"] * p["ppc"] ** 2, (p["cells"] + 5) * (p["rows"] + 5)),
    steps=lambda p: (_first_step(p), _t_end(p), 1))
def setup(material="annular_shear", phi0=0.505, u_inner=0.084, r_inner=R_INNER,
          r_outer=R_OUTER, cells=24, rows=50, ppc=2, rotation=0.31, ramp_time=0.0, p0=1e-3,
          kappa=None, transfer="apic", flip_alpha=0.99, swirl_flip=0.99, rules="table8",
          cfl=0.5):
    params = dict(locals())                   # every parameter, as checked
    m = scene_material("annular_shear", material, rules=rules)
    if kappa is not None:
        m = dataclasses.replace(m, kappa=float(kappa))
    h = (r_outer - r_inner) / cells
    grid = Grid(cells, rows, h, origin=(r_inner, 0.0), axisymmetric=True,
                boundaries=dict(xmin="noslip", xmax="noslip", ymin="periodic", ymax="periodic"),
                wall_swirl={"xmin": u_inner})
    x, area = box((r_inner, 0.0), (r_outer, rows * h), h / ppc)
    pts = ParticleSet("suspension", Suspension(m, locked=True), x, area, phi=phi0,
                      stress=-p0 * np.eye(3), f=0.0, axisymmetric=True)
    sim = Simulation(grid, [pts], transfer=transfer, flip_alpha=flip_alpha, cfl=cfl, swirl=True,
                     swirl_flip=swirl_flip, swirl_ramp=ramp_time, name="annular")
    t_end = _t_end(params)
    fjam = float(f_jam(phi0, m))

    def bob_speed(t):
        return u_inner * (min(1.0, t / ramp_time) if ramp_time > 0 else 1.0)

    def record(sim):
        s = sim.sets[0]
        r, vt = radial_profile(s.x, s.vtheta, r_inner, h, ppc)
        _, f = radial_profile(s.x, s.f, r_inner, h, ppc)
        u = bob_speed(sim.t)
        return {"rotation_rad": float(_rotation(sim.t, u_inner, ramp_time, r_inner)),
                "front_m": front_position(r, vt, r_inner, r_outer, u),
                "f_bob": float(f[0]), "f_jam": fjam,
                "vtheta_mid_over_u": float(np.interp(0.5 * (r_inner + r_outer), r, vt)
                                           / u_inner)}

    return Scene(sim, t_end, params, frames=10, history_rows=400, record=record,
                 report=lambda sim, hist, out: report(out, params, hist),
                 notes="annular gap grid (bob = xmin wall, cup = xmax wall), periodic in z")


def _rotation(t, u, ramp, r_inner):
    if ramp > 0 and t < ramp:
        return 0.5 * u * t * t / ramp / r_inner
    return u * (t - 0.5 * ramp) / r_inner


def summarise(params, hist) -> dict:
    """Front speed of the jammed band from a run's history (band: f at the bob >= f_jam/2)."""
    band = hist["f_bob"].to_numpy() >= 0.5 * hist["f_jam"].to_numpy()
    front = np.where(band, hist["front_m"].to_numpy(), np.nan)
    fit = front_fit(hist["time_s"].to_numpy(), front, params["r_inner"], params["r_outer"])
    u = params["u_inner"]
    return {"u_inner_m_per_s": u, "front_speed_m_per_s": fit["speed"],
            "front_speed_over_u_inner": fit["speed"] / u, "front_fit_r2": fit["r2"],
            "fit_t_start_s": fit["t_start"], "fit_t_end_s": fit["t_end"],
            "fit_points": fit["points"], "band_formed": bool(band.any()),
            "front_fit_gap_reached": fit["gap_reached"],
            "front_crossed_gap": bool(fit["gap_reached"] >= FIT_HI),
            "cells": params["cells"], "h_m": (params["r_outer"] - params["r_inner"])
            / params["cells"]}


def report(out, params, hist):
    s = summarise(params, hist)
    nullable = ("front_speed_m_per_s", "front_speed_over_u_inner", "front_fit_r2",
                "fit_t_start_s", "fit_t_end_s", "front_fit_gap_reached")
    atomic_write_json(out / "annular_summary.json", s, nullable=nullable)
    cols = ["time_s", "rotation_rad", "front_m", "f_bob", "vtheta_mid_over_u"]
    atomic_write_csv(out / "annular_front.csv", hist[cols])
    fig, ax = plots.plt.subplots(figsize=(6.5, 5))
    g = params["r_outer"] - params["r_inner"]
    ax.plot(hist["rotation_rad"], (hist["front_m"] - params["r_inner"]) / g, "-")
    ax.set_xlabel("bob rotation [rad]")
    ax.set_ylabel("(front - R_i) / gap")
    sp = s["front_speed_over_u_inner"]
    ax.set_title(f"annular cell, u_i = {params['u_inner'] * 1e3:g} mm/s: front speed "
                 + (f"{sp:.3g} u_i" if sp == sp else "- (no band)"))
    return [plots.save(fig, out / "annular.png")]
