"""Checkpoints of ``rheometer program``: an interrupted program resumes where it stopped.

After every completed step, at most every ``every`` seconds of computing, and always on Ctrl-C
or SIGTERM, ``<out>.checkpoint.npz`` is written (:class:`runkit.run.Checkpoint`): the rows so
far, the exact state at the end of the last completed step, the events, solver counts and ends,
and the run's fingerprint (material, volume fractions, program text, options; a resume with
another is refused, naming the difference). Every step's IDA solve starts from a consistent
state built from (taubar, gap, strain) alone, so the resumed CSV is the uninterrupted run's,
bit for bit; a step interrupted half-way is computed again.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd

from rheology.run_end import RunEnd
from runkit.io import previous_checkpoint
from runkit.run import Checkpoint, Interrupts

from .program import Program
from .protocols import at_phi, combined, run_program
from .transient import COLUMNS, Progress, State

_REQUIRED = ("done_phi", "done_rows", "done_columns", "t", "y", "step", "state",
             "next_step", "events", "counts")


def fingerprint(material, phis, text: str, options: dict) -> dict:
    """Everything that determines a program's output (:class:`runkit.run.Checkpoint` names the
    first difference at a resume): the material's fields and the program text by their hashes;
    of the options not ``label`` (a callable: it names refusals, no part of the output)."""
    fields = {f.name: getattr(material, f.name) for f in dataclasses.fields(material)
              if f.name != "notes"}
    return {"material": hashlib.sha256(repr(sorted(fields.items())).encode()).hexdigest(),
            "--phi": [float(p) for p in phis],
            "program": hashlib.sha256(text.encode()).hexdigest(),
            "options": repr(sorted((k, v) for k, v in options.items() if not callable(v)))}


class ProgramCheckpoint:
    """Runs a program over several volume fractions with checkpoints (see module docstring).

    Parameters
    ----------
    path : Path
        The checkpoint file (``<out>.checkpoint.npz``).
    material : Material
    phis : list of float
    text : str
        The program text (part of the fingerprint).
    options : dict
        G, K0, rtol, points (passed to :func:`rheometer.protocols.run_program`).
    every : float
        Least computing time between two checkpoints after completed steps [s] (> 0).
    """

    def __init__(self, path, material, phis, text: str, options: dict, every: float = 60.0):
        self.path = Path(path)
        self.store = Checkpoint(self.path, fingerprint(material, phis, text, options))
        self.material, self.phis, self.options = material, list(phis), dict(options)
        self.every = float(every)
        self.done: list[pd.DataFrame] = []
        self.ends: list[RunEnd] = []        # of the volume fractions that ended early
        self.progress: Progress | None = None
        self.attrs: dict = {}
        self._last = time.monotonic()
        self._signals = Interrupts(defer=False)

    # ------------------------------------------------------------------ reading
    def load(self, log=None) -> Path:
        """Read the checkpoint for ``--resume``; returns the file read (the previous checkpoint
        NAME.prev.npz when NAME.npz is corrupt, with a notice through ``log``, or absent).
        ValueError if there is none, it is corrupt (naming the file) or it belongs to another
        run."""
        prev = previous_checkpoint(self.path)
        used = [prev if not self.path.is_file() and prev.is_file() else self.path]

        def notice(msg):
            if str(prev) in msg:
                used[0] = prev
            if log is not None:
                log(msg)

        data = self.store.load(required=_REQUIRED, log=notice)
        columns = [str(c) for c in data["done_columns"]]
        rows = data["done_rows"]
        ndone = int(data["done_phi"])
        if ndone:
            table = pd.DataFrame(rows, columns=columns)
            table["step"] = table["step"].astype(int)
            self.done = [table[table["phi"] == ph].reset_index(drop=True)
                         for ph in self.phis[:ndone]]
        if "ends" in data:
            self.ends = [RunEnd(**e) for e in json.loads(str(data["ends"]))]
        nxt = int(data["next_step"])
        if nxt > 0:
            self.progress = Progress(data["t"], data["y"], data["step"].astype(int),
                                     State(*map(float, data["state"])), nxt,
                                     [tuple(e) for e in json.loads(str(data["events"]))],
                                     *map(int, data["counts"]))
        return used[0]

    # ------------------------------------------------------------------ writing
    def save(self) -> None:
        """Write the checkpoint now (finished phis, and the current phi's completed steps)."""
        done = pd.concat(self.done, ignore_index=True) if self.done else None
        pr = self.progress
        empty = np.zeros(0)
        self.store.save(dict(
            done_phi=np.array(len(self.done)),
            done_rows=(done.to_numpy(dtype=float) if done is not None else np.zeros((0, 0))),
            done_columns=np.array(list(done.columns) if done is not None else [], dtype=str),
            t=pr.t if pr else empty, y=pr.y if pr else np.zeros((0, 5)),
            step=pr.step if pr else np.zeros(0, int),
            state=np.array(dataclasses.astuple(pr.state)) if pr else empty,
            next_step=np.array(pr.next_step if pr else 0),
            events=np.array(json.dumps([list(e) for e in pr.events] if pr else [])),
            counts=np.array([pr.solves, pr.nfev, pr.njev] if pr else [0, 0, 0]),
            ends=np.array(json.dumps([e.record() for e in self.ends]))))
        self._last = time.monotonic()

    def remove(self) -> None:
        """Delete the checkpoint (and its predecessor) after the results are written."""
        self.store.remove()

    # ------------------------------------------------------------------ running
    def _on_step(self, progress: Progress) -> None:
        self.progress = progress
        self._signals.check()          # a signal whose KeyboardInterrupt was swallowed (it can
        if time.monotonic() - self._last >= self.every:    # land in a ctypes callback)
            self.save()

    def run(self, program: Program) -> pd.DataFrame:
        """Run (or continue) the program at every phi; the rows of all, column ``phi`` first.

        A phi whose run ends early (:class:`rheology.run_end.EndedEarly`) keeps its rows up to
        the end and the next phi runs; ``attrs["ends"]`` lists those ends (each ``run`` "phi =
        ..."). Raises RuntimeError if no phi has a row, and KeyboardInterrupt("checkpoint
        written to ...; rerun with --resume ...") after saving, when interrupted.
        """
        with Interrupts(defer=False) as self._signals:
            try:
                for ph in self.phis[len(self.done):]:
                    df = at_phi(lambda p: run_program(self.material, p, program,
                                                      resume=self.progress,
                                                      on_step=self._on_step, **self.options),
                                ph, self.ends)
                    if df is None:             # a placeholder: the phi is done (resume)
                        df = pd.DataFrame(columns=list(COLUMNS), dtype=float)
                    df.insert(0, "phi", ph)
                    self.attrs = dict(df.attrs) or self.attrs
                    self.done.append(df)
                    self.progress = None
            except KeyboardInterrupt:
                if not self.done and self.progress is None:
                    raise KeyboardInterrupt("no step was completed, nothing to save; rerun to "
                                            "start again") from None
                self.save()
                raise KeyboardInterrupt(f"checkpoint written to {self.path}; rerun the same "
                                        f"command with --resume to continue") from None
        return combined(self.done, self.ends, self.attrs or {})
