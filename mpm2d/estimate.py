"""The size of a run before it starts: point-steps, memory and an estimated wall time.

Point-steps are the number of material points times the number of steps, the measure of a run's
work (each step visits every point a fixed number of times). Before a scene's set-up (which can
take minutes at a fine resolution: a bed's geostatic relaxation), the parameters bound them from
below: the points of the scene's declared size and at least ``t_end / dt_max`` steps, with dt_max
the scene's first stable step from its parameters, or the largest the parameters allow
(:func:`mpm2d.scenes.spec.run_steps`).
A run of more than :data:`CONFIRM_POINT_STEPS` point-steps is refused unless confirmed (``mpm2d
run ... --yes``), with its estimate: the wall time then comes from a short timed probe of the
same scene at a coarse resolution (a few steps, seconds per point-step), since the scene
itself is not built yet. After the set-up, every fresh run prints its size: its points, the
steps at its first stable step, point-steps, the memory estimate and the wall time from a probe
of a few steps of the scene itself (on a copy, after the first step, which includes the
kernels' compilation), with the load average, since a loaded machine runs slower.
"""

from __future__ import annotations

import copy
import math
import os
import time
import warnings

import numpy as np

from .scenes.spec import estimate_bytes, run_steps

#: runs of more point-steps need confirmation (``--yes``): about an hour or more of two cores
#: at the ~3e6 point-steps per second of the suspension scenes
CONFIRM_POINT_STEPS = 1e10
#: the probes: about this many points before the set-up; at most these many timed steps (or
#: PROBE_SECONDS of wall time) after the first, whose median is taken
PROBE_POINTS = 4000
PROBE_STEPS = 20
PROBE_SECONDS = 1.0


def build_quietly(setup, params: dict):
    """The scene of ``params`` or None when its set-up fails (numpy quiet)."""
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            return setup(**params)
    except (ArithmeticError, ValueError, RuntimeError, TypeError):
        return None


def _clock(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "unknown"
    if seconds < 1:
        return "< 1 s"
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.3g} h"


def _about(seconds: float) -> str:
    text = _clock(seconds)
    return text if text.startswith(("<", "unknown")) else "~" + text


def _load() -> str:
    try:
        return f"load average {os.getloadavg()[0]:.1f}"
    except OSError:
        return "load average unknown"


def timed_steps(sim, steps: int = PROBE_STEPS, budget: float = PROBE_SECONDS):
    """(median wall seconds of a step, steps timed) of ``sim`` over up to ``steps`` steps
    (fewer once ``budget`` wall seconds are spent); ``sim`` is stepped (pass a copy). NaN and 0
    when no step succeeds."""
    times = []
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            start = time.perf_counter()
            for _ in range(steps):
                t0 = time.perf_counter()
                sim.step()
                times.append(time.perf_counter() - t0)
                if time.perf_counter() - start > budget:
                    break
    except (RuntimeError, ArithmeticError, ValueError):
        pass
    return (float(np.median(times)) if times else float("nan")), len(times)


def _coarse_probe(setup, params: dict, points: float) -> tuple[float, str]:
    """(seconds per point-step, what was probed) from the scene at a coarse resolution."""
    key = "cells_per_mm" if "cells_per_mm" in params else "h" if "h" in params else None
    if key is None or not isinstance(params.get(key), (int, float)) or not points > 0:
        return float("nan"), ""
    factor = max(1.0, math.sqrt(points / PROBE_POINTS))        # never finer than the run
    coarse = params[key] / factor if key == "cells_per_mm" else params[key] * factor
    for _ in range(8):                 # a value the scene refuses: halfway back (geometric)
        scene = build_quietly(setup, {**params, key: coarse})
        if scene is not None:
            break
        coarse = math.sqrt(coarse * params[key])
    else:
        return float("nan"), ""
    sim = scene.sim
    n = sum(len(s.x) for s in sim.sets)
    timed_steps(sim, 1)                                   # compilation, caches
    per, k = timed_steps(sim)
    return per / max(n, 1), f"{key} = {coarse:.3g} ({n} points, the median of {k} steps)"


def check_before_setup(setup, spec, params: dict, name: str, yes: bool, log) -> None:
    """Refuse (ValueError, one line, exit 2) a run of more than :data:`CONFIRM_POINT_STEPS`
    point-steps at the lower bound the parameters give, unless ``yes``; with ``yes`` log the
    estimate. Scenes without a declared size or step bound are not checked here."""
    bound = run_steps(spec, params)
    if bound is None or spec.extent is None:
        return
    points = float(spec.extent(params)[0])
    dt, t_end, _ = bound
    steps = t_end / dt if dt > 0 else math.inf
    work = points * steps
    if not work > CONFIRM_POINT_STEPS:
        return
    per, probed = _coarse_probe(setup, params, points)
    wall = (f"at least {_clock(work * per)} ({per:.3g} s per point-step from a timed probe at "
            f"{probed}, {_load()})" if math.isfinite(per) else "not estimated")
    text = (f"{points:.3g} points x at least {steps:.3g} steps = at least {work:.3g} "
            f"point-steps; memory ~{estimate_bytes(spec, params) / 1e9:.3g} GB (estimate); wall "
            f"time {wall}")
    if not yes:
        raise ValueError(f"scene {name}: a run of {text}: runs past {CONFIRM_POINT_STEPS:.0e} "
                         "point-steps need --yes")
    log(f"run size (before the set-up): {text}")


def report_after_setup(scene, spec, params: dict, name: str, yes: bool, log) -> None:
    """Log the size of a freshly set-up run (points, steps at its first stable step,
    point-steps, memory, wall time from a probe of a few steps on a copy of the scene);
    refuse (ValueError) a run of more than :data:`CONFIRM_POINT_STEPS` point-steps without
    ``yes``."""
    sim = scene.sim
    points = sum(len(s.x) for s in sim.sets)
    with np.errstate(all="ignore"):
        dt = sim.user_dt if sim.user_dt is not None else sim.stable_dt()
        steps = (scene.t_end - sim.t) / dt if dt > 0 else math.inf
    work = points * steps
    probe = copy.deepcopy(sim)
    timed_steps(probe, 1)
    per, probed = timed_steps(probe)
    del probe
    text = (f"{points} points x ~{steps:.3g} steps (at the first stable step, {dt:.3g} s) = "
            f"{work:.3g} point-steps; memory ~{estimate_bytes(spec, params) / 1e9:.3g} GB "
            f"(estimate); wall time {_about(per * steps)} ({per * 1e3:.3g} ms a step, the "
            f"median of a timed probe of {probed} steps, {_load()})")
    if work > CONFIRM_POINT_STEPS and not yes:
        raise ValueError(f"scene {name}: a run of {text}: runs past {CONFIRM_POINT_STEPS:.0e} "
                         "point-steps need --yes")
    log(f"run size: {text}")
