"""A small two-phase column: a suspension settling under gravity (granular + fluid points).

Equations: Table 8 in full. Granular points follow the suspension law (rheology.local_update:
stress free while separated, compaction and jamming in the bed), fluid points the Newtonian
fluid phase; Beetstra drag (implicit at the nodes), buoyancy, p_f = kappa ln(rho_f/rho_0f)::

    phi rho_s dv_s/dt = phi rho_s g + div sigma~ - phi grad p_f - C (v_s - v_f)
    n rho_f dv_f/dt   = n rho_f g   + div tau_f  - n grad p_f   + C (v_s - v_f)

A column of suspension at phi0 (periodic sideways, closed bottom, free top) starts at rest with
the hydrostatic pore pressure of the mixture. The grains settle; a clear fluid layer opens at
the top and a bed builds up from the bottom (Kynch). While the grains are suspended (no
contacts, stress free), the top interface descends at the hindered settling speed of phi0
(zero net volume flux in a closed column)::

    |v_s| = n^2 phi (rho_s - rho_f) g / C(phi, Re),  n = 1 - phi

(mpm2d.analytic.hindered_settling_velocity, with the Reynolds number solved consistently).
The bed compacts to the jamming fraction phi_m(f) and carries its buoyant weight elastically.

Parameter choices (the paper gives no settling scene): the Table 5 set ``rod_impact``
(cornstarch in water/glycerol, rho_s = 1620, rho_f = 1000 kg/m^3) with water's viscosity
eta0 = 1 mPa s, grains of d = 0.5 mm so settling takes seconds instead of days
(d = 5.85 um settles at ~1 um/s), and moduli K = G = kappa = 1e5 Pa so the explicit step is
~3e-5 s; elastic strains stay below 1% (the paper's criterion).

Parameters: height [m] (suspension), width_cells, cells (over the height), ppc, phi0,
material, d [m], eta0 [Pa s], K, G, kappa [Pa], t_end [s], gravity [m/s^2], cfl.

Run: ``mpm2d run column --out column`` (mode: two-phase)
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from rheology import get_material
from rheology.fluid import drag_coefficient
from runkit.io import atomic_write_csv
from runkit.limits import ge

from .. import analytic, plots
from ..bodies import box
from ..grid import Grid
from ..materials import NewtonianFluid, Suspension
from ..output import load_frames
from ..particles import ParticleSet
from . import spec
from ..run import Scene
from ..simulation import Drag, Simulation
from .beds import bed_phases


def _first_step(p) -> float:
    """The first step [s]: the wave limit of the grains (K + 4G/3 on phi0 rho_s) or the pore
    fluid (kappa on (1 - phi0) rho_f), or the fluid's viscous limit, whichever is smallest."""
    m = get_material(p["material"], d=p["d"], eta0=p["eta0"], K=p["K"], G=p["G"],
                     kappa=p["kappa"], rules=p["rules"])
    return spec.first_step(p["cfl"], p["height"] / p["cells"],
                           bed_phases(m, p["phi0"], "two-phase"))


@spec.parameters_of(
    height=spec.length("height of the suspension",
                       above=ge(lambda p: p["cells"] * p["d"],
                                "at least cells x d: a cell of at least one grain diameter, the "
                                "continuum limit of the model")),
    width_cells=spec.cells("cells across (periodic)", 2, 1000, hi_why="a 1-D settling: more "
                           "cells across only repeat the column"),
    cells=spec.cells("cells over the height"),
    ppc=spec.ppc(),
    phi0=spec.phi_below_jamming(),
    material=spec.Param(choices=spec.materials_where(
        lambda m: m.rho_s and m.rho_f and m.rho_s > m.rho_f, "sets with grains denser than the fluid"),
        doc="rheology parameter set (grains must be denser than the fluid)"),
    d=spec.grain_size(),
    eta0=spec.viscosity(),
    K=spec.modulus("granular bulk modulus"), G=spec.modulus("granular shear modulus"),
    kappa=spec.modulus("fluid bulk modulus"),
    t_end=spec.duration("end time"),
    gravity=spec.gravity("gravitational acceleration (downwards)"),
    rules=spec.rules(),
    cfl=spec.cfl(),
    size=lambda p: (2 * p["width_cells"] * p["cells"] * p["ppc"] ** 2,
                    (p["width_cells"] + 5) * (p["cells"] + 9)),
    steps=lambda p: (_first_step(p), p["t_end"], 1))
def setup(height=0.02, width_cells=4, cells=20, ppc=2, phi0=0.3, material="rod_impact", d=5e-4,
          eta0=1e-3, K=1e5, G=1e5, kappa=1e5, t_end=1.5, gravity=9.81, rules="table8", cfl=0.5):
    params = dict(locals())                   # every parameter, as checked
    m = get_material(material, d=d, eta0=eta0, K=K, G=G, kappa=kappa, rules=rules)
    m.require("rho_s", "rho_f")
    h = height / cells
    grid = Grid(width_cells, cells + 4, h, boundaries=dict(xmin="periodic", xmax="periodic",
                                                          ymin="noslip", ymax="free"))
    x, area = box((0.0, 0.0), (width_cells * h, height), h / ppc)
    rho_mix = phi0 * m.rho_s + (1 - phi0) * m.rho_f
    p_hydro = rho_mix * gravity * (height - x[:, 1])          # the suspension's weight
    grains = ParticleSet("grains", Suspension(m), x, area, phi=phi0, f=0.0)
    fluid = ParticleSet("fluid", NewtonianFluid.from_material(m), x, area, phi=phi0,
                        rho_f=m.rho_f * np.exp(p_hydro / m.kappa))
    sim = Simulation(grid, [grains, fluid], mode="two-phase", drag=Drag.from_material(m),
                     gravity=(0.0, -gravity), cfl=cfl, name="column")
    def record(sim):
        g = sim.sets[0]
        return {"interface_m": interface_height(g.x[:, 1], h / ppc, width_cells * ppc),
                "max_phi": float(np.max(g.svol / g.V)),
                "bed_pressure_Pa": float(np.mean(-np.trace(g.stress[g.x[:, 1] < h], axis1=1,
                                                          axis2=2) / 3.0)),
                "mean_grain_velocity_m_per_s": float(np.mean(g.v[:, 1])),
                **dict(zip(("suspended_grain_velocity_m_per_s", "suspended_share"),
                           suspended_grains(g, phi0)))}

    return Scene(sim, t_end, params, frames=10, history_rows=300, record=record,
                 report=lambda sim, hist, out: report(sim, hist, out, params),
                 frame_times=tuple(np.linspace(0, t_end, 6)[1:]),
                 notes="mode two-phase: granular and fluid points, implicit Beetstra drag",
                 undefined=("suspended_grain_velocity_m_per_s",))


def suspended_grains(g, phi0):
    """Mean vertical velocity [m/s] of the grains still at phi0 (within 2%), and their share."""
    phi = g.svol / g.V
    sel = np.abs(phi - phi0) < 0.02 * phi0
    return (float(np.mean(g.v[sel, 1])) if sel.any() else float("nan"),
            float(np.count_nonzero(sel)) / len(phi))


def interface_height(y, spacing, per_row) -> float:
    """Height of the suspension's top [m]: the mean of the highest row of grains plus half a
    point spacing (robust to single stray points)."""
    top = np.sort(y)[-per_row:]
    return float(np.mean(top) + 0.5 * spacing)


def settling_speed(params) -> float:
    """Hindered settling speed of phi0 with the Reynolds number solved consistently [m/s]."""
    m = get_material(params["material"], d=params["d"], eta0=params["eta0"])
    phi, g = params["phi0"], params["gravity"]
    v = 0.0
    for _ in range(50):                      # fixed point in Re (converges in a few sweeps)
        rel = v / (1.0 - phi)                # v_s - v_f with zero net flux
        C = float(drag_coefficient(phi, m, m.rho_f * rel * m.d / m.eta0))
        v = analytic.hindered_settling_velocity(phi, m.rho_s, m.rho_f, g, C)
    return v


def analyse(history, params) -> dict:
    """Settling speed of the suspension at phi0 against Kynch's hindered settling speed.

    Two measures: the mean velocity of the grains still at phi0 (after the start-up, 0.05 s,
    while at least 30% of the grains are suspended), and the slope of the interface height while
    less than 40% of the column has settled (quantised by the point rows: use runs with a drop of
    several cells).
    """
    v_exact = settling_speed(params)
    t0 = history["time_s"]
    ok = (t0 > 0.05) & (history["suspended_share"] > 0.3)
    v_grains = float(-history.loc[ok, "suspended_grain_velocity_m_per_s"].mean()) if ok.any() \
        else float("nan")
    h0 = history["interface_m"].iloc[0]
    drop = h0 - history["interface_m"]
    t = history["time_s"]
    # fit after the start-up (drag time ~ ms) while less than 40% of the column has settled
    sel = (t > 0.05 * t.iloc[-1]) & (drop < 0.4 * params["height"])
    slope = float(-np.polyfit(t[sel], history["interface_m"][sel], 1)[0]) if sel.sum() >= 3 \
        else float("nan")
    return {"settling_speed_exact_m_per_s": v_exact, "grain_speed_m_per_s": v_grains,
            "grain_speed_error": abs(v_grains - v_exact) / v_exact,
            "interface_speed_m_per_s": slope, "relative_error": abs(slope - v_exact) / v_exact}


def report(sim, history, out, params):
    res = analyse(history, params)
    snaps = {float(f["time_s"]): (f["grains.x"][:, 1], f["grains.phi"])
             for f in load_frames(out, "event")}
    # undefined (empty) for a run too short to measure: no suspended grains after 0.05 s, or
    # fewer than 3 history rows before 40% of the column has settled
    atomic_write_csv(out / "column_result.csv", pd.DataFrame([res]),
                     empty_ok=("grain_speed_m_per_s", "grain_speed_error",
                               "interface_speed_m_per_s", "relative_error"))
    fig, axs = plots.plt.subplots(1, 3, figsize=(13, 5), width_ratios=(3, 3, 1.2))
    t = history["time_s"]
    h0 = history["interface_m"].iloc[0]
    axs[0].plot(t, history["interface_m"] * 1e3, "r-", label="MPM: top of the grains")
    axs[0].plot(t, (h0 - res["settling_speed_exact_m_per_s"] * t) * 1e3, "k--",
                label="hindered settling of phi0 (Kynch)")
    axs[0].set_ylim(0, params["height"] * 1.1e3)
    axs[0].set_xlabel("t [s]")
    axs[0].set_ylabel("height [mm]")
    axs[0].legend()
    axs[0].set_title(f"interface speed error {100 * res['relative_error']:.1f}%, suspended "
                     f"grains {100 * res['grain_speed_error']:.1f}%")
    h = params["height"] / params["cells"]
    bins = np.arange(0, params["height"] + h, h)
    for i, (tt, (y, phi)) in enumerate(sorted(snaps.items())):
        idx = np.digitize(y, bins)
        prof = [np.mean(phi[idx == k]) if np.any(idx == k) else np.nan
                for k in range(1, len(bins))]
        axs[1].plot(prof, 0.5 * (bins[1:] + bins[:-1]) * 1e3, "o-", ms=3,
                    color=plots.plt.cm.viridis(i / max(len(snaps) - 1, 1)), label=f"t = {tt:.2f} s")
    axs[1].set_xlabel("grain volume fraction phi")
    axs[1].set_ylabel("height [mm]")
    axs[1].legend(fontsize=8)
    axs[1].set_title("phi profiles (grain points)")
    sc = plots.particles(axs[2], sim, "phi", sets=["grains"], cmap="magma")
    fig.colorbar(sc, ax=axs[2], label="phi")
    axs[2].set_title(f"grains at t = {sim.t:.2f} s")
    return [plots.save(fig, out / "column.png")]
