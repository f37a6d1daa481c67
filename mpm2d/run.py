"""Running a scene: history, snapshots, checkpoints, resume, figures.

:func:`run_scene` is what ``mpm2d run SCENE --set key=value --out DIR`` calls. A scene's
``setup(**params)`` returns a :class:`Scene`; the runner steps it to ``t_end``, records a history
row every ``t_end/history_rows`` of simulated time, writes ``frames`` snapshots (npz + vtu), a
checkpoint every ``checkpoint_every`` seconds of wall time and at the end, then the scene's
report (CSV tables and PNG figures). ``resume=True`` continues from ``DIR/checkpoint.npz``
bit-for-bit: the model is rebuilt from the parameters stored with the checkpoint and its state
is loaded, so N steps equal k steps + restart + N - k steps exactly.
"""

from __future__ import annotations

import inspect
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from rheology.io import atomic_write_csv, load_checkpoint, save_checkpoint

from .output import write_frame, write_manifest, write_pvds
from .progress import Progress
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


def history_row(sim: Simulation, scene: Scene) -> dict:
    """The standard history columns plus the scene's."""
    row = {"time_s": sim.t, "step": sim.step_count, "dt_s": sim.last_dt}
    row.update(sim.energies())
    p = sim.momentum()
    row["momentum_x_kg_m_per_s"], row["momentum_y_kg_m_per_s"] = float(p[0]), float(p[1])
    if scene.record is not None:
        row.update(scene.record(sim))
    return row


def coerce(params: dict, setup: Callable) -> dict:
    """Convert ``--set`` strings to the types of ``setup``'s defaults; reject unknown keys."""
    sig = inspect.signature(setup)
    known = {k: p.default for k, p in sig.parameters.items()
             if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)}
    out = {}
    for k, v in params.items():
        if k not in known:
            raise ValueError(f"unknown parameter {k!r}; valid: {', '.join(sorted(known))}")
        d = known[k]
        if not isinstance(v, str):
            out[k] = v
            continue
        try:
            if isinstance(d, bool):
                if v.lower() not in ("true", "false", "1", "0", "yes", "no"):
                    raise ValueError
                out[k] = v.lower() in ("true", "1", "yes")
            elif isinstance(d, int):
                out[k] = int(v)
            elif isinstance(d, float):
                out[k] = float(v)
            elif d is None:
                try:
                    out[k] = float(v)
                except ValueError:
                    out[k] = v
            else:
                out[k] = v
        except ValueError:
            raise ValueError(f"{k} = {v!r} is not a valid {type(d).__name__}") from None
    return out


def run_scene(setup: Callable, out, params: dict | None = None, *, resume: bool = False,
              progress: bool = True, vtk: bool = True, frames: int | None = None,
              checkpoint_every: float = 60.0, log=None, stop_after_steps: int | None = None,
              scene_name: str = "") -> dict:
    """Run a scene to its end time (or ``stop_after_steps`` steps, then checkpoint).

    Parameters
    ----------
    setup : the scene's ``setup`` function
    out : output folder (created)
    params : parameter overrides (strings from the CLI are converted)
    resume : continue from ``out/checkpoint.npz``
    progress : progress bar on stderr
    vtk : also write .vtu snapshots
    frames : number of snapshots (default: the scene's)
    checkpoint_every : wall-clock seconds between checkpoints
    log : callable(str) for the run log (default: print to stdout)
    stop_after_steps : stop (with a checkpoint) after this many steps in this call

    Returns
    -------
    dict with ``scene``, ``history`` (DataFrame), ``figures``, ``manifest``, ``complete``.
    """
    log = log or (lambda msg: print(msg, flush=True))
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ckpt_path = out / "checkpoint.npz"
    params = coerce(dict(params or {}), setup)
    saved = None
    if resume:
        if not ckpt_path.exists():
            raise ValueError(f"--resume: no checkpoint at {ckpt_path}")
        saved = load_checkpoint(ckpt_path)
        stored = json.loads(str(saved["run.params"]))
        if params and any(stored.get(k) != v for k, v in params.items()):
            raise ValueError(f"--resume: parameters {params} differ from the checkpoint's "
                             f"{stored}; resume without --set or start a new folder")
        params = stored
    scene = setup(**params)
    sim = scene.sim
    nframes = scene.frames if frames is None else int(frames)
    t_end = scene.t_end
    rec_dt = t_end / max(scene.history_rows, 1)
    frame_dt = t_end / max(nframes, 1)
    manifest = {"scene": scene_name or setup.__module__.rsplit(".", 1)[-1],
                "command": " ".join(sys.argv), "params": {**_defaults(setup), **params},
                "mode": sim.mode, "transfer": sim.transfer, "description": sim.describe(),
                "grid": {"nx": sim.grid.nx, "ny": sim.grid.ny, "h_m": sim.grid.h,
                         "origin_m": list(sim.grid.origin), "axisymmetric": sim.grid.axisymmetric,
                         "boundaries": sim.grid.boundaries},
                "t_end_s": t_end, "notes": scene.notes, "frames": [], "status": "running"}
    rows: list[dict] = []
    if saved is not None:
        sim.load_state({k: v for k, v in saved.items() if not k.startswith("run.")})
        cols = [str(c) for c in saved["run.history_columns"]]
        rows = [dict(zip(cols, r)) for r in saved["run.history"]]
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
    bar = Progress(sim.t, t_end, sim.step_count, label=f"{manifest['scene']} ") if progress else None
    last_ckpt = time.perf_counter()
    steps_here = 0

    def checkpoint():
        hist = pd.DataFrame(rows)
        state = sim.state()
        state["run.params"] = np.array(json.dumps(params, default=str))
        state["run.history"] = hist.to_numpy(dtype=float)
        state["run.history_columns"] = np.array(list(hist.columns))
        state["run.frames"] = np.array(json.dumps(manifest["frames"]))
        state["run.next_times"] = np.array([next_rec, next_frame])
        save_checkpoint(ckpt_path, **state)
        atomic_write_csv(out / "history.csv", hist)
        write_manifest(out, manifest)

    complete = True
    try:
        while sim.t < t_end * (1.0 - 1e-12):
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
            if sim.t >= next_frame * (1.0 - 1e-9):
                manifest["frames"].append(write_frame(out, len(manifest["frames"]), sim, vtk))
                next_frame += frame_dt
            if events and sim.t >= events[0] * (1.0 - 1e-9):
                while events and sim.t >= events[0] * (1.0 - 1e-9):
                    events.pop(0)
                manifest["frames"].append(write_frame(out, len(manifest["frames"]), sim, vtk,
                                                      tag="event"))
            if bar is not None:
                bar.update(sim.t, sim.step_count)
            if time.perf_counter() - last_ckpt > checkpoint_every:
                checkpoint()
                last_ckpt = time.perf_counter()
    except KeyboardInterrupt:
        checkpoint()
        log(f"interrupted at t = {sim.t:.6g} s (step {sim.step_count}); checkpoint written: "
            "continue with --resume")
        raise
    if bar is not None:
        bar.close(sim.t, sim.step_count)
    history = pd.DataFrame(rows)
    figures = []
    if complete:
        if manifest["frames"][-1]["step"] != sim.step_count:
            manifest["frames"].append(write_frame(out, len(manifest["frames"]), sim, vtk))
        if vtk:
            write_pvds(out, manifest["frames"])
        write_manifest(out, manifest)                  # the report reads the frames from it
        if scene.report is not None:
            figures = [str(Path(f).relative_to(out)) if Path(f).is_relative_to(out) else str(f)
                       for f in scene.report(sim, history, out)]
        manifest["status"] = "complete"
        manifest["figures"] = figures
    manifest["history"] = "history.csv"
    manifest["steps"] = sim.step_count
    checkpoint()
    log(f"{'finished' if complete else 'stopped'} at t = {sim.t:.6g} s after {sim.step_count} "
        f"steps; results in {out}")
    return {"scene": scene, "history": history, "figures": figures, "manifest": manifest,
            "complete": complete}


def _defaults(setup) -> dict:
    return {k: p.default for k, p in inspect.signature(setup).parameters.items()
            if p.default is not inspect.Parameter.empty}
