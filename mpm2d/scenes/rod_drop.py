"""A free rigid rod falls onto a suspension bed (axisymmetric, locked mixture).

Equations: axisymmetric (r, z) locked mixture of the Table 8 law (rheology.local_update) with
the undrained pore pressure; the rod is a free rigid body (mass, gravity, axial translation)
meeting the bed through multi-velocity-field contact (mpm2d.contact: only where the surfaces
touch, while they approach, frictionless, free to separate), solved implicitly with the rod's
velocity (no added-mass limit on dt)::

    M V^{n+1} = M (V^n + dt g) - sum_k lambda_k,   F_rod = -sum_k lambda_k/dt

A small version of the paper's rod impact (Fig. 4-5; Waitukaitis & Jaeger 2012): an aluminium
rod (radius 5 mm, length 20 mm, 2700 kg/m^3) hits a bed of cornstarch suspension (Table 5 set
``rod_impact``, phi0 = 0.47) at v0 = 1 m/s. The paper's moduli (K = 8.3e7 Pa) need dt ~ 1e-6 s
at h = 1 mm; this demonstration uses the Table 4 moduli (K = 8.3e5, G = 3.8e5 Pa,
kappa = 8.3e5 Pa) for dt ~ 1e-5 s, with elastic strains still below 1%. The bed starts at rest
(mpm2d.geostatic): phi0 < phi_j, so its grains carry nothing and the pore pressure the whole
weight, rho_mix g depth. The paper's full scene is mpm2d.scenes.impact; this one proves the coupling.

Parameters: radius (container) [m], depth (bed) [m], cells_per_mm (1/h in 1/mm), rod_radius,
rod_length [m], rod_density [kg/m^3], v0 [m/s], phi0, K, G, kappa [Pa], t_end [s], cfl.

Run: ``mpm2d run rod_drop --out rod_drop`` (mode: locked mixture)
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from rheology import get_material
from runkit.io import atomic_write_csv
from runkit.limits import ge, lt

from .. import plots
from ..bodies import RigidBody, box
from ..geostatic import geostatic
from ..grid import Grid
from ..materials import Suspension
from ..particles import ParticleSet
from . import spec
from ..run import Scene
from ..simulation import Simulation
from .beds import bed_phases


def _steps(p) -> tuple:
    """(first step [s], end time [s], fewest steps) from the parameters: the wave limit of the
    locked mixture (the scene's K, G, kappa), its viscous limit or the advection of the rod at
    v0, whichever is smallest."""
    m = get_material("rod_impact", K=p["K"], G=p["G"], kappa=p["kappa"], rules=p["rules"])
    return (spec.first_step(p["cfl"], 1e-3 / p["cells_per_mm"],
                            bed_phases(m, p["phi0"], "locked mixture"), p["v0"]), p["t_end"], 1)


@spec.parameters_of(
    radius=spec.length("container radius",
                       above=ge(lambda p: 2e-3 / p["cells_per_mm"], "at least 2 cells")),
    depth=spec.length("bed depth", above=ge(lambda p: 1e-3 / p["cells_per_mm"],
                                            "at least 1 cell")),
    cells_per_mm=spec.resolution(),
    rod_radius=spec.length("rod radius",
                           above=ge(lambda p: 0.5e-3 / p["cells_per_mm"], "at least h/2"),
                           below=lt(lambda p: p["radius"], "inside the container")),
    rod_length=spec.length("rod length",
                           above=ge(lambda p: 0.5e-3 / p["cells_per_mm"], "at least h/2")),
    rod_density=spec.density("rod density"),
    v0=spec.speed("impact speed (downwards; 0: dropped from rest)", also=(0.0,)),
    phi0=spec.phi_below_jamming(fixed="rod_impact", doc="solid volume fraction of the bed"),
    K=spec.modulus("granular bulk modulus"), G=spec.modulus("granular shear modulus"),
    kappa=spec.modulus("fluid bulk modulus"),
    t_end=spec.duration("end time"),
    gravity=spec.gravity(), rules=spec.rules(), cfl=spec.cfl(),
    size=lambda p: (4 * (p["radius"] * p["depth"] + p["rod_radius"] * p["rod_length"])
                    * (p["cells_per_mm"] * 1e3) ** 2,
                    (p["radius"] * p["cells_per_mm"] * 1e3 + 5)
                    * ((p["depth"] + p["rod_length"]) * p["cells_per_mm"] * 1e3 + 11)),
    steps=lambda p: _steps(p))
def setup(radius=0.03, depth=0.03, cells_per_mm=1.0, rod_radius=0.005, rod_length=0.02,
          rod_density=2700.0, v0=1.0, phi0=0.47, K=8.3e5, G=3.8e5, kappa=8.3e5, t_end=0.02,
          gravity=9.81, rules="table8", cfl=0.5):
    params = dict(locals())                   # every parameter, as checked
    h = 1e-3 / cells_per_mm
    m = get_material("rod_impact", K=K, G=G, kappa=kappa, rules=rules)
    nx = int(round(radius / h))
    nz = int(round((depth + rod_length + 4 * h) / h)) + 2
    grid = Grid(nx, nz, h, axisymmetric=True,
                boundaries=dict(xmin="axis", xmax="slip", ymin="noslip", ymax="free"))
    x, area = box((0.0, 0.0), (nx * h, depth), h / 2)
    bed = ParticleSet("bed", Suspension(m, locked=True), x, area, phi=phi0, f=0.0,
                      axisymmetric=True)
    z0 = depth + h
    xr, ar = box((0.0, z0), (rod_radius, z0 + rod_length), h / 2)
    rod = RigidBody("rod", xr, ar, density=rod_density, velocity=(0.0, -v0), prescribed="none",
                    axisymmetric=True, mu_w=0.0)
    sim = Simulation(grid, [bed], [rod], gravity=(0.0, -gravity), cfl=cfl, name="rod_drop")
    # the bed at rest under gravity (mpm2d.geostatic): a loose bed (phi0 < phi_j) carries its
    # weight in the pore pressure rho_mix g d, grains stress-free, f = 0, residual relaxed
    geostatic(sim)
    def record(sim):
        r = sim.bodies[0]
        return {"rod_depth_m": depth - (r.center[1] - 0.5 * rod_length),
                "rod_velocity_m_per_s": float(r.velocity[1]),
                "rod_force_N_per_rad": float(r.force[1]),
                "rod_acceleration_m_per_s2": float(r.force[1] / r.mass - gravity),
                "max_f": float(np.max(sim.sets[0].f))}

    return Scene(sim, t_end, params, frames=10, history_rows=400, record=record,
                 report=lambda sim, hist, out: report(sim, hist, out, params),
                 notes="mode locked mixture; rod: free rigid body in frictionless contact; bed geostatic")


def report(sim, history, out, params):
    rod = sim.bodies[0]
    res = {"rod_mass_kg_per_rad": rod.mass, "final_velocity_m_per_s": float(rod.velocity[1]),
           "final_depth_m": float(history["rod_depth_m"].iloc[-1]),
           "max_deceleration_m_per_s2": float(history["rod_acceleration_m_per_s2"].max()),
           "max_f": float(history["max_f"].max())}
    atomic_write_csv(out / "rod_drop_result.csv", pd.DataFrame([res]))
    fig, axs = plots.plt.subplots(1, 4, figsize=(17, 4.5), width_ratios=(3, 3, 3, 2))
    t = history["time_s"] * 1e3
    axs[0].plot(t, history["rod_depth_m"] * 1e3, "r-")
    axs[0].set_ylabel("rod tip depth below the bed surface [mm]")
    axs[1].plot(t, history["rod_velocity_m_per_s"], "b-")
    axs[1].set_ylabel("rod velocity [m/s]")
    axs[2].plot(t, history["rod_acceleration_m_per_s2"], "k-", lw=1)
    axs[2].set_ylabel("rod acceleration [m/s^2]")
    for ax in axs[:3]:
        ax.set_xlabel("t [ms]")
    sc = plots.particles(axs[3], sim, "f", cmap="inferno", vmin=0.0, vmax=1.0)
    fig.colorbar(sc, ax=axs[3], label="structure f")
    axs[3].set_title(f"t = {sim.t * 1e3:.1f} ms")
    fig.tight_layout()
    return [plots.save(fig, out / "rod_drop.png")]
