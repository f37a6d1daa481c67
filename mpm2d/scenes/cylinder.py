"""Axisymmetric check: radial vibration of a solid elastic cylinder (exact Bessel mode).

Equations (axisymmetric, (r, z), plane strain along z: one cell layer periodic in z)::

    rho dv_r/dt = d sigma_rr/dr + (sigma_rr - sigma_thth)/r,
    d sigma/dt = lambda tr(D) 1 + 2 G D,  D_rr = dv_r/dr, D_thth = v_r/r

i.e. (K + 4G/3)(u'' + u'/r - u/r^2) = rho u_tt. With the outer surface r = R held (u_r = 0)
and the axis r = 0 a symmetry boundary, mode 1 is v_r = v0 J1(k r) cos(omega t), k = j_{1,1}/R
(j_{1,1} = 3.8317), omega = k c, c = sqrt((K + 4G/3)/rho). It exercises exactly what the
axisymmetric scenes need: per-radian volumes r A, the hoop force -sigma_thth N/r, L_thth = v_r/r
and the axis. The modal amplitude a(t) = sum m v_r J1(k r) / sum m J1(k r)^2 is compared with
v0 cos(omega (t - dt/2)) (velocities live at half steps).

Parameters: radius R [m], cells (along R), ppc, E [Pa], nu, rho [kg/m^3], v0 [m/s], periods,
transfer, cfl.

Run: ``mpm2d run cylinder --set cells=32 --out cylinder``
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from runkit.io import atomic_write_csv
from runkit.limits import le

from .. import analytic, plots
from ..bodies import box
from ..grid import Grid
from ..materials import LinearElastic
from ..particles import ParticleSet
from . import spec
from ..run import Scene
from ..simulation import Simulation


def _steps(p) -> tuple:
    """(first step [s], end time [s], fewest steps) from the parameters: the wave limit of
    K + 4G/3 on rho (or the advection of v0, where larger); ``periods`` periods 2 pi/omega of
    the J1 mode."""
    mat = LinearElastic(p["rho"], E=p["E"], nu=p["nu"])
    _, omega = analytic.cylinder_mode1(p["radius"], np.sqrt(mat.wave_modulus() / p["rho"]))
    return (spec.first_step(p["cfl"], p["radius"] / p["cells"], [(mat, p["rho"])], p["v0"]),
            p["periods"] * 2 * np.pi / omega, 1)


@spec.parameters_of(
    radius=spec.length("cylinder radius R"),
    cells=spec.cells("cells along R"),
    ppc=spec.ppc(),
    E=spec.modulus("Young's modulus"),
    nu=spec.poisson(),
    rho=spec.density(),
    v0=spec.speed("J1-mode velocity amplitude",
                  below=le(lambda p: 0.01 * (p["E"] / p["rho"]) ** 0.5,
                           "small strain: v0 <= 0.01 sqrt(E/rho)")),
    periods=spec.runs_for("run length in periods", 1000.0, "1000 periods: the frequency needs "
                          "a few; the scheme's phase error grows with each"),
    transfer=spec.transfer(), cfl=spec.cfl(),
    size=lambda p: (2 * p["cells"] * p["ppc"] ** 2, (p["cells"] + 5) * 7),
    steps=lambda p: _steps(p))
def setup(radius=1.0, cells=32, ppc=2, E=1.0e6, nu=0.25, rho=1000.0, v0=1.0e-3, periods=2.0,
          transfer="apic", cfl=0.5):
    params = dict(locals())                   # every parameter, as checked
    h = radius / cells
    grid = Grid(cells, 2, h, axisymmetric=True,
                boundaries=dict(xmin="axis", xmax="slip", ymin="periodic", ymax="periodic"))
    mat = LinearElastic(rho, E=E, nu=nu)
    k, omega = analytic.cylinder_mode1(radius, np.sqrt(mat.wave_modulus() / rho))
    x, area = box((0.0, 0.0), (radius, 2 * h), h / ppc)
    v = np.zeros_like(x)
    v[:, 0] = v0 * analytic.bessel_j1(k * x[:, 0])
    cyl = ParticleSet("cylinder", mat, x, area, v=v, axisymmetric=True)
    sim = Simulation(grid, [cyl], transfer=transfer, cfl=cfl, name="cylinder")

    def record(sim):
        s = sim.sets[0]
        J = analytic.bessel_j1(k * s.x[:, 0])
        t_half = sim.t - 0.5 * sim.last_dt
        return {"t_velocity_s": t_half,
                "amplitude_m_per_s": float(np.sum(s.m * s.v[:, 0] * J) / np.sum(s.m * J * J)),
                "amplitude_exact_m_per_s": float(v0 * np.cos(omega * t_half))}

    return Scene(sim, periods * 2 * np.pi / omega, params, frames=8, history_rows=100000,
                 record=record, report=lambda sim, hist, out: report(hist, params, out))


def analyse(history: pd.DataFrame, params: dict) -> dict:
    """Fitted modal amplitude and frequency against the exact Bessel mode."""
    h = history.iloc[1:]
    mat = LinearElastic(params["rho"], E=params["E"], nu=params["nu"])
    _, omega0 = analytic.cylinder_mode1(params["radius"], np.sqrt(mat.wave_modulus() / params["rho"]))
    amp, omega, _ = analytic.fit_oscillation(h["t_velocity_s"], h["amplitude_m_per_s"], omega0)
    v0 = params["v0"]
    return {"cells": params["cells"], "h_m": params["radius"] / params["cells"],
            "omega_exact_rad_per_s": omega0, "omega_rad_per_s": omega,
            "frequency_error": abs(omega - omega0) / omega0, "amplitude_m_per_s": amp,
            "amplitude_error": abs(amp - v0) / v0,
            "max_error": float(np.max(np.abs(h["amplitude_m_per_s"]
                                             - h["amplitude_exact_m_per_s"])) / v0)}


def report(history, params, out):
    res = analyse(history, params)
    atomic_write_csv(out / "cylinder_result.csv", pd.DataFrame([res]))
    fig, ax = plots.plt.subplots(figsize=(7, 4))
    h = history.iloc[1:]
    ax.plot(h["t_velocity_s"], h["amplitude_exact_m_per_s"], "k-", lw=2, label="exact J1 mode")
    ax.plot(h["t_velocity_s"], h["amplitude_m_per_s"], "r--", label=f"MPM, {params['cells']} cells")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("modal amplitude of v_r [m/s]")
    ax.set_title(f"axisymmetric cylinder: frequency error {res['frequency_error']:.2e}, "
                 f"amplitude error {res['amplitude_error']:.2e}")
    ax.legend()
    return [plots.save(fig, out / "cylinder.png")]
