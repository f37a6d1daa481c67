"""Parameter sweeps of a scene on Dask: ``mpm2d sweep SCENE --set k=v1,v2 [...] --out DIR``.

The cases are the Cartesian product of the ``--set`` lists (``--set phi0=0.46,0.47 --set
v0=0.2,0.5`` is four cases). They run on ``dask.distributed``: by default a ``LocalCluster`` on
this machine (one worker process per core, one thread each, numba set to one thread per worker);
``scheduler="tcp://host:8786"`` sends the same sweep to an existing Dask cluster (its workers
need this package installed and ``DIR`` on a shared file system).

Each case is a normal scene run (:func:`mpm2d.run.run_scene`) in ``DIR/<case>.partial/``, moved
to ``DIR/<case>/`` by one ``os.replace`` when it completes, so a case folder without the suffix
is always whole. On a rerun, complete cases are skipped, and a partial case continues from its
checkpoint (written every ``checkpoint_every`` wall seconds; a worker stopped by Ctrl-C or
SIGTERM of the sweep loses at most that much). A case that fails is reported with its error
while the others finish. ``DIR/sweep.csv`` lists every case with its parameters, status
(``done``, ``skipped``, ``failed``), wall time and error; a scene module may define
``sweep_report(table, out) -> list of paths`` to add its own tables and figures (e.g. the
intruder's fronts).

Bad input (an unknown scene or parameter, a value out of range, an empty list) is refused before
any case runs, exactly as ``mpm2d run`` refuses it.
"""

from __future__ import annotations

import itertools
import json
import os
import re
import shutil
import sys
import time
from pathlib import Path

import numba
import pandas as pd
from tqdm import tqdm

from runkit.command import one_line
from runkit.io import atomic_write_csv, check_output_dir

from . import estimate
from .run import coerce, run_scene
from .scenes.spec import spec_of
from .scenes import get_setup

#: parameter-name pattern of a case folder (stable across reruns)
_SAFE = re.compile(r"[^A-Za-z0-9.+\-]+")


def parse_grid(items, lists: bool = True) -> dict[str, list[str]]:
    """``["phi0=0.46,0.47", "v0=0.2"]`` -> ``{"phi0": ["0.46", "0.47"], "v0": ["0.2"]}``.

    ``lists=False`` (``mpm2d run``): each value is one string, commas included (the scene's
    validation then names the parameter and its range).

    Raises
    ------
    ValueError
        An item without ``=``, an empty value list, or a key given twice.
    """
    grid: dict[str, list[str]] = {}
    for item in items or []:
        if "=" not in item:
            raise ValueError(f"--set {item!r} must be key=value[,value...]")
        key, values = (s.strip() for s in item.split("=", 1))
        vals = [v.strip() for v in values.split(",")] if lists else [values]
        if not key or any(v == "" for v in vals):
            raise ValueError(f"--set {item!r}: empty key or value (an optional parameter's "
                             "default is given as none, e.g. --set v0=none)")
        if key in grid:
            raise ValueError(f"--set {key} given twice" + (f"; list its values once: {key}=a,b,c"
                                                           if lists else ""))
        grid[key] = vals
    return grid


def expand(grid: dict[str, list[str]]) -> list[dict[str, str]]:
    """The Cartesian product of the grid, in the order the keys were given."""
    keys = list(grid)
    return [dict(zip(keys, combo)) for combo in itertools.product(*(grid[k] for k in keys))]


def case_name(params: dict) -> str:
    """Folder name of a case, e.g. ``phi0=0.46_v0=0.2`` (``base`` for an empty grid)."""
    if not params:
        return "base"
    return "_".join(f"{_SAFE.sub('-', str(k))}={_SAFE.sub('-', str(v))}"
                    for k, v in params.items())


def check_distinct_cases(grid: dict[str, list[str]], canonical: dict | None = None) -> None:
    """Refuse a grid two of whose cases would be the same run or share a folder: one line naming
    the ``--set`` key and its values that collide: a value given twice (``8,8``), two spellings
    of one value (``0.001,1e-3``, ``apic,APIC``: ``canonical`` maps key -> {text: value as
    the scene reads it}), or values that differ only in characters a folder name cannot hold
    (``a b`` and ``a-b``: :func:`case_name`).

    Raises
    ------
    ValueError
        ``--set KEY: values 'A' and 'B' ...; give distinct values of KEY``.
    """
    for key, values in grid.items():
        folders: dict[str, str] = {}
        runs: dict = {}
        for v in values:
            folder = case_name({key: v})
            value = (canonical or {}).get(key, {}).get(v, v)
            if folder in folders and folders[folder] == v:
                raise ValueError(f"--set {key}: value {v!r} is given twice; give distinct values "
                                 f"of {key}")
            first = runs.get(value)          # scene values: numbers, text, bools, None
            if first is not None:
                raise ValueError(f"--set {key}: values {first!r} and {v!r} are the same value "
                                 f"({value}); give distinct values of {key}")
            if folder in folders:
                raise ValueError(f"--set {key}: values {folders[folder]!r} and {v!r} give the "
                                 f"same case folder {folder!r}; give distinct values of {key}")
            folders[folder] = v
            runs.setdefault(value, v)


def _complete(folder: Path) -> bool:
    try:
        return json.loads((folder / "manifest.json").read_text())["status"] == "complete"
    except (OSError, ValueError, KeyError):
        return False


def run_case(scene: str, out: str, params: dict, checkpoint_every: float = 60.0,
             vtk: bool = False, threads: int = 1) -> dict:
    """Run one case into ``out/<case>`` (through ``<case>.partial``); runs on a Dask worker.

    Returns
    -------
    dict with ``case``, ``status`` (``done`` or ``skipped``), ``wall_s``. Errors propagate (the
    sweep records them per case).
    """
    name = case_name(params)
    final, partial = Path(out) / name, Path(out) / f"{name}.partial"
    if _complete(final):
        return {"case": name, "status": "skipped", "wall_s": 0.0}
    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))  # <= pool
    t0 = time.perf_counter()
    resume = (partial / "checkpoint.npz").exists() and (partial / "manifest.json").exists()
    run_scene(get_setup(scene), partial, dict(params), resume=resume, progress=False, vtk=vtk,
              checkpoint_every=checkpoint_every, log=lambda msg: None, scene_name=scene)
    if final.exists():                      # a stale, incomplete folder of an older sweep
        shutil.rmtree(final)
    os.replace(partial, final)
    return {"case": name, "status": "done", "wall_s": time.perf_counter() - t0}


def _client(scheduler: str | None, workers: int | None):
    from dask.distributed import Client, LocalCluster

    if scheduler:
        try:
            return Client(scheduler, timeout="20s"), None
        except (OSError, ValueError, TypeError) as exc:
            raise ValueError(f"--scheduler = {scheduler!r}: cannot reach a Dask scheduler there "
                             f"({one_line(exc)})") from None
    n = workers or os.cpu_count() or 1
    # one numba thread per worker: run_case calls numba.set_num_threads(1). NUMBA_NUM_THREADS is
    # left alone: changing it once numba's pool runs is an error, and dask applies a worker
    # environment late (env=, seen racing numba) or to the parent process too (pre-spawn-environ)
    saved = dict(os.environ)                 # nannies write their pre-spawn variables into ours
    try:
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=50)
    finally:
        os.environ.clear()
        os.environ.update(saved)
    return Client(cluster), cluster


def run_sweep(scene: str, grid: dict[str, list[str]], out, *, scheduler: str | None = None,
              workers: int | None = None, checkpoint_every: float = 60.0, vtk: bool = False,
              progress: bool = True, log=print, quiet: bool = False,
              yes: bool = False) -> pd.DataFrame:
    """Run every case of ``grid`` for ``scene`` on Dask and write ``out/sweep.csv``.

    Parameters
    ----------
    scene : str
        A scene name (``mpm2d list``).
    grid : dict of str -> list of str
        Parameter values per key (:func:`parse_grid`); every case is validated before any runs.
    out : path
        The sweep folder (one sub-folder per case).
    scheduler : str, optional
        Address of an existing Dask scheduler; default: a LocalCluster.
    workers : int, optional
        Workers of the LocalCluster (default: one per core).
    quiet : bool
        No progress bar and no log lines except the failed cases (on stderr).
    yes : bool
        Run cases past :data:`mpm2d.estimate.CONFIRM_POINT_STEPS` point-steps (``mpm2d sweep
        --yes``); without it such a case is refused with its estimate, as by ``mpm2d run``.

    Returns
    -------
    pandas.DataFrame, one row per case (parameters, ``case``, ``status``, ``wall_s``, ``error``).

    Raises
    ------
    ValueError
        Bad input (unknown scene or key, a value out of range), before anything is written.
    RuntimeError
        Every case failed.
    """
    if quiet:
        log, progress = (lambda msg: None), False
    if scheduler is not None and not scheduler.strip():     # '' ran on a local cluster
        raise ValueError(f"--scheduler = {scheduler!r} is empty; valid: the address of a Dask "
                         "scheduler (tcp://host:8786), or no --scheduler for a local cluster")

    setup = get_setup(scene)
    cases = expand(grid)
    canonical: dict = {k: {} for k in grid}
    spec = spec_of(setup)
    for params in cases:                     # bad input: refused before any work
        given = coerce(dict(params), setup)
        for k, v in given.items():
            canonical[k][params[k]] = v
        # the size refusals of ``mpm2d run``, case by case, before the cluster starts
        full = {**spec.defaults, **given}    # spec.validate without checking ``given`` again
        estimate.check_before_setup(setup, spec, full, f"{scene} (case {case_name(params)})",
                                    yes, log)
    check_distinct_cases(grid, canonical)
    names = [case_name(p) for p in cases]
    out = check_output_dir("--out", out)       # created once the cluster is reached
    rows = {n: {**p, "case": n, "status": "pending", "wall_s": 0.0, "error": ""}
            for n, p in zip(names, cases)}
    todo = [(n, p) for n, p in zip(names, cases) if not _complete(out / n)]
    for n in rows:
        if n not in dict(todo):
            rows[n]["status"] = "skipped"
    log(f"sweep {scene}: {len(cases)} cases, {len(cases) - len(todo)} complete already, "
        f"{len(todo)} to run; results in {out}")
    if todo:
        _run_on_dask(scene, out, todo, rows, scheduler, workers, checkpoint_every, vtk,
                     progress, log)
    table = pd.DataFrame(list(rows.values()))
    atomic_write_csv(out / "sweep.csv", table)
    failed = table[table["status"] == "failed"]
    for _, r in failed.iterrows():
        line = f"case {r['case']} failed: {r['error']}"
        if quiet:
            print(f"mpm2d sweep: {line}", file=sys.stderr, flush=True)
        else:
            log(line)
    module = __import__(setup.__module__, fromlist=["sweep_report"])
    report = getattr(module, "sweep_report", None)
    done = table[table["status"].isin(["done", "skipped"])]
    if report is not None and len(done):
        for path in report(done, out):
            log(f"wrote {path}")
    if len(failed) == len(table):
        raise RuntimeError(f"every case of the sweep failed (first: {failed['error'].iloc[0]}); "
                           f"see {out / 'sweep.csv'}")
    log(f"sweep {scene}: {len(done)} of {len(table)} cases complete, {len(failed)} failed; "
        f"wrote {out / 'sweep.csv'}")
    return table


def _run_on_dask(scene, out, todo, rows, scheduler, workers, checkpoint_every, vtk, progress,
                 log) -> None:
    from dask.distributed import as_completed

    client, cluster = _client(scheduler, workers)
    out.mkdir(parents=True, exist_ok=True)
    bar = None
    try:
        log(f"dask: {client.scheduler.address if hasattr(client.scheduler, 'address') else ''}"
            f" with {len(client.scheduler_info()['workers'])} worker(s)")
        futures = {}
        for name, params in todo:
            fut = client.submit(run_case, scene, str(out), params, checkpoint_every, vtk, 1,
                                key=f"{scene}-{name}", pure=False)
            futures[fut] = name
        if progress:
            bar = tqdm(total=len(futures), desc=f"sweep {scene}", unit="case")
        for fut in as_completed(futures):
            name = futures[fut]
            try:
                res = fut.result()
                rows[name].update(status=res["status"], wall_s=res["wall_s"])
            except Exception as exc:         # a failing case must not stop the others
                rows[name].update(status="failed", error=f"{type(exc).__name__}: {one_line(exc)}")
            if bar is not None:
                running = sum(1 for f in futures if f.status == "pending")
                bar.set_postfix(running=min(running, len(client.scheduler_info()["workers"])),
                                failed=sum(r["status"] == "failed" for r in rows.values()))
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
        client.close()
        if cluster is not None:
            cluster.close()
