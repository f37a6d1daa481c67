"""Running a scene: history, snapshots, checkpoints, resume, figures.

:func:`run_scene` is what ``mpm2d run SCENE --set key=value --out DIR`` calls. The parameters
are validated first (every key through the scene's declared ranges, :mod:`mpm2d.scenes.spec`,
and the run's memory estimate): bad input raises ``ValueError`` before anything is written. A
scene's ``setup(**params)`` returns a :class:`Scene`; the runner steps it to ``t_end``, records a
history row every ``t_end/history_rows`` of simulated time, writes ``frames`` snapshots (npz +
VTK), a checkpoint every ``checkpoint_every`` seconds of wall time and at the end, then the
scene's report (CSV tables and PNG figures).

Interruption: SIGINT and SIGTERM are deferred to the end of the current step (a signal inside a
step would leave the state half-updated: positions moved, stresses not); the runner then
writes a checkpoint and raises ``KeyboardInterrupt``. ``resume=True`` continues from
``DIR/checkpoint.npz`` (or its kept predecessor if it is corrupt) bit-for-bit: the model is
rebuilt from the parameters stored with the checkpoint, its state is loaded, and every file the
resumed run writes (history, manifest, frames, VTK, result tables, figures) is byte-identical to
an uninterrupted run's. A resume of another scene, with other parameters or other output options
is refused by name. The scene's set-up (a bed's geostatic relaxation can take minutes at paper
size; a resume repeats it, then loads the checkpoint) runs before anything is written and stops
at once on SIGINT/SIGTERM, writing nothing.
"""

from __future__ import annotations

import json
import math
import re
import signal
import threading
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from rheology.io import (atomic_write_csv, check_output_dir, load_checkpoint,
                         previous_checkpoint, save_checkpoint)

from .output import write_frame, write_manifest, write_pvds
from .progress import Progress
from .simulation import Simulation

#: temporary files of an atomic write (``.NAME.XXXXXXXX.suffix``) left by a killed run
_TEMP = re.compile(r"^\..+\.[a-z0-9_]{8}\.(npz|tmp|vtu|pvd|png|csv|json)$")
#: a run whose first stable step would need more steps than this to reach t_end is refused
#: (a cfl of 1e-300 or a t_end of years: it would never end; 1e8 steps of the smallest scene
#: take about a day on one core)
MAX_STEPS = 1e8


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
    frames : int
        Number of snapshots after the initial one.
    history_rows : int
        Approximate number of history rows.
    record : callable(sim) -> dict, optional
        Extra history columns (units in the names).
    report : callable(sim, history DataFrame, out Path) -> list of Path, optional
        Result tables and figures written after the run.
    before_step : callable(sim), optional
        Called before every step (time-dependent loading).
    frame_times : tuple of float
        Extra snapshot times [s] (written at the first step reaching each, tagged ``event`` in
        the manifest), e.g. the profile times a report compares; reports read them back with
        :func:`mpm2d.output.load_frames`, so they survive ``--resume``.
    notes : str
        Written to the manifest.
    undefined : tuple of str
        History columns that may be undefined by construction at some rows (NaN, written as an
        empty cell), e.g. a stress behind a front before the front has formed; every other
        history value must be finite (else the run fails with diagnostics).
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
    notes: str = ""
    undefined: tuple = ()


def history_row(sim: Simulation, scene: Scene) -> dict:
    """The standard history columns plus the scene's."""
    row = {"time_s": sim.t, "step": int(sim.step_count), "dt_s": sim.last_dt}
    row.update(sim.energies())
    p = sim.momentum()
    row["momentum_x_kg_m_per_s"], row["momentum_y_kg_m_per_s"] = float(p[0]), float(p[1])
    if scene.record is not None:
        row.update(scene.record(sim))
    return row


def spec_of(setup: Callable):
    """The declared parameters (:class:`mpm2d.scenes.spec.SceneSpec`) of a scene's ``setup``."""
    spec = getattr(setup, "spec", None)
    if spec is None:
        raise TypeError(f"{getattr(setup, '__module__', setup)}.setup declares no parameters "
                        "(decorate it with mpm2d.scenes.spec.parameters_of)")
    return spec


def coerce(params: dict, setup: Callable) -> dict:
    """Convert ``--set`` strings (or Python values) to the declared types and check every key
    (type, finiteness, range, derived bounds, memory estimate) through the scene's declaration;
    returns the overrides with their canonical types.

    Raises
    ------
    ValueError
        One line naming the parameter, its value and the valid range (or an unknown key).
    """
    return spec_of(setup).coerce(dict(params))


class _DeferredSignals:
    """SIGINT/SIGTERM recorded instead of raised while a step runs (main thread only).

    Nested windows (a run whose report runs sub-runs, the wheel's other omegas) share what they
    record: a signal that came while the outer run finished its last files stops the sub-run at
    its first step, and one recorded by a sub-run is the outer run's too."""

    _open: list = []

    def __init__(self):
        self.pending = None
        self._old = {}

    def __enter__(self):
        if self._open:
            self.pending = self._open[-1].pending
        self._open.append(self)
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._record)
        return self

    def _record(self, signum, frame):
        self.pending = signal.Signals(signum).name

    def __exit__(self, *exc):
        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._open.remove(self)
        if self._open and self.pending:
            self._open[-1].pending = self.pending
        return False


def check_step_count(scene, name: str) -> None:
    """Refuse (ValueError, one line) a run that needs more than MAX_STEPS steps at its first
    stable step: the parameters that set it are named with their values (cfl, t_end, the
    resolution) and the step count they imply."""
    sim = scene.sim
    dt = sim.user_dt if sim.user_dt is not None else sim.stable_dt()
    steps = (scene.t_end - sim.t) / dt
    if steps > MAX_STEPS:
        knobs = f"cfl = {sim.cfl:g}, t_end = {scene.t_end:g} s, h = {sim.grid.h:g} m"
        raise ValueError(f"scene {name}: {knobs} give a step of {dt:.3g} s, about "
                         f"{steps:.3g} steps to t_end; valid: at most {MAX_STEPS:.0e} steps "
                         "(raise cfl, shorten t_end or coarsen the grid)")


def check_step_bound(spec, params: dict, name: str) -> None:
    """The step-count refusal of :func:`check_step_count` before the scene's set-up (which takes
    seconds to minutes: a bed's geostatic relaxation), where the parameters bound the stable step
    (:meth:`mpm2d.scenes.spec.SceneSpec.step_bound`): a run that needs more than MAX_STEPS
    steps even at that bound is refused at once, one line naming cfl, t_end and h."""
    bound = spec.step_bound(params)
    if bound is None:
        return
    dt, t_end, knobs = bound
    with np.errstate(all="ignore"):
        steps = t_end / dt if dt > 0 else math.inf
    if steps > MAX_STEPS:
        raise ValueError(f"scene {name}: {knobs} give a step of at most {dt:.3g} s, at least "
                         f"{steps:.3g} steps to t_end; valid: at most {MAX_STEPS:.0e} steps "
                         "(raise cfl, shorten t_end or coarsen the grid)")


def _remove_stale_temporaries(out: Path) -> list[str]:
    """Delete the temporary files of atomic writes a killed run (SIGKILL, power loss) left."""
    gone = []
    for folder in (out, out / "frames", out / "vtk"):
        if folder.is_dir():
            for f in folder.iterdir():
                if f.is_file() and _TEMP.match(f.name):
                    f.unlink()
                    gone.append(str(f.relative_to(out)))
    return gone


_FRAME = re.compile(r"frame_\d+\.npz$")


def _remove_previous_run(out: Path) -> list[str]:
    """Delete what an earlier run wrote into ``out`` that a fresh run would not overwrite in
    full: its snapshots (frames/frame_N.npz, vtk/*.vtu, *.pvd), checkpoints, history, manifest
    and the figures its manifest lists (a fresh run with fewer frames left the old ones beside
    its own). The scene's result tables are rewritten by the new run at its end."""
    gone = []
    man = out / "manifest.json"
    figures = []
    if man.is_file():
        try:
            figures = [str(f) for f in json.loads(man.read_text()).get("figures", [])]
        except (ValueError, OSError, AttributeError):
            figures = []
    files = [out / "frames" / f.name for f in (out / "frames").glob("frame_*.npz")
             if _FRAME.match(f.name)] if (out / "frames").is_dir() else []
    if (out / "vtk").is_dir():
        files += [f for f in (out / "vtk").iterdir() if f.suffix in (".vtu", ".pvd")]
    files += [out / n for n in ("checkpoint.npz", "checkpoint.prev.npz", "history.csv",
                                "manifest.json")]
    files += [out / f for f in figures if "/" not in f and "\\" not in f]
    for f in files:
        if f.is_file():
            f.unlink()
            gone.append(str(f.relative_to(out)))
    return gone


def _history_arrays(rows: list[dict]) -> dict[str, np.ndarray]:
    """The history as one typed array per column (integer columns stay integer)."""
    hist = pd.DataFrame(rows)
    out = {"run.history_columns": np.array(list(hist.columns))}
    for i, c in enumerate(hist.columns):
        out[f"run.history.{i}"] = hist[c].to_numpy()
    return out


def _history_rows(saved: dict) -> list[dict]:
    cols = [str(c) for c in saved["run.history_columns"]]
    if "run.history.0" not in saved:                 # a checkpoint of an older version
        return [dict(zip(cols, r)) for r in saved["run.history"]]
    arrays = [saved[f"run.history.{i}"] for i in range(len(cols))]
    return [{c: a[k].item() for c, a in zip(cols, arrays)} for k in range(len(arrays[0]))]


def command_line(name: str, params: dict, defaults: dict, frames, vtk: bool) -> str:
    """The canonical command of a run (deterministic: no output folder, no --resume)."""
    sets = " ".join(f"--set {k}={v}" for k, v in params.items()
                    if k in defaults and v != defaults[k])
    return " ".join(filter(None, [f"mpm2d run {name}", sets,
                                  f"--frames {frames}" if frames is not None else "",
                                  "" if vtk else "--no-vtk"]))


def run_scene(setup: Callable, out, params: dict | None = None, *, resume: bool = False,
              progress: bool = True, vtk: bool | None = None, frames: int | None = None,
              checkpoint_every: float = 60.0, log=None, stop_after_steps: int | None = None,
              scene_name: str = "", quiet: bool = False) -> dict:
    """Run a scene to its end time (or ``stop_after_steps`` steps, then checkpoint).

    Parameters
    ----------
    setup : the scene's (declared) ``setup`` function
    out : output folder (created once the input is valid)
    params : parameter overrides (strings from the CLI are converted)
    resume : continue from ``out/checkpoint.npz``
    progress : progress bar on stderr (tqdm)
    vtk : also write VTK snapshots (points and grid); default True, or the checkpoint's choice
    frames : number of snapshots (default: the scene's, or the checkpoint's)
    checkpoint_every : wall-clock seconds between checkpoints (> 0)
    log : callable(str) for the run log (default: print to stdout)
    stop_after_steps : stop (with a checkpoint) after this many steps in this call
    quiet : no progress bar and no log lines (set-up, notes, the closing line; ``mpm2d run
        --quiet``); a run started inside a quiet run (the wheel report's other omegas) is quiet
        too, whatever its own ``log`` and ``progress``. Errors are raised as always.

    Returns
    -------
    dict with ``scene``, ``history`` (DataFrame), ``figures``, ``manifest``, ``complete``.

    Raises
    ------
    ValueError
        Bad input (a parameter, a resume that does not match the checkpoint), before anything
        is written.
    RuntimeError
        The run diverged (non-finite energy); a checkpoint is written first.
    KeyboardInterrupt
        SIGINT/SIGTERM: after the current step, a checkpoint is written (during the set-up:
        at once, nothing written).
    """
    quiet = quiet or bool(_Quiet.depth)
    if quiet:
        log, progress = (lambda msg: None), False
    log = log or (lambda msg: print(msg, flush=True))
    with _Quiet(quiet):
        return _run_scene(setup, out, params, resume, progress, vtk, frames, checkpoint_every,
                          log, stop_after_steps, scene_name)


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


def _run_scene(setup, out, params, resume, progress, vtk, frames, checkpoint_every, log,
               stop_after_steps, scene_name) -> dict:
    """:func:`run_scene` with its log and progress settled."""
    out = check_output_dir("--out", out)
    ckpt_path = out / "checkpoint.npz"
    spec = spec_of(setup)
    name = scene_name or spec.name
    given = coerce(dict(params or {}), setup)
    if not (isinstance(checkpoint_every, (int, float)) and checkpoint_every > 0):
        raise ValueError(f"checkpoint_every = {checkpoint_every} must be > 0 s")
    if frames is not None and (int(frames) != frames or frames < 1):
        raise ValueError(f"frames = {frames} must be an integer >= 1")
    saved = None
    options = {"frames": frames, "vtk": vtk}
    if resume:
        if not ckpt_path.exists() and not ckpt_path.with_name("checkpoint.prev.npz").exists():
            raise ValueError(f"--resume: no checkpoint at {ckpt_path}; run without --resume to "
                             "start")
        saved = load_checkpoint(ckpt_path, required=("run.params", "t", "step"), log=log)
        stored_name = str(saved["run.scene"]) if "run.scene" in saved else None
        stored = json.loads(str(saved["run.params"]))
        if stored_name is not None and stored_name != name:
            raise ValueError(f"--resume: the checkpoint in {out} is of scene {stored_name!r}, "
                             f"not {name!r}; resume it with 'mpm2d run {stored_name} --resume' "
                             "or start a new folder")
        foreign = [k for k in stored if k not in spec.params]
        if foreign:
            raise ValueError(f"--resume: the checkpoint in {out} has parameters "
                             f"{', '.join(foreign)} that scene {name} does not have: it was "
                             "written by another scene; start a new folder")
        stored = spec.coerce(stored)
        full_stored = {**spec.defaults, **stored}
        for k, v in given.items():
            if full_stored[k] != v:
                def shown(x):
                    return "none (the scene's default)" if x is None else x
                raise ValueError(f"--resume: {k} = {shown(v)} differs from the checkpoint's {k} "
                                 f"= {shown(full_stored[k])}; resume without --set {k} or start "
                                 "a new folder")
        given = stored
        old = json.loads(str(saved["run.options"])) if "run.options" in saved else {}
        for k, v in old.items():
            if options.get(k) is not None and options[k] != v:
                raise ValueError(f"--resume: {'--frames' if k == 'frames' else '--no-vtk'} "
                                 f"differs from the interrupted run's ({k} = {v})")
            options[k] = v if options.get(k) is None else options[k]
    vtk = True if options["vtk"] is None else bool(options["vtk"])
    options["vtk"] = vtk
    params = spec.validate(given)
    check_step_bound(spec, params, name)     # before the set-up where the parameters tell
    # the scene's set-up (a bed's geostatic relaxation can take minutes) is interrupted at once
    # by Ctrl-C or SIGTERM (there is nothing to save yet); nothing is written before it ends
    log(f"setting up scene {name}" + (" (then the checkpoint is loaded)" if saved is not None
                                       else "") + "...")
    # numpy's warnings of the set-up (an overflow from a modulus of 1e-300) are held: a set-up
    # that then fails is refused in one line that cites the first; one that succeeds shows them
    held = []
    try:
        with warnings.catch_warnings(record=True) as held:
            warnings.simplefilter("always", RuntimeWarning)
            scene = setup(**params)
    except KeyboardInterrupt:
        raise KeyboardInterrupt("during the scene's set-up, nothing written"
                                + (f"; {ckpt_path} is as it was" if saved is not None else ""))
    except (ArithmeticError, ValueError) as exc:
        # a value inside its declared range whose set-up arithmetic still breaks down (a length
        # of 1e-300: a division by zero, or an area of 0 refused by the body it builds; a
        # modulus that overflows): the parameters given are the cause. A set-up refusal that
        # names a given parameter itself stands as it is.
        if isinstance(exc, ValueError) and any(re.search(rf"\b{re.escape(k)}\b", str(exc))
                                               for k in given):
            raise
        given_text = ", ".join(f"{k} = {v}" for k, v in given.items()) or "the defaults"
        first = next((w for w in held if issubclass(w.category, RuntimeWarning)), None)
        after = f" after numpy's '{first.message}'" if first is not None else ""
        raise ValueError(f"scene {name}: with {given_text} the set-up breaks down "
                         f"({type(exc).__name__}: {exc}{after}); valid: values away from the "
                         f"extremes of their ranges ('mpm2d show {name}')") from None
    for w in held:                           # a set-up that succeeded: its warnings as they were
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    with np.errstate(all="ignore"):          # inf/0 steps are the check's to refuse
        check_step_count(scene, name)
    if saved is None and (ckpt_path.exists() or ckpt_path.with_name("checkpoint.prev.npz").exists()):
        log(f"note: {out} holds the checkpoint of an earlier run; this run starts afresh and "
            "replaces it (--resume continues it instead)")
    with _DeferredSignals() as stop:         # from here on, a signal stops between steps
        out.mkdir(parents=True, exist_ok=True)
        for f in _remove_stale_temporaries(out):
            log(f"removed {f}, a temporary file of an interrupted write")
        if saved is None:
            gone = _remove_previous_run(out)
            if gone:
                log(f"removed the earlier run's {len(gone)} files in {out} (snapshots, VTK, "
                    "checkpoints, history, manifest, figures); its result tables are replaced "
                    "when this run ends")
        sim = scene.sim
        nframes = scene.frames if options["frames"] is None else int(options["frames"])
        t_end = scene.t_end
        rec_dt = t_end / max(scene.history_rows, 1)
        frame_dt = t_end / max(nframes, 1)
        manifest = {"scene": name,
                    "command": command_line(name, params, spec.defaults, options["frames"], vtk),
                    "params": params, "mode": sim.mode, "transfer": sim.transfer,
                    "description": sim.describe(),
                    "grid": {"nx": sim.grid.nx, "ny": sim.grid.ny, "h_m": sim.grid.h,
                             "origin_m": list(sim.grid.origin),
                             "axisymmetric": sim.grid.axisymmetric,
                             "boundaries": sim.grid.boundaries},
                    "t_end_s": t_end, "notes": scene.notes, "frames": [], "status": "running"}
        rows: list[dict] = []
        if saved is not None:
            sim.load_state({k: v for k, v in saved.items() if not k.startswith("run.")})
            rows = _history_rows(saved)
            manifest["frames"] = json.loads(str(saved["run.frames"]))
            next_times = saved["run.next_times"]
            log(f"resumed from {ckpt_path} at t = {sim.t:.6g} s, step {sim.step_count}")
        log(sim.describe())
        log(f"mode: {sim.mode}")
        if not rows:
            rows.append(history_row(sim, scene))
        if not manifest["frames"]:
            manifest["frames"].append(write_frame(out, 0, sim, vtk))
        if saved is not None:
            next_rec, next_frame = float(next_times[0]), float(next_times[1])
        else:
            next_rec, next_frame = sim.t + rec_dt, sim.t + frame_dt
        events = sorted(t for t in scene.frame_times if t > sim.t * (1 + 1e-12))
        last_ckpt = time.perf_counter()
        steps_here = 0

        def write_history(hist):
            atomic_write_csv(out / "history.csv", hist, empty_ok=scene.undefined)

        def checkpoint():
            state = sim.state()
            state["run.scene"] = np.array(name)
            state["run.params"] = np.array(json.dumps(params))     # all: defaults may change
            state["run.options"] = np.array(json.dumps(options))
            state.update(_history_arrays(rows))
            state["run.frames"] = np.array(json.dumps(manifest["frames"]))
            state["run.next_times"] = np.array([next_rec, next_frame])
            save_checkpoint(ckpt_path, **state)
            write_history(pd.DataFrame(rows))        # a non-finite value fails here, after the save
            write_manifest(out, manifest)

        complete = True
        bar = Progress(sim.t, t_end, sim.step_count, label=name) if progress else None
        try:
            while sim.t < t_end * (1.0 - 1e-12):
                if stop.pending:
                    raise KeyboardInterrupt
                if stop_after_steps is not None and steps_here >= stop_after_steps:
                    complete = False
                    break
                if scene.before_step is not None:
                    scene.before_step(sim)
                sim.step()
                steps_here += 1
                if sim.t >= next_rec * (1.0 - 1e-9) or sim.t >= t_end * (1.0 - 1e-12):
                    row = history_row(sim, scene)
                    if not np.isfinite(row["total_J"]):
                        checkpoint()
                        raise RuntimeError(f"non-finite energy at t = {sim.t:.6g} s (step "
                                           f"{sim.step_count}): the run diverged; see {out}")
                    rows.append(row)
                    next_rec += rec_dt
                regular = sim.t >= next_frame * (1.0 - 1e-9)
                event = bool(events) and sim.t >= events[0] * (1.0 - 1e-9)
                while events and sim.t >= events[0] * (1.0 - 1e-9):
                    events.pop(0)
                if regular or event:             # one snapshot per step, tagged event if asked
                    manifest["frames"].append(write_frame(out, len(manifest["frames"]), sim, vtk,
                                                          tag="event" if event else "frame"))
                if regular:
                    next_frame += frame_dt
                if bar is not None:
                    bar.update(sim.t, sim.step_count)
                if time.perf_counter() - last_ckpt > checkpoint_every:
                    checkpoint()
                    last_ckpt = time.perf_counter()
        except KeyboardInterrupt:
            if bar is not None:
                bar.close(sim.t, sim.step_count)
            checkpoint()
            log(f"interrupted ({stop.pending or 'KeyboardInterrupt'}) at t = {sim.t:.6g} s "
                f"(step {sim.step_count}); checkpoint written to {ckpt_path}: continue with "
                "--resume")
            raise KeyboardInterrupt(f"checkpoint written to {ckpt_path}: rerun with --resume "
                                    "to continue") from None
        if bar is not None:
            bar.close(sim.t, sim.step_count)
        history = pd.DataFrame(rows)
        figures = []
        if complete:
            if manifest["frames"][-1]["step"] != sim.step_count:
                manifest["frames"].append(write_frame(out, len(manifest["frames"]), sim, vtk))
            if vtk:
                write_pvds(out, manifest["frames"])
            write_history(history)               # the report may read it
            write_manifest(out, manifest)        # the report reads the frames from it
            if scene.report is not None:
                # the final state first: a report that runs sub-runs (the wheel's other omegas)
                # can be interrupted, and the same command with --resume then finds this run
                # complete, goes straight to its report and resumes the sub-run
                checkpoint()
                figures = [str(Path(f).relative_to(out)) if Path(f).is_relative_to(out)
                           else str(f) for f in scene.report(sim, history, out)]
            manifest["status"] = "complete"
            manifest["figures"] = figures
        manifest["history"] = "history.csv"
        manifest["steps"] = sim.step_count
        checkpoint()
        if complete:                         # the final state is whole: no fallback needed, and
            previous_checkpoint(ckpt_path).unlink(missing_ok=True)   # files match a fresh run
        log(f"{'finished' if complete else 'stopped'} at t = {sim.t:.6g} s after "
            f"{sim.step_count} steps; results in {out}")
        if stop.pending:                     # a signal while the last files were written
            log(f"{stop.pending} received after the last step: every output is complete")
    return {"scene": scene, "history": history, "figures": figures, "manifest": manifest,
            "complete": complete}
