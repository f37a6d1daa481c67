"""Running on oobleck (paper section 3, Figs. 8, 9 and 14): a four-spoked wheel (the paper's is
elastic; ours is rigid by default, see below) driven at a constant angular velocity omega on a
cornstarch bed; fast (omega = 10 1/s) it runs along the surface, slow (omega = 1 1/s) it sinks.

Equations: plane-strain MPM. The bed is the Table 8 law (rheology.local_update) with the Table 7
parameter set ``wheel`` on the Hermes 2016 steady fit (eta0 = 1 mPa s, rho_s = rho_f = 1620
kg/m^3, G = 3.8e5 Pa, K = 8.3e5 Pa, K0 = 1; d = 5.85 um, K3 = 4.715, K4 = 0; kappa = K) as a
LOCKED MIXTURE (one velocity field, undrained pore pressure: the drainage time L^2/c_v against
the run's duration, docs/measurements.md). The wheel is
a rigid body whose angular velocity is prescribed (-omega: clockwise, driving to +x, from t = 0)
and whose translation is free (mass, gravity, contact; mpm2d.bodies), meeting the bed through
mpm2d.contact (no slip mu_w = inf, free separation); ``spokes=elastic`` makes the spokes
plane-strain linear elastic points (Jaumann rate, E, nu) bonded to a rigid hub. The bed starts
at rest under gravity (mpm2d.geostatic: pore pressure rho g depth, granular stress 0, f = 0).

The paper's set-up: 2 m x 1 m periodic in x, 150 x 75 elements (h = 13.3 mm), wheel radius 15 cm,
density 3000 kg/m^3, four spokes, Table 7. Our choices where the paper is silent:

- wheel geometry after the author's generator (aaronbaumgarten/mpm_3d,
  mpm_pygen/GenerateWheel2D_v2.py, ``WheelOne``): a hub of radius 5 cm and four straight spokes
  10 cm long, NO rim, each as wide as the author's tread at the hub, 2 r_hub sin((1 - 0.25) pi/4)
  = 55.6 mm; mass 89.9 kg per metre of thickness;
- the start: at rest, spinning at omega from t = 0, the spokes at ``start_angle`` = 45 deg to the
  vertical, resting on two spoke tips (``start_angle = 0``: one spoke straight down);
- contact: no slip (``mu_w`` none: the suspension wets the spokes);
- rigid by default: the author's driver (mpm_3d src/objects/bodies/wheel_body.cpp) turns the
  wheel rigidly (every node's tangential velocity omega r about the centre of mass);
  ``spokes=elastic`` is for short runs (docs/measurements.md);
- bed 2.0 m x 0.5 m (the author's 0.5 m);
- phi0 = 0.5075, inside the author's 0.50-0.51, between phi_c = 0.436 and phi_j = 0.535: loose
  at rest (f = 0, the pore fluid carries the weight) but shear-jammable (phi_m(f) = phi0 at
  f_jam = 0.28); a calibration inside the author's range, not a prediction;
- t_end = 1.0 s (Fig. 14's snapshot time); the wheel starts 0.25 m from the left edge: a rigid
  body does not wrap through a periodic side, so START_X + omega R t_end + R + 3 h <= width is
  checked first and a wheel within R + 3 h of the right edge stops the run.

Default ``mpm2d run wheel``: ``omega = none`` runs BOTH omegas: 10 1/s in DIR then 1 1/s in
DIR/omega_1 (a resumable sub-run), and writes ``DIR/hub.csv`` (omega_per_s, time_s, x_m, y_m),
``DIR/summary.json`` (sink depth per omega and the checks), ``hub.png``, ``fig8.png`` (omega =
10), ``fig9.png`` (omega = 1), ``wheel.gif``. ``--set omega=1`` runs one omega. Each run keeps
``frames`` = 8 snapshots (every 0.125 s) with :data:`FRAME_FIELDS`, no VTK unless asked
(``--vtk``), and its final checkpoint.

Figures 8-9: the bed's f as cell averages, velocity vectors (block averages) of lengths
l_i = 1.215 v_i sqrt(R/g), the grid volume fraction phi = 0.1 contour as the surface. Fig. 14:
``moduli_factor`` multiplies the granular G and K (not kappa), ``transfer`` selects APIC or FLIP;
:func:`pressure_noise` is the RMS cell-to-cell jump of the granular pressure under the wheel over
its mean, :func:`pressure_figure` draws the cases (validation/cases_wheel.py).

Parameters: omega [1/s] (none: both 10 and 1), radius, hub_radius, spoke_width [m], density
[kg/m^3], spokes (rigid or elastic), E [Pa], nu (elastic spokes), phi0, width, height,
bed_depth, h [m], t_end [s], start_angle [deg], mu_w (none: no slip), moduli_factor,
kappa_factor, transfer, gravity [m/s^2], rules, cfl, frames.

Run: ``mpm2d run wheel --out wheel`` (both omegas)
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.animation import PillowWriter

from rheology import get_material
from runkit import limits
from runkit.io import atomic_write_csv, atomic_write_json
from runkit.limits import ge, le

from .. import plots
from ..bodies import RigidBody, fill
from ..fronts import cell_field
from ..geostatic import geostatic
from ..grid import Grid
from ..materials import LinearElastic, Suspension
from ..output import bspline_weights, case_summaries, load_frames
from ..particles import ParticleSet
from . import spec
from .. import run as runner
from ..run import Scene
from ..simulation import Simulation
from .beds import bed_phases

#: the default run's omegas [1/s]: the main run first (DIR), then the others (DIR/omega_<w>)
OMEGAS = (10.0, 1.0)
#: number of spokes (the paper's wheel)
N_SPOKES = 4
#: the wheel's start: its hub this far from the left edge [m]
START_X = 0.25
#: the reasons of the bed's modulus factors (moduli_factor, kappa_factor)
FACTOR_WHY = ("a hundredth: the bed's moduli (~1e7 Pa) stay above a gel's", "a thousand times: "
              "the step, which falls as the square root, 30 times shorter")
#: vector length factor of Figs. 8-9: l_i = VECTOR_SCALE v_i sqrt(R/g)
VECTOR_SCALE = 1.215
#: the surface contour of Figs. 8-9 (grid volume fraction)
SURFACE_PHI = 0.1
#: check: the fast wheel's hub stays within this fraction of R of its start height
#: (while it advances at least R): 0.8 R is the hub centre's start height above the undisturbed
#: surface (0.81-0.83 R, resting on two spoke tips), i.e. the hub never goes below the surface it
#: started on; a wheel whose hub sinks below the surface is not "running along" it
FAST_BAND = 0.8
#: check: the slow wheel sinks at least this many times deeper than the fast one
SINK_RATIO = 3.0
#: what a snapshot keeps (the figures, the animation and Fig. 14's pressure noise read them):
#: 1.7 MB a snapshot of the default bed (22 500 points), besides id and x
FRAME_FIELDS = ("v", "m", "V", "phi", "f", "granular_pressure_Pa")
#: hub.csv columns (interface)
HUB_COLUMNS = ("omega_per_s", "time_s", "x_m", "y_m")


def _omega_key(w) -> str:
    return f"{float(w):g}"


def wheel_shape(center, radius, hub_radius, spoke_width, spacing, n_spokes=N_SPOKES,
                angle0=math.pi / 4):
    """Points of the spokes (elastic) and of the hub (rigid), with areas, on one lattice.

    Spoke k is the rectangle along the direction angle0 + 2 pi k/n_spokes from the centre out to
    ``radius`` (along its axis), ``spoke_width`` wide, outside the hub disk (r <= hub_radius).

    Returns ((x_spokes (N, 2), area (N,)), (x_hub (M, 2), area (M,))) [m, m^2].
    """
    c = np.asarray(center, float)
    dirs = [(math.cos(angle0 + 2 * math.pi * k / n_spokes),
             math.sin(angle0 + 2 * math.pi * k / n_spokes)) for k in range(n_spokes)]

    def spokes(x, y):
        dx, dy = x - c[0], y - c[1]
        r = np.hypot(dx, dy)
        inside = np.zeros_like(r, dtype=bool)
        for ex, ey in dirs:
            s = dx * ex + dy * ey
            t = -dx * ey + dy * ex
            inside |= (s > 0.0) & (s <= radius) & (np.abs(t) < 0.5 * spoke_width)
        return inside & (r > hub_radius)

    reach = math.hypot(radius, 0.5 * spoke_width)
    lo, hi = c - reach - spacing, c + reach + spacing
    elastic = fill(spokes, lo, hi, spacing)
    hub = fill(lambda x, y: np.hypot(x - c[0], y - c[1]) <= hub_radius, lo, hi, spacing)
    return elastic, hub


def _points(p) -> float:
    wheel = math.pi * p["hub_radius"] ** 2 + N_SPOKES * p["spoke_width"] * p["radius"]
    return 4 * (p["width"] * p["bed_depth"] + wheel) / p["h"] ** 2


def _steps(p) -> tuple:
    """(first step [s], end time [s], fewest steps) from the parameters: the wave limit of the
    locked bed (and of elastic spokes), its viscous limit or the advection of the spoke tips
    at omega hypot(R, spoke_width/2) (omega none: the first run's, 10 1/s), whichever is
    smallest."""
    phases = bed_phases(bed_material(p["moduli_factor"], p["kappa_factor"], p["rules"]),
                        p["phi0"], "locked mixture")
    if p["spokes"] == "elastic":
        phases.append((LinearElastic(p["density"], E=p["E"], nu=p["nu"]), p["density"]))
    w = OMEGAS[0] if p["omega"] is None else p["omega"]
    return (spec.first_step(p["cfl"], p["h"], phases,
                            w * math.hypot(p["radius"], 0.5 * p["spoke_width"])), p["t_end"], 1)


@spec.parameters_of(
    omega=spec.physical(limits.FREQUENCY_MIN, le(100.0, "ten times the paper's fastest wheel "
                                                        "(10 1/s)"), "1/s",
                        "prescribed angular velocity (clockwise, driving to +x); none: both 10 "
                        "and 1 1/s (the default run)", optional=True),
    radius=spec.length("wheel radius R (along each spoke's axis)"),
    hub_radius=spec.length("rigid hub radius", above=ge(lambda p: p["h"], "one cell to the radius "
                                                        "- 2 cells"),
                           below=le(lambda p: p["radius"] - 2 * p["h"], "one cell to the radius "
                                    "- 2 cells")),
    spoke_width=spec.length("spoke width",
                            above=ge(lambda p: p["h"] / 2, "a point spacing (h/2) to the hub "
                                     "diameter"),
                            below=le(lambda p: 2 * p["hub_radius"], "a point spacing (h/2) to "
                                     "the hub diameter")),
    density=spec.density("wheel density"),
    spokes=spec.Param(choices=("rigid", "elastic"),
                      doc="rigid wheel (hub and spokes one rigid body) or elastic spokes bonded "
                          "to the rigid hub"),
    E=spec.modulus("elastic spokes: Young's modulus"),
    nu=spec.poisson("elastic spokes: Poisson ratio"),
    phi0=spec.phi_below_jamming(fixed="wheel", doc="bed solid volume fraction"),
    width=spec.length("domain width (periodic)", above=ge(lambda p: 4 * p["radius"],
                                                          "at least 4 radii")),
    height=spec.length("domain height",
                       above=ge(lambda p: p["bed_depth"] + 3 * p["radius"] + 2 * p["h"],
                                "bed + 3 radii + 2 cells")),
    bed_depth=spec.length("bed depth", above=ge(lambda p: p["radius"],
                                                "at least the wheel radius")),
    h=spec.length("cell size (2/150: the paper's 150 x 75 grid)",
                  above=ge(lambda p: p["radius"] / 100.0, "radius/100 to radius/4"),
                  below=le(lambda p: p["radius"] / 4.0, "radius/100 to radius/4")),
    t_end=spec.duration("end time", below=le(
        lambda p: (p["width"] - START_X - p["radius"] - 3 * p["h"]) / (
            (OMEGAS[0] if p["omega"] is None else p["omega"]) * p["radius"]),
        "omega R t_end <= width - 0.25 m - R - 3 h: the wheel must not reach the periodic side")),
    start_angle=spec.Param(0.0, 45.0, unit="deg",
                           doc="the spokes' angle from the vertical at t = 0 (45: resting on two "
                               "spoke tips; 0: on one spoke, pointing straight down)",
                           lo_why="0: on one spoke, pointing straight down",
                           hi_why="45: on two spoke tips; the four spokes repeat every 90"),
    mu_w=spec.Param(0.0, 100.0, optional=True,
                    doc="Coulomb coefficient between wheel and bed (none: no slip)",
                    lo_why="0: frictionless", hi_why="100: no slip in effect (the bed's own "
                    "friction, mu ~0.3-1, slips first)"),
    moduli_factor=spec.Param(0.01, 1000.0, doc="multiplies the bed's granular G and K (Fig. 14)",
                             lo_why=FACTOR_WHY[0], hi_why=FACTOR_WHY[1]),
    kappa_factor=spec.Param(0.01, 1000.0, doc="multiplies the pore fluid's bulk modulus kappa",
                            lo_why=FACTOR_WHY[0], hi_why=FACTOR_WHY[1]),
    transfer=spec.Param(choices=("apic", "flip"), doc="particle-grid transfer (Fig. 14)"),
    gravity=spec.gravity("gravitational acceleration (downwards)"),
    rules=spec.rules(),
    cfl=spec.cfl(),
    frames=spec.count(1, 200, "snapshots per run (figures, animation)",
                      "at least the final snapshot", "an animation of 8 s at 25 frames/s"),
    size=lambda p: (_points(p), (p["width"] / p["h"] + 5) * (p["height"] / p["h"] + 5)),
    steps=lambda p: _steps(p))
def setup(omega=None, radius=0.15, hub_radius=0.05, spoke_width=0.0556, density=3000.0,
          spokes="rigid", E=1.0e7, nu=0.3, phi0=0.5075, width=2.0, height=1.0, bed_depth=0.5,
          h=2.0 / 150.0, t_end=1.0, start_angle=45.0, mu_w=None, moduli_factor=1.0,
          kappa_factor=1.0, transfer="apic", gravity=9.81, rules="table8", cfl=0.5, frames=8):
    params = dict(locals())                   # every parameter, as checked
    w = OMEGAS[0] if omega is None else float(omega)
    nx, ny = int(round(width / h)), int(round(height / h))
    grid = Grid(nx, ny, h, boundaries=dict(xmin="periodic", xmax="periodic", ymin="noslip",
                                          ymax="free"))
    spacing = h / 2
    depth = round(bed_depth / spacing) * spacing           # whole point rows
    xb, ab = fill(lambda x, y: np.ones_like(x, dtype=bool), (0.0, 0.0), (nx * h, depth), spacing)
    m = bed_material(moduli_factor, kappa_factor, rules)
    mu = math.inf if mu_w is None else float(mu_w)
    bed = ParticleSet("bed", Suspension(m, locked=True), xb, ab, phi=phi0, f=0.0)
    # the wheel on the lattice around (0, 0), then moved so that its lowest point faces touch the
    # bed's top faces (resting on the surface) with its hub START_X from the left edge
    (xw, aw), (xh, ah) = wheel_shape((0.0, 0.0), radius, hub_radius, spoke_width, spacing,
                                     angle0=-math.pi / 2 + math.radians(start_angle))
    lift = depth - (min(xw[:, 1].min(), xh[:, 1].min()) - 0.5 * spacing)
    shift = np.array([START_X, lift])
    xw, xh = xw + shift, xh + shift
    if spokes == "rigid":
        # hub and spokes one rigid body: omega prescribed, translation free, no-slip contact
        hub = RigidBody("hub", np.concatenate([xh, xw]), np.concatenate([ah, aw]),
                        density=density, omega=-w, prescribed=("omega",), mu_w=mu)
        sets, contact = [bed], {}
    else:
        wheel = ParticleSet("wheel", LinearElastic(density, E=E, nu=nu), xw, aw)
        hub = RigidBody("hub", xh, ah, density=density, omega=-w, prescribed=("omega",),
                        bonded_to=("wheel",))
        sets, contact = [bed, wheel], {"wheel": mu}
    sim = Simulation(grid, sets, [hub], mode="locked mixture", gravity=(0.0, -gravity),
                     cfl=cfl, transfer=transfer, name="wheel", contact_sets=contact)
    geostatic(sim, sets=["bed"])          # the bed at rest under gravity (mpm2d.geostatic)
    right = nx * h - radius - 3 * h

    def before_step(sim):
        c = sim.bodies[0].center
        if not (radius + 3 * h <= c[0] <= right):
            raise RuntimeError(f"wheel: the hub reached x = {c[0]:.3f} m, within R + 3 h of the "
                               "domain's periodic side; the engine does not wrap rigid bodies "
                               "through a periodic side: shorten t_end or widen the domain")

    def record(sim):
        b = sim.bodies[0]
        if spokes == "rigid":
            spin = b.omega
        else:
            ws = sim.sets[1]
            r = ws.x - b.center
            rel = ws.v - b.velocity
            spin = np.sum(ws.m * (r[:, 0] * rel[:, 1] - r[:, 1] * rel[:, 0])) / np.sum(
                ws.m * np.einsum("ij,ij->i", r, r))
        return {"wheel_omega_per_s": float(spin),
                "hub_x_m": float(b.center[0]), "hub_y_m": float(b.center[1]),
                "hub_vx_m_per_s": float(b.velocity[0]), "hub_vy_m_per_s": float(b.velocity[1]),
                "hub_torque_N": float(b.torque), "max_f": float(np.max(sim.sets[0].f))}

    events = (1.0,) if t_end >= 1.0 else ()
    notes = (f"omega {w:g} 1/s{' (then the others of the default run)' if omega is None else ''}"
             f"; locked mixture, phi0 {phi0}, moduli x{moduli_factor:g}, {transfer}; hub rigid "
             "(omega prescribed, translation free), spokes elastic (own field, no-slip contact)")
    return Scene(sim, t_end, params, frames=frames, history_rows=400,
                 record=record, before_step=before_step, frame_times=events,
                 frame_fields=FRAME_FIELDS, vtk=False,
                 report=lambda sim, hist, out: report(sim, hist, out, params, w), notes=notes)


def bed_material(moduli_factor=1.0, kappa_factor=1.0, rules="table8"):
    """The Table 7 set ``wheel`` with its granular G and K multiplied by ``moduli_factor``, its
    fluid bulk modulus kappa by ``kappa_factor``, and the yield ``rules``."""
    m = get_material("wheel", rules=rules)
    if moduli_factor == 1.0 and kappa_factor == 1.0:
        return m
    return m.replace(G=m.G * moduli_factor, K=m.K * moduli_factor, kappa=m.kappa * kappa_factor)


# ---------------------------------------------------------------- analysis
def hub_table(history, omega) -> pd.DataFrame:
    """The interface table: omega_per_s, time_s, x_m, y_m (hub centre)."""
    return pd.DataFrame({"omega_per_s": float(omega), "time_s": history["time_s"].to_numpy(),
                         "x_m": history["hub_x_m"].to_numpy(),
                         "y_m": history["hub_y_m"].to_numpy()})[list(HUB_COLUMNS)]


def analyse(history, params, omega) -> dict:
    """Sink depth (hub drop at the end), its largest excursions, the advance and speed, the
    wheel's spin against omega (second half), for one run."""
    t = history["time_s"].to_numpy()
    x = history["hub_x_m"].to_numpy()
    y = history["hub_y_m"].to_numpy()
    dy = y - y[0]
    R = params["radius"]
    surface = _surface(params)
    late = t > 0.5 * t[-1]
    speed = float(np.polyfit(t[late], x[late], 1)[0]) if late.sum() > 2 else float("nan")
    spin = float(-history["wheel_omega_per_s"].to_numpy()[late].mean()) if late.any() \
        else float("nan")
    return {"omega_per_s": float(omega), "t_end_s": float(t[-1]),
            "sink_depth_m": float(-dy[-1]), "sink_over_R": float(-dy[-1] / R),
            "max_sink_m": float(-dy.min()), "max_rise_m": float(dy.max()),
            "max_excursion_over_R": float(np.abs(dy).max() / R),
            "advance_m": float(x[-1] - x[0]), "advance_over_R": float((x[-1] - x[0]) / R),
            "speed_m_per_s": speed, "omega_R_m_per_s": float(omega * R),
            "wheel_spin_per_s": spin, "max_f": float(history["max_f"].max()),
            "start_y_m": float(y[0]), "start_x_m": float(x[0]),
            "start_height_over_R": float((y[0] - surface) / R),
            "lowest_hub_above_surface_m": float(y.min() - surface)}


def _surface(params) -> float:
    """The undisturbed bed top [m] (whole rows of points at spacing h/2)."""
    spacing = params["h"] / 2
    return round(params["bed_depth"] / spacing) * spacing


def checks(results: dict, R: float) -> dict:
    """The run-or-sink checks of Figs. 8-9 from the per-omega results (keys: omega strings)."""
    out = {"fast_band_over_R": FAST_BAND, "sink_ratio_required": SINK_RATIO}
    fast, slow = results.get(_omega_key(10.0)), results.get(_omega_key(1.0))
    if fast is not None:
        out["fast_stays_up"] = bool(fast["max_excursion_over_R"] <= FAST_BAND
                                    and fast["advance_m"] >= R)
    if fast is not None and slow is not None:
        ref = max(fast["sink_depth_m"], 0.0)
        ratio = slow["sink_depth_m"] / ref if ref > 0 else math.inf
        out["sink_ratio"] = ratio if math.isfinite(ratio) else None
        out["slow_sinks_3x"] = bool(slow["sink_depth_m"] > 0 and
                                    slow["sink_depth_m"] >= SINK_RATIO * ref)
        dip = max(fast["max_sink_m"], 0.0)            # the same ratio by the largest dips
        out["sink_ratio_largest_dip"] = slow["max_sink_m"] / dip if dip > 0 else None
    return out


def _finite(d):
    if isinstance(d, dict):
        return {k: _finite(v) for k, v in d.items()}
    if isinstance(d, float) and not math.isfinite(d):
        return None
    return d


# ---------------------------------------------------------------- grid fields
def grid_phi(x, svol, h, nx, ny) -> np.ndarray:
    """The grains' volume fraction on the nodes, (nx, ny + 1) (periodic in x): sum_p N_ip
    phi_p V_p / h^2 (quadratic B-splines; 0 where no point reaches)."""
    out = np.zeros((nx, ny + 3))
    bx, wx = bspline_weights(x[:, 0] / h)
    by, wy = bspline_weights(x[:, 1] / h)
    for a in range(3):
        for b in range(3):
            np.add.at(out, (np.mod(bx + a, nx), np.clip(by + b, 0, ny + 2)), wx[a] * wy[b] * svol)
    return out[:, : ny + 1] / h ** 2


def cell_average(x, q, w, h, nx, ny) -> np.ndarray:
    """Weighted cell average of the point values q (weights w), (nx, ny); NaN in empty cells
    (:func:`mpm2d.fronts.cell_field` on the bed's cells from the origin)."""
    return cell_field(x, q, w, (0.0, 0.0), h, (nx, ny))


def pressure_window(frame, params):
    """The granular pressure p~ [Pa] on the cells under the wheel: |x - x_hub| <= 2R, from the
    hub down to 2R below it, cells full of bed (grid phi >= 0.9 phi0 at all four nodes).

    Returns (p (ni, nj) with NaN outside, x edges, y edges)."""
    h = params["h"]
    nx, ny = int(round(params["width"] / h)), int(round(params["height"] / h))
    x = frame["bed.x"]
    phi = frame["bed.phi"]
    vol = frame["bed.V"]
    p = cell_average(x, frame["bed.granular_pressure_Pa"], frame["bed.m"], h, nx, ny)
    gp = grid_phi(x, phi * vol, h, nx, ny)
    full = np.minimum.reduce([gp[:, :-1], np.roll(gp, -1, 0)[:, :-1], gp[:, 1:],
                              np.roll(gp, -1, 0)[:, 1:]]) >= 0.9 * params["phi0"]
    c = frame["body.hub.center"]
    R = params["radius"]
    xc = (np.arange(nx) + 0.5) * h
    yc = (np.arange(ny) + 0.5) * h
    inx = np.abs(xc - c[0]) <= 2 * R
    iny = (yc <= c[1]) & (yc >= c[1] - 2 * R)
    sel = full & inx[:, None] & iny[None, :]
    p = np.where(sel, p, np.nan)
    ii, jj = np.nonzero(inx)[0], np.nonzero(iny)[0]
    if ii.size == 0 or jj.size == 0:
        return np.full((0, 0), np.nan), np.zeros(1), np.zeros(1)
    sub = p[ii.min(): ii.max() + 1, jj.min(): jj.max() + 1]
    return sub, np.arange(ii.min(), ii.max() + 2) * h, np.arange(jj.min(), jj.max() + 2) * h


def pressure_noise(frame, params) -> float:
    """Noise of the granular pressure under the wheel (Fig. 14): the RMS of the jumps between
    neighbouring cells (x and y) of :func:`pressure_window`, over the mean p~ there, counting only
    cells that carry a granular pressure (p~ > 1 % of the window's largest): a loose suspension
    carries none (f = 0, phi < phi_m), so the edges of the jammed zones are left out and only the
    field inside them is judged. A smooth field varies by ~ h/L of itself from cell to cell (a few
    %); checkerboard noise of amplitude a gives 2a. NaN when fewer than 4 cell pairs qualify."""
    p, _, _ = pressure_window(frame, params)
    if p.size == 0 or not np.isfinite(p).any():
        return float("nan")
    top = np.nanmax(p)
    if not (top > 0):
        return float("nan")
    q = np.where(p > 0.01 * top, p, np.nan)
    jumps = np.concatenate([(q[1:, :] - q[:-1, :]).ravel(), (q[:, 1:] - q[:, :-1]).ravel()])
    jumps = jumps[np.isfinite(jumps)]
    if jumps.size < 4:
        return float("nan")
    return float(np.sqrt(np.mean(jumps ** 2)) / np.nanmean(q))


def mean_pressure_noise(out, params, t0, t1) -> tuple[float, float, int]:
    """:func:`pressure_noise` averaged over the run's snapshots with t0 <= t <= t1 [s].

    One snapshot's value fluctuates by ~30% from one snapshot to the next (15 ms apart: each
    spoke strike rebuilds the jammed zone), so the level of the noise, and its ordering between
    runs, is read from the mean. Returns (mean, standard error of the mean, snapshots used);
    NaN where no snapshot has a value."""
    vals = np.array([pressure_noise(f, params) for f in load_frames(out)
                     if t0 - 1e-9 <= float(f["time_s"]) <= t1 + 1e-9])
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return float("nan"), float("nan"), 0
    sem = float(np.std(vals, ddof=1) / np.sqrt(vals.size)) if vals.size > 1 else float("nan")
    return float(np.mean(vals)), sem, int(vals.size)


def frame_at(out, t) -> dict:
    """The snapshot of the run in ``out`` nearest to time ``t`` [s]."""
    frames = load_frames(out)
    return min(frames, key=lambda f: abs(float(f["time_s"]) - t))


# ---------------------------------------------------------------- figures
#: Figs. 8-9: velocity vectors on cells of this many grid cells (a few hundred per panel)
ARROW_CELLS = 5


def f_field(frame, params):
    """The bed's mass-weighted cell average of f on the grid cells, (nx, ny) (NaN where a cell
    holds no bed point), with the cell edges in x and y [m]."""
    h = params["h"]
    nx, ny = int(round(params["width"] / h)), int(round(params["height"] / h))
    f = cell_average(frame["bed.x"], frame["bed.f"], frame["bed.m"], h, nx, ny)
    return f, np.arange(nx + 1) * h, np.arange(ny + 1) * h


def draw_state(ax, frame, params, vmax_f, arrow_cells=ARROW_CELLS):
    """Fig. 8/9 panel: f of the bed as its cell averages (every cell of bed in its colour),
    wheel and hub points in grey, cell-averaged velocity vectors of the bed on blocks of
    ``arrow_cells`` cells with lengths 1.215 v sqrt(R/g) [m] (the paper's scale), the grid
    phi = 0.1 contour (the surface). Returns the mappable (colour range 0 to ``vmax_f``)."""
    h = params["h"]
    nx, ny = int(round(params["width"] / h)), int(round(params["height"] / h))
    x = frame["bed.x"]
    f, xe, ye = f_field(frame, params)
    im = ax.pcolormesh(xe, ye, np.ma.masked_invalid(f.T), cmap="viridis", vmin=0.0,
                       vmax=vmax_f, shading="flat", rasterized=True)
    for key, grey in (("wheel.x", "0.45"), ("body.hub.x", "0.2")):
        if key in frame:
            ax.scatter(frame[key][:, 0], frame[key][:, 1], s=4, c=grey, linewidths=0,
                       marker="s", rasterized=True)
    gp = grid_phi(x, frame["bed.phi"] * frame["bed.V"], h, nx, ny)
    xs = np.arange(nx + 1) * h
    gpp = np.vstack([gp, gp[:1]])
    ax.contour(xs, np.arange(ny + 1) * h, gpp.T, levels=[SURFACE_PHI], colors="w",
               linewidths=1.2)
    k = arrow_cells
    L = VECTOR_SCALE * math.sqrt(params["radius"] / params["gravity"])
    vx = cell_average(x, frame["bed.v"][:, 0], frame["bed.m"], k * h, nx // k, ny // k)
    vy = cell_average(x, frame["bed.v"][:, 1], frame["bed.m"], k * h, nx // k, ny // k)
    X, Y = np.meshgrid((np.arange(nx // k) + 0.5) * k * h, (np.arange(ny // k) + 0.5) * k * h,
                       indexing="ij")
    ok = np.isfinite(vx) & np.isfinite(vy)
    ax.quiver(X[ok], Y[ok], L * vx[ok], L * vy[ok], angles="xy", scale_units="xy", scale=1.0,
              width=0.002, headwidth=4, color="k")
    ax.set_xlim(0, nx * h)
    ax.set_ylim(0, min(ny * h, params["bed_depth"] + 3 * params["radius"]))
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return im


def _state_title(res: dict, R: float) -> str:
    """What a run shows, from its summary entry (:func:`analyse`)."""
    return (f"omega = {res['omega_per_s']:g} 1/s: the hub sank {res['sink_depth_m'] * 1e3:.0f} "
            f"mm ({res['sink_over_R']:.2f} R) by t = {res['t_end_s']:.2g} s, at most "
            f"{res['max_sink_m'] * 1e3:.0f} mm ({res['max_sink_m'] / R:.2f} R), and advanced "
            f"{res['advance_m']:.2f} m")


def _calibration(phi0) -> str:
    """What the bed's phi0 is, for a figure's title."""
    if abs(phi0 - 0.5075) < 1e-12:
        return ("phi0 = 0.5075: a calibration inside the author's 0.50-0.51 (only a narrow "
                "window of phi0 gives the two wheels' contrast)")
    return f"phi0 = {phi0:g} (the calibrated default is 0.5075)"


def snapshots_figure(out, params, omega, path, n=4, summary=None):
    """Fig. 8 (omega = 10) / Fig. 9 (omega = 1): the state at n times, one colour scale for all
    panels spanning f of every panel (at least to f_jam, marked on the bar); with the run's
    ``summary`` entry (:func:`analyse`) the title says how far the hub sank. ``path`` None:
    return the figure."""
    frames = load_frames(out)
    t_end = float(frames[-1]["time_s"])
    want = [t_end * (k + 1) / n for k in range(n)]
    chosen = [min(frames, key=lambda f: abs(float(f["time_s"]) - t)) for t in want]
    m = get_material("wheel")
    f_jam = (m.phi_j - params["phi0"]) / (m.phi_j - m.phi_c)
    vmax = max(f_jam, max(float(np.nanmax(fr["bed.f"])) for fr in chosen))
    fig, axs = plots.plt.subplots(n, 1, figsize=(9, 3.3 * n + 1.0), constrained_layout=True)
    for ax, fr in zip(np.atleast_1d(axs), chosen):
        im = draw_state(ax, fr, params, vmax)
        c = fr["body.hub.center"]
        ax.set_title(f"t = {float(fr['time_s']):.2f} s: hub centre at x = {c[0]:.2f} m, "
                     f"{(c[1] - _surface(params)) / params['radius']:+.2f} R above the "
                     "undisturbed surface", fontsize=9)
    cb = fig.colorbar(im, ax=axs, shrink=0.6,
                      label=f"f (cell average; jammed above f_jam = {f_jam:.2f}, where "
                            "phi_m(f) = phi0)")
    cb.ax.axhline(f_jam, color="w", lw=2)
    head = (_state_title(summary, params["radius"]) if summary is not None
            else f"omega = {omega:g} 1/s")
    fig.suptitle(head + f"\n{_calibration(params['phi0'])}; vectors: 1.215 v sqrt(R/g) on "
                 f"blocks of {ARROW_CELLS} x {ARROW_CELLS} cells; white line: the surface (grid "
                 f"phi = {SURFACE_PHI:g})", fontsize=10)
    return plots.save(fig, path) if path is not None else fig


def animation(runs, params, path):
    """GIF (matplotlib PillowWriter) of every run's snapshots side by side: runs = [(omega,
    folder)], one colour scale (0 to the largest f of every snapshot, at least f_jam)."""
    plt = plots.plt
    seqs = [(w, load_frames(d)) for w, d in runs]
    n = min(len(s) for _, s in seqs)
    m = get_material("wheel")
    f_jam = (m.phi_j - params["phi0"]) / (m.phi_j - m.phi_c)
    vmax = max([f_jam] + [float(np.nanmax(fr["bed.f"])) for _, seq in seqs for fr in seq])
    fig, axs = plt.subplots(len(seqs), 1, figsize=(8, 2.4 * len(seqs)))
    axs = np.atleast_1d(axs)
    writer = PillowWriter(fps=4)
    tmp = Path(path).with_name("." + Path(path).name + ".tmp.gif")
    with writer.saving(fig, str(tmp), dpi=80):
        for k in range(n):
            for ax, (w, seq) in zip(axs, seqs):
                ax.clear()
                draw_state(ax, seq[k], params, vmax, arrow_cells=2 * ARROW_CELLS)
                ax.set_title(f"omega = {w:g} 1/s, t = {float(seq[k]['time_s']):.2f} s "
                             f"(colour: f, 0 to {vmax:.2f})", fontsize=9)
            fig.tight_layout()
            writer.grab_frame()
    plt.close(fig)
    tmp.replace(path)
    return Path(path)


def hub_figure(hub: pd.DataFrame, R, path=None, summary=None):
    """Hub height change and advance against time for every omega of ``hub``; the fast-wheel
    band (+-FAST_BAND R) only where the fast wheel (omega = 10) is drawn, and the slow/fast
    ratios of the summary's checks in the title. ``path`` None: return the figure."""
    fig, axs = plots.plt.subplots(1, 2, figsize=(11, 4.8))
    for w, g in hub.groupby("omega_per_s"):
        t = g["time_s"].to_numpy()
        axs[0].plot(t, (g["y_m"] - g["y_m"].iloc[0]) / R, label=f"omega = {w:g} 1/s")
        axs[1].plot(t, (g["x_m"] - g["x_m"].iloc[0]) / R, label=f"omega = {w:g} 1/s")
    if OMEGAS[0] in set(hub["omega_per_s"]):
        axs[0].axhspan(-FAST_BAND, FAST_BAND, color="0.9", zorder=0,
                       label=f"fast-wheel check (omega = {OMEGAS[0]:g} only): within "
                             f"+-{FAST_BAND:.2g} R of its start")
    axs[0].set_ylabel("hub height change / R")
    axs[1].set_ylabel("hub advance / R")
    for ax in axs:
        ax.set_xlabel("t [s]")
    title = f"hub of the wheel (R = {R:g} m)"
    if summary is not None:
        title = f"{title}; {_calibration(summary['phi0'])}\n"
        runs = summary["runs"]
        title += "sink at t_end " + ", ".join(
            f"{r['sink_depth_m'] * 1e3:.0f} mm (largest {r['max_sink_m'] * 1e3:.0f} mm) at "
            f"omega = {r['omega_per_s']:g} 1/s" for r in runs.values())
        ch = summary["checks"]
        if "slow_sinks_3x" in ch:
            ratio = (f"{ch['sink_ratio']:.2f}" if ch["sink_ratio"] is not None
                     else "undefined (the fast wheel did not sink)")
            dip = (f"{ch['sink_ratio_largest_dip']:.2f}"
                   if ch.get("sink_ratio_largest_dip") is not None else "undefined")
            title += (f"\nslow/fast sink {ratio} at t_end (check >= {SINK_RATIO:g}: "
                      f"{'passed' if ch['slow_sinks_3x'] else 'failed'}), {dip} by the "
                      f"largest dips; fast wheel within +-{FAST_BAND:.2g} R: "
                      f"{'yes' if ch['fast_stays_up'] else 'no'}")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0.08, 1, 0.95))
    handles, labels = axs[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8,
               frameon=False)
    return plots.save(fig, path) if path is not None else fig


def pressure_figure(cases, params_of, path, t=1.0, t_from=None):
    """Fig. 14: granular pressure under the wheel at time t for each case (label, run folder),
    three maps a row (each titled with its snapshot's noise), and per case the noise's mean over
    the snapshots from ``t_from`` to t with its standard error (bars; :func:`mean_pressure_noise`;
    ``t_from`` None: t/3). Returns (path, {label: snapshot noise}, {label: (mean, sem, n)})."""
    plt = plots.plt
    t_from = t / 3.0 if t_from is None else t_from
    n = len(cases)
    rows = (n + 2) // 3
    fig = plt.figure(figsize=(12, 3.0 * rows + 3.2), constrained_layout=True)
    gs = fig.add_gridspec(rows + 1, 3)
    noise, mean = {}, {}
    for k, (label, folder) in enumerate(cases):
        p = params_of(folder)
        fr = frame_at(folder, t)
        pw, xe, ye = pressure_window(fr, p)
        noise[label] = pressure_noise(fr, p)
        mean[label] = mean_pressure_noise(folder, p, t_from, t)
        ax = fig.add_subplot(gs[k // 3, k % 3])
        if pw.size:
            im = ax.pcolormesh(xe, ye, pw.T / 1e3, cmap="magma", shading="flat")
            fig.colorbar(im, ax=ax, label="p~ [kPa]", shrink=0.8)
        ax.set_aspect("equal")
        ax.set_title(f"{label}: t = {float(fr['time_s']):.2f} s, noise {noise[label]:.2f}",
                     fontsize=9)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    ax = fig.add_subplot(gs[rows, :])
    ax.bar(range(n), [mean[c[0]][0] for c in cases], yerr=[mean[c[0]][1] for c in cases],
           capsize=4, color="C1")
    ax.set_xticks(range(n))
    ax.set_xticklabels([c[0] for c in cases], fontsize=8)
    ax.set_ylabel(f"RMS cell jump of p~ / mean p~\n(mean over {t_from:.2g}-{t:.2g} s, +- s.e.)")
    return plots.save(fig, path), noise, mean


# ---------------------------------------------------------------- report


def report(sim, history, out, params, omega):
    """One run's tables and figures; the default run (omega = none) then runs the other omegas
    in DIR/omega_<w> and writes the combined hub.csv, summary.json, hub.png, fig8/fig9, GIF."""
    out = Path(out)
    R = params["radius"]
    runs = [(omega, out, history)]
    if params["omega"] is None:
        for w in OMEGAS[1:]:
            sub = out / f"omega_{_omega_key(w)}"
            resume = (sub / "checkpoint.npz").exists()
            given = {k: v for k, v in params.items() if k != "omega"}
            res = runner.run_scene(setup, sub, {**given, "omega": w}, resume=resume,
                                   progress=True, vtk=(out / "vtk").exists(),
                                   log=lambda msg: print(msg, flush=True))
            runs.append((w, sub, res["history"]))
    hub = pd.concat([hub_table(h_, w) for w, _, h_ in runs], ignore_index=True)
    results = {_omega_key(w): analyse(h_, params, w) for w, _, h_ in runs}
    summary = {"omegas_per_s": [float(w) for w, _, _ in runs],
               "sink_depth_m": {k: r["sink_depth_m"] for k, r in results.items()},
               "runs": results, "checks": checks(results, R),
               "radius_m": R, "phi0": params["phi0"], "h_m": params["h"],
               "moduli_factor": params["moduli_factor"], "transfer": params["transfer"],
               "sink_depth_definition": "hub height at t = 0 minus at t_end [m] (> 0: sank)"}
    paths = [atomic_write_csv(out / "hub.csv", hub),
             atomic_write_json(out / "summary.json", _finite(summary),
                               nullable=("sink_ratio", "sink_ratio_largest_dip",
                                         "speed_m_per_s", "wheel_spin_per_s")),
             hub_figure(hub, R, out / "hub.png", summary)]
    for w, folder, _ in runs:
        name = {10.0: "fig8.png", 1.0: "fig9.png"}.get(float(w), f"state_omega_{_omega_key(w)}.png")
        paths.append(snapshots_figure(folder, params, w, out / name,
                                      summary=results[_omega_key(w)]))
    paths.append(animation([(w, folder) for w, folder, _ in runs], params, out / "wheel.gif"))
    return [Path(p) for p in paths]


# ---------------------------------------------------------------- sweeps
def transition_omega(omegas, sinks) -> float:
    """The omega [1/s] where the sink depth crosses half-way between its largest and smallest
    value over the sweep, interpolated linearly in log omega between the bracketing cases (the
    first crossing from below); NaN if it never crosses."""
    w = np.asarray(omegas, float)
    s = np.asarray(sinks, float)
    order = np.argsort(w)
    w, s = w[order], s[order]
    if len(w) < 2:
        return float("nan")
    mid = 0.5 * (s.max() + s.min())
    for k in range(len(w) - 1):
        if s[k] >= mid > s[k + 1]:
            a = (s[k] - mid) / (s[k] - s[k + 1])
            return float(math.exp(math.log(w[k]) + a * (math.log(w[k + 1]) - math.log(w[k]))))
    return float("nan")


def sweep_report(table, out) -> list:
    """``out/sink.csv`` (omega_per_s, sink_depth_m, max_excursion_over_R, advance_m, case) and
    ``out/sink.png`` (sink depth against omega with the transition omega), from each case's
    ``summary.json``."""
    out = Path(out)
    rows = []
    R = None
    for case, _, s in case_summaries(table, out):
        R = s["radius_m"]
        for k, res in s["runs"].items():
            rows.append({"omega_per_s": res["omega_per_s"], "sink_depth_m": res["sink_depth_m"],
                         "max_excursion_over_R": res["max_excursion_over_R"],
                         "advance_m": res["advance_m"], "case": case})
    if not rows:
        return []
    df = pd.DataFrame(rows).sort_values("omega_per_s")
    wt = transition_omega(df["omega_per_s"], df["sink_depth_m"])
    paths = [atomic_write_csv(out / "sink.csv", df)]
    atomic_write_json(out / "transition.json", {"transition_omega_per_s": _finite(wt),
                                                "omegas_per_s": df["omega_per_s"].tolist(),
                                                "sink_depth_m": df["sink_depth_m"].tolist()},
                      nullable=("transition_omega_per_s",))
    paths.append(out / "transition.json")
    fig, ax = plots.plt.subplots(figsize=(5.5, 4.2))
    ax.plot(df["omega_per_s"], df["sink_depth_m"] / R, "ko-")
    if math.isfinite(wt):
        ax.axvline(wt, color="r", ls="--", label=f"transition omega = {wt:.2g} 1/s")
        ax.legend(fontsize=8)
    ax.set_xscale("log")
    ax.set_xlabel("omega [1/s]")
    ax.set_ylabel("sink depth at t_end / R")
    ax.set_title("running on oobleck: sink depth against omega", fontsize=9)
    paths.append(plots.save(fig, out / "sink.png"))
    return [Path(p) for p in paths]
