"""mpm2d swirl in axisymmetry: the annular cell of Fig. 3 as a 2-D (r, z) MPM, held against shear1d.

Two cases: the steady Newtonian annular Couette flow v = A r + B/r (analytic) under refinement,
and the fast Fig. 3 case (u_i = 84 mm/s, Table 4 ``annular_shear``, locked mixture) whose jammed
front speed is compared with shear1d's explicit method on the same radii. This module may import
both tiers (validation is above them).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from mpm2d.analytic import observed_orders
from mpm2d.scenes import annular
from runkit.plotting import plt
from shear1d.integrate import solve
from shear1d.scenes import annular_shear_jamming, summarize

from .cases_mpm2d import run_quiet
from .framework import NO_COARSER, Verdict, case, save_figure, slope_plot, write_csv

#: the paper's grid mapped onto the gap: 24 cells of 23.5/24 mm (see mpm2d.scenes.annular)
PAPER_CELLS = 24


@case("mpm2d", "mpm2d_swirl_newtonian",
      "mpm2d swirl: steady Newtonian annular Couette flow v = A r + B/r, error vs h")
def swirl_newtonian(out: Path, quick: bool) -> Verdict:
    cells = (12, 24) if quick else (12, 24, 48)
    df = pd.DataFrame([annular.newtonian_check(n) for n in cells])
    orders = observed_orders(df["h_m"].to_numpy(), df["max_error"].to_numpy())
    df["order_max_error"] = np.concatenate([[np.nan], orders])
    write_csv(out, "swirl_newtonian.csv", df, ["order_max_error"])
    fig, ax = plt.subplots(figsize=(6.5, 5))
    ax.axhline(2e-3, color="r", lw=0.8, label="target 2e-3 u_i")
    slope_plot(ax, df["h_m"] * 1e3, {"max |v_theta - (A r + B/r)| / u_i": (df["max_error"], "o-"),
                                     "rms": (df["rms_error"], "s-")}, 2, "h [mm]", "error / u_i",
               "steady Newtonian annulus R_i = 12.5 mm, R_o = 36 mm (swirl engine)",
               legend=dict(fontsize=8))
    fig_path = save_figure(fig, out, "swirl_newtonian.png")
    paper = df.loc[df["cells"] == PAPER_CELLS, "max_error"].iloc[0]
    ok = bool(paper < 2e-3) and bool(np.all(orders > 1.8))
    ok &= bool(df["max_meridional_over_u"].max() < 1e-6)
    return Verdict(
        criterion="on the paper's grid (24 cells of 0.979 mm across the 23.5 mm gap) max "
                  "|v_theta - (A r + B/r)| < 2e-3 u_i after one viscous time; observed order "
                  "> 1.8 under halving h; meridional velocity < 1e-6 u_i",
        measured=f"max error {paper:.2e} u_i at 24 cells; by h: "
                 + ", ".join(f"{n}: {e:.2e}" for n, e in zip(df['cells'], df['max_error']))
                 + "; observed orders " + ", ".join(f"{o:.2f}" for o in orders),
        passed=ok, figures=[fig_path], rows=df.to_dict("records"),
        notes={"order_max_error": NO_COARSER})


def _shear1d_front(u_inner: float, n_cells: int) -> dict:
    problem, t_end = annular_shear_jamming(u_inner, n_cells=n_cells)
    res = solve(problem, t_end, method="explicit", n_out=310)
    s = summarize(res)
    return {"front_speed_m_per_s": s["front_speed_m_per_s"],
            "front_speed_over_u_inner": s["front_speed_over_u_inner"],
            "front_fit_r2": s["front_fit_r2"], "t": res.t, "front": res.front()}


def _mpm_runs(quick: bool) -> list[dict]:
    """The mpm2d runs: (label, role, cells, rows, scene overrides). Roles: ``paper`` (the
    paper's grid, scene defaults), ``dt`` (same cells, smaller steps), ``h`` (finer cells),
    ``incompressible`` (kappa = 10 K, near shear1d's fixed-phi locked mode), ``apic`` (plain
    APIC swirl transfer, the former engine: the cause)."""
    K = 8.3e5                                  # Table 4 (annular_shear): kappa = K
    runs = [dict(label="paper grid", role="paper", cells=PAPER_CELLS, rows=2 if quick else 50,
                 set={})]
    runs += [dict(label=f"cfl {c}", role="dt", cells=PAPER_CELLS, rows=2, set={"cfl": c})
             for c in ((0.25,) if quick else (0.25, 0.125))]
    runs += [dict(label=f"{n} cells", role="h", cells=n, rows=2, set={})
             for n in ((2 * PAPER_CELLS,) if quick else (2 * PAPER_CELLS, 4 * PAPER_CELLS))]
    runs += [dict(label="kappa = 10 K", role="incompressible", cells=PAPER_CELLS, rows=2,
                  set={"kappa": 10 * K})]
    if not quick:
        runs += [dict(label=f"kappa = 10 K, {n} cells", role="incompressible h", cells=n,
                      rows=2, set={"kappa": 10 * K}) for n in (4 * PAPER_CELLS,)]
        runs += [dict(label=f"plain APIC, cfl {c}", role="apic", cells=PAPER_CELLS, rows=2,
                      set={"swirl_flip": 0.0, "cfl": c}) for c in (0.5, 0.125)]
    return runs


@case("mpm2d", "mpm2d_annular_front",
      "mpm2d swirl: Fig. 3 fast case (84 mm/s), jammed front speed vs shear1d", slow=True)
def annular_front(out: Path, quick: bool) -> Verdict:
    u = 0.084
    rows_out, hist = [], {}
    for k, run in enumerate(_mpm_runs(quick)):
        p = {"u_inner": u, "cells": run["cells"], "rows": run["rows"], **run["set"]}
        r = run_quiet(annular.setup, out / f"mpm_{k}", **p)
        s = annular.summarise(r["scene"].params, r["history"])
        hist[run["label"]] = r["history"]
        rows_out.append({"model": f"mpm2d {run['label']}", "role": run["role"],
                         "cells_across_gap": run["cells"], "rows": run["rows"],
                         "cfl": r["scene"].params["cfl"],
                         "swirl_flip": r["scene"].params["swirl_flip"],
                         "kappa_Pa": float(r["scene"].sim.sets[0].material.m.kappa),
                         "dt_s": float(r["scene"].sim.last_dt),
                         **{c: s[c] for c in ("front_speed_m_per_s", "front_speed_over_u_inner",
                                              "front_fit_r2")}})
    s1 = {n: _shear1d_front(u, n) for n in (PAPER_CELLS, 200)}
    rows_out += [{"model": f"shear1d explicit, {n} cells", "role": "shear1d",
                  "cells_across_gap": n, "rows": 1, "cfl": np.nan, "swirl_flip": np.nan,
                  "kappa_Pa": np.nan, "dt_s": np.nan,
                  **{k: s[k] for k in ("front_speed_m_per_s", "front_speed_over_u_inner",
                                       "front_fit_r2")}} for n, s in s1.items()]
    table = write_csv(out, "annular_front_speeds.csv", rows_out,
                      ["cfl", "swirl_flip", "kappa_Pa", "dt_s"])
    fig, ax = plt.subplots(figsize=(6.5, 5))
    gap = annular.R_OUTER - annular.R_INNER
    for label, h in hist.items():
        ax.plot(h["time_s"] * 1e3, (h["front_m"] - annular.R_INNER) / gap, "-",
                lw=0.8 if "APIC" in label else 1.4, label=f"mpm2d {label}")
    for n, s in s1.items():
        ax.plot(np.asarray(s["t"]) * 1e3, (np.asarray(s["front"]) - annular.R_INNER) / gap,
                "k--" if n == 200 else "k:", label=f"shear1d explicit, {n} cells")
    ax.set(xlabel="t [ms]", ylabel="(front - R_i) / gap",
           title="Fig. 3 fast case, u_i = 84 mm/s: kinematic front (v/(u_i r/R_i) = 1/2)")
    ax.legend(fontsize=7)
    fig_path = save_figure(fig, out, "annular_front.png")

    def speed(role):
        return table.loc[table["role"] == role, "front_speed_m_per_s"].to_numpy()

    ref = {n: s["front_speed_m_per_s"] for n, s in s1.items()}
    paper = float(speed("paper")[0])
    dts = np.concatenate([[paper], speed("dt")])
    hs = speed("h")
    finest = int(table.loc[table["role"] == "h", "cells_across_gap"].max())
    incomp = float(speed("incompressible")[0])
    same_h = paper / ref[PAPER_CELLS] - 1.0
    paper_vs_fine = paper / ref[200] - 1.0
    converged = float(hs[-1]) / ref[200] - 1.0
    incomp_vs_fine = incomp / ref[200] - 1.0
    dt_spread = float(dts.max() / dts.min() - 1.0)
    checks = [same_h, converged, incomp_vs_fine]
    ok = bool(all(np.isfinite(c) and abs(c) < 0.10 for c in checks))
    ok &= bool(np.isfinite(dt_spread) and dt_spread < 0.05)
    inc_h = table.loc[table["role"] == "incompressible h"]
    inc_note = "".join(f"; kappa = 10 K, {int(c)} cells: {v:.4g} m/s "
                       f"({100 * (v / ref[200] - 1):+.1f} % vs shear1d 200)"
                       for c, v in zip(inc_h["cells_across_gap"], inc_h["front_speed_m_per_s"]))
    apic = speed("apic")
    apic_note = (f"; the former plain-APIC swirl transfer: {apic[0]:.4g} m/s at cfl 0.5, "
                 f"{apic[-1]:.4g} at cfl 0.125 (dt-dependent)" if apic.size else "")
    return Verdict(
        criterion="front speed of the jammed band (fit over 10-90 % of the gap, shear1d's "
                  "definition and window) within 10 % of shear1d's explicit method on the same "
                  "radii: (a) the paper's grid (24 cells, scene defaults: APIC-FLIP swirl blend "
                  "0.99, cfl 0.5) against shear1d at 24 cells; (b) like for like with shear1d's "
                  "locked mode, which holds phi fixed (an incompressible mixture): the paper "
                  "grid with kappa = 10 K against shear1d at 200 cells; (c) mpm2d's finest grid "
                  f"({finest} cells, kappa = K) against shear1d at 200 cells; (d) the paper "
                  "grid's front speed changes by less than 5 % when dt is divided by 2 and 4. "
                  "Reported, not a criterion: the paper grid with Table 4's kappa = K against "
                  "shear1d at 200 cells (it mixes the h error with the compressibility that "
                  "shear1d's locked mode does not have)",
        measured=f"paper grid: mpm2d {paper:.4g} m/s ({paper / u:.3g} u_i); shear1d 24 cells "
                 f"{ref[PAPER_CELLS]:.4g} ({100 * same_h:+.1f} %), 200 cells {ref[200]:.4g} "
                 f"({100 * paper_vs_fine:+.1f} %); by cfl "
                 + ", ".join(f"{v:.4g}" for v in dts) + f" (spread {100 * dt_spread:.1f} %); "
                 "by cells " + ", ".join(f"{v:.4g}" for v in np.concatenate([[paper], hs]))
                 + f" ({finest} cells vs shear1d 200: {100 * converged:+.1f} %); kappa = 10 K: "
                 f"{incomp:.4g} ({100 * incomp_vs_fine:+.1f} % vs shear1d 200)" + inc_note
                 + apic_note,
        passed=ok, figures=[fig_path], rows=table.to_dict("records"),
        notes={**{c: "shear1d row: no MPM step, transfer or fluid modulus (its locked mode "
                     "holds phi fixed)" for c in ("cfl", "swirl_flip", "kappa_Pa", "dt_s")},
               **{c: "no jammed front to fit (none formed or crossed 10-90 % of the gap): "
                     "the case fails" for c in ("front_speed_m_per_s",
                                                "front_speed_over_u_inner", "front_fit_r2")}})
