"""Validation cases and benchmarks: registration, execution and their results.

A *case* holds one tier against the paper, an analytic solution or the tier below, with a stated
pass criterion; a *benchmark* measures speed (and accuracy) against a reference method timed in the
same process. Each lives in a module ``validation/cases_<tier>.py`` or ``validation/bench_<tier>.py``
(discovered automatically) and registers itself with :func:`case` or :func:`benchmark` (an
example: the developer guide's "How to add a validation case"). ``out`` is the folder for the
case's files (figures go there, referenced by path); ``quick`` asks for the small sizes used by
the test suite.

``slow=True`` marks a case whose run is long and whose criteria hold at its full size only:
``python -m validation report --quick`` (and ``--no-slow``, at full size) skips it (listed as
skipped in the console, the report and ``results.json``) and refuses it when it is named with
``--only``. A case that passes at both sizes, however long, can stay ``slow=False``. Benchmarks
are always ``slow``; they run at small sizes under ``--quick`` (``--no-bench`` leaves them out).

Values a result reports (:func:`clean`): every number in a case's or benchmark's ``rows``,
``targets`` and other fields must be finite. A value undefined by construction (an error where the
run diverged, a convergence order at the coarsest grid) is ``None`` (or NaN) with its reason in the
row's ``<column>_note`` or the result's ``notes[column]``: it is written as ``null`` and shown as
"-" with the reason. Anything else (NaN or inf, a null without a reason, a value that is no
number, string, bool or path) fails that entry alone, named with its row and column, and is
written as ``null`` with "unexpected" as its reason; the other entries and the report are kept.
Prose (``measured``, ``details``, ``summary``) is not scanned: numbers that matter go in ``rows``.
"""

from __future__ import annotations

import ast
import dataclasses
import hashlib
import importlib
import pkgutil
import sys
import time
import traceback
from dataclasses import dataclass, field
from functools import lru_cache, wraps
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from runkit.io import atomic_savefig, atomic_write_csv, strict_json
from runkit.plotting import plt
from runkit.run import retire_checkpoints
import validation


@dataclass
class Verdict:
    """What a case returns: its pass criterion, the measured value(s) and the verdict;
    ``rows`` and ``notes`` as in :class:`BenchResult`."""

    criterion: str
    measured: str
    passed: bool
    figures: list[Path] = field(default_factory=list)
    details: str = ""
    rows: list[dict] = field(default_factory=list)
    notes: dict[str, str] = field(default_factory=dict)


@dataclass
class BenchResult:
    """What a benchmark returns.

    Attributes
    ----------
    summary : str
        One paragraph: machine, method, reference, medians and ratios.
    rows : list of dict
        The measured table (one dict per row). A value undefined by construction is ``None``
        (or NaN) with its reason in the row's ``<column>_note`` key or in ``notes``.
    targets : list of (target, measured, met)
        Each target with its measured value and whether it is met.
    figures : list of Path
    notes : dict of str to str
        Column -> why its values are null where they are (for every row of the table).
    """

    summary: str
    rows: list[dict] = field(default_factory=list)
    targets: list[tuple[str, str, bool]] = field(default_factory=list)
    figures: list[Path] = field(default_factory=list)
    notes: dict[str, str] = field(default_factory=dict)


@dataclass
class Entry:
    kind: str          # "case" or "benchmark"
    tier: str
    name: str
    title: str
    func: Callable
    slow: bool = False


REGISTRY: dict[str, Entry] = {}
TIERS = ("rheology", "rheometer", "shear1d", "mpm2d")


def _register(kind: str, tier: str, name: str, title: str, slow: bool):
    if tier not in TIERS:
        raise ValueError(f"tier = {tier!r} must be one of {TIERS}")

    def deco(func):
        if name in REGISTRY:
            raise ValueError(f"validation entry {name!r} registered twice")
        REGISTRY[name] = Entry(kind, tier, name, title, func, slow)
        return func

    return deco


def case(tier: str, name: str, title: str, slow: bool = False):
    """Register a validation case ``func(out: Path, quick: bool) -> Verdict``; ``slow``: judged
    at full size only (``report --quick`` skips it)."""
    return _register("case", tier, name, title, slow)


def benchmark(tier: str, name: str, title: str):
    """Register a benchmark ``func(out: Path, quick: bool) -> BenchResult``."""
    return _register("benchmark", tier, name, title, True)


def table_cases(tier: str, func: Callable, table: dict, slow: bool = False) -> None:
    """Register one case per row ``name: (title, params)`` of ``table``, cases that differ only
    by data: each runs ``func(out, quick, **params) -> Verdict``."""
    for name, (title, params) in table.items():
        @wraps(func)            # the entry's module (its fingerprint) is func's
        def run(out, quick, params=params):
            return func(out, quick, **params)
        case(tier, name, title, slow)(run)


def save_figure(fig, out, name: str, tight: bool = False) -> Path:
    """Save a case's figure atomically as ``out/name`` (``tight``: after ``fig.tight_layout()``)
    and close it; returns the path."""
    if tight:
        fig.tight_layout()
    path = atomic_savefig(fig, Path(out) / name)
    plt.close(fig)
    return path


def write_csv(out, name: str, rows, nullable=()) -> pd.DataFrame:
    """A case's table (a DataFrame, or what builds one: row dicts, a dict of columns) written
    atomically as ``out/name``; NaN only in the ``nullable`` columns (empty cells). Returns the
    DataFrame."""
    df = rows if isinstance(rows, pd.DataFrame) else pd.DataFrame(rows)
    atomic_write_csv(Path(out) / name, df, empty_ok=nullable)
    return df


def slope_plot(ax, x, series: dict, slope: float, xlabel: str, ylabel: str, title=None,
               ref=None, legend=None):
    """The standard convergence figure: each ``label: (y, style)`` of ``series`` on log-log
    axes and the reference line of ``slope`` through (x[0], ``ref``), by default the first
    point of the first series."""
    x = np.asarray(x, dtype=float)
    for label, (y, style) in series.items():
        ax.loglog(x, y, style, label=label)
    y0 = np.asarray(next(iter(series.values()))[0], dtype=float)[0] if ref is None else ref
    ax.loglog(x, y0 * (x / x[0]) ** slope, "k:", label=f"slope {slope:g}")
    ax.set(xlabel=xlabel, ylabel=ylabel, **({} if title is None else {"title": title}))
    ax.legend(**(legend or {}))


def timed(fn, repeats: int, clock=time.perf_counter):
    """``repeats`` calls of ``fn``: (median time [s], every time [s], the last call's result)."""
    times, result = [], None
    for _ in range(repeats):
        t0 = clock()
        result = fn()
        times.append(clock() - t0)
    return float(np.median(times)), times, result


def interleaved(jobs: dict, repeats: int, clock=time.perf_counter,
                results: dict | None = None) -> dict[str, list[float]]:
    """Each ``name: fn`` of ``jobs`` called once per repeat, the jobs interleaved so that machine
    load hits all alike: name -> every time [s]. ``results``, if given, receives name -> the
    last call's result."""
    times, results = {k: [] for k in jobs}, {} if results is None else results
    for _ in range(repeats):
        for k, fn in jobs.items():
            _, t, results[k] = timed(fn, 1, clock)
            times[k] += t
    return times


def load_all() -> dict[str, Entry]:
    """Import every ``validation.cases_*`` and ``validation.bench_*`` module; return the registry."""
    for mod in sorted(pkgutil.iter_modules(validation.__path__), key=lambda m: m.name):
        if mod.name.startswith(("cases_", "bench_")):
            importlib.import_module(f"validation.{mod.name}")
    return REGISTRY


NOTE = "_note"     #: suffix of a row's key giving why that row's value of a column is null
UNEXPECTED = "unexpected: not a result (the entry fails)"
#: why a convergence table's observed order is null on its first row
NO_COARSER = "the coarsest grid: no coarser one to give an observed order"


def clean(result) -> tuple[dict, list[str]]:
    """A case's or benchmark's result as strict-JSON data, and the values that are not results.

    Returns
    -------
    data : dict
        Every field of the :class:`Verdict` or :class:`BenchResult` in plain Python (targets as
        ``[target, measured, met]`` lists). Nulls keep their reason; an unexpected value is
        ``None`` and, in a row, gets ``<column>_note`` = :data:`UNEXPECTED`.
    problems : list of str
        One line per unexpected value: ``"rows[11].error = nan (row 11: method=explicit, ...)"``
        (NaN or inf), ``"... is null with no reason"`` or ``"... = a Foo (not JSON)"``. Non-empty
        fails the entry.
    """
    problems: list[str] = []

    def conv(x, where: str, reason=None):
        def bad(path, v):
            what = repr(float(v)) if isinstance(v, float) else f"a {type(v).__name__} (not JSON)"
            problems.append(f"{where}{'.' + path if path else ''} = {what}")
        if x is None and not reason:
            problems.append(f"{where} is null with no reason")
        return strict_json(x, where, ("",) if reason else (), on_bad=bad)

    notes = {str(k): v for k, v in conv(result.notes, "notes").items()}
    data = {f.name: conv(getattr(result, f.name), f.name)
            for f in dataclasses.fields(result) if f.name not in ("rows", "notes", "targets")}
    data["notes"] = notes
    data["targets"] = [[conv(x, f"targets[{i}][{j}]") for j, x in enumerate(t)]
                       for i, t in enumerate(getattr(result, "targets", ()))]
    data["rows"] = []
    for i, row in enumerate(result.rows):
        out = {}
        for col, v in row.items():
            col = str(col)
            if col.endswith(NOTE):
                out[col] = conv(v, f"rows[{i}].{col}", reason="a note may be empty")
                continue
            n = len(problems)
            out[col] = conv(v, f"rows[{i}].{col}", row.get(col + NOTE) or notes.get(col))
            if len(problems) > n:
                where = "".join(f", {k}={w:g}" if isinstance(w, float) else f", {k}={w}"
                                for k, w in [kv for kv in row.items() if kv[0] != col][:2]
                                if isinstance(w, (str, int, float)) and not k.endswith(NOTE))
                problems[n:] = [f"{p} (row {i}{where})" for p in problems[n:]]
                out[col + NOTE] = UNEXPECTED
        data["rows"].append(out)
    return data, problems


@dataclass
class Outcome:
    """One run of an entry: its result as strict-JSON ``data`` (:func:`clean`) and the
    ``problems`` found there, or the traceback of the exception it raised (``error``)."""

    entry: Entry
    seconds: float
    data: dict = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)
    error: str | None = None

    @property
    def passed(self) -> bool:
        if self.error is not None or self.problems:
            return False
        if self.entry.kind == "case":
            return self.data.get("passed") is True
        return all(t[2] is True for t in self.data["targets"])

    @property
    def reason(self) -> str | None:
        """One line (None when passed): the last line of an error, the values that are not
        results, a failed case's criterion and measured value, or a benchmark's unmet targets."""
        if self.error is not None:
            return "error: " + self.error.strip().splitlines()[-1]
        if self.problems:
            more = f"; and {len(self.problems) - 3} more" if len(self.problems) > 3 else ""
            return "values that are not results: " + "; ".join(self.problems[:3]) + more
        if self.passed:
            return None
        d = self.data
        if self.entry.kind == "case":
            return f"criterion {d.get('criterion')}; measured {d.get('measured')}"
        return "; ".join(f"target {t}: measured {m}" for t, m, met in d["targets"]
                         if met is not True)


def run_entry(entry: Entry, out: Path, quick: bool = False) -> Outcome:
    """Run one case or benchmark in its own folder ``out/<name>``; an exception it raises (other
    than ``KeyboardInterrupt``) is its outcome's ``error``, never fatal to the report. When it
    ends (not interrupted), the runs that completed under ``out`` lose their checkpoints
    (:func:`runkit.run.retire_checkpoints`: the mpm2d runner keeps a completed run's)."""
    folder = Path(out) / entry.name
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    try:
        result = entry.func(folder, quick)
        want = Verdict if entry.kind == "case" else BenchResult
        if not isinstance(result, want):
            raise TypeError(f"{entry.kind} {entry.name} returned a {type(result).__name__}, "
                            f"not a {want.__name__}")
        outcome = Outcome(entry, time.perf_counter() - t0, *clean(result))
    except Exception:  # a failing case is reported, not fatal to the report
        outcome = Outcome(entry, time.perf_counter() - t0, error=traceback.format_exc())
    retire_checkpoints(out)
    return outcome


# ------------------------------------------------------------------ fingerprint (--resume)
ROOT = Path(__file__).resolve().parent.parent     #: the folder holding the project's packages


@lru_cache(maxsize=None)
def _package_files(name: str) -> tuple[Path, ...]:
    """Every file of the project package ``name`` (caches and hidden files excluded); empty for
    a module that is not one of the project's packages."""
    folder = ROOT / name
    if not (folder / "__init__.py").is_file():
        return ()
    return tuple(sorted(p for p in folder.rglob("*") if p.is_file()
                        and "__pycache__" not in p.parts and not p.name.startswith(".")
                        and p.suffix not in (".pyc", ".nbi", ".nbc")))


@lru_cache(maxsize=None)
def _imports(module_file: Path, mtime_ns: int) -> tuple[str, ...]:
    """The dotted names a module imports anywhere (also inside functions), relative imports
    made absolute; cached per file version."""
    names: list[str] = []
    for node in ast.walk(ast.parse(module_file.read_bytes())):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = module_file.parent
            for _ in range(max(node.level - 1, 0)):
                base = base.parent
            pkg = ".".join(base.relative_to(ROOT).parts) if node.level else ""
            head = ".".join(filter(None, [pkg, node.module]))
            names += [head] + [f"{head}.{a.name}" for a in node.names]
    return tuple(names)


def _sources(module_file: Path, seen: set[Path]) -> set[Path]:
    """``module_file``, the ``validation`` modules it imports (recursively) and every file of
    the other project packages it imports."""
    if module_file in seen or not module_file.is_file():
        return set()
    seen.add(module_file)
    files = {module_file}
    for name in _imports(module_file, module_file.stat().st_mtime_ns):
        top, *rest = name.split(".")
        if top != "validation":
            files.update(_package_files(top))
            continue
        for f in (ROOT.joinpath(top, *rest).with_suffix(".py"),
                  ROOT.joinpath(top, *rest, "__init__.py")):
            files |= _sources(f, seen)
    return files


def fingerprint(entry: Entry, quick: bool) -> str:
    """What an entry's result depends on, for ``report --resume``: its size (``quick``) and a
    SHA-256 of the files (path and bytes) of the ``rheology`` package, of the entry's tier
    package, of its own module (``validation/cases_<tier>.py``, say), of the sibling modules it
    imports relatively (``validation/framework.py``, ...) and of every project package it
    imports. Installed libraries (numpy, SUNDIALS, ...) are not part of it."""
    module = Path(sys.modules[entry.func.__module__].__file__).resolve()
    files = (set(_package_files("rheology")) | set(_package_files(entry.tier))
             | _sources(module, set()))
    h = hashlib.sha256()
    for f in sorted(files):
        h.update(str(f.relative_to(ROOT) if f.is_relative_to(ROOT) else f).encode() + b"\0")
        h.update(f.read_bytes())
    return f"{'quick' if quick else 'full'}:{h.hexdigest()[:20]}"
