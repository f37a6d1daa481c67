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

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

import rheology
from rheology.checks import check_memory, check_positive, check_range
from rheology.cli_common import TIME_MAX, TIME_MIN
from runkit.io import atomic_write_csv, atomic_write_json, check_output_dir, previous_checkpoint
from rheology.run_end import EndedEarly, run_record

from . import analysis
from .analytic import annular_steady
from .geometry import Grid
from .integrate import (EVENTS, METHODS, Result, check_time_step, memory_estimate,
                        output_times, solve, stable_time_step)
from .model import Couette

R_INNER = 12.5e-3
R_OUTER = 36e-3
SPEEDS = (0.84e-3, 84e-3)
ROTATIONS = (0.0, 0.1, 0.2, 0.31)
ROTATION_END = 0.31


def annular_shear_jamming(u_inner: float = 0.084, *, n_cells: int = 200, mode: str = "locked",
                          r_inner: float = R_INNER, r_outer: float = R_OUTER,
                          rotation: float = ROTATION_END, ramp_time: float = 0.0,
                          material="annular_shear", phi0: float | None = None,
                          **overrides) -> tuple[Couette, float]:
    """The Fig. 3 annular cell: (problem, t_end [s]) for a bob surface speed u_inner [m/s] > 0.

    ``overrides`` replace material parameters (e.g. K=8.3e6); t_end = rotation R_i/u_inner
    (+ ramp_time/2 with a start-up ramp), the time at which the bob has turned ``rotation``.

    Raises
    ------
    ValueError
        A parameter out of its range, or a t_end outside the durations of every tier
        [TIME_MIN, TIME_MAX] (rheology.cli_common: 1 ps to 30 years), naming u_inner and rotation
        with their ranges at the other's value (u_inner = 1e-300 asked for 3.9e297 s and failed
        in the law; rotation = 1e-300 ran 1.5e-301 s and wrote its files).
    """
    check_positive("u_inner", u_inner, note="m/s, bob surface speed")
    check_positive("rotation", rotation, note="rad of bob rotation to simulate")
    m = rheology.get_material(material, **overrides)
    grid = Grid("annular", float(r_inner), float(r_outer), n_cells)
    problem = Couette(m, grid, mode=mode, wall_speed=float(u_inner), ramp_time=ramp_time,
                      phi0=phi0)
    t_end = float(rotation) * grid.inner / float(u_inner) + 0.5 * float(ramp_time)
    if not TIME_MIN <= t_end <= TIME_MAX:
        arc = grid.inner / float(u_inner)           # s per rad of rotation
        raise ValueError(
            f"u_inner = {u_inner:g} m/s and rotation = {rotation:g} rad make a run of "
            f"{t_end:.4g} s, outside the valid durations [{TIME_MIN:g}, {TIME_MAX:g}] s: at "
            f"rotation = {rotation:g} rad, u_inner in [{rotation * grid.inner / TIME_MAX:.6g}, "
            f"{rotation * grid.inner / TIME_MIN:.6g}] m/s; at u_inner = {u_inner:g} m/s, rotation "
            f"in [{TIME_MIN / arc:.6g}, {TIME_MAX / arc:.6g}] rad")
    return problem, t_end


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


def flow_stop_time(result: Result) -> float | None:
    """Time [s] the flow stopped after the band reached the outer wall (None if it did not)."""
    ev = result.events
    wall_t = ev.get("front_at_wall", [])[:1]
    wall = wall_t[0] if wall_t else None
    return next((x for x in ev.get("flow_stopped", []) if wall is None or x >= wall), None)


def flow_restart_time(result: Result) -> float | None:
    """The first output time [s] after the flow stopped (:func:`flow_stop_time`) at which the
    bulk speed is back above FLOW_STOP_LEVEL of the wall speed (None: it stays stopped)."""
    from .integrate import FLOW_STOP_LEVEL

    stop = flow_stop_time(result)
    if stop is None:
        return None
    g, u, v = result.problem.grid, result.problem.drive_amplitude, result.field("v")
    return next((float(t) for t, vk in zip(result.t, v)
                 if t > stop and analysis.bulk_speed(g, vk, u) >= FLOW_STOP_LEVEL), None)


def band_present(result: Result) -> np.ndarray:
    """(n_out,) bool: outputs at which a jammed band grows from the moving wall.

    A band exists where f >= f_jam(phi0)/2 in the cell at the moving wall (the structure front
    has left it); it grows until it reaches the outer wall (the ``front_at_wall`` event) or the
    flow stops (``flow_stopped``), whichever comes first. From then on the band fills the gap (or
    has stopped), and the rigid-ratio threshold crossing is only the edge of the decelerating
    layer at the bob, which falls back and oscillates with the elastic waves - no front of a band.
    """
    pb = result.problem
    fjam = float(rheology.f_jam(pb.phi0, pb.material))
    f = result.field("f")
    band = f[:, 0] >= 0.5 * fjam
    ends = [ts[0] for ts in (result.events.get("front_at_wall", []),
                             result.events.get("flow_stopped", [])) if ts]
    if ends:
        band &= result.t <= min(ends)
    return band


def band_front(result: Result) -> np.ndarray:
    """Kinematic front position [m] where a jammed band exists (:func:`band_present`), NaN
    elsewhere (undefined by construction: no band, no front)."""
    return np.where(band_present(result), result.front(), np.nan)


#: Summary keys that are null where undefined by construction: the front fit when no jammed band
#: crossed 10 % of the gap (the slow case, or a run stopped early) or fewer than 3 outputs fell in
#: the crossing; the band rigidity and the largest front position when no band formed.
NULLABLE = ("front_speed_m_per_s", "front_speed_over_u_inner", "front_fit_r2",
            "front_fit_gap_reached", "front_fit_intercept_m", "front_fit_rotation_rad",
            "structure_front_speed_m_per_s", "structure_front_fit_r2", "band_rigidity_mean",
            "band_rigidity_min", "max_front_position_m")


def summarize(result: Result) -> dict:
    """Front speed and linearity, rigidity, events, conservation and Newtonian deviation, and
    how the run ended (``status``, ``ends``: :func:`rheology.run_end.run_record`).

    Values undefined by construction are NaN (written as null: see :data:`NULLABLE`). The wall
    time is not part of the summary (it is printed): a resumed run's files are the same bytes as
    an uninterrupted run's.
    """
    pb, g = result.problem, result.problem.grid
    m, u = pb.material, pb.drive_amplitude
    v, f, phi = result.field("v"), result.field("f"), result.field("phi")
    band = band_present(result)
    front = np.where(band, result.front(), np.nan)
    fjam = float(rheology.f_jam(pb.phi0, m))
    sfront = np.array([analysis.structure_front(g, ff, fjam) for ff in f])
    sfront = np.where(band, sfront, np.nan)
    fit = analysis.front_fit(result.t, front, g)
    sfit = analysis.front_fit(result.t, sfront, g)
    rot = rotation_of(result, result.t)
    window = (result.t >= fit["t_start"]) & (result.t <= fit["t_end"]) & band
    rigid = [analysis.band_rigidity(g, v[k], u, front[k]) for k in np.flatnonzero(window)]
    rigid = [x for x in rigid if np.isfinite(x)]
    vol = g.cell_volumes()
    solids = phi @ vol
    ev = {k: [float(x) for x in result.events.get(k, [])] for k in EVENTS}
    wall_t = ev["front_at_wall"][0] if ev["front_at_wall"] else None
    stop_t = flow_stop_time(result)
    again_t = flow_restart_time(result)
    newt = {}
    for target in ROTATIONS[1:]:
        k = int(np.argmin(np.abs(rot - target)))
        if abs(rot[k] - target) < 1e-3 + 0.5 * np.max(np.diff(rot), initial=0.0):
            vn = annular_steady(g.faces, g.inner, g.outer, u)
            newt[f"{target:g}"] = float(np.max(np.abs(v[k] - vn)) / u)
    tau = np.abs(result.field("shear_stress"))
    nan = float("nan")
    stats = {k: (float(x) if isinstance(x, (float, np.floating)) else int(x))
             for k, x in result.stats.items()}
    return dict(
        u_inner_m_per_s=u, mode=pb.mode, method=result.method, n_cells=g.n, r_inner_m=g.inner,
        r_outer_m=g.outer, phi0=pb.phi0, t_end_s=float(result.t[-1]),
        rotation_end_rad=float(rot[-1]), solver=stats,
        front_speed_m_per_s=fit["speed"], front_speed_over_u_inner=fit["speed"] / u,
        front_fit_r2=fit["r2"], front_fit_intercept_m=fit["intercept"],
        front_fit_rotation_rad=[float(rotation_of(result, fit["t_start"])),
                                float(rotation_of(result, fit["t_end"]))],
        front_fit_gap_reached=fit["gap_reached"],
        front_crossed_gap=bool(fit["gap_reached"] >= analysis.WALL_FRACTION),
        structure_front_speed_m_per_s=sfit["speed"], structure_front_fit_r2=sfit["r2"],
        band_rigidity_mean=float(np.mean(rigid)) if rigid else nan,
        band_rigidity_min=float(np.min(rigid)) if rigid else nan,
        max_front_position_m=float(np.nanmax(front)) if band.any() else nan,
        front_at_wall_rotation_rad=None if wall_t is None else float(rotation_of(result, wall_t)),
        flow_stopped_rotation_rad=None if stop_t is None else float(rotation_of(result, stop_t)),
        flow_restarted_rotation_rad=None if again_t is None else float(rotation_of(result,
                                                                                   again_t)),
        events_s=ev,
        newtonian_deviation_max_over_u=newt,
        f_max=float(f.max()), f_jam=fjam, phi_min=float(phi.min()), phi_max=float(phi.max()),
        solid_volume_drift=float(np.max(np.abs(solids - solids[0])) / solids[0]),
        bob_shear_stress_max_Pa=float(np.max(tau[:, 0] * (g.centres[0] / g.inner) ** 2)),
        granular_pressure_max_Pa=float(result.field("pressure").max()),
        **run_record([result.end] if result.end else []),
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


#: Columns of <tag>_front.csv left empty where undefined by construction: the front and the
#: band's rigidity where no jammed band exists (:func:`band_present`).
FRONT_EMPTY_OK = ("front_m", "band_rigidity")


def front_frame(result: Result) -> pd.DataFrame:
    """Front position and bob stress against time (front_m and band_rigidity empty where no
    jammed band exists)."""
    pb, g = result.problem, result.problem.grid
    u = pb.drive_amplitude
    v, f = result.field("v"), result.field("f")
    front = band_front(result)
    fjam = float(rheology.f_jam(pb.phi0, pb.material))
    tau = np.abs(result.field("shear_stress"))[:, 0] * (g.centres[0] / g.inner) ** 2
    rigidity = [analysis.band_rigidity(g, vv, u, fr) if np.isfinite(fr) else np.nan
                for vv, fr in zip(v, front)]
    return pd.DataFrame({
        "time_s": result.t, "rotation_rad": rotation_of(result, result.t), "front_m": front,
        "structure_front_m": [analysis.structure_front(g, ff, fjam) for ff in f],
        "band_rigidity": rigidity,
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
    """Write a run's CSV files and summary JSON into ``out`` (atomic, finite; empty cells and
    nulls only where undefined by construction); return the paths."""
    out = Path(out)
    vel, cells = profile_frames(run.result)
    paths = [atomic_write_csv(out / f"{run.tag}_velocity_profiles.csv", vel),
             atomic_write_csv(out / f"{run.tag}_cell_profiles.csv", cells),
             atomic_write_csv(out / f"{run.tag}_front.csv", front_frame(run.result),
                              empty_ok=FRONT_EMPTY_OK),
             atomic_write_csv(out / f"{run.tag}_fields.csv",
                              fields_frame(run.result, every=max(1, len(run.result.t) // 160))),
             atomic_write_json(out / f"{run.tag}_summary.json", run.summary, nullable=NULLABLE)]
    return paths


#: Largest explicit run accepted, in cell-steps (cells x steps): about 3 hours at the ~1e8
#: cell-steps per second of the explicit kernel; longer runs are refused with the estimate.
MAX_CELL_STEPS = 1e12


def precheck(problem: Couette, method: str, rtol: float, dt: float | None,
             t_end: float | None = None, duration: str = "--time") -> None:
    """Refuse a bad method, tolerance, an unstable explicit step or an explicit run longer than
    MAX_CELL_STEPS before anything is written. The cell-step refusal names every option that
    sets the count, cells x t_end / dt: --cells, ``duration`` (the option(s) that set t_end,
    e.g. ``"--rotation / --u-inner"``), --dt (or its default, half the stability limit), with
    the smallest --dt that fits when one within the stability limit does."""
    if method not in METHODS:
        raise ValueError(f"method = {method!r} must be one of {METHODS}")
    check_range("rtol", rtol, 1e-12, 1e-2)
    if method == "explicit":
        if dt is not None:
            try:
                check_time_step(problem, dt)
            except ValueError as exc:     # named as the user's option (--dt, --method ida)
                text = str(exc)
                raise ValueError(("--" + text if text.startswith("dt ") else text)
                                 .replace("method='ida'", "--method ida")) from None
        if t_end is not None:
            limit = stable_time_step(problem)["dt"]
            step = dt if dt is not None else 0.5 * limit
            n = problem.grid.n
            work = n * t_end / step
            if work > MAX_CELL_STEPS:
                given = "" if dt is not None else " (the default, half the stability limit)"
                need = n * t_end / MAX_CELL_STEPS
                larger = (f"--dt >= {need:.3g} s (stability limit {limit:.3g} s), "
                          if need <= limit else "")
                raise ValueError(f"--method explicit: --cells {n} over t_end = {t_end:.4g} s "
                                 f"({duration}) at --dt = {step:.3g} s{given} are {work:.2e} "
                                 f"cell-steps (estimate), more than {MAX_CELL_STEPS:.0e} (hours); "
                                 f"valid: {larger}{'fewer --cells, ' if n > 4 else ''}t_end <= "
                                 f"{MAX_CELL_STEPS * step / n:.3g} s at these --cells and --dt "
                                 f"(a smaller {duration}), or --method ida")


def check_out_dir(out) -> Path:
    """The output folder as a Path; ValueError if it exists and is not a folder or cannot be
    written (runkit.io.check_output_dir)."""
    return check_output_dir("--out", out)


def _solve_to_end(problem, t_end, ends: list, tag: str, **options) -> Result:
    """:func:`shear1d.integrate.solve` with the elastic-strain limit on; a run that ends early
    (rheology.run_end) is returned with its outputs so far, its end added to ``ends`` as
    ``tag``'s; one that ended before its second output fails (RuntimeError)."""
    try:
        return solve(problem, t_end, elastic_limit=True, **options)
    except EndedEarly as exc:
        res = exc.partial
        if res is None or len(res.t) < 2:
            raise RuntimeError(exc.ends[0].reason) from None
        ends.append(res.end.replace(run=tag))
        return res


def _checkpoint_files(ck: Path) -> list[Path]:
    return [p for p in (ck, previous_checkpoint(ck)) if p.is_file()]


def _interrupted(exc: KeyboardInterrupt, checkpoints) -> KeyboardInterrupt:
    """The interrupt message: where the checkpoints are, or that nothing was saved."""
    msg = str(exc) if "checkpoint" in str(exc) else ""
    kept = [p for p in checkpoints if p.is_file() and str(p) not in msg]
    if kept:
        msg += ("; " if msg else "") + "checkpoints kept: " + ", ".join(str(p) for p in kept)
        if "--resume" not in msg:
            msg += "; rerun with --resume to continue"
    return KeyboardInterrupt(msg or "nothing was saved")


def run_annular(out, speeds=SPEEDS, modes=("locked",), *, n_cells: int = 200,
                method: str = "ida", rtol: float = 1e-4, dt: float | None = None,
                n_out: int = 310, r_inner: float = R_INNER, r_outer: float = R_OUTER,
                rotation: float = ROTATION_END, ramp_time: float = 0.0, resume: bool = False,
                checkpoint_every: float = 60.0, progress: bool = False, stop_hook=None,
                material="annular_shear", phi0: float | None = None,
                log=print) -> list[SceneRun]:
    """Solve the Fig. 3 scene for every speed and mode; write CSV, JSON and PNG into ``out``.

    Every run keeps a checkpoint ``<tag>.checkpoint.npz`` (written every ``checkpoint_every``
    seconds, at its end and on an interrupt) until all runs' files are written; with
    ``resume=True`` finished runs are read back from theirs, an interrupted one continues from
    its own, and runs that had not started start. ``resume=True`` with no checkpoint of these
    runs in ``out`` is refused (ValueError). Every parameter and the memory the runs need are
    checked before the first run.

    A run that ends early (a solver or local-update failure, an unphysical state, a cell's
    elastic strain past 0.1: :mod:`rheology.run_end`) keeps its outputs up to the end: its files
    and figures are written from them (the end in its summary's ``status``/``ends`` and marked
    on its figures) and the next run starts.

    Raises
    ------
    ValueError
        Bad input, not enough memory (estimate stated), nothing to resume.
    rheology.run_end.EndedEarly
        After every file is written, when a run ended early (``partial``: the runs).
    RuntimeError
        A run that failed before its second output (nothing written for it).
    KeyboardInterrupt
        Interrupted; the message names the checkpoints kept (or says nothing was saved).
    """
    from . import plots

    out = check_out_dir(out)
    problems = []
    for u in speeds:                         # validate everything before the first long run
        for mode in modes:
            problems.append((u, mode) + annular_shear_jamming(
                u, n_cells=n_cells, mode=mode, r_inner=r_inner, r_outer=r_outer,
                rotation=rotation, ramp_time=ramp_time, material=material, phi0=phi0))
    if len(set(speeds)) != len(tuple(speeds)) or len(set(modes)) != len(tuple(modes)):
        raise ValueError(f"--u-inner {' '.join(f'{u:g}' for u in speeds)}: each speed (and "
                         "mode) once")
    for *_, problem, t_end in problems:
        precheck(problem, method, rtol, dt, t_end,
                 duration="--rotation x --r-inner / --u-inner" + (" + --ramp-time/2"
                                                                  if ramp_time else ""))
    check_memory("--cells x --outputs", f"{n_cells} x {n_out}",
                 memory_estimate(n_cells, n_out, runs=len(problems)))
    cks = {run_tag(u, mode): out / f"{run_tag(u, mode)}.checkpoint.npz" for u, mode, *_ in problems}
    if resume:
        if not any(_checkpoint_files(ck) for ck in cks.values()):
            raise ValueError(f"--resume: no checkpoint of these runs in {out}/ (looked for "
                             f"{', '.join(p.name for p in cks.values())}); run without --resume "
                             "to start")
    out.mkdir(parents=True, exist_ok=True)
    if not resume:
        for ck in cks.values():              # stale checkpoints of an earlier run
            for p in _checkpoint_files(ck):
                p.unlink()
    runs, ends = [], []
    try:
        for u, mode, problem, t_end in problems:
            tag = run_tag(u, mode)
            ck = cks[tag]
            again = resume and bool(_checkpoint_files(ck))
            log(f"shear1d: {tag}: {n_cells} cells, {method}, to {rotation:g} rad (t_end = "
                f"{t_end:.4g} s){' resuming from ' + str(ck) if again else ''} ...", flush=True)
            res = _solve_to_end(problem, t_end, ends, tag, method=method, n_out=n_out,
                                rtol=rtol, dt=dt, checkpoint=ck,
                                checkpoint_every=checkpoint_every, resume=again,
                                progress=progress, label=tag, stop_hook=stop_hook, log=log)
            run = SceneRun(tag, res, summarize(res))
            write_run(out, run)
            plots.run_fields(out / f"{tag}_fields.png", run)
            _report(run, log)
            runs.append(run)
        figs = [plots.velocity_profiles(out / "velocity_profiles.png", runs),
                plots.front_positions(out / "front_position.png", runs)]
        if len(set(modes)) > 1:
            figs.append(plots.mode_comparison(out / "mode_comparison.png", runs))
    except KeyboardInterrupt as exc:
        raise _interrupted(exc, list(cks.values())) from None
    for ck in cks.values():
        for p in _checkpoint_files(ck):
            p.unlink()
    log(f"shear1d: wrote {out}/ (" + ", ".join(p.name for p in figs) + " and per-run CSV/JSON)")
    if ends:
        raise EndedEarly(ends, partial=runs, written=[str(out)])
    return runs


def _report(run: SceneRun, log) -> None:
    s, res = run.summary, run.result
    if jammed(s) and s["front_speed_m_per_s"] == s["front_speed_m_per_s"]:
        log(f"    {res.wall_time:.2f} s; jammed band: front speed {s['front_speed_m_per_s']:.3g}"
            f" m/s ({s['front_speed_over_u_inner']:.3g} u_i, R^2 {s['front_fit_r2']:.3f}), "
            f"band v/(omega r) {s['band_rigidity_mean']:.2f}, at the outer wall "
            f"{_fmt_rot(s['front_at_wall_rotation_rad'])}, flow stopped "
            f"{_fmt_rot(s['flow_stopped_rotation_rad'])}", flush=True)
    elif jammed(s):
        log(f"    {res.wall_time:.2f} s; a jammed band formed (f_max/f_jam "
            f"{s['f_max'] / s['f_jam']:.2f}) but its front did not cross 10-90 % of the gap in "
            f"this run: no front speed", flush=True)
    else:
        dev = ", ".join(f"{k} rad {v:.1e}" for k, v in s["newtonian_deviation_max_over_u"].items())
        log(f"    {res.wall_time:.2f} s; no jamming (f_max/f_jam {s['f_max'] / s['f_jam']:.1e})"
            f"; max |v - v_Newtonian|/u_i: {dev or '-'}", flush=True)


def run_couette(out, problem: Couette, t_end: float, *, method: str = "ida", n_out: int = 200,
                rtol: float = 1e-4, dt: float | None = None, resume: bool = False,
                checkpoint_every: float = 60.0, progress: bool = False, stop_hook=None,
                log=print) -> Result:
    """Solve a plane Couette start-up and write couette_profiles.csv, couette_wall.csv,
    couette.png and the run record couette.json (:func:`rheology.run_end.run_record`) into
    ``out`` (checkpoint ``couette.checkpoint.npz`` until the files are written; same resume rules
    as :func:`run_annular`). A run that ends early writes them from its outputs so far and then
    raises :class:`rheology.run_end.EndedEarly` (``partial``: the Result)."""
    from . import plots

    out = check_out_dir(out)
    output_times(t_end, n_out)
    precheck(problem, method, rtol, dt, t_end)
    check_memory("--cells x --outputs", f"{problem.grid.n} x {n_out}",
                 memory_estimate(problem.grid.n, n_out))
    ck = out / "couette.checkpoint.npz"
    if resume and not _checkpoint_files(ck):
        raise ValueError(f"--resume: no checkpoint at {ck}; run without --resume to start")
    out.mkdir(parents=True, exist_ok=True)
    if not resume:
        for p in _checkpoint_files(ck):
            p.unlink()
    ends = []
    try:
        res = _solve_to_end(problem, t_end, ends, "couette", method=method, n_out=n_out,
                            rtol=rtol, dt=dt, checkpoint=ck, checkpoint_every=checkpoint_every,
                            resume=resume, progress=progress, label="couette",
                            stop_hook=stop_hook, log=log)
        prof, wall = couette_frames(res)
        atomic_write_csv(out / "couette_profiles.csv", prof)
        atomic_write_csv(out / "couette_wall.csv", wall)
        png = plots.couette(out / "couette.png", res, couette_profile_outputs(res))
        atomic_write_json(out / "couette.json", run_record(ends, t_end_s=float(res.t[-1]),
                                                           outputs=len(res.t)))
    except KeyboardInterrupt as exc:
        raise _interrupted(exc, [ck]) from None
    for p in _checkpoint_files(ck):
        p.unlink()
    g = problem.grid
    log(f"shear1d: plane Couette, {g.n} cells, {res.method}, {res.wall_time:.2f} s; wrote "
        f"{out}/couette_profiles.csv, couette_wall.csv, {png.name}, couette.json")
    if ends:
        raise EndedEarly(ends, partial=res, written=[str(out)])
    return res


def couette_profile_outputs(res: Result) -> np.ndarray:
    """Indices of the (up to 6) outputs whose velocity profiles are written and drawn."""
    return np.unique(np.linspace(0, len(res.t) - 1, 6).astype(int))


def couette_frames(res: Result) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(profiles, wall history) of a plane Couette run: v(y) at a few times; wall speed, wall
    shear stress, mean shear rate and mean f against time."""
    g = res.problem.grid
    v, tau = res.field("v"), np.abs(res.field("shear_stress"))
    idx = couette_profile_outputs(res)
    prof = pd.concat([pd.DataFrame({"time_s": res.t[k], "y_m": g.faces, "v_m_per_s": v[k]})
                      for k in idx], ignore_index=True)
    wall = pd.DataFrame({"time_s": res.t, "wall_speed_m_per_s": v[:, 0],
                         "wall_shear_stress_Pa": tau[:, 0],
                         "mean_shear_rate_per_s": (v[:, 0] - v[:, -1]) / g.gap,
                         "f_mean": res.field("f").mean(axis=1)})
    return prof, wall


def jammed(summary: dict) -> bool:
    """Whether a run grew a jammed band (f reached half of f_jam(phi0) somewhere)."""
    return summary["f_max"] >= 0.5 * summary["f_jam"]


def _fmt_rot(x) -> str:
    return "-" if x is None else f"{x:.3f} rad"


__all__ = ["annular_shear_jamming", "plane_couette", "run_annular", "run_couette", "summarize",
           "SceneRun", "band_present", "band_front", "R_INNER", "R_OUTER", "SPEEDS", "ROTATIONS"]
