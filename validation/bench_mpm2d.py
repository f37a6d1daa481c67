"""mpm2d speed: point-steps per second as a ratio to a bare P2G + G2P loop in the same run.

Targets (issue 10, item 5): machines differ by 2x, so each mode is measured against the bare APIC
transfer timed on the same points and grid in the same process, with 2 threads (the parallel
numba builds), median of at least 3 repetitions (each the median step time of a run of steps,
interleaved step by step with the bare loop so load changes hit both):

(a) single-phase linear elastic block (Jaumann update, rheology.local_update.jaumann_elastic_plane):
    >= 0.60 x bare;
(b) two-phase suspension: granular points with the Table 8 law (rheology.local_update.update_point,
    homogeneous shear so most points take the dilatant shear-flow solve) and as many fluid points,
    implicit drag, buoyancy: >= 0.30 x bare;
(c) locked mixture: the same shear with one velocity field (Suspension(locked=True)): >= 0.30 x bare.

The bare reference: P2G of mass and momentum, nodal velocities, G2P of velocity and affine matrix
and the position update (no stress, boundaries or materials). Per-phase shares come from the
simulation's own clocks (the step size's extremes are taken in the P2G pass, so its share is the
remaining bookkeeping; the body force is added in the P2G reduction, and in plane single-field
runs such as (a) the nodal velocities too, so "grid update" is then the boundaries alone; a
linear-elastic set's stress update is done in its G2P pass, so (a) has no "constitutive" share). For the suspension modes
the Table 8 update is also timed alone on the run's points, with the bracket-only solve (the
reference), and the Newton solve (rheology.local_update.update_block's vectorised stages, what
mpm2d calls) from a cold start and from the previous plastic rate (warm start), with residual
evaluations per point.

Peer: with the ``bench`` extra (``pip install -e ".[bench]"``: Taichi), Taichi's mpm88-style APIC
step of a linear elastic block (written here, CPU backend, 2 threads, float64, fixed dt) on the same
number of points and grid beside (a); skipped with a note when Taichi is absent.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numba as nb
import numpy as np

from mpm2d import Drag, Grid, LinearElastic, NewtonianFluid, ParticleSet, Simulation, Suspension, box
from mpm2d.grid import PAD
from mpm2d.kernels import dual
import mpm2d.shape as _shape
from mpm2d.shape import APIC_D_INV, weights
from mpm2d.transfer import chunk_bounds
from rheology import get_material
from rheology.local_update import NOUT, SHEAR_FLOW, kernel_parameters, update_points_serial
from rheology.numba_cache import guard

from .framework import BenchResult, benchmark

guard(__file__, _shape.__file__)   # its bare kernels inline mpm2d.shape's weights

#: Ratio of the full step's point-steps/s to the bare P2G + G2P loop's, per mode (issue 10).
TARGETS = {"elastic": 0.60, "two-phase suspension": 0.30, "locked mixture": 0.30}
THREADS = 2


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


def _bare_setup(sim):
    shape = sim.grid.shape
    sets = [(s.x.copy(), s.v.copy(), s.C.copy(), s.m.copy()) for s in sim.sets]
    return (sim.grid.geometry(), sets, np.zeros((sim.nc,) + shape + (3,)), np.zeros(shape + (2,)),
            1e-12 * sim.grid.h)                  # dt: positions stay put (same cells every step)


def _bare_step(sim, bare):
    """One bare P2G + grid + G2P pass, with the engine's serial/parallel choices (sim.par for the
    point loops, sim.par_grid for the grid loop), so both sides pay the same thread costs."""
    geo, sets, priv, vg, dt = bare
    for x, v, C, m in sets:
        _bare_p2g[sim.par](x, v, C, m, geo, chunk_bounds(len(x), sim.nc), priv)
    _bare_grid[sim.par_grid](priv, vg)
    for x, v, C, m in sets:
        _bare_g2p[sim.par](x, v, C, vg, geo, dt)


def _median_step(fn, steps: int, clock=time.perf_counter) -> float:
    times = []
    for _ in range(steps):
        t0 = clock()
        fn()
        times.append(clock() - t0)
    return float(np.median(times))


def elastic_block(cells: int) -> Simulation:
    """(a): a vibrating elastic block filling the unit square (frictionless walls)."""
    h = 1.0 / cells
    grid = Grid(cells, cells, h, boundaries=dict(xmin="slip", xmax="slip", ymin="slip",
                                                ymax="slip"))
    x, area = box((0.0, 0.0), (1.0, 1.0), h / 2)
    v = 1e-3 * np.stack([np.sin(np.pi * x[:, 1]), np.sin(np.pi * x[:, 0])], axis=1)
    ps = ParticleSet("block", LinearElastic(1000.0, E=1e6, nu=0.3), x, area, v=v)
    return Simulation(grid, [ps], name="bench elastic")


def _shear_grid(cells: int, size: float, rate: float) -> Grid:
    return Grid(cells, cells, size / cells, boundaries=dict(xmin="periodic", xmax="periodic",
                                                            ymin="noslip", ymax="noslip"),
                wall_velocity={"ymax": (rate * size, 0.0)})


def sheared_suspension(cells: int) -> Simulation:
    """(b): two-phase suspension (annular_shear, phi = 0.45) in homogeneous shear at 10 1/s
    between noslip walls (top moving), periodic sideways, gravity on."""
    m = get_material("annular_shear")
    size, rate = 0.05, 10.0
    grid = _shear_grid(cells, size, rate)
    x, area = box((0.0, 0.0), (size, size), size / cells / 2)
    v = np.stack([rate * x[:, 1], np.zeros(len(x))], axis=1)
    grains = ParticleSet("grains", Suspension(m), x, area, v=v, phi=0.45,
                         stress=-50.0 * np.eye(3), f=0.0)
    fluid = ParticleSet("fluid", NewtonianFluid.from_material(m), x, area, v=v, phi=0.45)
    for s in (grains, fluid):
        s.C[:, 0, 1] = rate
    return Simulation(grid, [grains, fluid], mode="two-phase", drag=Drag.from_material(m),
                      gravity=(0.0, -9.81), name="bench two-phase suspension")


def sheared_locked(cells: int) -> Simulation:
    """(c): the same shear of a locked mixture (annular_shear, phi = 0.45, one velocity field,
    undrained pore pressure) on a sqrt(2) finer grid, so that it has as many points (4 per cell)
    as (b) has granular plus fluid points."""
    m = get_material("annular_shear")
    size, rate = 0.05, 10.0
    cells = int(round(cells * np.sqrt(2.0)))
    grid = _shear_grid(cells, size, rate)
    x, area = box((0.0, 0.0), (size, size), size / cells / 2)
    v = np.stack([rate * x[:, 1], np.zeros(len(x))], axis=1)
    bed = ParticleSet("mixture", Suspension(m, locked=True), x, area, v=v, phi=0.45,
                      stress=-50.0 * np.eye(3), f=0.0)
    bed.C[:, 0, 1] = rate
    return Simulation(grid, [bed], mode="locked mixture", gravity=(0.0, -9.81),
                      name="bench locked mixture")


def law_alone(sim, s, dt, steps: int) -> dict:
    """The Table 8 update alone on set s's points (their state now, L of the last step):
    bracket-only reference, Newton cold (what mpm2d calls) and warm (previous rate).

    Serial build, timed in process CPU time (medians): the comparison is of the algorithms, and
    CPU time is less disturbed by other jobs on a shared machine than a parallel region's wall
    time."""
    Lc = s.L
    L = np.zeros((len(s), 3, 3))
    L[:, 0, 0], L[:, 0, 1], L[:, 1, 0], L[:, 1, 1], L[:, 2, 2] = (Lc[:, 0], Lc[:, 1], Lc[:, 2],
                                                                 Lc[:, 3], Lc[:, 4])
    sig, f, phi = s.stress.copy(), s.f.copy(), s.svol / s.V
    g_prev = s.gdot_p.copy()
    P = kernel_parameters(s.material.m)
    so, out = np.empty_like(sig), np.empty((len(s), NOUT))
    row = {}
    for label, kw in (("bracket", dict(newton=False)), ("newton_cold", {}),
                      ("newton_warm", dict(g_prev=g_prev))):
        call = lambda: update_points_serial(sig, L, phi, f, dt, P, so, out, **kw)
        call()
        t = _median_step(call, max(5, steps // 2), clock=time.process_time)
        flow = out[:, 12] == SHEAR_FLOW
        row[f"law_{label}_Mpoints_per_s"] = len(s) / t / 1e6
        row[f"law_{label}_evals_per_flow_point"] = float(out[flow, 13].mean()) if flow.any() else 0.0
    row["law_flow_fraction"] = float(np.mean(out[:, 12] == SHEAR_FLOW))
    row["law_speedup_cold"] = row["law_newton_cold_Mpoints_per_s"] / row["law_bracket_Mpoints_per_s"]
    row["law_speedup_warm"] = row["law_newton_warm_Mpoints_per_s"] / row["law_bracket_Mpoints_per_s"]
    return row


def _interleaved(full, bare, steps: int):
    """Median wall times of ``full`` and ``bare`` called alternately, one call each in turn (so
    that the machine's load changes hit both alike)."""
    wf, wb = [], []
    for _ in range(steps):
        for fn, w in ((full, wf), (bare, wb)):
            t0 = time.perf_counter()
            fn()
            w.append(time.perf_counter() - t0)
    return float(np.median(wf)), float(np.median(wb))


def time_model(make, cells: int, steps: int, reps: int = 5) -> dict:
    """Full steps and the bare loop, interleaved step by step, ``reps`` repetitions of ``steps``
    pairs; medians and ratios of wall time."""
    sim = make(cells)                # the engine's own serial/parallel choice per kernel
    for _ in range(3):                             # compile / warm caches
        sim.step()
    bare = _bare_setup(sim)
    _bare_step(sim, bare)
    sim.timings = dict.fromkeys(sim.timings, 0.0)
    n = sum(len(s) for s in sim.sets)
    full, ref, ratios = [], [], []
    for _ in range(reps):
        tf, tb = _interleaved(sim.step, lambda: _bare_step(sim, bare), steps)
        full.append(n / tf)
        ref.append(n / tb)
        ratios.append(tb / tf)
    total = sum(sim.timings.values())
    row = {"model": sim.name.replace("bench ", ""), "threads": nb.get_num_threads(),
           "parallel_points": bool(sim.par), "parallel_grid": bool(sim.par_grid),
           "points": n, "grid_nodes": sim.grid.shape[0] * sim.grid.shape[1],
           "repetitions": reps, "steps_per_repetition": steps,
           "Mpoint_steps_per_s": float(np.median(full)) / 1e6,
           "bare_Mpoint_steps_per_s": float(np.median(ref)) / 1e6,
           "ratio_to_bare": float(np.median(ratios)),
           "ratio_min": float(np.min(ratios)), "ratio_max": float(np.max(ratios))}
    for k, v in sim.timings.items():
        row[f"share_{k.replace(' ', '_')}"] = v / total if total > 0 else 0.0
    for s in sim.sets:
        if isinstance(s.material, Suspension):
            row.update(law_alone(sim, s, sim.last_dt, steps))
    return row


# ------------------------------------------------------------------ Taichi peer (mpm88-style)
def taichi_elastic_rate(cells: int, steps: int, reps: int = 3):
    """Point-steps/s of an mpm88-style APIC step of a linear elastic block in Taichi.

    Same layout as (a): unit square, 2 x 2 points per cell of a cells x cells grid, small-strain
    linear elasticity (E = 1e6 Pa, nu = 0.3, rho = 1000) from the deformation gradient, slip walls,
    fixed dt (0.5 h / c), quadratic B-splines, APIC; CPU backend, 2 threads, float64. Returns
    (rate, note); rate None when Taichi is not installed.
    """
    # Taichi wraps every kernel call with a print-buffer flush when sys.stdout is not the
    # console's own (it is a filter under rheology.cli_common.run_command): a per-call cost
    # that is not Taichi's speed (seen: 6.6 instead of 11-13 M point-steps/s). Our kernels
    # do not print, so the buffer is off.
    os.environ.setdefault("TI_ENABLE_PYBUF", "0")
    try:
        import taichi as ti
    except ImportError:
        return None, "Taichi not installed (pip install -e \".[bench]\"): peer skipped"
    ti.init(arch=ti.cpu, cpu_max_num_threads=THREADS, default_fp=ti.f64, log_level=ti.ERROR,
            offline_cache=True)
    pad = 3
    ng = cells + 2 * pad
    dx = 1.0 / cells
    inv_dx = float(cells)
    side = 2 * cells
    n = side * side
    E, nu, rho = 1e6, 0.3, 1000.0
    mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    p_vol = (dx / 2) ** 2
    p_mass = rho * p_vol
    dt = 0.5 * dx / np.sqrt((lam + 2 * mu) / rho)
    x = ti.Vector.field(2, float, n)
    v = ti.Vector.field(2, float, n)
    C = ti.Matrix.field(2, 2, float, n)
    F = ti.Matrix.field(2, 2, float, n)
    grid_v = ti.Vector.field(2, float, (ng, ng))
    grid_m = ti.field(float, (ng, ng))

    @ti.kernel
    def init():
        for p in x:
            i, j = p // side, p % side
            x[p] = ti.Vector([(i + 0.5) / side, (j + 0.5) / side])
            v[p] = 1e-3 * ti.Vector([ti.sin(np.pi * x[p][1]), ti.sin(np.pi * x[p][0])])
            F[p] = ti.Matrix.identity(float, 2)
            C[p] = ti.Matrix.zero(float, 2, 2)

    @ti.kernel
    def substep():
        for i, j in grid_m:
            grid_v[i, j] = ti.Vector.zero(float, 2)
            grid_m[i, j] = 0.0
        for p in x:
            Xp = x[p] * inv_dx + pad
            base = ti.cast(Xp - 0.5, ti.i32)
            fx = Xp - base
            w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1) ** 2, 0.5 * (fx - 0.5) ** 2]
            eps = 0.5 * (F[p] + F[p].transpose()) - ti.Matrix.identity(float, 2)
            sig = 2 * mu * eps + lam * eps.trace() * ti.Matrix.identity(float, 2)
            affine = -dt * 4 * inv_dx * inv_dx * p_vol * sig + p_mass * C[p]
            for i, j in ti.static(ti.ndrange(3, 3)):
                offset = ti.Vector([i, j])
                dpos = (offset - fx) * dx
                weight = w[i][0] * w[j][1]
                grid_v[base + offset] += weight * (p_mass * v[p] + affine @ dpos)
                grid_m[base + offset] += weight * p_mass
        for i, j in grid_m:
            if grid_m[i, j] > 0:
                gv = grid_v[i, j] / grid_m[i, j]
                if (i < pad + 1 and gv[0] < 0) or (i > ng - pad - 2 and gv[0] > 0):
                    gv[0] = 0.0
                if (j < pad + 1 and gv[1] < 0) or (j > ng - pad - 2 and gv[1] > 0):
                    gv[1] = 0.0
                grid_v[i, j] = gv
        for p in x:
            Xp = x[p] * inv_dx + pad
            base = ti.cast(Xp - 0.5, ti.i32)
            fx = Xp - base
            w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1) ** 2, 0.5 * (fx - 0.5) ** 2]
            new_v = ti.Vector.zero(float, 2)
            new_C = ti.Matrix.zero(float, 2, 2)
            for i, j in ti.static(ti.ndrange(3, 3)):
                dpos = ti.Vector([i, j]) - fx
                g_v = grid_v[base + ti.Vector([i, j])]
                weight = w[i][0] * w[j][1]
                new_v += weight * g_v
                new_C += 4 * inv_dx * weight * g_v.outer_product(dpos)
            v[p] = new_v
            x[p] += dt * new_v
            F[p] = (ti.Matrix.identity(float, 2) + dt * new_C) @ F[p]
            C[p] = new_C

    init()
    for _ in range(3):                                   # compile, warm up
        substep()
    ti.sync()

    def one():
        substep()
        ti.sync()

    rate = float(np.median([n / _median_step(one, steps) for _ in range(reps)]))
    version = ".".join(map(str, ti.__version__))
    return rate, (f"Taichi {version} mpm88-style APIC elastic step, CPU backend, {THREADS} "
                  f"threads, float64, {n} points, {cells}^2 cells")


@benchmark("mpm2d", "mpm2d_speed", "mpm2d: point-steps per second against the bare P2G + G2P "
           "loop (elastic, two-phase, locked mixture) and beside Taichi")
def speed(out: Path, quick: bool) -> BenchResult:
    import os

    import pandas as pd

    from rheology.io import atomic_write_csv
    from mpm2d.plots import plt, save

    nb.set_num_threads(min(THREADS, nb.config.NUMBA_NUM_THREADS))
    cells = {"elastic": 64 if quick else 256, "two-phase suspension": 32 if quick else 128,
             "locked mixture": 32 if quick else 128}
    makers = {"elastic": elastic_block, "two-phase suspension": sheared_suspension,
              "locked mixture": sheared_locked}
    steps = 4 if quick else 10
    load0 = os.getloadavg()[0]
    rows = [{"case": name, **time_model(make, cells[name], steps)} for name, make in makers.items()]
    ti_rate, ti_note = taichi_elastic_rate(cells["elastic"], steps)
    load1 = os.getloadavg()[0]
    ela = rows[0]
    if ti_rate is not None:
        ela["taichi_Mpoint_steps_per_s"] = ti_rate / 1e6
        ela["ratio_to_taichi"] = ela["Mpoint_steps_per_s"] * 1e6 / ti_rate
    df = pd.DataFrame(rows)
    atomic_write_csv(out / "mpm2d_speed.csv", df, empty_ok=tuple(c for c in df.columns
                                                                if c.startswith(("law_", "taichi",
                                                                                 "ratio_to_t"))))
    targets = []
    for k, (name, target) in enumerate(TARGETS.items()):
        r = rows[k]
        targets.append((f"({'abc'[k]}) {name} >= {target:.2f} x the bare P2G + G2P loop "
                        f"({THREADS} threads, median of {r['repetitions']})",
                        f"{r['ratio_to_bare']:.3f} x (range {r['ratio_min']:.3f}-{r['ratio_max']:.3f}; "
                        f"{r['Mpoint_steps_per_s']:.2f} vs {r['bare_Mpoint_steps_per_s']:.2f} M "
                        "point-steps/s)", bool(r["ratio_to_bare"] >= target)))
    if ti_rate is not None:
        targets.append(("peer: elastic step beside Taichi's mpm88-style APIC step (report)",
                        f"ours {ela['Mpoint_steps_per_s']:.2f} M/s, Taichi {ti_rate / 1e6:.2f} M/s:"
                        f" {ela['ratio_to_taichi']:.2f} x Taichi", True))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(13, 4.5))
    xs = np.arange(len(rows))
    labels = [f"({'abc'[k]}) {r['case']}" for k, r in enumerate(rows)]
    a1.bar(xs, df["ratio_to_bare"], 0.6, label="full step / bare P2G + G2P")
    for k, (name, target) in enumerate(TARGETS.items()):
        a1.hlines(target, k - 0.3, k + 0.3, colors="k", linestyles=":")
    if ti_rate is not None:
        a1.bar([len(rows)], [ti_rate / 1e6 / ela["bare_Mpoint_steps_per_s"]], 0.6, color="C2",
               label="Taichi mpm88-style elastic / our bare loop")
        labels.append("Taichi (elastic)")
        xs = np.arange(len(rows) + 1)
    a1.set_xticks(xs, labels, fontsize=8, rotation=15)
    a1.set_ylabel("point-steps/s ratio to the bare loop (dotted: target)")
    top = max(max(TARGETS.values()), float(df["ratio_to_bare"].max()),
              ti_rate / 1e6 / ela["bare_Mpoint_steps_per_s"] if ti_rate is not None else 0.0)
    a1.set_ylim(0, 1.3 * top)
    a1.legend(fontsize=8, loc="upper left")
    shares = [c for c in df.columns if c.startswith("share_")]
    bottom = np.zeros(len(rows))
    for c in shares:
        a2.bar(np.arange(len(rows)), df[c], bottom=bottom, label=c[6:].replace("_", " "))
        bottom += df[c].to_numpy()
    a2.set_xticks(np.arange(len(rows)), labels[:len(rows)], fontsize=8, rotation=15)
    a2.set_ylabel("share of the step time")
    a2.legend(fontsize=8)
    fig_path = save(fig, out / "mpm2d_speed.png")
    law = "; ".join(
        f"{r['case']}: Table 8 update alone (serial, CPU time) {r['law_newton_cold_Mpoints_per_s']:.2f} M points/s "
        f"(Newton, cold; {r['law_speedup_cold']:.2f} x the bracket-only solve, "
        f"{r['law_newton_warm_Mpoints_per_s']:.2f} warm = {r['law_speedup_warm']:.2f} x), residual "
        f"evaluations per flowing point {r['law_bracket_evals_per_flow_point']:.2f} (bracket) -> "
        f"{r['law_newton_cold_evals_per_flow_point']:.2f} (cold) / "
        f"{r['law_newton_warm_evals_per_flow_point']:.2f} (warm)"
        for r in rows if "law_speedup_cold" in r)
    summary = (f"{THREADS} numba threads (the engine picks the parallel build of a point kernel "
               f"above its size threshold, likewise for grid kernels, and the bare loop makes the same choices); per mode {rows[0]['repetitions']} "
               f"repetitions, each the median of {steps} steps after 3 warm-up steps, interleaved "
               "step by step with the bare APIC P2G + G2P loop on the same points and grid; the "
               "ratio is the median over repetitions. Points: " + ", ".join(f"{r['case']} {r['points']}" for r in rows)
               + f". Load average {load0:.2f} before, {load1:.2f} after (2-core machine shared "
               f"with other jobs). {law}. Peer: {ti_note}"
               + (f": {ti_rate / 1e6:.2f} M point-steps/s, ours {ela['ratio_to_taichi']:.2f} x "
                  "Taichi's." if ti_rate is not None else "."))
    return BenchResult(summary=summary, rows=rows, targets=targets, figures=[fig_path])
