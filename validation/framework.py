"""Validation cases and benchmarks: registration, execution and their results.

A *case* holds one tier against the paper, an analytic solution or the tier below, with a stated
pass criterion; a *benchmark* measures speed (and accuracy) against a reference method timed in the
same process. Each lives in a module ``validation/cases_<tier>.py`` or ``validation/bench_<tier>.py``
(discovered automatically) and registers itself with the decorators below::

    @case("rheology", "fig2_flow_curves", "Fig. 2: steady flow curves of the six experiments")
    def fig2(out: Path, quick: bool) -> Verdict:
        ...
        return Verdict(criterion="...", measured="...", passed=err < 1e-8, figures=[png])

``out`` is the folder for the case's files (figures go there, referenced by path); ``quick`` asks
for the small sizes used by the test suite.

``slow=True`` marks a case whose run is long and whose criteria hold at its full size only:
``python -m validation report --quick`` skips it (listed as skipped in the console, the report and
``results.json``) and refuses it when it is named with ``--only``. A case that passes at both
sizes, however long, can stay ``slow=False``. Benchmarks are always ``slow``; they run at small
sizes under ``--quick`` (``--no-bench`` leaves them out).
"""

from __future__ import annotations

import importlib
import pkgutil
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable


@dataclass
class Verdict:
    """What a case returns: its pass criterion, the measured value(s) and the verdict."""

    criterion: str
    measured: str
    passed: bool
    figures: list[Path] = field(default_factory=list)
    details: str = ""


@dataclass
class BenchResult:
    """What a benchmark returns.

    Attributes
    ----------
    summary : str
        One paragraph: machine, method, reference, medians and ratios.
    rows : list of dict
        The measured table (one dict per row, same keys).
    targets : list of (target, measured, met)
        Each target of the issue with its measured value and whether it is met.
    figures : list of Path
    """

    summary: str
    rows: list[dict] = field(default_factory=list)
    targets: list[tuple[str, str, bool]] = field(default_factory=list)
    figures: list[Path] = field(default_factory=list)


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
    """Register a validation case ``func(out: Path, quick: bool) -> Verdict``.

    ``slow``: a long case judged at full size only (``report --quick`` skips it).
    """
    return _register("case", tier, name, title, slow)


def benchmark(tier: str, name: str, title: str):
    """Register a benchmark ``func(out: Path, quick: bool) -> BenchResult``."""
    return _register("benchmark", tier, name, title, True)


def save_figure(fig, out, name: str) -> Path:
    """Save a case's figure atomically as ``out/name`` and close it; returns the path."""
    import matplotlib.pyplot as plt

    from rheology.io import atomic_savefig

    path = atomic_savefig(fig, Path(out) / name)
    plt.close(fig)
    return path


def load_all() -> dict[str, Entry]:
    """Import every ``validation.cases_*`` and ``validation.bench_*`` module; return the registry."""
    import validation

    for mod in sorted(pkgutil.iter_modules(validation.__path__), key=lambda m: m.name):
        if mod.name.startswith(("cases_", "bench_")):
            importlib.import_module(f"validation.{mod.name}")
    return REGISTRY


@dataclass
class Outcome:
    entry: Entry
    seconds: float
    result: Verdict | BenchResult | None
    error: str | None = None

    @property
    def passed(self) -> bool:
        if self.error is not None:
            return False
        if isinstance(self.result, Verdict):
            return bool(self.result.passed)
        return all(met for _, _, met in self.result.targets)

    @property
    def reason(self) -> str:
        """One line: a failed case's criterion and measured value, a benchmark's unmet targets,
        or the last line of an error."""
        if self.error is not None:
            return "error: " + self.error.strip().splitlines()[-1]
        r = self.result
        if isinstance(r, Verdict):
            return f"criterion {r.criterion}; measured {r.measured}"
        return "; ".join(f"target {t}: measured {m}" for t, m, met in r.targets if not met)


def run_entry(entry: Entry, out: Path, quick: bool = False) -> Outcome:
    """Run one case or benchmark in its own folder ``out/<name>``, capturing errors."""
    folder = Path(out) / entry.name
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    try:
        result = entry.func(folder, quick)
        return Outcome(entry, time.perf_counter() - t0, result)
    except Exception:  # a failing case is reported, not fatal to the report
        return Outcome(entry, time.perf_counter() - t0, None, traceback.format_exc())
