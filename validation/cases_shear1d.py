"""Validation cases of the shear1d tier (1-D plane and annular Couette, Fig. 3).

Each case states a falsifiable criterion and measures it; ``quick=True`` uses small grids (the
test suite calls them so). Run: ``python -m validation report --out DIR --tier shear1d``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

import rheology
from rheometer import creep
from runkit.io import atomic_write_json
from runkit.plotting import plt
from shear1d import analysis, kernels, plots
from shear1d.analytic import annular_steady, plane_couette_startup
from shear1d.integrate import solve
from shear1d.model import Couette
from shear1d.scenes import SceneRun, annular_shear_jamming, plane_couette
from shear1d.summary import NULLABLE, rotation_of, summarize

from .framework import Verdict, case, save_figure, slope_plot

TIER = "shear1d"
FAST, SLOW = 84e-3, 0.84e-3
#: phi of the Newtonian checks: the granular stress ~ eta0 (a phi/phi_j)^2 gdot is 1e-12 of the
#: fluid's, so the suspension is the Newtonian fluid eta0 (1 + 5/2 phi) to round-off.
PHI_NEWTONIAN = 1e-6


def _convergence(errors) -> tuple[np.ndarray, str]:
    """Observed orders log2(e_h/e_h/2) and the 'errors ...; orders ...' text of a refinement."""
    e = np.asarray(errors, dtype=float)
    orders = np.log2(e[:-1] / e[1:])
    return orders, (f"errors {', '.join(f'{e:.2e}' for e in errors)}; orders "
                    f"{', '.join(f'{o:.3f}' for o in orders)}")


# ----------------------------------------------------------------------------- Newtonian
@case(TIER, "shear1d_couette_startup_order",
      "Newtonian start-up of plane Couette flow against the analytic series: 2nd order in space")
def couette_startup_order(out: Path, quick: bool) -> Verdict:
    gap, speed = 1e-2, 1e-2
    cells = [8, 16, 32] if quick else [16, 32, 64, 128]
    errors, profiles = [], []
    for n in cells:
        pb = plane_couette(speed, gap=gap, n_cells=n, phi0=PHI_NEWTONIAN)
        m = pb.material
        nu = m.eta0 * (1 + 2.5 * PHI_NEWTONIAN) / m.rho_f
        t = 0.05 * gap ** 2 / nu
        res = solve(pb, t, n_out=1, rtol=1e-9)
        v = res.field("v")[-1]
        exact = plane_couette_startup(pb.grid.faces, t, gap, speed, nu)
        errors.append(float(np.sqrt(np.mean((v - exact) ** 2)) / speed))
        profiles.append((pb.grid.faces, v, exact))
    orders, text = _convergence(errors)
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    y, v, ex = profiles[-1]
    ax[0].plot(y * 1e3, ex / speed, "k-", label="analytic series")
    ax[0].plot(y * 1e3, v / speed, "o", ms=3, label=f"shear1d, {cells[-1]} cells")
    ax[0].set(xlabel="y [mm]", ylabel="v/U", title="t = 0.05 H^2/nu")
    ax[0].legend()
    slope_plot(ax[1], cells, {"RMS error / U": (errors, "o-")}, -2, "cells", "error")
    png = save_figure(fig, out, "couette_startup.png", tight=True)
    return Verdict(criterion="observed order log2(e_h/e_h/2) > 1.9 for every refinement "
                             "(IDA rtol 1e-9, phi = 1e-6)",
                   measured=text, passed=bool(np.all(orders > 1.9)), figures=[png])


@case(TIER, "shear1d_annular_newtonian_steady",
      "Steady Newtonian annular Couette profile v = A r + B/r: 2nd order in space")
def annular_newtonian_steady(out: Path, quick: bool) -> Verdict:
    cells = [8, 16, 32] if quick else [16, 32, 64, 128]
    speed = 1e-2
    errors = []
    for n in cells:
        pb, _ = annular_shear_jamming(speed, n_cells=n, phi0=PHI_NEWTONIAN)
        g, m = pb.grid, pb.material
        nu = m.eta0 * (1 + 2.5 * PHI_NEWTONIAN) / m.rho_f
        res = solve(pb, 3.0 * g.gap ** 2 / nu, n_out=1, rtol=1e-9)
        v = res.field("v")[-1]
        exact = annular_steady(g.faces, g.inner, g.outer, speed)
        errors.append(float(np.max(np.abs(v - exact)) / speed))
    orders, text = _convergence(errors)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(g.faces * 1e3, exact / speed, "k-", label="A r + B/r")
    ax.plot(g.faces * 1e3, v / speed, "o", ms=3, label=f"shear1d, {cells[-1]} cells, t = 3 gap^2/nu")
    ax.set(xlabel="r [mm]", ylabel="v/u_i")
    ax.legend()
    return Verdict(criterion="max |v - (A r + B/r)|/u_i < 1e-3 on the finest grid and observed "
                             "order > 1.9 (t = 3 gap^2/nu, phi = 1e-6)",
                   measured=text, passed=bool(errors[-1] < 1e-3 and np.all(orders > 1.9)),
                   figures=[save_figure(fig, out, "annular_steady.png")])


# ----------------------------------------------------------------------------- narrow gap vs 0-D
def _narrow_gap(stress: float, t_end: float, n_cells: int = 16, n_out: int = 100,
                rate_step: float | None = None):
    """1 mm plane gap driven by a mixture shear stress: (problem, result, mean shear rate)."""
    pb = plane_couette(stress=stress, gap=1e-3, n_cells=n_cells, rate_step=rate_step)
    res = solve(pb, t_end, n_out=n_out, rtol=1e-4)
    v = res.field("v")
    return pb, res, (v[:, 0] - v[:, -1]) / pb.grid.gap


@case(TIER, "shear1d_narrow_gap_steady",
      "Narrow gap at imposed stress: steady shear rate and structure match the 0-D steady state")
def narrow_gap_steady(out: Path, quick: bool) -> Verdict:
    m = rheology.get_material("annular_shear")
    stresses = [2.0, 20.0] if quick else [2.0, 10.0, 20.0]
    rows, worst = [], 0.0
    for tau in stresses:
        pb, res, rate = _narrow_gap(tau, 400.0, n_out=40, rate_step=1e-2)
        st = rheology.steady_states_mixture_stress(tau, pb.phi0, m)
        k = int(np.flatnonzero(st.stable)[0])
        err_rate = abs(rate[-1] / st.shear_rate[k] - 1.0)
        err_f = abs(res.field("f")[-1].mean() / st.f[k] - 1.0)
        worst = max(worst, err_rate, err_f)
        rows.append(dict(stress_Pa=tau, shear_rate_1d=float(rate[-1]),
                         shear_rate_0d=float(st.shear_rate[k]), rel_err_rate=float(err_rate),
                         f_1d=float(res.field("f")[-1].mean()), f_0d=float(st.f[k]),
                         rel_err_f=float(err_f)))
    flow = rheology.steady_state_stress(np.logspace(-1, 2, 200), 0.505, m)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.loglog(flow.shear_rate, flow.shear_stress, "k-", label="rheology steady flow curve")
    ax.loglog([r["shear_rate_1d"] for r in rows], stresses, "o", label="shear1d narrow gap, t = 400 s")
    ax.set(xlabel="shear rate [1/s]", ylabel="mixture shear stress [Pa]", title="phi = 0.505")
    ax.legend()
    png = save_figure(fig, out, "narrow_gap_steady.png")
    return Verdict(criterion="relative difference of the steady shear rate and f from "
                             "rheology.steady_states_mixture_stress < 1e-3 (1 mm gap, 16 cells, "
                             "t = 400 s; rate-form step fixed at 10 ms: fixed points do not "
                             "depend on it)",
                   measured=f"worst {worst:.2e}: " + "; ".join(
                       f"{r['stress_Pa']:g} Pa: {r['shear_rate_1d']:.6g} vs "
                       f"{r['shear_rate_0d']:.6g} 1/s, f {r['f_1d']:.5f} vs {r['f_0d']:.5f}"
                       for r in rows),
                   passed=bool(worst < 1e-3), figures=[png], details=json.dumps(rows, indent=1))


@case(TIER, "shear1d_narrow_gap_creep",
      "Narrow gap at imposed stress: creep transient matches the 0-D rheometer (rheometer.creep)")
def narrow_gap_creep(out: Path, quick: bool) -> Verdict:
    tau, t_end = 10.0, 300.0 if not quick else 60.0
    pb, res, rate = _narrow_gap(tau, t_end, n_out=150)
    m = pb.material
    ref = creep(m, pb.phi0, tau, t_end, G=m.G, K0=m.K0, points=400)
    t_ref, r_ref = ref["time_s"].to_numpy(), ref["shear_rate_per_s"].to_numpy()
    sel = res.t >= 1.0
    r0 = np.interp(res.t[sel], t_ref, r_ref)
    dev = float(np.max(np.abs(rate[sel] / r0 - 1.0)))
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.semilogx(t_ref[1:], r_ref[1:], "k-", label="rheometer.creep (0-D, reduced law)")
    ax.semilogx(res.t[1:], rate[1:], "o", ms=3, label="shear1d, 1 mm gap, full law")
    ax.set(xlabel="t [s]", ylabel="shear rate [1/s]", title=f"creep at {tau:g} Pa, phi = 0.505")
    ax.legend()
    return Verdict(criterion="max relative difference of the shear rate from rheometer.creep "
                             "< 1 % for t >= 1 s (after the elastic/inertial start)",
                   measured=f"max deviation {dev:.2e} over {sel.sum()} outputs to {t_end:g} s; "
                            f"final rate {rate[-1]:.5g} vs {r_ref[-1]:.5g} 1/s",
                   passed=bool(dev < 1e-2), figures=[save_figure(fig, out, "narrow_gap_creep.png")])


# ----------------------------------------------------------------------------- law choice (0-D)
def _full_law_homogeneous(m, phi, gdot, t_end, dt):
    """Homogeneous simple shear of one cell with the shared local update (isochoric, locked)."""
    n = int(np.ceil(t_end / dt))
    S = np.zeros((1, 4))
    S[0, :3] = -1e-3
    f = np.zeros(1)
    P = rheology.kernel_parameters(m)
    So, fo, diag = np.empty((1, 4)), np.empty(1), np.empty((1, kernels.NDIAG))
    g, z = np.array([gdot]), np.zeros(1)
    ph = np.array([phi])
    every = max(1, n // 400)
    T, TB, F = [], [], []
    for k in range(n):
        kernels.local_updates(S, f, ph, g, z, z, dt, P, 1e-3, So, fo, diag)
        S[:], f[:] = So, fo
        if k % every == 0:
            p = -S[0, :3].mean()
            dev = S[0, :3] + p
            T.append((k + 1) * dt)
            TB.append(float(np.sqrt(0.5 * np.sum(dev ** 2) + S[0, 3] ** 2)))
            F.append(float(f[0]))
    return np.array(T), np.array(TB), np.array(F)


def _reduced_law_homogeneous(m, phi, gdot, t_end):
    """The reduced (critical-state, K -> inf) law: taubar' = G (gdot - gdot_p), gdot_p algebraic."""
    def rhs(t, y):
        tb, f = max(y[0], 0.0), min(max(y[1], 0.0), 1.0)
        gp = float(rheology.critical_shear_rate(tb, phi, f, m))
        return [m.G * (gdot - gp), float(rheology.structure_rate(f, tb, gp, phi, m))]
    sol = solve_ivp(rhs, (0.0, t_end), [0.0, 0.0], method="Radau", rtol=1e-8, atol=[1e-8, 1e-12],
                    dense_output=True)
    return sol


@case(TIER, "shear1d_reduced_vs_full_law",
      "Which law the scene needs: reduced (critical-state) law against the full Table 8 update, 0-D")
def reduced_vs_full_law(out: Path, quick: bool) -> Verdict:
    m = rheology.get_material("annular_shear")
    phi, fjam = m.phi0, float(rheology.f_jam(m.phi0, m))
    gap = 23.5e-3
    rates = {"slow (0.84 mm/s over the gap)": SLOW / gap, "fast (84 mm/s over the gap)": FAST / gap}
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    notes, ok = [], True
    for ax, (label, gdot) in zip(axes, rates.items()):
        t_end = 1.0 / gdot * (20.0 if gdot < 1 else 2.0)
        dt = (2e-4 if quick else 5e-5) / gdot
        T, TB, F = _full_law_homogeneous(m, phi, gdot, t_end, dt)
        red = _reduced_law_homogeneous(m, phi, gdot, t_end)
        tb_r, f_r = red.sol(T)
        rel = np.abs(TB - tb_r) / np.maximum(tb_r, 1e-12)
        after = T * gdot >= 0.1                    # past the elastic start from zero pressure
        agree = float(np.max(rel[after & (F <= 0.5 * fjam)]))
        late = {q: float(np.max(rel[after & (F <= q * fjam)])) for q in (0.7, 0.9)}
        ratio = float(tb_r[-1] / TB[-1])
        ax.semilogy(T * gdot, TB, "C0-", label="full Table 8 local update (K = 8.3e5 Pa)")
        ax.semilogy(T * gdot, tb_r, "C3--", label="reduced law (pressure at critical state)")
        ax.set(xlabel="strain", ylabel="granular shear stress [Pa]",
               title=f"{label}: {gdot:.3g} 1/s")
        ax2 = ax.twinx()
        ax2.plot(T * gdot, F / fjam, "C2:", label="f/f_jam (full)")
        ax2.set_ylabel("f / f_jam")
        ax.legend(fontsize=7, loc="upper left")
        notes.append(f"{label}: differ by {agree:.1e} while f <= f_jam/2, by {late[0.7]:.1e} "
                     f"while f <= 0.7 f_jam, {late[0.9]:.1e} while f <= 0.9 f_jam; final f/f_jam "
                     f"{F[-1] / fjam:.4f}; final stress reduced/full = {ratio:.3g} "
                     f"(reduced elastic strain taubar/G = {tb_r[-1] / m.G:.2%})")
        if gdot > 1:
            ok &= agree < 0.02 and F[-1] > 0.99 * fjam and ratio > 10
        else:
            ok &= agree < 1e-4
    png = save_figure(fig, out, "reduced_vs_full.png", tight=True)
    return Verdict(criterion="homogeneous isochoric shear from rest, strain >= 0.1: the reduced law "
                             "is the K -> inf limit of the full law, so they agree (within 1e-4 "
                             "at the slow rate; within 2 % at the fast rate while f <= f_jam/2); "
                             "at the fast rate, once f -> f_jam, the reduced law's elastic stress "
                             "exceeds the full law's dilatancy-limited one by > 10x: the scene "
                             "needs the full law with its pressure dynamics",
                   measured="; ".join(notes), passed=bool(ok), figures=[png])


# ----------------------------------------------------------------------------- Fig. 3
def _fig3(u, quick, mode="locked", n_cells=None, rate_step=None):
    pb, t_end = annular_shear_jamming(u, n_cells=n_cells or (60 if quick else 200), mode=mode)
    if rate_step is not None:
        pb = Couette(pb.material, pb.grid, mode=mode, wall_speed=u, rate_step=rate_step)
    res = solve(pb, t_end, n_out=155 if quick else 310)
    s = summarize(res)
    s["wall_time_s"] = res.wall_time          # for the verdicts (not in the scene's files)
    return res, s


@case(TIER, "shear1d_fig3_slow_newtonian",
      "Fig. 3, u_i = 0.84 mm/s: the profile approaches the Newtonian one")
def fig3_slow(out: Path, quick: bool) -> Verdict:
    res, s = _fig3(SLOW, quick)
    dev = s["newtonian_deviation_max_over_u"]
    png = plots.velocity_profiles(out / "slow_profiles.png", [SceneRun("slow", res, s)])
    atomic_write_json(out / "summary.json", s, nullable=NULLABLE)
    passed = all(d <= 0.01 for d in dev.values()) and s["f_max"] < 0.05 * s["f_jam"]
    return Verdict(criterion="max |v - v_Newtonian|/u_i <= 0.01 at 0.1, 0.2 and 0.31 rad "
                             "(v_Newtonian = A r + B/r, steady) and no jamming (f < 0.05 f_jam)",
                   measured=", ".join(f"{k} rad: {v:.2e}" for k, v in dev.items())
                            + f"; f_max/f_jam = {s['f_max'] / s['f_jam']:.2e}; "
                            f"{s['n_cells']} cells, {s['wall_time_s']:.2f} s",
                   passed=bool(passed), figures=[png])


@case(TIER, "shear1d_fig3_fast_front",
      "Fig. 3, u_i = 84 mm/s: a nearly rigid jammed band grows at constant speed; flow stops")
def fig3_fast(out: Path, quick: bool) -> Verdict:
    res, s = _fig3(FAST, quick)
    run = SceneRun("fast", res, s)
    figs = [plots.velocity_profiles(out / "fast_profiles.png", [run]),
            plots.front_positions(out / "front.png", [run]),
            plots.run_fields(out / "fields.png", run)]
    atomic_write_json(out / "summary.json", s, nullable=NULLABLE)
    wall, stop = s["front_at_wall_rotation_rad"], s["flow_stopped_rotation_rad"]
    g = res.problem.grid
    newt = annular_steady(g.faces, g.inner, g.outer, FAST)
    mid = s["front_fit_intercept_m"] + s["front_speed_m_per_s"] * 0.5 * (
        s["front_fit_rotation_rad"][0] + s["front_fit_rotation_rad"][1]) * g.inner / FAST
    newt_rigidity = analysis.band_rigidity(g, newt, FAST, mid)
    passed = (s["front_fit_r2"] >= 0.95 and s["band_rigidity_mean"] >= 0.75
              and wall is not None and stop is not None and 0 <= stop - wall <= 0.05)
    return Verdict(
        criterion="front (v/(omega r) = 1/2) linear in time, R^2 >= 0.95 while it crosses the gap; "
                  "band nearly rigid: mean v/(omega r) between bob and front >= 0.75; the band "
                  "(f = f_jam/2) "
                  "reaches 90 % of the gap, and the bulk flow stops (mean |v|/u_i beyond 20 % of "
                  "the gap < 0.1) within 0.05 rad after",
        measured=f"front speed {s['front_speed_m_per_s']:.3g} m/s = {s['front_speed_over_u_inner']:.2f}"
                 f" u_i, R^2 = {s['front_fit_r2']:.4f} over {s['front_fit_rotation_rad'][0]:.3f}-"
                 f"{s['front_fit_rotation_rad'][1]:.3f} rad; band rigidity mean "
                 f"{s['band_rigidity_mean']:.3f} (min {s['band_rigidity_min']:.3f}; the steady "
                 f"Newtonian profile gives {newt_rigidity:.3f} over the band at mid-window); "
                 f"band at wall "
                 f"{_rad(wall)}, flow stopped {_rad(stop)}; {s['n_cells']} cells, "
                 f"{s['wall_time_s']:.2f} s",
        passed=bool(passed), figures=figs)


def _rad(x) -> str:
    return "never" if x is None else f"{x:.3f} rad"


@case(TIER, "shear1d_fig3_modes",
      "Fig. 3: two-phase Darcy migration against the locked mixture")
def fig3_modes(out: Path, quick: bool) -> Verdict:
    runs, rows = [], []
    for u in (FAST, SLOW):
        # both modes with the two-phase rate-form step, so that only the migration differs
        pb, _ = annular_shear_jamming(u, n_cells=60 if quick else 200, mode="two-phase")
        delta = pb.rate_step_at(1e-4, 0.0)
        for mode in ("locked", "two-phase"):
            res, s = _fig3(u, quick, mode=mode, rate_step=delta)
            runs.append(SceneRun(f"{u}-{mode}", res, s))
            rows.append(s)
    fast_l, fast_t, slow_l, slow_t = rows
    d_speed = abs(fast_t["front_speed_m_per_s"] / fast_l["front_speed_m_per_s"] - 1)
    res_l, res_t = runs[0].result, runs[1].result
    v_diff = float(np.max(np.abs(res_t.field("v") - res_l.field("v"))) / FAST)
    slow_diff = float(np.max(np.abs(runs[3].result.field("v") - runs[2].result.field("v"))) / SLOW)
    dphi = max(abs(r["phi_min"] - r["phi0"]) for r in (fast_t, slow_t))
    dphi_max = max(abs(r["phi_max"] - r["phi0"]) for r in (fast_t, slow_t))
    drift = max(fast_t["solid_volume_drift"], slow_t["solid_volume_drift"])
    png = plots.mode_comparison(out / "modes.png", runs[:2])
    passed = d_speed < 0.02 and drift < 1e-9 and slow_diff < 0.01
    return Verdict(
        criterion="migration changes little on this scene: fast front speeds of the two modes "
                  "within 2 %, slow profiles within 1 % of u_i at all times (both modes with the "
                  "same rate-form step); two-phase conserves the solids (relative drift of "
                  "sum phi V < 1e-9)",
        measured=f"fast front {fast_l['front_speed_m_per_s']:.4g} (locked) vs "
                 f"{fast_t['front_speed_m_per_s']:.4g} m/s (two-phase), {d_speed:.2%}; max |dv|/u_i"
                 f" fast {v_diff:.3f} (the post-stop oscillation), slow {slow_diff:.1e}; phi moved"
                 f" by -{dphi:.1e}/+{dphi_max:.1e}; solid drift {drift:.1e}; times "
                 f"{fast_l['wall_time_s']:.1f}/{fast_t['wall_time_s']:.1f} s (fast), "
                 f"{slow_l['wall_time_s']:.1f}/{slow_t['wall_time_s']:.1f} s (slow)",
        passed=bool(passed), figures=[png])


@case(TIER, "shear1d_ida_vs_explicit",
      "The two integrators agree on the fast Fig. 3 case (IDA rate form vs exact explicit steps)")
def ida_vs_explicit(out: Path, quick: bool) -> Verdict:
    n = 50 if quick else 100
    pb, t_end = annular_shear_jamming(FAST, n_cells=n)
    t_grow = 0.15 * pb.grid.inner / FAST                  # the growth phase, before the stop
    ref = solve(pb, t_grow, method="explicit", n_out=30)
    fr_ref = ref.front()
    rows = []
    for rtol in (3e-4, 1e-4, 3e-5):
        res = solve(pb, t_grow, n_out=30, rtol=rtol)
        err = float(np.max(np.abs(res.front() - fr_ref)) / pb.grid.gap)
        verr = float(np.max(np.abs(res.field("v") - ref.field("v"))) / FAST)
        rows.append((rtol, err, verr, res.wall_time))
    fig, ax = plt.subplots(figsize=(6, 4))
    rot = rotation_of(ref, ref.t)
    ax.plot(rot, (fr_ref - pb.grid.inner) * 1e3, "k-", lw=2, label="explicit (local update steps)")
    ax.plot(rot, (res.front() - pb.grid.inner) * 1e3, "C1--", label="IDA rtol 3e-5")
    ax.set(xlabel="bob rotation [rad]", ylabel="front - R_i [mm]")
    ax.legend()
    errs = [r[1] for r in rows]
    passed = errs[-1] < 0.01 and errs[-1] <= errs[0]
    return Verdict(criterion="front positions of IDA within 1 % of the gap of the explicit scheme "
                             "(dt = half its stability limit) at rtol 3e-5, and no worse than at "
                             "rtol 3e-4, over the growth phase (0-0.15 rad)",
                   measured="; ".join(f"rtol {r:g}: front {e:.2%} of gap, max |dv|/u_i {ve:.3f}, "
                                      f"{w:.2f} s" for r, e, ve, w in rows)
                            + f"; explicit {ref.wall_time:.2f} s, {ref.stats['steps']} steps",
                   passed=bool(passed), figures=[save_figure(fig, out, "ida_vs_explicit.png")])
