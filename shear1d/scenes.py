"""Scenes: the annular shear-jamming cell of the paper's Fig. 3, and plane Couette cells.

``annular_shear_jamming`` (paper section 'Dynamic Shear Jamming', Fig. 3, Table 4 on the Hermes
2016 steady fit: phi0 = 0.505, eta0 = 10 mPa s, rho = 1620 kg/m^3, G = 3.8e5 Pa, K = 8.3e5 Pa,
K0 = 0.06, d = 5.85 um): a bob of radius R_i turns impulsively with surface speed u_i inside a
cup of radius R_o, from rest, until the bob has turned 0.31 rad (t_end = 0.31 R_i/u_i);
u_i = 0.84 mm/s (slow: Newtonian-like profile) and 84 mm/s (fast: a jammed band grows from the
bob).

Radii (the paper gives none; our choice): R_o = 36 mm, the radial width of the paper's 36 x 50
element, 1 mm axisymmetric MPM grid (axis at r = 0, the cup wall at the grid edge); R_i =
12.5 mm (a 25 mm bob) makes the wide gap, R_o/R_i = 2.9, in which the Newtonian profile
A r + B/r is strongly curved, as in Fig. 3a. Both are options (``--r-inner``, ``--r-outer``).

Python::

    from shear1d.scenes import annular_shear_jamming
    from shear1d.integrate import solve
    problem, t_end = annular_shear_jamming(0.084, n_cells=200)
    result = solve(problem, t_end, n_out=310)
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import rheology
from rheology.run_end import EndedEarly, run_record
from runkit import limits as physical
from runkit.io import (atomic_write_csv, atomic_write_json, check_output_dir, load_checkpoint,
                       previous_checkpoint, remove_checkpoint)
from runkit.limits import ge, le
from runkit.params import OutOfRange, Param

from . import plots
from .geometry import Grid
from .integrate import Plan, Result, integrate, memory_estimate, prepare
from .model import WALL_SPEED, Couette
from .summary import (FRONT_EMPTY_OK, NULLABLE, SceneRun, couette_frames, couette_profile_outputs,
                      fields_frame, front_frame, jammed, profile_frames, run_tag, summarize)

TIME_MIN, TIME_MAX = physical.TIME_MIN.value, physical.TIME_MAX.value
SPEED_MIN = physical.SPEED_MIN.value
MAX_CELL_STEPS = physical.MAX_CELL_STEPS

R_INNER = 12.5e-3
R_OUTER = 36e-3
SPEEDS = (0.84e-3, 84e-3)
ROTATION_END = 0.31
#: The bob's rotation [rad].
ROTATION = Param(ge(physical.STRAIN_MIN.value, "the sample's strain is of order the bob's "
                                               "rotation: " + physical.STRAIN_MIN.why),
                 le(100.0, "16 turns, far past the 0.31 rad in which the Fig. 3 front crosses "
                           "the gap (the run's strain and cost grow with it)"), unit="rad")


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
        [TIME_MIN, TIME_MAX] (:mod:`runkit.limits`), naming u_inner and rotation with their
        ranges at the other's value.
    """
    m = rheology.get_material(material, **overrides)
    grid = Grid("annular", float(r_inner), float(r_outer), n_cells)
    ROTATION.check("rotation", rotation)
    problem = Couette(m, grid, mode=mode, wall_speed=u_inner, ramp_time=ramp_time, phi0=phi0)
    arc = grid.inner / float(u_inner)           # s per rad of rotation
    t_end = float(rotation) * arc + 0.5 * float(ramp_time)
    if not TIME_MIN <= t_end <= TIME_MAX:
        raise ValueError(f"u_inner = {u_inner:g} m/s and rotation = {rotation:g} rad make a run of "
                         f"{t_end:.4g} s, outside the valid durations [{TIME_MIN:g}, "
                         f"{TIME_MAX:g}] s: " + _duration_ranges(problem, float(rotation), arc))
    return problem, t_end


def _duration_ranges(problem: Couette, rotation: float, arc: float) -> str:
    """The ranges of u_inner at ``rotation`` and of rotation at u_inner (``arc`` = r_inner /
    u_inner, s per rad) in which t_end lies in [TIME_MIN, TIME_MAX], each within its own
    physical range (WALL_SPEED at the problem's material and phi0, ROTATION)."""
    _, _, _, u_hi, _, _ = WALL_SPEED.bounds({"material": problem.material, "phi0": problem.phi0})
    r_lo, _, _, r_hi, _, _ = ROTATION.bounds()
    r_i, u = problem.grid.inner, problem.wall_speed
    ranges = []
    for name, lo, hi, unit, at in (
            ("u_inner", max(SPEED_MIN, rotation * r_i / TIME_MAX),
             min(u_hi, rotation * r_i / TIME_MIN), "m/s", f"rotation = {rotation:g} rad"),
            ("rotation", max(r_lo, TIME_MIN / arc), min(r_hi, TIME_MAX / arc), "rad",
             f"u_inner = {u:g} m/s")):
        ranges.append(f"at {at}, {name} in [{lo:.6g}, {hi:.6g}] {unit}" if lo <= hi else
                      f"at {at}, no {name} is valid")
    return "; ".join(ranges)


def plane_couette(speed: float | None = None, *, stress: float | None = None, gap: float = 1e-2,
                  n_cells: int = 100, mode: str = "locked", phi0: float | None = None,
                  material: str = "annular_shear", ramp_time: float = 0.0,
                  rate_step: float | None = None, **overrides) -> Couette:
    """A plane Couette cell of width ``gap`` [m]: the plate at y = 0 moves at ``speed`` [m/s] or
    is pushed by the mixture shear stress ``stress`` [Pa]; the plate at y = gap is at rest."""
    m = rheology.get_material(material, **overrides)
    return Couette(m, Grid("plane", 0.0, float(gap), n_cells), mode=mode, wall_speed=speed,
                   wall_stress=stress, phi0=phi0, ramp_time=ramp_time, rate_step=rate_step)


def write_run(out: Path, run: SceneRun) -> list[Path]:
    """Write a run's CSV files and summary JSON into ``out`` (atomic, finite; empty cells and
    nulls only where undefined by construction); return the paths."""
    out, tag, res = Path(out), run.tag, run.result
    vel, cells = profile_frames(res)
    return [atomic_write_csv(out / f"{tag}_velocity_profiles.csv", vel),
            atomic_write_csv(out / f"{tag}_cell_profiles.csv", cells),
            atomic_write_csv(out / f"{tag}_front.csv", front_frame(res), empty_ok=FRONT_EMPTY_OK),
            atomic_write_csv(out / f"{tag}_fields.csv",
                             fields_frame(res, every=max(1, len(res.t) // 160))),
            atomic_write_json(out / f"{tag}_summary.json", run.summary, nullable=NULLABLE)]


def check_cell_steps(plan: Plan, t_end: float, duration: str = "--time") -> None:
    """Refuse an explicit run longer than MAX_CELL_STEPS before anything is written, naming
    every option that sets the count, cells x t_end / dt: --cells, ``duration`` (the option(s)
    that set t_end), --dt (or its default, half the stability limit), with the smallest --dt
    that fits when one within the stability limit does."""
    if plan.method != "explicit":
        return
    limit, step, n = plan.lim["dt"], plan.dt, plan.problem.grid.n
    work = n * t_end / step
    if work > MAX_CELL_STEPS:
        given = " (the default, half the stability limit)" if step == 0.5 * limit else ""
        need = n * t_end / MAX_CELL_STEPS
        larger = f"--dt >= {need:.3g} s (stability limit {limit:.3g} s), " if need <= limit else ""
        raise ValueError(f"--method explicit: --cells {n} over t_end = {t_end:.4g} s "
                         f"({duration}) at --dt = {step:.3g} s{given} are {work:.2e} "
                         f"cell-steps (estimate), more than {MAX_CELL_STEPS:.0e} (hours); "
                         f"valid: {larger}{'fewer --cells, ' if n > 4 else ''}t_end <= "
                         f"{MAX_CELL_STEPS * step / n:.3g} s at these --cells and --dt "
                         f"(a smaller {duration}), or --method ida")


def check_ramp(ramp_time: float, rotation: float, r_inner: float, speeds) -> None:
    """The ramp at most the rotation time at full speed, rotation r_inner / u, of the fastest
    speed: a longer ramp leaves the bob below full speed past half the rotation."""
    u = max(speeds)
    top = rotation * r_inner / u
    if ramp_time > top:
        rng = f"[{TIME_MIN:g}, {top:.4g}] s, or 0" if top >= TIME_MIN else "0 (impulsive) only"
        raise OutOfRange("ramp_time", f"{ramp_time:g} s", rng,
                         f"at most the rotation time --rotation x --r-inner / --u-inner = "
                         f"{rotation:g} x {r_inner:g} m / {u:g} m/s at full speed: a longer ramp "
                         "leaves the bob below full speed past half of --rotation, a slow "
                         "start-up, not a shear at --u-inner; lower it, or raise --rotation")


def _files(ck: Path) -> list[Path]:
    return [p for p in (ck, previous_checkpoint(ck)) if p.is_file()]


@contextlib.contextmanager
def _checkpointed(out: Path, cks, resume: bool, missing: str):
    """Around the runs of checkpoints ``cks``: before, with ``resume``, refuse them without any
    (``missing``: the message) and read each one there, so that a corrupt one is refused
    (:class:`runkit.io.CorruptCheckpoint`) before anything is printed; without, remove them
    (stale checkpoints of an earlier run); create ``out``. An interrupt names the checkpoints
    kept (:func:`_interrupted`); after the runs the checkpoints are removed."""
    kept = [ck for ck in cks if _files(ck)]
    if resume and not kept:
        raise ValueError(missing)
    for ck in kept if resume else ():
        load_checkpoint(ck, log=lambda *a, **k: None)
    out.mkdir(parents=True, exist_ok=True)
    for ck in () if resume else cks:
        remove_checkpoint(ck)
    try:
        yield
    except KeyboardInterrupt as exc:
        raise _interrupted(exc, list(cks)) from None
    for ck in cks:
        remove_checkpoint(ck)


def _solve_to_end(plan: Plan, ends: list, tag: str, **options) -> Result:
    """:func:`shear1d.integrate.integrate` with the elastic-strain limit on; a run that ends
    early (rheology.run_end) is returned with its outputs so far, its end added to ``ends`` as
    ``tag``'s; one that ended before its second output fails (RuntimeError)."""
    try:
        return integrate(plan, elastic_limit=True, **options)
    except EndedEarly as exc:
        res = exc.partial
        if res is None or len(res.t) < 2:
            raise RuntimeError(exc.ends[0].reason) from None
        ends.append(res.end.replace(run=tag))
        return res


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

    Every run keeps a checkpoint ``<tag>.checkpoint.npz`` (every ``checkpoint_every`` wall
    seconds, at its end and on an interrupt) until all runs' files are written; with
    ``resume=True`` finished runs are read back from theirs, an interrupted one continues from
    its own, and runs that had not started start. Every parameter and the memory the runs need
    are checked before the first run. A run that ends early (:mod:`rheology.run_end`) keeps its
    outputs up to the end: its files and figures are written from them and the next run starts.

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
    out = check_output_dir("--out", out)
    problems = [(u, mode) + annular_shear_jamming(
        u, n_cells=n_cells, mode=mode, r_inner=r_inner, r_outer=r_outer, rotation=rotation,
        ramp_time=ramp_time, material=material, phi0=phi0) for u in speeds for mode in modes]
    if len(set(speeds)) != len(tuple(speeds)) or len(set(modes)) != len(tuple(modes)):
        raise ValueError(f"--u-inner {' '.join(f'{u:g}' for u in speeds)}: each speed (and "
                         "mode) once")
    check_ramp(ramp_time, rotation, r_inner, speeds)
    cks = {run_tag(u, mode): out / f"{run_tag(u, mode)}.checkpoint.npz" for u, mode, *_ in problems}
    plans = {}
    for u, mode, problem, t_end in problems:
        ck = cks[run_tag(u, mode)]
        plans[ck] = prepare(problem, t_end, method=method, n_out=n_out, rtol=rtol, dt=dt,
                            checkpoint=ck, checkpoint_every=checkpoint_every,
                            resume=resume and bool(_files(ck)))
        check_cell_steps(plans[ck], t_end, "--rotation x --r-inner / --u-inner"
                         + (" + --ramp-time/2" if ramp_time else ""))
    physical.check_memory("--cells x --outputs", f"{n_cells} x {n_out}",
                          memory_estimate(n_cells, n_out, runs=len(problems)))
    runs, ends = [], []
    with _checkpointed(out, list(cks.values()), resume,
                       f"--resume: no checkpoint of these runs in {out}/ (looked for "
                       f"{', '.join(p.name for p in cks.values())}); run without --resume to "
                       "start"):
        for u, mode, problem, t_end in problems:
            tag = run_tag(u, mode)
            plan = plans[cks[tag]]
            log(f"shear1d: {tag}: {n_cells} cells, {method}, to {rotation:g} rad (t_end = "
                f"{t_end:.4g} s){' resuming from ' + str(cks[tag]) if plan.resume else ''} ...",
                flush=True)
            res = _solve_to_end(plan, ends, tag, progress=progress, label=tag,
                                stop_hook=stop_hook, log=log)
            run = SceneRun(tag, res, summarize(res))
            write_run(out, run)
            plots.run_fields(out / f"{tag}_fields.png", run)
            _report(run, log)
            runs.append(run)
        figs = [plots.velocity_profiles(out / "velocity_profiles.png", runs),
                plots.front_positions(out / "front_position.png", runs)]
        if len(set(modes)) > 1:
            figs.append(plots.mode_comparison(out / "mode_comparison.png", runs))
    log(f"shear1d: wrote {out}/ (" + ", ".join(p.name for p in figs) + " and per-run CSV/JSON)")
    if ends:
        raise EndedEarly(ends, partial=runs, written=[str(out)])
    return runs


def _report(run: SceneRun, log) -> None:
    s, res = run.summary, run.result
    if jammed(s) and s["front_speed_m_per_s"] == s["front_speed_m_per_s"]:
        log(f"    {res.wall_time:.2f} s; jammed band: front speed {s['front_speed_m_per_s']:.3g}"
            f" m/s ({s['front_speed_over_u_inner']:.3g} u_i, R^2 {s['front_fit_r2']:.3f}), "
            f"band v/(omega r) {s['band_rigidity_mean']:.2f}, structure at the outer wall "
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
    out = check_output_dir("--out", out)
    ck = out / "couette.checkpoint.npz"
    plan = prepare(problem, t_end, method=method, n_out=n_out, rtol=rtol, dt=dt, checkpoint=ck,
                   checkpoint_every=checkpoint_every, resume=resume)
    check_cell_steps(plan, t_end)
    physical.check_memory("--cells x --outputs", f"{problem.grid.n} x {n_out}",
                          memory_estimate(problem.grid.n, n_out))
    ends = []
    with _checkpointed(out, [ck], resume,
                       f"--resume: no checkpoint at {ck}; run without --resume to start"):
        res = _solve_to_end(plan, ends, "couette", progress=progress, label="couette",
                            stop_hook=stop_hook, log=log)
        prof, wall = couette_frames(res)
        atomic_write_csv(out / "couette_profiles.csv", prof)
        atomic_write_csv(out / "couette_wall.csv", wall)
        png = plots.couette(out / "couette.png", res, couette_profile_outputs(res))
        atomic_write_json(out / "couette.json", run_record(ends, t_end_s=float(res.t[-1]),
                                                           outputs=len(res.t)))
    log(f"shear1d: plane Couette, {problem.grid.n} cells, {res.method}, {res.wall_time:.2f} s; "
        f"wrote {out}/couette_profiles.csv, couette_wall.csv, {png.name}, couette.json")
    if ends:
        raise EndedEarly(ends, partial=res, written=[str(out)])
    return res


def _fmt_rot(x) -> str:
    return "-" if x is None else f"{x:.3f} rad"


__all__ = ["annular_shear_jamming", "plane_couette", "run_annular", "run_couette", "R_INNER",
           "R_OUTER", "SPEEDS"]
