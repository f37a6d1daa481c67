"""Scenes: the annular shear-jamming cell of the paper's Fig. 3, and plane Couette cells.

``annular_shear_jamming`` (paper section 'Dynamic Shear Jamming', Fig. 3, Table 4 on the Hermes
2016 steady fit: phi0 = 0.505, eta0 = 10 mPa s, rho = 1620 kg/m^3, G = 3.8e5 Pa, K = 8.3e5 Pa,
K0 = 0.06, d = 5.85 um): a bob of radius R_i turns impulsively with surface speed u_i inside a
cup of radius R_o, from rest, until the bob has turned 0.31 rad (t_end = 0.31 R_i/u_i);
u_i = 0.84 mm/s (slow: Newtonian-like profile) and 84 mm/s (fast: a jammed band grows from the
bob).

Radii (the paper gives none; Peters, Majumdar & Jaeger, Nature 532, 214 (2016), the experiment,
was not available to us): R_o = 36 mm is the radial width of the paper's 36 x 50 element, 1 mm
axisymmetric MPM grid, whose axis is at r = 0 (the axisymmetric weak form runs from the axis),
with the cup wall at the grid edge; R_i = 12.5 mm (a 25 mm bob) makes the wide gap,
R_o/R_i = 2.9, in which the Newtonian profile A r + B/r is strongly curved, as in Fig. 3a. Both
are options (``--r-inner``, ``--r-outer``).

Command: ``shear1d annular [--u-inner U ...] [--out DIR]``. Python::

    from shear1d.scenes import annular_shear_jamming
    from shear1d.integrate import solve
    problem, t_end = annular_shear_jamming(0.084, n_cells=200)
    result = solve(problem, t_end, n_out=310)
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

import rheology
from rheology.checks import check_positive
from rheology.io import atomic_write_csv, atomic_write_text

from . import analysis
from .analytic import annular_steady
from .geometry import Grid
from .integrate import EVENTS, Result, solve
from .model import Couette

R_INNER = 12.5e-3
R_OUTER = 36e-3
SPEEDS = (0.84e-3, 84e-3)
ROTATIONS = (0.0, 0.1, 0.2, 0.31)
ROTATION_END = 0.31


def annular_shear_jamming(u_inner: float = 0.084, *, n_cells: int = 200, mode: str = "locked",
                          r_inner: float = R_INNER, r_outer: float = R_OUTER,
                          rotation: float = ROTATION_END, ramp_time: float = 0.0,
                          material: str = "annular_shear", phi0: float | None = None,
                          **overrides) -> tuple[Couette, float]:
    """The Fig. 3 annular cell: (problem, t_end [s]) for a bob surface speed u_inner [m/s] > 0.

    ``overrides`` replace material parameters (e.g. K=8.3e6); t_end = rotation R_i/u_inner
    (+ ramp_time/2 with a start-up ramp), the time at which the bob has turned ``rotation``.
    """
    check_positive("u_inner", u_inner, note="m/s, bob surface speed")
    check_positive("rotation", rotation, note="rad of bob rotation to simulate")
    m = rheology.get_material(material, **overrides)
    grid = Grid("annular", float(r_inner), float(r_outer), n_cells)
    problem = Couette(m, grid, mode=mode, wall_speed=float(u_inner), ramp_time=ramp_time,
                      phi0=phi0)
    return problem, float(rotation) * grid.inner / float(u_inner) + 0.5 * float(ramp_time)


def plane_couette(speed: float | None = None, *, stress: float | None = None, gap: float = 1e-2,
                  n_cells: int = 100, mode: str = "locked", phi0: float | None = None,
                  material: str = "annular_shear", ramp_time: float = 0.0,
                  rate_step: float | None = None, **overrides) -> Couette:
    """A plane Couette cell of width ``gap`` [m]: the plate at y = 0 moves at ``speed`` [m/s] or
    is pushed by the mixture shear stress ``stress`` [Pa]; the plate at y = gap is at rest."""
    m = rheology.get_material(material, **overrides)
    return Couette(m, Grid("plane", 0.0, float(gap), n_cells), mode=mode, wall_speed=speed,
                   wall_stress=stress, phi0=phi0, ramp_time=ramp_time, rate_step=rate_step)


# ----------------------------------------------------------------------------- run summaries
@dataclass
class SceneRun:
    """One solved scene: its tag (file prefix), result and summary numbers."""

    tag: str
    result: Result
    summary: dict


def run_tag(u_inner: float, mode: str) -> str:
    return f"u{u_inner * 1e3:g}mm_s_{mode}"


def rotation_of(result: Result, t) -> np.ndarray:
    """Bob rotation [rad] at times t [s] (integral of u(t)/R_i, ramp included)."""
    pb = result.problem
    t = np.asarray(t, dtype=float)
    u, ramp = pb.drive_amplitude, pb.ramp_time
    dist = np.where(t < ramp, 0.5 * u * t ** 2 / ramp if ramp > 0 else 0.0, u * (t - 0.5 * ramp))
    return dist / pb.grid.inner


def summarize(result: Result) -> dict:
    """Front speed and linearity, rigidity, events, conservation and Newtonian deviation."""
    pb, g = result.problem, result.problem.grid
    m, u = pb.material, pb.drive_amplitude
    v, f, phi = result.field("v"), result.field("f"), result.field("phi")
    front = result.front()
    fjam = float(rheology.f_jam(pb.phi0, m))
    sfront = np.array([analysis.structure_front(g, ff, fjam) for ff in f])
    fit = analysis.front_fit(result.t, front, g)
    sfit = analysis.front_fit(result.t, sfront, g)
    rot = rotation_of(result, result.t)
    window = (result.t >= fit["t_start"]) & (result.t <= fit["t_end"])
    rigid = [analysis.band_rigidity(g, v[k], u, front[k]) for k in np.flatnonzero(window)]
    vol = g.cell_volumes()
    solids = phi @ vol
    ev = {k: [float(x) for x in result.events.get(k, [])] for k in EVENTS}
    wall_t = ev["front_at_wall"][0] if ev["front_at_wall"] else None
    stop_t = next((x for x in ev["flow_stopped"] if wall_t is None or x >= wall_t), None)
    newt = {}
    for target in ROTATIONS[1:]:
        k = int(np.argmin(np.abs(rot - target)))
        if abs(rot[k] - target) < 1e-3 + 0.5 * np.max(np.diff(rot), initial=0.0):
            vn = annular_steady(g.faces, g.inner, g.outer, u)
            newt[f"{target:g}"] = float(np.max(np.abs(v[k] - vn)) / u)
    tau = np.abs(result.field("shear_stress"))
    return dict(
        u_inner_m_per_s=u, mode=pb.mode, method=result.method, n_cells=g.n, r_inner_m=g.inner,
        r_outer_m=g.outer, phi0=pb.phi0, t_end_s=float(result.t[-1]),
        rotation_end_rad=float(rot[-1]), wall_time_s=result.wall_time,
        solver={k: (float(x) if isinstance(x, (float, np.floating)) else int(x))
                for k, x in result.stats.items()},
        front_speed_m_per_s=fit["speed"], front_speed_over_u_inner=fit["speed"] / u,
        front_fit_r2=fit["r2"], front_fit_intercept_m=fit["intercept"],
        front_fit_rotation_rad=[float(rotation_of(result, fit["t_start"])),
                                float(rotation_of(result, fit["t_end"]))],
        structure_front_speed_m_per_s=sfit["speed"], structure_front_fit_r2=sfit["r2"],
        band_rigidity_mean=float(np.nanmean(rigid)) if rigid else float("nan"),
        band_rigidity_min=float(np.nanmin(rigid)) if rigid else float("nan"),
        max_front_position_m=float(front.max()),
        front_at_wall_rotation_rad=None if wall_t is None else float(rotation_of(result, wall_t)),
        flow_stopped_rotation_rad=None if stop_t is None else float(rotation_of(result, stop_t)),
        events_s=ev,
        newtonian_deviation_max_over_u=newt,
        f_max=float(f.max()), f_jam=fjam, phi_min=float(phi.min()), phi_max=float(phi.max()),
        solid_volume_drift=float(np.max(np.abs(solids - solids[0])) / solids[0]),
        bob_shear_stress_max_Pa=float(np.max(tau[:, 0] * (g.centres[0] / g.inner) ** 2)),
        granular_pressure_max_Pa=float(result.field("pressure").max()),
    )


# ----------------------------------------------------------------------------- files
def profile_frames(result: Result, rotations=ROTATIONS) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Velocity profiles (faces) and cell profiles at the outputs nearest the given rotations."""
    pb, g = result.problem, result.problem.grid
    rot = rotation_of(result, result.t)
    u = pb.drive_amplitude
    fields = {k: result.field(k) for k in ("v", "f", "phi", "sigma_rth", "pressure",
                                           "shear_stress", "shear_rate", "plastic_shear_rate")}
    vrows, crows = [], []
    for target in rotations:
        k = int(np.argmin(np.abs(rot - target)))
        vk = fields["v"][k]
        vrows.append(pd.DataFrame({
            "rotation_rad": rot[k], "time_s": result.t[k], "r_m": g.faces, "v_m_per_s": vk,
            "v_over_u_inner": vk / u, "v_over_omega_r": analysis.rigid_ratio(g, vk, u)}))
        crows.append(pd.DataFrame({
            "rotation_rad": rot[k], "time_s": result.t[k], "r_m": g.centres, "f": fields["f"][k],
            "phi": fields["phi"][k], "granular_shear_stress_Pa": np.abs(fields["sigma_rth"][k]),
            "granular_pressure_Pa": fields["pressure"][k],
            "shear_stress_Pa": np.abs(fields["shear_stress"][k]),
            "shear_rate_per_s": np.abs(fields["shear_rate"][k]),
            "plastic_shear_rate_per_s": fields["plastic_shear_rate"][k]}))
    return pd.concat(vrows, ignore_index=True), pd.concat(crows, ignore_index=True)


def front_frame(result: Result) -> pd.DataFrame:
    """Front position and bob stress against time."""
    pb, g = result.problem, result.problem.grid
    u = pb.drive_amplitude
    v, f = result.field("v"), result.field("f")
    front = result.front()
    fjam = float(rheology.f_jam(pb.phi0, pb.material))
    tau = np.abs(result.field("shear_stress"))[:, 0] * (g.centres[0] / g.inner) ** 2
    return pd.DataFrame({
        "time_s": result.t, "rotation_rad": rotation_of(result, result.t), "front_m": front,
        "structure_front_m": [analysis.structure_front(g, ff, fjam) for ff in f],
        "band_rigidity": [analysis.band_rigidity(g, vv, u, fr) for vv, fr in zip(v, front)],
        "bulk_speed_over_u_inner": [analysis.bulk_speed(g, vv, u) for vv in v],
        "bob_shear_stress_Pa": tau,
        "bob_torque_per_height_N": 2 * np.pi * g.inner ** 2 * tau})


def fields_frame(result: Result, every: int = 1) -> pd.DataFrame:
    """Space-time fields at cell centres (long format): f, phi, v/(omega r), rates, pressure."""
    pb, g = result.problem, result.problem.grid
    u = pb.drive_amplitude
    idx = np.arange(0, len(result.t), max(1, every))
    v = result.field("v")[idx]
    vc = 0.5 * (v[:, 1:] + v[:, :-1])
    nt, n = len(idx), g.n
    return pd.DataFrame({
        "time_s": np.repeat(result.t[idx], n),
        "rotation_rad": np.repeat(rotation_of(result, result.t[idx]), n),
        "r_m": np.tile(g.centres, nt),
        "v_over_omega_r": (vc / g.rigid_speed(u, g.centres)).ravel(),
        "f": result.field("f")[idx].ravel(), "phi": result.field("phi")[idx].ravel(),
        "plastic_shear_rate_per_s": result.field("plastic_shear_rate")[idx].ravel(),
        "granular_pressure_Pa": result.field("pressure")[idx].ravel()})


def write_run(out: Path, run: SceneRun) -> list[Path]:
    """Write a run's CSV files and summary JSON into ``out`` (atomic); return the paths."""
    out = Path(out)
    vel, cells = profile_frames(run.result)
    paths = [atomic_write_csv(out / f"{run.tag}_velocity_profiles.csv", vel),
             atomic_write_csv(out / f"{run.tag}_cell_profiles.csv", cells),
             atomic_write_csv(out / f"{run.tag}_front.csv", front_frame(run.result)),
             atomic_write_csv(out / f"{run.tag}_fields.csv",
                              fields_frame(run.result, every=max(1, len(run.result.t) // 160))),
             atomic_write_text(out / f"{run.tag}_summary.json",
                               json.dumps(run.summary, indent=1, default=_json))]
    return paths


def _json(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    raise TypeError(type(x).__name__)


def run_annular(out, speeds=SPEEDS, modes=("locked",), *, n_cells: int = 200,
                method: str = "ida", rtol: float = 1e-4, dt: float | None = None,
                n_out: int = 310, r_inner: float = R_INNER, r_outer: float = R_OUTER,
                rotation: float = ROTATION_END, ramp_time: float = 0.0, resume: bool = False,
                log=print) -> list[SceneRun]:
    """Solve the Fig. 3 scene for every speed and mode; write CSV, JSON and PNG into ``out``.

    Checkpoints ``<tag>.checkpoint.npz`` are written during each run (resume with
    ``resume=True``) and removed when the run's files are written.
    """
    from . import plots

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    problems = []
    for u in speeds:                         # validate everything before the first long run
        for mode in modes:
            problems.append((u, mode) + annular_shear_jamming(
                u, n_cells=n_cells, mode=mode, r_inner=r_inner, r_outer=r_outer,
                rotation=rotation, ramp_time=ramp_time))
    runs = []
    for u, mode, problem, t_end in problems:
        tag = run_tag(u, mode)
        ck = out / f"{tag}.checkpoint.npz"
        log(f"shear1d: {tag}: {n_cells} cells, {method}, to {rotation:g} rad (t_end = "
            f"{t_end:.4g} s) ...", flush=True)
        res = solve(problem, t_end, method=method, n_out=n_out, rtol=rtol, dt=dt, checkpoint=ck,
                    resume=resume)
        run = SceneRun(tag, res, summarize(res))
        write_run(out, run)
        figs = plots.run_fields(out / f"{tag}_fields.png", run)
        ck.unlink(missing_ok=True)
        s = run.summary
        if jammed(s):
            log(f"    {res.wall_time:.2f} s; jammed band: front speed {s['front_speed_m_per_s']:.3g}"
                f" m/s ({s['front_speed_over_u_inner']:.3g} u_i, R^2 {s['front_fit_r2']:.3f}), "
                f"band v/(omega r) {s['band_rigidity_mean']:.2f}, at the outer wall "
                f"{_fmt_rot(s['front_at_wall_rotation_rad'])}, flow stopped "
                f"{_fmt_rot(s['flow_stopped_rotation_rad'])}", flush=True)
        else:
            dev = ", ".join(f"{k} rad {v:.1e}" for k, v in
                            s["newtonian_deviation_max_over_u"].items())
            log(f"    {res.wall_time:.2f} s; no jamming (f_max/f_jam {s['f_max'] / s['f_jam']:.1e})"
                f"; max |v - v_Newtonian|/u_i: {dev}", flush=True)
        runs.append(run)
    figs = [plots.velocity_profiles(out / "velocity_profiles.png", runs),
            plots.front_positions(out / "front_position.png", runs)]
    if len(set(modes)) > 1:
        figs.append(plots.mode_comparison(out / "mode_comparison.png", runs))
    log(f"shear1d: wrote {out}/ (" + ", ".join(p.name for p in figs) + " and per-run CSV/JSON)")
    return runs


def jammed(summary: dict) -> bool:
    """Whether a run grew a jammed band (f reached half of f_jam(phi0) somewhere)."""
    return summary["f_max"] >= 0.5 * summary["f_jam"]


def _fmt_rot(x) -> str:
    return "-" if x is None else f"{x:.3f} rad"


__all__ = ["annular_shear_jamming", "plane_couette", "run_annular", "summarize", "SceneRun",
           "R_INNER", "R_OUTER", "SPEEDS", "ROTATIONS"]
