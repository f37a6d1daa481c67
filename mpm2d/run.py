"""Running a scene: history, snapshots, checkpoints, resume, figures.

:func:`run_scene` is what ``mpm2d run SCENE --set key=value --out DIR`` calls. The parameters
are checked once, by the scene's declaration (:mod:`mpm2d.scenes.spec`: types, ranges with their
reasons, bounds derived from the other parameters, the step count where the parameters bound
the step, the memory estimate). The scene's
``setup(**params)`` returns a :class:`Scene`; :func:`runkit.run.drive` steps it to ``t_end``
(SIGINT/SIGTERM deferred to the end of the step, then a checkpoint; numpy's warnings held; a
checkpoint every ``checkpoint_every`` wall seconds), recording a history row every
``t_end/history_rows`` of simulated time and ``frames`` snapshots (npz + VTK); then the scene's
report (CSV tables and PNG figures).

Refused before anything is written (ValueError, one line): a run needing more than MAX_STEPS
steps or fewer than the scene's fewest, said before the set-up about the parameter the user set with its bound at the
other values where the scene states its run from its parameters
(:func:`mpm2d.scenes.spec.run_refusal`; the step count also after it, at its first stable
step); a set-up that breaks down; a resume of another scene, with other parameters or output
options. ``resume=True`` continues from ``DIR/checkpoint.npz`` (or its kept predecessor)
bit-for-bit: every file equals an uninterrupted run's. A fresh run removes only the files a
previous run of ours wrote (:class:`mpm2d.output.RunFolder`). A run whose step fails
ends there (:mod:`rheology.run_end`): history up to the last row, ``history.png``, manifest
``status: ended_early`` with ``ends``, :class:`~rheology.run_end.EndedEarly` (exit status 3); a
report that fails marks it ``failed`` and raises RuntimeError.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numba
import numpy as np
import pandas as pd

from runkit.io import atomic_write_csv, previous_checkpoint, read_checkpoint, save_checkpoint
from runkit.limits import MAX_STEPS, ge, gt, le
from runkit.params import Number
from runkit.run import (TEMPORARY, HeldWarnings, Interrupts, Notice, Progress, drive, table_arrays,
                        table_rows)
from rheology.run_end import EndedEarly, RunEnd, run_record

from . import estimate, plots
from .output import RunFolder, command_line, write_frame, write_pvds
from .scenes.spec import STEPS_WHY, run_refusal, spec_of
from .simulation import Simulation


@dataclass
class Scene:
    """What a scene's ``setup(**params)`` returns.

    Attributes
    ----------
    sim : Simulation
    t_end : float
        End time [s].
    params : dict
        The parameters used (for the manifest and resume).
    frames, history_rows : int
        Snapshots after the initial one; about how many history rows.
    record : callable(sim) -> dict, optional
        Extra history columns (units in the names).
    report : callable(sim, history DataFrame, out Path) -> list of Path, optional
        Result tables and figures written after the run.
    before_step : callable(sim), optional
        Called before every step (time-dependent loading).
    frame_times : tuple of float
        Extra snapshot times [s], tagged ``event`` (reports read them back with
        :func:`mpm2d.output.load_frames`, so they survive ``--resume``).
    frame_fields : tuple of str
        The point fields a snapshot keeps besides ``id`` and ``x``; empty: every field.
    vtk : bool
        Whether VTK snapshots are written by default (``mpm2d run --vtk``/``--no-vtk``).
    notes : str
        Written to the manifest.
    undefined : tuple of str
        History columns that may be undefined by construction (NaN, an empty cell), e.g. a
        stress behind a front not yet formed; every other value must be finite.
    min_steps : int
        The fewest first stable steps the run (and its analysis) needs, at least one.
    """

    sim: Simulation
    t_end: float
    params: dict
    frames: int = 10
    history_rows: int = 400
    record: Callable | None = None
    report: Callable | None = None
    before_step: Callable | None = None
    frame_times: tuple = ()
    frame_fields: tuple = ()
    vtk: bool = True
    notes: str = ""
    undefined: tuple = ()
    min_steps: int = 1


def history_row(sim: Simulation, scene: Scene) -> dict:
    """The standard history columns plus the scene's."""
    row = {"time_s": sim.t, "step": int(sim.step_count), "dt_s": sim.last_dt}
    row.update(sim.energies())
    p = sim.momentum()
    row["momentum_x_kg_m_per_s"], row["momentum_y_kg_m_per_s"] = float(p[0]), float(p[1])
    if scene.record is not None:
        row.update(scene.record(sim))
    return row


def coerce(params: dict, setup: Callable) -> dict:
    """The ``--set`` overrides (strings or Python values) checked by the scene's declaration
    (:meth:`runkit.params.Schema.coerce`), with their canonical types; ValueError."""
    return spec_of(setup).coerce(dict(params))


def _first_step(scene) -> tuple[float, float, int]:
    """(first step [s], number of steps to t_end at it, the fewest steps the scene needs) of a
    freshly set-up scene (inf/0 steps and NaN are returned, not raised)."""
    sim = scene.sim
    with np.errstate(all="ignore"):
        dt = sim.user_dt if sim.user_dt is not None else sim.stable_dt()
        steps = (scene.t_end - sim.t) / dt if dt > 0 else math.inf
    return float(dt), float(steps), max(1, int(scene.min_steps))


def check_step_count(scene, name: str) -> None:
    """Refuse (ValueError, one line) a run needing more than MAX_STEPS steps or fewer than the
    scene's ``min_steps`` at its first stable step (a resumed run: its parameters were taken)."""
    dt, steps, need = _first_step(scene)
    t0 = scene.sim.t
    if steps > MAX_STEPS or not steps >= need:
        raise ValueError(f"scene {name}: an end time of {scene.t_end:.3g} s is {steps:.3g} of its "
                         f"first stable steps ({dt:.3g} s); valid: an end time in "
                         f"[{t0 + need * dt:.3g}, {t0 + MAX_STEPS * dt:.3g}] s at the other "
                         f"values (at "
                         f"least {need} step{'s' if need > 1 else ''}; at most {MAX_STEPS:.0e}, "
                         f"{STEPS_WHY})")


#: the run options, with the reasons of their limits (``mpm2d run --frames``,
#: ``--checkpoint-every``: the same check from the command line and from Python)
FRAMES = Number("--frames", ge(1, "at least the final snapshot"),
                le(100000, "a file per snapshot: 1e5 is past any animation or analysis"),
                integer=True)
CHECKPOINT_EVERY = Number("--checkpoint-every", gt(0.0, "a checkpoint interval is a positive "
                                                        "wall time"),
                          le(1e6, "12 days, longer than the longest run (1e8 steps, about a day "
                                  "on one core)"), unit="s")

#: a set-up taking longer than this [wall s] is announced ('setting up scene X...', a status
#: line on a terminal's stderr, erased when the set-up ends); a fast one is not. A refusal after
#: the set-up (the step count) is then the only output, on every stream
SETUP_NOTICE_S = 2.0


def run_scene(setup: Callable, out, params: dict | None = None, *, resume: bool = False,
              progress: bool = True, vtk: bool | None = None, frames: int | None = None,
              checkpoint_every: float = 60.0, log=None, stop_after_steps: int | None = None,
              scene_name: str = "", quiet: bool = False, yes: bool = True) -> dict:
    """Run a scene to its end time (or ``stop_after_steps`` steps, then checkpoint).

    Parameters
    ----------
    setup : the scene's (declared) ``setup`` function
    out : output folder (created once the input is valid)
    params : parameter overrides (strings from the CLI are converted)
    resume : continue from ``out/checkpoint.npz``
    progress : progress bar on stderr (tqdm)
    vtk : also write VTK snapshots (points and grid); default the scene's (``Scene.vtk``), or
        the checkpoint's choice
    frames : number of snapshots (default: the scene's, or the checkpoint's)
    checkpoint_every : wall-clock seconds between checkpoints (> 0)
    log : callable(str) for the run log (default: print to stdout)
    stop_after_steps : stop (with a checkpoint) after this many steps in this call
    quiet : no progress bar and no log lines (set-up, notes, the closing line; ``mpm2d run
        --quiet``); a run started inside a quiet run (the wheel report's other omegas) is quiet
        too, whatever its own ``log`` and ``progress``. Errors are raised as always.
    yes : run a fresh run past :data:`mpm2d.estimate.CONFIRM_POINT_STEPS` point-steps (``mpm2d
        run --yes``); False refuses it with its estimate (ValueError) before anything is
        written. Every fresh run logs its size and estimated wall time (:mod:`mpm2d.estimate`).

    Returns
    -------
    dict with ``scene``, ``history`` (DataFrame), ``figures``, ``manifest``, ``complete``.

    Raises
    ------
    ValueError
        Bad input (a parameter, a run too long or too short, values breaking the first step or
        the analysis, a resume that does not match the checkpoint or its --threads, an output
        folder that is not empty and not a run of ours), before anything is written.
    RuntimeError
        The run diverged (non-finite energy; a checkpoint is written first) or its report
        failed: the manifest is marked ``failed`` with the message, the files stay.
    KeyboardInterrupt
        SIGINT/SIGTERM: after the current step, a checkpoint is written (during the set-up:
        at once, nothing written).
    """
    quiet = quiet or bool(_Quiet.depth)
    if quiet:
        log, progress = (lambda msg: None), False
    log = log or (lambda msg: print(msg, flush=True))
    # a signal before the step loop (the set-up, a resume's reading) stops at once, as Ctrl-C
    # does, also when no command line opened a window (SIGTERM's default would end the process)
    with _Quiet(quiet), Interrupts(defer=False):
        return _run_scene(setup, out, params, resume, progress, vtk, frames, checkpoint_every,
                          log, stop_after_steps, scene_name, yes)


class _Quiet:
    """The quiet runs open now (a run inside one is quiet too)."""

    depth = 0

    def __init__(self, on: bool):
        self.on = on

    def __enter__(self):
        _Quiet.depth += int(self.on)

    def __exit__(self, *exc):
        _Quiet.depth -= int(self.on)
        return False


def _resumed(out: Path, spec, name: str, given: dict, options: dict, log):
    """The checkpoint of ``out`` and where it was read from, with the run's stored parameters and
    options; ValueError where the resume does not match it (scene, parameters, --frames, --vtk,
    --threads)."""
    saved, used = read_checkpoint(out / "checkpoint.npz", required=("run.params", "t", "step"),
                                  log=log)
    if "chunks" in saved:
        chunks, threads = int(saved["chunks"]), numba.get_num_threads()
        if chunks != threads:
            cap = numba.config.NUMBA_NUM_THREADS
            more = (f" (NUMBA_NUM_THREADS = {cap} here allows at most {cap}: raise it)"
                    if chunks > cap else "")
            raise ValueError(f"--resume: the checkpoint in {out} was written with --threads "
                             f"{chunks}, this run has {threads}; resume with --threads "
                             f"{chunks} to continue bit-for-bit{more}")
    stored_name = str(saved["run.scene"]) if "run.scene" in saved else None
    stored = json.loads(str(saved["run.params"]))
    if stored_name is not None and stored_name != name:
        raise ValueError(f"--resume: the checkpoint in {out} is of scene {stored_name!r}, not "
                         f"{name!r}; resume it with 'mpm2d run {stored_name} --resume' or start "
                         "a new folder")
    foreign = [k for k in stored if k not in spec.params]
    if foreign:
        raise ValueError(f"--resume: the checkpoint in {out} has parameters "
                         f"{', '.join(foreign)} that scene {name} does not have: it was written "
                         "by another scene; start a new folder")
    stored = spec.coerce(stored)
    full_stored = {**spec.defaults, **stored}

    def shown(x):
        return "none (the scene's default)" if x is None else x

    for k, v in given.items():
        if full_stored[k] != v:
            raise ValueError(f"--resume: {k} = {shown(v)} differs from the checkpoint's {k} = "
                             f"{shown(full_stored[k])}; resume without --set {k} or start a "
                             "new folder")
    old = json.loads(str(saved["run.options"])) if "run.options" in saved else {}
    for k, v in old.items():
        if options.get(k) is not None and options[k] != v:
            if k == "frames":
                theirs = ("the scene's default number of snapshots" if v is None
                          else f"--frames {v}")
                raise ValueError(f"--resume: --frames {options[k]} differs from the "
                                 f"interrupted run's ({theirs}); resume without --frames")
            flag = "--vtk" if options[k] else "--no-vtk"
            raise ValueError(f"--resume: {flag} differs from the interrupted run's (it "
                             f"{'wrote' if v else 'did not write'} VTK); resume without {flag}")
        options[k] = v if options.get(k) is None else options[k]
    return saved, used, stored


def _set_up(setup, params: dict, given: dict, name: str, resuming: str, show: bool):
    """The scene of ``setup(**params)`` (its warnings held: shown after a set-up that works, cited
    by a refusal of one that breaks down). Announced when slow (a bed's relaxation) and ``show``
    (not quiet), as a status line on a terminal's stderr that is erased when the set-up ends;
    Ctrl-C or SIGTERM stops it at once, nothing written."""
    notice = f"setting up scene {name}" + (
        " (then the checkpoint is loaded)" if resuming else "") + "..."
    try:
        with Notice(notice, SETUP_NOTICE_S, show), HeldWarnings() as held:
            scene = getattr(setup, "raw", setup)(**params)     # params are checked already
    except KeyboardInterrupt:
        raise KeyboardInterrupt("during the scene's set-up, nothing written"
                                + (f"; {resuming} is as it was" if resuming else "")) from None
    except (ArithmeticError, ValueError) as exc:
        # a value inside its declared range whose set-up still breaks down (an area of 0
        # refused by the body it builds, a modulus that overflows): a set-up refusal that names
        # a given parameter stands as it is
        if isinstance(exc, ValueError) and any(re.search(rf"\b{re.escape(k)}\b", str(exc))
                                               for k in given):
            raise
        given_text = ", ".join(f"{k} = {v}" for k, v in given.items()) or "the defaults"
        raise ValueError(f"scene {name}: with {given_text} the set-up breaks down "
                         f"({type(exc).__name__}: {exc}{held.after()}); valid: values away "
                         f"from the extremes of their ranges ('mpm2d show {name}')") from None
    return scene, held


class _Run:
    """The stepping of one run (the :class:`runkit.run.Stepper` :func:`runkit.run.drive`
    advances, and the checkpoint it saves): history rows, snapshots, the checkpoint with the
    history and the manifest."""

    def __init__(self, folder, scene, name, params, defaults, options, saved):
        sim = scene.sim
        self.folder, self.out = folder, folder.path
        self.scene, self.sim, self.name = scene, sim, name
        self.params, self.options = params, options
        self.manifest = manifest = folder.manifest = {
            "scene": name, "command": command_line(name, params, defaults, options["frames"],
                                                   options["vtk"], scene.vtk),
            "params": params, "mode": sim.mode, "transfer": sim.transfer,
            "description": sim.describe(),
            "grid": {"nx": sim.grid.nx, "ny": sim.grid.ny, "h_m": sim.grid.h,
                     "origin_m": list(sim.grid.origin), "axisymmetric": sim.grid.axisymmetric,
                     "boundaries": sim.grid.boundaries},
            "t_end_s": scene.t_end, "notes": scene.notes, "frames": [], "status": "running",
            "ends": []}
        self.path = self.out / "checkpoint.npz"
        self.t_end, self.rows = scene.t_end, []
        nframes = scene.frames if options["frames"] is None else int(options["frames"])
        self.rec_dt = scene.t_end / max(scene.history_rows, 1)
        self.frame_dt = scene.t_end / max(nframes, 1)
        if saved is not None:
            self.sim.load_state({k: v for k, v in saved.items() if not k.startswith("run.")})
            self.rows = (table_rows(saved, "run.history") if "run.history.0" in saved else
                         [dict(zip([str(c) for c in saved["run.history_columns"]], r))
                          for r in saved["run.history"]])     # a checkpoint of an older version
            manifest["frames"] = json.loads(str(saved["run.frames"]))
            self.next_rec, self.next_frame = (float(x) for x in saved["run.next_times"])
        else:
            self.next_rec, self.next_frame = self.sim.t + self.rec_dt, self.sim.t + self.frame_dt
        self.events = sorted(t for t in scene.frame_times if t > self.sim.t * (1 + 1e-12))

    @property
    def t(self) -> float:
        return self.sim.t

    @property
    def steps(self) -> int:
        return self.sim.step_count

    def frame(self, tag="frame") -> None:
        self.manifest["frames"].append(write_frame(self.out, len(self.manifest["frames"]),
                                                   self.sim, self.options["vtk"], tag=tag,
                                                   fields=self.scene.frame_fields))

    def advance(self) -> None:
        sim, scene = self.sim, self.scene
        if scene.before_step is not None:
            scene.before_step(sim)
        try:
            sim.step()
        except ValueError as exc:            # a point off the grid: the run ends here
            raise RuntimeError(str(exc)) from None
        if sim.t >= self.next_rec * (1.0 - 1e-9) or sim.t >= self.t_end * (1.0 - 1e-12):
            row = history_row(sim, scene)
            if not np.isfinite(row["total_J"]):
                self.save()
                raise RuntimeError(f"non-finite energy at t = {sim.t:.6g} s (step "
                                   f"{sim.step_count}): the run diverged; see {self.out}")
            self.rows.append(row)
            self.next_rec += self.rec_dt
        regular = sim.t >= self.next_frame * (1.0 - 1e-9)
        event = bool(self.events) and sim.t >= self.events[0] * (1.0 - 1e-9)
        while self.events and sim.t >= self.events[0] * (1.0 - 1e-9):
            self.events.pop(0)
        if regular or event:                 # one snapshot per step, tagged event if asked
            self.frame("event" if event else "frame")
        if regular:
            self.next_frame += self.frame_dt

    def state(self) -> dict:
        return {}

    def write_history(self) -> None:
        atomic_write_csv(self.out / "history.csv", pd.DataFrame(self.rows),
                         empty_ok=self.scene.undefined)

    def save(self, _state=None) -> None:
        """The checkpoint (every parameter: defaults may change), then the history (a
        non-finite value fails there, after the save) and the manifest."""
        state = self.sim.state()
        state["run.scene"] = np.array(self.name)
        state["run.params"] = np.array(json.dumps(self.params))
        state["run.options"] = np.array(json.dumps(self.options))
        state.update(table_arrays(self.rows, "run.history"))
        state["run.frames"] = np.array(json.dumps(self.manifest["frames"]))
        state["run.next_times"] = np.array([self.next_rec, self.next_frame])
        save_checkpoint(self.path, **state)
        self.write_history()
        self.folder.write_manifest()

    def finish(self) -> list:
        """The last snapshot, the .pvd series, history and manifest, then the scene's report
        (after a checkpoint of the final state: a report that runs sub-runs, the wheel's other
        omegas, can be interrupted and resumed); returns the report's files."""
        out, m = self.out, self.manifest
        if m["frames"][-1]["step"] != self.sim.step_count:
            self.frame()
        if self.options["vtk"]:
            write_pvds(out, m["frames"])
        self.write_history()                 # the report may read it
        self.folder.write_manifest()         # the report reads the frames from it
        if self.scene.report is None:
            return []
        self.save()
        return [str(Path(f).relative_to(out)) if Path(f).is_relative_to(out) else str(f)
                for f in self.scene.report(self.sim, pd.DataFrame(self.rows), out)]

    def ended(self, message: str, stepping: bool):
        """The run failed (its files stay): in a step it ended there (history up to the last
        row, history.png, manifest ``ended_early``: EndedEarly), else manifest ``failed``."""
        out, m = self.out, self.manifest
        end = RunEnd("solver_failure", f"{message}; the run's files up to there are in {out}",
                     float(self.rows[-1]["time_s"]), past_s=float(self.sim.t)) \
            if stepping else None
        m.update(status="failed", error=message, steps=self.sim.step_count)
        try:
            if end is not None:
                self.write_history()
                plots.ended_history(pd.DataFrame(self.rows), end, out / "history.png", self.name)
                m.update(run_record([end]), figures=["history.png"])
            self.folder.write_manifest()
        except (RuntimeError, ValueError, OSError):
            end = None
        if end is not None:
            return EndedEarly([end], written=[str(out)])
        return RuntimeError(f"{message}; the run's files are in {out} (manifest status failed)")


def _run_scene(setup, out, params, resume, progress, vtk, frames, checkpoint_every, log,
               stop_after_steps, scene_name, yes=True) -> dict:
    """:func:`run_scene` with its log and progress settled."""
    folder = RunFolder(out)
    out, ckpt_path = folder.path, folder.path / "checkpoint.npz"
    spec = spec_of(setup)
    name = scene_name or spec.name
    given = coerce(dict(params or {}), setup)
    checkpoint_every = CHECKPOINT_EVERY.check(checkpoint_every)
    frames = None if frames is None else FRAMES.check(frames)
    saved, options = None, {"frames": frames, "vtk": vtk}
    if resume:
        saved, used, given = _resumed(out, spec, name, given, options, log)
    params = {**spec.defaults, **given}           # checked once, by coerce
    if saved is None:                             # a long run needs --yes (mpm2d.estimate)
        refusal = run_refusal(spec, params, given)
        if refusal is not None:
            raise refusal
        estimate.check_before_setup(setup, spec, params, name, yes, log)
        # a fresh run removes only what a previous run of ours wrote; a folder of the user's
        # is refused here, before the set-up and before anything is written
        folder.check()
    scene, held = _set_up(setup, params, given, name, str(ckpt_path) if saved else "",
                          progress)
    options["vtk"] = vtk = scene.vtk if options["vtk"] is None else bool(options["vtk"])
    check_step_count(scene, name)
    if saved is None:
        estimate.report_after_setup(scene, spec, params, name, yes, log)
    held.replay()                            # a set-up that succeeded: its warnings as they were
    if saved is None and (ckpt_path.exists() or previous_checkpoint(ckpt_path).exists()):
        log(f"note: {out} holds the checkpoint of an earlier run; this run starts afresh and "
            "replaces it (--resume continues it instead)")
    with Interrupts() as stop:         # from here on, a signal stops between steps
        removed = folder.prepare(resume=saved is not None)
        earlier = [f for f in removed if not TEMPORARY.match(Path(f).name)]
        for f in (f for f in removed if f not in earlier):
            log(f"removed {f}, a temporary file of an interrupted write")
        if earlier:
            log(f"removed the earlier run's {len(earlier)} files in {out} (snapshots, VTK, "
                "checkpoints, history, manifest, figures); its result tables are replaced "
                "when this run ends")
        run = _Run(folder, scene, name, params, spec.defaults, options, saved)
        sim, manifest = scene.sim, run.manifest
        if saved is not None:
            log(f"resumed from {used} at t = {sim.t:.6g} s, step {sim.step_count}")
        log(sim.describe())
        log(f"mode: {sim.mode}")
        if not run.rows:
            run.rows.append(history_row(sim, scene))
        if saved is None:                    # the folder is marked as a run of ours before its
            folder.write_manifest()          # first file (a run killed now can be replaced)
        if not manifest["frames"]:
            run.frame()
        stepping, figures = True, []
        with HeldWarnings() as held_run:
            try:
                bar = Progress(sim.t, scene.t_end, sim.step_count, label=spec.name,
                               t_start=float(run.rows[0]["time_s"])) if progress else None
                try:
                    complete = drive(run, checkpoint=run, every=checkpoint_every, progress=bar,
                                     stop_after=stop_after_steps)
                except KeyboardInterrupt:        # drive saved the checkpoint and says so
                    log(f"interrupted ({stop.pending or 'KeyboardInterrupt'}) at t = "
                        f"{sim.t:.6g} s (step {sim.step_count}); checkpoint written to "
                        f"{ckpt_path}: continue with --resume")
                    raise
                stepping = False
                if complete:
                    figures = run.finish()
                    manifest.update(status="complete", figures=figures)
            except (RuntimeError, ArithmeticError, ValueError) as exc:
                after = held_run.after()
                raise run.ended(f"{exc} ({after.strip()})" if after else str(exc),
                                stepping) from None
            except Exception as exc:         # a report's own fault: the run's files stay
                if stepping:
                    raise
                raise run.ended(f"the report failed: {type(exc).__name__}: {exc}",
                                False) from exc
        held_run.replay()                    # a run that succeeded: its warnings as they were
        manifest.update(history="history.csv", steps=sim.step_count)
        run.save()
        if complete:                         # the final state is whole: no fallback needed, and
            previous_checkpoint(ckpt_path).unlink(missing_ok=True)   # files match a fresh run
        log(f"{'finished' if complete else 'stopped'} at t = {sim.t:.6g} s after "
            f"{sim.step_count} steps; results in {out}")
        if stop.pending:                     # a signal while the last files were written
            log(f"{stop.pending} received after the last step: every output is complete")
    return {"scene": scene, "history": pd.DataFrame(run.rows), "figures": figures,
            "manifest": manifest, "complete": complete}
