"""mpm2d intruder scene (Figs. 6-7): jamming fronts ahead of a rod driven at constant speed.

- ``mpm2d_intruder_fig6``: the default run (phi0 = 0.47, v0 = 0.175 m/s, 20 ms, the paper's
  50 x 35 grid at 1 mm): k_l/k_t in [1.5, 2.5] (Han et al. 2016's k_l ~ 2 k_t) and fronts at
  near-constant speed (R^2 >= 0.95 for both straight-line fits);
- ``mpm2d_intruder_fig7``: the ten cases of Fig. 7 (phi0 0.46-0.50 x v0 0.2, 0.5 m/s) through
  ``mpm2d.sweep.run_sweep`` on Dask: every k_l/k_t in [1.5, 2.5];
- ``mpm2d_intruder_convergence``: one case (phi0 = 0.47, v0 = 0.5 m/s, 4 ms) at h = 1 mm and
  0.5 mm: k_l and k_t within 25% of each other;
- ``mpm2d_intruder_modes``: the locked mixture (default) against two-phase on one case: k_l and
  k_t within 25%, which justifies the locked default (the scene's docstring gives the time
  scales).

Quick mode (the test suite) runs a coarse, short version of each and checks the machinery: finite
k_l and k_t and fronts ahead of the rod.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from mpm2d.run import run_scene  # noqa: E402
from mpm2d.scenes import get_setup  # noqa: E402
from rheology.io import atomic_savefig, atomic_write_csv  # noqa: E402

from .framework import Verdict, case  # noqa: E402

#: the quick (test-suite) case: h = 1 mm, a 20 x 16 mm bed, 2 ms at 0.5 m/s
QUICK = dict(radius=0.02, depth=0.016, v0=0.5, t_end=0.002, fit_margin=0.002)
#: the convergence and mode comparisons: a Fig. 7 case (phi0 = 0.47, v0 = 0.5 m/s, where the
#: plug forms within 0.3 ms) over its first 4 ms (the fronts advance until ~11 ms at 1 mm)
REDUCED = dict(phi0=0.47, v0=0.5, t_end=0.004)
RATIO_RANGE = (1.5, 2.5)
R2_MIN = 0.95


def _run(out: Path, **params) -> dict:
    res = run_scene(get_setup("intruder"), out, params, progress=False, vtk=False,
                    log=lambda m: None)
    summary = json.loads((Path(out) / "summary.json").read_text())
    summary["steps"] = int(res["scene"].sim.step_count)
    summary["points"] = int(sum(len(s) for s in res["scene"].sim.sets))
    return summary


def _num(x) -> float:
    return float("nan") if x is None else float(x)


def _fmt(s: dict) -> str:
    return (f"k_l = {_num(s['k_l']):.3g}, k_t = {_num(s['k_t']):.3g}, k_l/k_t = "
            f"{_num(s['k_l_over_k_t']):.3g}, R^2 = {_num(s['r2_longitudinal']):.3f} / "
            f"{_num(s['r2_transverse']):.3f}")


def _in_range(s) -> bool:
    r = _num(s.get("k_l_over_k_t"))
    return math.isfinite(r) and RATIO_RANGE[0] <= r <= RATIO_RANGE[1]


@case("mpm2d", "mpm2d_intruder_fig6", "mpm2d: intruder at 0.175 m/s, phi 0.47 (Fig. 6): fronts",
      slow=True)
def intruder_fig6(out: Path, quick: bool) -> Verdict:
    params = dict(QUICK) if quick else {}
    t0 = time.perf_counter()
    s = _run(out / "run", **params)
    wall = time.perf_counter() - t0
    figs = [out / "run" / "fields.png", out / "run" / "front.png"]
    ps = s["points"] * s["steps"]
    measured = (f"{_fmt(s)}; {s['steps']} steps x {s['points']} points = {ps:.3g} point-steps "
                f"in {wall:.0f} s wall ({ps / wall / 1e6:.2f} M point-steps/s, machine shared)")
    if quick:
        ok = math.isfinite(_num(s["k_l"])) and math.isfinite(_num(s["k_t"]))
        return Verdict("quick: finite k_l and k_t (machinery)", measured, ok, figs)
    ok = _in_range(s) and min(_num(s["r2_longitudinal"]), _num(s["r2_transverse"])) >= R2_MIN
    return Verdict(f"k_l/k_t in [{RATIO_RANGE[0]}, {RATIO_RANGE[1]}] and both fits R^2 >= "
                   f"{R2_MIN}", measured, ok, figs)


@case("mpm2d", "mpm2d_intruder_fig7", "mpm2d: intruder sweep phi x v0 on Dask (Fig. 7): k_l/k_t",
      slow=True)
def intruder_fig7(out: Path, quick: bool) -> Verdict:
    from mpm2d.sweep import parse_grid, run_sweep

    if quick:
        grid = [f"{k}={v}" for k, v in QUICK.items() if k not in ("v0",)]
        grid += ["phi0=0.46,0.50", "v0=0.5"]
    else:
        grid = ["phi0=0.46,0.47,0.48,0.49,0.50", "v0=0.2,0.5"]
    t0 = time.perf_counter()
    table = run_sweep("intruder", parse_grid(grid), out / "sweep", progress=False,
                      log=lambda m: None)
    wall = time.perf_counter() - t0
    fronts = pd.read_csv(out / "sweep" / "fronts.csv")
    failed = int((table["status"] == "failed").sum())
    ratio = fronts["k_l_over_k_t"]
    lines = "; ".join(f"phi {r.phi0:g} v0 {r.v0_m_per_s:g}: k_l {r.k_l:.3g} k_t {r.k_t:.3g} "
                      f"ratio {r.k_l_over_k_t:.3g}{'' if r.jammed else ' (not jammed)'}"
                      for r in fronts.itertuples())
    measured = (f"{len(fronts)} cases ({failed} failed), k_l/k_t mean {ratio.mean():.3g} sd "
                f"{ratio.std(ddof=0):.3g} [{ratio.min():.3g}, {ratio.max():.3g}], sweep wall "
                f"{wall:.0f} s on 2 workers; {lines}")
    figs = [out / "sweep" / "fronts.png"]
    if quick:
        ok = failed == 0 and len(fronts) == 2 and ratio.notna().all()
        return Verdict("quick: both cases complete with a finite k_l/k_t", measured, ok, figs)
    ok = failed == 0 and len(fronts) == 10 and bool(ratio.between(*RATIO_RANGE).all())
    return Verdict(f"all ten cases complete with k_l/k_t in [{RATIO_RANGE[0]}, "
                   f"{RATIO_RANGE[1]}]", measured, ok, figs)


def _compare(out: Path, quick: bool, variants: dict, tol: float, title: str, png: str):
    rows = []
    for name, params in variants.items():
        t0 = time.perf_counter()
        s = _run(out / name, **params)
        rows.append({"variant": name, "k_l": _num(s["k_l"]), "k_t": _num(s["k_t"]),
                     "k_l_over_k_t": _num(s["k_l_over_k_t"]),
                     "r2_longitudinal": _num(s["r2_longitudinal"]),
                     "r2_transverse": _num(s["r2_transverse"]), "steps": s["steps"],
                     "points": s["points"], "wall_s": time.perf_counter() - t0})
    df = pd.DataFrame(rows)
    atomic_write_csv(out / "comparison.csv", df, empty_ok=("k_l", "k_t", "k_l_over_k_t",
                                                           "r2_longitudinal", "r2_transverse"))
    a, b = df.iloc[0], df.iloc[1]
    dl = abs(b["k_l"] - a["k_l"]) / abs(a["k_l"])
    dt = abs(b["k_t"] - a["k_t"]) / abs(a["k_t"])
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for (name, _), c in zip(variants.items(), "br"):
        f = pd.read_csv(out / name / "front.csv")
        ax.plot(f["time_s"] * 1e3, f["longitudinal_m"] * 1e3, c + "-", label=f"{name}: longitudinal")
        ax.plot(f["time_s"] * 1e3, f["transverse_m"] * 1e3, c + "--", label=f"{name}: transverse")
    ax.set_xlabel("t [ms]")
    ax.set_ylabel("front position [mm]")
    ax.set_title(f"{title}: k_l differs {100 * dl:.1f}%, k_t {100 * dt:.1f}%", fontsize=9)
    ax.legend(fontsize=7)
    fig_path = atomic_savefig(fig, out / png)
    plt.close(fig)
    measured = "; ".join(f"{r.variant}: k_l {r.k_l:.3g} k_t {r.k_t:.3g} ratio "
                         f"{r.k_l_over_k_t:.3g} ({r.wall_s:.0f} s)" for r in df.itertuples())
    measured += f"; relative differences k_l {dl:.3f}, k_t {dt:.3f}"
    ok = math.isfinite(dl) and math.isfinite(dt)
    if not quick:
        ok = ok and dl <= tol and dt <= tol
    crit = ("quick: finite k_l, k_t in both (machinery)" if quick else
            f"k_l and k_t of the two within {100 * tol:.0f}%")
    return Verdict(crit, measured, ok, [fig_path])


@case("mpm2d", "mpm2d_intruder_convergence", "mpm2d: intruder fronts at h = 1 mm and 0.5 mm",
      slow=True)
def intruder_convergence(out: Path, quick: bool) -> Verdict:
    if quick:
        base = dict(QUICK)
        variants = {"h_2mm": {**base, "cells_per_mm": 0.5}, "h_1mm": base}
    else:
        base = dict(REDUCED)
        variants = {"h_1mm": base, "h_0.5mm": {**base, "cells_per_mm": 2.0}}
    return _compare(out, quick, variants, 0.25, "grid convergence", "intruder_convergence.png")


@case("mpm2d", "mpm2d_intruder_modes", "mpm2d: intruder, locked mixture vs two-phase",
      slow=True)
def intruder_modes(out: Path, quick: bool) -> Verdict:
    base = dict(QUICK) if quick else dict(REDUCED)
    variants = {"locked": base, "two_phase": {**base, "mode": "two-phase"}}
    return _compare(out, quick, variants, 0.25, "locked mixture vs two-phase",
                    "intruder_modes.png")
