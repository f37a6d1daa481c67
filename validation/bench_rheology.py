"""Speed of the shared constitutive module.

1. Stress-controlled flow curves: the vectorised solver (one bracketed Chandrupatla solve for all
   points, scipy.optimize.elementwise) against a scalar loop of scipy.optimize.brentq on the same
   residual, in the same process. Targets: >= 1e5 points/s and >= 50x the loop.
2. The Table 8 local update (numba, parallel over points): material points per second on random
   states (all cases), on flowing states (every point in the dilatant shear-flow solve) and on a
   batch of sheared material points stepped 20 times; the Newton solve (cold and warm starts)
   against the bracket-only solve in the same process, with residual evaluations per point.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

import rheology as r
from runkit.plotting import plt
from rheology.local_update import NOUT, kernel_parameters, update_points, update_points_serial
from rheology.steady import steady_residual

from .framework import BenchResult, benchmark, save_figure, timed
from .report import machine_description


def scalar_flow_curve(taus, phis, m):
    """Reference: one brentq per point on the same residual (in f), then the steady state."""
    dphi = m.phi_j - m.phi_c
    out = np.empty((phis.size, taus.size))
    for i, phi in enumerate(phis):
        fm = float(r.f_max(phi, m))
        k0 = float(1.0 / r.eta_B(phi, m))
        y0 = m.phi_j - phi
        fhi = min(fm, y0 / dphi)
        for j, t in enumerate(taus):
            H = (t / m.tau_star) ** 1.5
            f = brentq(lambda x: steady_residual(x, y0 - x * dphi, x - fm, t, phi, H, t * k0, m), 0.0, fhi,
                       xtol=1e-300, rtol=4 * np.finfo(float).eps)
            out[i, j] = float(r.critical_shear_rate(t, phi, f, m))
    return out


@benchmark("rheology", "bench_flow_curve_throughput",
           "Stress-controlled flow curves: vectorised solver vs a scalar brentq loop")
def flow_curve_throughput(out: Path, quick: bool) -> BenchResult:
    m = r.get_material("hermes2016")
    phis = np.linspace(0.44, 0.53, 10)
    rows, sizes = [], ([200] if quick else [20, 200, 2000, 20000])
    taus_ref = np.logspace(-3, 4, 50 if quick else 200)
    t_ref = timed(lambda: scalar_flow_curve(taus_ref, phis, m), 1 if quick else 3)[0]
    ref_rate = taus_ref.size * phis.size / t_ref
    vec = r.steady_state_stress(taus_ref[None, :], phis[:, None], m).shear_rate
    agree = float(np.max(np.abs(vec / scalar_flow_curve(taus_ref, phis, m) - 1)))
    for n in sizes:
        taus = np.logspace(-3, 4, n)
        t = timed(lambda: r.steady_state_stress(taus[None, :], phis[:, None], m),
                  3 if quick else 7)[0]
        rows.append({"points": n * phis.size, "vectorised_s": t,
                     "points_per_s": n * phis.size / t, "speed-up vs loop": n * phis.size / t / ref_rate})
    best = rows[-1]
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.loglog([q["points"] for q in rows], [q["points_per_s"] for q in rows], "o-", label="vectorised")
    ax.axhline(ref_rate, color="k", ls="--", label="scalar brentq loop")
    ax.axhline(1e5, color="r", ls=":", label="target 1e5 points/s")
    ax.set(xlabel="points per call", ylabel="points / s")
    ax.legend()
    ax.set_title("Hermes 2016 flow curve, 10 volume fractions")
    png = save_figure(fig, out, "flow_curve_throughput.png")
    summary = (f"Machine: {machine_description()}. Scalar reference: {ref_rate:.3g} points/s "
               f"(brentq loop, {taus_ref.size * phis.size} points). Vectorised and scalar shear rates "
               f"agree to {agree:.1e} relative. Medians of repeated runs in the same process.")
    return BenchResult(summary, rows, [
        (">= 1e5 points/s", f"{best['points_per_s']:.3g} points/s ({best['points']} points)",
         best["points_per_s"] >= 1e5),
        (">= 50x the scalar loop", f"{best['speed-up vs loop']:.0f}x", best["speed-up vs loop"] >= 50),
        ("vectorised = scalar to 1e-10", f"{agree:.1e}", agree <= 1e-10)], [png])


def _flowing_states(m, n, rng):
    """Points in steady dilatant shear flow at random rates, stressed slightly off the steady state."""
    phi = rng.uniform(0.40, 0.50, n)
    taus = 10.0 ** rng.uniform(-2, 3, n)
    st = r.steady_state_stress(taus, phi, m)
    sig = np.zeros((n, 3, 3))
    sig[:, 0, 1] = sig[:, 1, 0] = st.taubar
    sig -= (st.pressure * 0.999)[:, None, None] * np.eye(3)
    L = np.zeros((n, 3, 3))
    L[:, 0, 1] = st.shear_rate * 1.01
    return sig, L, phi, st.f


def _sheared_sequence(m, n, steps, dt_strain, mode):
    """``steps`` steps of sheared material points (steady flowing states sheared 2% faster, a
    little volume change): returns (time per step [s], residual evaluations per flowing point).
    mode: "bracket" (bracket-only reference), "cold" (Newton), "warm" (Newton from the previous
    plastic rate, kept between steps as a caller would)."""
    sig, L, phi, f = _flowing_states(m, n, np.random.default_rng(7))
    L[:, 0, 1] *= 1.02 / 1.01
    L[:, 1, 1] = np.random.default_rng(8).normal(0, 1e-3, n) * L[:, 0, 1]
    P = kernel_parameters(m)
    dt = dt_strain / float(np.median(L[:, 0, 1]))
    g = L[:, 0, 1].copy()
    so, o = np.empty_like(sig), np.empty((n, NOUT))
    kw = dict(newton=False) if mode == "bracket" else {}
    update_points_serial(sig, L, phi, f, dt, P, so, o, **kw)                 # compile
    times, evals = [], []
    for _ in range(steps):
        if mode == "warm":
            kw = dict(g_prev=g)
        t0 = time.process_time()
        update_points_serial(sig, L, phi, f, dt, P, so, o, **kw)
        times.append(time.process_time() - t0)
        flow = o[:, 12] == 2
        evals.append(o[flow, 13].mean() if flow.any() else 0.0)
        sig, f, g = so.copy(), o[:, 0].copy(), o[:, 1].copy()
    return float(np.median(times)), float(np.mean(evals))


@benchmark("rheology", "bench_local_update_throughput",
           "Table 8 local update: material points per second (numba, parallel), Newton against "
           "the bracket-only solve, cold and warm starts")
def local_update_throughput(out: Path, quick: bool) -> BenchResult:
    m = r.get_material("annular_shear")
    P = kernel_parameters(m)
    rng = np.random.default_rng(0)
    n = 20000 if quick else 400000
    A = rng.normal(size=(n, 3, 3))
    scale = 10.0 ** rng.uniform(-2, 4, n)[:, None, None]
    sig_r = (A + A.transpose(0, 2, 1)) * scale * 0.2 - np.eye(3) * scale
    L_r = rng.normal(size=(n, 3, 3)) * 10.0 ** rng.uniform(-2, 2, n)[:, None, None]
    f_r = rng.uniform(0, 0.3, n)
    phi_r = rng.uniform(0.40, 0.54, n)
    sets = {"random states (all cases)": (sig_r, L_r, phi_r, f_r),
            "steady shear flow (dilatant solve)": _flowing_states(m, n, rng)}
    rows = []
    for label, (sig, L, phi, f) in sets.items():
        res = {}
        so, o = np.empty_like(sig), np.empty((n, NOUT))
        update_points(sig, L, phi, f, 1e-5, P, so, o)                          # compile / warm up
        t_par = timed(lambda: update_points(sig, L, phi, f, 1e-5, P, so, o), 5)[0]
        for mode, kw in (("bracket", dict(newton=False)), ("newton", {})):
            # the algorithms compared serially in process CPU time (robust to other jobs)
            so, o = np.empty_like(sig), np.empty((n, NOUT))
            update_points_serial(sig, L, phi, f, 1e-5, P, so, o, **kw)
            t = timed(lambda: update_points_serial(sig, L, phi, f, 1e-5, P, so, o, **kw), 5,
                      time.process_time)[0]
            res[mode] = (t, float(o[o[:, 12] == 2, 13].mean()) if np.any(o[:, 12] == 2) else 0.0, o)
        o = res["newton"][2]
        cases = {c: float(np.mean(o[:, 12] == c)) for c in (0, 1, 2, 3)}
        rows.append({"states": label, "points": n, "median_s": t_par,
                     "points_per_s": n / t_par,
                     "speed-up vs bracket": res["bracket"][0] / res["newton"][0],
                     "evaluations per flowing point (bracket)": res["bracket"][1],
                     "evaluations per flowing point (Newton)": res["newton"][1],
                     "elastic/separated/shear/compaction": "/".join(f"{cases[c]:.2f}" for c in cases)})
    ns, steps = (5000, 5) if quick else (100000, 20)
    seq = {mode: _sheared_sequence(m, ns, steps, 2e-3, mode) for mode in ("bracket", "cold", "warm")}
    for mode in ("cold", "warm"):
        rows.append({"states": f"sheared material points, {steps} steps ({mode} start)", "points": ns,
                     "median_s": seq[mode][0], "points_per_s": ns / seq[mode][0],
                     "speed-up vs bracket": seq["bracket"][0] / seq[mode][0],
                     "evaluations per flowing point (bracket)": seq["bracket"][1],
                     "evaluations per flowing point (Newton)": seq[mode][1],
                     "elastic/separated/shear/compaction": ""})
    summary = (f"Machine: {machine_description()}. points_per_s: update_points (parallel) on {n} "
               f"points, dt = 1e-5 s, annular_shear material, wall-time medians of 5 runs after "
               f"warm-up; speed-ups: the serial build in process CPU time. Reference in the same "
               f"process: the bracket-only solve (newton=False: bracket expansion + Brent, today's "
               f"algorithm before the Newton start). Sheared material points: {ns} points in steady "
               f"flow sheared 2% faster, {steps} steps of 0.2% strain, median serial step CPU time; the warm "
               f"start passes each point's previous plastic rate.")
    return BenchResult(summary, rows, [(f"throughput ({q['states']})",
                                        f"{q['points_per_s']:.3g} points/s, "
                                        f"{q['speed-up vs bracket']:.2f} x the bracket-only solve, "
                                        f"evaluations/flowing point "
                                        f"{q['evaluations per flowing point (bracket)']:.2f} -> "
                                        f"{q['evaluations per flowing point (Newton)']:.2f}",
                                        q["speed-up vs bracket"] >= 1.0) for q in rows])
