"""Benchmarks of the shear1d tier: speed of the fast Fig. 3 case, cost against cell count, and
the work-precision chart of IDA against the explicit scheme (with where the explicit scheme
fails). Reference methods are timed in the same process; medians are reported."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from runkit.plotting import plt
from shear1d.integrate import solve, stable_time_step
from shear1d.scenes import annular_shear_jamming, summarize

from .framework import BenchResult, benchmark, save_figure, timed
from .report import machine_description

FAST = 84e-3


def _warm_up():
    """Compile (or load) every numba kernel once, outside the timings."""
    pb, t_end = annular_shear_jamming(FAST, n_cells=8, rotation=0.01)
    solve(pb, t_end, n_out=2)
    solve(pb, t_end, method="explicit", n_out=2)
    solve(pb, t_end, method="dae", n_out=2)


def _front_speed(res) -> float:
    return float(summarize(res)["front_speed_m_per_s"])


@benchmark("shear1d", "shear1d_fig3_speed",
           "Fast Fig. 3 case (84 mm/s, to 0.31 rad) at 800 cells: the full-law DAE against the "
           "explicit method")
def fig3_speed(out: Path, quick: bool) -> BenchResult:
    _warm_up()
    n, reps = (100, 3) if quick else (800, 3)
    pb, t_end = annular_shear_jamming(FAST, n_cells=n)
    rows, medians, speeds = [], {}, {}
    for method in ("dae", "explicit"):
        r = reps if method == "dae" or n <= 200 else 1
        med, times, res = timed(lambda: solve(pb, t_end, method=method, n_out=310), r)
        medians[method] = med
        speeds[method] = _front_speed(res)
        rows.append(dict(method=method, cells=n, median_s=med, min_s=min(times), max_s=max(times),
                         runs=r, front_speed_m_per_s=speeds[method],
                         front_over_explicit=None, front_r2=summarize(res)["front_fit_r2"],
                         load_average_1min=os.getloadavg()[0],
                         stats=", ".join(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}"
                                         for k, v in res.stats.items())))
    for r in rows:
        r["front_over_explicit"] = r["front_speed_m_per_s"] / speeds["explicit"]
    ratio = medians["dae"] / medians["explicit"]
    dev = speeds["dae"] / speeds["explicit"] - 1
    return BenchResult(
        summary=f"{machine_description()} (2 cores shared with other jobs, under load: read the "
                f"ratio). Fast Fig. 3 case, {n} cells, 310 outputs, locked mixture; both methods "
                f"in this process after a warm-up compile, medians of {rows[0]['runs']} (dae) "
                f"and {rows[1]['runs']} (explicit) run(s). dae (the full Table 8 law as a smooth "
                f"DAE on IDA, rtol 1e-4) {medians['dae']:.2f} s, explicit (the local update "
                f"stepped at half the stability limit) {medians['explicit']:.2f} s: dae/explicit "
                f"= {ratio:.3f}; front speeds {speeds['dae']:.4g} (dae) and "
                f"{speeds['explicit']:.4g} m/s (explicit), {dev:+.2%}.",
        rows=rows,
        targets=[(f"fast Fig. 3 case at {n} cells in under 10 s (dae; the machine is shared: "
                  "read the dae/explicit ratio)",
                  f"{medians['dae']:.2f} s (explicit {medians['explicit']:.2f} s, ratio "
                  f"{ratio:.3f})", medians["dae"] < 10.0),
                 ("dae front speed the explicit full law's within 2 %", f"{dev:+.2%}",
                  abs(dev) <= 0.02)])


@benchmark("shear1d", "shear1d_cost_vs_cells",
           "Cost against cell count, fast Fig. 3 case: the full-law DAE beside the explicit "
           "method (and the rate-form IDA up to 200 cells), 50-800 cells")
def cost_vs_cells(out: Path, quick: bool) -> BenchResult:
    _warm_up()
    cells = [25, 50, 100] if quick else [50, 100, 200, 400, 800]
    ida_max = 100 if quick else 200          # the rate form costs ~cells^2.4: 81-222 s at 800
    methods = ("dae", "explicit", "ida")
    rows, data, speed = [], {k: {} for k in methods}, {k: {} for k in methods}
    loads = []
    for n in cells:
        pb, t_end = annular_shear_jamming(FAST, n_cells=n)
        for method in methods:
            if method == "ida" and n > ida_max:
                continue
            reps = 3 if method == "dae" or n <= 200 else 1
            load0 = os.getloadavg()[0]
            med, times, res = timed(lambda: solve(pb, t_end, method=method, n_out=62), reps)
            data[method][n] = med
            speed[method][n] = _front_speed(res)
            load = 0.5 * (load0 + os.getloadavg()[0])
            loads.append(load)
            rows.append(dict(cells=n, method=method, median_s=med, runs=reps,
                             min_s=min(times), max_s=max(times),
                             over_explicit_time=None,
                             front_speed_m_per_s=speed[method][n],
                             front_over_explicit=None, load_average_1min=load,
                             steps_or_nfev=res.stats.get("steps", res.stats.get("nfev")),
                             njev=res.stats.get("njev")))
        for r in rows:
            if r["cells"] == n:
                r["front_over_explicit"] = r["front_speed_m_per_s"] / speed["explicit"][n]
                r["over_explicit_time"] = r["median_s"] / data["explicit"][n]

    def slope(k):
        ns = sorted(data[k])
        return float(np.polyfit(np.log(ns), np.log([data[k][n] for n in ns]), 1)[0])

    slopes = {k: slope(k) for k in methods}
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.4))
    for k, c in zip(methods, ("C2", "C3", "C0")):
        ns = sorted(data[k])
        lab = {"dae": "dae (full law, smooth DAE)", "explicit": "explicit (full law)",
               "ida": "ida (full law, rate form)"}[k]
        ax[0].loglog(ns, [data[k][n] for n in ns], "o-", color=c,
                     label=f"{lab}: slope {slopes[k]:.2f}")
        ax[1].semilogx(ns, [speed[k][n] for n in ns], "o-", color=c, label=lab)
    ax[0].loglog(cells, data["dae"][cells[0]] * np.array(cells) / cells[0], "k--", lw=0.8,
                 label="slope 1")
    ax[0].loglog(cells, data["explicit"][cells[0]] * (np.array(cells) / cells[0]) ** 2, "k:",
                 lw=0.8, label="slope 2")
    ax[0].set(xlabel="cells", ylabel="wall time [s] (median, loaded machine)",
              title="fast Fig. 3 case to 0.31 rad (locked)")
    ax[1].set(xlabel="cells", ylabel="front speed [m/s]", title="front speed of the same runs")
    for a in ax:
        a.legend(fontsize=8)
        a.grid(alpha=0.3)
    ratios = ", ".join(f"{n}: {data['dae'][n] / data['explicit'][n]:.3f}" for n in cells)
    front = {n: speed["dae"][n] / speed["explicit"][n] for n in cells}
    n_big = cells[-1]

    def series(k):
        return ", ".join(f"{data[k][n]:.2f}" for n in sorted(data[k]))

    def speeds(k):
        return ", ".join(f"{speed[k][n]:.4f}" for n in sorted(speed[k]))

    return BenchResult(
        summary=f"{machine_description()}. Wall time of the fast Fig. 3 case against cells, all "
                f"methods in this process, interleaved per cell count, medians of 3 runs (1 for "
                f"the explicit method at 400 and 800 cells), under load (1-min load average "
                f"{min(loads):.1f}-{max(loads):.1f} on 2 cores: read the ratios). Seconds at "
                f"{', '.join(map(str, cells))} cells: dae {series('dae')}; explicit "
                f"{series('explicit')}; ida (rate form, to {ida_max} cells) {series('ida')}. "
                f"Log-log slopes: dae {slopes['dae']:.2f}, explicit {slopes['explicit']:.2f} "
                f"(its step shrinks with dx: elastic shear-wave limit dx/c, so ~2 is expected), "
                f"ida {slopes['ida']:.2f}. dae/explicit time ratios: {ratios}. Front speeds [m/s]: "
                f"dae {speeds('dae')}; explicit {speeds('explicit')}; ida {speeds('ida')}; "
                f"dae/explicit {min(front.values()):.4f}-{max(front.values()):.4f}. All three "
                f"integrate the full Table 8 law (dae: continuous form, compaction regularised "
                f"with K4 = 0.1, see shear1d.dae).",
        rows=rows,
        targets=[("dae cost about linear in the cell count (log-log slope <= 1.3, "
                  f"{cells[0]}-{n_big} cells)", f"slope {slopes['dae']:.2f}",
                  slopes["dae"] <= 1.3),
                 (f"dae at {n_big} cells under 10 s (loaded machine)",
                  f"{data['dae'][n_big]:.2f} s (explicit {data['explicit'][n_big]:.2f} s)",
                  data["dae"][n_big] < 10.0),
                 ("dae front speed the explicit full law's within 2 % at every cell count",
                  ", ".join(f"{n}: {x:.4f}" for n, x in front.items()),
                  all(abs(x - 1) <= 0.02 for x in front.values()))],
        figures=[save_figure(fig, out, "cost_vs_cells.png", tight=True)],
        notes={"njev": "the explicit scheme forms no Jacobian"})


@benchmark("shear1d", "shear1d_work_precision",
           "Work-precision: IDA (several rtol) against the explicit scheme (several dt)")
def work_precision(out: Path, quick: bool) -> BenchResult:
    _warm_up()
    n = 50 if quick else 100
    pb, _ = annular_shear_jamming(FAST, n_cells=n)
    t_end = 0.15 * pb.grid.inner / FAST                   # the growth phase of the band
    lim = stable_time_step(pb)
    dt_ref = lim["dt"] / 16
    ref_time, _, ref = timed(lambda: solve(pb, t_end, method="explicit", dt=dt_ref, n_out=15), 1)
    v_ref = ref.field("v")

    def error(res):
        return float(np.max(np.abs(res.field("v") - v_ref)) / FAST)

    rows = []
    for rtol in ([1e-3, 1e-4, 1e-5] if quick else [1e-3, 3e-4, 1e-4, 3e-5, 1e-5]):
        med, _, res = timed(lambda: solve(pb, t_end, n_out=15, rtol=rtol), 1)
        rows.append(dict(method="ida", setting=f"rtol {rtol:g}", dt_over_limit=None,
                         seconds=med, error=error(res), failed=False))
    for frac in ([1.0, 0.5, 0.25] if quick else [1.0, 0.5, 0.25, 0.125]):
        med, _, res = timed(lambda: solve(pb, t_end, method="explicit", dt=frac * lim["dt"],
                                           n_out=15), 1)
        rows.append(dict(method="explicit", setting=f"dt {frac:g} x limit", dt_over_limit=frac,
                         seconds=med, error=error(res), failed=False))
    first_fail = None
    for frac in (1.05, 1.2, 1.5, 1.75, 2.0, 3.0):
        t0 = time.perf_counter()
        why = "the run diverged: its velocity is not finite, so it has no error"
        try:
            res = solve(pb, t_end, method="explicit", dt=frac * lim["dt"], n_out=15,
                        check_stability=False)
            err = error(res)
        except RuntimeError as exc:
            err = float("nan")
            why = ("the run diverged and stopped, so it has no error ("
                   f"{' '.join(str(exc).split())[:160]})")
        failed = not np.isfinite(err) or err > 10
        rows.append(dict(method="explicit", setting=f"dt {frac:g} x limit (unchecked)",
                         dt_over_limit=frac, seconds=time.perf_counter() - t0,
                         error=err if np.isfinite(err) else None,
                         error_note=None if np.isfinite(err) else why, failed=failed))
        if failed and first_fail is None:
            first_fail = frac
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    ida = [r for r in rows if r["method"] == "ida"]
    exp = sorted((r for r in rows if r["method"] == "explicit" and not r["failed"]),
                 key=lambda r: r["dt_over_limit"])
    bad = [r for r in rows if r["failed"]]
    for rs, style, colour, label in ((ida, "o-", "C0", "IDA"), (exp, "s-", "C3", "explicit")):
        ax[0].loglog([r["seconds"] for r in rs], [r["error"] for r in rs], style, color=colour,
                     label=label)
        for r in rs:
            ax[0].annotate(r["setting"], (r["seconds"], r["error"]), fontsize=7)
    ax[0].set(xlabel="wall time [s]", ylabel="max |v - v_ref| / u_i",
              title=f"fast Fig. 3, {n} cells, to 0.15 rad")
    ax[0].legend()
    ax[1].loglog([r["dt_over_limit"] * lim["dt"] for r in exp], [r["error"] for r in exp], "s-",
                 color="C3", label="explicit error")
    for r in bad:
        ax[1].axvline(r["dt_over_limit"] * lim["dt"], color="k", ls=":", lw=1)
        ax[1].text(r["dt_over_limit"] * lim["dt"], 0.5, "diverged", rotation=90, fontsize=7,
                   transform=ax[1].get_xaxis_transform())
    ax[1].axvline(lim["dt"], color="C2", lw=1.5, label=f"stability limit {lim['dt']:.2e} s")
    ax[1].set(xlabel="dt [s]", ylabel="max |v - v_ref| / u_i", title="explicit step size")
    ax[1].legend(fontsize=8)
    best_exp = min(exp, key=lambda r: r["seconds"])
    return BenchResult(
        summary=f"{machine_description()}. Fast Fig. 3 case, {n} cells, 0-0.15 rad; reference: "
                f"explicit with dt = limit/16 ({ref_time:.2f} s). Error = max over 15 outputs of "
                f"max |v - v_ref|/u_i. Explicit stability limit {lim['dt']:.3g} s (elastic "
                f"{lim['dt_wave']:.3g} s, viscous {lim['dt_viscous']:.3g} s); first divergence at "
                f"{first_fail} x the limit. The explicit scheme steps the exact Table 8 local "
                f"update; IDA integrates its rate form, whose regularisation shrinks with rtol.",
        rows=rows,
        targets=[("explicit scheme diverges beyond its stated stability limit (first failure "
                  "within 3x the limit) and is refused there by default",
                  f"first divergence at {first_fail} x limit", first_fail is not None),
                 ("IDA error decreases with rtol",
                  ", ".join(f"{r['setting']}: {r['error']:.2e}" for r in ida),
                  ida[-1]["error"] < ida[0]["error"]),
                 ("both methods reach 1 % of u_i",
                  f"IDA best {min(r['error'] for r in ida):.2e}; explicit best "
                  f"{min(r['error'] for r in exp):.2e} (fastest explicit {best_exp['seconds']:.2f}"
                  f" s)", min(r['error'] for r in ida) < 0.01 and min(r['error'] for r in exp)
                  < 0.01)],
        figures=[save_figure(fig, out, "work_precision.png", tight=True)],
        notes={"dt_over_limit": "IDA chooses its own (adaptive) steps: no fixed dt"})
