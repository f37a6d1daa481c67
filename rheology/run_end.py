"""Runs that end before their end time keep what they computed, the same way in every tier.

A time-dependent run (``rheometer`` startup, creep, relax, program, material-point; ``shear1d``
annular and couette; ``mpm2d run``) can reach a point past which its numbers are not results:
the elastic strain of the hypoelastic law passes its small-strain limit (taubar/G or p/K above
:data:`rheology.elastic.ELASTIC_STRAIN_LIMIT`), the solver fails (SUNDIALS IDA gives up or
returns an unphysical state), or the Table 8 local update fails. The run then ends there:

- the rows computed up to the end are kept, nothing past it: the first row past a limit is not
  written, so the last row written is the last valid one;
- the run's JSON record holds ``status`` (``"complete"`` or ``"ended_early"``) and ``ends``, one
  :meth:`RunEnd.record` per run that ended early (``run``, ``kind``, ``reason`` with the solver's
  diagnostics, ``time_s`` of the last row written, ``quantity``, ``value``, ``limit`` and
  ``past_s``, the time of the first row past the limit or of the failure; null where a kind has
  none). The record is ``NAME.json`` next to a rheometer ``NAME.csv``, a shear1d run's
  ``TAG_summary.json`` or ``couette.json``, and an mpm2d run's ``manifest.json``;
- its figures are drawn up to there, the end marked by a line and its reason (:func:`mark_end`);
- the command prints one line per end on stderr, ``PROG: RUN: ended early at t = T s (last row
  written): REASON``, and exits with :data:`ENDED_EARLY` (3), beside 0 (complete), 1 (failed,
  nothing new written), 2 (bad input) and 130 (interrupted) of :mod:`runkit.command`.
"""

from __future__ import annotations

import dataclasses
import math

#: Exit status of a command whose run ended early, its results up to the end written.
ENDED_EARLY = 3
#: What ended a run: a limit of the law's validity, the solver, the local update.
KINDS = ("validity_limit", "solver_failure", "law_failure")


@dataclasses.dataclass(frozen=True)
class RunEnd:
    """Where and why a run ended before its end time.

    Attributes
    ----------
    kind : one of :data:`KINDS`
    reason : str
        One line: the check that stopped the run, with the solver's diagnostics.
    time_s : float or None
        Time of the last row kept [s] (None: no row was kept).
    quantity : str
        What passed its limit (``"elastic strain taubar/G"``), "" for a failure.
    value, limit : float or None
        Its value at the first row past the limit, and the limit.
    past_s : float or None
        Time of the first row past the limit, or of the failure [s].
    run : str
        Which run of the command (``"phi = 0.5"``, a shear1d run's tag), "" for a single run.
    """

    kind: str
    reason: str
    time_s: float | None = None
    quantity: str = ""
    value: float | None = None
    limit: float | None = None
    past_s: float | None = None
    run: str = ""

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"RunEnd kind = {self.kind!r} must be one of {', '.join(KINDS)}")

    def replace(self, **changes) -> "RunEnd":
        return dataclasses.replace(self, **changes)

    @property
    def label(self) -> str:
        """A short label for a figure: ``"elastic strain taubar/G > 0.1"``, ``"solver failure"``."""
        what = (f"{self.quantity} > {self.limit:g}" if self.quantity and self.limit is not None
                else self.kind.replace("_", " "))
        return f"{self.run}: {what}" if self.run else what

    def line(self) -> str:
        """The console line (without the program's name)."""
        at = (f"at t = {self.time_s:.6g} s (last row written)" if self.time_s is not None
              else "before its first row")
        return f"{self.run + ': ' if self.run else ''}ended early {at}: {self.reason}"

    def record(self) -> dict:
        """The JSON record (strict: non-finite numbers as null)."""
        out = dataclasses.asdict(self)
        for k, v in out.items():
            if isinstance(v, float) and not math.isfinite(v):
                out[k] = None
        return out


class EndedEarly(RuntimeError):
    """A run ended before its end time (:class:`RunEnd`), its rows up to there kept.

    ``ends``: one per run of a command; ``partial``: what the run computed up to there (a
    DataFrame, a shear1d Result); ``written``: the files a command wrote from it.
    :func:`runkit.command.run` prints the ends and returns :data:`ENDED_EARLY` when ``written``
    is set, else the run counts as failed (status 1).
    A RuntimeError, so code that does not look for it sees the failure it always saw.
    """

    def __init__(self, ends, partial=None, written=()):
        self.ends = list(ends)
        if not self.ends:
            raise ValueError("EndedEarly needs at least one RunEnd")
        self.partial = partial
        self.written = list(written)
        super().__init__(self.ends[0].reason)


def run_record(ends, **fields) -> dict:
    """The JSON record of a command's runs: ``status``, ``ends`` (records) and ``fields``."""
    ends = list(ends)
    return {"status": "ended_early" if ends else "complete",
            "ends": [e.record() for e in ends], **fields}


def mark_end(ax, x: float, text: str, *, vertical: bool = True, color: str = "crimson") -> None:
    """Mark a run's end on a matplotlib axes: a dashed line at ``x`` (a vertical line in data
    coordinates of the x axis, or horizontal with ``vertical=False``) and ``text`` beside it."""
    line = ax.axvline if vertical else ax.axhline
    line(x, color=color, ls="--", lw=1.2, zorder=5)
    if vertical:
        ax.annotate(text, (x, 0.5), xycoords=("data", "axes fraction"), rotation=90,
                    fontsize=7, color=color, ha="right", va="center", xytext=(-2, 0),
                    textcoords="offset points")
    else:
        ax.annotate(text, (0.02, x), xycoords=("axes fraction", "data"), fontsize=7,
                    color=color, ha="left", va="top", xytext=(0, -2),
                    textcoords="offset points")
