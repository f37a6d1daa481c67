"""Axial vibration of an elastic bar: the frequency and amplitude verification.

Equations (plane strain, one cell layer periodic in y, so the strain is uniaxial)::

    rho dv/dt = d sigma_xx/dx,  d sigma_xx/dt = (K + 4G/3) dv/dx,   nu = 0: K + 4G/3 = E

Bar 0 <= x <= L fixed at x = 0 (noslip wall), free at x = L, started in mode 1 at zero stress:
v(x, 0) = v0 sin(pi x/(2L)). Exact: v = v0 sin(pi x/2L) cos(omega t), omega = pi c/(2L),
c = sqrt(E/rho); the centre-of-mass velocity is v0 (2/pi) cos(omega t).

The explicit step is symplectic Euler with the stress updated last, so the particle velocity after
step n lives at t_n - dt/2; it is compared with the exact solution there. Small v0 keeps the
strain (v0/c = 3e-5 by default) in the linear range of the analytic solution.

Parameters: length L [m], cells (along L), ppc (points per cell and direction), E [Pa],
rho [kg/m^3], v0 [m/s], periods (run length in periods), transfer (apic, flip, pic),
flip_alpha, cfl, dt [s] (None: adaptive).

Run: ``mpm2d run bar --set cells=64 --out bar``
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from runkit.io import atomic_write_csv
from runkit.limits import ge, le

from .. import analytic, plots
from ..bodies import box
from ..grid import Grid
from ..materials import LinearElastic
from ..particles import ParticleSet
from . import spec
from ..run import Scene
from ..simulation import Simulation


#: the fewest steps (history samples) a run takes: the oscillation fit (analyse) has 3
#: unknowns (amplitude, phase, frequency), so at least 3 samples
MIN_SAMPLES = 3


def _steps(p) -> tuple:
    """(first step [s], end time [s], fewest steps) from the parameters: the wave limit with
    c = sqrt(E/rho) (nu = 0; or the advection of v0, where smaller), or the fixed dt below it
    (one above it is the set-up's refusal, the stability limit); ``periods`` periods
    2 pi/omega of mode 1."""
    c = math.sqrt(p["E"] / p["rho"])
    dt = spec.first_step(p["cfl"], p["length"] / p["cells"],
                         [(LinearElastic(p["rho"], E=p["E"], nu=0.0), p["rho"])], p["v0"])
    dt = dt if p["dt"] is None else min(dt, p["dt"])
    return dt, p["periods"] * 2 * np.pi / analytic.bar_mode1(0.0, p["v0"], p["length"], c)[1], \
        MIN_SAMPLES


@spec.parameters_of(
    length=spec.length("bar length L"),
    cells=spec.cells("cells along L"),
    ppc=spec.ppc(),
    E=spec.modulus("Young's modulus"),
    rho=spec.density(),
    v0=spec.speed("mode-1 velocity amplitude",
                  above=ge(lambda p: 1e-9 * (p["E"] / p["rho"]) ** 0.5,
                           "strain amplitude v0/c >= 1e-9, c = sqrt(E/rho): a smaller motion is "
                           "lost in the rounding of the positions"),
                  below=le(lambda p: 0.01 * (p["E"] / p["rho"]) ** 0.5,
                           "strain amplitude v0/c <= 0.01, c = sqrt(E/rho): a larger one is not "
                           "linear")),
    periods=spec.runs_for("run length in periods", 1000.0, "1000 periods: the fit of amplitude "
                          "and frequency needs a few; the scheme's phase error grows with each"),
    transfer=spec.transfer(), flip_alpha=spec.flip_alpha(), cfl=spec.cfl(),
    dt=spec.duration("fixed step (none: adaptive)", optional=True),
    size=lambda p: (2 * p["cells"] * p["ppc"] ** 2, (p["cells"] + 8) * 7),
    steps=lambda p: _steps(p))
def setup(length=1.0, cells=32, ppc=2, E=1.0e6, rho=1000.0, v0=1.0e-3, periods=2.0,
          transfer="apic", flip_alpha=0.99, cfl=0.5, dt=None):
    params = dict(locals())                   # every parameter, as checked
    h = length / cells
    grid = Grid(cells + 3, 2, h, boundaries=dict(xmin="noslip", xmax="free", ymin="periodic",
                                                ymax="periodic"))
    x, area = box((0.0, 0.0), (length, 2 * h), h / ppc)
    v = np.zeros_like(x)
    v[:, 0] = v0 * np.sin(np.pi * x[:, 0] / (2.0 * length))
    bar = ParticleSet("bar", LinearElastic(rho, E=E, nu=0.0), x, area, v=v)
    sim = Simulation(grid, [bar], transfer=transfer, flip_alpha=flip_alpha, cfl=cfl, dt=dt,
                     name="bar")
    c = np.sqrt(E / rho)
    _, omega = analytic.bar_mode1(0.0, v0, length, c)

    def record(sim):
        s = sim.sets[0]
        t_half = sim.t - 0.5 * sim.last_dt
        vc = float(np.sum(s.m * s.v[:, 0]) / np.sum(s.m))
        return {"v_cm_m_per_s": vc, "t_velocity_s": t_half,
                "v_cm_exact_m_per_s": float(analytic.bar_mode1(t_half, v0, length, c)[0])}

    # the fit of amplitude, frequency and phase (analyse) needs samples beyond its 3 unknowns:
    # a run of fewer than MIN_SAMPLES steps (one history row per step) is refused
    return Scene(sim, periods * 2 * np.pi / omega, params, frames=8, history_rows=100000,
                 min_steps=MIN_SAMPLES, record=record, report=lambda sim, hist, out: report(hist, params, out))


def analyse(history: pd.DataFrame, params: dict) -> dict:
    """Fitted amplitude and frequency of the centre-of-mass velocity against the exact mode."""
    h = history.iloc[1:]
    c = np.sqrt(params["E"] / params["rho"])
    amp0 = params["v0"] * 2.0 / np.pi
    _, omega0 = analytic.bar_mode1(0.0, params["v0"], params["length"], c)
    amp, omega, _ = analytic.fit_oscillation(h["t_velocity_s"], h["v_cm_m_per_s"], omega0)
    return {"cells": params["cells"], "h_m": params["length"] / params["cells"],
            "omega_exact_rad_per_s": omega0, "omega_rad_per_s": omega,
            "frequency_error": abs(omega - omega0) / omega0,
            "amplitude_exact_m_per_s": amp0, "amplitude_m_per_s": amp,
            "amplitude_error": abs(amp - amp0) / amp0,
            "max_error": float(np.max(np.abs(h["v_cm_m_per_s"] - h["v_cm_exact_m_per_s"])) / amp0)}


def report(history, params, out):
    res = analyse(history, params)
    atomic_write_csv(out / "bar_result.csv", pd.DataFrame([res]))
    fig, (a1, a2) = plots.plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    h = history.iloc[1:]
    a1.plot(h["t_velocity_s"], h["v_cm_exact_m_per_s"], "k-", lw=2, label="exact (mode 1)")
    a1.plot(h["t_velocity_s"], h["v_cm_m_per_s"], "r--", label=f"MPM, {params['cells']} cells")
    a1.set_ylabel("centre-of-mass velocity [m/s]")
    a1.legend()
    a1.set_title(f"bar: frequency error {res['frequency_error']:.2e}, amplitude error "
                 f"{res['amplitude_error']:.2e}")
    a2.plot(h["t_velocity_s"], (h["v_cm_m_per_s"] - h["v_cm_exact_m_per_s"])
            / res["amplitude_exact_m_per_s"], "b-")
    a2.set_xlabel("t [s]")
    a2.set_ylabel("error / amplitude")
    return [plots.save(fig, out / "bar.png")]
