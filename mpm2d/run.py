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

Refusals before anything is written (ValueError, one line, the only output): a run needing more
than MAX_STEPS steps or fewer than the scene's ``min_steps`` at its first stable step; history
values the scene's analysis divides by that are zero at t = 0 (``Scene.divides_by``); a first
step that fails (tried on a copy). Each names the parameter the user set that causes it, with
its bound at the other values (:func:`blame`: each given key put back to its default, then a
bisection between value and default over new set-ups). A fresh run into a folder removes only
the files a previous run of ours wrote (:func:`previous_run_files`, from its manifest); a
non-empty folder without our manifest is refused. A run whose step fails (a diverging step, a
failed local update, a point off the grid) ends there (:mod:`rheology.run_end`): it keeps its
files, writes its history up to the last recorded row, marks ``manifest.json`` ``status:
ended_early`` with ``ends`` (where and why) and raises :class:`rheology.run_end.EndedEarly`
(exit status 3); one that fails after its last step (a report that cannot be written) marks it
``status: failed`` with the message and raises RuntimeError. Both cite numpy's first warning
(numpy's warnings of the run are held, shown only when the run succeeds).
"""

from __future__ import annotations

import json
import math
import re
import threading
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from runkit.io import (atomic_write_csv, check_output_dir, load_checkpoint,
                         previous_checkpoint, save_checkpoint)
from runkit.limits import MAX_STEPS
from runkit.run import TEMPORARY, Interrupts, Progress
from rheology.run_end import EndedEarly, RunEnd, run_record

from . import estimate, plots
from .output import write_frame, write_manifest, write_pvds
from runkit.params import shown as shown_value
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
    frame_fields : tuple of str
        The point fields a snapshot keeps besides ``id`` and ``x`` (``v``, ``m``, ``f``...);
        empty: every field (a scene whose snapshots would be too large keeps what its report
        reads).
    vtk : bool
        Whether VTK snapshots are written by default (``mpm2d run --vtk``/``--no-vtk`` choose).
    notes : str
        Written to the manifest.
    undefined : tuple of str
        History columns that may be undefined by construction at some rows (NaN, written as an
        empty cell), e.g. a stress behind a front before the front has formed; every other
        history value must be finite (else the run fails with diagnostics).
    min_steps : int
        The fewest steps the run (and the scene's analysis) needs: a run whose end time is
        shorter than ``min_steps`` first stable steps is refused before anything is written
        (at least one step, else the results would be made up from the initial state).
    divides_by : tuple of str
        History columns whose initial value the scene's analysis divides by (the disks' energy
        loss is relative to the initial energy): with parameters that make one of them zero or
        non-finite at t = 0 (speed = 1e-300: the kinetic energy underflows to 0) the analysis is
        undefined and the run is refused before anything is written, naming the parameter set
        with its bound.
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
    divides_by: tuple = ()


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


def _first_step(scene) -> tuple[float, float, int]:
    """(first step [s], number of steps to t_end at it, the fewest steps the scene needs) of a
    freshly set-up scene (inf/0 steps and NaN are returned, not raised)."""
    sim = scene.sim
    with np.errstate(all="ignore"):
        dt = sim.user_dt if sim.user_dt is not None else sim.stable_dt()
        steps = (scene.t_end - sim.t) / dt if dt > 0 else math.inf
    return float(dt), float(steps), max(1, int(scene.min_steps))


def _steps_ok(scene) -> bool:
    _, steps, need = _first_step(scene)
    return bool(need <= steps <= MAX_STEPS)


def _after_numpy(held) -> str:
    """" after numpy's 'MESSAGE'" for the first RuntimeWarning among ``held`` (warnings recorded
    by ``warnings.catch_warnings(record=True)``), "" when there is none."""
    first = next((w for w in held if issubclass(w.category, RuntimeWarning)), None)
    return f" after numpy's '{first.message}'" if first is not None else ""


def check_step_count(scene, name: str) -> None:
    """Refuse (ValueError, one line) a run that needs more than MAX_STEPS steps, or fewer than
    the scene's ``min_steps`` (at least one: an end time below one stable step), at its first
    stable step. Without the set-up function the parameters cannot be blamed one by one: the
    message names the step and the end time (:func:`run_scene` names the parameter set)."""
    dt, steps, need = _first_step(scene)
    if steps > MAX_STEPS or not steps >= need:
        raise ValueError(f"scene {name}: a step of {dt:.3g} s to t_end = {scene.t_end:.3g} s is "
                         f"{steps:.3g} steps; valid: {need} to {MAX_STEPS:.0e} steps")


#: a set-up taking longer than this [wall s] is announced ('setting up scene X...'); a fast one
#: is not, so that a refusal after it is the only output
SETUP_NOTICE_S = 2.0
#: wall seconds the search for the parameter that makes a run too long/short may take (set-ups
#: of bed scenes take seconds each: the bound found so far is reported, a conservative one)
BLAME_BUDGET_S = 20.0


def _round_toward(x: float, good_side_up: bool) -> float:
    """``x`` to 3 significant digits, rounded away from the invalid side."""
    if x == 0 or not math.isfinite(x):
        return x
    e = math.floor(math.log10(abs(x))) - 2
    m = x / 10.0 ** e
    m = math.ceil(m) if good_side_up else math.floor(m)
    return float(f"{m * 10.0 ** e:.3g}")


def _bisect(ok, bad: float, good: float, deadline: float) -> float:
    """The valid end of [bad, good] nearest the transition (log-spaced when both are > 0)."""
    log = bad > 0 and good > 0
    for _ in range(60):
        if time.perf_counter() > deadline:
            break
        mid = math.exp(0.5 * (math.log(bad) + math.log(good))) if log else 0.5 * (bad + good)
        if mid in (bad, good) or (log and abs(math.log(good / bad)) < 0.02) or \
                (not log and abs(good - bad) <= 1e-3 * max(abs(good), abs(bad))):
            break
        if ok(mid):
            good = mid
        else:
            bad = mid
    return good


def refuse_step_count(setup, scene, params: dict, given: dict, name: str) -> None:
    """Raise the one-line ValueError of a run needing more than MAX_STEPS steps or fewer than the
    scene's ``min_steps`` at its first stable step, said about the parameter the user set.

    Each given parameter is put back to its default in turn (a new set-up): those whose default
    makes the step count valid are named, with their valid bound at the others' values found by
    bisection between the value given and the default (a fixed ``dt`` exactly: the step is dt);
    when no single one does, every given parameter is named. The search is limited to
    BLAME_BUDGET_S wall seconds (the bound found so far is a valid one)."""
    dt, steps, need = _first_step(scene)
    if need <= steps <= MAX_STEPS:
        return
    long = not steps < need
    spec = spec_of(setup)
    duration = scene.t_end - scene.sim.t
    what = (f"a step of {dt:.3g} s to t_end = {scene.t_end:.3g} s is {steps:.3g} steps, more "
            f"than {MAX_STEPS:.0e}" if long else
            f"t_end = {scene.t_end:.3g} s is {steps:.3g} of its first stable steps ({dt:.3g} s); "
            f"the run needs at least {need}")
    deadline = time.perf_counter() + BLAME_BUDGET_S
    spec_changed = [k for k, v in given.items() if v != spec.defaults.get(k)]
    if not spec_changed:
        raise ValueError(f"scene {name}: {what} with its defaults")
    special = {}
    if "dt" in spec_changed and scene.sim.user_dt is not None:
        bound = duration / (MAX_STEPS if long else need)
        special["dt"] = (f"dt {'>=' if long else '<='} {_round_toward(bound, long):.3g} s at the "
                         "other values, or dt = none (the stable step)")
    raise blame(setup, params, given, name, acceptable,
                f"makes the run too {'long' if long else 'short'} ({what})", deadline, special)


def blame(setup, params: dict, given: dict, name: str, ok: Callable, why: str,
          deadline: float, special: dict | None = None) -> ValueError:
    """The one-line ValueError for a set of parameters whose scene fails ``ok(scene)``, said
    about the given parameter(s) responsible: each changed one is put back to its default in
    turn (a new set-up); those whose default passes are named with their valid bound at the
    others' values, found by bisection between the value and the default (``special``: a
    ready bound text per key); when no single one is responsible, all are named."""
    spec = spec_of(setup)
    special = special or {}
    changed = [k for k, v in given.items() if v != spec.defaults.get(k)]

    def ok_at(k, x):
        probe = estimate.build_quietly(setup, {**params, k: x})
        return probe is not None and ok(probe)

    culprits = [k for k in changed if time.perf_counter() < deadline
                and ok_at(k, spec.defaults[k])]
    if not culprits:
        shown = ", ".join(f"{k} = {shown_value(params[k])}" for k in changed) or "the defaults"
        return ValueError(f"scene {name}: {shown} {why}; valid: move them toward their "
                          f"defaults ('mpm2d show {name}' lists the ranges)")
    parts = []
    for k in culprits:
        v, d = params[k], spec.defaults[k]
        head = f"{k} = {shown_value(v)} {why}"
        if k in special:
            parts.append(f"{head}; valid: {special[k]}")
            continue
        p = spec.params[k]
        numeric = p.kind == "number" and isinstance(v, (int, float)) and \
            isinstance(d, (int, float)) and not isinstance(d, bool)
        if not numeric:
            parts.append(f"{head}; valid: e.g. the default {k} = {d}")
            continue
        good = _bisect(lambda x: ok_at(k, x), float(v), float(d), deadline)
        up = good > v
        good = _round_toward(good, up)
        if p.integer:
            good = float(math.ceil(good) if up else math.floor(good))
        if not ok_at(k, good):              # rounding crossed the transition
            good = float(d)
        unit = f" {p.unit}" if p.unit else ""
        parts.append(f"{head}; valid: {k} {'>=' if up else '<='} {good:.3g}{unit} at the "
                     "other values")
    return ValueError(f"scene {name}: " + "; ".join(parts))


def initial_values_ok(scene) -> tuple[bool, str]:
    """Whether the history columns the scene's analysis divides by (``Scene.divides_by``) are
    finite and non-zero at the start (record is called on the fresh scene's state)."""
    if not scene.divides_by:
        return True, ""
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        row = history_row(scene.sim, scene)
    bad = [k for k in scene.divides_by if not (np.isfinite(row[k]) and row[k] != 0)]
    if bad:
        return False, ", ".join(f"{k} = {row[k]:g} at t = 0" for k in bad)
    return True, ""


def acceptable(scene) -> bool:
    """Every check of a fresh scene before its run: the step count (:func:`_steps_ok`), the
    initial values its analysis divides by and the first step (on a copy). The bounds a refusal
    states are the bounds of this (a value at the bound is not refused for another reason)."""
    return _steps_ok(scene) and initial_values_ok(scene)[0] and first_step_ok(scene)[0]


def first_step_ok(scene) -> tuple[bool, str]:
    """Whether one step of a copy of the freshly set-up scene succeeds with finite energies
    (the scene itself is untouched: bit-for-bit runs); (False, reason) otherwise."""
    import copy

    try:
        with warnings.catch_warnings(record=True) as held, np.errstate(all="warn"):
            warnings.simplefilter("always", RuntimeWarning)
            probe = copy.deepcopy(scene.sim)
            probe.step()
            e = probe.energies()
    except (RuntimeError, ArithmeticError, ValueError) as exc:
        return False, f"{type(exc).__name__}: {exc}{_after_numpy(held)}"
    bad = [k for k, x in e.items() if not np.isfinite(x)]
    if bad:
        return False, f"non-finite {', '.join(bad)}{_after_numpy(held)}"
    return True, ""


def check_step_bound(spec, params: dict, name: str, given: dict | None = None) -> None:
    """The step-count refusal of :func:`check_step_count` before the scene's set-up (which takes
    seconds to minutes: a bed's geostatic relaxation), where the parameters bound the stable step
    (:meth:`mpm2d.scenes.spec.SceneSpec.step_bound`): a run that needs more than MAX_STEPS
    steps even at that bound is refused at once, one line naming the parameters among dt, cfl,
    t_end and the cell size that the user set (``given``), each with its bound at the others'
    values (the step is proportional to dt, cfl and h, the step count to t_end)."""
    bound = spec.step_bound(params)
    if bound is None:
        return
    dt, t_end, knobs = bound
    with np.errstate(all="ignore"):
        steps = t_end / dt if dt > 0 else math.inf
    if not steps > MAX_STEPS:
        return
    given = given or {}
    r = steps / MAX_STEPS
    fixed = isinstance(params.get("dt"), (int, float)) and params["dt"] is not None
    limits = []
    with np.errstate(all="ignore"):
        if fixed and "dt" in given:
            limits.append(f"dt >= {_round_toward(t_end / MAX_STEPS, True):.3g} s (or dt = none)")
        if not fixed and "cfl" in given:
            lim = params["cfl"] * r
            limits.append(f"cfl >= {_round_toward(lim, True):.3g}" if lim < 1 else
                          f"cfl = {params['cfl']:g} cannot help (it would need > 1)")
        if "t_end" in given:
            limits.append(f"t_end <= {_round_toward(t_end / r, False):.3g} s")
        if not fixed and "h" in given:
            limits.append(f"h >= {_round_toward(params['h'] * r, True):.3g} m")
        if not fixed and "cells_per_mm" in given:
            limits.append(f"cells_per_mm <= {_round_toward(params['cells_per_mm'] / r, False):.3g}")
    shown = ", ".join(f"{k} = {shown_value(v)}" for k, v in given.items()) or "the defaults"
    verb = "makes" if len(given) == 1 else "make"
    head = f"scene {name}: {shown} {verb} the run too long: {knobs} give a step of at most " \
           f"{dt:.3g} s, at least {steps:.3g} steps to t_end, more than {MAX_STEPS:.0e}"
    if limits:
        raise ValueError(f"{head}; valid (each at the others' values): {', '.join(limits)}")
    raise ValueError(head + ("; valid: dt >= " f"{_round_toward(t_end / MAX_STEPS, True):.3g} s"
                             if fixed else "; valid: the values that set the wave speed "
                             f"back toward their defaults, or cfl >= "
                             f"{_round_toward(params['cfl'] * r, True):.3g}"))


def _remove_stale_temporaries(out: Path) -> list[str]:
    """Delete the temporary files of atomic writes a killed run (SIGKILL, power loss) left."""
    gone = []
    for folder in (out, out / "frames", out / "vtk"):
        if folder.is_dir():
            for f in folder.iterdir():
                if f.is_file() and TEMPORARY.match(f.name):
                    f.unlink()
                    gone.append(str(f.relative_to(out)))
    return gone


_FRAME = re.compile(r"frame_\d{5}\.npz$")
_VTU = re.compile(r"(.+)_\d{5}\.vtu")


def _our_manifest(out: Path) -> dict | None:
    """The manifest of a previous run of ours in ``out`` (scene, params, frames), else None."""
    man = out / "manifest.json"
    if not man.is_file():
        return None
    try:
        m = json.loads(man.read_text())
    except (ValueError, OSError, UnicodeDecodeError):
        return None
    if not (isinstance(m, dict) and isinstance(m.get("scene"), str)
            and isinstance(m.get("params"), dict) and isinstance(m.get("frames"), list)):
        return None
    return m


def _inside(out: Path, rel) -> Path | None:
    """``out/rel`` when ``rel`` is a plain relative path inside ``out`` (top level, frames/ or
    vtk/), else None (a manifest is never trusted to name a file elsewhere)."""
    if not isinstance(rel, str) or not rel or "\\" in rel:
        return None
    parts = Path(rel).parts
    if Path(rel).is_absolute() or ".." in parts or len(parts) > 2 or \
            (len(parts) == 2 and parts[0] not in ("frames", "vtk")):
        return None
    return out / rel


def _is_empty(out: Path) -> bool:
    """No entry besides empty frames/ and vtk/ folders and temporaries of our atomic writes."""
    for f in out.iterdir():
        if f.is_dir() and f.name in ("frames", "vtk") and not any(f.iterdir()):
            continue
        if f.is_file() and TEMPORARY.match(f.name):
            continue
        return False
    return True


def previous_run_files(out: Path) -> list[Path]:
    """The files a previous run of ours wrote into ``out``, which a fresh run removes: those its
    manifest lists (snapshots, their VTK files and .pvd series, figures and result tables), its
    checkpoints, history and manifest, and the snapshots written after its last manifest
    (``frames/frame_NNNNN.npz``, ``vtk/SET_NNNNN.vtu`` of its sets). Nothing else is touched.

    Raises
    ------
    ValueError
        ``out`` is a non-empty folder without the manifest of a run of ours (a folder of the
        user's: nothing in it is removed or overwritten), before anything is written.
    """
    if not out.is_dir() or _is_empty(out):
        return []
    m = _our_manifest(out)
    if m is None:
        raise ValueError(f"--out = {str(out)!r} is a non-empty folder that holds no mpm2d run "
                         "(no manifest.json of ours): give a new or empty folder, nothing of "
                         "yours is overwritten")
    files, names = [], set()
    for f in m["frames"]:
        if not isinstance(f, dict):
            continue
        files.append(_inside(out, f.get("npz")))
        for n, v in (f.get("vtu") or {}).items():
            files.append(_inside(out, v))
            names.add(str(n))
    if (out / "frames").is_dir():
        files += [f for f in (out / "frames").iterdir() if _FRAME.match(f.name)]
    if (out / "vtk").is_dir():
        files += [f for f in (out / "vtk").iterdir()
                  if (v := _VTU.fullmatch(f.name)) is not None and v.group(1) in names]
        files += [out / "vtk" / f"{n}.pvd" for n in names if "/" not in n]
    files += [out / n for n in ("checkpoint.npz", "checkpoint.prev.npz", "history.csv",
                                "manifest.json")]
    files += [_inside(out, f) for f in m.get("figures", []) or []]
    files += [_inside(out, f) for f in m.get("results", []) or []]
    seen, keep = set(), []
    for f in files:
        if f is not None and f not in seen and f.is_file():
            seen.add(f)
            keep.append(f)
    return keep


def _remove_previous_run(out: Path, files: list[Path]) -> list[str]:
    """Delete ``files`` (:func:`previous_run_files`) and return their names relative to out."""
    gone = []
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


def command_line(name: str, params: dict, defaults: dict, frames, vtk: bool,
                 vtk_default: bool = True) -> str:
    """The canonical command of a run (deterministic: no output folder, no --resume)."""
    sets = " ".join(f"--set {k}={v}" for k, v in params.items()
                    if k in defaults and v != defaults[k])
    return " ".join(filter(None, [f"mpm2d run {name}", sets,
                                  f"--frames {frames}" if frames is not None else "",
                                  "" if vtk == vtk_default else
                                  ("--vtk" if vtk else "--no-vtk")]))


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
    with _Quiet(quiet):
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


def _run_scene(setup, out, params, resume, progress, vtk, frames, checkpoint_every, log,
               stop_after_steps, scene_name, yes=True) -> dict:
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
        used = [ckpt_path if ckpt_path.is_file() else previous_checkpoint(ckpt_path)]

        def fallback(msg):                   # load_checkpoint fell back to the kept one
            used[0] = previous_checkpoint(ckpt_path)
            log(msg)

        saved = load_checkpoint(ckpt_path, required=("run.params", "t", "step"), log=fallback)
        if "chunks" in saved:
            import numba

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
                if k == "frames":
                    theirs = ("the scene's default number of snapshots" if v is None
                              else f"--frames {v}")
                    raise ValueError(f"--resume: --frames {options[k]} differs from the "
                                     f"interrupted run's ({theirs}); resume without --frames")
                flag = "--vtk" if options[k] else "--no-vtk"
                raise ValueError(f"--resume: {flag} differs from the interrupted run's (it "
                                 f"{'wrote' if v else 'did not write'} VTK); resume without "
                                 f"{flag}")
            options[k] = v if options.get(k) is None else options[k]
    params = spec.validate(given)
    check_step_bound(spec, params, name, given)   # before the set-up where the parameters tell
    if saved is None:                             # a long run needs --yes (mpm2d.estimate)
        estimate.check_before_setup(setup, spec, params, name, yes, log)
    # a fresh run removes only what a previous run of ours wrote; a folder of the user's is
    # refused here, before the set-up and before anything is written
    previous = previous_run_files(out) if saved is None else []
    # the scene's set-up (a bed's geostatic relaxation can take minutes) is interrupted at once
    # by Ctrl-C or SIGTERM (there is nothing to save yet); nothing is written before it ends
    # the set-up line only when the set-up is slow (a bed's relaxation): a refusal of a fast
    # scene is then the only output
    announce = threading.Timer(SETUP_NOTICE_S, log, args=(f"setting up scene {name}" + (
        " (then the checkpoint is loaded)" if saved is not None else "") + "...",))
    announce.daemon = True
    if threading.current_thread() is threading.main_thread():
        announce.start()
    # numpy's warnings of the set-up (an overflow from a modulus of 1e-300) are held: a set-up
    # that then fails is refused in one line that cites the first; one that succeeds shows them
    held = []
    try:
        with warnings.catch_warnings(record=True) as held:
            warnings.simplefilter("always", RuntimeWarning)
            scene = setup(**params)
    except KeyboardInterrupt:
        announce.cancel()
        raise KeyboardInterrupt("during the scene's set-up, nothing written"
                                + (f"; {ckpt_path} is as it was" if saved is not None else ""))
    except (ArithmeticError, ValueError) as exc:
        announce.cancel()
        # a value inside its declared range whose set-up arithmetic still breaks down (a length
        # of 1e-300: a division by zero, or an area of 0 refused by the body it builds; a
        # modulus that overflows): the parameters given are the cause. A set-up refusal that
        # names a given parameter itself stands as it is.
        if isinstance(exc, ValueError) and any(re.search(rf"\b{re.escape(k)}\b", str(exc))
                                               for k in given):
            raise
        given_text = ", ".join(f"{k} = {v}" for k, v in given.items()) or "the defaults"
        raise ValueError(f"scene {name}: with {given_text} the set-up breaks down "
                         f"({type(exc).__name__}: {exc}{_after_numpy(held)}); valid: values "
                         f"away from the extremes of their ranges ('mpm2d show {name}')") from None
    announce.cancel()
    vtk = scene.vtk if options["vtk"] is None else bool(options["vtk"])   # the scene's default
    options["vtk"] = vtk
    if saved is None:
        # too many steps, or fewer than the scene's analysis needs (an end time below one
        # stable step): refused naming the parameter set, with its bound (new set-ups)
        refuse_step_count(setup, scene, params, given, name)
        # values for which the scene's equations break down at once (a point thrown off the
        # grid, an energy that overflows in the first step) are bad input, not a failed run
        fine, reason = initial_values_ok(scene)
        if not fine:
            raise blame(setup, params, given, name, acceptable,
                        f"leaves the scene's analysis undefined ({reason}; it divides by it)",
                        time.perf_counter() + BLAME_BUDGET_S)
        fine, reason = first_step_ok(scene)
        if not fine:
            raise blame(setup, params, given, name, acceptable,
                        f"breaks the first step ({reason})",
                        time.perf_counter() + BLAME_BUDGET_S)
        estimate.report_after_setup(scene, spec, params, name, yes, log)
    with np.errstate(all="ignore"):          # inf/0 steps are the check's to refuse
        check_step_count(scene, name)
    for w in held:                           # a set-up that succeeded: its warnings as they were
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if saved is None and (ckpt_path.exists()
                          or ckpt_path.with_name("checkpoint.prev.npz").exists()):
        log(f"note: {out} holds the checkpoint of an earlier run; this run starts afresh and "
            "replaces it (--resume continues it instead)")
    with Interrupts() as stop:         # from here on, a signal stops between steps
        out.mkdir(parents=True, exist_ok=True)
        for f in _remove_stale_temporaries(out):
            log(f"removed {f}, a temporary file of an interrupted write")
        if saved is None:
            gone = _remove_previous_run(out, previous)
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
                    "command": command_line(name, params, spec.defaults, options["frames"], vtk,
                                            scene.vtk),
                    "params": params, "mode": sim.mode, "transfer": sim.transfer,
                    "description": sim.describe(),
                    "grid": {"nx": sim.grid.nx, "ny": sim.grid.ny, "h_m": sim.grid.h,
                             "origin_m": list(sim.grid.origin),
                             "axisymmetric": sim.grid.axisymmetric,
                             "boundaries": sim.grid.boundaries},
                    "t_end_s": t_end, "notes": scene.notes, "frames": [], "status": "running",
                    "ends": []}
        rows: list[dict] = []
        if saved is not None:
            sim.load_state({k: v for k, v in saved.items() if not k.startswith("run.")})
            rows = _history_rows(saved)
            manifest["frames"] = json.loads(str(saved["run.frames"]))
            next_times = saved["run.next_times"]
            log(f"resumed from {used[0]} at t = {sim.t:.6g} s, step {sim.step_count}")
        log(sim.describe())
        log(f"mode: {sim.mode}")
        if not rows:
            rows.append(history_row(sim, scene))
        if saved is None:                    # the folder is marked as a run of ours before its
            write_manifest(out, manifest)    # first file (a run killed now can be replaced)
        if not manifest["frames"]:
            manifest["frames"].append(write_frame(out, 0, sim, vtk, fields=scene.frame_fields))
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

        held_run = []
        try:
            with warnings.catch_warnings(record=True) as held_run:
                warnings.simplefilter("always", RuntimeWarning)
                complete = stepping = True
                bar = Progress(sim.t, t_end, sim.step_count, label=spec.name) if progress else None
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
                                raise RuntimeError(f"non-finite energy at t = {sim.t:.6g} s "
                                                   f"(step {sim.step_count}): the run diverged; "
                                                   f"see {out}")
                            rows.append(row)
                            next_rec += rec_dt
                        regular = sim.t >= next_frame * (1.0 - 1e-9)
                        event = bool(events) and sim.t >= events[0] * (1.0 - 1e-9)
                        while events and sim.t >= events[0] * (1.0 - 1e-9):
                            events.pop(0)
                        if regular or event:    # one snapshot per step, tagged event if asked
                            manifest["frames"].append(write_frame(
                                out, len(manifest["frames"]), sim, vtk,
                                tag="event" if event else "frame", fields=scene.frame_fields))
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
                    log(f"interrupted ({stop.pending or 'KeyboardInterrupt'}) at t = "
                        f"{sim.t:.6g} s (step {sim.step_count}); checkpoint written to "
                        f"{ckpt_path}: continue with --resume")
                    raise KeyboardInterrupt(f"checkpoint written to {ckpt_path}: rerun with "
                                            "--resume to continue") from None
                stepping = False
                if bar is not None:
                    bar.close(sim.t, sim.step_count)
                history = pd.DataFrame(rows)
                figures = []
                if complete:
                    if manifest["frames"][-1]["step"] != sim.step_count:
                        manifest["frames"].append(write_frame(out, len(manifest["frames"]), sim,
                                                              vtk, fields=scene.frame_fields))
                    if vtk:
                        write_pvds(out, manifest["frames"])
                    write_history(history)               # the report may read it
                    write_manifest(out, manifest)        # the report reads the frames from it
                    if scene.report is not None:
                        # the final state first: a report that runs sub-runs (the wheel's other
                        # omegas) can be interrupted, and the same command with --resume then
                        # finds this run complete, goes straight to its report and resumes the
                        # sub-run
                        checkpoint()
                        figures = [str(Path(f).relative_to(out)) if Path(f).is_relative_to(out)
                                   else str(f) for f in scene.report(sim, history, out)]
                    manifest["status"] = "complete"
                    manifest["figures"] = figures
        except (RuntimeError, ArithmeticError, ValueError) as exc:
            # a run that fails mid-way: its files stay for the diagnosis and the manifest
            # says so (numpy's warnings of the run are cited, not printed before)
            after = _after_numpy(held_run)
            message = f"{exc} ({after.strip()})" if after else str(exc)
            # failing in a step, the run ended there (rheology.run_end): its history up to the
            # last recorded row is written, the manifest's status and ends say where and why
            end = RunEnd("solver_failure", f"{message}; the run's files up to there are in "
                         f"{out}", float(rows[-1]["time_s"]), past_s=float(sim.t)) \
                if stepping else None
            manifest.update(status="failed", error=message, steps=sim.step_count)
            try:
                if end is not None:
                    write_history(pd.DataFrame(rows))
                    plots.ended_history(pd.DataFrame(rows), end, out / "history.png", name)
                    manifest.update(run_record([end]), figures=["history.png"])
                write_manifest(out, manifest)
            except (RuntimeError, ValueError, OSError):
                end = None
            if end is not None:
                raise EndedEarly([end], written=[str(out)]) from None
            raise RuntimeError(f"{message}; the run's files are in {out} (manifest status "
                               "failed)") from None
        for w in held_run:                   # a run that succeeded: its warnings as they were
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
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
