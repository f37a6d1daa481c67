"""A rigid piston at prescribed velocity drives a compression wave into an elastic bar.

Equations: plane-strain linear elasticity with nu = 0 in one periodic cell layer (uniaxial
strain, c = sqrt(E/rho)). The bar 0 <= x <= L is at rest; a rigid body (the piston, body points
in -w <= x <= 0) moves at the prescribed velocity V from t = 0 (rigid body with every degree of
freedom prescribed; it pushes the bar through frictionless contact, mpm2d.contact).
Exact (d'Alembert): behind the front x = c t the bar moves at V with stress
sigma_xx = -rho c V; the force on the piston is rho c V times the bar's height (per unit
thickness). The run stops before the front reaches the free end (t_end <
L/c).

Parameters: length L [m], cells (along L), ppc, E [Pa], rho [kg/m^3], V [m/s], t_end_fraction
(t_end as a fraction of L/c), cfl.

Run: ``mpm2d run piston --out piston``
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from runkit.io import atomic_write_csv
from runkit.limits import le

from .. import plots
from ..bodies import RigidBody, box
from ..grid import Grid
from ..materials import LinearElastic
from ..particles import ParticleSet
from . import spec
from ..run import Scene
from ..simulation import Simulation


def _steps(p) -> tuple:
    """(first step [s], end time [s], fewest steps) from the parameters: the wave limit of the
    bar (E on rho, nu = 0) or the advection of the piston at V; ``t_end_fraction`` times
    L/c, c = sqrt(E/rho)."""
    bar = LinearElastic(p["rho"], E=p["E"], nu=0.0)
    return (spec.first_step(p["cfl"], p["length"] / p["cells"], [(bar, p["rho"])], p["V"]),
            p["t_end_fraction"] * p["length"] / np.sqrt(p["E"] / p["rho"]), 1)


@spec.parameters_of(
    length=spec.length("bar length L"),
    cells=spec.cells("cells along L"),
    ppc=spec.ppc(),
    E=spec.modulus("Young's modulus of the bar"),
    rho=spec.density("density of bar and piston"),
    V=spec.speed("piston velocity", below=le(lambda p: 0.01 * (p["E"] / p["rho"]) ** 0.5,
                                             "small strain: V <= 0.01 c, c = sqrt(E/rho)")),
    t_end_fraction=spec.runs_for("end time as a fraction of L/c (before the reflection)", 1.0,
                                 "the wave reaches the far end at L/c: after it, the reflection "
                                 "is not the impact stress rho c V"),
    cfl=spec.cfl(),
    size=lambda p: (2 * (p["cells"] + 4) * p["ppc"] ** 2, (p["cells"] + 15) * 7),
    steps=lambda p: _steps(p))
def setup(length=1.0, cells=64, ppc=2, E=1.0e6, rho=1000.0, V=0.01, t_end_fraction=0.6, cfl=0.5):
    params = dict(locals())                   # every parameter, as checked
    h = length / cells
    c = np.sqrt(E / rho)
    w = 4 * h
    grid = Grid(cells + 10, 2, h, origin=(-6 * h, 0.0),
                boundaries=dict(xmin="free", xmax="free", ymin="periodic", ymax="periodic"))
    x, area = box((0.0, 0.0), (length, 2 * h), h / ppc)
    bar = ParticleSet("bar", LinearElastic(rho, E=E, nu=0.0), x, area)
    xb, ab = box((-w, 0.0), (0.0, 2 * h), h / ppc)
    piston = RigidBody("piston", xb, ab, density=rho, velocity=(V, 0.0), prescribed="all")
    sim = Simulation(grid, [bar], [piston], cfl=cfl, name="piston")

    def record(sim):
        b = sim.sets[0]
        front = sim.t * c
        behind = (b.x[:, 0] > sim.bodies[0].center[0] + 0.5 * w + 2 * h) & (b.x[:, 0] < front - 4 * h)
        sig = float(np.mean(b.stress[behind, 0, 0])) if behind.any() else np.nan
        vel = float(np.mean(b.v[behind, 0])) if behind.any() else np.nan
        return {"stress_behind_front_Pa": sig, "velocity_behind_front_m_per_s": vel,
                "piston_force_N_per_m": float(-sim.bodies[0].force[0]),
                "piston_x_m": float(sim.bodies[0].center[0])}

    return Scene(sim, t_end_fraction * length / c, params, frames=8, history_rows=400,
                 record=record, report=lambda sim, hist, out: report(sim, hist, out, params),
                 undefined=("stress_behind_front_Pa", "velocity_behind_front_m_per_s"))


def analyse(history, params) -> dict:
    """Mean stress, velocity and piston force over the second half of the run vs exact."""
    c = np.sqrt(params["E"] / params["rho"])
    s_ex = -params["rho"] * c * params["V"]
    height = 2 * params["length"] / params["cells"]
    late = history[history["time_s"] > 0.5 * history["time_s"].iloc[-1]]
    return {"stress_exact_Pa": s_ex,
            "stress_Pa": float(late["stress_behind_front_Pa"].mean()),
            "stress_error": float(abs(late["stress_behind_front_Pa"].mean() - s_ex) / abs(s_ex)),
            "velocity_error": float(abs(late["velocity_behind_front_m_per_s"].mean()
                                        - params["V"]) / params["V"]),
            "force_exact_N_per_m": -s_ex * height,
            "force_N_per_m": float(late["piston_force_N_per_m"].mean()),
            "force_error": float(abs(late["piston_force_N_per_m"].mean() + s_ex * height)
                                 / abs(s_ex * height))}


def report(sim, history, out, params):
    res = analyse(history, params)
    # undefined (empty) for a run too short for the front to leave material behind it
    atomic_write_csv(out / "piston_result.csv", pd.DataFrame([res]),
                     empty_ok=("stress_Pa", "stress_error", "velocity_error"))
    fig, (a1, a2) = plots.plt.subplots(1, 2, figsize=(12, 4))
    b = sim.sets[0]
    o = np.argsort(b.x[:, 0])
    a1.plot(b.x[o, 0], b.stress[o, 0, 0], "r.", ms=3, label="MPM points")
    c = np.sqrt(params["E"] / params["rho"])
    front = sim.t * c
    xs = np.linspace(0, params["length"], 400)
    a1.plot(xs, np.where(xs < front, res["stress_exact_Pa"], 0.0), "k-", label="exact")
    a1.set_xlabel("x [m]")
    a1.set_ylabel("sigma_xx [Pa]")
    a1.legend()
    a1.set_title(f"t = {sim.t:.3g} s: stress error {100 * res['stress_error']:.2f}%")
    a2.plot(history["time_s"], history["piston_force_N_per_m"], "r-", lw=1, label="MPM")
    a2.axhline(res["force_exact_N_per_m"], color="k", label="exact rho c V height")
    a2.set_xlabel("t [s]")
    a2.set_ylabel("force on the piston [N/m]")
    a2.legend()
    a2.set_title(f"mean force error {100 * res['force_error']:.1f}% (second half)")
    return [plots.save(fig, out / "piston.png")]
