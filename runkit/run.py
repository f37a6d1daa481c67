"""Long runs: one loop with checkpoint and resume, signals, held numpy warnings and progress,
and one output-folder policy with its manifest.

:func:`drive` advances a :class:`Stepper` (``t``, ``t_end``, ``steps``, ``advance()``) to its
end. Ctrl-C and SIGTERM are deferred to the end of the current ``advance`` (a signal inside a
step would leave a state half-updated), then the checkpoint is saved and ``KeyboardInterrupt``
raised with where it is. A checkpoint (:class:`Checkpoint`) is saved at most every ``every``
seconds of wall time and at an interrupt; it holds the stepper's state and the run's
fingerprint (everything that determines the output: a resume with anything else is refused,
naming the first difference). Resume is byte for byte: the resumed run continues from the
state at an ``advance`` boundary, and ``advance`` is a function of that state alone (an
explicit step; an IDA solve from a consistent state, restarted at each boundary in the
uninterrupted run too).

numpy's warnings of the run are held (:class:`HeldWarnings`): a run that fails cites the first
in its one line; one that completes shows them as they were. :class:`Progress` is a tqdm bar on
a terminal and a plain line every ``every`` seconds otherwise (a log file).

:class:`Folder` is the output-folder policy: a fresh run removes only the files a previous run
of ours listed in its ``manifest.json`` (and the temporaries of an interrupted atomic write); a
fresh run in a non-empty folder without our manifest is refused before anything is written.
The manifest's ``status`` is ``running``, ``complete``, ``stopped``, ``ended_early`` or
``failed`` (with the message). A completed run keeps no checkpoint (:meth:`Folder.write_manifest`
with ``complete``, :func:`retire_checkpoints` for the runs under a folder); an interrupted,
stopped or failed one keeps its own for ``--resume``. :func:`table_arrays` keeps a run's table
(its history) in a checkpoint; :class:`Notice` announces a slow set-up on a terminal.
"""

from __future__ import annotations

import json
import math
import re
import signal
import sys
import threading
import time
import warnings
from pathlib import Path
from typing import Protocol

import numpy as np
import pandas as pd
from tqdm import tqdm

from .io import (atomic_write_json, check_output_dir, load_checkpoint, previous_checkpoint,
                 remove_checkpoint, save_checkpoint)

#: the checkpoint of a run in its output folder
CHECKPOINT = "checkpoint.npz"
#: a temporary file of an atomic write (``.NAME.XXXXXXXX.suffix``) left by a killed run
TEMPORARY = re.compile(r"^\..+\.[a-z0-9_]{8}\.(npz|tmp|vtu|pvd|png|csv|json)$")


class Interrupts:
    """SIGINT and SIGTERM while open (main thread): recorded in ``pending`` (``defer``) or
    raised at once as ``KeyboardInterrupt`` and recorded too (one raised inside a C callback
    can be swallowed: :meth:`check` raises it again). Nested windows share what they record."""

    _open: list = []

    def __init__(self, defer: bool = True):
        self.defer, self.pending, self._old = defer, None, {}

    def __enter__(self):
        if self._open:
            self.pending = self._open[-1].pending
        self._open.append(self)
        if threading.current_thread() is threading.main_thread():
            self._old = {s: signal.signal(s, self._record) for s in (signal.SIGINT,
                                                                      signal.SIGTERM)}
        return self

    def _record(self, signum, frame):
        self.pending = signal.Signals(signum).name
        if not self.defer:
            raise KeyboardInterrupt

    def check(self) -> None:
        """Raise ``KeyboardInterrupt`` if a signal came."""
        if self.pending:
            raise KeyboardInterrupt

    def __exit__(self, *exc):
        for s, old in self._old.items():
            signal.signal(s, old)
        self._open.remove(self)
        if self._open and self.pending:
            self._open[-1].pending = self.pending
        return False


class HeldWarnings:
    """numpy's RuntimeWarnings recorded while open: :meth:`after` for a failure's line,
    :meth:`replay` shows them as they were (a run that succeeded)."""

    def __enter__(self):
        self._cm = warnings.catch_warnings(record=True)
        self.held = self._cm.__enter__()
        warnings.simplefilter("always", RuntimeWarning)
        return self

    def __exit__(self, *exc):
        return self._cm.__exit__(*exc)

    def after(self) -> str:
        """``" after numpy's 'MESSAGE'"`` for the first RuntimeWarning, "" without one."""
        first = next((w for w in self.held if issubclass(w.category, RuntimeWarning)), None)
        return f" after numpy's '{first.message}'" if first is not None else ""

    def replay(self) -> None:
        for w in self.held:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def _clock(seconds: float) -> str:
    s = int(round(max(seconds, 0.0)))
    h, m = divmod(s, 3600)
    m, s = divmod(m, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class Progress:
    """Progress over the simulated time from ``t0`` to ``t_end`` [s] of a run (on stderr).

    On a terminal a tqdm bar redraws in place (refreshed every ``interval`` wall s); otherwise
    (a log file, a pipe, a batch job) plain lines, one at most every ``every`` wall seconds and
    one at the end, each complete on its own (no carriage returns, no bar characters)::

        intruder: 25.2% t = 0.005043/0.02 s, step 4428, 15 ms/step, 1:06 elapsed, ~3:16 left

    The percentage is of the whole run, from ``t_start`` (a resumed run's first time; default
    ``t0``); the wall time per step and the time left count from ``t0``, the start or the
    resume (the simulated time per wall second since then).
    """

    def __init__(self, t0: float, t_end: float, step0: int = 0, *, t_start: float | None = None,
                 stream=None, interval: float = 0.5, label: str = "", every: float = 30.0):
        self.t0, self.t_end, self.step0 = float(t0), float(t_end), int(step0)
        self.t_start = self.t0 if t_start is None else float(t_start)
        self.stream, self.label = stream or sys.stderr, label or "run"
        self.start = time.perf_counter()
        self.done = min(max(self.t0 - self.t_start, 0.0), max(self.t_end - self.t_start, 0.0))
        self.t, self.step, self.every = self.t0, self.step0, float(every)
        self.next_line = self.start + self.every
        self.bar = None
        if getattr(self.stream, "isatty", lambda: False)():
            self.bar = tqdm(total=max(self.t_end - self.t_start, 0.0), initial=self.done,
                            file=self.stream,
                            desc=self.label, unit="s(sim)", dynamic_ncols=True,
                            mininterval=interval, leave=True,
                            bar_format="{desc}: {percentage:5.1f}%|{bar}| "
                                       "[{elapsed}<{remaining}{postfix}]")
            self.bar.set_postfix_str(self._postfix(self.t0, self.step0), refresh=False)

    def _postfix(self, t: float, step: int) -> str:
        per = (time.perf_counter() - self.start) / max(step - self.step0, 1)
        return f"t = {t:.4g}/{self.t_end:.4g} s, step {step}, {per * 1e3:.3g} ms/step"

    def line(self, t: float, step: int) -> str:
        """The plain progress line at simulated time ``t`` [s], step ``step``."""
        frac = min(max((t - self.t_start) / max(self.t_end - self.t_start, 1e-300), 0.0), 1.0)
        wall = time.perf_counter() - self.start
        pace = (t - self.t0) / wall if wall > 0 else 0.0      # simulated s per wall s since t0
        left = max(self.t_end - t, 0.0) / pace if pace > 0 else math.nan
        tail = f", ~{_clock(left)} left" if frac < 1.0 and left == left else ""
        return (f"{self.label}: {100 * frac:5.1f}% {self._postfix(t, step)}, "
                f"{_clock(wall)} elapsed{tail}")

    def update(self, t: float, step: int | None = None) -> None:
        """Advance to simulated time ``t`` [s] at step ``step``."""
        self.t, self.step = float(t), self.step if step is None else int(step)
        if self.bar is None:
            now = time.perf_counter()
            if now >= self.next_line:
                self.next_line = now + self.every
                print(self.line(self.t, self.step), file=self.stream, flush=True)
            return
        target = min(max(self.t - self.t_start, 0.0), self.bar.total)
        if target > self.done:
            self.done = target
            self.bar.set_postfix_str(self._postfix(self.t, self.step), refresh=False)
            self.bar.update(target - self.bar.n)

    def close(self, t: float | None = None, step: int | None = None) -> None:
        """The last line (or the bar's last state)."""
        t, step = self.t if t is None else float(t), self.step if step is None else int(step)
        if self.bar is None:
            print(self.line(t, step), file=self.stream, flush=True)
            return
        self.update(t, step)
        self.bar.set_postfix_str(self._postfix(t, step), refresh=False)
        self.bar.refresh()
        self.bar.close()


class Checkpoint:
    """An .npz checkpoint (atomic, its predecessor kept) with its run's ``fingerprint`` (a dict
    of JSON values: everything that determines the output)."""

    def __init__(self, path, fingerprint: dict):
        self.path, self.fingerprint = Path(path), dict(fingerprint)

    def exists(self) -> bool:
        return self.path.is_file() or previous_checkpoint(self.path).is_file()

    def save(self, state: dict) -> Path:
        return save_checkpoint(self.path, **state,
                               **{"run.fingerprint": np.array(json.dumps(self.fingerprint))})

    def load(self, required=(), log=None) -> dict:
        """The saved state; ValueError if there is none, it is corrupt (with no readable
        predecessor) or it is of another run (naming the first difference)."""
        data = load_checkpoint(self.path, required=("run.fingerprint", *required), log=log)
        stored = json.loads(str(data.pop("run.fingerprint")))
        for k in dict.fromkeys([*self.fingerprint, *stored]):
            mine, theirs = self.fingerprint.get(k), stored.get(k)
            if mine != theirs:
                raise ValueError(f"--resume: {k} = {mine} differs from the checkpoint's {k} = "
                                 f"{theirs} ({self.path}); resume with the same, or start again "
                                 "without --resume")
        return data

    def remove(self) -> None:
        remove_checkpoint(self.path)


def table_arrays(rows: list[dict], name: str) -> dict[str, np.ndarray]:
    """A table (rows of ``{column: value}``, e.g. a run's history) as checkpoint arrays:
    ``NAME_columns`` and one typed array per column, ``NAME.0``, ``NAME.1``... (integer columns
    stay integer; :func:`table_rows` reads them back)."""
    table = pd.DataFrame(rows)
    out = {f"{name}_columns": np.array(list(table.columns))}
    for i, c in enumerate(table.columns):
        out[f"{name}.{i}"] = table[c].to_numpy()
    return out


def table_rows(saved: dict, name: str) -> list[dict]:
    """The rows :func:`table_arrays` put in the checkpoint arrays ``saved`` (Python values)."""
    cols = [str(c) for c in saved[f"{name}_columns"]]
    arrays = [saved[f"{name}.{i}"] for i in range(len(cols))]
    return [{c: a[k].item() for c, a in zip(cols, arrays)} for k in range(len(arrays[0]))]


class Notice:
    """``text`` as a status line on a terminal's stderr once what it wraps has run ``delay``
    wall seconds (a slow set-up: a fast one says nothing), erased when it ends, so what follows
    (a refusal) stands alone; nothing unless ``show``, on a terminal, in the main thread."""

    def __init__(self, text: str, delay: float, show: bool = True):
        self.text, self.shown = text, threading.Event()
        self.timer = threading.Timer(delay, self._tell)
        self.timer.daemon = True
        self.show = (show and sys.stderr.isatty()
                     and threading.current_thread() is threading.main_thread())

    def _tell(self) -> None:
        sys.stderr.write(self.text)
        sys.stderr.flush()
        self.shown.set()

    def __enter__(self):
        if self.show:
            self.timer.start()
        return self

    def __exit__(self, *exc):
        self.timer.cancel()
        if self.timer.is_alive():            # a notice being written is whole before it goes
            self.timer.join()
        if self.shown.is_set():              # the status line goes: what follows stands alone
            sys.stderr.write("\r\x1b[K")
            sys.stderr.flush()
        return False


class Stepper(Protocol):
    """What :func:`drive` advances: the simulated time ``t`` [s] to ``t_end``, the ``steps``
    done, ``advance()`` one step or segment, ``state()`` what a checkpoint holds."""

    t: float
    t_end: float
    steps: int

    def advance(self) -> None: ...

    def state(self) -> dict: ...


def drive(stepper: Stepper, *, checkpoint: Checkpoint | None = None, every: float = 60.0,
          progress: Progress | None = None, stop_after: int | None = None,
          end_tol: float = 1e-12) -> bool:
    """Advance ``stepper`` to ``t_end`` (or ``stop_after`` advances): see the module docstring.

    Returns True at the end time, False when stopped by ``stop_after`` (checkpoint saved).

    Raises
    ------
    KeyboardInterrupt
        SIGINT/SIGTERM, after the current advance and the checkpoint: its message says where.
    RuntimeError
        ``advance`` failed (RuntimeError, ArithmeticError): the message with numpy's first
        warning of the run. An exception that ended the run early (``ends``) passes unchanged.
    """
    last, done = time.perf_counter(), 0
    with Interrupts(defer=True) as stop, HeldWarnings() as held:
        try:
            while stepper.t < stepper.t_end * (1.0 - end_tol):
                stop.check()
                if stop_after is not None and done >= stop_after:
                    break
                stepper.advance()
                done += 1
                if progress is not None:
                    progress.update(stepper.t, stepper.steps)
                if checkpoint is not None and time.perf_counter() - last >= every:
                    checkpoint.save(stepper.state())
                    last = time.perf_counter()
        except KeyboardInterrupt:
            if checkpoint is None:
                raise KeyboardInterrupt("nothing was saved") from None
            checkpoint.save(stepper.state())
            raise KeyboardInterrupt(f"checkpoint written to {checkpoint.path} at t = "
                                    f"{stepper.t:.6g} s: rerun with --resume to continue") from None
        except (RuntimeError, ArithmeticError) as exc:
            if getattr(exc, "ends", None):
                raise
            raise RuntimeError(f"{exc}{held.after()}") from None
        finally:
            if progress is not None:
                progress.close()
        complete = not stepper.t < stepper.t_end * (1.0 - end_tol)
        if checkpoint is not None and not complete:
            checkpoint.save(stepper.state())
    held.replay()
    return complete


class Folder:
    """The output folder of a run (see the module docstring); ``owner`` marks its manifest.

    A tier whose manifest has fields of its own subclasses it: :meth:`ours` recognises its
    manifest, :meth:`listed` names the files a previous run wrote, :attr:`subdirs` are the
    folders it writes into, :attr:`keeps_checkpoint` keeps a completed run's checkpoint; a run
    may replace ``manifest`` by its own fields before its first :meth:`write_manifest`.
    """

    #: the sub-folders a run writes into (a manifest naming a file elsewhere is not trusted;
    #: another entry is the user's); None: any, at any depth
    subdirs: tuple[str, ...] | None = None
    #: a completed run keeps its checkpoint (else :meth:`write_manifest` removes it)
    keeps_checkpoint = False

    def __init__(self, path, owner: str, option: str = "--out"):
        self.path = check_output_dir(option, path)
        self.owner, self.option = owner, option
        self.manifest = {"owner": owner, "status": "running", "files": []}

    def ours(self, manifest: dict) -> bool:
        """Whether ``manifest`` (a dict) is of a run of ours."""
        return manifest.get("owner") == self.owner and isinstance(manifest.get("files"), list)

    def listed(self, manifest: dict) -> list:
        """The names (relative to the folder) of the files the run of ``manifest`` wrote."""
        return manifest["files"] + ["manifest.json"]

    def previous(self) -> dict | None:
        """The manifest of a previous run of ours here, else None."""
        try:
            m = json.loads((self.path / "manifest.json").read_text())
        except (OSError, ValueError, UnicodeDecodeError):
            return None
        return m if isinstance(m, dict) and self.ours(m) else None

    def _inside(self, rel) -> Path | None:
        """``path/rel`` for a plain relative path inside the folder, at its top or in its
        :attr:`subdirs` (a manifest is never trusted to name a file elsewhere)."""
        if not isinstance(rel, str) or not rel or "\\" in rel or Path(rel).is_absolute() \
                or ".." in Path(rel).parts:
            return None
        parts = Path(rel).parts
        if self.subdirs is not None and (len(parts) > 2 or (len(parts) == 2
                                                           and parts[0] not in self.subdirs)):
            return None
        return self.path / rel

    def _entries(self) -> list[Path]:
        """The files where a run of ours writes (the top and :attr:`subdirs`, or at any depth)
        and every other entry (a folder of the user's)."""
        if not self.path.is_dir():
            return []
        if self.subdirs is None:
            return [f for f in self.path.rglob("*") if f.is_file()]
        return [f for e in self.path.iterdir()
                for f in (e.iterdir() if e.is_dir() and e.name in self.subdirs else [e])]

    def check(self, resume: bool = False) -> list[Path]:
        """The files :meth:`prepare` removes: the temporaries of interrupted writes and, for a
        fresh run, the files of the previous run of ours. ValueError, before anything is
        written, for a fresh run in a non-empty folder that holds no run of ours."""
        entries = self._entries()
        gone = [f for f in entries if f.is_file() and TEMPORARY.match(f.name)]
        previous = self.previous()
        if resume:
            if previous is not None:
                self.manifest = {**previous, "status": "running"}
            return gone
        if previous is None:
            if len(gone) < len(entries):
                raise ValueError(f"{self.option} = {str(self.path)!r} is a non-empty folder "
                                 f"that holds no {self.owner} run (no manifest.json of ours): "
                                 "give a new or empty folder, nothing of yours is overwritten")
            return gone
        listed = (self._inside(r) for r in self.listed(previous))
        return gone + [f for f in dict.fromkeys(listed) if f is not None and f.is_file()]

    def prepare(self, resume: bool = False) -> list[str]:
        """:meth:`check` the folder, create it and remove the files :meth:`check` names (the
        temporaries first). Returns the removed names."""
        gone = self.check(resume)
        self.path.mkdir(parents=True, exist_ok=True)
        for f in gone:
            f.unlink()
        return [str(f.relative_to(self.path)) for f in gone]

    def wrote(self, path) -> Path:
        """Record a file the run wrote (removed by the next fresh run here)."""
        rel = str(Path(path).resolve().relative_to(self.path.resolve()))
        if rel not in self.manifest["files"]:
            self.manifest["files"].append(rel)
        return Path(path)

    def write_manifest(self, status: str | None = None, **fields) -> Path:
        """``manifest.json`` (strict JSON) with ``status`` and ``fields``; at ``complete``, the
        folder's :data:`CHECKPOINT` is removed (after the manifest) unless
        :attr:`keeps_checkpoint`."""
        self.manifest.update(fields, **({"status": status} if status else {}))
        path = atomic_write_json(self.path / "manifest.json", self.manifest)
        if self.manifest["status"] == "complete" and not self.keeps_checkpoint:
            remove_checkpoint(self.path / CHECKPOINT)
        return path


def retire_checkpoints(folder) -> list[Path]:
    """Remove the checkpoints of the completed runs under ``folder`` (each :data:`CHECKPOINT`
    and its predecessor beside a ``manifest.json`` whose ``status`` is ``complete``); an
    interrupted, stopped or failed run keeps its own. Returns the files removed."""
    gone = []
    for man in sorted(Path(folder).rglob("manifest.json")):
        try:
            status = json.loads(man.read_text()).get("status")
        except (OSError, ValueError, UnicodeDecodeError, AttributeError):
            continue
        if status == "complete":
            gone += remove_checkpoint(man.parent / CHECKPOINT)
    return gone
