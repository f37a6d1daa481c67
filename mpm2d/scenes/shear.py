"""Homogeneous simple shear of the Table 8 suspension law (locked mixture) against one point.

Equations: the locked mixture (one velocity field), granular stress from the Table 8 local update
(rheology.local_update.update_point), fluid stress -p_f 1 + eta0 (1 + 5/2 phi)(L + L^T), undrained
pore pressure p_f = kappa ln(rho_f/rho_0f)::

    rho dv/dt = div(sigma~ - p_f 1 + tau_f)

A box periodic in x between noslip walls y = 0 (fixed) and y = H (moving at U = gdot H) starts
with the homogeneous velocity v = gdot y e_x, a uniform granular stress -p0 1 and structure f0.
A uniform stress has no divergence and the mirror walls carry the linear field exactly, so the
flow stays homogeneous: every point must follow the single material point driven by
L = gdot e_x e_y^T at constant volume ("volume" control) with the same steps, i.e. the
rheometer's material-point mode. The report compares the box averages of the granular shear
stress, granular pressure and f with that point (rheology.local_update in a loop).

Parameters: material (rheology parameter set), phi, rate gdot [1/s], p0 [Pa] (initial granular
pressure: a point sheared from exactly zero pressure stays separated), f0, height [m], cells
(over the height), ppc, t_end [s], dt [s] (fixed step; default 0.9 x the stable step), cfl.
``material`` is any SI parameter set or a material file (``fit/material.json`` from ``rheometer
fit``): its steady-flow parameters are used, and the moduli, densities, d and K0 it leaves unset
come from Table 4 (``annular_shear``).

Run: ``mpm2d run shear --set rate=50 --out shear`` (mode: locked mixture)
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from rheology.materials import scene_material
from rheology.local_update import NOUT, kernel_parameters, update_points
from runkit.io import atomic_write_csv
from runkit.limits import SPEED_MAX, le

from .. import plots
from ..bodies import box
from ..grid import Grid
from ..materials import Suspension
from ..particles import ParticleSet
from . import spec
from ..run import Scene
from ..simulation import Simulation


def _steps(p) -> tuple:
    """(first step [s], end time [s], fewest steps) from the parameters: 0.9 x the stable step
    of the locked mixture (its wave, the advection of the top points at gdot y, its viscous
    limit), or the fixed dt below it (one above it is refused by the first step)."""
    m = scene_material("annular_shear", p["material"], rules=p["rules"])
    h = p["height"] / p["cells"]
    stable = spec.first_step(p["cfl"], h, [(Suspension(m, locked=True), p["phi"] * m.rho_s
                                            + (1.0 - p["phi"]) * m.rho_f)],
                             p["rate"] * (p["height"] - 0.5 * h / p["ppc"]))
    return 0.9 * stable if p["dt"] is None else min(stable, p["dt"]), p["t_end"], 1


@spec.parameters_of(
    material=spec.scene_material_param("annular_shear"),
    phi=spec.phi_below_jamming(doc="solid volume fraction"),
    rate=spec.rate("shear rate gdot", below=le(lambda p: SPEED_MAX.value / p["height"],
                                               "the wall speed gdot H at most "
                                               f"{SPEED_MAX.value:g} m/s: {SPEED_MAX.why}")),
    p0=spec.stress("initial granular pressure (0: none)", zero=True),
    f0=spec.fraction("initial structure f", "no structure", "fully formed structure"),
    height=spec.length("box height"),
    cells=spec.count(2, 10000, "cells over the height", spec.CELLS_WHY,
                     "a homogeneous flow needs no finer grid (the step shrinks with the cell)"),
    ppc=spec.ppc(),
    t_end=spec.duration("end time"),
    dt=spec.duration("fixed step (none: 0.9 x the stable step)", optional=True,
                     below=le(lambda p: p["t_end"], "at most t_end: one step or more")),
    rules=spec.rules(),
    cfl=spec.cfl(),
    size=lambda p: (2 * p["cells"] * p["ppc"] ** 2, (p["cells"] + 5) * 7),
    steps=lambda p: _steps(p))
def setup(material="annular_shear", phi=0.40, rate=50.0, p0=1.0, f0=0.0, height=0.004, cells=4,
          ppc=2, t_end=0.5, dt=None, rules="table8", cfl=0.5):
    params = dict(locals())                   # every parameter, as checked
    m = scene_material("annular_shear", material, rules=rules)
    h = height / cells
    U = rate * height
    grid = Grid(2, cells, h, boundaries=dict(xmin="periodic", xmax="periodic", ymin="noslip",
                                            ymax="noslip"), wall_velocity={"ymax": (U, 0.0)})
    x, area = box((0.0, 0.0), (2 * h, height), h / ppc)
    v = np.zeros_like(x)
    v[:, 0] = rate * x[:, 1]
    pts = ParticleSet("suspension", Suspension(m, locked=True), x, area, v=v, phi=phi,
                      stress=-p0 * np.eye(3), f=f0)
    pts.C[:, 0, 1] = rate                       # the affine part of the homogeneous field
    sim = Simulation(grid, [pts], cfl=cfl, name="shear")
    if dt is None:                              # a fixed step, so the point can repeat it
        dt = 0.9 * sim.stable_dt()
    sim = Simulation(grid, [pts], cfl=cfl, dt=dt, name="shear")
    params["dt"] = dt

    def record(sim):
        s = sim.sets[0]
        w = s.V / s.V.sum()
        sig = np.einsum("n,nij->ij", w, s.stress)
        return {"granular_shear_stress_Pa": sig[0, 1],
                "granular_pressure_Pa": -np.trace(sig) / 3.0,
                "f": float(np.sum(w * s.f)),
                "shear_stress_Pa": sig[0, 1] + m.eta0 * (1 + 2.5 * phi) * rate,
                "pore_pressure_Pa": float(np.sum(w * s.pf)),
                "spread_shear_stress_Pa": float(np.ptp(s.stress[:, 0, 1])),
                "spread_f": float(np.ptp(s.f))}

    return Scene(sim, t_end, params, frames=5, history_rows=500, record=record,
                 report=lambda sim, hist, out: report(hist, out, params),
                 notes="mode locked mixture: grains and fluid share one velocity")


def point_history(params: dict, times) -> pd.DataFrame:
    """The single material point driven by L = gdot e_x e_y^T with the MPM's fixed step.

    The point takes the same steps (dt = params["dt"]) through rheology.local_update's kernel
    and is sampled at ``times`` (the MPM's history times, multiples of dt).
    """
    m = scene_material("annular_shear", params["material"])
    P = kernel_parameters(m)
    dt = params["dt"]
    L = np.zeros((1, 3, 3))
    L[0, 0, 1] = params["rate"]
    sig = -params["p0"] * np.eye(3)[None]
    f = np.array([params["f0"]])
    phi = np.array([params["phi"]])
    out = np.empty((1, NOUT))
    steps = np.rint(np.asarray(times) / dt).astype(int)
    rows, k = [], 0
    for n in range(steps.max() + 1):
        while k < steps.size and steps[k] == n:
            rows.append((n * dt, sig[0, 0, 1], -np.trace(sig[0]) / 3.0, f[0]))
            k += 1
        new = np.empty_like(sig)
        update_points(sig, L, phi, f, dt, P, new, out)
        sig, f = new, out[:, 0].copy()
    return pd.DataFrame(rows, columns=["time_s", "granular_shear_stress_Pa",
                                       "granular_pressure_Pa", "f"])


def analyse(history: pd.DataFrame, point: pd.DataFrame) -> dict:
    """Largest differences MPM - point, relative to the largest point value of each quantity."""
    out = {}
    for col in ("granular_shear_stress_Pa", "granular_pressure_Pa", "f"):
        scale = max(np.max(np.abs(point[col])), 1e-300)
        out[f"{col}_rel_diff"] = float(np.max(np.abs(history[col].to_numpy()
                                                     - point[col].to_numpy())) / scale)
    out["max_spread_shear_stress_Pa"] = float(history["spread_shear_stress_Pa"].max())
    return out


COLUMNS = {"granular_shear_stress_Pa": "granular shear stress sigma_xy [Pa]",
           "granular_pressure_Pa": "granular pressure [Pa]", "f": "structure f [-]"}


def comparison_figure(history, point, columns, diffs, title, path):
    """MPM box averages against the material point: one panel per quantity.

    ``columns`` maps the history's column names to the point frame's."""
    fig, axs = plots.plt.subplots(1, 3, figsize=(14, 4))
    for ax, (col, pcol) in zip(axs, columns.items()):
        ax.plot(point["time_s"], point[pcol], "k-", lw=2, label="material point")
        ax.plot(history["time_s"], history[col], "r--", label="MPM box average")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(COLUMNS[col])
        ax.set_title(f"max rel. difference {diffs[col]:.1e}")
    axs[0].legend()
    fig.suptitle(title, fontsize=9)
    return plots.save(fig, path)


def report(history, out, params):
    point = point_history(params, history["time_s"].to_numpy())
    res = analyse(history, point)
    atomic_write_csv(out / "shear_result.csv", pd.DataFrame([res]))
    atomic_write_csv(out / "shear_point.csv", point)
    diffs = {c: res[f"{c}_rel_diff"] for c in COLUMNS}
    return [comparison_figure(history, point, {c: c for c in COLUMNS}, diffs,
                              f"homogeneous simple shear, {params['material']}, phi = "
                              f"{params['phi']}, rate {params['rate']} 1/s (locked mixture)",
                              out / "shear.png")]
