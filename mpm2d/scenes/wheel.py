"""An elastic wheel driven at a prescribed angular velocity (plane strain).

Equations: plane-strain linear elasticity (Jaumann rate) for the wheel's spokes and rim,
rho dv/dt = div sigma + rho g; the hub is a rigid body whose angular velocity is prescribed
(omega, clockwise, i.e. driving to +x) while its translation is free (mass, gravity, contact
through the grid). The spokes attach to the hub through the shared grid nodes. The bed is by
default a locked Table 7 (``wheel``) suspension at phi0 (mode locked mixture), or an elastic
block (``bed=elastic``, single phase).

Geometry after the paper's running-on-oobleck wheel (Figs. 8-9): radius R = 15 cm, density
3000 kg/m^3, four spokes, h = 13.3 mm (150 x 75 cells over 2 m x 1 m in the paper). The
wheel's stiffness is not given by the paper: E = 1e7 Pa, nu = 0.3 is our choice. This scene
proves the driven elastic body (the report compares the wheel points' mean angular velocity
about the hub with omega); reproducing the paper's run-or-sink result (deeper bed, phi0, the
contact law) belongs to the wheel issue. The wheel (spokes and rim) has its own velocity field:
the spokes are bonded to the hub, the rim meets the bed through multi-velocity-field contact
(mpm2d.contact; no slip, mu_w = inf, free to separate). The bed starts at rest under gravity
(mpm2d.geostatic).

Parameters: omega [1/s], radius [m], hub_radius [m], spoke_width [m], rim_width [m],
density [kg/m^3], E, nu (wheel), bed (suspension or elastic), E_bed, nu_bed, rho_bed [kg/m^3]
(elastic bed), phi0 (suspension bed), width, height, bed_depth [m], h [m], t_end [s], cfl.

Run: ``mpm2d run wheel --set omega=10 --out wheel``
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from rheology import get_material
from rheology.io import atomic_write_csv

from .. import plots
from ..bodies import RigidBody, box, fill
from ..geostatic import geostatic
from ..grid import Grid
from ..materials import LinearElastic, Suspension
from ..particles import ParticleSet
from . import spec
from ..run import Scene
from ..simulation import Simulation


#: Coulomb coefficient between rim and bed (inf: no slip, the former single-field behaviour)
WHEEL_MU_W = float("inf")


def wheel_shape(center, radius, hub_radius, spoke_width, rim_width, spacing):
    """Points of the spokes and rim (elastic) and of the hub (rigid), with areas."""
    c = np.asarray(center, float)

    def spokes_rim(x, y):
        dx, dy = x - c[0], y - c[1]
        r = np.hypot(dx, dy)
        rim = (r <= radius) & (r >= radius - rim_width)
        spokes = (r < radius) & ((np.abs(dx) < 0.5 * spoke_width) | (np.abs(dy) < 0.5 * spoke_width))
        return (rim | spokes) & (r > hub_radius)

    lo, hi = c - radius - spacing, c + radius + spacing
    elastic = fill(spokes_rim, lo, hi, spacing)
    hub = fill(lambda x, y: np.hypot(x - c[0], y - c[1]) <= hub_radius, lo, hi, spacing)
    return elastic, hub


@spec.parameters_of(
    omega=spec.positive(1000.0, "1/s", "prescribed angular velocity (driving to +x)"),
    radius=spec.positive(10.0, "m", "wheel radius R"),
    hub_radius=spec.Param(lambda p: p["h"], lambda p: p["radius"] - p["rim_width"],
                          hi_closed=False, unit="m", doc="rigid hub radius",
                          note="at least one cell, inside the rim: below radius - rim_width"),
    spoke_width=spec.Param(lambda p: p["h"] / 2, lambda p: p["radius"], unit="m",
                           doc="spoke width", note="half a cell (a point spacing) to the radius"),
    rim_width=spec.Param(lambda p: p["h"] / 2, lambda p: p["radius"] - p["h"], hi_closed=False,
                         unit="m", doc="rim width",
                         note="half a cell (a point spacing) to the radius minus a cell"),
    density=spec.density("wheel density"),
    E=spec.modulus("wheel Young's modulus"),
    nu=spec.Param(-1.0, 0.5, lo_closed=False, hi_closed=False, doc="wheel Poisson ratio"),
    bed=spec.Param(choices=("suspension", "elastic"), doc="bed material"),
    E_bed=spec.modulus("elastic bed: Young's modulus"),
    nu_bed=spec.Param(-1.0, 0.5, lo_closed=False, hi_closed=False,
                      doc="elastic bed: Poisson ratio"),
    rho_bed=spec.density("elastic bed: density"),
    phi0=spec.phi_below_jamming(fixed="wheel", doc="suspension bed: solid volume fraction"),
    width=spec.Param(lambda p: 4 * p["radius"], 100.0, unit="m", doc="domain width (periodic)",
                     note="at least 4 radii"),
    height=spec.Param(lambda p: p["bed_depth"] + 2 * p["radius"] + 2 * p["h"], 100.0, unit="m",
                      doc="domain height", note="bed + wheel + 2 cells"),
    bed_depth=spec.Param(lambda p: p["h"], 100.0, unit="m", doc="bed depth",
                         note="at least 1 cell"),
    h=spec.Param(lambda p: p["radius"] / 100.0, lambda p: p["radius"] / 4.0, unit="m",
                 doc="cell size", note="radius/100 to radius/4"),
    t_end=spec.positive(100.0, "s", "end time"),
    gravity=spec.gravity(), cfl=spec.cfl(),
    size=lambda p: (4 * (p["width"] * p["bed_depth"] + 3.1416 * p["radius"] ** 2) / p["h"] ** 2,
                    (p["width"] / p["h"] + 5) * (p["height"] / p["h"] + 5)))
def setup(omega=10.0, radius=0.15, hub_radius=0.04, spoke_width=0.03, rim_width=0.03,
          density=3000.0, E=1.0e7, nu=0.3, bed="suspension", E_bed=1.0e6, nu_bed=0.3,
          rho_bed=1620.0, phi0=0.45, width=1.2, height=0.6, bed_depth=0.2, h=0.0133,
          t_end=0.4, gravity=9.81, cfl=0.5):
    params = dict(omega=omega, radius=radius, hub_radius=hub_radius, spoke_width=spoke_width,
                  rim_width=rim_width, density=density, E=E, nu=nu, bed=bed, E_bed=E_bed,
                  nu_bed=nu_bed, rho_bed=rho_bed, phi0=phi0, width=width, height=height,
                  bed_depth=bed_depth, h=h, t_end=t_end, gravity=gravity, cfl=cfl)
    nx, ny = int(round(width / h)), int(round(height / h))
    grid = Grid(nx, ny, h, boundaries=dict(xmin="periodic", xmax="periodic", ymin="noslip",
                                          ymax="free"))
    depth = bed_depth
    xb, ab = box((0.0, 0.0), (nx * h, depth), h / 2)
    if bed == "elastic":
        bed_mat = LinearElastic(rho_bed, E=E_bed, nu=nu_bed)
        bed_set = ParticleSet("bed", bed_mat, xb, ab)
        mode = "single phase"
    elif bed == "suspension":
        m = get_material("wheel")
        bed_set = ParticleSet("bed", Suspension(m, locked=True), xb, ab, phi=phi0, f=0.0)
        mode = "locked mixture"
    else:
        raise ValueError(f"bed = {bed!r} must be 'elastic' or 'suspension'")
    center = (0.3 * width, depth + radius + 0.5 * h)
    (xw, aw), (xh, ah) = wheel_shape(center, radius, hub_radius, spoke_width, rim_width, h / 2)
    wheel = ParticleSet("wheel", LinearElastic(density, E=E, nu=nu), xw, aw)
    # the spokes are bonded to the rigid hub; the rim meets the bed through contact (its own
    # velocity field, no-slip Coulomb limit mu_w = inf, free to separate: mpm2d.contact)
    hub = RigidBody("hub", xh, ah, density=density, omega=-omega, prescribed=("omega",),
                    bonded_to=("wheel",))
    sim = Simulation(grid, [bed_set, wheel], [hub], mode=mode, gravity=(0.0, -gravity), cfl=cfl,
                     name="wheel", contact_sets={"wheel": WHEEL_MU_W})
    geostatic(sim, sets=["bed"])          # the bed at rest under gravity (mpm2d.geostatic)

    def record(sim):
        b = sim.bodies[0]
        w = sim.sets[1]
        r = w.x - b.center
        rel = w.v - b.velocity
        spin = np.sum(w.m * (r[:, 0] * rel[:, 1] - r[:, 1] * rel[:, 0])) / np.sum(
            w.m * np.einsum("ij,ij->i", r, r))
        return {"wheel_omega_per_s": float(spin),
                "hub_x_m": float(b.center[0]), "hub_y_m": float(b.center[1]),
                "hub_vx_m_per_s": float(b.velocity[0]), "hub_vy_m_per_s": float(b.velocity[1]),
                "hub_torque_N": float(b.torque)}

    return Scene(sim, t_end, params, frames=10, history_rows=400, record=record,
                 report=lambda sim, hist, out: report(sim, hist, out, params),
                 notes=f"mode {mode}; hub: rigid body with prescribed omega, free translation")


def analyse(history, params) -> dict:
    """Over the second half: the wheel points' mean angular velocity about the hub (against the
    prescribed omega), the forward hub speed (against omega R) and the sinkage."""
    late = history[history["time_s"] > 0.5 * history["time_s"].iloc[-1]]
    t, x = late["time_s"].to_numpy(), late["hub_x_m"].to_numpy()
    speed = float(np.polyfit(t, x, 1)[0]) if len(t) > 2 else float("nan")
    ref = params["omega"] * params["radius"]
    spin = float(-late["wheel_omega_per_s"].mean())
    return {"wheel_omega_per_s": spin, "omega_per_s": params["omega"],
            "omega_error": abs(spin - params["omega"]) / params["omega"],
            "rolling_speed_m_per_s": speed, "omega_R_m_per_s": ref,
            "speed_ratio": speed / ref if ref else float("nan"),
            "sinkage_m": float(history["hub_y_m"].iloc[0] - history["hub_y_m"].iloc[-1])}


def report(sim, history, out, params):
    res = analyse(history, params)
    atomic_write_csv(out / "wheel_result.csv", pd.DataFrame([res]))
    fig, axs = plots.plt.subplots(1, 2, figsize=(13, 4.5))
    t = history["time_s"]
    axs[0].plot(t, history["hub_x_m"] - history["hub_x_m"].iloc[0], "r-", label="hub advance")
    axs[0].plot(t, params["omega"] * params["radius"] * t, "k--", label="omega R t")
    axs[0].plot(t, history["hub_y_m"] - history["hub_y_m"].iloc[0], "b-", label="hub height change")
    axs[0].set_xlabel("t [s]")
    axs[0].set_ylabel("displacement [m]")
    axs[0].legend()
    axs[0].set_title(f"wheel spin {res['wheel_omega_per_s']:.2f} 1/s (omega {params['omega']}); "
                     f"advance / omega R t = {res['speed_ratio']:.2f}")
    sc = plots.particles(axs[1], sim, "speed", size=2)
    fig.colorbar(sc, ax=axs[1], label="|v| [m/s]")
    axs[1].set_title(f"t = {sim.t:.2f} s, omega = {params['omega']} 1/s")
    fig.tight_layout()
    return [plots.save(fig, out / "wheel.png")]
