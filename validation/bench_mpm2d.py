"""mpm2d speed: point-steps per second as a ratio to a bare P2G + G2P loop in the same run.

Targets: machines differ by 2x, so each mode is measured against the bare APIC transfer timed on
the same points and grid in the same process, with 2 threads (the parallel numba builds), median
of at least 3 repetitions (each the median step time of a run of steps, interleaved step by step
with the bare loop so load changes hit both):

(a) single-phase linear elastic block (Jaumann update, rheology.local_update.jaumann_elastic_plane):
    >= 0.75 x bare;
(b) two-phase suspension: granular points with the Table 8 law (rheology.local_update.update_block,
    homogeneous shear so most points take the dilatant shear-flow solve) and as many fluid points,
    implicit drag, buoyancy: >= 0.45 x bare;
(c) locked mixture: the same shear with one velocity field (Suspension(locked=True)): >= 0.50 x bare.

The same ratios at 1 thread (the serial builds) are reported beside them, also in process CPU
time (``ratio_to_bare_cpu``: the serial work itself, which time-slicing on a loaded machine does
not change; with threads it counts their waiting too).

The bare reference: P2G of mass and momentum, nodal velocities, G2P of velocity and affine matrix
and the position update (no stress, boundaries or materials). Per-phase shares come from the
simulation's own clocks (the step size's extremes are taken in the P2G pass, so its share is the
remaining bookkeeping; the body force is added in the P2G reduction, and in plane single-field
runs such as (a) the nodal velocities too, so "grid update" is then the boundaries alone; a
linear-elastic set's stress update is done in its G2P pass, so (a) has no "constitutive" share).

Memory: each phase's bytes moved per point-step (the per-point arrays it reads and writes, a
write-only array counted twice for its write-allocate read; node fields, in cache, not counted)
against the machine's bandwidth measured in the same run by a stream triad (a = b + s c on three
64 MB arrays, serial and parallel): a phase whose bytes per second approach the triad's is
memory-bound.

The Table 8 update alone on the suspension modes' points (their state now, L of the last step),
serial, in process CPU time: the reference (update_point by the bracket alone, newton=False)
against the vectorised block (rheology.local_update.update_block, what mpm2d calls), per stage of
the block (the trial in mpm2d's layout, then each of update_block's stages: ns per point as the
difference of cumulative times), with residual evaluations per flowing point. The same two paths
on the points of a bed at rest (:func:`bed_at_rest`: a vanishing tensile trial pressure, the
state of a scene's bed under its free surface and of most of its points through a run).

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
from mpm2d.materials import trial_stress
from rheology.local_update import (BLOCK, NOUT, NSTRESS, NWORK, SHEAR_FLOW, block_finish,
                                   block_handed, block_inv_eta_B, block_newton, block_retry,
                                   block_start, block_test, kernel_parameters,
                                   update_points_serial)
from rheology.numba_cache import guard

from .framework import BenchResult, benchmark, interleaved, timed
import pandas as pd
from mpm2d.plots import plt, save
from runkit.io import atomic_write_csv

guard(__file__, _shape.__file__)   # its bare kernels inline mpm2d.shape's weights

#: Ratio of the full step's point-steps/s to the bare P2G + G2P loop's, per mode (2 threads).
TARGETS = {"elastic": 0.75, "two-phase suspension": 0.45, "locked mixture": 0.50}
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


@nb.njit(error_model="numpy")
def _law_upto(stop, stress, L, Lw, phi, f0, g0, dt, P, S, W, fb, gb, cb):
    """The suspension kernel's law on blocks of BLOCK points up to stage ``stop`` (0: the trial
    in mpm2d's layout, mpm2d.materials.trial_stress; 1-7: update_block's stages in turn), on copies
    of f and gdot (the inputs are not changed)."""
    N = phi.shape[0]
    G, K = P[16], P[17]
    for lo in range(0, N, BLOCK):
        n = min(lo + BLOCK, N) - lo
        for k in range(n):
            trial_stress(stress, L, Lw, lo + k, dt, G, K, S, k)
            fb[k], gb[k] = f0[lo + k], g0[lo + k]
        ph, f, g, case = phi[lo:lo + n], fb[:n], gb[:n], cb[:n]
        if stop >= 1:
            block_start(S, ph, f, dt, P, W)
        if stop >= 2:
            block_newton(ph, f, dt, P, W)
        if stop >= 3:
            block_test(ph, f, dt, P, W)
        if stop >= 4:
            block_retry(ph, f, dt, P, W)
        if stop >= 5:
            block_inv_eta_B(ph, P, W)
        if stop >= 6:
            block_handed(ph, f, g, dt, P, W)
        if stop >= 7:
            block_finish(S, ph, f, g, case, dt, P, W)


#: update_block's stages as the benchmark times them (after mpm2d's trial, stage 0)
LAW_STAGES = ("trial", "start", "newton", "test", "retry", "inv_eta_B", "handed", "finish")


def law_alone(s, dt, reps: int) -> dict:
    """The Table 8 update alone on set s's points (their state now, L of the last step): the
    reference (update_point by the bracket alone) and the block (mpm2d's path), per stage.

    Serial, in process CPU time (less disturbed by other jobs on a shared machine than wall
    time): ns per point, medians of ``reps`` passes over the points, the stages' passes
    interleaved. A stage's time is the difference of the cumulative times up to it and before
    it."""
    Lc = s.L
    L3 = np.zeros((len(s), 3, 3))
    L3[:, 0, 0], L3[:, 0, 1], L3[:, 1, 0], L3[:, 1, 1], L3[:, 2, 2] = (Lc[:, 0], Lc[:, 1], Lc[:, 2],
                                                                   Lc[:, 3], Lc[:, 4])
    sig, f, phi, g = s.stress.copy(), s.f.copy(), s.svol / s.V, s.gdot_p.copy()
    P = kernel_parameters(s.material.m)
    n = len(s)
    so, out = np.empty_like(sig), np.empty((n, NOUT))
    work = (np.zeros((NSTRESS, BLOCK)), np.zeros((NWORK, BLOCK)), np.zeros(BLOCK), np.zeros(BLOCK),
            np.zeros(BLOCK))
    Lw = np.zeros((0, 2))
    calls = {"reference": lambda: update_points_serial(sig, L3, phi, f, dt, P, so, out, g, False),
             "block": lambda: update_points_serial(sig, L3, phi, f, dt, P, so, out, g)}
    calls.update({f"upto_{k}": (lambda k=k: _law_upto(k, s.stress, Lc, Lw, phi, f, g, dt, P, *work))
                  for k in range(len(LAW_STAGES))})
    times = {k: [] for k in calls}
    for fn in calls.values():
        fn()
    for _ in range(reps):
        for k, fn in calls.items():
            t0 = time.process_time()
            fn()
            times[k].append(time.process_time() - t0)
    ns = {k: float(np.median(v)) * 1e9 / n for k, v in times.items()}
    row = {"law_points": n, "law_reference_ns_per_point": ns["reference"],
           "law_block_ns_per_point": ns["block"]}
    prev = 0.0
    for k, name in enumerate(LAW_STAGES):
        row[f"law_stage_{name}_ns_per_point"] = ns[f"upto_{k}"] - prev
        prev = ns[f"upto_{k}"]
    row["law_mpm2d_ns_per_point"] = prev
    for label, newton in (("reference", False), ("block", True)):
        update_points_serial(sig, L3, phi, f, dt, P, so, out, g, newton)
        flow = out[:, 12] == SHEAR_FLOW
        row[f"law_{label}_evals_per_flow_point"] = float(out[flow, 13].mean()) if flow.any() else 0.0
    row["law_flow_fraction"] = float(np.mean(flow))
    row["law_speedup"] = ns["reference"] / ns["block"]
    return row


# ------------------------------------------------------------------ memory
@dual
def _triad(a, b, c, s):
    for i in nb.prange(a.shape[0]):
        a[i] = b[i] + s * c[i]


def stream_bandwidth(parallel: bool, mb: int = 64, reps: int = 7) -> float:
    """The machine's memory bandwidth [GB/s]: a stream triad a = b + s c on three arrays of
    ``mb`` MB each (past the caches), 24 bytes a element (write-allocate not counted, as in
    STREAM); median of ``reps``."""
    n = mb * (1 << 20) // 8
    a, b, c = np.zeros(n), np.ones(n), np.ones(n)
    _triad[parallel](a, b, c, 3.0)
    return 24.0 * n / timed(lambda: _triad[parallel](a, b, c, 3.0), reps)[0] / 1e9


def phase_bytes(sim) -> dict:
    """Bytes each phase of a step moves per point, from the per-point arrays its kernels read
    and write (8 bytes a value; a write-only array twice, for its write-allocate read; node
    fields, which stay in cache, not counted): the model's total over its sets divided by its
    points."""
    tot = dict.fromkeys(("P2G", "G2P", "constitutive"), 0.0)
    for s in sim.sets:
        n, two = len(s), sim.two_phase
        fluid, susp = s.phase == "fluid", isinstance(s.material, Suspension)
        elastic = s.name in sim._fused_update
        # P2G: x, v, C, m, V, sp (+ pf of two-phase fluid points, svol of two-phase grains)
        p2g = 2 + 2 + 4 + 1 + 1 + 4 + (two and fluid) + (two and not fluid)
        # G2P: reads x, v, C and writes them, L write-only; a linear-elastic set's fused update:
        # stress and V read and written, sp write-only
        g2p = 8 + 8 + 2 * 5 + (2 * 9 + 2 + 2 * 4 if elastic else 0)
        if two and fluid:  # porosity and div q gathered (write-only), n = 1 - phi (numpy)
            g2p += 2 * 2 + 3
        con = 0
        if susp:           # reads stress, L, V, svol, f, gdot (+ m); writes stress, V, f, gdot,
            con = 9 + 5 + 1 + 1 + 1 + 1 + s.material.locked + 9 + 1 + 1 + 1 + 2 * (1 + 4 + 1)
        elif fluid:        # reads L, V, rho, m or (div q, n); writes V, rho; sp, pf write-only
            con = 5 + 1 + 1 + (2 if two else 1) + 1 + 1 + 2 * (4 + 1)
        for k, v in (("P2G", p2g), ("G2P", g2p), ("constitutive", con)):
            tot[k] += 8.0 * v * n
    npts = sum(len(s) for s in sim.sets)
    return {k: v / npts for k, v in tot.items()}


def _interleaved(full, bare, steps: int):
    """Median wall times of ``full`` and ``bare`` called alternately, one call each in turn (so
    that the machine's load changes hit both alike), and the ratio of their median process CPU
    times (bare/full: with the serial builds the work itself, unaffected by time-slicing on a
    loaded machine; with threads it also counts their waiting)."""
    wf, wb, cf, cb = [], [], [], []
    for _ in range(steps):
        for fn, w, c in ((full, wf, cf), (bare, wb, cb)):
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            w.append(time.perf_counter() - t0)
            c.append(time.process_time() - c0)
    return float(np.median(wf)), float(np.median(wb)), float(np.median(cb) / np.median(cf))


def time_model(make, cells: int, steps: int, reps: int = 5, law: bool = False) -> dict:
    """Full steps and the bare loop, interleaved step by step, ``reps`` repetitions of ``steps``
    pairs; medians and ratios of wall time; per phase ns, bytes and bytes/s per point-step; with
    ``law`` the Table 8 update alone on the suspension points (:func:`law_alone`)."""
    sim = make(cells)                # the engine's own serial/parallel choice per kernel
    for _ in range(3):                             # compile / warm caches
        sim.step()
    bare = _bare_setup(sim)
    _bare_step(sim, bare)
    sim.timings = dict.fromkeys(sim.timings, 0.0)
    n = sum(len(s) for s in sim.sets)
    full, ref, ratios, cpu = [], [], [], []
    for _ in range(reps):
        tf, tb, rc = _interleaved(sim.step, lambda: _bare_step(sim, bare), steps)
        full.append(n / tf)
        ref.append(n / tb)
        ratios.append(tb / tf)
        cpu.append(rc)
    total = sum(sim.timings.values())
    row = {"model": sim.name.replace("bench ", ""), "threads": nb.get_num_threads(),
           "parallel_points": bool(sim.par), "parallel_grid": bool(sim.par_grid),
           "points": n, "grid_nodes": sim.grid.shape[0] * sim.grid.shape[1],
           "repetitions": reps, "steps_per_repetition": steps,
           "Mpoint_steps_per_s": float(np.median(full)) / 1e6,
           "bare_Mpoint_steps_per_s": float(np.median(ref)) / 1e6,
           "ratio_to_bare": float(np.median(ratios)),
           "ratio_min": float(np.min(ratios)), "ratio_max": float(np.max(ratios)),
           "ratio_to_bare_cpu": float(np.median(cpu))}
    for k, v in sim.timings.items():
        row[f"share_{k.replace(' ', '_')}"] = v / total if total > 0 else 0.0
    # each phase's wall time and bytes moved per point-step, and its bytes per second
    nsteps = reps * steps
    for k, b in phase_bytes(sim).items():
        t = sim.timings[k] / nsteps / n * 1e9
        row[f"ns_{k}"] = t
        row[f"bytes_{k}"] = b
        row[f"GBps_{k}"] = b / t if t > 0 else 0.0
    if law:
        for s in sim.sets:
            if isinstance(s.material, Suspension):
                row.update(law_alone(s, sim.last_dt, max(5, steps)))
    return row


def bed_at_rest(n: int, seed: int = 7):
    """States of the points of a bed at rest under its free surface, as the scenes' beds start
    (the impact bed's, 88% of its points): phi = 0.47, trial pressure p* < 0 a vanishing
    tension (1e-12 to 1e-3 Pa), tau* above the separation bound |p*| G/(K K3 phi) by 1.001 to
    1e3, no flow (L = 0), f = 0; material rod_impact, dt = 2e-6 s. Returns (stress (n, 3, 3),
    L (n, 3, 3), phi, f, dt, P)."""
    m = get_material("rod_impact")
    rng = np.random.default_rng(seed)
    phi = np.full(n, 0.47)
    p_t = -10.0 ** rng.uniform(-12, -3, n)
    tau = -p_t * m.G / (m.K * m.K3 * phi) * 10.0 ** rng.uniform(0.0005, 3, n)
    sig = np.zeros((n, 3, 3))
    sig[:, 0, 0] = sig[:, 1, 1] = sig[:, 2, 2] = -p_t
    sig[:, 0, 1] = sig[:, 1, 0] = tau
    return sig, np.zeros((n, 3, 3)), phi, np.zeros(n), 2e-6, kernel_parameters(m)


def law_at_rest(n: int, reps: int) -> dict:
    """The Table 8 update alone on :func:`bed_at_rest` points, serial, process CPU time (median
    of ``reps``): the reference (bracket alone) against the block path warm from each point's
    previous rate (the solution perturbed by 1e-4, as a step at rest changes it), ns a point."""
    sig, L, phi, f, dt, P = bed_at_rest(n)
    so, out = np.empty_like(sig), np.empty((n, NOUT))
    update_points_serial(sig, L, phi, f.copy(), dt, P, so, out, None)
    g = out[:, 1] * (1.0 + 1e-4 * np.random.default_rng(1).uniform(-1, 1, n))
    calls = {"reference": lambda: update_points_serial(sig, L, phi, f.copy(), dt, P, so, out,
                                                       None, False),
             "block": lambda: update_points_serial(sig, L, phi, f.copy(), dt, P, so, out, g)}
    for fn in calls.values():                        # compile
        fn()
    ns = {k: float(np.median(v)) * 1e9 / n
          for k, v in interleaved(calls, reps, clock=time.process_time).items()}
    return {"rest_points": n, "rest_reference_ns_per_point": ns["reference"],
            "rest_block_ns_per_point": ns["block"]}


# ------------------------------------------------------------------ Taichi peer (mpm88-style)
def taichi_elastic_rate(cells: int, steps: int, reps: int = 3):
    """Point-steps/s of an mpm88-style APIC step of a linear elastic block in Taichi.

    Same layout as (a): unit square, 2 x 2 points per cell of a cells x cells grid, small-strain
    linear elasticity (E = 1e6 Pa, nu = 0.3, rho = 1000) from the deformation gradient, slip walls,
    fixed dt (0.5 h / c), quadratic B-splines, APIC; CPU backend, 2 threads, float64. Returns
    (rate, note); rate None when Taichi is not installed.
    """
    # Taichi wraps every kernel call with a print-buffer flush when sys.stdout is not the
    # console's own (it is a filter under runkit.command.run): a per-call cost
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

    rate = float(np.median([n / timed(one, steps)[0] for _ in range(reps)]))
    version = ".".join(map(str, ti.__version__))
    return rate, (f"Taichi {version} mpm88-style APIC elastic step, CPU backend, {THREADS} "
                  f"threads, float64, {n} points, {cells}^2 cells")


@benchmark("mpm2d", "mpm2d_speed", "mpm2d: point-steps per second against the bare P2G + G2P "
           "loop (elastic, two-phase, locked mixture; 1 and 2 threads), memory traffic, the Table 8 "
           "update per stage, and Taichi")
def speed(out: Path, quick: bool) -> BenchResult:
    threads = min(THREADS, nb.config.NUMBA_NUM_THREADS)
    cells = {"elastic": 64 if quick else 256, "two-phase suspension": 32 if quick else 128,
             "locked mixture": 32 if quick else 128}
    makers = {"elastic": elastic_block, "two-phase suspension": sheared_suspension,
              "locked mixture": sheared_locked}
    steps = 4 if quick else 10
    load0 = os.getloadavg()[0]
    bw = {}
    rows = []
    try:
        for th in (threads, 1):
            nb.set_num_threads(th)
            bw[th] = stream_bandwidth(th > 1, 8 if quick else 64)
            for name, make in makers.items():
                r = {"case": name, **time_model(make, cells[name], steps, law=th == threads)}
                r["stream_GBps"] = bw[th]
                rows.append(r)
        nb.set_num_threads(threads)
        rest = law_at_rest(2000 if quick else 20000, 5)
        ti_rate, ti_note = taichi_elastic_rate(cells["elastic"], steps)
    finally:
        nb.set_num_threads(threads)
    load1 = os.getloadavg()[0]
    main = [r for r in rows if r["threads"] == threads]
    one = {r["case"]: r for r in rows if r["threads"] == 1}
    ela = main[0]
    main[-1].update(rest)                            # the locked mixture's row (the law's set)
    if ti_rate is not None:
        ela["taichi_Mpoint_steps_per_s"] = ti_rate / 1e6
        ela["ratio_to_taichi"] = ela["Mpoint_steps_per_s"] * 1e6 / ti_rate
    df = pd.DataFrame(rows)
    atomic_write_csv(out / "mpm2d_speed.csv", df, empty_ok=tuple(
        c for c in df.columns if c.startswith(("law_", "rest_", "taichi", "ratio_to_t"))))
    targets = []
    for k, (name, target) in enumerate(TARGETS.items()):
        r = main[k]
        targets.append((f"({'abc'[k]}) {name} >= {target:.2f} x the bare P2G + G2P loop "
                        f"({threads} threads, median of {r['repetitions']})",
                        f"{r['ratio_to_bare']:.3f} x (range {r['ratio_min']:.3f}-"
                        f"{r['ratio_max']:.3f}; {r['Mpoint_steps_per_s']:.2f} vs "
                        f"{r['bare_Mpoint_steps_per_s']:.2f} M point-steps/s); 1 thread "
                        f"{one[name]['ratio_to_bare']:.3f} x (in CPU time "
                        f"{one[name]['ratio_to_bare_cpu']:.3f} x)",
                        bool(r["ratio_to_bare"] >= target)))
    targets.append(("the Table 8 update alone on a bed at rest (p* <= 0, the dilatant tension "
                    "solve; serial): the block path warm from the previous rate faster than the "
                    "reference (bracket)",
                    f"{rest['rest_block_ns_per_point']:.0f} against "
                    f"{rest['rest_reference_ns_per_point']:.0f} ns a point",
                    bool(rest["rest_block_ns_per_point"] < rest["rest_reference_ns_per_point"])))
    if ti_rate is not None:
        targets.append(("peer: elastic step beside Taichi's mpm88-style APIC step (report)",
                        f"ours {ela['Mpoint_steps_per_s']:.2f} M/s, Taichi {ti_rate / 1e6:.2f} M/s:"
                        f" {ela['ratio_to_taichi']:.2f} x Taichi", True))
    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(17, 4.5))
    xs = np.arange(len(main))
    labels = [f"({'abc'[k]}) {r['case']}" for k, r in enumerate(main)]
    a1.bar(xs - 0.2, [r["ratio_to_bare"] for r in main], 0.4, label=f"{threads} threads")
    a1.bar(xs + 0.2, [one[r["case"]]["ratio_to_bare"] for r in main], 0.4, label="1 thread")
    for k, (name, target) in enumerate(TARGETS.items()):
        a1.hlines(target, k - 0.4, k + 0.4, colors="k", linestyles=":")
    if ti_rate is not None:
        a1.bar([len(main)], [ti_rate / 1e6 / ela["bare_Mpoint_steps_per_s"]], 0.4, color="C2",
               label="Taichi mpm88-style elastic / our bare loop")
        labels.append("Taichi (elastic)")
        xs = np.arange(len(main) + 1)
    a1.set_xticks(xs, labels, fontsize=8, rotation=15)
    a1.set_ylabel("point-steps/s ratio to the bare loop (dotted: target)")
    a1.legend(fontsize=8, loc="upper left")
    phases = ("P2G", "G2P", "constitutive")
    for j, ph in enumerate(phases):
        a2.bar(np.arange(len(main)) + 0.25 * (j - 1), [r[f"GBps_{ph}"] for r in main], 0.25,
               label=ph)
    a2.axhline(bw[threads], color="k", ls=":", label=f"stream triad, {threads} threads")
    a2.set_xticks(np.arange(len(main)), labels[:len(main)], fontsize=8, rotation=15)
    a2.set_ylabel("bytes moved / phase time [GB/s]")
    a2.legend(fontsize=8)
    law_rows = [r for r in main if "law_block_ns_per_point" in r]
    for j, r in enumerate(law_rows):
        bottom = 0.0
        for k, st in enumerate(LAW_STAGES):
            v = max(r[f"law_stage_{st}_ns_per_point"], 0.0)
            a3.bar(2 * j, v, 0.8, bottom=bottom, color=f"C{k}", label=st if j == 0 else None)
            bottom += v
        a3.bar(2 * j + 1, r["law_reference_ns_per_point"], 0.8, color="0.5",
               label="reference (bracket)" if j == 0 else None)
    a3.set_xticks([2 * j + 0.5 for j in range(len(law_rows))], [r["case"] for r in law_rows],
                  fontsize=8)
    a3.set_ylabel("Table 8 update alone, serial [ns per point]")
    a3.legend(fontsize=7)
    fig_path = save(fig, out / "mpm2d_speed.png")
    law = "; ".join(
        f"{r['case']}: the Table 8 update alone (serial, CPU time) "
        f"{r['law_mpm2d_ns_per_point']:.1f} ns a point in mpm2d's block path ("
        + ", ".join(f"{st} {r[f'law_stage_{st}_ns_per_point']:.1f}" for st in LAW_STAGES)
        + f"), the reference (bracket alone) {r['law_reference_ns_per_point']:.1f} ns "
        f"({r['law_speedup']:.1f} x); residual evaluations per flowing point "
        f"{r['law_reference_evals_per_flow_point']:.2f} (reference) -> "
        f"{r['law_block_evals_per_flow_point']:.2f} (block)" for r in law_rows)
    mem = "; ".join(
        f"{r['case']} ({r['threads']} thr): " + ", ".join(
            f"{ph} {r[f'bytes_{ph}']:.0f} B in {r[f'ns_{ph}']:.1f} ns = {r[f'GBps_{ph}']:.1f} GB/s"
            for ph in phases if r[f"bytes_{ph}"] > 0) for r in rows)
    summary = (f"{threads} numba threads (the engine picks the parallel build of a point kernel "
               "above its size threshold, likewise for grid kernels, and the bare loop makes the "
               f"same choices; 1 thread: the serial builds); per mode {main[0]['repetitions']} "
               f"repetitions, each the median of {steps} steps after 3 warm-up steps, interleaved "
               "step by step with the bare APIC P2G + G2P loop on the same points and grid; the "
               "ratio is the median over repetitions. Points: "
               + ", ".join(f"{r['case']} {r['points']}" for r in main)
               + f". Load average {load0:.2f} before, {load1:.2f} after (2-core machine shared "
               f"with other jobs). Memory: stream triad {bw[threads]:.1f} GB/s ({threads} "
               f"threads), {bw[1]:.1f} GB/s (1); bytes moved per point-step and their rate: {mem}. "
               f"{law}. Peer: {ti_note}"
               + (f": {ti_rate / 1e6:.2f} M point-steps/s, ours {ela['ratio_to_taichi']:.2f} x "
                  "Taichi's." if ti_rate is not None else "."))
    return BenchResult(summary=summary, rows=rows, targets=targets, figures=[fig_path])
