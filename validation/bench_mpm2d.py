"""mpm2d speed: material-point steps per second beside a bare P2G + G2P loop in the same run.

(a) single-phase linear elastic block (Jaumann update of rheology.local_update.elastic_trial);
(b) two-phase suspension: granular points with the Table 8 law (rheology.local_update.update_point,
    homogeneous shear so every point takes the plastic shear-flow branch) and as many fluid
    points, implicit drag, buoyancy.

Each is timed with the serial and the parallel (2 threads) kernel builds. The reference is a
bare APIC transfer on the same points and grid: P2G of mass and momentum, nodal velocities,
G2P of velocity and affine matrix and the position update (no stress, boundaries or materials).
Medians over the timed steps; per-phase shares from the simulation's own clocks. The machine is
shared with other jobs: the parallel builds in particular are sensitive to it (a parallel
region waits for both cores).
"""

from __future__ import annotations

import time
from pathlib import Path

import numba as nb
import numpy as np

from mpm2d import Drag, Grid, LinearElastic, NewtonianFluid, ParticleSet, Simulation, Suspension, box
from mpm2d.grid import PAD
from mpm2d.kernels import dual
from mpm2d.shape import APIC_D_INV, weights
from mpm2d.transfer import chunk_bounds
from rheology import get_material

from .framework import BenchResult, benchmark

TARGETS = {"elastic": 20e6, "two-phase suspension": 10e6}


@dual
def _bare_p2g(x, v, C, m, geo, chunks, priv):
    x0, y0, h = geo[0], geo[1], geo[2]
    inv_h = 1.0 / h
    for c in nb.prange(chunks.shape[0] - 1):
        G = priv[c]
        for p in range(chunks[c], chunks[c + 1]):
            bx, fx, wx0, wx1, wx2, _, _, _ = weights((x[p, 0] - x0) * inv_h)
            by, fy, wy0, wy1, wy2, _, _, _ = weights((x[p, 1] - y0) * inv_h)
            wx = (wx0, wx1, wx2)
            wy = (wy0, wy1, wy2)
            mp = m[p]
            for a in range(3):
                rx = (a - fx) * h
                for b in range(3):
                    ry = (b - fy) * h
                    w = wx[a] * wy[b] * mp
                    G[bx + a + PAD, by + b + PAD, 0] += w
                    G[bx + a + PAD, by + b + PAD, 1] += w * (v[p, 0] + C[p, 0, 0] * rx + C[p, 0, 1] * ry)
                    G[bx + a + PAD, by + b + PAD, 2] += w * (v[p, 1] + C[p, 1, 0] * rx + C[p, 1, 1] * ry)


@dual
def _bare_grid(priv, vg):
    for I in nb.prange(vg.shape[0]):
        for J in range(vg.shape[1]):
            m = mx = my = 0.0
            for c in range(priv.shape[0]):
                m += priv[c, I, J, 0]
                mx += priv[c, I, J, 1]
                my += priv[c, I, J, 2]
                priv[c, I, J, 0] = priv[c, I, J, 1] = priv[c, I, J, 2] = 0.0
            vg[I, J, 0] = mx / m if m > 0 else 0.0
            vg[I, J, 1] = my / m if m > 0 else 0.0


@dual
def _bare_g2p(x, v, C, vg, geo, dt):
    x0, y0, h = geo[0], geo[1], geo[2]
    inv_h = 1.0 / h
    dinv = APIC_D_INV * inv_h * inv_h
    for p in nb.prange(x.shape[0]):
        bx, fx, wx0, wx1, wx2, _, _, _ = weights((x[p, 0] - x0) * inv_h)
        by, fy, wy0, wy1, wy2, _, _, _ = weights((x[p, 1] - y0) * inv_h)
        wx = (wx0, wx1, wx2)
        wy = (wy0, wy1, wy2)
        vx = vy = bxx = bxy = byx = byy = 0.0
        for a in range(3):
            rx = (a - fx) * h
            for b in range(3):
                ry = (b - fy) * h
                w = wx[a] * wy[b]
                ux, uy = vg[bx + a + PAD, by + b + PAD, 0], vg[bx + a + PAD, by + b + PAD, 1]
                vx += w * ux
                vy += w * uy
                bxx += w * ux * rx
                bxy += w * ux * ry
                byx += w * uy * rx
                byy += w * uy * ry
        v[p, 0], v[p, 1] = vx, vy
        C[p, 0, 0], C[p, 0, 1], C[p, 1, 0], C[p, 1, 1] = dinv * bxx, dinv * bxy, dinv * byx, dinv * byy
        x[p, 0] += dt * vx
        x[p, 1] += dt * vy


def bare_loop_rate(sim, parallel: bool, steps: int) -> float:
    """Median particle-steps per second of the bare APIC transfer on copies of sim's points."""
    shape = sim.grid.shape
    geo = sim.grid.geometry()
    sets = [(s.x.copy(), s.v.copy(), s.C.copy(), s.m.copy()) for s in sim.sets]
    priv = np.zeros((sim.nc,) + shape + (3,))
    vg = np.zeros(shape + (2,))
    n = sum(len(s[0]) for s in sets)
    dt = 1e-12 * sim.grid.h                     # positions stay put (same cells every step)
    times = []
    for k in range(steps + 2):
        t0 = time.perf_counter()
        for x, v, C, m in sets:
            _bare_p2g[parallel](x, v, C, m, geo, chunk_bounds(len(x), sim.nc), priv)
        _bare_grid[parallel](priv, vg)
        for x, v, C, m in sets:
            _bare_g2p[parallel](x, v, C, vg, geo, dt)
        if k >= 2:
            times.append(time.perf_counter() - t0)
    return n / float(np.median(times))


def elastic_block(cells: int) -> Simulation:
    """(a): a vibrating elastic block filling the unit square (frictionless walls)."""
    h = 1.0 / cells
    grid = Grid(cells, cells, h, boundaries=dict(xmin="slip", xmax="slip", ymin="slip",
                                                ymax="slip"))
    x, area = box((0.0, 0.0), (1.0, 1.0), h / 2)
    v = 1e-3 * np.stack([np.sin(np.pi * x[:, 1]), np.sin(np.pi * x[:, 0])], axis=1)
    ps = ParticleSet("block", LinearElastic(1000.0, E=1e6, nu=0.3), x, area, v=v)
    return Simulation(grid, [ps], name="bench elastic")


def sheared_suspension(cells: int) -> Simulation:
    """(b): two-phase suspension (annular_shear, phi = 0.45) in homogeneous shear at 10 1/s
    between noslip walls (top moving), periodic sideways, gravity on."""
    m = get_material("annular_shear")
    size = 0.05
    h = size / cells
    rate = 10.0
    grid = Grid(cells, cells, h, boundaries=dict(xmin="periodic", xmax="periodic",
                                                ymin="noslip", ymax="noslip"),
                wall_velocity={"ymax": (rate * size, 0.0)})
    x, area = box((0.0, 0.0), (size, size), h / 2)
    v = np.stack([rate * x[:, 1], np.zeros(len(x))], axis=1)
    grains = ParticleSet("grains", Suspension(m), x, area, v=v, phi=0.45,
                         stress=-50.0 * np.eye(3), f=0.0)
    fluid = ParticleSet("fluid", NewtonianFluid.from_material(m), x, area, v=v, phi=0.45)
    for s in (grains, fluid):
        s.C[:, 0, 1] = rate
    return Simulation(grid, [grains, fluid], mode="two-phase", drag=Drag.from_material(m),
                      gravity=(0.0, -9.81), name="bench two-phase")


def time_model(make, cells: int, parallel: bool, steps: int) -> dict:
    sim = make(cells)
    sim.par = sim.par_grid = parallel
    for _ in range(3):                             # compile / warm caches
        sim.step()
    sim.timings = dict.fromkeys(sim.timings, 0.0)
    times = []
    for _ in range(steps):
        t0 = time.perf_counter()
        sim.step()
        times.append(time.perf_counter() - t0)
    n = sum(len(s) for s in sim.sets)
    med = float(np.median(times))
    bare = bare_loop_rate(sim, parallel, steps)
    total = sum(sim.timings.values())
    row = {"model": sim.name.replace("bench ", ""), "build": "parallel" if parallel else "serial",
           "threads": nb.get_num_threads() if parallel else 1, "points": n,
           "grid_nodes": sim.grid.shape[0] * sim.grid.shape[1],
           "ms_per_step": 1e3 * med, "Mpoint_steps_per_s": n / med / 1e6,
           "bare_Mpoint_steps_per_s": bare / 1e6, "ratio_to_bare": (n / med) / bare}
    for k, v in sim.timings.items():
        row[f"share_{k.replace(' ', '_')}"] = v / total
    # each material's constitutive update alone (the rheology kernels), points per second
    dt = sim.last_dt
    for s in sim.sets:
        t_mat = []
        for _ in range(max(3, steps // 4)):
            t0 = time.perf_counter()
            s.material.update(s, dt, sim._chunks[s.name], parallel, two_phase=sim.two_phase)
            t_mat.append(time.perf_counter() - t0)
        row[f"law_{s.name}_Mpoints_per_s"] = len(s) / float(np.median(t_mat)) / 1e6
    return row


@benchmark("mpm2d", "mpm2d_speed", "mpm2d: material-point steps per second (elastic, two-phase)")
def speed(out: Path, quick: bool) -> BenchResult:
    import pandas as pd

    from rheology.io import atomic_write_csv
    from mpm2d.plots import plt, save

    cells = {"elastic": 64 if quick else 256, "two-phase suspension": 32 if quick else 128}
    makers = {"elastic": elastic_block, "two-phase suspension": sheared_suspension}
    steps = 5 if quick else 20
    rows = []
    for name, make in makers.items():
        for parallel in (False, True):
            rows.append({"case": name, **time_model(make, cells[name], parallel, steps)})
    df = pd.DataFrame(rows)
    atomic_write_csv(out / "mpm2d_speed.csv", df)
    targets = []
    for name, target in TARGETS.items():
        sub = df[df["case"] == name]
        best = sub.loc[sub["Mpoint_steps_per_s"].idxmax()]
        targets.append((f"({'a' if name == 'elastic' else 'b'}) {name} >= {target / 1e6:g} M "
                        "point-steps/s (2 cores)",
                        f"{best['Mpoint_steps_per_s']:.2f} M/s ({best['build']}), "
                        f"{best['ratio_to_bare']:.2f} x the bare loop", bool(best["Mpoint_steps_per_s"] * 1e6 >= target)))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(13, 4.5))
    labels = [f"({'a' if r['case'] == 'elastic' else 'b'}) {r['build']}" for r in rows]
    xs = np.arange(len(rows))
    a1.bar(xs - 0.2, df["Mpoint_steps_per_s"], 0.4, label="full MPM step")
    a1.bar(xs + 0.2, df["bare_Mpoint_steps_per_s"], 0.4, label="bare P2G + G2P")
    for name, target in TARGETS.items():
        a1.axhline(target / 1e6, ls=":", color="k")
        a1.text(len(rows) - 0.5, target / 1e6, f" target {name}", fontsize=7, va="bottom",
                ha="right")
    a1.set_xticks(xs, labels, fontsize=8)
    a1.set_ylabel("M point-steps / s")
    a1.set_title("(a) elastic block, (b) two-phase suspension")
    a1.legend()
    shares = [c for c in df.columns if c.startswith("share_")]
    bottom = np.zeros(len(rows))
    for c in shares:
        a2.bar(xs, df[c], bottom=bottom, label=c[6:].replace("_", " "))
        bottom += df[c].to_numpy()
    a2.set_xticks(xs, labels, fontsize=8)
    a2.set_ylabel("share of the step time")
    a2.legend(fontsize=8)
    fig_path = save(fig, out / "mpm2d_speed.png")
    summary = ("Median wall time per step over {} steps after 3 warm-up steps; elastic block {} "
               "points, two-phase suspension {} points (half granular, half fluid); serial and "
               "parallel numba builds; reference: bare APIC P2G + G2P on the same points and "
               "grid in the same process; law_* columns: each material's constitutive update "
               "alone (rheology's elastic_trial / update_point). Machine shared with other jobs "
               "(noisy, parallel regions especially).").format(steps, int(df[df.case == "elastic"].points.iloc[0]),
                                              int(df[df.case != "elastic"].points.iloc[0]))
    return BenchResult(summary=summary, rows=rows, targets=targets, figures=[fig_path])
