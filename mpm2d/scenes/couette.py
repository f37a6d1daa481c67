"""Newtonian startup of plane Couette flow (verification against the series solution).

Equations (single phase, weakly compressible Newtonian fluid)::

    rho dv/dt = div(-p 1 + eta (L + L^T - 2/3 tr L 1)),  p = kappa ln(rho/rho0)

Fluid at rest between a fixed wall y = 0 and a wall y = H that moves at U from t = 0 (noslip
walls with wall velocity; periodic in x). Shear flow does not compress the fluid, so the exact
solution is the incompressible series (mpm2d.analytic.couette_startup)::

    u(y, t) = U y/H + sum_k 2U(-1)^k/(k pi) sin(k pi y/H) exp(-nu k^2 pi^2 t/H^2),  nu = eta/rho

The particle velocities live at half steps and are compared at t - dt/2, at the times
t = ``profile_T`` H^2/nu (the impulsive start's boundary layer is resolved by then).

Parameters: gap H [m], cells (across the gap), ppc, eta [Pa s], rho [kg/m^3], kappa [Pa],
U [m/s], t_end_T (end time in units of H^2/nu), transfer, cfl.

Run: ``mpm2d run couette --set cells=32 --out couette``
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from runkit.io import atomic_write_csv
from runkit.limits import le

from .. import analytic, plots
from ..bodies import box
from ..grid import Grid
from ..materials import NewtonianFluid
from ..output import load_frames
from ..particles import ParticleSet
from . import spec
from ..run import Scene
from ..simulation import Simulation

PROFILE_T = (0.02, 0.05, 0.1, 0.2, 0.5)


def _steps(p) -> tuple:
    """(first step [s], end time [s], fewest steps) from the parameters: the acoustic
    (kappa on rho) or viscous (eta/rho) limit, whichever is smaller (the fluid starts at rest);
    ``t_end_T`` times H^2/nu."""
    fluid = NewtonianFluid(p["eta"], p["rho"], p["kappa"], einstein=False)
    return (spec.first_step(p["cfl"], p["gap"] / p["cells"], [(fluid, p["rho"])]),
            p["t_end_T"] * p["gap"] ** 2 * p["rho"] / p["eta"], 1)


@spec.parameters_of(
    gap=spec.length("gap H"),
    cells=spec.cells("cells across the gap"),
    ppc=spec.ppc(),
    eta=spec.viscosity("viscosity"),
    rho=spec.density(),
    kappa=spec.modulus("bulk modulus"),
    U=spec.speed("velocity of the moving wall",
                 below=le(lambda p: 0.1 * (p["kappa"] / p["rho"]) ** 0.5,
                          "U <= 0.1 c, c = sqrt(kappa/rho): nearly incompressible")),
    t_end_T=spec.runs_for("end time in units of H^2/nu", 100.0, "100 H^2/nu: the flow is "
                          "steady (to e^-1000) long before"),
    transfer=spec.transfer(), cfl=spec.cfl(),
    size=lambda p: (2 * p["cells"] * p["ppc"] ** 2, (p["cells"] + 5) * 7),
    steps=lambda p: _steps(p))
def setup(gap=0.01, cells=16, ppc=2, eta=0.1, rho=1000.0, kappa=1.0e4, U=0.01, t_end_T=0.5,
          transfer="apic", cfl=0.5):
    params = dict(locals())                   # every parameter, as checked
    h = gap / cells
    grid = Grid(2, cells, h, boundaries=dict(xmin="periodic", xmax="periodic", ymin="noslip",
                                            ymax="noslip"), wall_velocity={"ymax": (U, 0.0)})
    x, area = box((0.0, 0.0), (2 * h, gap), h / ppc)
    fluid = ParticleSet("fluid", NewtonianFluid(eta, rho, kappa, einstein=False), x, area)
    sim = Simulation(grid, [fluid], transfer=transfer, cfl=cfl, name="couette")
    t_nu = gap ** 2 * rho / eta

    def record(sim):
        f = sim.sets[0]
        mid = np.abs(f.x[:, 1] - 0.5 * gap) < 0.5 * h / ppc + 1e-12
        return {"mid_velocity_m_per_s": float(np.mean(f.v[mid, 0]))}

    return Scene(sim, t_end_T * t_nu, params, frames=10, history_rows=2000, record=record,
                 report=lambda sim, hist, out: report(out, params),
                 frame_times=tuple(T * t_nu for T in PROFILE_T if T <= t_end_T + 1e-12))


def profiles(out) -> list[tuple]:
    """(t - dt/2, y, u) at the profile times (velocities live at half steps)."""
    return [(float(f["time_s"] - 0.5 * f["dt_s"]), f["fluid.x"][:, 1], f["fluid.v"][:, 0])
            for f in load_frames(out, "event")]


def analyse(params, profiles) -> list[dict]:
    """Max |u - u_exact|/U over the points at each profile time."""
    nu = params["eta"] / params["rho"]
    t_nu = params["gap"] ** 2 / nu
    rows = []
    for t, y, u in profiles:
        ex = analytic.couette_startup(y, t, params["gap"], params["U"], nu)
        rows.append({"time_s": t, "T": t / t_nu, "cells": params["cells"],
                     "max_error": float(np.max(np.abs(u - ex)) / params["U"]),
                     "rms_error": float(np.sqrt(np.mean((u - ex) ** 2)) / params["U"])})
    return rows


def report(out, params):
    prof = profiles(out)
    rows = analyse(params, prof)
    atomic_write_csv(out / "couette_result.csv", pd.DataFrame(rows))
    nu = params["eta"] / params["rho"]
    fig, ax = plots.plt.subplots(figsize=(6.5, 5))
    y = np.linspace(0, params["gap"], 200)
    for i, (t, yp, u) in enumerate(prof):
        col = plots.plt.cm.viridis(i / max(len(prof) - 1, 1))
        ax.plot(analytic.couette_startup(y, t, params["gap"], params["U"], nu) / params["U"],
                y / params["gap"], "-", color=col, label=f"t nu/H^2 = {t * nu / params['gap'] ** 2:.2f}")
        ax.plot(u / params["U"], yp / params["gap"], ".", color=col, ms=3)
    ax.set_xlabel("u / U")
    ax.set_ylabel("y / H")
    err = max(r["max_error"] for r in rows) if rows else float("nan")
    ax.set_title(f"plane Couette startup ({params['cells']} cells): max error {err:.2e} U")
    ax.legend(title="lines exact, dots MPM", fontsize=8)
    return [plots.save(fig, out / "couette.png")]
