"""An elastic column settling under its own weight: a worked example of a scene of your own.

A scene is a Python file with a ``setup(**params)`` that declares every parameter with its valid
range (``@spec.parameters_of``) and returns a :class:`mpm2d.run.Scene`; ``mpm2d`` runs it by
path exactly like a built-in scene (validation, progress, snapshots, VTK, checkpoints,
``--resume``, the report)::

    mpm2d show mpm2d/examples/elastic_column.py        # this text and the parameters
    mpm2d run mpm2d/examples/elastic_column.py --set cells=32 --out column_demo

Equations (plane strain, linear elastic solid with the Jaumann rate,
:class:`mpm2d.materials.LinearElastic`): a column of height H between two frictionless walls
(the strain is uniaxial) on a no-slip floor, released at rest and stress free under gravity g.
It oscillates about its static state sigma_yy = -rho g (H - y), whose settlement is
u(y) = rho g (H y - y^2/2)/M with the constrained modulus M = K + 4G/3. Its modes are those of
a bar fixed at its foot and free at its top, omega_n = (2n - 1) pi c/(2H), c = sqrt(M/rho): over
whole periods T = 4H/c of the first one every mode completes whole cycles, so the centre of mass
sinks on average by exactly the static rho g H^2/(3M), and at t = T/2, where every mode is at
its extreme, by twice that.

Parameters: height H [m], cells (along H), E [Pa], nu, rho [kg/m^3], gravity [m/s^2], periods
(run length in periods T), cfl.

Outputs (besides history.csv, frames, manifest): ``column_result.csv`` (static and measured mean
and largest sink of the centre of mass [m], their ratios) and ``column.png``.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from mpm2d import plots
from mpm2d.bodies import box
from mpm2d.grid import Grid
from mpm2d.materials import LinearElastic
from mpm2d.particles import ParticleSet
from mpm2d.run import Scene
from mpm2d.scenes import spec
from mpm2d.simulation import Simulation
from runkit.io import atomic_write_csv


@spec.parameters_of(
    height=spec.length("column height H"),
    cells=spec.cells("cells along H", 4, 4096, "4 cells: the first mode resolved by a few",
                     "4096 cells: the grid's error far below the rounding"),
    E=spec.modulus("Young's modulus"),
    nu=spec.poisson(),
    rho=spec.density(),
    gravity=spec.gravity("gravity (downwards)"),
    periods=spec.count(1, 100, "run length in periods T = 4H/c of the first mode",
                       "one period: the mean and maximum of the oscillation",
                       "100 periods: the scheme's phase error grows with each"),
    cfl=spec.cfl(),
    size=lambda p: (4 * 2 * p["cells"], 12 * (p["cells"] + 10)))
def setup(height=1.0, cells=16, E=1.0e6, nu=0.3, rho=1000.0, gravity=9.81, periods=2,
          cfl=0.5):
    params = dict(locals())                   # every parameter, as checked
    h = height / cells
    grid = Grid(2, cells + 4, h, boundaries=dict(xmin="slip", xmax="slip", ymin="noslip",
                                                 ymax="free"))
    x, area = box((0.0, 0.0), (2 * h, height), h / 2)           # 2 x 2 points per cell
    column = ParticleSet("column", LinearElastic(rho, E=E, nu=nu), x, area)
    sim = Simulation(grid, [column], gravity=(0.0, -gravity), cfl=cfl, name="elastic_column")
    mat = column.material
    M = mat.K + 4.0 * mat.G / 3.0
    c = math.sqrt(M / rho)
    y0 = float(np.mean(x[:, 1]))                                # equal masses: the mean

    def record(sim):
        return {"com_sink_m": y0 - float(np.mean(sim.sets[0].x[:, 1]))}

    info = dict(static=rho * gravity * height ** 2 / (3.0 * M), period=4.0 * height / c)
    return Scene(sim, periods * info["period"], params, frames=4, history_rows=400,
                 record=record, report=lambda sim, hist, out: report(hist, info, out))


def report(history: pd.DataFrame, info: dict, out):
    """The mean and the largest sink of the centre of mass against the exact ones."""
    t, sink = history["time_s"].to_numpy(), history["com_sink_m"].to_numpy()
    mean = float(np.trapezoid(sink, t) / (t[-1] - t[0]))
    res = {"static_sink_m": info["static"], "mean_sink_m": mean,
           "mean_over_static": mean / info["static"], "max_sink_m": float(sink.max()),
           "max_over_static": float(sink.max()) / info["static"], "period_s": info["period"]}
    atomic_write_csv(out / "column_result.csv", pd.DataFrame([res]))
    fig, ax = plots.plt.subplots(figsize=(7, 4.5))
    ax.plot(t / info["period"], sink * 1e3, "b-", label="MPM: sink of the centre of mass")
    ax.axhline(info["static"] * 1e3, color="k", ls="--", label="exact mean: rho g H^2/(3M)")
    ax.axhline(2 * info["static"] * 1e3, color="k", ls=":", label="exact largest: twice that")
    ax.set_xlabel("t / T (T = 4H/c)")
    ax.set_ylabel("sink [mm]")
    ax.set_title(f"elastic column under gravity: mean sink {res['mean_over_static']:.4f} x the "
                 f"static one, largest {res['max_over_static']:.3f} x", fontsize=9)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=2, fontsize=8,
              frameon=False)
    return [plots.save(fig, out / "column.png")]
