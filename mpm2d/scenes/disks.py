"""Collision of two elastic disks (Sulsky, Chen & Schreyer 1994): energy histories.

Equations: plane-strain linear elasticity (Jaumann rate), rho dv/dt = div sigma. Two disks of
radius R in the unit square (frictionless walls) move towards each other with speeds
+-(v0, v0), collide near the centre, rebound and separate. A single velocity field makes the
contact sticky on first touch, so some kinetic energy is lost in the impact layer (O(h)).

What the transfer conserves (printed in the report): APIC and the explicit grid update conserve
linear and angular momentum exactly (round-off); no MPM transfer conserves energy: PIC removes
every sub-cell velocity variation each step (large loss), APIC keeps the affine part (loss
that vanishes under refinement), FLIP keeps the particle velocities and loses less energy but
accumulates noise in the grid's null space (``null_space_J``: the kinetic energy of the part of
the particle velocities the grid cannot see, the source of ringing); PIC and APIC have none.

Parameters: cells (per side of the unit square), ppc, E [Pa], nu, rho [kg/m^3], radius [m],
speed v0 [m/s], offset [m] (impact parameter: an oblique collision that sets the disks
spinning, so the angular momentum is not zero by symmetry), walls (slip, or free: no external
force, so the total angular momentum is a conserved quantity; the disks stay inside the grid
until t = 3 s), t_end [s], transfer (apic, flip, pic), flip_alpha, cfl.

Run: ``mpm2d run disks --out disks`` (``--set transfer=flip`` to compare)
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd

from runkit.io import atomic_write_csv
from runkit.limits import ge, le

from .. import plots
from ..bodies import disk
from ..grid import Grid
from ..materials import LinearElastic
from ..particles import ParticleSet
from . import spec
from ..run import Scene
from ..simulation import Simulation
from ..transfer import g2p


@spec.parameters_of(
    cells=spec.cells("cells per side of the unit square", 4, 4096,
                     "4 cells: a disk of a quarter of the square spans at least one cell",
                     "4096^2 cells: 1.7e7 nodes and 2e7 points, the memory of a workstation"),
    ppc=spec.ppc(),
    E=spec.modulus("Young's modulus"),
    nu=spec.poisson(),
    rho=spec.density(),
    radius=spec.length("disk radius (the disks start apart)",
                       hi=le(0.25, "the disks, centred 0.25 m from the walls, inside the unit "
                                   "square"),
                       above=ge(lambda p: 1.0 / p["cells"], "at least one cell")),
    speed=spec.speed("speed v0 of each velocity component",
                     below=le(lambda p: 0.1 * (p["E"] / p["rho"]) ** 0.5,
                              "v0 <= 0.1 c, c = sqrt(E/rho): an elastic impact")),
    offset=spec.Param(-0.2, 0.2, unit="m", doc="impact parameter (oblique collision)",
                      lo_why="the default radius: the disks at most graze",
                      hi_why="the default radius: the disks at most graze"),
    walls=spec.Param(choices=("slip", "free"), doc="frictionless walls, or none"),
    t_end=spec.duration("end time"),
    transfer=spec.transfer(), flip_alpha=spec.flip_alpha(), cfl=spec.cfl(),
    size=lambda p: (2 * 3.1416 * p["radius"] ** 2 * (p["cells"] * p["ppc"]) ** 2,
                    (p["cells"] + 5) ** 2),
    steps=lambda p: (spec.first_step(p["cfl"], 1.0 / p["cells"],
                                     [(LinearElastic(p["rho"], E=p["E"], nu=p["nu"]), p["rho"])],
                                     np.sqrt(2.0) * p["speed"]), p["t_end"], 1))
def setup(cells=32, ppc=2, E=1000.0, nu=0.3, rho=1000.0, radius=0.2, speed=0.1, offset=0.0,
          walls="slip", t_end=3.0, transfer="apic", flip_alpha=0.99, cfl=0.5):
    params = dict(locals())                   # every parameter, as checked
    h = 1.0 / cells
    grid = Grid(cells, cells, h, boundaries=dict(xmin=walls, xmax=walls, ymin=walls,
                                                ymax=walls))
    mat = LinearElastic(rho, E=E, nu=nu)
    sets = []
    s = 0.5 * offset / np.sqrt(2.0)               # impact parameter across the diagonal
    for name, c, v in (("disk_a", (0.25 - s, 0.25 + s), (speed, speed)),
                       ("disk_b", (0.75 + s, 0.75 - s), (-speed, -speed))):
        x, area = disk(c, radius, h / ppc, lower=(0.0, 0.0), upper=(1.0, 1.0))
        sets.append(ParticleSet(name, mat, x, area, v=np.tile(v, (len(x), 1))))
    sim = Simulation(grid, sets, transfer=transfer, flip_alpha=flip_alpha, cfl=cfl, name="disks")

    def record(sim):
        return {"angular_momentum_kg_m2_per_s": sim.angular_momentum(),
                "null_space_J": null_space_energy(sim)}

    # the report's energy loss and gains are relative to the initial energy, positive for
    # speed >= runkit.limits.SPEED_MIN
    return Scene(sim, t_end, params, frames=12, history_rows=300, record=record,
                 report=lambda sim, hist, out: report(sim, hist, out))


def null_space_energy(sim) -> float:
    """Kinetic energy of the particle velocities' part the grid does not represent [J].

    sum_p 1/2 m_p |v_p - sum_i N_ip v_i|^2 with v_i the grid velocity a fresh P2G of the
    current state gives; zero for PIC and APIC by construction, the ringing mode of FLIP.
    """
    if sim.transfer == "apic" or sim.flip_alpha == 0.0:
        return 0.0
    probe = copy.deepcopy(sim)
    probe._p2g()
    probe._grid_update(0.0)
    e = 0.0
    for s in probe.sets:
        v = s.v.copy()
        x = s.x.copy()
        g2p[probe.par](x, v, s.C.copy(), s.L.copy(), probe.vg["solid"], probe.vg_old["solid"],
                       probe._geo, probe.grid.axisymmetric, False, 0.0, 0.0, probe.grid.kind,
                       probe._flag)
        e += 0.5 * float(np.sum(s.m[:, None] * (s.v - v) ** 2))
    return e


def report(sim, history, out):
    e0 = history["total_J"].iloc[0]
    L0 = history["angular_momentum_kg_m2_per_s"].iloc[0]
    p0 = history[["momentum_x_kg_m_per_s", "momentum_y_kg_m_per_s"]].iloc[0].to_numpy()
    pscale = float(np.sum([np.sum(s.m) for s in sim.sets])) * abs(sim.sets[0].v).max() + 1e-300
    res = {"transfer": sim.transfer, "cells": sim.grid.nx,
           "energy_loss": 1.0 - history["total_J"].iloc[-1] / e0,
           "max_energy_gain": history["total_J"].max() / e0 - 1.0,
           "angular_momentum_drift": float(np.abs(history["angular_momentum_kg_m2_per_s"] - L0).max()),
           "angular_momentum_scale": float(pscale),
           "momentum_drift_rel": float(np.abs(history[["momentum_x_kg_m_per_s",
                                                       "momentum_y_kg_m_per_s"]].to_numpy() - p0).max()
                                       / pscale),
           "max_null_space_fraction": float(history["null_space_J"].max() / e0)}
    atomic_write_csv(out / "disks_result.csv", pd.DataFrame([res]))
    fig, (a1, a2) = plots.plt.subplots(1, 2, figsize=(12, 4.5))
    t = history["time_s"]
    a1.plot(t, history["kinetic_J"] / e0, label="kinetic")
    a1.plot(t, history["strain_J"] / e0, label="strain")
    a1.plot(t, history["total_J"] / e0, "k", lw=2, label="total")
    if res["max_null_space_fraction"] > 0:
        a1.plot(t, history["null_space_J"] / e0, ":", label="null space (FLIP noise)")
    a1.set_xlabel("t [s]")
    a1.set_ylabel("energy / initial energy")
    a1.set_title(f"{sim.transfer}: energy loss {100 * res['energy_loss']:.1f}%, "
                 f"|dL| {res['angular_momentum_drift']:.1e}")
    a1.legend()
    sc = plots.particles(a2, sim, "speed")
    fig.colorbar(sc, ax=a2, label="|v| [m/s]")
    a2.set_title(f"t = {sim.t:.3g} s")
    return [plots.save(fig, out / "disks.png")]
